//! Running the `citywalk` binary from a test and reading what it printed.

use std::path::Path;
use std::process::{Command, Output};

/// Runs the binary with `RUST_BACKTRACE=1`, so that a backtrace would show if an error printed
/// one (user errors must print only their message).
pub fn citywalk(args: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .args(args)
        .env("RUST_BACKTRACE", "1")
        .output()
        .expect("run citywalk")
}

/// Standard output and standard error together.
pub fn text(out: &Output) -> String {
    format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    )
}

pub fn path_str(p: &Path) -> &str {
    p.to_str().expect("utf-8 temp path")
}
