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
