//! Runs camera paths through every culling mode, checking every frame against the exact
//! ID-buffer oracle and measuring cost and image error against the brute-force frame.

use std::path::PathBuf;
use std::time::Instant;

use citywalk_scenes::camera_path::CameraPath;
use citywalk_scenes::city_sphere::CitySphere;

use crate::bound::EdgeDistance;
use crate::mode::Mode;
use crate::pixel_error::pixel_error;
use citywalk_runtime::auto::AutoPlanner;
use citywalk_runtime::camera::Camera;
use citywalk_runtime::cluster_textures::ClusterShading;
use citywalk_runtime::cpu_clock::CpuClock;
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::frame::Visibility;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::gpu_timer::{GpuTimer, GpuTimes};
use citywalk_runtime::lod::LodCriterion;
use citywalk_runtime::oracle::{IdImage, Oracle, VisibleSet};
use citywalk_runtime::render::selected::SelectedRenderer;
use citywalk_runtime::render::targets::{OffscreenTarget, ReadbackError};
use citywalk_runtime::render::{BruteRenderer, GroundSurfacePass, SurfaceMeshes};
pub use citywalk_runtime::runner::DRAW_PHASES;
use citywalk_runtime::runner::{Completion, FrameRunner, FrameTarget};

/// One scene ready for benchmarking: its geometry on the GPU and its culling structures.
#[derive(Debug)]
pub struct BenchScene {
    pub name: String,
    /// The buildings, and the cluster tree's LOD scene (`lod` mode), blocks and quadtree
    /// (`quadtree` mode) and virtual occluders (`occluders` mode) where the scene has them.
    pub drawable: DrawableScene,
    /// The city's sphere ([`CitySphere::of`] its buildings), the one the generated paths are
    /// built around: the unit of the far views ([`crate::far`]).
    pub sphere: CitySphere,
}

/// What to measure.
#[derive(Debug, Clone)]
pub struct BenchConfig {
    pub modes: Vec<Mode>,
    pub width: u32,
    pub height: u32,
    /// Where to write PNG frames (every `png_every`-th frame of each path and mode), if at all.
    pub frames_dir: Option<PathBuf>,
    pub png_every: usize,
}

/// The measurements of one frame in one mode.
#[derive(Debug, Clone, PartialEq, serde::Serialize)]
pub struct FrameRecord {
    pub scene: String,
    pub path: String,
    pub mode: String,
    pub frame: usize,
    /// Buildings with at least one visible pixel in the full-detail, unculled scene.
    pub visible: usize,
    /// Buildings drawn, themselves or (`lod`, `all`) through a drawn cluster containing them.
    pub drawn: usize,
    /// Cluster meshes of the LOD cut drawn (`lod`, `all`; 0 in the other modes).
    pub clusters: usize,
    /// Visible buildings that were not drawn. Must be zero.
    pub false_culls: usize,
    /// Share of the scene's buildings not drawn.
    pub culled_fraction: f64,
    pub triangles: u64,
    /// `triangles` ÷ the scene's triangles at full detail ([`crate::far::triangle_share`]).
    pub triangle_share: f64,
    /// The camera's distance from the centre of the scene's buildings, in diameters of their
    /// bounding box ([`crate::far::distance_in_diameters`]); beyond 1 the frame is a far view.
    pub distance_diameters: f64,
    pub draw_calls: u32,
    /// CPU time of the culling selection (ms).
    pub select_ms: f64,
    /// CPU wall time of selection, recording, submission and GPU completion (ms).
    pub frame_ms: f64,
    /// The engine's own CPU time: thread CPU time ([`citywalk_runtime::cpu_clock`]) of the mode's selection
    /// (frustum test, quadtree, LOD cut), recording and submission, without the wait for the GPU
    /// (ms). For the two-phase modes the frame's share is its own
    /// [`citywalk_runtime::frame::FrameStats::cpu_ms`].
    pub cpu_ms: f64,
    /// Chang et al. §9: share of pixels whose grey level differs from the brute-force frame.
    pub pixel_error_grey: f64,
    /// Chang et al. §9: share of pixels differing by more than 40 in a channel.
    pub pixel_error_colour: f64,
    /// The frame's pixel bound (px): the LOD criterion's tolerance + 1 ([`crate::bound`]).
    pub bound_px: f32,
    /// Pixels whose grey level differs from the brute-force frame (the count behind
    /// `pixel_error_grey`).
    pub differing_px: u64,
    /// Of them, those farther than `bound_px` from every edge of the brute-force frame.
    pub beyond_bound_px: u64,
    /// GPU time per phase from timestamp queries: `draw` for the single-pass modes, the
    /// two-phase frame's phases ([`citywalk_runtime::gpu_timer::FRAME_PHASES`]) for the HiZ modes; every
    /// phase `None` when the adapter has no timestamps, and no phases for an untimed frame.
    pub gpu: GpuTimes,
}

