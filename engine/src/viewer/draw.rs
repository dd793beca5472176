//! The viewer's frame: the scene drawn along the [`DrawPath`] the settings ask for (brute force,
//! CPU frustum / B-Quadtree culling, the LOD cut, the two-phase HZB frame, or the LOD cut
//! through the HZB frame), then the debug view, if any, from what that frame drew.

use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::frustum::Frustum;
use citywalk_scenes::occluder::OccluderSet;
use citywalk_scenes::quadtree::BQuadtree;

use super::overlay::StageCounts;
use super::settings::{DebugView, DrawPath, RenderSettings, SceneFeatures};
use crate::bench::mode::{CullingData, Mode, select, visible_blocks};
use crate::camera::Camera;
use crate::frame::{
    CullingOptions, CullingRenderer, FrameError, FrameOutput, FrameScene, OccluderMeshes,
    Visibility,
};
use crate::gpu::GpuContext;
use crate::lod::LodView;
use crate::lod::scene::{LodFrame, LodScene};
use crate::render::debug::pyramid::GreyRange;
use crate::render::debug::{
    ClusterView, DepthPyramid, OccluderOverlay, OccluderOverlayMeshes, PyramidView,
};
use crate::render::selected::SelectedRenderer;
use crate::render::{BruteRenderer, DepthTarget};
use crate::scene_gpu::SceneGpu;

/// What the viewer draws from, on the CPU.
#[derive(Debug)]
pub struct ViewerScene {
    pub city: citywalk_scenes::City,
    /// A scene package's virtual occluders.
    pub occluders: Option<OccluderSet>,
    /// A scene package's cluster tree (the LOD cut needs it).
    pub cluster_tree: Option<ClusterTree>,
    /// A scene package's urban blocks and B-Quadtree (frustum culling of whole blocks).
    pub blocks: Option<(UrbanBlocks, BQuadtree)>,
}

impl ViewerScene {
    /// What this scene offers to the settings.
    pub fn features(&self) -> SceneFeatures {
        SceneFeatures {
            occluders: self
                .occluders
                .as_ref()
                .is_some_and(|o| !o.occluders.is_empty()),
            cluster_tree: self.cluster_tree.is_some(),
            quadtree: self.blocks.is_some(),
        }
    }
}

/// What a frame drew, for the overlay and the debug views.
#[derive(Debug, Clone, Default)]
pub struct Drawn {
    pub counts: StageCounts,
    /// Draw ids drawn (into the LOD scene when `lod_scene`, else the plain scene).
    pub ids: Vec<u32>,
    pub lod_scene: bool,
    /// The frame went through the two-phase HZB renderer (its pyramid is the frame's).
    pub hzb: bool,
    /// The occluders the pre-pass selected, indices into [`OccluderMeshes::occluders`] (the
    /// rule of [`OccluderMeshes::select`], recomputed from the visible set the frame started
    /// with).
    pub selected_occluders: Vec<usize>,
}

/// Every renderer and GPU resource of the viewer's frame.
#[derive(Debug)]
pub struct FrameDrawer {
    brute: BruteRenderer,
    selected: SelectedRenderer,
    culling: CullingRenderer,
    scene: SceneGpu,
    lod: Option<LodScene>,
    blocks: Option<(UrbanBlocks, BQuadtree)>,
    occluders: Option<OccluderMeshes>,
    occluder_overlay_meshes: Option<OccluderOverlayMeshes>,
    /// Last frame's visible buildings, carried along the camera stream.
    visibility: Visibility,
    /// The newest report of the HZB frame read so far (reports come a frame or more late), and
    /// whether it was drawn with the LOD scene.
    last_report: Option<(FrameOutput, bool)>,
    /// Wait for each HZB frame's own report instead of showing the newest ready one: for
    /// screenshots and headless runs, whose counts must be the frame's. The interactive viewer
    /// never waits.
    pub wait_for_reports: bool,
    cluster_view: ClusterView,
    depth_pyramid: DepthPyramid,
    pyramid_view: PyramidView,
    occluder_overlay: OccluderOverlay,
}

