//! The corpus in tests/invalid_jobs/: every file must be refused with an error that
//! names the field (and says what is allowed), by the library and by the CLI (exit
//! code 2, no panic). Each file's first line lists the expected fragments:
//! `# expect: <fragment> | <fragment> ...`.

use std::path::PathBuf;
use std::process::Command;
use toolmark::model::Job;

fn corpus() -> Vec<(PathBuf, Vec<String>)> {
    let dir = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("tests/invalid_jobs");
    let mut cases: Vec<_> = std::fs::read_dir(&dir)
        .expect("tests/invalid_jobs exists")
        .map(|entry| entry.expect("readable entry").path())
        .filter(|path| path.extension().is_some_and(|e| e == "toml"))
        .map(|path| {
            let text = std::fs::read_to_string(&path).expect("readable job");
            let first = text.lines().next().unwrap_or_default();
            let fragments = first
                .strip_prefix("# expect:")
                .unwrap_or_else(|| panic!("{}: first line must be '# expect: ...'", path.display()))
                .split('|')
                .map(|f| f.trim().to_string())
                .collect();
            (path, fragments)
        })
        .collect();
    cases.sort();
    cases
}

#[test]
fn every_invalid_job_is_refused_with_an_error_naming_the_field() {
    let cases = corpus();
    assert!(cases.len() >= 20, "corpus shrank to {}", cases.len());
    for (path, fragments) in cases {
        let message = match Job::load(&path) {
            Ok(_) => panic!("{} was accepted", path.display()),
            Err(err) => err.to_string(),
        };
        println!("{}: {message}", path.file_name().unwrap().to_string_lossy());
        for fragment in &fragments {
            assert!(
                message.contains(fragment.as_str()),
                "{}: error does not mention {fragment:?}:\n{message}",
                path.display()
            );
        }
    }
}

#[test]
fn the_cli_refuses_invalid_jobs_with_exit_code_2_and_no_panic() {
    let out = std::env::temp_dir().join(format!("toolmark-invalid-{}", std::process::id()));
    for (path, fragments) in corpus() {
        let output = Command::new(env!("CARGO_BIN_EXE_toolmark"))
            .args(["run", "--engine", "cpu", "--out"])
            .arg(&out)
            .arg(&path)
            .output()
            .expect("toolmark runs");
        let stderr = String::from_utf8_lossy(&output.stderr);
        assert_eq!(
            output.status.code(),
            Some(2),
            "{}: {stderr}",
            path.display()
        );
        assert!(!stderr.contains("panicked"), "{}: {stderr}", path.display());
        assert!(
            stderr.contains(fragments[0].as_str()),
            "{}: {stderr}",
            path.display()
        );
    }
    assert!(!out.exists(), "a refused job must not write outputs");
}

/// A job derived on another grid (`Job::on_grid`, the diagnosis's model grid) is the job
/// its own file would give with that grid, and a derived grid is checked as a file's is.
#[test]
fn a_derived_grid_is_the_grid_a_file_gives_and_is_checked_alike() {
    let text = std::fs::read_to_string("examples/flat_facing.toml").unwrap();
    let job = Job::from_toml_str(&text, "flat").unwrap();
    let annulus = toolmark::model::Aperture {
        inner_radius_mm: 1.0,
        outer_radius_mm: 3.0,
    };
    let derived = job.on_grid(annulus, 0.5e-3, 16).unwrap();
    let edited = text
        .replace(
            "aperture_diameter_mm = 10.0",
            "aperture_diameter_mm = 6.0\ninner_diameter_mm = 2.0",
        )
        .replace("pitch_um = 1.0", "pitch_um = 0.5")
        .replace("azimuths = 32", "azimuths = 16");
    let from_file = Job::from_toml_str(&edited, "flat").unwrap();
    assert_eq!(derived.sample_count(), from_file.sample_count());
    assert_eq!(derived.resolved.grid, from_file.resolved.grid);
    assert_eq!(derived.aperture, from_file.aperture);

    // Past the sample limit: refused by the grid's name, as a file would be.
    let err = job.on_grid(job.aperture, 1e-6, 65_536).unwrap_err();
    assert_eq!(err.field, "grid.pitch_um", "{err}");
    // An annulus outside the part, or empty.
    let outside = toolmark::model::Aperture {
        inner_radius_mm: 1.0,
        outer_radius_mm: 6.0,
    };
    let err = job.on_grid(outside, 1e-3, 16).unwrap_err();
    assert_eq!(err.field, "surface.aperture_diameter_mm", "{err}");
    let empty = toolmark::model::Aperture {
        inner_radius_mm: 2.0,
        outer_radius_mm: 2.0,
    };
    assert!(job.on_grid(empty, 1e-3, 16).is_err());
}
