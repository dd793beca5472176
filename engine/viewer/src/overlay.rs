//! The on-screen overlay: an egui panel with the frame statistics and the viewer's controls,
//! drawn over the scene into the same colour target.
//!
//! Two halves: [`OverlayStats`] / [`OverlayControls`] / [`RenderSettings`] and [`panel`] (what
//! is shown and edited, plain data and egui calls, no GPU), and [`Overlay`] (egui-winit input
//! and the egui-wgpu painter). The panel shows the counts of each culling stage that ran, the
//! stage toggles, the LOD criterion with its ε / τ / δh / δa sliders and the debug view; only
//! numbers the renderer really measured are shown.

use std::sync::Arc;

use glam::Vec3;
use winit::event::WindowEvent;
use winit::window::Window;

use super::settings::{CriterionKind, DebugView, LodSettings, RenderSettings, SceneFeatures};
use citywalk_runtime::cluster_textures::{ClusterShading, TextureResidency};
use citywalk_runtime::gpu::GpuContext;

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
    /// Buildings and triangles in the scene.
    pub buildings_total: usize,
    pub triangles_total: usize,
    /// What the frame measured, stage by stage.
    pub counts: StageCounts,
    /// What the scene offers (stages it lacks are shown disabled).
    pub features: SceneFeatures,
    /// Poses recorded so far, while recording.
    pub recording_poses: Option<usize>,
    /// (pose shown, pose count) while playing a path.
    pub playback: Option<(usize, usize)>,
    /// The panel rows of the building or cluster mesh picked with a left click.
    pub picked: Option<Vec<(String, String)>>,
}

/// Counts of one frame, per culling stage; `None` for a stage that did not run.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct StageCounts {
    /// Which frame drew (e.g. "LOD cut + two-phase HiZ culling").
    pub renderer: String,
    /// Culled by the frustum (or B-Quadtree, or left out of the LOD cut): buildings, or
    /// candidates of the HZB frame.
    pub frustum_culled: Option<u32>,
    /// Candidates in the frustum hidden behind the depth pyramid.
    pub occlusion_culled: Option<u32>,
    /// Buildings drawn, themselves or through a drawn cluster.
    pub buildings_drawn: u32,
    /// Cluster meshes drawn (with LOD).
    pub clusters_drawn: Option<u32>,
    /// The cluster textures' residency (a package with them, LOD on).
    pub textures: Option<TextureResidency>,
    /// Triangles of the drawn buildings and clusters.
    pub triangles: u64,
    /// Non-empty draws issued.
    pub draw_calls: u32,
    /// Streets and ground areas drawn: chunk draws and triangles (not in `triangles`).
    pub surfaces: (u32, u64),
    /// Virtual occluders drawn into the pyramid's depth (with the pre-pass).
    pub occluders_drawn: Option<u32>,
    /// Last frame's visible candidates the occluder gate kept out of the early pass (with the
    /// gate).
    pub gate_culled: Option<u32>,
    /// CPU time of the frame: selection, recording, submission, waiting for the GPU (ms).
    pub cpu_ms: f64,
    /// GPU time per phase (ms), where the frame measured it.
    pub gpu_ms: Vec<(String, f64)>,
    /// What the debug view shows (e.g. "pyramid level 3 of 11 (160×90)").
    pub debug: Option<String>,
}

/// What the user did in the panel this frame (the render settings are edited in place).
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OverlayControls {
    /// The field of view slider (degrees); applied to the controllers' cameras.
    pub fov_y_deg: f32,
    /// "walk / fly" was clicked.
    pub toggle_mode: bool,
    /// "record" / "stop recording" was clicked.
    pub toggle_recording: bool,
}

/// Narrowest and widest field of view the slider offers (degrees).
const FOV_RANGE_DEG: std::ops::RangeInclusive<f32> = 20.0..=120.0;

/// The highest pyramid level the slider offers (a 65536-pixel viewport has 17 levels).
const MAX_MIP_LEVEL: u32 = 16;