impl FrameDrawer {
    /// Uploads `scene` and makes every pipeline for colour targets of `format`.
    pub fn new(gpu: &GpuContext, format: wgpu::TextureFormat, scene: ViewerScene) -> FrameDrawer {
        let occluders = scene.occluders.filter(|o| !o.occluders.is_empty());
        FrameDrawer {
            brute: BruteRenderer::new(gpu, format),
            selected: SelectedRenderer::new(gpu, format),
            culling: CullingRenderer::new(gpu, format),
            scene: SceneGpu::upload_city(gpu, &scene.city),
            lod: scene
                .cluster_tree
                .map(|tree| LodScene::upload(gpu, &scene.city, tree)),
            blocks: scene.blocks,
            occluder_overlay_meshes: occluders
                .as_ref()
                .map(|set| OccluderOverlayMeshes::upload(gpu, set)),
            occluders: occluders
                .as_ref()
                .map(|set| OccluderMeshes::upload(gpu, set)),
            visibility: Visibility::default(),
            last_report: None,
            wait_for_reports: false,
            cluster_view: ClusterView::new(gpu, format),
            depth_pyramid: DepthPyramid::new(gpu),
            pyramid_view: PyramidView::new(gpu, format),
            occluder_overlay: OccluderOverlay::new(gpu, format),
        }
    }

    /// Buildings and their triangles in the scene.
    pub fn scene_counts(&self) -> (usize, usize) {
        (self.scene.building_count(), self.scene.triangle_count)
    }

