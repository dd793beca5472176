//! Scratch files and CPU timing for the loader tests.

use std::path::PathBuf;

/// Writes `bytes` to `name` in a temp folder of this test binary and process.
pub fn temp_file(name: &str, bytes: &[u8]) -> PathBuf {
    let dir = std::env::temp_dir().join(format!(
        "citywalk-{}-{}",
        env!("CARGO_CRATE_NAME"),
        std::process::id()
    ));
    std::fs::create_dir_all(&dir).unwrap();
    let path = dir.join(name);
    std::fs::write(&path, bytes).unwrap();
    path
}

/// CPU time of this thread (ns), from `/proc/thread-self/schedstat` (0 where unavailable): the
/// timings printed are shared-machine wall times, the CPU time is the fairer figure.
pub fn thread_cpu_ns() -> u64 {
    std::fs::read_to_string("/proc/thread-self/schedstat")
        .ok()
        .and_then(|s| s.split_whitespace().next()?.parse().ok())
        .unwrap_or(0)
}
