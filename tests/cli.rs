//! The command line as a user runs it: outputs, summary schema, engine choice.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};

fn toolmark(args: &[&str], env: &[(&str, &str)]) -> Output {
    let mut command = Command::new(env!("CARGO_BIN_EXE_toolmark"));
    command.args(args).current_dir(env!("CARGO_MANIFEST_DIR"));
    for (key, value) in env {
        command.env(key, value);
    }
    command.output().expect("toolmark runs")
}

fn out_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("toolmark-cli-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    dir
}

fn summary(dir: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(dir.join("summary.json")).expect("summary.json written");
    serde_json::from_str(&text).expect("summary.json is JSON")
}

#[test]
fn run_writes_every_output_with_the_documented_summary_schema() {
    let dir = out_dir("flat");
    let output = toolmark(
        &[
            "run",
            "examples/flat_facing.toml",
            "--engine",
            "cpu",
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    for file in [
        "surface.exr",
        "polar.exr",
        "deviation.png",
        "deviation_colour.png",
        "scallop_colour.png",
        "radial_profile.csv",
        "summary.json",
        "job.resolved.toml",
        "deviation_centre.png",
        "centre_profile.png",
    ] {
        assert!(dir.join(file).is_file(), "{file} missing");
    }
    let leftovers: Vec<_> = std::fs::read_dir(&dir)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "temporary files left: {leftovers:?}");

    let s = summary(&dir);
    assert_eq!(s["schema"], "toolmark.summary/1");
    assert_eq!(s["engine"]["kind"], "cpu");
    // Flat facing, R 0.5 mm, f 10 µm: cusps R − √(R² − f²/4) = 25.0006 nm (closed form);
    // the deviation PV is the cusp height (bottoms touch nominal).
    let pv = s["deviation"]["pv_nm"].as_f64().unwrap();
    let scallop = s["scallop"]["max_nm"].as_f64().unwrap();
    assert!((scallop - 25.0006).abs() < 0.25, "scallop.max_nm {scallop}");
    assert!((pv - 25.0006).abs() < 0.25, "deviation.pv_nm {pv}");
    for key in ["rms_nm", "mean_nm"] {
        assert!(s["deviation"][key].as_f64().is_some(), "deviation.{key}");
    }
    assert!(s["scallop"]["mean_nm"].as_f64().is_some());
    assert!(s["timings_s"]["removal"].as_f64().unwrap() >= 0.0);
    assert_eq!(s["grid"]["azimuths"], 32);
    assert_eq!(s["job"]["process"]["feed_per_rev_mm"], 0.01);
    assert_eq!(s["job_hash"].as_str().unwrap().len(), 16);

    // The EXR carries its metadata and a valid deviation channel.
    let exr = toolmark::formats::exr_io::read_exr(&dir.join("surface.exr")).unwrap();
    for key in [
        "units",
        "pixel_pitch_mm",
        "frame",
        "engine",
        "adapter",
        "job_hash",
    ] {
        assert!(exr.attributes.contains_key(key), "surface.exr lacks {key}");
    }
    assert_eq!(exr.attributes["job_hash"], s["job_hash"].as_str().unwrap());
    let deviation = exr.channel("deviation_nm").unwrap();
    let valid = exr.channel("valid").unwrap();
    assert!(deviation.iter().all(|v| v.is_finite()));
    assert!(valid.iter().filter(|&&v| v == 1.0).count() > deviation.len() / 2);
}

#[test]
fn same_job_gives_byte_identical_cpu_maps() {
    let (a, b) = (out_dir("det-a"), out_dir("det-b"));
    for dir in [&a, &b] {
        let output = toolmark(
            &[
                "run",
                "golden/concave_sphere_xzb.toml",
                "--engine",
                "cpu",
                "--out",
                dir.to_str().unwrap(),
            ],
            &[],
        );
        assert!(output.status.success());
    }
    for file in [
        "polar.exr",
        "surface.exr",
        "deviation.png",
        "radial_profile.csv",
    ] {
        assert_eq!(
            std::fs::read(a.join(file)).unwrap(),
            std::fs::read(b.join(file)).unwrap(),
            "{file} differs between two CPU runs"
        );
    }
}

#[test]
fn gpu_engine_runs_from_the_cli_and_is_recorded() {
    let dir = out_dir("gpu");
    let output = toolmark(
        &[
            "run",
            "examples/flat_facing.toml",
            "--engine",
            "gpu",
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    assert!(
        output.status.success(),
        "the GPU engine must run here (CI: lavapipe): {}",
        String::from_utf8_lossy(&output.stderr)
    );
    let s = summary(&dir);
    assert_eq!(s["engine"]["kind"], "gpu");
    assert!(!s["engine"]["adapter"].as_str().unwrap().is_empty());
}

#[test]
fn without_an_adapter_auto_falls_back_to_cpu_and_gpu_fails() {
    // Asking wgpu for a backend this platform lacks leaves it with no adapter.
    let no_gpu = [("WGPU_BACKEND", "metal")];
    let dir = out_dir("fallback");
    let output = toolmark(
        &[
            "run",
            "golden/flat_facing.toml",
            "--out",
            dir.to_str().unwrap(),
        ],
        &no_gpu,
    );
    let stderr = String::from_utf8_lossy(&output.stderr);
    assert!(output.status.success(), "{stderr}");
    assert!(stderr.contains("no GPU adapter found"), "{stderr}");
    assert!(stderr.contains("using the CPU engine"), "{stderr}");
    assert_eq!(summary(&dir)["engine"]["kind"], "cpu");

    let output = toolmark(
        &[
            "run",
            "golden/flat_facing.toml",
            "--engine",
            "gpu",
            "--out",
            dir.to_str().unwrap(),
        ],
        &no_gpu,
    );
    assert_eq!(output.status.code(), Some(1));
    assert!(String::from_utf8_lossy(&output.stderr).contains("--engine gpu"));
}

#[test]
fn compensate_writes_a_correction_a_job_and_a_program_that_run() {
    let dir = out_dir("compensate");
    let output = toolmark(
        &[
            "compensate",
            "examples/asphere_xz_with_errors.toml",
            "--cycles",
            "1",
            "--engine",
            "cpu",
            "--out",
            dir.to_str().unwrap(),
        ],
        &[],
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}{}",
        String::from_utf8_lossy(&output.stderr)
    );
    for file in [
        "correction.csv",
        "compensated.toml",
        "compensation.json",
        "form_error.png",
        "compensated.nc",
    ] {
        assert!(dir.join(file).is_file(), "{file} missing");
    }
    let report: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(dir.join("compensation.json")).unwrap())
            .unwrap();
    let cycles = report["cycles"].as_array().unwrap();
    assert_eq!(cycles.len(), 2);
    let (first, second) = (
        cycles[0]["form_pv_nm"].as_f64().unwrap(),
        cycles[1]["form_pv_nm"].as_f64().unwrap(),
    );
    assert!(second < first / 5.0, "{first} → {second}");
    // The compensated job runs (its effects still play the machine) and lands on cycle 1's form.
    let rerun = dir.join("rerun");
    let output = toolmark(
        &[
            "run",
            dir.join("compensated.toml").to_str().unwrap(),
            "--engine",
            "cpu",
            "--out",
            rerun.to_str().unwrap(),
        ],
        &[],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    // The written program parses as the C-X-Z form the reader accepts.
    let program = std::fs::read_to_string(dir.join("compensated.nc")).unwrap();
    let parsed = toolmark::formats::nc::parse_nc(&program).expect("compensated.nc parses");
    assert_eq!(parsed.passes.len(), 1);
}

/// A small generating job: the seed-000 wheel (R_t 3.5, r 0.5) on a concave R 53.5 mm
/// part, its circle 15 µm past the axis and its inclination 0.01° off.
const GENERATING_JOB: &str = r#"version = 1
name = "cli generating"
[surface]
kind = "sphere"
form = "concave"
radius_mm = 53.5
aperture_diameter_mm = 4.0
[tool]
kind = "cup_wheel"
cutting_radius_mm = 3.5
edge_radius_mm = 0.5
[process]
kind = "generating"
[grid]
pitch_um = 2.0
azimuths = 8
[[effects]]
kind = "cutter_displacement"
offset_mm = -0.015
[[effects]]
kind = "inclination_error"
error_deg = 0.01
"#;

fn json(path: &Path) -> serde_json::Value {
    let text = std::fs::read_to_string(path).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
    serde_json::from_str(&text).expect("JSON")
}

#[test]
fn correct_tries_both_sides_and_writes_a_corrected_job_that_runs_clean() {
    let dir = out_dir("correct");
    std::fs::create_dir_all(&dir).unwrap();
    let job = dir.join("generating.toml");
    std::fs::write(&job, GENERATING_JOB).unwrap();
    let out = dir.join("correction");
    let output = toolmark(
        &[
            "correct",
            job.to_str().unwrap(),
            "--engine",
            "cpu",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{}\n{stdout}",
        String::from_utf8_lossy(&output.stderr)
    );
    println!("{stdout}");
    for file in [
        "corrected.toml",
        "correction.json",
        "centre_before.png",
        "centre_after.png",
        "centre_profiles.png",
        "before/summary.json",
        "after/summary.json",
    ] {
        assert!(out.join(file).is_file(), "{file} missing");
    }
    let report = json(&out.join("correction.json"));
    assert_eq!(report["schema"], "toolmark.correction/1");
    let cuts = report["cuts"].as_array().unwrap();
    // Past the axis: the first (short-side) try doubles the pip, the second removes it.
    assert_eq!(cuts.len(), 3);
    let first = cuts[0]["central_pv_nm"].as_f64().unwrap();
    let last = cuts[2]["central_pv_nm"].as_f64().unwrap();
    assert!(first / last >= 20.0, "{first} → {last}");
    let miss = report["estimate"]["miss_mm"].as_f64().unwrap();
    assert!((miss - 0.015).abs() < 1e-4, "miss {miss}");
    // The corrected job, run as a user would, leaves no central feature.
    let rerun = dir.join("rerun");
    let output = toolmark(
        &[
            "run",
            out.join("corrected.toml").to_str().unwrap(),
            "--engine",
            "cpu",
            "--out",
            rerun.to_str().unwrap(),
        ],
        &[],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let summary = summary(&rerun);
    assert_eq!(summary["protrusion"]["shape"], "none");
    let error = summary["path"]["part_sphere"]["radius_error_um"]
        .as_f64()
        .unwrap();
    assert!(error.abs() < 1e-3, "radius error {error} µm");
}

#[test]
fn correct_reads_a_measured_profile_and_names_both_sides() {
    let dir = out_dir("correct-measured");
    std::fs::create_dir_all(&dir).unwrap();
    let job = dir.join("generating.toml");
    std::fs::write(&job, GENERATING_JOB).unwrap();
    let part = dir.join("part");
    let output = toolmark(
        &[
            "run",
            job.to_str().unwrap(),
            "--engine",
            "cpu",
            "--out",
            part.to_str().unwrap(),
        ],
        &[],
    );
    assert!(output.status.success());
    let out = dir.join("estimate");
    let output = toolmark(
        &[
            "correct",
            job.to_str().unwrap(),
            "--measured",
            part.join("radial_profile.csv").to_str().unwrap(),
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert!(
        output.status.success(),
        "{}",
        String::from_utf8_lossy(&output.stderr)
    );
    let report = json(&out.join("correction.json"));
    let estimate = &report["estimate"];
    let miss = estimate["miss_mm"].as_f64().unwrap();
    let past = &estimate["hypotheses"][1];
    assert_eq!(past["side"], "past");
    println!("{}", serde_json::to_string_pretty(estimate).unwrap());
    // The truth (past by 15 µm, inclination 0.01° high) is one of the two hypotheses.
    assert!((miss - 0.015).abs() < 1e-4, "miss {miss}");
    assert!((past["tilt_deg"].as_f64().unwrap() + 0.01).abs() < 1e-4);
    assert!((past["move_mm"].as_f64().unwrap() - 0.015).abs() < 1e-4);
    assert!(
        out.join("corrected_short.toml").is_file() && out.join("corrected_past.toml").is_file()
    );
    // A turning job is refused with a pointer to the right command.
    let output = toolmark(
        &[
            "correct",
            "examples/flat_facing.toml",
            "--out",
            out.to_str().unwrap(),
        ],
        &[],
    );
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("compensate"));
}

#[test]
fn formulas_prints_the_seeds_worked_numbers_and_refuses_bad_parameters() {
    let output = toolmark(&["formulas"], &[]);
    assert!(output.status.success());
    let text = String::from_utf8_lossy(&output.stdout);
    // Seed 004: φ 31.79°, φ₁ 10.81°, De 8.429 mm, h 0.1419 mm, Tn 0.7997 mm, De₁ 14.595 mm;
    // seed 003: 126.52 mm; seed 000: 49.880 mm.
    for number in [
        "31.79°",
        "10.81°",
        "8.429 mm",
        "0.1419 mm",
        "0.7997 mm",
        "14.595 mm",
        "126.52 mm",
        "49.880 mm",
    ] {
        assert!(text.contains(number), "missing {number}:\n{text}");
    }
    let output = toolmark(
        &[
            "formulas",
            "ball-end",
            "--diameter-mm",
            "16",
            "--depth-mm",
            "9",
            "--stepover-mm",
            "3",
        ],
        &[],
    );
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains("--depth-mm 9"));
}

/// Writes `text` to `name` in `dir` (created) and returns the path as a string.
fn write_file(dir: &Path, name: &str, text: &str) -> String {
    std::fs::create_dir_all(dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, text).unwrap();
    path.to_str().unwrap().to_string()
}

/// The flat-facing example with an X decentre of its own.
fn facing_with_a_decentre() -> String {
    let base = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/flat_facing.toml"),
    )
    .unwrap();
    format!("{base}\n[[effects]]\nkind = \"x_decentre\"\noffset_mm = 0.001\n")
}

const DRIFT_FRAGMENT: &str = "# the machine's drift, measured on the last part\n[[effects]]\nkind = \"axial_drift\"\ndrift_mm = 0.0005\n";

#[test]
fn an_effects_file_changes_the_part_exactly_as_the_same_tables_in_the_job() {
    let files = out_dir("fragment-files");
    let job = write_file(&files, "job.toml", &facing_with_a_decentre());
    let fragment = write_file(&files, "drift.toml", DRIFT_FRAGMENT);
    let inline = write_file(
        &files,
        "inline.toml",
        &format!("{}\n{DRIFT_FRAGMENT}", facing_with_a_decentre()),
    );
    let (with_file, with_tables, without) = (
        out_dir("fragment-a"),
        out_dir("fragment-b"),
        out_dir("fragment-c"),
    );
    let run = |args: &[&str]| {
        let output = toolmark(args, &[]);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
    };
    let cpu = ["--engine", "cpu", "--out"];
    run(&[
        &["run", &job, "--effects", &fragment],
        &cpu[..],
        &[with_file.to_str().unwrap()],
    ]
    .concat());
    run(&[
        &["run", &inline],
        &cpu[..],
        &[with_tables.to_str().unwrap()],
    ]
    .concat());
    run(&[&["run", &job], &cpu[..], &[without.to_str().unwrap()]].concat());
    // Same resolved job (both effects, in order), same hash, same maps byte for byte.
    let (a, b, c) = (
        summary(&with_file),
        summary(&with_tables),
        summary(&without),
    );
    assert_eq!(a["job"]["effects"], b["job"]["effects"]);
    assert_eq!(a["job"]["effects"][1]["kind"], "axial_drift");
    assert_eq!(a["job"]["effects"][1]["drift_mm"], 0.0005);
    assert_eq!(a["job_hash"], b["job_hash"]);
    assert_eq!(a["deviation"], b["deviation"]);
    for file in [
        "polar.exr",
        "surface.exr",
        "radial_profile.csv",
        "job.resolved.toml",
    ] {
        assert_eq!(
            std::fs::read(with_file.join(file)).unwrap(),
            std::fs::read(with_tables.join(file)).unwrap(),
            "{file} differs between --effects and the same tables in the job"
        );
    }
    let resolved = std::fs::read_to_string(with_file.join("job.resolved.toml")).unwrap();
    assert!(
        resolved.contains("kind = \"axial_drift\"") && resolved.contains("kind = \"x_decentre\"")
    );
    // And the drift did what it says: at radius r it lifts the cut by
    // d·(R_s − r)/(f·N) (N = R_s/f + 1 revolutions from R_s = 5.02 mm, the last a
    // dwell), whose area-weighted mean over the Ø10 face is d·(R_s − 2a/3)/(f·N).
    let lift =
        a["deviation"]["mean_nm"].as_f64().unwrap() - c["deviation"]["mean_nm"].as_f64().unwrap();
    let (start, feed, rim) = (5.02, 0.01, 5.0);
    let expected = 0.0005e6 * (start - 2.0 * rim / 3.0) / (feed * (start / feed + 1.0));
    println!("mean deviation with the drift file: +{lift:.2} nm (closed form {expected:.2} nm)");
    assert!((lift / expected - 1.0).abs() < 0.01, "{lift} vs {expected}");
}

#[test]
fn a_bad_effects_file_is_refused_with_its_path_and_table_index() {
    let files = out_dir("fragment-bad");
    let job = write_file(&files, "job.toml", &facing_with_a_decentre());
    let out = files.join("out");
    let refused = |fragment: &str, expected: &[&str]| {
        let output = toolmark(
            &[
                "run",
                &job,
                "--effects",
                fragment,
                "--engine",
                "cpu",
                "--out",
                out.to_str().unwrap(),
            ],
            &[],
        );
        let stderr = String::from_utf8_lossy(&output.stderr);
        println!("{stderr}");
        assert_eq!(output.status.code(), Some(2), "{stderr}");
        for fragment in expected {
            assert!(stderr.contains(fragment), "missing {fragment:?}: {stderr}");
        }
    };
    // The job has one table of its own; the file's second is its effects[1].
    let bad_value = write_file(
        &files,
        "bad_value.toml",
        "[[effects]]\nkind = \"axial_drift\"\ndrift_mm = 0.0001\n[[effects]]\nkind = \"axial_drift\"\ndrift_mm = 0.3\n",
    );
    refused(
        &bad_value,
        &[
            &format!("{bad_value}: effects[1].drift_mm"),
            "out of range",
            "[−0.25, 0.25]",
        ],
    );
    let wrong_kind = write_file(
        &files,
        "wrong_kind.toml",
        "[[effects]]\nkind = \"spindle_tram\"\ntilt_x_deg = 0.1\n",
    );
    refused(
        &wrong_kind,
        &[
            &format!("{wrong_kind}: effects[0].kind"),
            "milling effect",
            "axial_drift",
        ],
    );
    let more_than_effects = write_file(
        &files,
        "more.toml",
        "[[effects]]\nkind = \"axial_drift\"\ndrift_mm = 0.0001\n[process]\nkind = \"turning\"\n",
    );
    refused(
        &more_than_effects,
        &[
            &format!("{more_than_effects}: process"),
            "only [[effects]] tables",
        ],
    );
    let missing = files.join("no_such_file.toml");
    refused(
        missing.to_str().unwrap(),
        &["no_such_file.toml", "cannot read"],
    );
    assert!(!out.exists(), "a refused run must not write outputs");
}

#[test]
fn compensate_takes_an_effects_file_as_more_machine_errors() {
    let files = out_dir("fragment-compensate");
    let example = std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR")).join("examples/asphere_xz_with_errors.toml"),
    )
    .unwrap();
    let fragment_text = "[[effects]]\nkind = \"axial_drift\"\ndrift_mm = -0.0003\n";
    let job = write_file(&files, "job.toml", &example);
    let fragment = write_file(&files, "drift.toml", fragment_text);
    let inline = write_file(
        &files,
        "inline.toml",
        &format!("{example}\n{fragment_text}"),
    );
    let (with_file, with_tables) = (out_dir("fragment-comp-a"), out_dir("fragment-comp-b"));
    for (args, dir) in [
        (vec!["compensate", &job, "--effects", &fragment], &with_file),
        (vec!["compensate", &inline], &with_tables),
    ] {
        let mut args = args;
        args.extend([
            "--cycles",
            "1",
            "--engine",
            "cpu",
            "--out",
            dir.to_str().unwrap(),
        ]);
        let output = toolmark(&args, &[]);
        assert!(
            output.status.success(),
            "{}",
            String::from_utf8_lossy(&output.stderr)
        );
    }
    let (a, b) = (
        json(&with_file.join("compensation.json")),
        json(&with_tables.join("compensation.json")),
    );
    assert_eq!(a["job_hash"], b["job_hash"]);
    assert_eq!(a["cycles"], b["cycles"]);
    let compensated = std::fs::read_to_string(with_file.join("compensated.toml")).unwrap();
    assert!(
        compensated.contains("kind = \"axial_drift\""),
        "{compensated}"
    );
    let bad = write_file(&files, "bad.toml", "version = 1\n");
    let output = toolmark(
        &["compensate", &job, "--effects", &bad, "--cycles", "1"],
        &[],
    );
    assert_eq!(output.status.code(), Some(2));
    assert!(String::from_utf8_lossy(&output.stderr).contains(&format!("{bad}: version")));
}
