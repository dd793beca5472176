//! The two-phase occlusion-culled frame (hierarchical Z with last frame's visible set, and
//! optionally the virtual-occluder pre-pass), over every building of a scene
//! ([`CullingRenderer::render`]) or over the candidates of a screen-space LOD cut
//! ([`CullingRenderer::render_lod`]: the cut's buildings and cluster meshes), as a script:
//!
//! ```text
//! (lod_cut      → caller: B-Quadtree + frustum + LOD cut, LodScene::select: the candidates)
//! occluder_gate → (occluders on, gate on) the ground and nearby virtual occluders into the
//!                 culling depth, their pyramid, last frame's visible candidates culled against it
//! early_pass    → colour + depth: the ground and last frame's visible building candidates
//!                 (with the gate: those it kept)
//! occluder_pass → (occluders on) copy of that depth + nearby virtual occluders, depth only
//!                 (with the gate: that depth merged into the occluders' depth, nearest wins)
//! build_pyramid → HiZ pyramid from that depth
//! cull          → every candidate's box, then its parts, against the pyramid (status,
//!                 indirect commands, count)
//! late_pass     → colour + depth: the candidates the cull kept that the early pass did not draw
//! read_status   → status to the CPU: statistics and next frame's visible set
//! final_cull    → (option) pyramid of the final depth, the candidates culled again: the next
//!                 frame's visible set from that status instead
//! ```
//!
//! Greene, Kass & Miller, *Hierarchical Z-buffer visibility* (SIGGRAPH 1993) for the pyramid;
//! the two-phase use of last frame's visible set follows the "early draw → pyramid → late cull →
//! late draw" frame of zeux/niagara. Virtual occluders after Germs & Jansen (2001), built
//! offline by the preprocessor. The LOD cut after Chang et al. (2008) §8 and Yang et al. (2011)
//! §4 ([`crate::lod`]).
//!
//! **Why it is conservative.** The pyramid is built from depth that holds only real geometry
//! (the ground and buildings drawn in full) and, with occluders on, virtual occluders, each of
//! which lies inside its building, so anything they hide the building hides as well. A building
//! visible in the final image is therefore not behind that depth, the cull keeps it and the late
//! pass draws it in the same frame, even right after a fast turn (disocclusion). Occluders are
//! drawn into a *copy* of the depth used only for the pyramid: the final image's depth never
//! holds them, so a building wall that coincides with its own occluder still passes the depth
//! test and the image equals brute force. With a LOD cut, cluster meshes are never drawn before
//! the pyramid (they are not contained in their buildings) and each is culled by a box holding
//! every building under it, so a building visible in the full-detail scene keeps the candidate
//! that covers it (`frame/candidates.rs`).
//!
//! **The occluder gate.** Last frame's visible set is a guess: after a jump or a fast move much of
//! it is hidden, and drawing it early costs draws the cull would have saved. With occluders and
//! [`CullingOptions::occluder_gate`], the ground and the occluders go first, alone, into the
//! culling depth; the early candidates are culled against their pyramid (the cull's `gate` entry
//! point), and the early pass draws only those kept, through the gate's indirect commands. The
//! early depth is then merged into the culling depth (the nearer wins) and the main pyramid built
//! from the merge, so it holds the same kinds of depth as without the gate (real geometry and
//! occluders contained in their buildings): conservative for the same reason. An early candidate
//! the gate keeps out is culled with every other candidate and drawn late when visible, in the same
//! frame; the main cull reads the gate's per-candidate flags and issues no draw for one the gate
//! drew. The frame then draws a subset of what a frame with no early set at all would draw: the
//! gate's pyramid is that frame's pyramid (the ground and the same occluders), and the main pyramid
//! holds at least that depth, so the main cull keeps no more either. A building the final image
//! shows is never kept out by the gate (nothing real, hence no occluder, is in front of it).
//!
//! **Late draws.** The cull reads a copy of the candidates' records whose index count is zero for
//! every candidate the early pass drew (with the gate: its flags), so the late pass issues an empty
//! command for those and draws each candidate at most once per frame. [`FrameStats::draw_calls`]
//! counts non-empty draws only; [`FrameStats::late_commands`] is every command the late pass
//! walked.
//!
//! **Visibility.** The next frame's early set is this frame's cull status `CULL_VISIBLE`, read
//! back with the (small) status buffer. With [`CullingOptions::visibility_from_final_depth`] it
//! is the status of a second cull of the same candidates against a pyramid of the *final*
//! depth (`final_cull` after `read_status` above): the first cull tests against the early depth,
//! which is coarse where last frame's set was small, and keeps far more than is visible; a
//! candidate hidden behind the final depth is not visible in this frame's image either. A LOD
//! frame that drew a cluster mesh keeps the first cull's set: cluster meshes are not contained
//! in their buildings, so the final depth may hide buildings the full-detail scene shows. The
//! early set is a hint, not a promise (the late cull still tests every candidate), so this does
//! not touch conservativeness. The set is kept per building id in [`Visibility`] (a visible
//! cluster marks every building under it), so it carries over when the LOD cut changes between
//! frames. A visibility of another building count (a new scene) is reset to empty, which is
//! still correct: the early pass then draws only the ground and the late pass everything the
//! cull keeps.
//!
//! # Example: the combined frame (B-Quadtree + LOD + HZB + occluders)
//!
//! ```no_run
//! # fn frame(
//! #     gpu: &citywalk_engine::gpu::GpuContext,
//! #     package: &citywalk_scenes::package::ScenePackage,
//! #     lod: &citywalk_engine::lod::scene::LodScene,
//! #     occluders: &citywalk_engine::frame::OccluderMeshes,
//! #     camera: &citywalk_engine::camera::Camera,
//! #     colour: &wgpu::TextureView,
//! # ) -> Result<(), citywalk_engine::frame::FrameError> {
//! use citywalk_engine::bench::mode::visible_blocks;
//! use citywalk_engine::frame::{CullingOptions, CullingRenderer, Visibility};
//! use citywalk_engine::render::BruteRenderer;
//!
//! let mut renderer = CullingRenderer::new(gpu, BruteRenderer::PNG_FORMAT);
//! let mut visibility = Visibility::default(); // keep it from frame to frame
//! let (width, height) = (1280, 720);
//! let options = CullingOptions { occluders: true, ..CullingOptions::default() };
//! // Per frame: the cut (after B-Quadtree culling of the urban blocks), then the frame.
//! let blocks = visible_blocks(&package.quadtree, package.blocks.blocks.len(), camera, width, height);
//! let cut = lod.select(camera, width, height, lod.default_criterion(camera), Some(&blocks));
//! let out = renderer.render_lod(
//!     gpu, lod, &cut, Some(occluders), &options, &mut visibility, camera, colour, (width, height),
//! )?;
//! // `out.drawn`: buildings drawn themselves or through a drawn cluster (`out.clusters`).
//! println!("{} clusters, {} buildings", out.stats.clusters_drawn, out.stats.drawn);
//! # Ok(())
//! # }
//! ```

