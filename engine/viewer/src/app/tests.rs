//! The viewer's own event handlers through a real window (issue 14, GPU faults): each test
//! runs [`App`] under a [`Driver`] that forwards every event to it and acts between its frames,
//! as a user or a driver would, in a child process of this test binary under Xvfb
//! (`xvfb-run -a`; winit allows one event loop per process). Without `xvfb-run` or a GPU
//! adapter the tests are skipped with a message, except under CI (env `CI` set), where they
//! fail.

use std::process::Command;

use winit::event_loop::EventLoop;
use winit::platform::x11::EventLoopBuilderExtX11;

use super::*;
use citywalk_runtime::plan::FramePlan;
use citywalk_scenes::generate::{GenerateParams, generate_city};

/// Names the test a child process runs (set by [`in_xvfb_child`] for the child).
const CHILD_ENV: &str = "CITYWALK_VIEWER_WINDOW_TEST";
/// The window's size at start.
const SIZE: (u32, u32) = (160, 120);
/// A run that has drawn this many frames without finishing its script has failed.
const MAX_FRAMES: u32 = 400;

/// True in the child process that runs `test`; in the parent, runs that child under Xvfb,
/// asserts that it passed, and returns false.
fn in_xvfb_child(test: &str) -> bool {
    if std::env::var(CHILD_ENV).as_deref() == Ok(test) {
        return true;
    }
    let has_xvfb = std::env::var_os("PATH").is_some_and(|paths| {
        std::env::split_paths(&paths).any(|dir| dir.join("xvfb-run").is_file())
    });
    if !has_xvfb {
        let why = "xvfb-run is not installed (apt-get install xvfb)";
        assert!(std::env::var_os("CI").is_none(), "CI is set but {why}");
        eprintln!("skipping {test}: {why}");
        return false;
    }
    let exe = std::env::current_exe().expect("the test binary");
    let output = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x1024x24"])
        .arg(exe)
        .args([
            &format!("app::tests::{test}"),
            "--exact",
            "--nocapture",
            "--test-threads=1",
        ])
        .env(CHILD_ENV, test)
        // X11 through Xvfb, even from a Wayland session.
        .env_remove("WAYLAND_DISPLAY")
        .output()
        .expect("start xvfb-run");
    let log = format!(
        "{}{}",
        String::from_utf8_lossy(&output.stdout),
        String::from_utf8_lossy(&output.stderr)
    );
    if log.contains("NO ADAPTER") {
        assert!(
            std::env::var_os("CI").is_none(),
            "CI is set but no GPU adapter can present to a window:\n{log}"
        );
        eprintln!("skipping {test}: no GPU adapter can present to a window");
        return false;
    }
    assert!(
        output.status.success() && log.contains("1 passed"),
        "{test} under Xvfb failed ({}):\n{log}",
        output.status
    );
    eprintln!("{log}");
    false
}

/// What the script does after a frame: go on, or stop the event loop.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Next {
    Continue,
    Exit,
}

/// Forwards every event to the viewer's [`App`] and, after each frame it draws, runs the
/// script with the number of frames drawn so far.
struct Driver<F: FnMut(&mut App, &ActiveEventLoop, u32) -> Next> {
    app: App,
    script: F,
    drawn: u32,
}

impl<F: FnMut(&mut App, &ActiveEventLoop, u32) -> Next> ApplicationHandler for Driver<F> {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        self.app.resumed(event_loop);
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, id: WindowId, event: WindowEvent) {
        self.app.window_event(event_loop, id, event);
        if self.app.frames_drawn > self.drawn {
            self.drawn = self.app.frames_drawn;
            let next = if self.drawn >= MAX_FRAMES {
                Next::Exit
            } else {
                (self.script)(&mut self.app, event_loop, self.drawn)
            };
            if next == Next::Exit {
                event_loop.exit();
            }
        }
    }

    fn device_event(&mut self, event_loop: &ActiveEventLoop, id: DeviceId, event: DeviceEvent) {
        self.app.device_event(event_loop, id, event);
    }

    fn about_to_wait(&mut self, event_loop: &ActiveEventLoop) {
        self.app.about_to_wait(event_loop);
    }
}

