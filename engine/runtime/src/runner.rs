//! The frame runner: carries out a [`FramePlan`] over a scene, the one place where a frame's
//! stages are dispatched, for `render`, `view` and `bench` alike. As a script:
//!
//! ```text
//! resolve       → the plan as the scene can run it (FramePlan::resolve)
//! cpu_cull      → (frustum) urban blocks through the B-Quadtree, or buildings by their boxes
//! lod_cut       → (lod, no tree cull) the CPU's screen-space LOD cut over the visible blocks
//! hzb frame     → (hzb) the two-phase occlusion-culled frame over every building, the CPU's
//!                 cut (crate::frame: occluder gate, early, occluders, pyramid, cull, late), or,
//!                 with lod where the adapter can, the tree cull: the GPU cuts the cluster tree
//!                 inside the frame, culling whole subtrees against the pyramid
//!                 (crate::frame::CullingRenderer::submit_tree)
//! plain pass    → (no hzb) one pass drawing everything, the frustum's buildings or the cut
//! report        → one FrameReport: counts, times, what was drawn
//! ```
//!
//! Without the HZB frame the report is ready when the frame is submitted (its counts are the
//! CPU's own); the HZB frame's report comes from the GPU a frame or more late
//! ([`Completion::Poll`]) unless the caller waits for it ([`Completion::Wait`]).

use std::time::Instant;

use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::frustum::Frustum;
use citywalk_scenes::quadtree::BQuadtree;

use crate::camera::Camera;
use crate::cpu_clock::CpuClock;
use crate::frame::{
    CullingOptions, CullingRenderer, FrameError, FrameOutput, FrameScene, OccluderMeshes,
    Visibility,
};
use crate::gpu::GpuContext;
use crate::gpu_timer::{GpuTimer, GpuTimes};
use crate::hzb::HzbPyramid;
use crate::lod::scene::{LodFrame, LodScene};
use crate::lod::{LodCriterion, LodView, VisibleBlocks};
use crate::plan::{FramePlan, SceneFeatures};
use crate::render::selected::SelectedRenderer;
use crate::render::targets::OffscreenTarget;
use crate::render::{BruteRenderer, DepthTarget, GroundSurfacePass, SurfaceMeshes, SurfaceStats};
use crate::scene_gpu::SceneGpu;

/// The phase of the plain (single-pass) frames: the scene pass.
pub const DRAW_PHASES: &[&str] = &["draw"];

/// What a frame draws from: the scene and the structures its stages need (each `None` when the
/// scene has none).
#[derive(Debug, Clone, Copy)]
pub struct SceneRefs<'a> {
    pub scene: &'a SceneGpu,
    pub lod: Option<&'a LodScene>,
    pub blocks: Option<(&'a UrbanBlocks, &'a BQuadtree)>,
    pub occluders: Option<&'a OccluderMeshes>,
    /// Streets and ground areas, drawn over every frame after its scene passes.
    pub surfaces: Option<&'a SurfaceMeshes>,
}

impl SceneRefs<'_> {
    /// What the scene offers the stages.
    pub fn features(&self) -> SceneFeatures {
        SceneFeatures {
            occluders: self.occluders.is_some_and(|o| !o.occluders.is_empty()),
            cluster_tree: self.lod.is_some(),
            quadtree: self.blocks.is_some(),
        }
    }
}

/// Whether the caller waits for the frame: the benchmark, tests and screenshots do (times to
/// GPU completion, this frame's own HZB counts); the interactive viewer never does.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Completion {
    Wait,
    Poll,
}

/// Where a frame goes.
#[derive(Debug, Clone, Copy)]
pub struct FrameTarget<'a> {
    pub colour: &'a wgpu::TextureView,
    /// Depth for the plain passes (the HZB frame owns its own).
    pub depth: &'a DepthTarget,
    pub size: (u32, u32),
}

