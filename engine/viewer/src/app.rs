//! The winit application: window events in, one rendered frame per redraw out.

use std::sync::Arc;
use std::sync::mpsc::Receiver;
use std::time::Instant;

use image::RgbaImage;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{DeviceEvent, DeviceId, ElementState, MouseButton, WindowEvent};
use winit::event_loop::ActiveEventLoop;
use winit::keyboard::PhysicalKey;
use winit::window::{CursorGrabMode, Window, WindowId};

use super::draw::{Drawn, FrameDrawer, ViewerScene};
use super::input::{Command, InputTracker, KEY_HELP};
use super::overlay::{Overlay, OverlayStats, StageCounts};
use super::picked::{PickFacts, Picked, SourceIds, describe};
use super::screenshot::{ScreenshotError, to_rgba_image};
use super::settings::{RenderSettings, SceneFeatures};
use super::surface::{Acquired, WindowSurface};
use super::{ViewerError, ViewerOptions};
use citywalk_runtime::camera::Camera;
use citywalk_runtime::camera_path_io::{PathPlayer, PathRecorder, pose_from_camera};
use citywalk_runtime::controller::{CameraRig, CollisionWorld, Mode};
use citywalk_runtime::render::OffscreenTarget;
use citywalk_runtime::render::targets::read_texture;
use citywalk_scenes::package::{BuildingDetails, PackageError, PackageFile};

/// Longest time step fed to the controllers (seconds): a stall does not teleport the walker.
const MAX_DT_S: f32 = 0.25;
/// How often the title bar is refreshed (seconds).
const TITLE_PERIOD_S: f32 = 0.5;

pub(super) struct App {
    /// The scene, until the graphics upload it.
    scene: Option<ViewerScene>,
    features: SceneFeatures,
    world: CollisionWorld,
    rig: CameraRig,
    options: ViewerOptions,
    input: InputTracker,
    look: MouseLook,
    gfx: Option<Graphics>,
    last_frame: Instant,
    fps: FpsCounter,
    frames_drawn: u32,
    screenshot_taken: bool,
    error: Option<ViewerError>,
    /// Recording the camera (R), one pose per frame drawn.
    recorder: Option<PathRecorder>,
    /// Playing a path (`--play`); `None` once a stopping path is over.
    player: Option<PathPlayer>,
    /// The overlay's field of view slider (degrees), applied to the controllers' cameras.
    fov_y_deg: f32,
    /// The last measured frame rate and frame time, for the overlay.
    last_fps: Option<f32>,
    frame_ms: f32,
    /// What the next frame is drawn with (the overlay and the keys edit it).
    settings: RenderSettings,
    /// The buildings' source ids, kept for the pick panel after the buildings are freed.
    source_ids: SourceIds,
    /// The cursor in the window (physical pixels), for picking.
    cursor: Option<(f32, f32)>,
    /// The camera and size of the last frame drawn: a pick is cast through what the user sees.
    last_view: Option<(Camera, (u32, u32))>,
    /// The building or cluster mesh picked last (left click), tinted and outlined in the
    /// frames.
    picked: Option<Picked>,
    /// The package the scene was read from, for a picked building's levels and tags.
    package: Option<Arc<PackageFile>>,
    /// A picked building's levels and tags being read from the package, on a thread of its
    /// own: the read walks the details of every building before it (a second or so at a
    /// million buildings), which the frames must not wait for.
    reading_details: Option<(u32, Receiver<Result<BuildingDetails, PackageError>>)>,
}

/// Everything that exists only while there is a window.
struct Graphics {
    surface: WindowSurface,
    drawer: FrameDrawer,
    overlay: Overlay,
}

/// Mouse look is on while the right button is held, or after M until M / Esc.
#[derive(Debug, Default)]
struct MouseLook {
    button_held: bool,
    toggled: bool,
}

impl MouseLook {
    fn active(&self) -> bool {
        self.button_held || self.toggled
    }
}

