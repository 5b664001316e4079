//! The defects a new user and a first mutation run found (issue 15), each kept as a
//! corpus test: what once panicked, hung, aborted or misled now runs or is refused by
//! name.

use std::path::{Path, PathBuf};
use std::process::{Command, Output};
use toolmark::formats::measured::{MeasuredSurface, ReadOptions, read_measured};
use toolmark::model::Job;

fn toolmark(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_toolmark"))
        .args(args)
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .output()
        .expect("toolmark runs")
}

fn temp(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("toolmark-i15-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).unwrap();
    dir
}

fn example(name: &str) -> String {
    std::fs::read_to_string(
        Path::new(env!("CARGO_MANIFEST_DIR"))
            .join("examples")
            .join(name),
    )
    .unwrap()
}

fn stderr(output: &Output) -> String {
    String::from_utf8_lossy(&output.stderr).into_owned()
}

/// Flat facing cut small (Ø1 mm) so a CLI run takes a fraction of a second.
fn small_facing(azimuths: u32) -> String {
    example("flat_facing.toml")
        .replace("aperture_diameter_mm = 10.0", "aperture_diameter_mm = 1.0")
        .replace("azimuths = 32", &format!("azimuths = {azimuths}"))
}

#[test]
fn a_turning_job_with_one_azimuth_runs_and_measures_its_scallops() {
    // Once: "min > max, or either was NaN" (f64::clamp in the top view) for azimuths = 1.
    let dir = temp("one-azimuth");
    let job = dir.join("job.toml");
    std::fs::write(&job, small_facing(1)).unwrap();
    let out = dir.join("out");
    let output = toolmark(&[
        "run",
        job.to_str().unwrap(),
        "--engine",
        "cpu",
        "--out",
        out.to_str().unwrap(),
    ]);
    assert!(output.status.success(), "{}", stderr(&output));
    let summary: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("summary.json")).unwrap()).unwrap();
    // R − √(R² − f²/4) with R = 0.5 mm, f = 0.01 mm: 25.0 nm (the example's own closed form).
    let expected = toolmark::geometry::formulas::flat_scallop_height(0.5, 0.01) * 1e6;
    let max = summary["scallop"]["max_nm"].as_f64().unwrap();
    assert!(
        (max - expected).abs() < 0.01 * expected,
        "{max} vs {expected}"
    );
    assert!(out.join("deviation_colour.png").is_file());
}