mod candidates;
mod depth_copy;
mod grow_buffer;
mod occluders;
mod status_readback;
mod targets;
mod visibility;

use std::time::Instant;

use citywalk_scenes::frustum::Frustum;
use citywalk_shaders::{BuildingRecord, DrawIndexedIndirectArgs, SCENE_WGSL};
use glam::Mat4;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::gpu_timer::{FRAME_PHASES, GpuTimer, GpuTimes};
use crate::hzb::cull::{CullError, EarlyDraws};
use crate::hzb::{HzbCull, HzbPyramid};
use crate::lod::scene::{LodFrame, LodScene};
use crate::render::targets::ReadbackError;
use crate::render::view::{SceneStyle, view_uniforms};
use crate::scene_gpu::SceneGpu;

use candidates::{Candidates, LodSource};
use depth_copy::depth_copy_pipeline;
use grow_buffer::GrowBuffer;
pub use occluders::{OccluderDraw, OccluderMeshes};
use status_readback::StatusReadback;
use targets::Targets;
pub use visibility::Visibility;

/// Default projected-size threshold of the occluder selection: an occluder is drawn when its
/// bounding sphere's projected diameter exceeds this many pixels (a "near" occluder: Germs &
/// Jansen §4 select occluders by their screen size; the value is ours, measured on the
/// generated 100k city's street walk). With axis-aligned boxes, before cull parts: 48 px left
/// the far end of the street open and the cull kept 10.9 × the visible set, 24 px 3.7 × at the
/// same frame time, 12 px 2.4 × for ~20 % more frame time on lavapipe. With cull parts and
/// nothing drawn early (mode `all`, 20 frames ~500 m apart): 24 px keeps 2.22 × the visible
/// set, 16 px 1.54 ×, 12 px 1.38 ×, 6 px 1.35 ×; 12 px draws about 3 × as many occluders as
/// 24 px (5,900 a frame, one multi-draw), +10–35 % frame time on lavapipe.
pub const DEFAULT_OCCLUDER_MIN_PX: f32 = 12.0;