impl App {
    pub(super) fn new(mut scene: ViewerScene, options: ViewerOptions) -> App {
        let world = CollisionWorld::from_city(&scene.city);
        let rig = CameraRig::for_city(&scene.city, &world, options.mode);
        tracing::info!(
            buildings = scene.city.buildings.len(),
            walls = world.wall_count(),
            start = %rig.camera().to_arg_string(),
            "viewer ready; {KEY_HELP}"
        );
        let source_ids = SourceIds::of(&scene.city);
        let package = scene.package.take().map(Arc::new);
        scene.release_buildings();
        let player = (options.play.as_ref()).map(|p| PathPlayer::new(p.path.clone(), p.end));
        if let Some(p) = &options.play {
            tracing::info!(poses = p.path.poses.len(), name = %p.path.name, "playing a camera path");
        }
        App {
            features: scene.features(),
            scene: Some(scene),
            settings: options.settings,
            world,
            rig,
            options,
            recorder: None,
            player,
            fov_y_deg: Camera::DEFAULT_FOV_Y_RAD.to_degrees(),
            last_fps: None,
            frame_ms: 0.0,
            input: InputTracker::default(),
            look: MouseLook::default(),
            gfx: None,
            last_frame: Instant::now(),
            fps: FpsCounter::default(),
            frames_drawn: 0,
            screenshot_taken: false,
            error: None,
            source_ids,
            cursor: None,
            last_view: None,
            picked: None,
            package,
            reading_details: None,
        }
    }

    /// The outcome once the event loop has returned. A recording still running is written.
    pub(super) fn finish(mut self) -> Result<(), ViewerError> {
        if let Some(recorder) = self.recorder.take() {
            save_recording(&recorder)?;
        }
        if let Some(e) = self.error {
            return Err(e);
        }
        match &self.options.screenshot {
            Some(shot) if !self.screenshot_taken => Err(ViewerError::ScreenshotNotTaken {
                drawn: self.frames_drawn,
                wanted: shot.frames,
            }),
            _ => Ok(()),
        }
    }

    /// Picks the drawn building or cluster mesh under the cursor in the last frame, describes
    /// it in the panel, tints and outlines it (a package building's levels and tags are read
    /// from the package off this thread); a click on the sky or the ground clears the pick.
    fn pick_under_cursor(&mut self) {
        let (Some(gfx), Some(cursor), Some((camera, size))) =
            (&mut self.gfx, self.cursor, self.last_view)
        else {
            return;
        };
        let pick = gfx.drawer.pick(&camera, size, cursor);
        let city = gfx.drawer.city();
        self.picked = pick.map(|p| {
            let (bounds, covered) = gfx.drawer.draw_facts(p.draw);
            describe(&PickFacts {
                draw: p.draw,
                distance_m: p.distance_m,
                building_count: gfx.drawer.building_count(),
                bounds,
                covered: &covered,
                source_ids: &self.source_ids,
                city,
                package_details: self.package.is_some()
                    && (p.draw as usize) >= city.buildings.len(),
            })
        });
        self.reading_details = None;
        if let (Some(id), Some(package)) = (
            self.picked.as_ref().and_then(|p| p.details_pending),
            &self.package,
        ) {
            let (send, receive) = std::sync::mpsc::channel();
            let package = Arc::clone(package);
            std::thread::spawn(move || {
                let start = Instant::now();
                let read = package.building_details(id as usize);
                tracing::debug!(
                    building = id,
                    ms = start.elapsed().as_secs_f64() * 1e3,
                    "read a building's details from the package"
                );
                // The pick may have moved on and dropped the receiver: nothing to tell.
                let _ = send.send(read);
            });
            self.reading_details = Some((id, receive));
        }
        if let Some(p) = &self.picked {
            let summary: Vec<String> = p
                .rows
                .iter()
                .take(3)
                .map(|(k, v)| format!("{k} {v}"))
                .collect();
            tracing::info!("picked {}", summary.join(", "));
        }
        let gpu = &gfx.surface.gpu;
        gfx.drawer
            .set_highlight(gpu, self.picked.as_ref().map(|p| p.draw));
    }

    /// Puts a picked building's levels and tags in the panel once their read is done.
    fn receive_details(&mut self) {
        let Some((id, receiver)) = &self.reading_details else {
            return;
        };
        let read = match receiver.try_recv() {
            Ok(read) => read.map_err(|e| e.to_string()),
            Err(std::sync::mpsc::TryRecvError::Empty) => return,
            Err(std::sync::mpsc::TryRecvError::Disconnected) => {
                Err("the read stopped without an answer".to_string())
            }
        };
        if let Some(picked) = &mut self.picked {
            picked.fill_details(*id, read);
        }
        self.reading_details = None;
    }