impl FrameRecord {
    /// The frame's differing pixels and those beyond the bound.
    pub fn bound_check(&self) -> crate::bound::BoundCheck {
        crate::bound::BoundCheck {
            differing: self.differing_px,
            beyond: self.beyond_bound_px,
        }
    }
}

/// Why a benchmark run stopped.
#[derive(Debug, thiserror::Error)]
pub enum BenchError {
    #[error("reading a frame back from the GPU failed: {0}")]
    Readback(ReadbackError),
    #[error("mode '{0}' is not implemented yet")]
    ModeNotAvailable(Mode),
    #[error("modes 'lod' and 'all' need the scene's cluster tree, and scene '{0}' has none")]
    NoClusterTree(String),
    #[error(
        "modes 'occluders' and 'all' need the scene's virtual occluders, and scene '{0}' has none"
    )]
    NoOccluders(String),
    #[error("rendering a culled frame failed: {0}")]
    Frame(citywalk_runtime::frame::FrameError),
    #[error("writing {path}: {reason}")]
    Write { path: PathBuf, reason: String },
    #[error("{0}; the benchmark stops")]
    DeviceLost(#[from] citywalk_runtime::gpu::DeviceLost),
}

/// A frame or readback that failed because the device went is the device's loss, said once.
impl From<citywalk_runtime::frame::FrameError> for BenchError {
    fn from(error: citywalk_runtime::frame::FrameError) -> Self {
        use citywalk_runtime::frame::FrameError;
        match error {
            FrameError::DeviceLost(lost)
            | FrameError::Readback(ReadbackError::DeviceLost(lost)) => BenchError::DeviceLost(lost),
            other => BenchError::Frame(other),
        }
    }
}

impl From<ReadbackError> for BenchError {
    fn from(error: ReadbackError) -> Self {
        match error {
            ReadbackError::DeviceLost(lost) => BenchError::DeviceLost(lost),
            other => BenchError::Readback(other),
        }
    }
}

/// The renderers a run reuses across frames.
#[derive(Debug)]
pub struct BenchRenderers {
    brute: BruteRenderer,
    selected: SelectedRenderer,
    oracle: Oracle,
    /// The streets and ground areas over the frames not drawn by the frame runner (the
    /// reference, `oracle`), as the runner draws them over its own.
    surfaces: GroundSurfacePass,
    /// Every mode with a frame plan runs through it, with each mode's visible set carried from
    /// frame to frame along a path.
    runner: FrameRunner,
    visibility: std::collections::HashMap<Mode, Visibility>,
    /// Times the scene pass of `oracle` and the test-only mode ([`DRAW_PHASES`]).
    timer: GpuTimer,
    /// The GPU times of the frame [`render_mode`] rendered last.
    last_gpu: GpuTimes,
    /// The `auto` mode's planner along the current path.
    auto: Option<AutoPlanner>,
}

impl BenchRenderers {
    pub fn new(gpu: &GpuContext) -> BenchRenderers {
        BenchRenderers {
            brute: BruteRenderer::new(gpu, BruteRenderer::PNG_FORMAT),
            selected: SelectedRenderer::new(gpu, BruteRenderer::PNG_FORMAT),
            oracle: Oracle::new(gpu),
            surfaces: GroundSurfacePass::new(gpu, BruteRenderer::PNG_FORMAT),
            runner: FrameRunner::new(gpu, BruteRenderer::PNG_FORMAT),
            visibility: std::collections::HashMap::new(),
            timer: GpuTimer::new(gpu, "bench draw timer", DRAW_PHASES),
            last_gpu: GpuTimes::default(),
            auto: None,
        }
    }