/// Runs the viewer on a small generated city (HZB culling on, the auto plan off, so every
/// frame is the culling frame) under `script`; returns the app once the loop has stopped.
fn run_viewer(script: impl FnMut(&mut App, &ActiveEventLoop, u32) -> Next) -> App {
    let city = generate_city(&GenerateParams::new(60, 9)).expect("generate");
    let scene = ViewerScene {
        city,
        cluster_tree: None,
        blocks: None,
        gpu_scene: None,
        ground_surfaces: None,
        package: None,
        cluster_textures: None,
    };
    let options = ViewerOptions {
        mode: Mode::Walk,
        size_px: SIZE,
        screenshot: None,
        title: "window test".to_string(),
        record_to: std::env::temp_dir().join("citywalk-window-test.path"),
        play: None,
        overlay: true,
        settings: RenderSettings {
            stages: FramePlan {
                frustum: true,
                hzb: true,
                ..FramePlan::NONE
            },
            auto: false,
            ..RenderSettings::default()
        },
        started: Instant::now(),
    };
    let event_loop = EventLoop::builder()
        .with_any_thread(true)
        .build()
        .expect("an event loop on the X server");
    event_loop.set_control_flow(winit::event_loop::ControlFlow::Poll);
    let mut driver = Driver {
        app: App::new(scene, options),
        script,
        drawn: 0,
    };
    event_loop.run_app(&mut driver).expect("the event loop ran");
    match &driver.app.error {
        // The parent skips (or fails under CI) on this line.
        Some(e @ ViewerError::Gpu(_)) => panic!("NO ADAPTER: {e}"),
        Some(ViewerError::Surface(e)) if e.contains("no GPU adapter") => {
            panic!("NO ADAPTER: {e}")
        }
        _ => {}
    }
    driver.app
}

/// The window's surface size and its GPU, while there is a window.
fn surface_size(app: &App) -> Option<(u32, u32)> {
    let gfx = app.gfx.as_ref()?;
    Some((gfx.surface.config.width, gfx.surface.config.height))
}

/// The device is destroyed between two frames of the running viewer (wgpu's `Device::destroy`:
/// the loss a driver reset or an unplugged GPU gives, with the reason "destroyed"): the viewer
/// stops with `ViewerError::DeviceLost`, whose message names the loss and its reason; no panic,
/// no hang. wgpu reports a destroyed device once its queue has drained, so a frame already on
/// its way may still be "drawn" (every call on the lost device does nothing), never more.
#[test]
fn a_device_lost_while_the_viewer_runs_stops_it_with_the_reason() {
    const TEST: &str = "a_device_lost_while_the_viewer_runs_stops_it_with_the_reason";
    if !in_xvfb_child(TEST) {
        return;
    }
    const LOST_AT: u32 = 4;
    let app = run_viewer(|app, _, drawn| {
        if drawn == LOST_AT {
            let gfx = app.gfx.as_ref().expect("a window");
            gfx.surface.gpu.device.destroy();
        }
        Next::Continue
    });
    assert!(
        app.frames_drawn <= LOST_AT + 1,
        "{} frames drawn after the device was lost",
        app.frames_drawn - LOST_AT
    );
    let error = app.finish().expect_err("the viewer stops with the loss");
    let text = error.to_string();
    assert!(
        matches!(error, ViewerError::DeviceLost(_)),
        "not a device loss: {error:?}"
    );
    assert!(
        text.contains("GPU device was lost")
            && text.contains("destroyed")
            && text.contains("the viewer stops"),
        "{text}"
    );
    eprintln!("the viewer stopped with: {text}");
}

/// Where the resize test is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Phase {
    /// Drawing at the start size.
    Start,
    /// Asked for 1×1; the frames drawn since the surface became 1×1.
    Tiny(u32),
    /// Asked for the start size again; the frames drawn since the surface has it.
    Back(u32),
}

