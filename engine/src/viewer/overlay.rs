//! The on-screen overlay: an egui panel with the frame statistics and the viewer's controls,
//! drawn over the scene into the same colour target.
//!
//! Two halves: [`OverlayStats`] / [`OverlayControls`] and [`panel`] (what is shown, plain data
//! and egui calls, no GPU), and [`Overlay`] (egui-winit input and the egui-wgpu painter).
//! To show more (the culling stages' counts, their ε / τ / δh / δa sliders and stage toggles),
//! add fields to [`OverlayStats`] / [`OverlayControls`] and a section to [`panel`]; only show
//! numbers the renderer really measured.

use std::sync::Arc;

use glam::Vec3;
use winit::event::WindowEvent;
use winit::window::Window;

use crate::gpu::GpuContext;

/// What the panel reports for the frame just drawn.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OverlayStats {
    /// Frames per second over the last measuring period (`None` until the first period ends).
    pub fps: Option<f32>,
    /// CPU time between the last two frames (milliseconds).
    pub frame_ms: f32,
    /// `walk`, `fly` or `path` (playing a path).
    pub mode: String,
    pub position_m: Vec3,
    pub yaw_deg: f32,
    pub pitch_deg: f32,
    /// Buildings submitted for drawing this frame, and in the scene.
    pub buildings_drawn: usize,
    pub buildings_total: usize,
    /// Triangles submitted for drawing this frame.
    pub triangles_drawn: usize,
    /// Which renderer drew the frame (e.g. "brute force, no culling").
    pub renderer: String,
    /// The culling frame's measured counts, when the culling renderer drew the frame.
    pub culling: Option<CullingCounts>,
    /// Whether the culling renderer is on (the checkbox's state).
    pub culling_on: bool,
    /// Whether the occluder pre-pass is on; `None` when the scene has no occluders.
    pub occluders_on: Option<bool>,
    /// Poses recorded so far, while recording.
    pub recording_poses: Option<usize>,
    /// (pose shown, pose count) while playing a path.
    pub playback: Option<(usize, usize)>,
}

/// Counts measured by the culling renderer for one frame ([`crate::frame::FrameStats`]).
#[derive(Debug, Clone, Copy, Default, PartialEq)]
pub struct CullingCounts {
    /// Buildings outside the view frustum.
    pub frustum_culled: u32,
    /// Buildings in the frustum hidden behind the depth pyramid.
    pub occlusion_culled: u32,
    /// Buildings drawn (early and late pass).
    pub drawn: u32,
    /// Triangles of the buildings drawn.
    pub triangles: u64,
    /// Non-empty draws issued.
    pub draw_calls: u32,
    /// Virtual occluders drawn into the pyramid's depth.
    pub occluders_drawn: u32,
    /// CPU time of the frame (encoding, waiting for the GPU, reading the status back).
    pub cpu_ms: f64,
}

/// What the user changed in the panel this frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OverlayControls {
    /// The field of view slider (degrees); applied to the controllers' cameras.
    pub fov_y_deg: f32,
    /// "walk / fly" was clicked.
    pub toggle_mode: bool,
    /// "record" / "stop recording" was clicked.
    pub toggle_recording: bool,
    /// The "occlusion culling" checkbox was clicked.
    pub toggle_culling: bool,
    /// The "occluder pre-pass" checkbox was clicked.
    pub toggle_occluders: bool,
}

/// Narrowest and widest field of view the slider offers (degrees).
const FOV_RANGE_DEG: std::ops::RangeInclusive<f32> = 20.0..=120.0;