    /// Records the ground-surface pass of `surfaces` (if any) over the frame in `target`.
    fn encode_surfaces(
        &self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        surfaces: Option<&SurfaceMeshes>,
        camera: &Camera,
        target: &OffscreenTarget,
    ) {
        if let Some(meshes) = surfaces {
            self.surfaces.encode(
                gpu,
                encoder,
                meshes,
                camera,
                (&target.colour_view, &target.depth),
                &self.brute.style,
            );
        }
    }

    /// Forgets every mode's last visible set (the start of a camera path).
    pub fn reset_visibility(&mut self) {
        self.visibility.clear();
    }

    /// The `auto` mode's planner of the last path run, with the costs it measured.
    pub fn auto_planner(&self) -> Option<&AutoPlanner> {
        self.auto.as_ref()
    }
}

/// The camera of a path pose.
pub fn pose_camera(path: &CameraPath, i: usize) -> Camera {
    let pose = path.poses[i];
    let mut camera = Camera::new(
        pose.position,
        pose.yaw_deg.to_radians(),
        pose.pitch_deg.to_radians(),
    );
    camera.fov_y_rad = path.fov_y_deg.to_radians();
    camera
}

/// What one mode did in one frame.
#[derive(Debug, Clone, PartialEq)]
struct ModeFrame {
    /// Buildings drawn, themselves or through a drawn cluster containing them, in id order.
    drawn: Vec<u32>,
    draw_calls: u32,
    /// Cluster meshes of the LOD cut drawn (`lod`, `all`; 0 otherwise).
    clusters: usize,
    select_ms: f64,
    frame_ms: f64,
    cpu_ms: f64,
    /// Triangles of the drawn buildings and clusters.
    triangles: u64,
}

/// Renders one frame of `mode` into `target`: through the frame runner with the mode's plan
/// ([`Mode::plan`]), waiting for it, or, for `oracle` (`visible`: the oracle's visible set of the
/// frame, in id order) and the test-only mode, as one plain pass of a selection. For `lod` and
/// `all`, a building counts as drawn when it is drawn itself or through a drawn cluster
/// containing it, and triangles are the buildings' and clusters'. The frame's GPU times are left
/// in `renderers.last_gpu`.
fn render_mode(
    gpu: &GpuContext,
    renderers: &mut BenchRenderers,
    scene: &BenchScene,
    mode: Mode,
    camera: &Camera,
    visible: &[u32],
    target: &OffscreenTarget,
) -> Result<ModeFrame, BenchError> {
    let refs = scene.drawable.refs();
    let plan = match (mode, mode.plan()) {
        (Mode::Auto, _) => renderers
            .auto
            .get_or_insert_with(|| AutoPlanner::new(refs.features(), refs.lod.is_some()))
            .plan_for(camera),
        (_, Some(plan)) => plan,
        (_, None) => return render_selection(gpu, renderers, scene, mode, camera, visible, target),
    };
    if plan.lod && refs.lod.is_none() {
        return Err(BenchError::NoClusterTree(scene.name.clone()));
    }
    if plan.occluders && refs.occluders.is_none() {
        return Err(BenchError::NoOccluders(scene.name.clone()));
    }
    if let Some(texturing) = scene.drawable.texturing() {
        texturing.set_shading(if mode == Mode::LodFlat {
            ClusterShading::Flat
        } else {
            ClusterShading::Textured
        });
    }
    let visibility = renderers.visibility.entry(mode).or_default();
    let report = renderers
        .runner
        .run(
            gpu,
            refs,
            plan,
            None,
            visibility,
            camera,
            FrameTarget::offscreen(target),
            (Completion::Wait, true),
        )?
        .expect("a waited frame has its report");
    if let (Mode::Auto, Some(planner)) = (mode, &mut renderers.auto) {
        planner.record(&report);
    }
    renderers.last_gpu = report.gpu.clone();
    Ok(ModeFrame {
        drawn: report.drawn.unwrap_or_default(),
        draw_calls: report.draw_calls,
        clusters: report.clusters_drawn.unwrap_or(0) as usize,
        select_ms: report.select_ms,
        frame_ms: report.frame_ms,
        cpu_ms: report.cpu_ms,
        triangles: report.triangles,
    })
}

