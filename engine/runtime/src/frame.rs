//! The two-phase occlusion-culled frame (hierarchical Z with last frame's visible set, and
//! optionally the virtual-occluder pre-pass), over every building of a scene
//! ([`CullingRenderer::render`]) or over the candidates of a screen-space LOD cut
//! ([`CullingRenderer::render_lod`]: the cut's buildings and cluster meshes), as a script
//! below. A LOD frame whose cut the GPU computes, with hierarchical culling of the cluster
//! tree, is [`CullingRenderer::submit_tree`] (`frame/tree_frame.rs`); it shares these passes.
//!
//! ```text
//! (lod_cut      → caller: B-Quadtree + frustum + LOD cut, LodScene::select: the candidates)
//! occluder_gate → (occluders on, gate on) the ground and nearby virtual occluders into the
//!                 culling depth, their pyramid, last frame's visible candidates culled against it
//! early_cull    → (no gate) last frame's visible candidates inside the frustum
//! early_pass    → colour + depth: the ground and what the gate or the early cull kept
//! occluder_pass → (occluders on, no gate) nearby virtual occluders alone into the cleared
//!                 culling depth, depth only (with the gate they are there already)
//! build_pyramid → HiZ pyramid from the early depth, with occluders merged with the culling
//!                 depth in the same dispatch (the nearer depth of the two kept per pixel)
//! cull          → every candidate's box, then its parts, against the pyramid (status,
//!                 indirect commands, count, visibility stamps for the next frame)
//! late_pass     → colour + depth: the candidates the cull kept that the early pass did not draw
//! report        → timestamps and statuses copied to a ring slot, read a frame or more late
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
//! which lies inside its building, so anything they hide the building hides as well (their
//! depth is eroded by one texel as the pyramid reads it, so that rounding where an occluder's
//! edge meets its building's silhouette cannot cover a pixel the building leaves open:
//! [`crate::hzb::reference::erode`]). A building
//! visible in the final image is therefore not behind that depth, the cull keeps it and the late
//! pass draws it in the same frame, even right after a fast turn (disocclusion). Occluders are
//! drawn into a depth target of their own, merged with the early depth only by the pyramid
//! build: the final image's depth never holds them, so a building wall that coincides with its
//! own occluder still passes the depth test and the image equals brute force. With a LOD cut, cluster meshes are never drawn before
//! the pyramid (they are not contained in their buildings) and each is culled by a box holding
//! every building under it, so a building visible in the full-detail scene keeps the candidate
//! that covers it (`frame/candidates.rs`).
//!
//! **The occluder gate.** Last frame's visible set is a guess: after a jump or a fast move much of
//! it is hidden, and drawing it early costs draws the cull would have saved. With occluders and
//! [`CullingOptions::occluder_gate`], the ground and the occluders go first, alone, into the
//! culling depth; the early candidates are culled against their pyramid (the cull's `gate` entry
//! point), and the early pass draws only those kept, through the gate's indirect commands. The
//! main pyramid is then built from the early depth merged with the culling depth (the nearer
//! wins, in the pyramid's first dispatch), so it holds the same kinds of depth as without the
//! gate (real geometry and occluders contained in their buildings): conservative for the same reason. An early candidate
//! the gate keeps out is culled with every other candidate and drawn late when visible, in the same
//! frame; the main cull reads the gate's per-candidate flags and issues no draw for one the gate
//! drew. The frame then draws a subset of what a frame with no early set at all would draw: the
//! gate's pyramid is that frame's pyramid (the ground and the same occluders), and the main pyramid
//! holds at least that depth, so the main cull keeps no more either. A building the final image
//! shows is never kept out by the gate (nothing real, hence no occluder, is in front of it).
//!
//! **Late draws.** The early entry point marks each candidate it drew in a per-candidate flag
//! buffer; the cull appends no draw for a marked candidate, so the late pass draws each candidate
//! at most once per frame. [`FrameStats::draw_calls`] counts non-empty draws only;
//! [`FrameStats::late_commands`] is every command the late pass walked.
//!
//! **Visibility lives on the GPU** (niagara's `drawVisibility`, [`Visibility`]): the cull stamps
//! every kept candidate's draw id with the frame's number, and the next frame's early entry point
//! takes a building whose draw id, or a cluster's above it, carries last frame's number. The CPU
//! neither walks nor uploads the set: per frame it records the passes and, for a LOD cut, uploads
//! the cut's draw ids. The set is a hint, not a promise (the late cull still tests every
//! candidate), so it does not touch conservativeness; a visibility of another scene shape starts
//! empty, which is still correct.
//!
//! **Statistics come back late.** [`CullingRenderer::submit`] copies the frame's timestamps and
//! statuses into a slot of a ring of readback buffers and returns; nothing in the frame waits on
//! the GPU. [`CullingRenderer::poll_report`] (the viewer) takes the newest ready report without
//! waiting; [`CullingRenderer::render`] and [`CullingRenderer::render_lod`] (the benchmark, the
//! tests) submit and wait for their own frame's report.
//!
//! # Example: the combined frame (B-Quadtree + LOD + HZB + occluders)
//!
//! ```no_run
//! # fn frame(
//! #     gpu: &citywalk_runtime::gpu::GpuContext,
//! #     package: &citywalk_scenes::package::ScenePackage,
//! #     lod: &citywalk_runtime::lod::scene::LodScene,
//! #     occluders: &citywalk_runtime::frame::OccluderMeshes,
//! #     camera: &citywalk_runtime::camera::Camera,
//! #     colour: &wgpu::TextureView,
//! # ) -> Result<(), citywalk_runtime::frame::FrameError> {
//! use citywalk_runtime::runner::visible_blocks;
//! use citywalk_runtime::frame::{CullingOptions, CullingRenderer, Visibility};
//! use citywalk_runtime::render::BruteRenderer;
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
mod grow_buffer;
mod occluders;
mod report_ring;
mod sphere_index;
mod targets;
mod tree_frame;
mod visibility;