/// The panel's contents: the statistics, the camera controls, and `settings` (stages, LOD
/// criterion and tolerances, debug view) edited in place.
pub fn panel(
    ui: &mut egui::Ui,
    stats: &OverlayStats,
    settings: &mut RenderSettings,
    controls: &mut OverlayControls,
) {
    stats_grid(ui, stats);
    ui.separator();
    picked_grid(ui, stats.picked.as_deref());
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
    ui.add(egui::Slider::new(&mut controls.fov_y_deg, FOV_RANGE_DEG).text("fov y (°)"));
    ui.separator();
    stage_toggles(ui, stats.features, settings);
    ui.separator();
    lod_controls(ui, stats.features, settings);
    ui.separator();
    debug_controls(ui, settings);
    ui.label("H hides this panel");
}

fn picked_grid(ui: &mut egui::Ui, picked: Option<&[(String, String)]>) {
    let Some(rows) = picked else {
        ui.label("left click a building to inspect it");
        return;
    };
    egui::Grid::new("citywalk picked")
        .num_columns(2)
        .striped(true)
        .show(ui, |ui| {
            for (name, value) in rows {
                ui.label(name);
                ui.monospace(value);
                ui.end_row();
            }
        });
}

fn stats_grid(ui: &mut egui::Ui, stats: &OverlayStats) {
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
            let c = &stats.counts;
            row("renderer", c.renderer.clone());
            if let Some(n) = c.frustum_culled {
                row("frustum-culled", n.to_string());
            }
            if let Some(n) = c.occlusion_culled {
                row("occlusion-culled", n.to_string());
            }
            row(
                "buildings",
                format!("{} / {}", c.buildings_drawn, stats.buildings_total),
            );
            if let Some(n) = c.clusters_drawn {
                row("clusters", n.to_string());
            }
            if let Some(t) = &c.textures {
                row(
                    "cluster textures",
                    format!(
                        "{} of {} page views resident ({:.0} MiB), {} loading, {} evicted{}",
                        t.resident,
                        t.layers,
                        t.resident_mib,
                        t.loading,
                        t.evictions,
                        match t.shading {
                            ClusterShading::Textured => "",
                            ClusterShading::Flat => " (off)",
                            ClusterShading::Bins => " (bins view)",
                        }
                    ),
                );
            }
            row(
                "triangles",
                format!("{} / {}", c.triangles, stats.triangles_total),
            );
            row("draw calls", c.draw_calls.to_string());
            if c.surfaces.0 > 0 {
                row(
                    "streets, ground areas",
                    format!("{} chunks, {} triangles", c.surfaces.0, c.surfaces.1),
                );
            }
            if let Some(n) = c.occluders_drawn {
                row("occluders drawn", n.to_string());
            }
            if let Some(n) = c.gate_culled {
                row("kept out by the gate", n.to_string());
            }
            row("frame cpu", format!("{:.2} ms", c.cpu_ms));
            for (phase, ms) in &c.gpu_ms {
                row(&format!("gpu {phase}"), format!("{ms:.3} ms"));
            }
            if let Some(debug) = &c.debug {
                row("debug view", debug.clone());
            }
            if let Some((shown, count)) = stats.playback {
                row("path", format!("pose {} / {count}", shown + 1));
            }
        });
}

fn stage_toggles(ui: &mut egui::Ui, features: SceneFeatures, settings: &mut RenderSettings) {
    ui.checkbox(
        &mut settings.auto,
        "auto: stages by their measured cost (P)",
    );
    let manual = !settings.auto;
    let stages = &mut settings.stages;
    let frustum = if features.quadtree {
        "frustum / B-Quadtree (B)"
    } else {
        "frustum (B)"
    };
    ui.add_enabled(manual, egui::Checkbox::new(&mut stages.frustum, frustum));
    ui.add_enabled(
        manual,
        egui::Checkbox::new(&mut stages.hzb, "HZB occlusion culling (C)"),
    );
    ui.add_enabled(
        manual && stages.hzb && features.occluders,
        egui::Checkbox::new(&mut stages.occluders, "occluder pre-pass (V)"),
    );
    ui.add_enabled(
        manual && stages.hzb && stages.occluders && features.occluders,
        egui::Checkbox::new(
            &mut stages.occluder_gate,
            "occluder gate of the early set (N)",
        ),
    );
    ui.add_enabled(
        features.cluster_tree,
        egui::Checkbox::new(&mut stages.lod, "LOD cut (L)"),
    );
    if !features.cluster_tree {
        ui.label("(LOD needs a scene package with a cluster tree)");
    }
}

