//! The occlusion benchmark: scenes × camera paths × culling modes, every frame checked against
//! the exact visibility oracle, written as `frames.csv`, `bench.json` and `summary.md`.

pub mod baseline;
pub mod bound;
pub mod decimate;
pub mod far;
pub mod mode;
pub mod output;
pub mod pixel_error;
pub mod plots;
pub mod run;

pub use mode::Mode;
pub use output::{
    AdapterSummary, BenchReport, ModeSummary, SceneLoad, TextureUse, resident_mib, summarise,
    write_outputs,
};
pub use run::{BenchConfig, BenchError, BenchRenderers, BenchScene, FrameRecord, run_path};