/// The panel's contents.
pub fn panel(ui: &mut egui::Ui, stats: &OverlayStats, controls: &mut OverlayControls) {
    egui::Grid::new("citywalk stats")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            let mut row = |name: &str, value: String| {
                ui.label(name);
                ui.monospace(value);
                ui.end_row();
            };
            row(
                "fps",
                stats
                    .fps
                    .map_or_else(|| "…".to_string(), |f| format!("{f:.1}")),
            );
            row("frame", format!("{:.2} ms", stats.frame_ms));
            row("mode", stats.mode.clone());
            let p = stats.position_m;
            row("position", format!("{:.1}, {:.1}, {:.1} m", p.x, p.y, p.z));
            row(
                "yaw / pitch",
                format!("{:.1}° / {:.1}°", stats.yaw_deg, stats.pitch_deg),
            );
            row(
                "buildings",
                format!("{} / {}", stats.buildings_drawn, stats.buildings_total),
            );
            row("triangles", stats.triangles_drawn.to_string());
            row("renderer", stats.renderer.clone());
            if let Some(c) = &stats.culling {
                row("frustum-culled", c.frustum_culled.to_string());
                row("occlusion-culled", c.occlusion_culled.to_string());
                row("draw calls", c.draw_calls.to_string());
                row("occluders drawn", c.occluders_drawn.to_string());
                row("culling cpu", format!("{:.2} ms", c.cpu_ms));
            }
            if let Some((shown, count)) = stats.playback {
                row("path", format!("pose {} / {count}", shown + 1));
            }
        });
    ui.separator();
    ui.horizontal(|ui| {
        if stats.playback.is_none() {
            let other = if stats.mode == "walk" { "fly" } else { "walk" };
            controls.toggle_mode = ui.button(format!("{other} (F)")).clicked();
        }
        let record = match stats.recording_poses {
            Some(n) => format!("stop recording ({n} poses) (R)"),
            None => "record (R)".to_string(),
        };
        controls.toggle_recording = ui.button(record).clicked();
    });
    let mut culling = stats.culling_on;
    controls.toggle_culling = ui.checkbox(&mut culling, "occlusion culling (C)").clicked();
    if let Some(on) = stats.occluders_on {
        let mut occluders = on;
        controls.toggle_occluders = ui
            .add_enabled(
                stats.culling_on,
                egui::Checkbox::new(&mut occluders, "occluder pre-pass (V)"),
            )
            .clicked();
    }
    ui.add(egui::Slider::new(&mut controls.fov_y_deg, FOV_RANGE_DEG).text("fov y (°)"));
    ui.label("H hides this panel");
}

/// egui state for one window and the painter for its surface format.
pub struct Overlay {
    context: egui::Context,
    input: egui_winit::State,
    painter: egui_wgpu::Renderer,
    /// The last frame's triangles, kept so a screenshot can paint them again offscreen.
    primitives: Vec<egui::ClippedPrimitive>,
    pixels_per_point: f32,
    /// Whether the panel is shown (H toggles).
    pub visible: bool,
}

impl std::fmt::Debug for Overlay {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Overlay")
            .field("visible", &self.visible)
            .field("primitives", &self.primitives.len())
            .finish_non_exhaustive()
    }
}

impl Overlay {
    /// An overlay for `window`, painting into targets of `format`.
    pub fn new(
        gpu: &GpuContext,
        window: &Arc<Window>,
        format: wgpu::TextureFormat,
        visible: bool,
    ) -> Overlay {
        let context = egui::Context::default();
        let max_side = gpu.device.limits().max_texture_dimension_2d as usize;
        let input = egui_winit::State::new(
            context.clone(),
            egui::ViewportId::ROOT,
            window.as_ref(),
            Some(window.scale_factor() as f32),
            window.theme(),
            Some(max_side),
        );
        let painter =
            egui_wgpu::Renderer::new(&gpu.device, format, egui_wgpu::RendererOptions::default());
        Overlay {
            context,
            input,
            painter,
            primitives: Vec::new(),
            pixels_per_point: 1.0,
            visible,
        }
    }

    /// Feeds a window event to egui; true when egui wants it for itself (a click on the panel).
    pub fn window_event(&mut self, window: &Window, event: &WindowEvent) -> bool {
        let response = self.input.on_window_event(window, event);
        self.visible && response.consumed
    }

    /// Whether egui has keyboard focus (then the viewer's keys are left alone).
    pub fn wants_keyboard(&self) -> bool {
        self.visible && self.context.egui_wants_keyboard_input()
    }

    /// Lays out the panel for this frame and uploads what changed (font atlas). Returns what the
    /// user did; nothing is drawn until [`Overlay::paint`].
    pub fn prepare(
        &mut self,
        gpu: &GpuContext,
        window: &Window,
        stats: &OverlayStats,
        fov_y_deg: f32,
    ) -> OverlayControls {
        let mut controls = OverlayControls {
            fov_y_deg,
            ..OverlayControls::default()
        };
        let raw = self.input.take_egui_input(window);
        let visible = self.visible;
        let mut output = self.context.run_pass(raw, |ctx| {
            if visible {
                egui::Window::new("citywalk")
                    .anchor(egui::Align2::LEFT_TOP, [8.0, 8.0])
                    .resizable(false)
                    .collapsible(true)
                    .show(ctx, |ui| panel(ui, stats, &mut controls));
            }
        });
        self.input
            .handle_platform_output(window, output.platform_output);
        for (id, deltas) in &output.textures_delta.set {
            for delta in deltas {
                self.painter
                    .update_texture(&gpu.device, &gpu.queue, *id, delta);
            }
        }
        for id in &output.textures_delta.free {
            self.painter.free_texture(id);
        }
        // Applied above; egui checks that no delta is dropped unapplied.
        output.textures_delta.clear();
        self.pixels_per_point = output.pixels_per_point;
        self.primitives = self
            .context
            .tessellate(output.shapes, output.pixels_per_point);
        controls
    }