impl<'a> FrameTarget<'a> {
    /// The whole of an offscreen target (the benchmark's, `render`'s).
    pub fn offscreen(target: &'a OffscreenTarget) -> FrameTarget<'a> {
        FrameTarget {
            colour: &target.colour_view,
            depth: &target.depth,
            size: (target.width, target.height),
        }
    }
}

/// One frame's report, whatever its plan.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameReport {
    /// The plan as run (resolved against the scene).
    pub plan: FramePlan,
    /// The draw ids drawn index the LOD scene (buildings, then cluster meshes), not the plain
    /// scene.
    pub lod_scene: bool,
    /// Draw ids drawn.
    pub ids: Vec<u32>,
    /// Buildings shown, themselves or through a drawn cluster, ascending: computed when the
    /// caller asks ([`FrameRunner::run`]'s `drawn_set`; the HZB frame always has it).
    pub drawn: Option<Vec<u32>>,
    pub buildings_drawn: u32,
    pub clusters_drawn: Option<u32>,
    pub frustum_culled: Option<u32>,
    pub occlusion_culled: Option<u32>,
    pub occluders_drawn: Option<u32>,
    pub gate_culled: Option<u32>,
    pub triangles: u64,
    pub draw_calls: u32,
    /// CPU wall time of the CPU culling and the LOD cut (ms).
    pub select_ms: f64,
    /// Thread CPU time of the frame's own work: selection, recording, submission, reading its
    /// report (ms).
    pub cpu_ms: f64,
    /// Wall time to GPU completion (ms; [`Completion::Wait`] only, else 0).
    pub frame_ms: f64,
    /// GPU time per pass, where timed ([`DRAW_PHASES`] or [`crate::gpu_timer::FRAME_PHASES`]).
    pub gpu: GpuTimes,
    /// The occluders the HZB frame drew into its pyramid (indices into
    /// [`OccluderMeshes::occluders`]).
    pub occluders: Vec<usize>,
    /// The streets and ground areas drawn (not in `triangles` or `draw_calls`).
    pub surfaces: SurfaceStats,
    /// Frames run after this one before its report came back: 0 unless an HZB frame's report
    /// was polled late ([`Completion::Poll`]), then the HZB frames run since (other plans' frames
    /// in between, which report at once, are not counted).
    pub frames_late: u32,
}

/// Runs frames of any plan: the renderers a plan may need, made once.
#[derive(Debug)]
pub struct FrameRunner {
    brute: BruteRenderer,
    selected: SelectedRenderer,
    culling: CullingRenderer,
    surfaces: GroundSurfacePass,
    timer: GpuTimer,
    /// The last frame was the HZB frame, whose depth is its own.
    last_drew_own_depth: bool,
}

impl FrameRunner {
    pub fn new(gpu: &GpuContext, format: wgpu::TextureFormat) -> FrameRunner {
        FrameRunner {
            brute: BruteRenderer::new(gpu, format),
            selected: SelectedRenderer::new(gpu, format),
            culling: CullingRenderer::new(gpu, format),
            surfaces: GroundSurfacePass::new(gpu, format),
            timer: GpuTimer::new(gpu, "plain frame timer", DRAW_PHASES),
            last_drew_own_depth: false,
        }
    }

    /// Tints the draw `draw` (a picked building or cluster mesh) in every frame from now on;
    /// `None` tints nothing.
    pub fn set_highlight(&mut self, draw: Option<u32>) {
        self.brute.style.highlight = draw;
        self.selected.scene_pass.style.highlight = draw;
        self.culling.style.highlight = draw;
    }

    /// The HZB frame's renderer (its pyramid and style, for debug views).
    pub fn culling(&self) -> &CullingRenderer {
        &self.culling
    }

    /// The depth the last frame left: the HZB frame's own, or else `target`'s (that frame's
    /// [`FrameTarget::depth`]), for a pass drawn over the frame (the pick outline).
    pub fn frame_depth<'a>(&'a self, target: &'a DepthTarget) -> &'a DepthTarget {
        match self.culling.depth() {
            Some(own) if self.last_drew_own_depth => own,
            _ => target,
        }
    }

