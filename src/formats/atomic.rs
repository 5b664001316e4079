//! Crash-safe file writing: every output is written to a temporary name in the
//! destination folder and renamed into place, so a reader never sees half a file
//! and an earlier good file survives a failed write.

use std::fs;
use std::io;
use std::path::{Path, PathBuf};
use std::sync::Mutex;

/// Temporary files being written now, and the files completed so far, so that an
/// interrupt (Ctrl-C) can remove the half-written ones and say what was kept.
static IN_FLIGHT: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());
static COMPLETED: Mutex<Vec<PathBuf>> = Mutex::new(Vec::new());

fn lock<'a>(list: &'a Mutex<Vec<PathBuf>>) -> std::sync::MutexGuard<'a, Vec<PathBuf>> {
    list.lock().unwrap_or_else(|poisoned| poisoned.into_inner())
}

/// Removes every temporary file still being written; returns (removed, completed).
pub fn interrupt_cleanup() -> (Vec<PathBuf>, Vec<PathBuf>) {
    let removed: Vec<PathBuf> = lock(&IN_FLIGHT)
        .drain(..)
        .filter(|temp| fs::remove_file(temp).is_ok())
        .collect();
    (removed, lock(&COMPLETED).clone())
}

/// On Ctrl-C (SIGINT/SIGTERM): remove the half-written temporaries, say what was kept
/// (every file already renamed into place is complete), exit with 130.
pub fn install_interrupt_handler() {
    let _ = ctrlc::set_handler(|| {
        let (removed, kept) = interrupt_cleanup();
        eprintln!(
            "\ninterrupted: removed {} half-written file(s); kept {} complete file(s){}",
            removed.len(),
            kept.len(),
            match kept.last().and_then(|p| p.parent()) {
                Some(dir) => format!(" in {}", dir.display()),
                None => String::new(),
            }
        );
        std::process::exit(130);
    });
}

/// The temporary sibling used while `path` is being written.
fn temp_path_for(path: &Path) -> PathBuf {
    let name = path
        .file_name()
        .map(|n| n.to_string_lossy().into_owned())
        .unwrap_or_else(|| "output".to_string());
    path.with_file_name(format!(".{name}.tmp-{}", std::process::id()))
}

/// Calls `write` with a temporary path next to `path`, then renames it onto `path`.
/// On error the temporary file is removed and `path` is left untouched.
pub fn write_atomically<T>(
    path: &Path,
    write: impl FnOnce(&Path) -> io::Result<T>,
) -> io::Result<T> {
    if let Some(dir) = path.parent().filter(|d| !d.as_os_str().is_empty()) {
        fs::create_dir_all(dir)?;
    }
    let temp = temp_path_for(path);
    lock(&IN_FLIGHT).push(temp.clone());
    let outcome = match write(&temp) {
        Ok(value) => fs::rename(&temp, path).map(|()| value),
        Err(err) => Err(err),
    };
    lock(&IN_FLIGHT).retain(|t| t != &temp);
    match outcome {
        Ok(value) => {
            lock(&COMPLETED).push(path.to_path_buf());
            Ok(value)
        }
        Err(err) => {
            let _ = fs::remove_file(&temp);
            Err(err)
        }
    }
}

/// Writes `bytes` to `path` atomically.
pub fn write_bytes_atomically(path: &Path, bytes: &[u8]) -> io::Result<()> {
    write_atomically(path, |temp| fs::write(temp, bytes))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn an_interrupt_removes_the_file_being_written_and_keeps_the_finished_ones() {
        let dir = std::env::temp_dir().join(format!("toolmark-interrupt-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let done = dir.join("done.txt");
        write_bytes_atomically(&done, b"complete").unwrap();
        let half = dir.join("half.txt");
        let _: io::Result<()> = write_atomically(&half, |temp| {
            fs::write(temp, b"half")?;
            // The interrupt arrives mid-write.
            let (removed, kept) = interrupt_cleanup();
            assert_eq!(removed, vec![temp_path_for(&half)]);
            assert!(kept.contains(&done));
            Err(io::Error::other("interrupted"))
        });
        assert!(!half.exists() && !temp_path_for(&half).exists());
        assert_eq!(fs::read(&done).unwrap(), b"complete");
        fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn failed_write_keeps_the_old_file_and_leaves_no_temp() {
        let dir = std::env::temp_dir().join(format!("toolmark-atomic-{}", std::process::id()));
        fs::create_dir_all(&dir).unwrap();
        let target = dir.join("a.txt");
        write_bytes_atomically(&target, b"good").unwrap();
        let result: io::Result<()> = write_atomically(&target, |temp| {
            fs::write(temp, b"half")?;
            Err(io::Error::other("disk full"))
        });
        assert!(result.is_err());
        assert_eq!(fs::read(&target).unwrap(), b"good");
        let leftovers: Vec<_> = fs::read_dir(&dir)
            .unwrap()
            .filter_map(|e| e.ok())
            .filter(|e| e.file_name().to_string_lossy().contains(".tmp-"))
            .collect();
        assert!(
            leftovers.is_empty(),
            "temporary files left behind: {leftovers:?}"
        );
        fs::remove_dir_all(&dir).unwrap();
    }
}