/// Default of [`CullingOptions::occluder_gate`]: on. Measured on the generated 100k city,
/// mode `all`, 12 px occluders (see [`DEFAULT_OCCLUDER_MIN_PX`]): last frame's set drawn
/// unculled makes the street walk (frames ~500 m apart) draw 1.58 × the visible set, with
/// nothing drawn early 1.38 ×; the gate's bound is the latter.
pub const DEFAULT_OCCLUDER_GATE: bool = true;

/// Default of [`CullingOptions::visibility_from_final_depth`]: off, by measurement (release build,
/// lavapipe, 1280 × 720, 16-frame street walks, mode `occluders`, with axis-aligned boxes before
/// cull parts). On the generated 100k city it lowers the buildings drawn per frame from 226 to 193
/// (61.6 visible), on the 10k city not at all (95.1, 48.8 visible): what a frame draws is mostly
/// what the first cull keeps, which the early set hardly changes. The second pyramid and cull cost
/// 7–10 ms per frame on lavapipe (30 → 39 ms on 10k, 39–45 → 49–56 ms on 100k), more than the fewer
/// draws save; on a real GPU both sides are a fraction of a millisecond.
pub const DEFAULT_VISIBILITY_FROM_FINAL_DEPTH: bool = false;

/// Changed late records closer than this many entries are uploaded in one write (a write has a
/// fixed cost; 64 records are 3 KiB).
const LATE_UPLOAD_MERGE_GAP: usize = 64;

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Readback(#[from] ReadbackError),
    #[error(transparent)]
    Cull(#[from] CullError),
}

/// What the frame does besides the two HiZ phases.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CullingOptions {
    /// Draw the selected virtual occluders into the depth the pyramid is built from.
    pub occluders: bool,
    /// Occluders whose bounding sphere projects to more than this many pixels are drawn.
    pub occluder_min_px: f32,
    /// With occluders drawn: cull last frame's visible candidates against the occluders' own
    /// pyramid first, and draw early only those it keeps (the others go to the main cull). Costs
    /// one more pyramid build and a cull of the early set per frame; see the module
    /// documentation and [`DEFAULT_OCCLUDER_GATE`].
    pub occluder_gate: bool,
    /// After the late pass, build the pyramid again from the final depth (ground, early and
    /// late draws; never occluders) and cull the candidates once more: the next frame's early
    /// set is what that second cull keeps, not what the first (against the coarser early depth)
    /// kept. This frame's statistics still come from the first cull. Costs one more pyramid
    /// build and cull per frame (see [`DEFAULT_VISIBILITY_FROM_FINAL_DEPTH`]).
    pub visibility_from_final_depth: bool,
}

impl Default for CullingOptions {
    fn default() -> Self {
        CullingOptions {
            occluders: false,
            occluder_min_px: DEFAULT_OCCLUDER_MIN_PX,
            occluder_gate: DEFAULT_OCCLUDER_GATE,
            visibility_from_final_depth: DEFAULT_VISIBILITY_FROM_FINAL_DEPTH,
        }
    }
}

/// Counts and timing of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    pub building_count: u32,
    /// Boxes the cull tested: every building, or the LOD cut's buildings and clusters.
    pub candidates: u32,
    /// Candidates drawn by the early pass (last frame's visible buildings, in the frustum; with
    /// the occluder gate, those it kept).
    pub early_drawn: u32,
    /// Last frame's visible candidates in the frustum that the occluder gate kept out of the
    /// early pass (culled with the others; 0 without the gate).
    pub gate_culled: u32,
    /// Virtual occluders drawn into the pyramid's depth.
    pub occluders_drawn: u32,
    pub occluder_triangles: u64,
    /// Candidates the cull found outside the frustum.
    pub frustum_culled: u32,
    /// Candidates the cull found hidden behind the pyramid.
    pub occlusion_culled: u32,
    /// Candidates the cull kept.
    pub cull_kept: u32,
    /// Candidates drawn by the late pass (kept, not drawn early).
    pub late_drawn: u32,
    /// Buildings drawn in all (early ∪ kept), themselves or through a drawn cluster.
    pub drawn: u32,
    /// Cluster meshes drawn (LOD cut only).
    pub clusters_drawn: u32,
    /// Buildings drawn only through a drawn cluster, not themselves (LOD cut only).
    pub buildings_through_clusters: u32,
    /// Triangles of the drawn candidates (ground and occluders excluded).
    pub triangles: u64,
    /// Non-empty draws: ground, early buildings, occluders, late candidates.
    pub draw_calls: u32,
    /// Commands the late pass walked (including the empty ones of early candidates).
    pub late_commands: u32,
    /// CPU wall time from the start of recording to the GPU's completion, status read (ms).
    pub cpu_ms: f64,
    /// GPU time of each pass ([`FRAME_PHASES`]: gate pyramid, gate, early, occluders (or the
    /// gate's depth merge), pyramid, cull, late) from
    /// timestamp queries; every phase `None` when the adapter has none, a phase `None` when
    /// its pass did not run this frame.
    pub gpu: GpuTimes,
}