    /// Draws the prepared panel over `target` (`width × height`, the overlay's format).
    pub fn paint(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        target: &wgpu::TextureView,
        width: u32,
        height: u32,
    ) {
        if self.primitives.is_empty() {
            return;
        }
        let screen = egui_wgpu::ScreenDescriptor {
            size_in_pixels: [width, height],
            pixels_per_point: self.pixels_per_point,
        };
        let extra = self.painter.update_buffers(
            &gpu.device,
            &gpu.queue,
            encoder,
            &self.primitives,
            &screen,
        );
        if !extra.is_empty() {
            gpu.queue.submit(extra);
        }
        let pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("overlay"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: target,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: None,
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        self.painter
            .render(&mut pass.forget_lifetime(), &self.primitives, &screen);
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Runs the panel headless (no window, no GPU) and returns the texts it laid out.
    fn texts(stats: &OverlayStats) -> String {
        let context = egui::Context::default();
        let mut controls = OverlayControls {
            fov_y_deg: 60.0,
            ..OverlayControls::default()
        };
        let mut shown = String::new();
        // Two passes: egui lays out grids on the first and shows them on the second.
        for _ in 0..2 {
            let mut output = context.run_ui(egui::RawInput::default(), |ui| {
                panel(ui, stats, &mut controls)
            });
            // No painter here: the font atlas is not uploaded anywhere.
            output.textures_delta.clear();
            shown.clear();
            for clipped in &output.shapes {
                collect_text(&clipped.shape, &mut shown);
            }
        }
        assert!(!controls.toggle_mode && !controls.toggle_recording);
        assert!(!controls.toggle_culling && !controls.toggle_occluders);
        assert_eq!(controls.fov_y_deg, 60.0);
        shown
    }

    fn collect_text(shape: &egui::Shape, out: &mut String) {
        match shape {
            egui::Shape::Text(t) => {
                out.push_str(t.galley.text());
                out.push('\n');
            }
            egui::Shape::Vec(shapes) => shapes.iter().for_each(|s| collect_text(s, out)),
            _ => {}
        }
    }

    #[test]
    fn the_panel_shows_the_stats_it_is_given() {
        let stats = OverlayStats {
            fps: Some(59.5),
            frame_ms: 16.81,
            mode: "walk".into(),
            position_m: Vec3::new(12.0, -3.5, 1.7),
            yaw_deg: 90.0,
            pitch_deg: -5.0,
            buildings_drawn: 7,
            buildings_total: 9,
            triangles_drawn: 1234,
            renderer: "brute force".into(),
            culling: None,
            culling_on: false,
            occluders_on: None,
            recording_poses: Some(42),
            playback: None,
        };
        let shown = texts(&stats);
        for want in [
            "59.5",
            "16.81 ms",
            "walk",
            "12.0, -3.5, 1.7 m",
            "7 / 9",
            "1234",
            "brute force",
            "stop recording (42 poses) (R)",
            "fly (F)",
        ] {
            assert!(shown.contains(want), "{want:?} not in the panel:\n{shown}");
        }
        let playing = texts(&OverlayStats {
            mode: "path".into(),
            recording_poses: None,
            playback: Some((4, 60)),
            ..stats.clone()
        });
        assert!(playing.contains("pose 5 / 60"), "{playing}");
        assert!(
            !playing.contains("frustum-culled") && !playing.contains("occluder pre-pass"),
            "no culling counts without the culling renderer:\n{playing}"
        );
        let culled = texts(&OverlayStats {
            renderer: "two-phase HiZ culling".into(),
            buildings_drawn: 17,
            buildings_total: 540,
            triangles_drawn: 98_765,
            culling: Some(CullingCounts {
                frustum_culled: 301,
                occlusion_culled: 222,
                drawn: 17,
                triangles: 98_765,
                draw_calls: 19,
                occluders_drawn: 5,
                cpu_ms: 1.25,
            }),
            culling_on: true,
            occluders_on: Some(true),
            ..stats
        });
        for want in [
            "frustum-culled",
            "301",
            "occlusion-culled",
            "222",
            "17 / 540",
            "98765",
            "19",
            "occluders drawn",
            "1.25 ms",
            "occlusion culling (C)",
            "occluder pre-pass (V)",
        ] {
            assert!(
                culled.contains(want),
                "{want:?} not in the panel:\n{culled}"
            );
        }
        assert!(playing.contains("record (R)"), "{playing}");
        assert!(
            !playing.contains("(F)"),
            "no mode switch while playing:\n{playing}"
        );
    }
}