use std::time::Instant;

use citywalk_scenes::frustum::Frustum;
use citywalk_shaders::SCENE_WGSL;
use citywalk_shaders::constants::{
    CULL_R_EARLY, CULL_R_GATE_CULLED, CULL_R_KEPT, CULL_R_OCCLUDED, CULL_R_WORDS, NO_PARENT,
};
use glam::Mat4;
use wgpu::util::DeviceExt;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::gpu_timer::{FRAME_PHASES, GpuTimer, GpuTimes, TimedPhases};
use crate::hzb::cull::{CullEntry, CullError, CullLinks, CullVisibility};
use crate::hzb::{HzbCull, HzbPyramid};
use crate::lod::scene::{LodFrame, LodScene};
use crate::render::targets::ReadbackError;
use crate::render::view::{SceneStyle, view_uniforms};
use crate::scene_gpu::SceneGpu;

use candidates::{Candidates, CullLists, LodSource};
use grow_buffer::GrowBuffer;
pub use occluders::{OccluderDraw, OccluderMeshes};
/// Frames a report may arrive after its own.
pub use report_ring::SLOTS as REPORT_LAG_FRAMES;
use report_ring::{ListSources, ReadSlot, ReportRing, SlotLayout, read_lists};
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

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Readback(#[from] ReadbackError),
    #[error(transparent)]
    Cull(#[from] CullError),
    #[error(
        "frame {0} recorded no report: every readback slot was still in flight (poll the reports)"
    )]
    NoReport(u64),
    #[error("the scene has no records of its own on the GPU (a LOD scene): cull it as a LOD cut")]
    NoRecords,
    #[error(transparent)]
    DeviceLost(#[from] crate::gpu::DeviceLost),
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
    /// one more pyramid build per frame; see the module documentation and
    /// [`DEFAULT_OCCLUDER_GATE`].
    pub occluder_gate: bool,
}

impl Default for CullingOptions {
    fn default() -> Self {
        CullingOptions {
            occluders: false,
            occluder_min_px: DEFAULT_OCCLUDER_MIN_PX,
            occluder_gate: DEFAULT_OCCLUDER_GATE,
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
    /// Last frame's visible candidates that the occluder gate kept out of the early pass
    /// (culled with the others; 0 without the gate).
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
    /// CPU time of the frame's own work, recording and submission, without any wait (ms).
    pub cpu_ms: f64,
    /// Wall time from the start of recording until the report was read (ms): for a frame
    /// rendered with [`CullingRenderer::render`] (which waits for it), the frame's time to GPU
    /// completion.
    pub frame_ms: f64,
    /// GPU time of each pass ([`FRAME_PHASES`]) from timestamp queries; every phase `None` when
    /// the adapter has none, a phase `None` when its pass did not run this frame.
    pub gpu: GpuTimes,
    /// HZB frames this renderer submitted after this one before its report was read: 0 when
    /// the caller waited for it, more for a report polled late.
    pub frames_late: u32,
}

/// The result of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameOutput {
    /// Buildings drawn (early ∪ kept), themselves or through a drawn cluster, in id order.
    pub drawn: Vec<u32>,
    /// Cluster tree nodes whose mesh was drawn, ascending (LOD cut only).
    pub clusters: Vec<u32>,
    /// Buildings the early pass drew (last frame's visible set as the GPU held it, through the
    /// gate when it ran), ascending.
    pub drawn_early: Vec<u32>,
    /// Buildings drawn as themselves (not only through a cluster), ascending.
    pub drawn_themselves: Vec<u32>,
    /// The frame's candidates were a LOD cut (draw ids of its LOD scene), not every building.
    pub lod_cut: bool,
    /// The virtual occluders drawn into the pyramid's depth (indices into
    /// [`OccluderMeshes::occluders`]), ascending.
    pub occluders: Vec<usize>,
    pub stats: FrameStats,
}

/// What a frame culls: every building of a scene, or the draw ids of a LOD cut of a LOD scene
/// (its buildings and cluster meshes).
#[derive(Debug, Clone, Copy)]
pub enum FrameScene<'a> {
    Buildings(&'a SceneGpu),
    Lod(&'a LodScene, &'a [u32]),
}

/// A submitted frame, whose report [`CullingRenderer::wait_report`] reads.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct FrameTicket {
    /// The frame's number (counting from 1 per renderer).
    pub number: u64,
    /// Whether the frame copied its statistics (every report slot may have been in flight).
    pub reported: bool,
}