    /// Stops with `error`; an error while the device is lost is that loss (the call that failed
    /// first is only its symptom).
    fn fail(&mut self, event_loop: &ActiveEventLoop, error: ViewerError) {
        let error = match self.gfx.as_ref().map(|gfx| &gfx.surface.gpu) {
            Some(gpu) if !matches!(error, ViewerError::DeviceLost(_)) => {
                gpu.wait_idle();
                gpu.alive().map_or_else(ViewerError::DeviceLost, |()| error)
            }
            _ => error,
        };
        tracing::error!("{error}");
        self.error.get_or_insert(error);
        event_loop.exit();
    }

    fn create_graphics(&mut self, event_loop: &ActiveEventLoop) -> Result<Graphics, ViewerError> {
        let (width, height) = self.options.size_px;
        let attributes = Window::default_attributes()
            .with_title(format!("citywalk — {}", self.options.title))
            .with_inner_size(PhysicalSize::new(width.max(1), height.max(1)));
        let window = Arc::new(event_loop.create_window(attributes)?);
        let surface = WindowSurface::new(window, self.options.screenshot.is_some())?;
        let Some(scene) = self.scene.take() else {
            return Err(ViewerError::Surface(
                "the scene was uploaded to an earlier window".to_string(),
            ));
        };
        let mut drawer = FrameDrawer::new(&surface.gpu, surface.config.format, scene)?;
        // A screenshot's panel shows the counts of the frame it captures.
        drawer.wait_for_reports = self.options.screenshot.is_some();
        let overlay = Overlay::new(
            &surface.gpu,
            &surface.window,
            surface.config.format,
            self.options.overlay,
        );
        Ok(Graphics {
            surface,
            drawer,
            overlay,
        })
    }

    fn set_mouse_look(&mut self, button_held: bool, toggled: bool) {
        let was = self.look.active();
        self.look = MouseLook {
            button_held,
            toggled,
        };
        let Some(gfx) = &self.gfx else { return };
        if was == self.look.active() {
            return;
        }
        let window = &gfx.surface.window;
        if self.look.active() {
            // Locked where the platform has it (Wayland, macOS), else confined (X11, Windows).
            let grabbed = window
                .set_cursor_grab(CursorGrabMode::Locked)
                .or_else(|_| window.set_cursor_grab(CursorGrabMode::Confined));
            if let Err(e) = grabbed {
                tracing::debug!("cursor grab unavailable: {e}");
            }
            window.set_cursor_visible(false);
        } else {
            if let Err(e) = window.set_cursor_grab(CursorGrabMode::None) {
                tracing::debug!("cursor release failed: {e}");
            }
            window.set_cursor_visible(true);
        }
    }

    fn command(&mut self, event_loop: &ActiveEventLoop, command: Command) {
        match command {
            Command::ToggleMode => self.rig.toggle_mode(&self.world),
            Command::Overview => self.rig.reset_to_overview(),
            Command::ToggleMouseLook => {
                self.set_mouse_look(self.look.button_held, !self.look.toggled);
            }
            Command::Escape if self.look.active() => self.set_mouse_look(false, false),
            Command::Escape => event_loop.exit(),
            Command::ToggleRecording => self.toggle_recording(),
            Command::ToggleOverlay => {
                if let Some(gfx) = &mut self.gfx {
                    gfx.overlay.visible = !gfx.overlay.visible;
                }
            }
            Command::ToggleFrustum => {
                let stages = &mut self.settings.stages;
                stages.frustum = !stages.frustum;
                tracing::info!(on = stages.frustum, "frustum culling");
            }
            Command::ToggleCulling => {
                let stages = &mut self.settings.stages;
                stages.hzb = !stages.hzb;
                tracing::info!(on = stages.hzb, "HZB occlusion culling");
            }
            Command::ToggleOccluders => {
                if self.features.occluders {
                    let stages = &mut self.settings.stages;
                    stages.occluders = !stages.occluders;
                    tracing::info!(on = stages.occluders, "occluder pre-pass");
                } else {
                    tracing::info!("this scene has no occluders (they come with scene packages)");
                }
            }
            Command::ToggleAuto => {
                self.settings.auto = !self.settings.auto;
                tracing::info!(on = self.settings.auto, "auto plan");
            }
            Command::ToggleOccluderGate => {
                let stages = &mut self.settings.stages;
                stages.occluder_gate = !stages.occluder_gate;
                tracing::info!(on = stages.occluder_gate, "occluder gate of the early set");
            }
            Command::ToggleLod => {
                if self.features.cluster_tree {
                    let stages = &mut self.settings.stages;
                    stages.lod = !stages.lod;
                    tracing::info!(on = stages.lod, "LOD cut");
                } else {
                    tracing::info!("this scene has no cluster tree (it comes with scene packages)");
                }
            }
            Command::ToggleClusterTextures => {
                self.settings.cluster_textures = !self.settings.cluster_textures;
                tracing::info!(on = self.settings.cluster_textures, "cluster textures");
            }
            Command::ToggleCriterion => {
                let lod = &mut self.settings.lod;
                lod.kind = lod.kind.next();
                tracing::info!(criterion = lod.kind.name(), "LOD criterion");
            }
            Command::NextDebugView => {
                self.settings.debug_view = self.settings.debug_view.next();
                tracing::info!(view = self.settings.debug_view.name(), "debug view");
            }
            Command::CoarserMip => self.settings.mip_level = (self.settings.mip_level + 1).min(16),
            Command::FinerMip => {
                self.settings.mip_level = self.settings.mip_level.saturating_sub(1);
            }
        }
    }

