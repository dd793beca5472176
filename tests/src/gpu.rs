//! GPU test helpers: the headless context (fail on CI without an adapter, skip locally) and
//! image comparison against golden PNGs.

use std::path::{Path, PathBuf};

use citywalk_runtime::gpu::GpuContext;

/// The headless GPU context for a test.
///
/// With the environment variable `CI` set, a missing adapter **fails** the test (CI installs
/// lavapipe, so no adapter means a broken setup). Without `CI`, the test is skipped with a
/// printed note: the caller returns early on `None`.
pub fn gpu_or_skip(test: &str) -> Option<GpuContext> {
    match GpuContext::headless() {
        Ok(gpu) => {
            eprintln!("{test}: adapter {}", gpu.adapter_summary());
            Some(gpu)
        }
        Err(e) if std::env::var_os("CI").is_some() => {
            panic!("{test}: CI is set and no GPU context could be made: {e}")
        }
        Err(e) => {
            eprintln!("{test}: SKIPPED (no GPU, CI unset): {e}");
            None
        }
    }
}

/// Directory of the golden images (`tests/golden/`).
pub fn golden_dir() -> PathBuf {
    Path::new(env!("CARGO_MANIFEST_DIR")).join("golden")
}

/// The result of comparing an image with its golden.
#[derive(Debug, Clone, PartialEq)]
pub struct ImageDiff {
    pub pixels: usize,
    /// Pixels where some channel differs by more than the tolerance.
    pub differing: usize,
    /// Largest channel difference seen.
    pub max_channel_diff: u8,
}

impl ImageDiff {
    /// Share of pixels within tolerance.
    pub fn matching_share(&self) -> f64 {
        1.0 - self.differing as f64 / self.pixels.max(1) as f64
    }
}

/// Compares two RGBA images of equal size, channel by channel.
pub fn diff_rgba(a: &image::RgbaImage, b: &image::RgbaImage, tolerance: u8) -> ImageDiff {
    assert_eq!(a.dimensions(), b.dimensions(), "image sizes differ");
    let mut differing = 0;
    let mut max_channel_diff = 0;
    for (pa, pb) in a.pixels().zip(b.pixels()) {
        let d =
            pa.0.iter()
                .zip(pb.0)
                .map(|(x, y)| x.abs_diff(y))
                .max()
                .unwrap_or(0);
        max_channel_diff = max_channel_diff.max(d);
        differing += usize::from(d > tolerance);
    }
    ImageDiff {
        pixels: (a.width() * a.height()) as usize,
        differing,
        max_channel_diff,
    }
}

/// Compares `actual` with `tests/golden/<name>`; with `CITYWALK_UPDATE_GOLDEN=1` writes it
/// instead. Panics (failing the test) when fewer than `min_share` of the pixels are within
/// `tolerance` per channel; writes the actual image beside the target dir for inspection.
pub fn assert_matches_golden(name: &str, actual: &image::RgbaImage, tolerance: u8, min_share: f64) {
    let path = golden_dir().join(name);
    if std::env::var("CITYWALK_UPDATE_GOLDEN").is_ok_and(|v| v == "1") {
        std::fs::create_dir_all(golden_dir()).expect("create tests/golden");
        actual.save(&path).expect("write golden");
        eprintln!("updated golden {}", path.display());
        return;
    }
    let golden = image::open(&path)
        .unwrap_or_else(|e| {
            panic!(
                "golden {} unreadable ({e}); regenerate with CITYWALK_UPDATE_GOLDEN=1",
                path.display()
            )
        })
        .to_rgba8();
    let diff = diff_rgba(actual, &golden, tolerance);
    if diff.matching_share() < min_share {
        let out = std::env::temp_dir().join(format!("actual-{name}"));
        let _ = actual.save(&out);
        panic!(
            "{name}: {} of {} pixels differ by more than {tolerance} (max {}); actual image at {}",
            diff.differing,
            diff.pixels,
            diff.max_channel_diff,
            out.display()
        );
    }
}