fn lod_controls(ui: &mut egui::Ui, features: SceneFeatures, settings: &mut RenderSettings) {
    let enabled = features.cluster_tree && settings.stages.lod;
    ui.add_enabled(
        enabled,
        egui::Checkbox::new(
            &mut settings.cluster_textures,
            "cluster textures (T; packages preprocessed with --cluster-textures)",
        ),
    );
    let lod = &mut settings.lod;
    ui.add_enabled_ui(enabled, |ui| {
        ui.horizontal(|ui| {
            ui.label("criterion (K)");
            ui.radio_value(&mut lod.kind, CriterionKind::Geometric, "geometric");
            ui.radio_value(&mut lod.kind, CriterionKind::Chang, "Chang");
            ui.radio_value(&mut lod.kind, CriterionKind::Yang, "Yang");
        });
        match lod.kind {
            CriterionKind::Geometric => {
                ui.add(slider(
                    &mut lod.tolerance_px,
                    LodSettings::TOLERANCE_RANGE_PX,
                    "tolerance (px)",
                ));
            }
            CriterionKind::Chang => {
                ui.add(slider(
                    &mut lod.epsilon_px,
                    LodSettings::EPSILON_RANGE_PX,
                    "ε (px)",
                ));
                ui.add(slider(&mut lod.tau_px, LodSettings::TAU_RANGE_PX, "τ (px)"));
            }
            CriterionKind::Yang => {
                ui.add(slider(
                    &mut lod.delta_h_px,
                    LodSettings::DELTA_H_RANGE_PX,
                    "δh (px)",
                ));
                ui.add(slider(
                    &mut lod.delta_a_px2,
                    LodSettings::DELTA_A_RANGE_PX2,
                    "δa (px²)",
                ));
            }
        }
        if ui.button("paper defaults").clicked() {
            *lod = LodSettings {
                kind: lod.kind,
                ..LodSettings::default()
            };
        }
    });
}

/// A logarithmic slider (tolerances span orders of magnitude).
fn slider<'a>(
    value: &'a mut f32,
    range: std::ops::RangeInclusive<f32>,
    text: &str,
) -> egui::Slider<'a> {
    egui::Slider::new(value, range).logarithmic(true).text(text)
}

