//! The viewer's frame: the scene drawn by the frame runner ([`citywalk_runtime::runner::FrameRunner`]) with
//! the plan the settings ask for, then the debug view, if any, from what that frame drew.

use citywalk_scenes::blocks::UrbanBlocks;
use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::ground_surfaces::GroundSurfaces;
use citywalk_scenes::package::{GpuScene, PackageFile};
use citywalk_scenes::quadtree::BQuadtree;

use super::overlay::StageCounts;
use super::settings::{DebugView, RenderSettings};
use citywalk_runtime::auto::AutoPlanner;
use citywalk_runtime::camera::Camera;
use citywalk_runtime::cluster_textures::ClusterShading;
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::frame::{FrameError, Visibility};
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::pick::{Pick, PickGeometry, Picker, pixel_ray};
use citywalk_runtime::plan::SceneFeatures;
use citywalk_runtime::render::debug::pyramid::GreyRange;
use citywalk_runtime::render::debug::{
    ClusterView, DepthPyramid, OccluderOverlay, OccluderOverlayMeshes, PyramidView,
};
use citywalk_runtime::render::{DepthTarget, OutlineRenderer};
use citywalk_runtime::runner::{Completion, FrameReport, FrameRunner, FrameTarget};
use citywalk_runtime::upload::UploadError;
use citywalk_scenes::cluster_texture::baked::ClusterTextures;

/// What the viewer draws from, on the CPU.
#[derive(Debug)]
pub struct ViewerScene {
    pub city: citywalk_scenes::City,
    /// A scene package's cluster tree (the LOD cut needs it).
    pub cluster_tree: Option<ClusterTree>,
    /// A scene package's urban blocks and B-Quadtree (frustum culling of whole blocks).
    pub blocks: Option<(UrbanBlocks, BQuadtree)>,
    /// A scene package's GPU-ready geometry and virtual occluders (uploaded from the mapping;
    /// `None`: built from the city at load, without occluders, which come from preprocessing).
    pub gpu_scene: Option<GpuScene>,
    /// A scene package's streets and ground areas as surfaces (`None`: built from the city).
    pub ground_surfaces: Option<GroundSurfaces>,
    /// The package the scene was read from, mapped, for what drawing does not decode: a picked
    /// building's levels and tags ([`PackageFile::building_details`]).
    pub package: Option<PackageFile>,
    /// A scene package's baked cluster textures, and the GPU memory they may take (MiB; 0:
    /// the clusters are drawn flat).
    pub cluster_textures: Option<(ClusterTextures, u64)>,
}

impl ViewerScene {
    /// Frees the buildings of a scene that draws from a package's GPU scene, once the collision
    /// world and the start are made from them: nothing else reads them (the upload reads the
    /// mapping), and at a million buildings with their parts they are most of a gigabyte.
    pub fn release_buildings(&mut self) {
        if self.gpu_scene.is_some() {
            self.city.buildings = Vec::new();
        }
    }