/// What a submitted frame keeps on the CPU until its report is read.
#[derive(Debug)]
struct PendingFrame {
    number: u64,
    /// The candidates: every building of a scene of this many, or a LOD cut's draw ids.
    buildings: usize,
    lod_ids: Option<Vec<u32>>,
    timed: TimedPhases,
    occluders: Vec<usize>,
    occluder_triangles: u64,
    /// Draw calls of the occluders ([`OccluderMeshes::merged_draws`]).
    occluder_draws: u32,
    cpu_ms: f64,
    started: Instant,
    /// A tree frame's lists ([`CullingRenderer::submit_tree`]).
    tree: Option<tree_frame::TreePending>,
    /// A candidate frame's kept and early lists on the GPU (the cull passes' reports).
    lists: Option<ListSources>,
}

/// The two-phase culling renderer: pipelines, the cull pass, draw lists and targets.
#[derive(Debug)]
pub struct CullingRenderer {
    scene_pipelines: crate::render::ScenePipelines,
    depth_pipeline: wgpu::RenderPipeline,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    /// The early entry points (`early`, `gate`): their status, the early pass's commands.
    early: HzbCull,
    /// The main cull.
    cull: HzbCull,
    /// Per candidate: drawn by the early pass (written by `early`, read by `cull`).
    drawn_early: GrowBuffer,
    /// The LOD cut's draw ids.
    draw_ids: GrowBuffer,
    /// One [`NO_PARENT`] word: the parents of a scene without a cluster tree.
    no_parents: wgpu::Buffer,
    occluder_draws: GrowBuffer,
    /// The GPU's LOD cut with hierarchical occlusion ([`CullingRenderer::submit_tree`]).
    tree_cull: crate::hzb::tree_cull::TreeCull,
    /// Kept and early ids a frame's report copies (grown when a frame needs more).
    report_entries: u32,
    reports: ReportRing<PendingFrame>,
    frames: u64,
    targets: Option<Targets>,
    multi_draw_count: bool,
    /// Timestamps around each pass ([`FRAME_PHASES`]).
    timer: GpuTimer,
    /// Sky, sun and fog.
    pub style: SceneStyle,
}

impl CullingRenderer {
    /// The pyramid the last frame culled against last (its early depth, with the selected
    /// occluders when the pre-pass ran), for debug views; `None` until a frame has made its
    /// targets.
    pub fn pyramid(&self) -> Option<&HzbPyramid> {
        self.targets.as_ref().map(|t| &t.pyramid)
    }

    /// Kept and early ids the next frame's report copies.
    pub fn report_entries(&self) -> u32 {
        self.report_entries
    }

    /// Sets the kept and early ids the next frame's report copies (at least 1; a frame that
    /// lists more grows it again). More up front spares a viewer the first polled reports of a
    /// wide view, which are dropped until the report holds the lists whole.
    pub fn set_report_entries(&mut self, entries: u32) {
        self.report_entries = entries.max(1);
    }

    /// The depth the last frame drew into; `None` until a frame has made its targets.
    pub fn depth(&self) -> Option<&crate::render::DepthTarget> {
        self.targets.as_ref().map(|t| &t.depth)
    }

