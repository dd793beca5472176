//! Scratch folders for the binary-driving tests.

use std::path::PathBuf;

/// An empty folder `citywalk-{name}-{pid}` in the system's temporary folder; a leftover from an
/// earlier run with the same process id is removed first, so it cannot hide missing outputs.
pub fn temp_dir(name: &str) -> PathBuf {
    let dir = std::env::temp_dir().join(format!("citywalk-{name}-{}", std::process::id()));
    let _ = std::fs::remove_dir_all(&dir);
    std::fs::create_dir_all(&dir).expect("create a temporary folder");
    dir
}