    /// What this scene offers to the settings.
    pub fn features(&self) -> SceneFeatures {
        SceneFeatures {
            occluders: self
                .gpu_scene
                .as_ref()
                .is_some_and(|g| !g.view().occluders.records.is_empty()),
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
    runner: FrameRunner,
    drawable: DrawableScene,
    occluder_overlay_meshes: Option<OccluderOverlayMeshes>,
    /// Last frame's visible buildings, carried along the camera stream.
    visibility: Visibility,
    /// The newest report read so far (an HZB frame's comes a frame or more late).
    last_report: Option<FrameReport>,
    /// The `auto` plan's planner, for the LOD setting it was made with.
    auto: Option<(bool, AutoPlanner)>,
    /// Wait for each frame's own report instead of showing the newest ready one: for
    /// screenshots and headless runs, whose counts must be the frame's. The interactive viewer
    /// never waits.
    pub wait_for_reports: bool,
    cluster_view: ClusterView,
    depth_pyramid: DepthPyramid,
    pyramid_view: PyramidView,
    occluder_overlay: OccluderOverlay,
    /// The picked draw's outline, over every frame.
    outline: OutlineRenderer,
    /// The drawn geometry on the CPU, for picking: a package's mapping (no resident copy), or
    /// the arrays built from a raw input.
    geometry: GpuScene,
    /// The BVH over the draws' bounds, built at the first pick.
    picker: Option<Picker>,
    /// The city as the viewer keeps it: a raw input's buildings with their tags, for the pick
    /// panel; a package's buildings are freed ([`ViewerScene::release_buildings`]).
    city: citywalk_scenes::City,
}

impl FrameDrawer {
    /// Uploads `scene` and makes every pipeline for colour targets of `format` (an error when
    /// the scene does not fit the GPU).
    pub fn new(
        gpu: &GpuContext,
        format: wgpu::TextureFormat,
        scene: ViewerScene,
    ) -> Result<FrameDrawer, UploadError> {
        // A raw input is meshed here, as preprocessing does for a package (no occluders).
        let geometry = scene
            .gpu_scene
            .unwrap_or_else(|| GpuScene::build(&scene.city, scene.cluster_tree.as_ref(), None));
        let surfaces = scene
            .ground_surfaces
            .unwrap_or_else(|| GroundSurfaces::build(&scene.city));
        let mut drawable =
            DrawableScene::upload_package(gpu, &geometry, scene.cluster_tree, scene.blocks)?
                .with_surfaces(gpu, &surfaces)?;
        if let Some((textures, budget_mib)) = scene.cluster_textures.filter(|(_, b)| *b > 0) {
            // Textures are a look, not the scene: one that cannot be drawn leaves clusters flat.
            match drawable.add_cluster_textures(gpu, &geometry, textures, budget_mib) {
                Ok(()) => {
                    if let Some(s) = drawable.texturing().map(|t| &t.summary) {
                        tracing::info!(
                            textured = s.textured_clusters,
                            layers = s.layers,
                            page_px = s.page_px,
                            "cluster textures"
                        );
                        if let Some((node, reason)) = s.rejected.first() {
                            tracing::warn!(
                                "{} placed clusters drawn flat (node {node}: {reason})",
                                s.rejected.len()
                            );
                        }
                    }
                }
                Err(e) => tracing::warn!("cluster meshes drawn flat: {e}"),
            }
        }
        let occluder_overlay_meshes = drawable.occluders.as_ref().map(OccluderOverlayMeshes::of);
        Ok(FrameDrawer {
            runner: FrameRunner::new(gpu, format),
            drawable,
            occluder_overlay_meshes,
            visibility: Visibility::default(),
            last_report: None,
            auto: None,
            wait_for_reports: false,
            cluster_view: ClusterView::new(gpu, format),
            depth_pyramid: DepthPyramid::new(gpu),
            pyramid_view: PyramidView::new(gpu, format),
            occluder_overlay: OccluderOverlay::new(gpu, format),
            outline: OutlineRenderer::new(gpu, format),
            geometry,
            picker: None,
            city: scene.city,
        })
    }

    /// The drawn building or cluster mesh under pixel `pixel` of a `size` view from `camera`,
    /// among what the newest frame report says was drawn (every building before the first
    /// report); the BVH is built at the first pick (about a second at a million buildings).
    pub fn pick(&mut self, camera: &Camera, size: (u32, u32), pixel: (f32, f32)) -> Option<Pick> {
        let view = self.geometry.view();
        let picker = self.picker.get_or_insert_with(|| Picker::new(view.records));
        let building_count = view.building_count;
        let mut drawn: Vec<u32> = self
            .last_report
            .as_ref()
            .map(|r| r.ids.clone())
            .unwrap_or_default();
        drawn.sort_unstable();
        let is_drawn = |d: u32| {
            if drawn.is_empty() {
                d < building_count
            } else {
                drawn.binary_search(&d).is_ok()
            }
        };
        let geometry = PickGeometry {
            records: view.records,
            vertices: view.vertices,
            indices: view.indices,
        };
        picker.pick(pixel_ray(camera, size, pixel), geometry, &is_drawn)
    }

    /// Bounds of draw `draw` and, for a cluster mesh, the buildings it stands for.
    pub fn draw_facts(&self, draw: u32) -> (([f32; 3], [f32; 3]), Vec<u32>) {
        let view = self.geometry.view();
        let bounds = view
            .records
            .get(draw as usize)
            .map_or(([0.0; 3], [0.0; 3]), |r| (r.bounds_min_m, r.bounds_max_m));
        let covered = match &self.drawable.lod {
            Some(lod) if draw >= lod.building_count => lod.covered_by(draw).collect(),
            _ => Vec::new(),
        };
        (bounds, covered)
    }

    /// The city as the viewer keeps it (see the field).
    pub fn city(&self) -> &citywalk_scenes::City {
        &self.city
    }

    /// Draws in the scene below this are buildings, the others cluster meshes.
    pub fn building_count(&self) -> u32 {
        self.geometry.view().building_count
    }

    /// Tints and outlines `draw` (a pick) in the frames that follow; `None` clears it. Its
    /// outline is built now from the CPU copy of the geometry; returns its number of edges.
    pub fn set_highlight(&mut self, gpu: &GpuContext, draw: Option<u32>) -> usize {
        self.runner.set_highlight(draw);
        let view = self.geometry.view();
        let geometry = PickGeometry {
            records: view.records,
            vertices: view.vertices,
            indices: view.indices,
        };
        self.outline.set(gpu, geometry, draw)
    }

    /// The pyramid of the last HZB frame and the newest report read (for the window tests).
    #[cfg(test)]
    pub(crate) fn last_frame(
        &self,
    ) -> (
        Option<&citywalk_runtime::hzb::HzbPyramid>,
        Option<&FrameReport>,
    ) {
        (self.runner.pyramid(), self.last_report.as_ref())
    }

    /// Buildings and their triangles in the scene.
    pub fn scene_counts(&self) -> (usize, usize) {
        (
            self.drawable.buildings.building_count(),
            self.drawable.buildings.triangle_count,
        )
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
        let lod = settings.stages.lod;
        let planner = match &mut self.auto {
            Some((made_for, planner)) if *made_for == lod => planner,
            slot => &mut slot.insert((lod, AutoPlanner::new(features, lod))).1,
        };
        let plan = if settings.auto {
            planner.plan_for(camera)
        } else {
            settings.plan(features)
        };
        if let Some(texturing) = self.drawable.texturing() {
            texturing.set_shading(match settings.debug_view {
                DebugView::Bins => ClusterShading::Bins,
                _ if settings.cluster_textures => ClusterShading::Textured,
                _ => ClusterShading::Flat,
            });
        }
        let start = std::time::Instant::now();
        let refs = self.drawable.refs();
        // The cluster view colours what this very frame drew: it waits for the frame's report.
        let wait = self.wait_for_reports || settings.debug_view == DebugView::Clusters;
        let completion = if wait {
            Completion::Wait
        } else {
            Completion::Poll
        };
        let report = self.runner.run(
            gpu,
            refs,
            plan,
            Some(settings.lod.criterion()),
            &mut self.visibility,
            camera,
            FrameTarget {
                colour,
                depth,
                size,
            },
            (completion, false),
        )?;
        if let Some(report) = report {
            if settings.auto
                && let Some((_, planner)) = &mut self.auto
            {
                planner.record(&report);
            }
            self.last_report = Some(report);
        }
        let mut drawn = Drawn {
            hzb: plan.hzb,
            ..Drawn::default()
        };
        if let Some(r) = &self.last_report {
            drawn.ids = r.ids.clone();
            drawn.lod_scene = r.lod_scene;
            drawn.selected_occluders = r.occluders.clone();
            drawn.counts = StageCounts {
                renderer: plan.describe(),
                frustum_culled: r.frustum_culled,
                occlusion_culled: r.occlusion_culled,
                buildings_drawn: r.buildings_drawn,
                clusters_drawn: r.clusters_drawn,
                triangles: r.triangles,
                draw_calls: r.draw_calls,
                surfaces: (r.surfaces.draws, r.surfaces.triangles),
                occluders_drawn: r.occluders_drawn,
                gate_culled: r.gate_culled,
                cpu_ms: 0.0,
                gpu_ms: r.gpu.timed().map(|(p, ms)| (p.to_string(), ms)).collect(),
                debug: None,
                textures: None,
            };
        }
        drawn.counts.textures = self
            .drawable
            .texturing()
            .filter(|_| plan.lod)
            .map(|t| t.residency());
        drawn.counts.renderer = if settings.auto {
            format!("auto: {}", plan.describe())
        } else {
            plan.describe()
        };
        drawn.counts.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        self.draw_debug(gpu, colour, size, camera, settings, &mut drawn)?;
        if self.outline.outlined().is_some() {
            let mut encoder = gpu
                .device
                .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                    label: Some("viewer outline"),
                });
            let depth = self.runner.frame_depth(depth);
            self.outline
                .encode(gpu, &mut encoder, camera, (colour, depth), size);
            gpu.queue.submit([encoder.finish()]);
        }
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
        let scene = match (drawn.lod_scene, self.drawable.lod.as_ref()) {
            (true, Some(lod)) => &lod.gpu_scene,
            _ => &self.drawable.buildings,
        };
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("viewer debug view"),
            });
        match settings.debug_view {
            DebugView::Off => return Ok(()),
            // Drawn by the scene pass itself (the cluster shading set in `draw`).
            DebugView::Bins => {
                drawn.counts.debug = Some(match self.drawable.texturing() {
                    Some(t) if drawn.lod_scene => format!(
                        "{} textured clusters by texture bin",
                        t.summary.textured_clusters
                    ),
                    Some(_) => "bins: switch the LOD cut on (L)".to_string(),
                    None => "this scene has no cluster textures".to_string(),
                });
                return Ok(());
            }
            DebugView::Pyramid => {
                // The culling frame's own pyramid when it drew this frame; otherwise one built
                // the same way from the depth of what was drawn.
                let pyramid = match self.runner.pyramid().filter(|_| drawn.hzb) {
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