    /// The pyramid of the last HZB frame.
    pub fn pyramid(&self) -> Option<&HzbPyramid> {
        self.culling.pyramid()
    }

    /// One frame of `plan` over `scene` from `camera` into `target`. `visibility` carries the HZB
    /// frame's visible set along a camera stream (a frame without the HZB frame resets it:
    /// the next culled frame starts from nothing). `criterion` is the LOD criterion (`None`:
    /// [`LodScene::default_criterion`]). `drawn_set` asks for [`FrameReport::drawn`] (the
    /// benchmark's oracle check; a LOD cut's set is as large as what its clusters stand for).
    /// Returns `None` only for an HZB frame under [`Completion::Poll`] whose report is not
    /// ready (the newest ready one of an earlier frame is returned instead when there is one).
    /// A lost device runs no frame: the frame is [`FrameError::DeviceLost`] with wgpu's reason,
    /// also when the device went during it (whatever call failed first).
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn run(
        &mut self,
        gpu: &GpuContext,
        scene: SceneRefs<'_>,
        plan: FramePlan,
        criterion: Option<LodCriterion>,
        visibility: &mut Visibility,
        camera: &Camera,
        target: FrameTarget<'_>,
        wait: (Completion, bool),
    ) -> Result<Option<FrameReport>, FrameError> {
        gpu.alive()?;
        // The cluster textures: this frame's roof view and the page views decoded since the
        // last; what the frame drew asks for the views the next frames need.
        let texturing = scene.lod.and_then(|lod| lod.gpu_scene.texturing.as_ref());
        if let Some(texturing) = texturing {
            texturing.begin_frame(gpu, camera);
        }
        let frame = self.run_frame(
            gpu, scene, plan, criterion, visibility, camera, target, wait,
        );
        gpu.alive()?;
        if let (Some(texturing), Ok(Some(report))) = (texturing, &frame)
            && report.lod_scene
        {
            texturing.note_drawn(gpu, &report.ids);
        }
        frame
    }