    /// Draws one frame from `camera` into `colour` (`width × height`; `depth` of that size for
    /// the passes that do not own theirs), then the debug view of `settings`.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn draw(
        &mut self,
        gpu: &GpuContext,
        colour: &wgpu::TextureView,
        depth: &DepthTarget,
        size: (u32, u32),
        camera: &Camera,
        settings: &RenderSettings,
        features: SceneFeatures,
    ) -> Result<Drawn, FrameError> {
        let path = settings.draw_path(features);
        let mut drawn = self.draw_scene(gpu, colour, depth, size, camera, settings, path)?;
        if !matches!(path, DrawPath::Hzb { .. } | DrawPath::LodHzb { .. }) {
            // Frames without the HZB frame start the next culled one from nothing.
            self.visibility.reset();
        }
        drawn.counts.renderer = path.describe().to_string();
        self.draw_debug(gpu, colour, size, camera, settings, &mut drawn)?;
        Ok(drawn)
    }

    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    fn draw_scene(
        &mut self,
        gpu: &GpuContext,
        colour: &wgpu::TextureView,
        depth: &DepthTarget,
        (width, height): (u32, u32),
        camera: &Camera,
        settings: &RenderSettings,
        path: DrawPath,
    ) -> Result<Drawn, FrameError> {
        let start = std::time::Instant::now();
        let n = self.scene.building_count() as u32;
        let aspect = width as f32 / height.max(1) as f32;
        let frustum = Frustum::from_view_proj(camera.view_proj(aspect));
        let mut drawn = Drawn::default();
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("viewer frame"),
            });
        match path {
            DrawPath::Brute => {
                self.brute
                    .encode(gpu, &mut encoder, &self.scene, camera, colour, depth);
                drawn.ids = (0..n).collect();
                drawn.counts.draw_calls = n + 1;
            }
            DrawPath::Frustum { quadtree } => {
                let ids = match (&self.blocks, quadtree) {
                    (Some((blocks, tree)), true) => select(
                        Mode::Quadtree,
                        &CullingData {
                            scene: &self.scene,
                            blocks,
                            quadtree: tree,
                        },
                        camera.view_proj(aspect),
                        None,
                    ),
                    _ => None,
                }
                .unwrap_or_else(|| self.scene.buildings_in_frustum(&frustum));
                drawn.counts.frustum_culled = Some(n.saturating_sub(ids.len() as u32));
                drawn.counts.draw_calls = self.selected.encode(
                    gpu,
                    &mut encoder,
                    &self.scene,
                    camera,
                    &ids,
                    colour,
                    depth,
                );
                drawn.ids = ids;
            }
            DrawPath::Lod { frustum, quadtree } => {
                let lod = self
                    .lod
                    .as_ref()
                    .expect("the path has LOD only with a tree");
                let cut = lod_cut(
                    lod,
                    self.blocks.as_ref(),
                    camera,
                    (width, height),
                    settings,
                    frustum,
                    quadtree,
                );
                let covered = cut.cut.covered_count(&lod.tree.tree) as u32;
                drawn.counts.frustum_culled = Some(n.saturating_sub(covered));
                drawn.counts.clusters_drawn = Some(cut.cut.clusters.len() as u32);
                drawn.counts.buildings_drawn = covered;
                drawn.counts.triangles = cut.triangles;
                drawn.counts.draw_calls = self.selected.encode(
                    gpu,
                    &mut encoder,
                    &lod.gpu_scene,
                    camera,
                    &cut.draw_ids,
                    colour,
                    depth,
                );
                drawn.ids = cut.draw_ids;
                drawn.lod_scene = true;
            }
            DrawPath::Hzb { occluders } | DrawPath::LodHzb { occluders, .. } => {
                drop(encoder);
                return self.draw_hzb(
                    gpu,
                    colour,
                    (width, height),
                    camera,
                    settings,
                    path,
                    occluders,
                );
            }
        }
        gpu.queue.submit([encoder.finish()]);
        if !drawn.lod_scene {
            drawn.counts.buildings_drawn = drawn.ids.len() as u32;
            drawn.counts.triangles = drawn
                .ids
                .iter()
                .filter_map(|&b| self.scene.records.get(b as usize))
                .map(|r| u64::from(r.index_count / 3))
                .sum();
        }
        drawn.counts.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(drawn)
    }

    /// The two-phase HZB frame, over every building or over the LOD cut's candidates.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    fn draw_hzb(
        &mut self,
        gpu: &GpuContext,
        colour: &wgpu::TextureView,
        size: (u32, u32),
        camera: &Camera,
        settings: &RenderSettings,
        path: DrawPath,
        with_occluders: bool,
    ) -> Result<Drawn, FrameError> {
        let options = CullingOptions {
            occluders: with_occluders,
            occluder_gate: settings.stages.occluder_gate,
            ..CullingOptions::default()
        };
        let occluders = self.occluders.as_ref().filter(|_| with_occluders);
        let mut drawn = Drawn::default();
        // The LOD cut when the frame draws one, else every building: the candidates the
        // occluder selection and the cull start from.
        let lod_frame = match (path, self.lod.as_ref()) {
            (
                DrawPath::LodHzb {
                    frustum: tree_frustum,
                    quadtree,
                    ..
                },
                Some(lod),
            ) => {
                let cut = lod_cut(
                    lod,
                    self.blocks.as_ref(),
                    camera,
                    size,
                    settings,
                    tree_frustum,
                    quadtree,
                );
                Some((lod, cut))
            }
            _ => None,
        };
        drawn.hzb = true;
        let start = std::time::Instant::now();
        let frame = match &lod_frame {
            Some((lod, cut)) => FrameScene::Lod(lod, &cut.draw_ids),
            None => FrameScene::Buildings(&self.scene),
        };
        let ticket = self.culling.submit(
            gpu,
            frame,
            occluders,
            &options,
            &mut self.visibility,
            camera,
            colour,
            size,
        )?;
        let scenes = (&self.scene, self.lod.as_ref());
        // The cluster view colours what this very frame drew: it waits for the frame's report.
        let wait = self.wait_for_reports || settings.debug_view == DebugView::Clusters;
        let report = if wait {
            Some(
                self.culling
                    .wait_report(gpu, ticket, scenes, &mut self.visibility)?,
            )
        } else {
            self.culling.poll_report(gpu, scenes)?
        };
        if let Some(output) = report {
            self.last_report = Some((output, lod_frame.is_some()));
        }
        let frame_cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        let Some((output, lod_report)) = &self.last_report else {
            drawn.counts.cpu_ms = frame_cpu_ms;
            return Ok(drawn);
        };
        match (*lod_report, &lod_frame) {
            (true, Some((lod, cut))) => {
                // Buildings of the cut drawn themselves, and the clusters drawn. (A landmark the
                // cull hid beside a drawn cluster that contains it is listed too: the frame
                // reports buildings covered, not the draw ids it kept.)
                drawn.ids = cut
                    .cut
                    .buildings
                    .iter()
                    .copied()
                    .filter(|b| output.drawn.binary_search(b).is_ok())
                    .chain(output.clusters.iter().map(|&c| lod.building_count + c))
                    .collect();
                drawn.lod_scene = true;
                drawn.counts.clusters_drawn = Some(output.stats.clusters_drawn);
            }
            _ => drawn.ids = output.drawn.clone(),
        }
        let s = &output.stats;
        let counts = &mut drawn.counts;
        counts.frustum_culled = Some(s.frustum_culled);
        counts.occlusion_culled = Some(s.occlusion_culled);
        counts.buildings_drawn = s.drawn;
        counts.triangles = s.triangles;
        counts.draw_calls = s.draw_calls;
        counts.occluders_drawn = occluders.map(|_| s.occluders_drawn);
        counts.gate_culled = occluders
            .filter(|_| options.occluder_gate)
            .map(|_| s.gate_culled);
        counts.cpu_ms = frame_cpu_ms;
        counts.gpu_ms = s.gpu.timed().map(|(p, ms)| (p.to_string(), ms)).collect();
        drawn.selected_occluders = output.occluders.clone();
        Ok(drawn)
    }

    /// The debug view of `settings` over (or instead of) the frame just drawn into `colour`.
    fn draw_debug(
        &mut self,
        gpu: &GpuContext,
        colour: &wgpu::TextureView,
        size: (u32, u32),
        camera: &Camera,
        settings: &RenderSettings,
        drawn: &mut Drawn,
    ) -> Result<(), FrameError> {
        let scene = match (drawn.lod_scene, self.lod.as_ref()) {
            (true, Some(lod)) => &lod.gpu_scene,
            _ => &self.scene,
        };
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("viewer debug view"),
            });
        match settings.debug_view {
            DebugView::Off => return Ok(()),
            DebugView::Pyramid => {
                // The culling frame's own pyramid when it drew this frame; otherwise one built
                // the same way from the depth of what was drawn.
                let pyramid = match self.culling.pyramid().filter(|_| drawn.hzb) {
                    Some(pyramid) => pyramid,
                    None => self.depth_pyramid.encode(
                        gpu,
                        &mut encoder,
                        scene,
                        camera,
                        &drawn.ids,
                        size,
                    )?,
                };
                let (min, max) = scene.bounds;
                let range = GreyRange::for_bounds(camera.near_m, camera.position, min, max);
                let level = self.pyramid_view.encode(
                    gpu,
                    &mut encoder,
                    pyramid,
                    settings.mip_level,
                    &range,
                    colour,
                );
                let (w, h) = pyramid.level_size(level);
                drawn.counts.debug = Some(format!(
                    "pyramid level {level} of {} ({w}×{h})",
                    pyramid.level_count()
                ));
            }
            DebugView::Clusters => {
                let draws = self.cluster_view.encode(
                    gpu,
                    &mut encoder,
                    scene,
                    camera,
                    &drawn.ids,
                    colour,
                    size,
                );
                drawn.counts.debug = Some(format!("{} entries coloured", draws - 1));
            }
            DebugView::Occluders => match &self.occluder_overlay_meshes {
                Some(meshes) => {
                    let highlighted = self.occluder_overlay.encode(
                        gpu,
                        &mut encoder,
                        meshes,
                        camera,
                        &drawn.selected_occluders,
                        colour,
                        size,
                    );
                    drawn.counts.debug = Some(format!(
                        "{} occluders, {highlighted} selected",
                        meshes.ranges.len()
                    ));
                }
                None => drawn.counts.debug = Some("this scene has no occluders".to_string()),
            },
        }
        gpu.queue.submit([encoder.finish()]);
        Ok(())
    }
}

/// The LOD cut of `settings`' criterion: after B-Quadtree culling of urban blocks when
/// `quadtree`, with the tree's frustum test when `frustum`.
fn lod_cut(
    lod: &LodScene,
    blocks: Option<&(UrbanBlocks, BQuadtree)>,
    camera: &Camera,
    (width, height): (u32, u32),
    settings: &RenderSettings,
    frustum: bool,
    quadtree: bool,
) -> LodFrame {
    let criterion = settings.lod.criterion();
    if !frustum {
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
        .filter(|_| quadtree)
        .map(|(b, tree)| visible_blocks(tree, b.blocks.len(), camera, width, height));
    lod.select(camera, width, height, criterion, visible.as_deref())
}