/// One plain pass of a selection: `oracle` draws the oracle's `visible` set (the limit any
/// culling could reach), the test-only mode brute force minus the first visible building.
fn render_selection(
    gpu: &GpuContext,
    renderers: &mut BenchRenderers,
    scene: &BenchScene,
    mode: Mode,
    camera: &Camera,
    visible: &[u32],
    target: &OffscreenTarget,
) -> Result<ModeFrame, BenchError> {
    renderers.timer.begin_frame();
    let start = Instant::now();
    let cpu = CpuClock::start();
    let drawn: Vec<u32> = match mode {
        Mode::Oracle => visible.to_vec(),
        Mode::DropOneVisibleForTest => (0..scene.drawable.buildings.building_count() as u32)
            .filter(|&b| Some(b) != visible.first().copied())
            .collect(),
        _ => return Err(BenchError::ModeNotAvailable(mode)),
    };
    let select_ms = start.elapsed().as_secs_f64() * 1e3;
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("bench selection"),
        });
    let draw_calls = renderers.selected.encode_timed(
        gpu,
        &mut encoder,
        &scene.drawable.buildings,
        camera,
        &drawn,
        (&target.colour_view, &target.depth),
        renderers.timer.render_pass_writes("draw"),
    );
    renderers.encode_surfaces(
        gpu,
        &mut encoder,
        scene.drawable.surfaces.as_ref(),
        camera,
        target,
    );
    renderers.timer.resolve(&mut encoder);
    gpu.queue.submit([encoder.finish()]);
    let cpu_ms = cpu.elapsed_ms();
    gpu.wait_idle();
    let frame_ms = start.elapsed().as_secs_f64() * 1e3;
    renderers.last_gpu = renderers.timer.read(gpu)?;
    let triangles = drawn
        .iter()
        .filter_map(|&b| scene.drawable.buildings.records.get(b as usize))
        .map(|r| u64::from(r.index_count / 3))
        .sum();
    Ok(ModeFrame {
        drawn,
        draw_calls,
        clusters: 0,
        select_ms,
        frame_ms,
        cpu_ms,
        triangles,
    })
}

/// Frames each mode draws at a path's first pose before its frames are timed (the issue's "after
/// two warm-up frames"): the first compiles and sizes, the second starts from the first's
/// visible set.
const WARM_UP_FRAMES: u32 = 2;

