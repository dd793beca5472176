//! `citywalk demo` as a new user runs it: from any working directory, on the bundled Chelsea
//! extract, with `all` and `auto` against brute force and every frame checked by the oracle.
//!
//! Without a GPU adapter (software ones count) the run is skipped with a message, except under
//! CI (env `CI` set), where it fails — the rule of `citywalk_tests::gpu::gpu_or_skip`.

use std::process::Command;

#[path = "support/gpu.rs"]
mod gpu;
#[path = "support/scratch.rs"]
mod scratch;
use gpu::gpu_available;
use scratch::temp_dir;

#[test]
fn demo_finds_the_bundled_scene_from_any_folder_and_runs_all_and_auto() {
    if !gpu_available("demo_cli") {
        return;
    }
    let dir = temp_dir("demo");
    let out = Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .current_dir(&dir)
        .args([
            "demo", "--out", "demo-out", "--frames", "2", "--size", "160x90",
        ])
        .output()
        .expect("run citywalk demo");
    let text = format!(
        "{}{}",
        String::from_utf8_lossy(&out.stdout),
        String::from_utf8_lossy(&out.stderr)
    );
    assert!(out.status.success(), "demo failed:\n{text}");
    assert!(text.contains("0 false culls"), "{text}");
    let summary =
        std::fs::read_to_string(dir.join("demo-out/summary.md")).expect("demo writes summary.md");
    for path in ["street", "flyover"] {
        for mode in ["brute", "all", "auto"] {
            assert!(
                summary.contains(&format!("| chelsea | {path} | {mode} |")),
                "summary.md lacks {path} / {mode}:\n{summary}"
            );
        }
    }
    let _ = std::fs::remove_dir_all(&dir);
}