    /// [`FrameRunner::run`] on a device that was working when it began.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    fn run_frame(
        &mut self,
        gpu: &GpuContext,
        scene: SceneRefs<'_>,
        plan: FramePlan,
        criterion: Option<LodCriterion>,
        visibility: &mut Visibility,
        camera: &Camera,
        target: FrameTarget<'_>,
        (completion, drawn_set): (Completion, bool),
    ) -> Result<Option<FrameReport>, FrameError> {
        let plan = plan.resolve(scene.features());
        self.last_drew_own_depth = plan.hzb;
        let start = Instant::now();
        let cpu = CpuClock::start();
        let (width, height) = target.size;
        // The GPU computes the cut inside the HZB frame where the adapter can (the tree cull);
        // the CPU cuts otherwise.
        let gpu_cut = match scene.lod {
            Some(lod) if plan.lod && plan.hzb && plan.frustum && self.culling.runs_tree(lod) => {
                Some((
                    lod,
                    criterion.unwrap_or_else(|| lod.default_criterion(camera)),
                ))
            }
            _ => None,
        };
        let cut = match (plan.lod && gpu_cut.is_none(), scene.lod) {
            (true, Some(lod)) => Some((
                lod,
                lod_cut(lod, scene.blocks, camera, target.size, criterion, plan),
            )),
            _ => None,
        };
        if plan.hzb {
            let select_ms = start.elapsed().as_secs_f64() * 1e3;
            let select_cpu_ms = cpu.elapsed_ms();
            let frame = match (gpu_cut, &cut) {
                (Some((lod, criterion)), _) => HzbFrame::Tree(lod, criterion),
                (None, Some((lod, cut))) => HzbFrame::Cut(lod, cut),
                (None, None) => HzbFrame::Buildings,
            };
            return self.run_hzb(
                gpu,
                scene,
                plan,
                frame,
                visibility,
                camera,
                target,
                completion,
                (select_ms, select_cpu_ms),
            );
        }
        visibility.reset();
        let timed = completion == Completion::Wait;
        self.timer.begin_frame();
        let writes = || {
            if timed {
                self.timer.render_pass_writes("draw")
            } else {
                None
            }
        };
        let n = scene.scene.building_count() as u32;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("plain frame"),
            });
        let mut report = FrameReport {
            plan,
            ..FrameReport::default()
        };
        match &cut {
            Some((lod, cut)) => {
                report.select_ms = start.elapsed().as_secs_f64() * 1e3;
                report.draw_calls = self.selected.encode_timed(
                    gpu,
                    &mut encoder,
                    &lod.gpu_scene,
                    camera,
                    &cut.draw_ids,
                    (target.colour, target.depth),
                    writes(),
                );
                let covered = cut.cut.covered_count(&lod.tree.tree) as u32;
                report.lod_scene = true;
                report.ids = cut.draw_ids.clone();
                report.buildings_drawn = covered;
                report.clusters_drawn = Some(cut.cut.clusters.len() as u32);
                report.frustum_culled = plan.frustum.then(|| n.saturating_sub(covered));
                report.triangles = cut.triangles;
                if drawn_set {
                    report.drawn = Some(lod.covered(cut));
                }
            }
            None if plan.frustum => {
                let frustum =
                    Frustum::from_view_proj(camera.view_proj(width as f32 / height.max(1) as f32));
                let ids = match scene.blocks.filter(|_| plan.quadtree) {
                    Some((blocks, tree)) => buildings_of_visible_blocks(blocks, tree, &frustum),
                    None => scene.scene.buildings_in_frustum(&frustum),
                };
                report.select_ms = start.elapsed().as_secs_f64() * 1e3;
                report.draw_calls = self.selected.encode_timed(
                    gpu,
                    &mut encoder,
                    scene.scene,
                    camera,
                    &ids,
                    (target.colour, target.depth),
                    writes(),
                );
                report.frustum_culled = Some(n.saturating_sub(ids.len() as u32));
                report.buildings_drawn = ids.len() as u32;
                report.triangles = building_triangles(scene.scene, &ids);
                report.drawn = drawn_set.then(|| ids.clone());
                report.ids = ids;
            }
            None => {
                self.brute.encode_timed(
                    gpu,
                    &mut encoder,
                    scene.scene,
                    camera,
                    target.colour,
                    target.depth,
                    writes(),
                );
                report.ids = (0..n).collect();
                report.draw_calls = n + 1;
                report.buildings_drawn = n;
                report.triangles = scene.scene.triangle_count as u64;
                report.drawn = drawn_set.then(|| report.ids.clone());
            }
        }
        if let Some(meshes) = scene.surfaces {
            report.surfaces = self.surfaces.encode(
                gpu,
                &mut encoder,
                meshes,
                camera,
                (target.colour, target.depth),
                &self.brute.style,
            );
        }
        if timed {
            self.timer.resolve(&mut encoder);
        }
        gpu.queue.submit([encoder.finish()]);
        report.cpu_ms = cpu.elapsed_ms();
        if timed {
            gpu.wait_idle();
            report.frame_ms = start.elapsed().as_secs_f64() * 1e3;
            report.gpu = self.timer.read(gpu)?;
        }
        Ok(Some(report))
    }

    /// The HZB frame over every building or over the cut's candidates.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    fn run_hzb(
        &mut self,
        gpu: &GpuContext,
        scene: SceneRefs<'_>,
        plan: FramePlan,
        frame: HzbFrame<'_>,
        visibility: &mut Visibility,
        camera: &Camera,
        target: FrameTarget<'_>,
        completion: Completion,
        select: (f64, f64),
    ) -> Result<Option<FrameReport>, FrameError> {
        let options = CullingOptions {
            occluders: plan.occluders,
            occluder_gate: plan.occluder_gate,
            ..CullingOptions::default()
        };
        let occluders = scene.occluders.filter(|_| plan.occluders);
        let frame_scene = match frame {
            HzbFrame::Tree(lod, criterion) => Err((lod, criterion)),
            HzbFrame::Cut(lod, cut) => Ok(FrameScene::Lod(lod, &cut.draw_ids)),
            HzbFrame::Buildings => Ok(FrameScene::Buildings(scene.scene)),
        };
        let ticket = match frame_scene {
            Err((lod, criterion)) => self.culling.submit_tree(
                gpu,
                lod,
                criterion,
                occluders,
                &options,
                visibility,
                camera,
                target.colour,
                target.size,
            )?,
            Ok(frame_scene) => self.culling.submit(
                gpu,
                frame_scene,
                occluders,
                &options,
                visibility,
                camera,
                target.colour,
                target.size,
            )?,
        };
        let surfaces = self.hzb_surfaces(gpu, scene, camera, target);
        let mut report =
            self.finish_hzb(gpu, scene, plan, ticket, visibility, completion, select)?;
        if let Some(report) = &mut report {
            report.surfaces = surfaces;
        }
        Ok(report)
    }

    /// The ground-surface pass over the HZB frame just submitted (its own depth target), in a
    /// submission of its own that the frame's completion waits for too.
    fn hzb_surfaces(
        &self,
        gpu: &GpuContext,
        scene: SceneRefs<'_>,
        camera: &Camera,
        target: FrameTarget<'_>,
    ) -> SurfaceStats {
        let (Some(meshes), Some(depth)) = (scene.surfaces, self.culling.depth()) else {
            return SurfaceStats::default();
        };
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("ground surfaces"),
            });
        let stats = self.surfaces.encode(
            gpu,
            &mut encoder,
            meshes,
            camera,
            (target.colour, depth),
            &self.brute.style,
        );
        gpu.queue.submit([encoder.finish()]);
        stats
    }

    /// Waits for or polls the report of the HZB frame `ticket`.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    fn finish_hzb(
        &mut self,
        gpu: &GpuContext,
        scene: SceneRefs<'_>,
        plan: FramePlan,
        ticket: crate::frame::FrameTicket,
        visibility: &mut Visibility,
        completion: Completion,
        (select_ms, select_cpu_ms): (f64, f64),
    ) -> Result<Option<FrameReport>, FrameError> {
        let scenes = (scene.scene, scene.lod);
        let output = match completion {
            Completion::Wait => Some(self.culling.wait_report(gpu, ticket, scenes, visibility)?),
            Completion::Poll => self.culling.poll_report(gpu, scenes)?,
        };
        let Some(output) = output else {
            return Ok(None);
        };
        let mut report = hzb_report(plan, output, scene);
        report.select_ms = select_ms;
        report.cpu_ms += select_cpu_ms;
        if completion == Completion::Wait {
            report.frame_ms += select_ms;
        }
        Ok(Some(report))
    }
}