/// Frames drawn at each size before the next resize.
const FRAMES_PER_SIZE: u32 = 3;
/// Frames drawn at one size waiting for a report of it, at most.
const MAX_FRAMES_AT_A_SIZE: u32 = 60;

/// While the viewer runs and draws HZB-culled frames, its window is resized to 1×1, draws
/// there, and back to its size, and draws again. The X server resizes the window and the
/// surface follows through the viewer's own handlers: the resize event, or the acquire that
/// finds the surface suboptimal before that event has come (which reconfigured the surface
/// while holding its texture: a wgpu validation error, a panic). The culling frame builds a
/// pyramid of the 1×1 target (one level, 1×1) and then of the full one, and its reports keep
/// arriving through the report ring; no error, no panic.
#[test]
fn the_viewer_resized_to_one_pixel_and_back_keeps_drawing() {
    const TEST: &str = "the_viewer_resized_to_one_pixel_and_back_keeps_drawing";
    if !in_xvfb_child(TEST) {
        return;
    }
    let mut phase = Phase::Start;
    let mut tiny_pyramids = 0;
    // The report newest when a resize was asked for; a report unequal to it (its times differ
    // if nothing else does) came from a frame drawn since, through the report ring.
    let mut before_resize: Option<citywalk_runtime::runner::FrameReport> = None;
    let (mut fresh_tiny, mut fresh_back) = (0, 0);
    let app = run_viewer(|app, _, drawn| {
        let size = surface_size(app);
        let gfx = app.gfx.as_ref().expect("a window");
        let (pyramid, report) = gfx.drawer.last_frame();
        let pyramid_size = pyramid.map(|p| (p.size(), p.level_count()));
        let fresh = report.is_some() && report.cloned() != before_resize;
        phase = match phase {
            Phase::Start if drawn >= FRAMES_PER_SIZE => {
                assert_eq!(size, Some(SIZE));
                before_resize = report.cloned();
                // Best effort: the X server answers with a resize event, waited for below.
                let _ = gfx
                    .surface
                    .window
                    .request_inner_size(PhysicalSize::new(1, 1));
                Phase::Tiny(0)
            }
            Phase::Tiny(n) if size == Some((1, 1)) => {
                tiny_pyramids += usize::from(pyramid_size == Some(((1, 1), 1)));
                fresh_tiny += usize::from(fresh);
                if n + 1 >= FRAMES_PER_SIZE && fresh_tiny > 0 || n >= MAX_FRAMES_AT_A_SIZE {
                    before_resize = report.cloned();
                    let (w, h) = SIZE;
                    let _ = gfx
                        .surface
                        .window
                        .request_inner_size(PhysicalSize::new(w, h));
                    Phase::Back(0)
                } else {
                    Phase::Tiny(n + 1)
                }
            }
            Phase::Back(n) if size == Some(SIZE) && pyramid_size.is_some_and(|p| p.0 == SIZE) => {
                fresh_back += usize::from(fresh && report.is_some_and(|r| r.buildings_drawn > 0));
                if n + 1 >= FRAMES_PER_SIZE && fresh_back > 0 || n >= MAX_FRAMES_AT_A_SIZE {
                    return Next::Exit;
                }
                Phase::Back(n + 1)
            }
            other => other,
        };
        Next::Continue
    });
    if let Some(e) = &app.error {
        panic!("the viewer failed: {e}");
    }
    assert!(
        matches!(phase, Phase::Back(n) if n + 1 >= FRAMES_PER_SIZE),
        "the resizes did not complete within {MAX_FRAMES} frames ({} drawn, {phase:?})",
        app.frames_drawn
    );
    assert!(
        tiny_pyramids >= 1,
        "no 1×1 frame had a 1×1 one-level pyramid"
    );
    assert!(fresh_tiny > 0, "no report of a 1×1 frame arrived");
    assert!(
        fresh_back > 0,
        "no report of a frame with buildings drawn arrived after the resizes"
    );
    eprintln!(
        "resized to 1×1 and back: {} frames, {tiny_pyramids} with the 1×1 pyramid, {fresh_tiny} \
         reports at 1×1 and {fresh_back} after",
        app.frames_drawn
    );
}