fn debug_controls(ui: &mut egui::Ui, settings: &mut RenderSettings) {
    ui.horizontal(|ui| {
        ui.label("debug view (G)");
        for view in DebugView::ALL {
            ui.radio_value(&mut settings.debug_view, view, view.name());
        }
    });
    if settings.debug_view == DebugView::Pyramid {
        ui.add(egui::Slider::new(&mut settings.mip_level, 0..=MAX_MIP_LEVEL).text("level ([ ])"));
    }
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
    /// user did (settings changes are made in `settings`, for the next frame); nothing is drawn
    /// until [`Overlay::paint`].
    pub fn prepare(
        &mut self,
        gpu: &GpuContext,
        window: &Window,
        stats: &OverlayStats,
        settings: &mut RenderSettings,
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
                // As tall as the window allows; a smaller window scrolls the panel.
                let height = (ctx.content_rect().height() - 48.0).max(120.0);
                egui::Window::new("citywalk")
                    .anchor(egui::Align2::LEFT_TOP, [8.0, 8.0])
                    .resizable(false)
                    .vscroll(true)
                    .default_height(height)
                    .max_height(height)
                    .collapsible(true)
                    .show(ctx, |ui| panel(ui, stats, settings, &mut controls));
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

    /// Runs the panel headless (no window, no GPU) and returns the texts it laid out; the
    /// settings must come back unchanged (no input was given).
    fn texts(stats: &OverlayStats, settings: &RenderSettings) -> String {
        let context = egui::Context::default();
        let mut controls = OverlayControls {
            fov_y_deg: 60.0,
            ..OverlayControls::default()
        };
        let mut edited = *settings;
        let mut shown = String::new();
        // Two passes: egui lays out grids on the first and shows them on the second.
        for _ in 0..2 {
            let mut output = context.run_ui(egui::RawInput::default(), |ui| {
                panel(ui, stats, &mut edited, &mut controls)
            });
            // No painter here: the font atlas is not uploaded anywhere.
            output.textures_delta.clear();
            shown.clear();
            for clipped in &output.shapes {
                collect_text(&clipped.shape, &mut shown);
            }
        }
        assert!(!controls.toggle_mode && !controls.toggle_recording);
        assert_eq!(controls.fov_y_deg, 60.0);
        assert_eq!(&edited, settings, "no input, no change");
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

    fn assert_shows(shown: &str, wanted: &[&str]) {
        for want in wanted {
            assert!(shown.contains(want), "{want:?} not in the panel:\n{shown}");
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
            buildings_total: 9,
            triangles_total: 5000,
            counts: StageCounts {
                renderer: "brute force".into(),
                buildings_drawn: 7,
                triangles: 1234,
                draw_calls: 8,
                cpu_ms: 3.5,
                ..StageCounts::default()
            },
            features: SceneFeatures::default(),
            recording_poses: Some(42),
            playback: None,
            picked: Some(vec![("source id".into(), "way/123".into())]),
        };
        let plain = RenderSettings::default();
        let shown = texts(&stats, &plain);
        assert_shows(
            &shown,
            &[
                "59.5",
                "16.81 ms",
                "walk",
                "12.0, -3.5, 1.7 m",
                "7 / 9",
                "1234 / 5000",
                "brute force",
                "3.50 ms",
                "stop recording (42 poses) (R)",
                "way/123",
                "fly (F)",
                "frustum (B)",
                "HZB occlusion culling (C)",
                "LOD needs a scene package",
                "debug view (G)",
            ],
        );
        assert!(
            !shown.contains("frustum-culled") && !shown.contains("occluders drawn"),
            "no counts of stages that did not run:\n{shown}"
        );
        let playing = texts(
            &OverlayStats {
                mode: "path".into(),
                recording_poses: None,
                playback: Some((4, 60)),
                ..stats.clone()
            },
            &plain,
        );
        assert_shows(&playing, &["pose 5 / 60", "record (R)"]);
        assert!(!playing.contains("(F)"), "no mode switch while playing");

        // A package frame with every stage: per-stage counts, GPU phases, the LOD sliders.
        let package = SceneFeatures {
            occluders: true,
            cluster_tree: true,
            quadtree: true,
        };
        let all = RenderSettings {
            stages: super::super::settings::FramePlan::ALL,
            debug_view: DebugView::Pyramid,
            mip_level: 3,
            ..plain
        };
        let culled = texts(
            &OverlayStats {
                buildings_total: 540,
                features: package,
                counts: StageCounts {
                    renderer: "LOD cut + HiZ culling + occluders".into(),
                    frustum_culled: Some(301),
                    occlusion_culled: Some(222),
                    buildings_drawn: 17,
                    clusters_drawn: Some(6),
                    textures: Some(TextureResidency {
                        resident: 12,
                        layers: 64,
                        resident_mib: 48.0,
                        evictions: 7,
                        ..TextureResidency::default()
                    }),
                    triangles: 98_765,
                    draw_calls: 19,
                    surfaces: (42, 4321),
                    occluders_drawn: Some(5),
                    gate_culled: Some(3),
                    cpu_ms: 1.25,
                    gpu_ms: vec![("late_pass".into(), 0.75)],
                    debug: Some("pyramid level 3 of 11 (160×90)".into()),
                },
                ..stats.clone()
            },
            &all,
        );
        assert_shows(
            &culled,
            &[
                "frustum-culled",
                "301",
                "occlusion-culled",
                "222",
                "17 / 540",
                "clusters",
                "12 of 64 page views resident (48 MiB), 0 loading, 7 evicted",
                "98765",
                "19",
                "streets, ground areas",
                "42 chunks, 4321 triangles",
                "occluders drawn",
                "kept out by the gate",
                "1.25 ms",
                "gpu late_pass",
                "0.750 ms",
                "pyramid level 3 of 11",
                "frustum / B-Quadtree (B)",
                "occluder pre-pass (V)",
                "occluder gate of the early set (N)",
                "LOD cut (L)",
                "geometric",
                "Chang",
                "Yang",
                "tolerance (px)",
                "level ([ ])",
            ],
        );
        let yang = texts(
            &OverlayStats {
                features: package,
                ..stats
            },
            &RenderSettings {
                stages: super::super::settings::FramePlan::ALL,
                lod: LodSettings {
                    kind: CriterionKind::Yang,
                    ..LodSettings::default()
                },
                ..plain
            },
        );
        assert_shows(&yang, &["δh (px)", "δa (px²)"]);
        assert!(!yang.contains("ε (px)"), "{yang}");
    }
}