#[test]
fn a_float_max_height_neither_hangs_the_plot_nor_counts_as_a_height() {
    // Once: an endless line loop in output/plot.rs for heights ≥ ~1e37. f32::MAX (an
    // instrument's invalid marker) is now an invalid point; 1e37 is a (wild) height that
    // is plotted.
    let dir = temp("float-max");
    let csv = dir.join("profile.csv");
    let mut text = String::from("X,Y\n");
    for i in 0..400 {
        let height = match i {
            100 => "3.4028235e38".to_string(),
            200 => "1e37".to_string(),
            _ => format!("{}", 0.02 * (i as f64 * 0.3).sin()),
        };
        text.push_str(&format!("{},{height}\n", i as f64 * 1.0));
    }
    std::fs::write(&csv, &text).unwrap();
    let options = ReadOptions {
        lateral_unit: Some(toolmark::formats::measured::LengthUnit::Micrometre),
        height_unit: Some(toolmark::formats::measured::LengthUnit::Micrometre),
        ..Default::default()
    };
    let read = read_measured(&csv, &options).unwrap();
    let MeasuredSurface::Profile(profile) = read else {
        panic!("a profile")
    };
    assert_eq!(
        profile.info.invalid_points, 1,
        "f32::MAX is the invalid marker"
    );

    let job = dir.join("job.toml");
    std::fs::write(&job, small_facing(8)).unwrap();
    let output = toolmark(&[
        "compare-profile",
        job.to_str().unwrap(),
        "--measured",
        csv.to_str().unwrap(),
        "--lateral-unit",
        "um",
        "--height-unit",
        "um",
        "--engine",
        "cpu",
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    let err = stderr(&output);
    assert!(!err.contains("panicked"), "{err}");
    assert!(dir.join("out/profile.png").is_file(), "{err}");
}

#[test]
fn check_prints_a_job_that_parses_and_checks_again() {
    // Once: the resolved job of the default (spindle_rpm + feed_mm_per_min) carried
    // feed_per_rev_mm as well and was refused; the status line went to stdout.
    let dir = temp("round-trip");
    let output = toolmark(&["check", "examples/asphere_xz.toml"]);
    assert!(output.status.success(), "{}", stderr(&output));
    let stdout = String::from_utf8(output.stdout.clone()).unwrap();
    assert!(stderr(&output).contains("valid"), "status goes to stderr");
    let first = Job::default_job();
    let again = Job::from_toml_str(&stdout, "again").expect("check's stdout is a valid job");
    assert_eq!(
        again.hash(),
        first.hash(),
        "the resolved job is a fixed point"
    );
    let path = dir.join("resolved.toml");
    std::fs::write(&path, &stdout).unwrap();
    let output = toolmark(&["check", path.to_str().unwrap()]);
    assert!(output.status.success(), "{}", stderr(&output));
    // The feed is the same: 2 mm/min at 300 rpm.
    let feed = again.process.pass_spacing_mm().unwrap();
    assert!((feed - 2.0 / 300.0).abs() < 1e-15, "{feed}");
    // check says what the job will cost.
    assert!(
        stderr(&output).contains("GB of memory"),
        "{}",
        stderr(&output)
    );
}

#[test]
fn check_estimates_memory_and_refuses_what_this_machine_cannot_hold() {
    // The 3.9e8-sample flat facing wanted ~48 GB and aborted after a minute. Since
    // the analysis streams (issue 10) it needs ~9.4 GB, which the project machine (23 GB)
    // holds, so 8192² map pixels go on top. Estimate, from the per-item figures in
    // io::job::resources: 64 MB + 3.906e8 samples × 24 B (no polar.exr at this size)
    // + 8192² pixels × 40 B × 6 maps = 2.55e10 B.
    let dir = temp("memory");
    let job = dir.join("big.toml");
    let text = example("flat_facing.toml")
        .replace("pitch_um = 1.0", "pitch_um = 0.0128")
        .replace("azimuths = 32", "azimuths = 1000")
        + "\n[output]\nmap_pixels = 8192\n";
    std::fs::write(&job, text).unwrap();
    let parsed = Job::load(&job).unwrap();
    let estimate = toolmark::model::resources::estimate(&parsed);
    assert!(
        (estimate.cpu_bytes / 2.55e10 - 1.0).abs() < 0.01,
        "{estimate:?}"
    );
    let available = toolmark::model::resources::available_bytes().unwrap();
    let refused = estimate.cpu_bytes > available;
    // Where a machine could hold it, `check` must say so, and the run (minutes) is not
    // attempted; on the project machine both commands must refuse.
    let commands: &[&str] = if refused {
        &["check", "run"]
    } else {
        &["check"]
    };
    for &command in commands {
        let output = toolmark(
            &[
                command,
                job.to_str().unwrap(),
                "--out",
                dir.join("out").to_str().unwrap(),
            ][..if command == "check" { 2 } else { 4 }],
        );
        let err = stderr(&output);
        if refused {
            assert_eq!(output.status.code(), Some(2), "{command}: {err}");
            assert!(err.contains("grid.pitch_um") && err.contains("GB"), "{err}");
        } else {
            assert!(output.status.success(), "{command}: {err}");
        }
    }
    assert!(!dir.join("out/summary.json").exists());
}

#[test]
fn out_is_checked_before_the_work_and_stale_outputs_are_removed() {
    let dir = temp("out");
    let job = dir.join("job.toml");
    std::fs::write(&job, small_facing(8)).unwrap();
    // A file where the folder should be: refused before any work (no summary printed).
    let blocker = dir.join("a-file");
    std::fs::write(&blocker, "x").unwrap();
    for out in [blocker.clone(), blocker.join("below")] {
        let output = toolmark(&["run", job.to_str().unwrap(), "--out", out.to_str().unwrap()]);
        assert_eq!(output.status.code(), Some(1), "{}", stderr(&output));
        assert!(stderr(&output).contains("--out"), "{}", stderr(&output));
        let stdout = String::from_utf8_lossy(&output.stdout);
        assert!(
            !stdout.contains("deviation:"),
            "ran before failing: {stdout}"
        );
    }
    // A reused folder: an earlier milling job's map goes; the user's own file stays.
    let out = dir.join("reused");
    std::fs::create_dir_all(&out).unwrap();
    std::fs::write(out.join("cutting_diameter.png"), "stale").unwrap();
    std::fs::write(out.join("my notes.txt"), "mine").unwrap();
    let output = toolmark(&["run", job.to_str().unwrap(), "--out", out.to_str().unwrap()]);
    assert!(output.status.success(), "{}", stderr(&output));
    assert!(!out.join("cutting_diameter.png").exists());
    assert_eq!(
        std::fs::read_to_string(out.join("my notes.txt")).unwrap(),
        "mine"
    );
}

#[test]
fn an_over_long_job_name_is_refused_by_check() {
    // Once: a 5,000-character name passed check and failed after the computation.
    let text = small_facing(8).replace(
        "name = \"flat facing\"",
        &format!("name = \"{}\"", "n".repeat(5000)),
    );
    let err = Job::from_toml_str(&text, "x").unwrap_err();
    assert_eq!(err.field, "name");
    assert!(
        err.message.contains("5000") && err.message.contains("200"),
        "{err}"
    );
    let ok = small_facing(8).replace(
        "name = \"flat facing\"",
        &format!("name = \"{}\"", "n".repeat(200)),
    );
    assert!(Job::from_toml_str(&ok, "x").is_ok());
}

#[test]
fn a_depth_of_cut_far_beyond_the_stock_is_warned_about() {
    // The 250× case: 0.5 mm into 0.002 mm of stock.
    let text = small_facing(8).replace("depth_of_cut_mm = 0.002", "depth_of_cut_mm = 0.5");
    let job = Job::from_toml_str(&text, "deep").unwrap();
    let warning = job
        .warnings
        .iter()
        .find(|w| w.contains("process.depth_of_cut_mm"))
        .expect("a warning");
    assert!(
        warning.contains("250×") && warning.contains("498.0 µm"),
        "{warning}"
    );
    // The example's depth equal to the stock is not warned about.
    assert!(
        Job::from_toml_str(&small_facing(8), "x")
            .unwrap()
            .warnings
            .is_empty()
    );
}

#[test]
fn the_feed_marks_example_states_the_closed_form_scallop() {
    // Once "625 nm" (s²/16r: the diameter used for the radius); r − √(r² − (s/2)²) with
    // r = 1 mm, s = 0.1 mm is 1250.8 nm.
    let text = example("milling_ball_feed_marks.toml");
    let expected = toolmark::geometry::formulas::flat_scallop_height(1.0, 0.1) * 1e6;
    assert!((expected - 1250.8).abs() < 0.05, "{expected}");
    assert!(text.contains("1250.8 nm") && !text.contains("625 nm"));
}

#[test]
fn decimal_comma_tables_read_as_their_point_twins() {
    let dir = temp("decimal-comma");
    let point = "x_um;height_nm\n0.5;1.25\n1.5;-2.5e1\n2.5;3\n3.5;4.75\n";
    let variants = [
        ("semicolon.csv", point.replace('.', ",")),
        ("tab.txt", point.replace('.', ",").replace(';', "\t")),
        (
            "space.txt",
            "# x_um height_nm\n0,5 1,25\n1,5 -2,5e1\n2,5 3\n3,5 4,75\n".to_string(),
        ),
    ];
    let reference = dir.join("point.csv");
    std::fs::write(&reference, point).unwrap();
    let options = ReadOptions {
        lateral_unit: Some(toolmark::formats::measured::LengthUnit::Micrometre),
        height_unit: Some(toolmark::formats::measured::LengthUnit::Nanometre),
        ..Default::default()
    };
    let read = |path: &Path| match read_measured(path, &options).unwrap() {
        MeasuredSurface::Profile(p) => p,
        MeasuredSurface::Map(_) => panic!("a profile"),
    };
    let expected = read(&reference);
    assert!((expected.height_mm[1] + 25e-6).abs() < 1e-18);
    for (name, text) in variants {
        let path = dir.join(name);
        std::fs::write(&path, text).unwrap();
        let got = read(&path);
        assert_eq!(got.x_mm, expected.x_mm, "{name}");
        assert_eq!(got.height_mm, expected.height_mm, "{name}");
        assert!(
            got.info.notes.iter().any(|n| n.contains("decimal comma")),
            "{name}"
        );
    }
    // A comma-separated file keeps its meaning (x = 0.5, height = 1.25).
    let csv = dir.join("comma.csv");
    std::fs::write(&csv, point.replace(';', ",")).unwrap();
    assert_eq!(read(&csv).height_mm, expected.height_mm);
}

#[test]
fn an_x3p_whose_checksum_does_not_match_is_said_on_the_console() {
    // Once only a note in the report. The corrupted copy differs in the declared MD5 of
    // the point data; diagnosing it must say so on stderr before anything else.
    let dir = temp("x3p-md5");
    let source = Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/measured/sample.x3p");
    let bytes = std::fs::read(&source).unwrap();
    let mut archive = zip::ZipArchive::new(std::io::Cursor::new(&bytes)).unwrap();
    let mut entries: Vec<(String, Vec<u8>)> = Vec::new();
    for k in 0..archive.len() {
        let mut entry = archive.by_index(k).unwrap();
        let mut data = Vec::new();
        std::io::Read::read_to_end(&mut entry, &mut data).unwrap();
        entries.push((entry.name().unwrap().into_owned(), data));
    }
    let main = entries.iter().find(|(n, _)| n == "main.xml").unwrap();
    let main = String::from_utf8(main.1.clone()).unwrap();
    let start = main
        .find("<MD5ChecksumPointData>")
        .expect("the sample declares it")
        + "<MD5ChecksumPointData>".len();
    let mut corrupted = main.clone();
    corrupted.replace_range(start..start + 32, &"0".repeat(32));
    let mut zip = zip::ZipWriter::new(std::io::Cursor::new(Vec::new()));
    for (name, data) in &entries {
        let data = if name == "main.xml" {
            corrupted.as_bytes()
        } else {
            data
        };
        zip.start_file(name, zip::write::SimpleFileOptions::default())
            .unwrap();
        std::io::Write::write_all(&mut zip, data).unwrap();
    }
    let path = dir.join("corrupted.x3p");
    std::fs::write(&path, zip.finish().unwrap().into_inner()).unwrap();
    let read = read_measured(&path, &ReadOptions::default()).unwrap();
    assert!(
        read.info()
            .notes
            .iter()
            .any(|n| n.starts_with("warning: ") && n.contains("MD5")),
        "{:?}",
        read.info().notes
    );
    let output = toolmark(&[
        "diagnose",
        "--job",
        "examples/flat_facing.toml",
        "--measured",
        path.to_str().unwrap(),
        "--engine",
        "cpu",
        "--out",
        dir.join("out").to_str().unwrap(),
    ]);
    let err = stderr(&output);
    assert!(
        err.contains("MD5") && err.contains("corrupted.x3p"),
        "{err}"
    );
    assert!(!err.contains("panicked"), "{err}");
}

#[test]
#[cfg(unix)]
fn ctrl_c_leaves_no_half_written_file_and_says_what_was_kept() {
    // The default job takes seconds (removal, analysis, ten outputs): interrupt it.
    let dir = temp("interrupt");
    let out = dir.join("out");
    let child = Command::new(env!("CARGO_BIN_EXE_toolmark"))
        .args(["run", "--engine", "cpu", "--out", out.to_str().unwrap()])
        .current_dir(env!("CARGO_MANIFEST_DIR"))
        .stdout(std::process::Stdio::null())
        .stderr(std::process::Stdio::piped())
        .spawn()
        .unwrap();
    std::thread::sleep(std::time::Duration::from_millis(800));
    // SAFETY: sending SIGINT to the child we spawned.
    unsafe { libc::kill(child.id() as i32, libc::SIGINT) };
    let output = child.wait_with_output().unwrap();
    let err = stderr(&output);
    if output.status.success() {
        return; // finished before the signal (a very fast machine): nothing to check
    }
    assert_eq!(output.status.code(), Some(130), "{err}");
    assert!(err.contains("interrupted"), "{err}");
    let leftovers: Vec<_> = std::fs::read_dir(&out)
        .unwrap()
        .filter_map(|e| e.ok())
        .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
        .collect();
    assert!(leftovers.is_empty(), "{leftovers:?}");
}