    /// A renderer drawing into colour targets of `colour_format` (as
    /// [`crate::render::BruteRenderer::new`]).
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> CullingRenderer {
        let device = &gpu.device;
        let layout = crate::render::view_bind_group_layout(device, "frame view");
        let (view_buffer, view_group) =
            crate::render::view_buffer_and_group(device, &layout, "frame view");
        let scene_pipelines =
            crate::render::ScenePipelines::new(device, "frame scene", &layout, colour_format);
        let depth_pipeline =
            crate::render::scene_pipeline(device, "occluder depth", SCENE_WGSL, &layout, None);
        let indirect = wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST;
        let storage = wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST;
        CullingRenderer {
            scene_pipelines,
            depth_pipeline,
            view_buffer,
            view_group,
            early: HzbCull::new(gpu, 1024),
            cull: HzbCull::new(gpu, 1024),
            drawn_early: GrowBuffer::new(device, "drawn early", storage),
            draw_ids: GrowBuffer::new(device, "cut draw ids", storage),
            no_parents: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("no parents"),
                contents: bytemuck::bytes_of(&NO_PARENT),
                usage: wgpu::BufferUsages::STORAGE,
            }),
            occluder_draws: GrowBuffer::new(device, "occluder draws", indirect),
            reports: ReportRing::new(device),
            frames: 0,
            targets: None,
            multi_draw_count: gpu.has(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT),
            tree_cull: crate::hzb::tree_cull::TreeCull::new(gpu),
            report_entries: report_ring::FIRST_LIST_ENTRIES,
            timer: GpuTimer::new(gpu, "frame timer", FRAME_PHASES),
            style: SceneStyle::default(),
        }
    }

    /// Renders one frame of every building of `scene` from `camera` into `colour`
    /// (`width × height`, the format given to [`CullingRenderer::new`]), with `occluders` when
    /// `options.occluders` is set and some are given, and waits for its report. Reads
    /// `visibility` (last frame) and marks it for the next frame.
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
        let frame = FrameScene::Buildings(scene);
        let ticket = self.submit(
            gpu, frame, occluders, options, visibility, camera, colour, size,
        )?;
        self.wait_report(gpu, ticket, (scene, None), visibility)
    }

    /// Renders one frame of the LOD cut `cut` of `lod` (from [`LodScene::select`] for this
    /// camera and viewport: its buildings and cluster meshes are the candidates of the two-phase
    /// frame), otherwise as [`CullingRenderer::render`]. [`FrameOutput::drawn`] lists the
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
        let frame = FrameScene::Lod(lod, &cut.draw_ids);
        let ticket = self.submit(
            gpu, frame, occluders, options, visibility, camera, colour, size,
        )?;
        self.wait_report(gpu, ticket, (&lod.gpu_scene, Some(lod)), visibility)
    }

    fn view_proj(camera: &Camera, (width, height): (u32, u32)) -> Mat4 {
        camera.view_proj(width as f32 / height.max(1) as f32)
    }

    /// Records and submits one frame of `scene` and returns without waiting: the frame script.
    /// Its statistics come later ([`CullingRenderer::wait_report`],
    /// [`CullingRenderer::poll_report`]).
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn submit(
        &mut self,
        gpu: &GpuContext,
        scene: FrameScene<'_>,
        occluders: Option<&OccluderMeshes>,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        colour: &wgpu::TextureView,
        (width, height): (u32, u32),
    ) -> Result<FrameTicket, FrameError> {
        let started = Instant::now();
        let clock = crate::cpu_clock::CpuClock::start();
        self.fit_targets(gpu, width, height)?;
        self.frames += 1;
        let number = self.frames;
        let no_parents = self.no_parents.clone();
        let frame = FrameInputs::of(scene, &no_parents)?;
        let n = frame.candidates;
        if let Some(ids) = frame.lod_ids {
            let bytes: &[u8] = bytemuck::cast_slice(ids);
            self.draw_ids.reserve(&gpu.device, bytes.len() as u64);
            gpu.queue.write_buffer(&self.draw_ids.buffer, 0, bytes);
        }
        let (stamps, frame_stamp) = visibility.begin_frame(gpu, frame.draw_id_count);
        let stamps = stamps.clone();
        let view_proj = Self::view_proj(camera, (width, height));
        let frustum = Frustum::from_view_proj(view_proj);
        let (occluder_meshes, occluders_drawn) =
            select_occluders(occluders, options, camera, &frustum, height);
        let gated = options.occluder_gate && occluder_meshes.is_some();
        let uniforms = view_uniforms(camera, width, height, &self.style);
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let flag_bytes = (n.max(1) * 4) as u64;
        self.drawn_early.reserve(&gpu.device, flag_bytes);
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("culled frame"),
            });
        self.timer.begin_frame();
        encoder.clear_buffer(&self.drawn_early.buffer, 0, Some(flag_bytes));
        self.early.clear_report(&mut encoder);
        self.cull.clear_report(&mut encoder);
        let draw_ids = frame.lod_ids.map(|_| self.draw_ids.buffer.clone());
        let drawn_early = self.drawn_early.buffer.clone();
        let links = CullLinks {
            draw_ids: draw_ids.as_ref(),
            drawn_early: Some(&drawn_early),
            visibility: Some(CullVisibility {
                stamps: &stamps,
                parents: frame.parents,
                frame_stamp,
                building_count: frame.building_count,
            }),
        };
        let cull_input = (frame.records, &frame.geometry.parts_buffer, links);

        // The selected occluders' draws, uploaded once for the gate or the occluder pass.
        let occluders = occluder_meshes.map(|meshes| {
            (
                meshes,
                self.upload_occluder_draws(gpu, meshes, &occluders_drawn),
            )
        });
        match occluders {
            Some(occluders) if gated => {
                self.occluder_gate(&mut encoder, occluders, frame.geometry)?;
                self.early_cull(gpu, &mut encoder, CullEntry::Gate, cull_input, n, view_proj)?;
            }
            _ => self.early_cull(
                gpu,
                &mut encoder,
                CullEntry::Early,
                cull_input,
                n,
                view_proj,
            )?,
        }
        let early_draws = IndirectDraws::of(&self.early);
        self.early_pass(
            &mut encoder,
            frame.geometry,
            (early_draws, n as u32),
            colour,
        );
        if let Some(occluders) = occluders.filter(|_| !gated) {
            self.occluder_pass(&mut encoder, occluders);
        }
        self.build_pyramid(&mut encoder, occluder_meshes.is_some());
        self.cull(gpu, &mut encoder, cull_input, n, view_proj)?;
        let late_draws = IndirectDraws::of(&self.cull);
        self.late_pass(&mut encoder, frame.geometry, (late_draws, n as u32), colour);
        let report = self.record_report(gpu, &mut encoder, n);

        gpu.queue.submit([encoder.finish()]);
        let reported = report.is_some();
        if let Some((ticket, layout, timed)) = report {
            let occluder_triangles = occluder_triangles(occluder_meshes, &occluders_drawn);
            let pending = PendingFrame {
                number,
                buildings: frame.building_count as usize,
                lod_ids: frame.lod_ids.map(<[u32]>::to_vec),
                timed,
                occluders: occluders_drawn,
                occluder_triangles,
                occluder_draws: occluders.map_or(0, |(_, draws)| draws),
                cpu_ms: clock.elapsed_ms(),
                started,
                tree: None,
                lists: Some(ListSources {
                    kept: (
                        self.cull.report_buffer().clone(),
                        u64::from(CULL_R_WORDS) * 4,
                    ),
                    early: (
                        self.early.report_buffer().clone(),
                        u64::from(CULL_R_WORDS + self.early.list_capacity()) * 4,
                    ),
                }),
            };
            self.reports.submitted(ticket, layout, pending);
        }
        Ok(FrameTicket { number, reported })
    }

    /// Waits for the report of the submitted frame `ticket` and reads it; the frame's scene is
    /// `scene` and, for a LOD frame, `lod`. Sets `visibility`'s CPU copy from it.
    pub fn wait_report(
        &mut self,
        gpu: &GpuContext,
        ticket: FrameTicket,
        (scene, lod): (&SceneGpu, Option<&LodScene>),
        visibility: &mut Visibility,
    ) -> Result<FrameOutput, FrameError> {
        if !ticket.reported {
            return Err(FrameError::NoReport(ticket.number));
        }
        let ready = self
            .reports
            .wait(gpu, |p| p.number, |p| p.number == ticket.number)?;
        let slot = ready
            .into_iter()
            .find(|r| r.pending.number == ticket.number)
            .ok_or(FrameError::NoReport(ticket.number))?;
        self.read_report(Some(gpu), slot, (scene, lod), Some(visibility))?
            .ok_or(FrameError::NoReport(ticket.number))
    }

    /// The newest report that is ready, without waiting (older ready ones are dropped); `None`
    /// when none is, when it belongs to a scene other than `scene` / `lod`, or when it is a
    /// tree frame's whose lists outgrew the report (the next reports copy more).
    pub fn poll_report(
        &mut self,
        gpu: &GpuContext,
        (scene, lod): (&SceneGpu, Option<&LodScene>),
    ) -> Result<Option<FrameOutput>, FrameError> {
        let ready = self.reports.take_ready(gpu, |p| p.number)?;
        match ready.into_iter().last() {
            Some(slot) => self.read_report(None, slot, (scene, lod), None),
            None => Ok(None),
        }
    }

    /// The frame's output from its read report slot (`gpu` when the caller waits: a tree
    /// frame's long lists are then read whole); `None` for a frame of another scene.
    fn read_report(
        &mut self,
        gpu: Option<&GpuContext>,
        slot: ReadSlot<PendingFrame>,
        (scene, lod): (&SceneGpu, Option<&LodScene>),
        visibility: Option<&mut Visibility>,
    ) -> Result<Option<FrameOutput>, FrameError> {
        // Reading the report is the frame's CPU work too (a frame or more late).
        let clock = crate::cpu_clock::CpuClock::start();
        let slot_number = slot.pending.number;
        let mut output = if slot.pending.tree.is_some() {
            match lod {
                Some(lod) if lod.building_count as usize == slot.pending.buildings => {
                    self.read_tree_report(gpu, slot, lod, visibility)?
                }
                _ => None,
            }
        } else {
            self.read_candidate_report(gpu, slot, (scene, lod), visibility)?
        };
        let frames_late = self.frames.saturating_sub(slot_number);
        if let Some(output) = &mut output {
            output.stats.cpu_ms += clock.elapsed_ms();
            output.stats.frames_late = u32::try_from(frames_late).unwrap_or(u32::MAX);
        }
        Ok(output)
    }

    /// A candidate frame's output from its read report slot (as
    /// [`CullingRenderer::read_report`]).
    fn read_candidate_report(
        &mut self,
        gpu: Option<&GpuContext>,
        slot: ReadSlot<PendingFrame>,
        (scene, lod): (&SceneGpu, Option<&LodScene>),
        visibility: Option<&mut Visibility>,
    ) -> Result<Option<FrameOutput>, FrameError> {
        let ReadSlot {
            bytes,
            layout,
            pending,
        } = slot;
        // The frame's time to GPU completion (as close as this read gets), before the CPU
        // works on its statistics.
        let frame_ms = pending.started.elapsed().as_secs_f64() * 1e3;
        let n = pending.lod_ids.as_ref().map_or(pending.buildings, Vec::len);
        let header: Vec<u32> = bytemuck::pod_collect_to_vec(
            &bytes[layout.header_at() as usize..layout.status_at() as usize],
        );
        let (early_header, cull_header) = header.split_at(CULL_R_WORDS as usize);
        let listed = |word: u32, header: &[u32]| (header[word as usize] as usize).min(n);
        let counts = (
            listed(CULL_R_KEPT, cull_header),
            listed(CULL_R_EARLY, early_header),
        );
        let sources = pending.lists.as_ref().expect("a candidate frame's lists");
        let Some((kept, early)) = read_lists(
            (&bytes, layout),
            counts,
            sources,
            gpu,
            &mut self.report_entries,
        )?
        else {
            tracing::debug!(
                frame = pending.number,
                kept = counts.0,
                early = counts.1,
                "frame report dropped: its lists outgrew the report"
            );
            return Ok(None);
        };
        let lists = CullLists::new(
            early,
            kept,
            cull_header[CULL_R_OCCLUDED as usize],
            early_header[CULL_R_GATE_CULLED as usize],
        );
        let candidates = match (&pending.lod_ids, lod) {
            (None, _) if scene.building_count() == pending.buildings => {
                Candidates::all_buildings(&scene.records, lists)
            }
            (Some(ids), Some(lod)) if lod.building_count as usize == pending.buildings => {
                Candidates::lod(LodSource::of(lod), ids, lists)
            }
            _ => return Ok(None),
        };
        if let Some(visibility) = visibility {
            candidates.update_visibility(visibility);
        }
        let mut output = candidates.statistics(!self.multi_draw_count);
        let stats = &mut output.stats;
        stats.occluders_drawn = pending.occluders.len() as u32;
        stats.occluder_triangles = pending.occluder_triangles;
        stats.draw_calls += pending.occluder_draws;
        stats.cpu_ms = pending.cpu_ms;
        stats.frame_ms = frame_ms;
        stats.gpu = self
            .timer
            .times_from(&pending.timed, &bytes[..layout.timestamps_bytes as usize]);
        output.occluders = pending.occluders;
        output.lod_cut = pending.lod_ids.is_some();
        Ok(Some(output))
    }

    /// The occluder gate's depth: the ground and the selected occluders alone into the culling
    /// depth, and their pyramid (the gate entry point culls against it).
    fn occluder_gate(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        occluders: (&OccluderMeshes, u32),
        scene: &SceneGpu,
    ) -> Result<(), FrameError> {
        {
            let clear = wgpu::LoadOp::Clear(Camera::DEPTH_CLEAR);
            let mut pass = self.depth_only_pass(encoder, "occluder_gate", clear, "gate_occluders");
            // The ground first, so that the gate's pyramid is the one a frame with no early
            // set would cull everything against (the ground and the occluders).
            pass.set_pipeline(&self.depth_pipeline);
            pass.set_bind_group(0, &self.view_group, &[]);
            scene.bind(&mut pass);
            scene.draw_ground(&mut pass);
            self.draw_occluders(&mut pass, occluders);
        }
        let targets = self.targets.as_ref().expect("fit_targets ran");
        targets.pyramid.build_occluders_timed(
            encoder,
            &targets.cull_depth_view,
            self.timer.compute_pass_writes("gate_pyramid"),
        );
        Ok(())
    }

    /// The early entry point over every candidate: `Gate` against the gate's pyramid, `Early`
    /// by the frustum alone; it writes the early pass's commands and the drawn-early flags.
    fn early_cull(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        entry: CullEntry,
        (records, parts, links): (&wgpu::Buffer, &wgpu::Buffer, CullLinks<'_>),
        n: usize,
        view_proj: Mat4,
    ) -> Result<(), FrameError> {
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let phase = if entry == CullEntry::Gate {
            "gate"
        } else {
            "early_cull"
        };
        self.early.encode_entry(
            gpu,
            encoder,
            (entry, records, Some(parts), links),
            n as u32,
            (&targets.pyramid, view_proj),
            self.timer.compute_pass_writes(phase),
        )?;
        Ok(())
    }

    /// Clears colour and depth, draws the ground and the early entry point's commands (at most
    /// one per candidate of `n`).
    fn early_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        (draws, n): (IndirectDraws<'_>, u32),
        colour: &wgpu::TextureView,
    ) {
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
        self.scene_pipelines.set(&mut pass, scene);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        scene.draw_ground(&mut pass);
        if n > 0 {
            self.indirect_draws(&mut pass, draws, n);
        }
    }

    /// Draws `draws` (at most `max`): through its count where the adapter has
    /// `multi_draw_indexed_indirect_count`, else all `max` slots (those past the count are
    /// zero: empty draws).
    fn indirect_draws(&self, pass: &mut wgpu::RenderPass<'_>, draws: IndirectDraws<'_>, max: u32) {
        if self.multi_draw_count {
            pass.multi_draw_indexed_indirect_count(
                draws.commands,
                0,
                draws.count,
                draws.count_offset,
                max,
            );
        } else {
            pass.multi_draw_indexed_indirect(draws.commands, 0, max);
        }
    }

    /// Writes the draws of the `selected` occluders to the occluder draw buffer, adjacent
    /// ranges merged ([`OccluderMeshes::merged_draws`]); returns how many there are.
    fn upload_occluder_draws(
        &mut self,
        gpu: &GpuContext,
        meshes: &OccluderMeshes,
        selected: &[usize],
    ) -> u32 {
        let draws = meshes.merged_draws(selected);
        let bytes: &[u8] = bytemuck::cast_slice(&draws);
        self.occluder_draws.reserve(&gpu.device, bytes.len() as u64);
        gpu.queue
            .write_buffer(&self.occluder_draws.buffer, 0, bytes);
        draws.len() as u32
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

    /// Draws the `count` occluder draws of this frame ([`CullingRenderer::upload_occluder_draws`]),
    /// depth only.
    fn draw_occluders(
        &self,
        pass: &mut wgpu::RenderPass<'_>,
        (meshes, count): (&OccluderMeshes, u32),
    ) {
        pass.set_pipeline(&self.depth_pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        pass.set_vertex_buffer(0, meshes.vertex_buffer.slice(..));
        pass.set_index_buffer(meshes.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        pass.multi_draw_indexed_indirect(&self.occluder_draws.buffer, 0, count);
    }

    /// The occluders' depth for the pyramid (without the gate; with it they and the ground are
    /// there already): the uploaded occluder draws alone into the cleared culling depth.
    /// [`CullingRenderer::build_pyramid`] merges it with the early depth.
    fn occluder_pass(
        &mut self,
        encoder: &mut wgpu::CommandEncoder,
        occluders: (&OccluderMeshes, u32),
    ) {
        let clear = wgpu::LoadOp::Clear(Camera::DEPTH_CLEAR);
        let mut pass = self.depth_only_pass(encoder, "occluder_pass", clear, "occluders");
        self.draw_occluders(&mut pass, occluders);
    }

    /// Builds the pyramid from the early depth, merged with the occluders' depth (the nearer
    /// of the two kept per pixel, as if the occluders had been drawn into the early depth:
    /// drawing them into a cleared depth of their own saves a full-screen copy).
    fn build_pyramid(&self, encoder: &mut wgpu::CommandEncoder, with_occluders: bool) {
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let timestamps = self.timer.compute_pass_writes("pyramid");
        if with_occluders {
            targets.pyramid.build_merged_timed(
                encoder,
                &targets.depth.view,
                &targets.cull_depth_view,
                timestamps,
            );
        } else {
            targets
                .pyramid
                .build_timed(encoder, &targets.depth.view, timestamps);
        }
    }

    /// Culls every candidate against the pyramid (by its record's parts), skipping the draws
    /// of those the early pass drew, and stamps the visible ones for the next frame.
    fn cull(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        (records, parts, links): (&wgpu::Buffer, &wgpu::Buffer, CullLinks<'_>),
        n: usize,
        view_proj: Mat4,
    ) -> Result<(), FrameError> {
        let targets = self.targets.as_ref().expect("fit_targets ran");
        self.cull.encode_entry(
            gpu,
            encoder,
            (CullEntry::Cull, records, Some(parts), links),
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
        (draws, n): (IndirectDraws<'_>, u32),
        colour: &wgpu::TextureView,
    ) {
        if n == 0 {
            return;
        }
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let mut pass = crate::render::overlay_pass(
            encoder,
            "late_pass",
            colour,
            &targets.depth,
            self.timer.render_pass_writes("late"),
        );
        self.scene_pipelines.set(&mut pass, scene);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        self.indirect_draws(&mut pass, draws, n);
    }

    /// Copies the frame's timestamps, the two cull passes' report headers and the first
    /// [`CullingRenderer::report_entries`] of the kept and early lists into a free report slot
    /// (`None`, and no copies, when every slot is in flight): O(what was drawn) bytes, never a
    /// word per candidate.
    fn record_report(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        n: usize,
    ) -> Option<(report_ring::SlotTicket, SlotLayout, TimedPhases)> {
        let entries = self.report_entries.min(n as u32);
        let layout = SlotLayout {
            timestamps_bytes: self.timer.resolved_bytes(),
            header_words: u64::from(2 * CULL_R_WORDS),
            candidates: u64::from(entries),
        };
        let (ticket, buffer) = self.reports.reserve(gpu, layout)?;
        let timed = self.timer.resolve_to(encoder, buffer, 0);
        let header_bytes = u64::from(CULL_R_WORDS) * 4;
        let (early, cull) = (self.early.report_buffer(), self.cull.report_buffer());
        encoder.copy_buffer_to_buffer(early, 0, buffer, layout.header_at(), header_bytes);
        encoder.copy_buffer_to_buffer(
            cull,
            0,
            buffer,
            layout.header_at() + header_bytes,
            header_bytes,
        );
        if entries > 0 {
            let bytes = u64::from(entries) * 4;
            encoder.copy_buffer_to_buffer(cull, header_bytes, buffer, layout.status_at(), bytes);
            let early_list_at = u64::from(CULL_R_WORDS + self.early.list_capacity()) * 4;
            encoder.copy_buffer_to_buffer(early, early_list_at, buffer, layout.early_at(), bytes);
        }
        Some((ticket, layout, timed))
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
        self.targets = Some(Targets::new(gpu, width, height)?);
        Ok(())
    }
}

/// The occluders a frame draws (`options.occluders`: those whose bounding sphere projects to
/// more than `options.occluder_min_px` pixels, by [`OccluderMeshes::select`]) and their meshes
/// (`None` when none is selected).
fn select_occluders<'a>(
    occluders: Option<&'a OccluderMeshes>,
    options: &CullingOptions,
    camera: &Camera,
    frustum: &Frustum,
    height: u32,
) -> (Option<&'a OccluderMeshes>, Vec<usize>) {
    let selected = match occluders.filter(|_| options.occluders) {
        Some(meshes) => meshes.select(camera, frustum, height, options.occluder_min_px),
        None => Vec::new(),
    };
    (occluders.filter(|_| !selected.is_empty()), selected)
}

/// Triangles of the `selected` occluders of `meshes`.
fn occluder_triangles(meshes: Option<&OccluderMeshes>, selected: &[usize]) -> u64 {
    meshes.map_or(0, |m| {
        selected
            .iter()
            .map(|&i| u64::from(m.occluders[i].triangles))
            .sum()
    })
}

/// Indirect draw commands and the buffer word counting them.
#[derive(Debug, Clone, Copy)]
struct IndirectDraws<'a> {
    commands: &'a wgpu::Buffer,
    count: &'a wgpu::Buffer,
    count_offset: u64,
}

impl<'a> IndirectDraws<'a> {
    fn of(cull: &'a HzbCull) -> IndirectDraws<'a> {
        IndirectDraws {
            commands: cull.commands_buffer(),
            count: cull.count_buffer(),
            count_offset: 0,
        }
    }
}

/// What the frame script reads of a [`FrameScene`].
struct FrameInputs<'a> {
    /// The geometry drawn (vertices, indices, parts, ground).
    geometry: &'a SceneGpu,
    /// The records the cull reads by draw id.
    records: &'a wgpu::Buffer,
    parents: &'a wgpu::Buffer,
    lod_ids: Option<&'a [u32]>,
    building_count: u32,
    draw_id_count: u32,
    candidates: usize,
}

impl<'a> FrameInputs<'a> {
    fn of(
        scene: FrameScene<'a>,
        no_parents: &'a wgpu::Buffer,
    ) -> Result<FrameInputs<'a>, FrameError> {
        Ok(match scene {
            FrameScene::Buildings(s) => FrameInputs {
                geometry: s,
                records: &s.all.as_ref().ok_or(FrameError::NoRecords)?.records_buffer,
                parents: no_parents,
                lod_ids: None,
                building_count: s.building_count() as u32,
                draw_id_count: s.building_count() as u32,
                candidates: s.building_count(),
            },
            FrameScene::Lod(lod, ids) => FrameInputs {
                geometry: &lod.gpu_scene,
                records: &lod.cull_records_buffer,
                parents: &lod.parents_buffer,
                lod_ids: Some(ids),
                building_count: lod.building_count,
                draw_id_count: lod.gpu_scene.records.len() as u32,
                candidates: ids.len(),
            },
        })
    }
}
