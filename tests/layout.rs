//! The library's rooms and the one direction data flows through them (README "Layout",
//! `src/lib.rs`): a room may import only the rooms before it in `ROOMS`, so there are no
//! import circles. Test modules (after a file's first `#[cfg(test)]`) may reach further.

use std::fs;
use std::path::{Path, PathBuf};

/// The library's rooms in the order data flows through them.
const ROOMS: [&str; 13] = [
    "numeric", "geometry", "field", "formats", "process", "model", "engine", "analysis",
    "pipeline", "output", "diagnose", "loops", "bench",
];

/// What else may stand at `src/`: the crate roots and the command line (the binary's).
const ROOTS: [&str; 4] = ["lib", "main", "cli", "bin"];

fn rank(room: &str) -> Option<usize> {
    ROOMS.iter().position(|r| *r == room)
}

fn rust_files(dir: &Path, out: &mut Vec<PathBuf>) {
    for entry in fs::read_dir(dir).unwrap() {
        let path = entry.unwrap().path();
        if path.is_dir() {
            rust_files(&path, out);
        } else if path.extension().is_some_and(|e| e == "rs") {
            out.push(path);
        }
    }
}

/// The room a source file belongs to: its first component under `src/`, less `.rs`.
fn room_of(path: &Path, src: &Path) -> String {
    let first = path.strip_prefix(src).unwrap().components().next().unwrap();
    let name = first.as_os_str().to_string_lossy();
    name.trim_end_matches(".rs").to_string()
}

/// The rooms `text` names as `crate::<room>` outside its test modules.
fn imported_rooms(text: &str) -> Vec<(usize, String)> {
    let code = text.split("#[cfg(test)]").next().unwrap_or("");
    let mut found = Vec::new();
    for (line, content) in code.lines().enumerate() {
        for (at, _) in content.match_indices("crate::") {
            let rest = &content[at + "crate::".len()..];
            let name: String = rest
                .chars()
                .take_while(|c| c.is_ascii_lowercase() || *c == '_')
                .collect();
            found.push((line + 1, name));
        }
    }
    found
}

#[test]
fn every_source_file_stands_in_a_known_room() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let strays: Vec<String> = files
        .iter()
        .map(|f| room_of(f, &src))
        .filter(|room| rank(room).is_none() && !ROOTS.contains(&room.as_str()))
        .collect();
    assert!(strays.is_empty(), "files outside the rooms: {strays:?}");
}

#[test]
fn no_room_imports_a_room_after_it() {
    let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
    let mut files = Vec::new();
    rust_files(&src, &mut files);
    let mut upward = Vec::new();
    for file in &files {
        let room = room_of(file, &src);
        let Some(own) = rank(&room) else { continue };
        for (line, target) in imported_rooms(&fs::read_to_string(file).unwrap()) {
            if rank(&target).is_some_and(|t| t > own) {
                upward.push(format!("{}:{line}: {room} → {target}", file.display()));
            }
        }
    }
    assert!(
        upward.is_empty(),
        "imports against the flow:\n{}",
        upward.join("\n")
    );
}

#[test]
fn the_check_sees_an_import_against_the_flow() {
    // The scanner itself: a model file naming the pipeline is found, a test module's not.
    let text = "use crate::geometry::Form;\nfn f() { crate::pipeline::simulate(); }\n\
                #[cfg(test)]\nmod tests { use crate::output::html; }\n";
    let names: Vec<String> = imported_rooms(text).into_iter().map(|(_, n)| n).collect();
    assert_eq!(names, ["geometry", "pipeline"]);
    assert!(rank("pipeline") > rank("model"));
}