/// What an HZB frame culls: every building, the CPU's LOD cut, or a cut the GPU computes
/// under a criterion (the tree cull).
#[derive(Debug, Clone, Copy)]
enum HzbFrame<'a> {
    Buildings,
    Cut(&'a LodScene, &'a LodFrame),
    Tree(&'a LodScene, LodCriterion),
}

/// The report of an HZB frame from its output (this frame's, or with [`Completion::Poll`] an
/// earlier one's). A LOD frame's draw ids are the buildings drawn themselves and the drawn
/// clusters (offset by the building count).
fn hzb_report(plan: FramePlan, output: FrameOutput, scene: SceneRefs<'_>) -> FrameReport {
    let s = &output.stats;
    let (lod_scene, ids) = match scene.lod {
        Some(lod) if output.lod_cut => (
            true,
            output
                .drawn_themselves
                .iter()
                .copied()
                .chain(output.clusters.iter().map(|&c| lod.building_count + c))
                .collect(),
        ),
        _ => (false, output.drawn.clone()),
    };
    FrameReport {
        plan,
        lod_scene,
        ids,
        buildings_drawn: s.drawn,
        clusters_drawn: lod_scene.then_some(s.clusters_drawn),
        frustum_culled: Some(s.frustum_culled),
        occlusion_culled: Some(s.occlusion_culled),
        occluders_drawn: plan.occluders.then_some(s.occluders_drawn),
        gate_culled: plan.occluder_gate.then_some(s.gate_culled),
        triangles: s.triangles,
        draw_calls: s.draw_calls,
        select_ms: 0.0,
        cpu_ms: s.cpu_ms,
        frame_ms: s.frame_ms,
        gpu: s.gpu.clone(),
        occluders: output.occluders.clone(),
        drawn: Some(output.drawn),
        surfaces: SurfaceStats::default(),
        frames_late: s.frames_late,
    }
}

