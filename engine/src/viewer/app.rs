//! The winit application: window events in, one rendered frame per redraw out.

use std::sync::Arc;
use std::time::Instant;

use citywalk_scenes::City;
use image::RgbaImage;
use winit::application::ApplicationHandler;
use winit::dpi::PhysicalSize;
use winit::event::{DeviceEvent, DeviceId, ElementState, MouseButton, WindowEvent};
use winit::event_loop::ActiveEventLoop;
use winit::keyboard::PhysicalKey;
use winit::window::{CursorGrabMode, Window, WindowId};

use super::input::{Command, InputTracker, KEY_HELP};
use super::screenshot::{ScreenshotError, to_rgba_image};
use super::surface::{Acquired, WindowSurface};
use super::{ViewerError, ViewerOptions};
use crate::camera::Camera;
use crate::controller::{CameraRig, CollisionWorld};
use crate::render::targets::read_texture;
use crate::render::{BruteRenderer, OffscreenTarget};
use crate::scene_gpu::SceneGpu;

/// Longest time step fed to the controllers (seconds): a stall does not teleport the walker.
const MAX_DT_S: f32 = 0.25;
/// How often the title bar is refreshed (seconds).
const TITLE_PERIOD_S: f32 = 0.5;

pub(super) struct App {
    city: City,
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
}

/// Everything that exists only while there is a window.
struct Graphics {
    surface: WindowSurface,
    renderer: BruteRenderer,
    scene: SceneGpu,
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
    pub(super) fn new(city: City, options: ViewerOptions) -> App {
        let world = CollisionWorld::from_city(&city);
        let rig = CameraRig::for_city(&city, &world, options.mode);
        tracing::info!(
            buildings = city.buildings.len(),
            walls = world.wall_count(),
            start = %rig.camera().to_arg_string(),
            "viewer ready; {KEY_HELP}"
        );
        App {
            city,
            world,
            rig,
            options,
            input: InputTracker::default(),
            look: MouseLook::default(),
            gfx: None,
            last_frame: Instant::now(),
            fps: FpsCounter::default(),
            frames_drawn: 0,
            screenshot_taken: false,
            error: None,
        }
    }

    /// The outcome once the event loop has returned.
    pub(super) fn finish(self) -> Result<(), ViewerError> {
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

    fn fail(&mut self, event_loop: &ActiveEventLoop, error: ViewerError) {
        tracing::error!("{error}");
        self.error.get_or_insert(error);
        event_loop.exit();
    }

    fn create_graphics(&self, event_loop: &ActiveEventLoop) -> Result<Graphics, ViewerError> {
        let (width, height) = self.options.size_px;
        let attributes = Window::default_attributes()
            .with_title(format!("citywalk — {}", self.options.title))
            .with_inner_size(PhysicalSize::new(width.max(1), height.max(1)));
        let window = Arc::new(event_loop.create_window(attributes)?);
        let surface = WindowSurface::new(window, self.options.screenshot.is_some())?;
        let renderer = BruteRenderer::new(&surface.gpu, surface.config.format);
        let scene = SceneGpu::upload_city(&surface.gpu, &self.city);
        Ok(Graphics {
            surface,
            renderer,
            scene,
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
        }
    }

    /// One frame: advance the camera, draw, present; in screenshot mode save the last frame.
    fn redraw(&mut self, event_loop: &ActiveEventLoop) -> Result<(), ViewerError> {
        let now = Instant::now();
        let dt_s = (now - self.last_frame).as_secs_f32().min(MAX_DT_S);
        self.last_frame = now;
        self.rig.update(dt_s, &self.input.take(), &self.world);
        let camera = self.rig.camera();

        let Some(gfx) = &mut self.gfx else {
            return Ok(());
        };
        let Acquired::Frame(frame) = gfx.surface.acquire()? else {
            return Ok(());
        };
        gfx.draw(&frame.texture, &camera);
        self.frames_drawn += 1;
        let shot = (self.options.screenshot.as_ref())
            .filter(|shot| !self.screenshot_taken && self.frames_drawn >= shot.frames);
        if let Some(shot) = shot {
            let image = gfx.capture(&frame.texture, &camera)?;
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

        if let Some(fps) = self.fps.tick(now) {
            gfx.surface
                .window
                .set_title(&status_line(&self.options.title, &self.rig, fps));
        }
        Ok(())
    }
}

impl Graphics {
    /// Draws the scene from `camera` into the surface texture.
    fn draw(&self, target: &wgpu::Texture, camera: &Camera) {
        let gpu = &self.surface.gpu;
        let view = target.create_view(&wgpu::TextureViewDescriptor::default());
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("viewer frame"),
            });
        self.renderer.encode(
            gpu,
            &mut encoder,
            &self.scene,
            camera,
            &view,
            self.surface.depth(),
        );
        gpu.queue.submit([encoder.finish()]);
    }

    /// The frame just drawn into `target`, read back before it is presented; where the surface
    /// cannot be copied from, the same view drawn again offscreen.
    fn capture(
        &self,
        target: &wgpu::Texture,
        camera: &Camera,
    ) -> Result<RgbaImage, ScreenshotError> {
        let gpu = &self.surface.gpu;
        let (width, height, format) = (target.width(), target.height(), target.format());
        let texels = if self.surface.copyable {
            read_texture(gpu, target, width, height)?
        } else {
            let offscreen = OffscreenTarget::new(gpu, width, height, format)?;
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("viewer screenshot"),
                });
            self.renderer.encode(
                gpu,
                &mut encoder,
                &self.scene,
                camera,
                &offscreen.colour_view,
                &offscreen.depth,
            );
            gpu.queue.submit([encoder.finish()]);
            offscreen.read_colour(gpu)?
        };
        to_rgba_image(texels, width, height, format)
    }
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