/// The result of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameOutput {
    /// Buildings drawn (early ∪ kept), themselves or through a drawn cluster, in id order.
    pub drawn: Vec<u32>,
    /// Per building: `CULL_VISIBLE`, `CULL_FRUSTUM_OUTSIDE` or `CULL_OCCLUDED` (with a LOD cut,
    /// the status of the candidates covering it; `CULL_FRUSTUM_OUTSIDE` when the cut left it
    /// out).
    pub status: Vec<u32>,
    /// Cluster tree nodes whose mesh was drawn, ascending (LOD cut only).
    pub clusters: Vec<u32>,
    /// The virtual occluders drawn into the pyramid's depth (indices into
    /// [`OccluderMeshes::occluders`]), ascending.
    pub occluders: Vec<usize>,
    pub stats: FrameStats,
}

/// The two-phase culling renderer: pipelines, the cull pass, draw lists and targets.
#[derive(Debug)]
pub struct CullingRenderer {
    scene_pipeline: wgpu::RenderPipeline,
    depth_pipeline: wgpu::RenderPipeline,
    copy_pipeline: wgpu::RenderPipeline,
    /// The depth copy that keeps the nearer of source and destination (the gate's merge).
    merge_pipeline: wgpu::RenderPipeline,
    copy_layout: wgpu::BindGroupLayout,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    cull: HzbCull,
    /// The occluder gate's cull (its own status, commands and count).
    gate: HzbCull,
    /// The gate's records, the candidate each stands for, and the per-candidate flags of
    /// those it drew early.
    gate_records: GrowBuffer,
    gate_targets: GrowBuffer,
    drawn_early: GrowBuffer,
    early_draws: GrowBuffer,
    occluder_draws: GrowBuffer,
    late_records: GrowBuffer,
    status_readback: StatusReadback,
    targets: Option<Targets>,
    /// The records the cull read last, with zero index counts for early buildings: the GPU
    /// buffer's contents, updated per frame where they changed.
    late_records_cpu: Vec<BuildingRecord>,
    multi_draw_count: bool,
    /// Timestamps around each pass ([`FRAME_PHASES`]).
    timer: GpuTimer,
    /// Sky, sun and fog.
    pub style: SceneStyle,
}

impl CullingRenderer {
    /// The pyramid the last frame culled against last: its early depth, with the selected
    /// occluders when the pre-pass ran, or, with
    /// [`CullingOptions::visibility_from_final_depth`], its final depth; for debug views;
    /// `None` until a frame has made its targets.
    pub fn pyramid(&self) -> Option<&HzbPyramid> {
        self.targets.as_ref().map(|t| &t.pyramid)
    }

    /// A renderer drawing into colour targets of `colour_format` (as
    /// [`crate::render::BruteRenderer::new`]).
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> CullingRenderer {
        let device = &gpu.device;
        let layout = crate::render::view_bind_group_layout(device, "frame view");
        let (view_buffer, view_group) =
            crate::render::view_buffer_and_group(device, &layout, "frame view");
        let scene_pipeline = crate::render::scene_pipeline(
            device,
            "frame scene",
            SCENE_WGSL,
            &layout,
            Some(colour_format),
        );
        let depth_pipeline =
            crate::render::scene_pipeline(device, "occluder depth", SCENE_WGSL, &layout, None);
        let (copy_pipeline, copy_layout) =
            depth_copy_pipeline(device, wgpu::CompareFunction::Always);
        let (merge_pipeline, _) = depth_copy_pipeline(device, wgpu::CompareFunction::Greater);
        let indirect = wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        CullingRenderer {
            scene_pipeline,
            depth_pipeline,
            copy_pipeline,
            merge_pipeline,
            copy_layout,
            view_buffer,
            view_group,
            cull: HzbCull::new(gpu, 1024),
            gate: HzbCull::new(gpu, 1024),
            gate_records: GrowBuffer::new(device, "gate records", storage),
            gate_targets: GrowBuffer::new(device, "gate targets", storage),
            drawn_early: GrowBuffer::new(device, "drawn early", storage),
            early_draws: GrowBuffer::new(device, "early draws", indirect),
            occluder_draws: GrowBuffer::new(device, "occluder draws", indirect),
            late_records: GrowBuffer::new(device, "late cull records", storage),
            status_readback: StatusReadback::new(device),
            targets: None,
            late_records_cpu: Vec::new(),
            multi_draw_count: gpu.has(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT),
            timer: GpuTimer::new(gpu, "frame timer", FRAME_PHASES),
            style: SceneStyle::default(),
        }
    }