/// Triangles of the buildings `ids` of `scene`.
fn building_triangles(scene: &SceneGpu, ids: &[u32]) -> u64 {
    ids.iter()
        .filter_map(|&b| scene.records.get(b as usize))
        .map(|r| u64::from(r.index_count / 3))
        .sum()
}

/// The buildings of the urban blocks the B-Quadtree finds in `frustum`, ascending (Pina et al.
/// 2013 §3-4: hierarchical frustum culling of whole blocks).
pub fn buildings_of_visible_blocks(
    blocks: &UrbanBlocks,
    quadtree: &BQuadtree,
    frustum: &Frustum,
) -> Vec<u32> {
    let mut out: Vec<u32> = quadtree
        .cull(frustum)
        .into_iter()
        .filter_map(|block| blocks.blocks.get(block as usize))
        .flat_map(|block| block.buildings.iter().map(|b| b.0))
        .collect();
    out.sort_unstable();
    out
}

/// The urban blocks the B-Quadtree finds in the frustum of `camera` on a
/// `width_px`×`height_px` viewport (Pina et al. 2013 §4), of `block_count`: the
/// `visible_blocks` argument of [`LodScene::select`], made in the time of the blocks in view.
pub fn visible_blocks(
    quadtree: &BQuadtree,
    block_count: usize,
    camera: &Camera,
    width_px: u32,
    height_px: u32,
) -> VisibleBlocks {
    let aspect = width_px.max(1) as f32 / height_px.max(1) as f32;
    let frustum = Frustum::from_view_proj(camera.view_proj(aspect));
    let mut ids = quadtree.cull(&frustum);
    ids.sort_unstable();
    ids.dedup();
    VisibleBlocks {
        ids,
        block_count: u32::try_from(block_count).unwrap_or(u32::MAX),
    }
}

/// The LOD cut of `plan` (resolved): after B-Quadtree culling of the urban blocks when
/// `plan.quadtree`, with the tree's own frustum test when `plan.frustum`, under `criterion`
/// (`None`: [`LodScene::default_criterion`]).
pub fn lod_cut(
    lod: &LodScene,
    blocks: Option<(&UrbanBlocks, &BQuadtree)>,
    camera: &Camera,
    (width, height): (u32, u32),
    criterion: Option<LodCriterion>,
    plan: FramePlan,
) -> LodFrame {
    let criterion = criterion.unwrap_or_else(|| lod.default_criterion(camera));
    if !plan.frustum {
        let view = LodView::new(camera, width, height).without_culling();
        let cut = lod.tree.cut(&view, criterion, None);
        let draw_ids = lod.draw_ids(&cut);
        return LodFrame {
            triangles: lod.triangles(&draw_ids),
            draw_ids,
            cut,
        };
    }
    let visible = blocks
        .filter(|_| plan.quadtree)
        .map(|(b, tree)| visible_blocks(tree, b.blocks.len(), camera, width, height));
    lod.select(camera, width, height, criterion, visible.as_ref())
}
