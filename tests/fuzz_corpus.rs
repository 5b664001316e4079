//! Inputs the fuzz harness (`src/bin/toolmark-fuzz.rs`) found, kept as corpus tests,
//! and a short run of the harness itself over every reader.

use std::path::Path;
use std::process::Command;
use toolmark::formats::measured::{ReadOptions, read_measured_bytes};

#[test]
fn an_exr_whose_header_declares_23_gb_is_refused_without_allocating_it() {
    // Found by the harness: a 546-byte mutated EXR whose data window made the decoder
    // allocate 23 GB (then ask for 1 PB and abort). Now refused from its header.
    let path =
        Path::new(env!("CARGO_MANIFEST_DIR")).join("tests/data/fuzz/exr_header_declares_23_gb.exr");
    let bytes = std::fs::read(&path).unwrap();
    assert!(bytes.len() < 4096);
    let err = read_measured_bytes(&path, &bytes, &ReadOptions::default()).unwrap_err();
    assert!(
        err.to_string().contains("declares more pixel data"),
        "{err}"
    );
}

#[test]
fn a_short_fuzz_run_finds_nothing_in_any_reader() {
    // 3,000 mutated inputs per reader (the README's figures come from 1e6 each, with
    // the 1 s hang bound; here the suite shares the cores, so 10 s).
    let output = Command::new(env!("CARGO_BIN_EXE_toolmark-fuzz"))
        .args([
            "--inputs",
            "3000",
            "--seed",
            "7",
            "--threads",
            "1",
            "--hang-ms",
            "10000",
        ])
        .output()
        .expect("the harness runs");
    let stdout = String::from_utf8_lossy(&output.stdout);
    assert!(
        output.status.success(),
        "{stdout}\n{}",
        String::from_utf8_lossy(&output.stderr)
    );
    assert_eq!(
        stdout
            .lines()
            .filter(|l| l.contains("| 3000 | 0 | 0 | 0 |"))
            .count(),
        9,
        "{stdout}"
    );
}
