//! The binary on hostile input and faults (issue 14): every error names the file and the
//! reason, exits non-zero, prints no backtrace, and destroys nothing. CPU only.

use std::path::Path;
use std::process::{Command, Output};

#[path = "support/scratch.rs"]
mod scratch;
use scratch::temp_dir;

/// Runs the binary with `RUST_BACKTRACE=1` (so a backtrace would show if one were printed).
fn citywalk(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("run citywalk")
}

fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}

/// A small generated city as GeoJSON in `dir`.
fn small_city(dir: &Path) -> String {
    let geojson = dir.join("city.geojson");
    let out = citywalk(&[
        "generate",
        "--buildings",
        "12",
        "--seed",
        "3",
        "-o",
        path_str(&geojson),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    path_str(&geojson).to_string()
}

/// Case 1: `preprocess … -o /dev/full` said "wrote /dev/full" and replaced the device with a
/// regular file. A named pipe stands in for the device: refused before the work starts, with
/// the path and the kind of file, exit code 1, no backtrace, and the pipe still a pipe.
#[cfg(unix)]
#[test]
fn preprocess_to_a_device_or_pipe_fails_and_leaves_it() {
    use std::os::unix::fs::FileTypeExt;
    let dir = temp_dir("hostile-output");
    let city = small_city(&dir);
    let fifo = dir.join("out.cwk");
    let made = Command::new("mkfifo").arg(&fifo).status();
    if !made.is_ok_and(|s| s.success()) {
        eprintln!("mkfifo unavailable: skipped");
        return;
    }
    let out = citywalk(&["preprocess", &city, "-o", path_str(&fifo)]);
    let all = text(&out);
    assert_eq!(out.status.code(), Some(1), "{all}");
    assert!(
        all.contains(path_str(&fifo)) && all.contains("named pipe"),
        "{all}"
    );
    assert!(!all.contains("wrote"), "{all}");
    assert!(!all.contains("backtrace"), "{all}");
    let kind = std::fs::symlink_metadata(&fifo).expect("pipe").file_type();
    assert!(kind.is_fifo(), "the pipe was replaced");
}