    /// Renders one frame of every building of `scene` from `camera` into `colour`
    /// (`width × height`, the format given to [`CullingRenderer::new`]), with `occluders` when
    /// `options.occluders` is set and some are given. Reads `visibility` (last frame) and writes
    /// it for the next frame. Waits for the GPU.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn render(
        &mut self,
        gpu: &GpuContext,
        scene: &SceneGpu,
        occluders: Option<&OccluderMeshes>,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        colour: &wgpu::TextureView,
        size: (u32, u32),
    ) -> Result<FrameOutput, FrameError> {
        let start = Instant::now();
        visibility.fit(scene.building_count());
        let frustum = Frustum::from_view_proj(Self::view_proj(camera, size));
        let candidates = Candidates::all_buildings(scene, visibility, &frustum);
        self.frame(
            gpu,
            scene,
            candidates,
            occluders.filter(|_| options.occluders),
            options,
            visibility,
            camera,
            colour,
            size,
            start,
        )
    }

    /// Renders one frame of the LOD cut `cut` of `lod` (from [`LodScene::select`] for this
    /// camera and viewport: its buildings and cluster meshes are the candidates of the two-phase
    /// frame), otherwise as [`CullingRenderer::render`]. `visibility` is per building of the
    /// scene, so the same one serves frames whose cuts differ. [`FrameOutput::drawn`] lists the
    /// buildings drawn themselves or through a drawn cluster.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn render_lod(
        &mut self,
        gpu: &GpuContext,
        lod: &LodScene,
        cut: &LodFrame,
        occluders: Option<&OccluderMeshes>,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        colour: &wgpu::TextureView,
        size: (u32, u32),
    ) -> Result<FrameOutput, FrameError> {
        let start = Instant::now();
        visibility.fit(lod.building_count as usize);
        let frustum = Frustum::from_view_proj(Self::view_proj(camera, size));
        let candidates = Candidates::lod(LodSource::of(lod), &cut.draw_ids, visibility, &frustum);
        self.frame(
            gpu,
            &lod.gpu_scene,
            candidates,
            occluders.filter(|_| options.occluders),
            options,
            visibility,
            camera,
            colour,
            size,
            start,
        )
    }

    fn view_proj(camera: &Camera, (width, height): (u32, u32)) -> Mat4 {
        camera.view_proj(width as f32 / height.max(1) as f32)
    }

    /// The frame script, over `candidates` of `scene`.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    fn frame(
        &mut self,
        gpu: &GpuContext,
        scene: &SceneGpu,
        mut candidates: Candidates<'_>,
        occluders: Option<&OccluderMeshes>,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        colour: &wgpu::TextureView,
        (width, height): (u32, u32),
        start: Instant,
    ) -> Result<FrameOutput, FrameError> {
        self.fit_targets(gpu, width, height)?;
        let n = candidates.len();
        let view_proj = Self::view_proj(camera, (width, height));
        let frustum = Frustum::from_view_proj(view_proj);
        let early_count = candidates.early_draw_count as usize - 1;
        // With the gate, every occluder counts (its pyramid has no early depth); without, not
        // those of buildings drawn early (their real geometry is in the depth).
        let gated = options.occluder_gate && occluders.is_some() && early_count > 0;
        let occluders_drawn = match occluders {
            Some(meshes) => meshes.select(
                camera,
                &frustum,
                height,
                options.occluder_min_px,
                if gated {
                    &[]
                } else {
                    &candidates.early_buildings
                },
            ),
            None => Vec::new(),
        };
        let gated = gated && !occluders_drawn.is_empty();
        candidates.gated = gated;
        let final_cull = options.visibility_from_final_depth && n > 0;
        let slots = 1 + usize::from(final_cull) + usize::from(gated);
        self.status_readback.reserve(gpu, n, slots);
        let uniforms = view_uniforms(camera, width, height, &self.style);
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("culled frame"),
            });
        self.timer.begin_frame();

        let occluder_meshes = occluders.filter(|_| !occluders_drawn.is_empty());
        if let (true, Some(meshes)) = (gated, occluder_meshes) {
            self.occluder_gate(
                gpu,
                &mut encoder,
                meshes,
                &occluders_drawn,
                (scene, &candidates),
                view_proj,
            )?;
        }
        self.early_pass(gpu, &mut encoder, scene, &candidates, colour);
        if let Some(meshes) = occluder_meshes {
            self.occluder_pass(gpu, &mut encoder, meshes, &occluders_drawn, gated);
        }
        self.build_pyramid(&mut encoder, occluder_meshes.is_some());
        self.cull(gpu, &mut encoder, scene, &candidates, view_proj)?;
        self.late_pass(&mut encoder, scene, n as u32, colour);
        self.read_status(&mut encoder, n, 0);
        if final_cull {
            self.final_depth_cull(gpu, &mut encoder, scene, n, view_proj)?;
        }
        if gated {
            self.status_readback.copy_from(
                &mut encoder,
                self.gate.status_buffer(),
                early_count,
                n,
                slots - 1,
            );
        }
        self.timer.resolve(&mut encoder);

        gpu.queue.submit([encoder.finish()]);
        let mut status = self.status_readback.read(gpu, slots * n)?;
        let mut later = status.split_off(n);
        let gate_culled = if gated {
            let gate_status = later.split_off(later.len() - n);
            candidates.apply_gate(&gate_status[..early_count])
        } else {
            0
        };
        let final_status = later;
        // A drawn cluster mesh may reach outside its buildings and hide, in the final depth,
        // buildings the full-detail scene shows: such a frame keeps the first cull's set.
        let from_final = final_cull && !candidates.cluster_kept(&status);
        candidates.update_visibility(visibility, if from_final { &final_status } else { &status });
        let mut output = candidates.statistics(status, !self.multi_draw_count);
        output.stats.gate_culled = gate_culled;
        if let Some(meshes) = occluders {
            output.stats.occluders_drawn = occluders_drawn.len() as u32;
            output.stats.occluder_triangles = occluders_drawn
                .iter()
                .map(|&i| u64::from(meshes.occluders[i].triangles))
                .sum();
            output.stats.draw_calls += occluders_drawn.len() as u32;
        }
        output.occluders = occluders_drawn;
        output.stats.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        output.stats.gpu = self.timer.read(gpu)?;
        Ok(output)
    }

    /// The occluder gate: the ground and the selected occluders alone into the culling depth,
    /// their pyramid, and the early candidates culled against it (the cull's `gate` entry
    /// point), which writes the early pass's commands and marks the candidates it keeps in
    /// `drawn_early`.
    fn occluder_gate(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        meshes: &OccluderMeshes,
        selected: &[usize],
        (scene, candidates): (&SceneGpu, &Candidates<'_>),
        view_proj: Mat4,
    ) -> Result<(), FrameError> {
        let (records, targets) = candidates.gate_records();
        let device = &gpu.device;
        self.gate_records
            .reserve(device, (records.len() * size_of::<BuildingRecord>()) as u64);
        gpu.queue
            .write_buffer(&self.gate_records.buffer, 0, bytemuck::cast_slice(&records));
        self.gate_targets
            .reserve(device, (targets.len() * 4) as u64);
        gpu.queue
            .write_buffer(&self.gate_targets.buffer, 0, bytemuck::cast_slice(&targets));
        let flag_bytes = (candidates.len().max(1) * 4) as u64;
        self.drawn_early.reserve(device, flag_bytes);
        encoder.clear_buffer(&self.drawn_early.buffer, 0, Some(flag_bytes));
        self.upload_occluder_draws(gpu, meshes, selected);
        {
            let clear = wgpu::LoadOp::Clear(Camera::DEPTH_CLEAR);
            let mut pass = self.depth_only_pass(encoder, "occluder_gate", clear, "gate_occluders");
            // The ground first, so that the gate's pyramid is the one a frame with no early
            // set would cull everything against (the ground and the occluders).
            pass.set_pipeline(&self.depth_pipeline);
            pass.set_bind_group(0, &self.view_group, &[]);
            scene.bind(&mut pass);
            let g = scene.ground;
            pass.draw_indexed(
                g.first_index..g.first_index + g.index_count,
                g.base_vertex,
                0..g.instance_count,
            );
            self.draw_occluders(&mut pass, meshes, selected.len());
        }
        let targets_view = self.targets.as_ref().expect("fit_targets ran");
        targets_view.pyramid.build_timed(
            encoder,
            &targets_view.cull_depth_view,
            self.timer.compute_pass_writes("gate_pyramid"),
        );
        self.gate.encode_with_early(
            gpu,
            encoder,
            (
                &self.gate_records.buffer,
                Some(&scene.parts_buffer),
                EarlyDraws::Mark {
                    drawn: &self.drawn_early.buffer,
                    targets: &self.gate_targets.buffer,
                },
            ),
            records.len() as u32,
            (&targets_view.pyramid, view_proj),
            self.timer.compute_pass_writes("gate"),
        )?;
        Ok(())
    }

    /// Clears colour and depth, draws the ground and the candidates to draw early (last frame's
    /// visible buildings that lie in the frustum; with the gate, the gate's commands).
    fn early_pass(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        candidates: &Candidates<'_>,
        colour: &wgpu::TextureView,
    ) {
        let mut draws = vec![scene.ground];
        if !candidates.gated {
            draws.extend(
                candidates
                    .records
                    .iter()
                    .zip(&candidates.early)
                    .filter(|(_, e)| **e)
                    .map(|(r, _)| r.draw_args()),
            );
        }
        let bytes: &[u8] = bytemuck::cast_slice(&draws);
        self.early_draws.reserve(&gpu.device, bytes.len() as u64);
        gpu.queue.write_buffer(&self.early_draws.buffer, 0, bytes);
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("early_pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: colour,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(self.style.clear_colour()),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(targets.depth.attachment()),
            timestamp_writes: self.timer.render_pass_writes("early"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.scene_pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        pass.multi_draw_indexed_indirect(&self.early_draws.buffer, 0, draws.len() as u32);
        if candidates.gated {
            let max = candidates.early_draw_count - 1;
            self.indirect_draws(&mut pass, &self.gate, max);
        }
    }

    /// Draws the commands `cull` wrote (at most `max`): through its count where the adapter
    /// has `multi_draw_indexed_indirect_count`, else all `max` slots (those past the count are
    /// zero: empty draws).
    fn indirect_draws(&self, pass: &mut wgpu::RenderPass<'_>, cull: &HzbCull, max: u32) {
        if self.multi_draw_count {
            pass.multi_draw_indexed_indirect_count(
                cull.commands_buffer(),
                0,
                cull.count_buffer(),
                0,
                max,
            );
        } else {
            pass.multi_draw_indexed_indirect(cull.commands_buffer(), 0, max);
        }
    }

    /// Writes the draws of the `selected` occluders to the occluder draw buffer.
    fn upload_occluder_draws(
        &mut self,
        gpu: &GpuContext,
        meshes: &OccluderMeshes,
        selected: &[usize],
    ) {
        let draws: Vec<DrawIndexedIndirectArgs> =
            selected.iter().map(|&i| meshes.occluders[i].draw).collect();
        let bytes: &[u8] = bytemuck::cast_slice(&draws);
        self.occluder_draws.reserve(&gpu.device, bytes.len() as u64);
        gpu.queue
            .write_buffer(&self.occluder_draws.buffer, 0, bytes);
    }

    /// A depth-only pass into the culling depth, timed as `phase`.
    fn depth_only_pass<'e>(
        &self,
        encoder: &'e mut wgpu::CommandEncoder,
        label: &str,
        load: wgpu::LoadOp<f32>,
        phase: &str,
    ) -> wgpu::RenderPass<'e> {
        let targets = self.targets.as_ref().expect("fit_targets ran");
        encoder
            .begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some(label),
                color_attachments: &[],
                depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                    view: &targets.cull_depth_view,
                    depth_ops: Some(wgpu::Operations {
                        load,
                        store: wgpu::StoreOp::Store,
                    }),
                    stencil_ops: None,
                }),
                timestamp_writes: self.timer.render_pass_writes(phase),
                occlusion_query_set: None,
                multiview_mask: None,
            })
            .forget_lifetime()
    }

    /// Draws the first `count` occluder draws of `draws`, depth only.
    fn draw_occluders(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        meshes: &OccluderMeshes,
        count: usize,
    ) {
        pass.set_pipeline(&self.depth_pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        pass.set_vertex_buffer(0, meshes.vertex_buffer.slice(..));
        pass.set_index_buffer(meshes.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        pass.multi_draw_indexed_indirect(&self.occluder_draws.buffer, 0, count as u32);
    }

    /// The culling depth for the pyramid: without the gate, the early depth copied and the
    /// `selected` occluders drawn into it; with the gate (the occluders are there already),
    /// the early depth merged in, the nearer depth kept.
    fn occluder_pass(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        meshes: &OccluderMeshes,
        selected: &[usize],
        gated: bool,
    ) {
        if !gated {
            self.upload_occluder_draws(gpu, meshes, selected);
        }
        let load = if gated {
            wgpu::LoadOp::Load
        } else {
            wgpu::LoadOp::Clear(Camera::DEPTH_CLEAR)
        };
        let mut pass = self.depth_only_pass(encoder, "occluder_pass", load, "occluders");
        let targets = self.targets.as_ref().expect("fit_targets ran");
        // The early depth, texel for texel (a shader copy: see `wgsl/depth_copy.wgsl`), or
        // with the gate the nearer of it and the occluders'.
        pass.set_pipeline(if gated {
            &self.merge_pipeline
        } else {
            &self.copy_pipeline
        });
        pass.set_bind_group(0, &targets.copy_group, &[]);
        pass.draw(0..3, 0..1);
        if !gated {
            self.draw_occluders(&mut pass, meshes, selected.len());
        }
    }

    /// Builds the pyramid from the early depth, or from its copy holding the occluders.
    fn build_pyramid(&self, encoder: &mut wgpu::CommandEncoder, with_occluders: bool) {
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let depth = if with_occluders {
            &targets.cull_depth_view
        } else {
            &targets.depth.view
        };
        let timestamps = self.timer.compute_pass_writes("pyramid");
        targets.pyramid.build_timed(encoder, depth, timestamps);
    }

    /// Culls every candidate against the pyramid (by the parts of `scene` its record names);
    /// early candidates get empty commands.
    fn cull(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        candidates: &Candidates<'_>,
        view_proj: Mat4,
    ) -> Result<(), FrameError> {
        let n = candidates.len();
        let bytes = (n.max(1) * size_of::<BuildingRecord>()) as u64;
        let grown = self.late_records.reserve(&gpu.device, bytes);
        if grown {
            // A new buffer holds nothing: every entry is uploaded.
            self.late_records_cpu.clear();
        }
        // Only the entries that changed since the last frame (mostly the early set's) go to
        // the GPU; the buffer keeps the rest.
        let runs =
            candidates.update_late_records(&mut self.late_records_cpu, LATE_UPLOAD_MERGE_GAP);
        let record_bytes = size_of::<BuildingRecord>() as u64;
        for (first, end) in runs {
            gpu.queue.write_buffer(
                &self.late_records.buffer,
                first as u64 * record_bytes,
                bytemuck::cast_slice(&self.late_records_cpu[first..end]),
            );
        }
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let early = if candidates.gated {
            EarlyDraws::Skip(&self.drawn_early.buffer)
        } else {
            EarlyDraws::None
        };
        self.cull.encode_with_early(
            gpu,
            encoder,
            (&self.late_records.buffer, Some(&scene.parts_buffer), early),
            n as u32,
            (&targets.pyramid, view_proj),
            self.timer.compute_pass_writes("cull"),
        )?;
        Ok(())
    }

    /// Draws the cull's commands (colour and depth loaded).
    fn late_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        n: u32,
        colour: &wgpu::TextureView,
    ) {
        if n == 0 {
            return;
        }
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("late_pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: colour,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth.view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: self.timer.render_pass_writes("late"),
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.scene_pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        self.indirect_draws(&mut pass, &self.cull, n);
    }

    /// Copies the cull status into slot `slot` of the readback buffer.
    fn read_status(&mut self, encoder: &mut wgpu::CommandEncoder, n: usize, slot: usize) {
        self.status_readback
            .copy_from(encoder, self.cull.status_buffer(), n, n, slot);
    }

    /// The next frame's visible set from this frame's final depth: the pyramid again, from the
    /// depth after the late pass (real geometry only: occluders went to the copy), the same
    /// candidates culled against it, the status copied into readback slot 1. Recorded after
    /// the late pass and the copy of the first status in the same encoder, so wgpu orders the
    /// first cull's commands, count and status (consumed there) before this cull overwrites
    /// them; the cull's uniforms are the same view and box count as the first cull's.
    fn final_depth_cull(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        n: usize,
        view_proj: Mat4,
    ) -> Result<(), FrameError> {
        let targets = self.targets.as_ref().expect("fit_targets ran");
        targets.pyramid.build(encoder, &targets.depth.view);
        self.cull.encode(
            gpu,
            encoder,
            (&self.late_records.buffer, Some(&scene.parts_buffer)),
            n as u32,
            &targets.pyramid,
            view_proj,
        )?;
        self.read_status(encoder, n, 1);
        Ok(())
    }

    /// (Re)makes the depth targets and the pyramid for a new viewport size.
    fn fit_targets(&mut self, gpu: &GpuContext, width: u32, height: u32) -> Result<(), FrameError> {
        if self
            .targets
            .as_ref()
            .is_some_and(|t| (t.depth.width, t.depth.height) == (width, height))
        {
            return Ok(());
        }
        self.targets = Some(Targets::new(gpu, &self.copy_layout, width, height)?);
        Ok(())
    }
}
