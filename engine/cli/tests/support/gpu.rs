//! Whether a binary-driving GPU test can run: the rule of `citywalk_tests::gpu::gpu_or_skip`.

use citywalk_runtime::gpu::GpuContext;

/// Whether a GPU context (software adapters count) can be made. Without one the test `test` is
/// skipped with a message, except under CI (env `CI` set), where it fails.
pub fn gpu_available(test: &str) -> bool {
    match GpuContext::headless() {
        Ok(_) => true,
        Err(e) if std::env::var_os("CI").is_some() => {
            panic!("{test}: CI is set and no GPU context could be made: {e}")
        }
        Err(e) => {
            eprintln!("{test}: SKIPPED (no GPU, CI unset): {e}");
            false
        }
    }
}