/// Runs one path of one scene through every configured mode. Each mode renders the path's
/// first pose [`WARM_UP_FRAMES`] times before timing (shader compilation, buffer growth, the
/// first visible set).
pub fn run_path(
    gpu: &GpuContext,
    renderers: &mut BenchRenderers,
    scene: &BenchScene,
    path: &CameraPath,
    config: &BenchConfig,
) -> Result<Vec<FrameRecord>, BenchError> {
    let (w, h) = (config.width, config.height);
    let target = OffscreenTarget::new(gpu, w, h, BruteRenderer::PNG_FORMAT)?;
    let reference = OffscreenTarget::new(gpu, w, h, BruteRenderer::PNG_FORMAT)?;
    let total = scene.drawable.buildings.building_count();
    let mut records = Vec::new();
    if path.poses.is_empty() {
        return Ok(records);
    }
    let warm_camera = pose_camera(path, 0);
    let warm_ids = renderers
        .oracle
        .id_image(gpu, &scene.drawable.buildings, &warm_camera, w, h)?;
    let warm_visible = visible_of(scene, &warm_ids);
    // A new path starts with nothing visible from the previous one, and `auto` learns its
    // costs anew, trying each of its plans at the first pose before timing starts. Every mode
    // warms up there with `WARM_UP_FRAMES` frames (shaders, targets, the first early set): the
    // timed frames are those a viewer draws once it runs, not its first.
    renderers.reset_visibility();
    renderers.auto = None;
    for &mode in &config.modes {
        let mut frames = 0;
        loop {
            render_mode(
                gpu,
                renderers,
                scene,
                mode,
                &warm_camera,
                &warm_visible,
                &target,
            )?;
            frames += 1;
            let exploring = renderers.auto.as_ref().is_some_and(AutoPlanner::exploring);
            if frames >= WARM_UP_FRAMES && !(mode == Mode::Auto && exploring) {
                break;
            }
        }
    }
    for i in 0..path.poses.len() {
        gpu.alive()?;
        let camera = pose_camera(path, i);
        // Outside every mode's timing: `oracle` draws this set, but finding it is not its work.
        let ids = renderers
            .oracle
            .id_image(gpu, &scene.drawable.buildings, &camera, w, h)?;
        let visible_ids = visible_of(scene, &ids);
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("bench reference"),
            });
        renderers.brute.encode(
            gpu,
            &mut encoder,
            &scene.drawable.buildings,
            &camera,
            &reference.colour_view,
            &reference.depth,
        );
        renderers.encode_surfaces(
            gpu,
            &mut encoder,
            scene.drawable.surfaces.as_ref(),
            &camera,
            &reference,
        );
        gpu.queue.submit([encoder.finish()]);
        let reference_rgba = reference.read_colour(gpu)?;
        let edges = EdgeDistance::of_frame(&reference_rgba, &ids.pixels, w, h);
        let bound_px = bound_px(scene, &camera);
        let distance_diameters = crate::far::distance_in_diameters(scene, &camera);
        for &mode in &config.modes {
            let out = render_mode(gpu, renderers, scene, mode, &camera, &visible_ids, &target)?;
            let rgba = target.read_colour(gpu)?;
            let error = pixel_error(&reference_rgba, &rgba);
            let bound = edges.check(&reference_rgba, &rgba, bound_px);
            let culled_visible: Vec<u32> = visible_ids
                .iter()
                .copied()
                .filter(|b| out.drawn.binary_search(b).is_err())
                .collect();
            let false_culls = culled_visible.len();
            if false_culls > 0 {
                // Named, so that the bug can be reproduced from the pose alone.
                tracing::error!(
                    scene = %scene.name,
                    path = %path.name,
                    mode = mode.name(),
                    frame = i,
                    buildings = ?&culled_visible[..false_culls.min(16)],
                    "visible buildings culled (draw ids)"
                );
            }
            if let Some(dir) = &config.frames_dir
                && config.png_every > 0
                && i % config.png_every == 0
            {
                let file = dir.join(format!(
                    "{}-{}-{}-{:04}.png",
                    scene.name, path.name, mode, i
                ));
                save_png(&file, w, h, rgba)?;
            }
            records.push(FrameRecord {
                scene: scene.name.clone(),
                path: path.name.clone(),
                mode: mode.name().to_string(),
                frame: i,
                visible: visible_ids.len(),
                drawn: out.drawn.len(),
                clusters: out.clusters,
                false_culls,
                culled_fraction: if total == 0 {
                    0.0
                } else {
                    1.0 - out.drawn.len() as f64 / total as f64
                },
                triangles: out.triangles,
                triangle_share: crate::far::triangle_share(scene, out.triangles),
                distance_diameters,
                draw_calls: out.draw_calls,
                select_ms: out.select_ms,
                frame_ms: out.frame_ms,
                cpu_ms: out.cpu_ms,
                pixel_error_grey: error.grey_fraction,
                pixel_error_colour: error.colour_fraction,
                bound_px,
                differing_px: bound.differing,
                beyond_bound_px: bound.beyond,
                gpu: renderers.last_gpu.clone(),
            });
        }
    }
    Ok(records)
}

/// The pixel bound of a frame from `camera`: the LOD criterion's tolerance + 1 px
/// ([`crate::bound`]); for Chang's and Yang's criteria, which bound no distance, and for a
/// scene without a cluster tree, the default geometric tolerance's.
pub(crate) fn bound_px(scene: &BenchScene, camera: &Camera) -> f32 {
    let tolerance_px = match scene.drawable.refs().lod {
        Some(lod) => lod.bound_px(camera),
        None => LodCriterion::tolerance_for_altitude(camera.position.z, f32::INFINITY),
    };
    tolerance_px + 1.0
}

/// The buildings the oracle's id image shows, in id order.
fn visible_of(scene: &BenchScene, ids: &IdImage) -> Vec<u32> {
    let total = scene.drawable.buildings.building_count();
    let visible = VisibleSet::from_id_image(ids, total);
    (0..total as u32)
        .filter(|&b| visible.contains(citywalk_scenes::BuildingId(b)))
        .collect()
}

fn save_png(file: &std::path::Path, w: u32, h: u32, rgba: Vec<u8>) -> Result<(), BenchError> {
    let err = |reason: String| BenchError::Write {
        path: file.to_path_buf(),
        reason,
    };
    let image = image::RgbaImage::from_raw(w, h, rgba).ok_or_else(|| err("bad size".into()))?;
    image.save(file).map_err(|e| err(e.to_string()))
}