    /// R: starts recording, or stops and writes the path (a failed write is logged; the
    /// viewer goes on).
    fn toggle_recording(&mut self) {
        match self.recorder.take() {
            Some(recorder) => {
                if let Err(e) = save_recording(&recorder) {
                    tracing::error!("{e}");
                }
            }
            None => {
                let recorder = PathRecorder::new(&self.options.record_to, "recorded");
                tracing::info!(
                    path = %recorder.output().display(),
                    "recording the camera path (one pose per frame); R stops and writes it"
                );
                self.recorder = Some(recorder);
            }
        }
    }

    /// The camera of this frame: the next pose of the path played, else the active controller
    /// advanced by `dt_s` (with the overlay's field of view). A stopping path hands over to fly
    /// mode at its last pose.
    fn next_camera(&mut self, dt_s: f32) -> Camera {
        let input = self.input.take();
        if let Some(player) = &mut self.player {
            if let Some(camera) = player.next_camera() {
                return camera;
            }
            if let Some(last) = player.path().poses.last() {
                self.rig.fly.position = last.position;
                self.rig.fly.yaw_rad = last.yaw_deg.to_radians();
                self.rig.fly.pitch_rad = last
                    .pitch_deg
                    .to_radians()
                    .clamp(-Camera::MAX_PITCH_RAD, Camera::MAX_PITCH_RAD);
                self.rig.mode = Mode::Fly;
            }
            tracing::info!("the path is over; fly mode from its last pose");
            self.player = None;
        }
        self.rig.update(dt_s, &input, &self.world);
        Camera {
            fov_y_rad: self.fov_y_deg.to_radians(),
            ..self.rig.camera()
        }
    }

    /// What the overlay shows for the frame drawn with `camera`; `scene_counts` are the
    /// scene's buildings and triangles, `counts` what the frame measured.
    fn overlay_stats(
        &self,
        camera: &Camera,
        scene_counts: (usize, usize),
        counts: StageCounts,
    ) -> OverlayStats {
        let (buildings_total, triangles_total) = scene_counts;
        let pose = pose_from_camera(camera);
        OverlayStats {
            fps: self.last_fps,
            frame_ms: self.frame_ms,
            mode: if self.player.is_some() {
                "path".to_string()
            } else {
                self.rig.mode.name().to_string()
            },
            position_m: pose.position,
            yaw_deg: pose.yaw_deg,
            pitch_deg: pose.pitch_deg,
            buildings_total,
            triangles_total,
            counts,
            features: self.features,
            recording_poses: self.recorder.as_ref().map(PathRecorder::len),
            playback: self.player.as_ref().map(PathPlayer::progress),
            picked: self.picked.as_ref().map(|p| p.rows.clone()),
        }
    }

