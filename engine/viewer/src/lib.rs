//! The interactive viewer: a winit window with a wgpu surface, walk and fly modes
//! ([`citywalk_runtime::controller`]), the frame drawn along the culling stages switched on ([`draw`],
//! [`settings`]: frustum / B-Quadtree, HZB occlusion, occluder pre-pass, LOD cut) with an
//! optional debug view (pyramid level, cluster colours, occluders), an egui overlay with the
//! per-stage statistics, stage toggles, LOD sliders and debug-view choice ([`overlay`]; H hides
//! it), a title bar showing mode, position and frame rate, recording of the camera into a `.path`
//! file (R starts and stops) and playback of a path (`--play`).
//!
//! `--screenshot` mode renders a fixed number of frames through the real window and surface,
//! writes the last one to PNG and exits; the Xvfb test drives the viewer that way.

mod app;
pub mod draw;
pub mod input;
pub mod overlay;
pub mod picked;
pub mod screenshot;
pub mod settings;
mod surface;

use std::path::PathBuf;

use citywalk_scenes::camera_path::CameraPath;

use citywalk_runtime::camera_path_io::{PlayEnd, RecordError};
use citywalk_runtime::controller::Mode;
use citywalk_runtime::gpu::GpuError;

pub use draw::ViewerScene;
pub use settings::{CriterionKind, DebugView, FramePlan, LodSettings, RenderSettings};

/// How to run the viewer.
#[derive(Debug, Clone, PartialEq)]
pub struct ViewerOptions {
    /// The mode to start in.
    pub mode: Mode,
    /// Window size in physical pixels.
    pub size_px: (u32, u32),
    /// Render this many frames, save the last and exit.
    pub screenshot: Option<ScreenshotRequest>,
    /// A name for the title bar (the scene's file name).
    pub title: String,
    /// Where R writes the recorded camera path.
    pub record_to: PathBuf,
    /// Play this path, one pose per frame, instead of the controllers.
    pub play: Option<PlayRequest>,
    /// Show the overlay panel at start (H toggles it).
    pub overlay: bool,
    /// The culling stages, LOD criterion and debug view at start (the overlay and the keys
    /// change them).
    pub settings: RenderSettings,
    /// When the command started: the first frame's log line says how long it took to show
    /// (issue 13's "first frame" time).
    pub started: std::time::Instant,
}

/// `--play PATH [--loop]`.
#[derive(Debug, Clone, PartialEq)]
pub struct PlayRequest {
    pub path: CameraPath,
    /// Loop, or stop at the last pose and hand the camera to fly mode there.
    pub end: PlayEnd,
}

/// `--screenshot PATH --frames N`.
#[derive(Debug, Clone, PartialEq)]
pub struct ScreenshotRequest {
    pub path: PathBuf,
    /// Frames to render before the one saved (at least 1).
    pub frames: u32,
}

/// Why the viewer stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ViewerError {
    #[error("event loop: {0}")]
    EventLoop(#[from] winit::error::EventLoopError),
    #[error("creating the window: {0}")]
    Window(#[from] winit::error::OsError),
    #[error("window surface: {0}")]
    Surface(String),
    #[error(transparent)]
    Gpu(#[from] GpuError),
    #[error(transparent)]
    Upload(#[from] citywalk_runtime::upload::UploadError),
    #[error("{0}; the viewer stops (restart it to reopen the scene)")]
    DeviceLost(#[from] citywalk_runtime::gpu::DeviceLost),
    #[error("screenshot: {0}")]
    Screenshot(#[from] screenshot::ScreenshotError),
    #[error("writing screenshot {path}: {source}")]
    Png {
        path: PathBuf,
        #[source]
        source: image::ImageError,
    },
    #[error(transparent)]
    Record(#[from] RecordError),
    #[error("culled frame: {0}")]
    Frame(citywalk_runtime::frame::FrameError),
    #[error("the window closed after {drawn} of {wanted} frames; no screenshot was taken")]
    ScreenshotNotTaken { drawn: u32, wanted: u32 },
}

/// A frame that failed because the device went is the device's loss, said once.
impl From<citywalk_runtime::frame::FrameError> for ViewerError {
    fn from(error: citywalk_runtime::frame::FrameError) -> Self {
        match error {
            citywalk_runtime::frame::FrameError::DeviceLost(lost)
            | citywalk_runtime::frame::FrameError::Readback(
                citywalk_runtime::render::targets::ReadbackError::DeviceLost(lost),
            ) => ViewerError::DeviceLost(lost),
            other => ViewerError::Frame(other),
        }
    }
}

/// Opens the window and runs until it is closed (or the screenshot is written). A scene
/// package's occluders, cluster tree and B-Quadtree feed the culling stages and the LOD cut.
pub fn run(scene: ViewerScene, options: ViewerOptions) -> Result<(), ViewerError> {
    let event_loop = winit::event_loop::EventLoop::new()?;
    event_loop.set_control_flow(winit::event_loop::ControlFlow::Poll);
    let mut app = app::App::new(scene, options);
    event_loop.run_app(&mut app)?;
    app.finish()
}