    /// One frame: advance the camera, draw, present; in screenshot mode save the last frame.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), ViewerError> {
        let now = Instant::now();
        let frame_s = (now - self.last_frame).as_secs_f32();
        self.frame_ms = frame_s * 1e3;
        self.last_frame = now;
        // No frame to draw (minimised, surface lost): skip it, and consume no pose of a path.
        let Some(gfx) = &mut self.gfx else {
            return Ok(());
        };
        // A lost device draws nothing more: stop with its reason (not a panic at the next call).
        gfx.surface.gpu.alive()?;
        let Acquired::Frame(frame) = gfx.surface.acquire()? else {
            return Ok(());
        };
        let scene_counts = gfx.drawer.scene_counts();
        let camera = self.next_camera(frame_s.min(MAX_DT_S));
        let settings = self.settings;
        let features = self.features;
        let Some(gfx) = &mut self.gfx else {
            return Ok(());
        };
        // The scene first, so the overlay shows this frame's own counts.
        let view = frame
            .texture
            .create_view(&wgpu::TextureViewDescriptor::default());
        let size = (frame.texture.width(), frame.texture.height());
        let drawn: Drawn = gfx.drawer.draw(
            &gfx.surface.gpu,
            &view,
            gfx.surface.depth(),
            size,
            &camera,
            &settings,
            features,
        )?;
        self.last_view = Some((camera, size));
        self.receive_details();
        let stats = self.overlay_stats(&camera, scene_counts, drawn.counts);
        let Some(gfx) = &mut self.gfx else {
            return Ok(());
        };
        let controls = gfx.overlay.prepare(
            &gfx.surface.gpu,
            &gfx.surface.window,
            &stats,
            &mut self.settings,
            self.fov_y_deg,
        );
        gfx.paint_overlay(&view, size);
        self.frames_drawn += 1;
        if let Some(recorder) = &mut self.recorder {
            recorder.push(&camera);
        }
        let shot = (self.options.screenshot.as_ref())
            .filter(|shot| !self.screenshot_taken && self.frames_drawn >= shot.frames);
        if let Some(shot) = shot {
            let image = gfx.capture(&frame.texture, &camera, &settings, features)?;
            image.save(&shot.path).map_err(|source| ViewerError::Png {
                path: shot.path.clone(),
                source,
            })?;
            tracing::info!(path = %shot.path.display(), frames = self.frames_drawn, "screenshot written");
            self.screenshot_taken = true;
            event_loop.exit();
        }
        gfx.surface.window.pre_present_notify();
        gfx.surface.gpu.queue.present(frame);
        if self.frames_drawn == 1 {
            tracing::info!(
                seconds = self.options.started.elapsed().as_secs_f64(),
                "first frame presented"
            );
        }

        if let Some(fps) = self.fps.tick(now) {
            self.last_fps = Some(fps);
            gfx.surface
                .window
                .set_title(&status_line(&self.options.title, &self.rig, fps));
        }
        self.fov_y_deg = controls.fov_y_deg;
        if controls.toggle_mode {
            self.command(event_loop, Command::ToggleMode);
        }
        if controls.toggle_recording {
            self.command(event_loop, Command::ToggleRecording);
        }
        Ok(())
    }
}

impl Graphics {
    /// Paints the prepared overlay over `view` (`width × height`).
    fn paint_overlay(&mut self, view: &wgpu::TextureView, (width, height): (u32, u32)) {
        let gpu = &self.surface.gpu;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("viewer overlay"),
            });
        self.overlay.paint(gpu, &mut encoder, view, width, height);
        gpu.queue.submit([encoder.finish()]);
    }

    /// The frame just drawn into `target`, read back before it is presented; where the surface
    /// cannot be copied from, the same view drawn again offscreen (with the same settings).
    fn capture(
        &mut self,
        target: &wgpu::Texture,
        camera: &Camera,
        settings: &RenderSettings,
        features: SceneFeatures,
    ) -> Result<RgbaImage, ViewerError> {
        let (width, height, format) = (target.width(), target.height(), target.format());
        let texels = if self.surface.copyable {
            read_texture(&self.surface.gpu, target, width, height).map_err(ScreenshotError::from)?
        } else {
            let offscreen = OffscreenTarget::new(&self.surface.gpu, width, height, format)
                .map_err(ScreenshotError::from)?;
            self.drawer.draw(
                &self.surface.gpu,
                &offscreen.colour_view,
                &offscreen.depth,
                (width, height),
                camera,
                settings,
                features,
            )?;
            self.paint_overlay(&offscreen.colour_view, (width, height));
            offscreen
                .read_colour(&self.surface.gpu)
                .map_err(ScreenshotError::from)?
        };
        Ok(to_rgba_image(texels, width, height, format)?)
    }
}

/// Writes a recording and says where.
fn save_recording(recorder: &PathRecorder) -> Result<(), ViewerError> {
    let file = recorder.save()?;
    tracing::info!(
        path = %file.display(),
        poses = recorder.len(),
        "camera path written (play it with `citywalk view SCENE --play PATH`)"
    );
    Ok(())
}

/// The title bar: scene, mode, eye position and frame rate.
fn status_line(title: &str, rig: &CameraRig, fps: f32) -> String {
    let p = rig.camera().position;
    format!(
        "citywalk — {title} — {} — x {:.1} y {:.1} z {:.1} m — {:.1} fps",
        rig.mode.name(),
        p.x,
        p.y,
        p.z,
        fps
    )
}

/// Frames per second over the last [`TITLE_PERIOD_S`].
#[derive(Debug, Default)]
struct FpsCounter {
    since: Option<Instant>,
    frames: u32,
}

impl FpsCounter {
    /// Counts a frame; returns the rate once per period.
    fn tick(&mut self, now: Instant) -> Option<f32> {
        let since = *self.since.get_or_insert(now);
        self.frames += 1;
        let elapsed_s = (now - since).as_secs_f32();
        if elapsed_s < TITLE_PERIOD_S {
            return None;
        }
        let fps = self.frames as f32 / elapsed_s;
        self.since = Some(now);
        self.frames = 0;
        Some(fps)
    }
}

impl ApplicationHandler for App {
    fn resumed(&mut self, event_loop: &ActiveEventLoop) {
        if self.gfx.is_some() {
            return;
        }
        match self.create_graphics(event_loop) {
            Ok(gfx) => {
                gfx.surface.window.request_redraw();
                self.gfx = Some(gfx);
                self.last_frame = Instant::now();
            }
            Err(e) => self.fail(event_loop, e),
        }
    }

    fn window_event(&mut self, event_loop: &ActiveEventLoop, _id: WindowId, event: WindowEvent) {
        if let Some(gfx) = &mut self.gfx {
            let consumed = gfx.overlay.window_event(&gfx.surface.window, &event);
            // Releases always reach the viewer, so no key or button released while egui has
            // focus or the pointer is over the panel is left held.
            let keyboard = matches!(
                &event,
                WindowEvent::KeyboardInput { event, .. } if event.state == ElementState::Pressed
            );
            let pointer = matches!(
                event,
                WindowEvent::MouseInput {
                    state: ElementState::Pressed,
                    ..
                } | WindowEvent::MouseWheel { .. }
            );
            // egui claims Tab for focus moves: keys go to egui only while it has focus.
            if (keyboard && gfx.overlay.wants_keyboard()) || (pointer && consumed) {
                return;
            }
        }
        match event {
            WindowEvent::CloseRequested => event_loop.exit(),
            WindowEvent::Resized(size) => {
                if let Some(gfx) = &mut self.gfx {
                    gfx.surface.resize(size.width, size.height);
                }
            }
            WindowEvent::Focused(false) => {
                self.input.release_all();
                self.set_mouse_look(false, false);
            }
            WindowEvent::KeyboardInput { event, .. } => {
                if let PhysicalKey::Code(key) = event.physical_key
                    && let Some(command) = self.input.key(key, event.state, event.repeat)
                {
                    self.command(event_loop, command);
                }
            }
            WindowEvent::MouseInput {
                state,
                button: MouseButton::Right,
                ..
            } => self.set_mouse_look(state == ElementState::Pressed, self.look.toggled),
            WindowEvent::MouseWheel { delta, .. } => self.input.scroll(delta),
            WindowEvent::CursorMoved { position, .. } => {
                self.cursor = Some((position.x as f32, position.y as f32));
            }
            WindowEvent::CursorLeft { .. } => self.cursor = None,
            WindowEvent::MouseInput {
                state: ElementState::Pressed,
                button: MouseButton::Left,
                ..
            } => self.pick_under_cursor(),
            WindowEvent::RedrawRequested => {
                if let Err(e) = self.redraw(event_loop) {
                    self.fail(event_loop, e);
                }
            }
            _ => {}
        }
    }

    fn device_event(&mut self, _: &ActiveEventLoop, _: DeviceId, event: DeviceEvent) {
        if let DeviceEvent::MouseMotion { delta: (dx, dy) } = event
            && self.look.active()
        {
            self.input.mouse_motion(dx, dy);
        }
    }

    fn about_to_wait(&mut self, _: &ActiveEventLoop) {
        if let Some(gfx) = &self.gfx {
            gfx.surface.window.request_redraw();
        }
    }
}

#[cfg(test)]
mod tests;
