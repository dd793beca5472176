//! Buildings and cluster meshes in one GPU scene, so a LOD cut is one
//! [`SelectedRenderer`](crate::render::selected::SelectedRenderer) draw list, or one candidate
//! list of the two-phase occlusion-culled frame
//! ([`CullingRenderer::render_lod`](crate::frame::CullingRenderer::render_lod), which culls
//! clusters by [`LodScene::cull_records_buffer`]).
//!
//! Layout: draw ids `0..building_count` are the buildings (the same ids and geometry as
//! [`crate::scene_gpu::SceneGeometry::from_city`]), then id `building_count + n` is the cluster mesh of tree node
//! `n` (empty for leaves, which draw nothing under that id). One combined scene was chosen
//! over two scenes drawn into the same targets because the selected renderer clears its
//! targets at the start of its pass. The plain scene's buildings are the combined scene's first
//! `building_count` records, so [`LodScene::upload_package`] shares the vertex, index and part
//! buffers with it: the building geometry is on the GPU once.

use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::package::{GpuScene, GpuSceneView};
use citywalk_scenes::{BuildingId, City};
use citywalk_shaders::constants::NO_PARENT;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::hzb::tree_cull::TreeBuffers;
use crate::lod::gpu_tree::TreeArrays;
use crate::lod::{LodCriterion, LodCut, LodTree, LodView, VisibleBlocks};
use crate::scene_gpu::SceneGpu;
use crate::upload::{UploadError, array_buffer};

pub use citywalk_scenes::scene_geometry::{cull_records, draw_id_parents, lod_geometry};

/// The combined scene of buildings and cluster meshes, with the tree the cut walks.
#[derive(Debug)]
pub struct LodScene {
    pub gpu_scene: SceneGpu,
    /// Number of buildings; cluster node `n` has draw id `building_count + n`.
    pub building_count: u32,
    pub tree: LodTree,
    /// The criterion of [`LodScene::default_criterion`]; `None` picks the geometric criterion
    /// at 1 px or 2 px by the camera's altitude ([`LodCriterion::for_altitude`]).
    pub criterion: Option<LodCriterion>,
    /// Per draw id, on the GPU only, the record the occlusion cull of the combined frame tests
    /// ([`crate::frame::CullingRenderer::render_lod`]): a building's own record; a cluster's
    /// record with its bounds widened to contain every building under it (a cluster mesh stops
    /// at its roof height, below its tallest buildings, and culling it by its own
    /// box could hide a building the full-detail scene shows). See [`cull_records`]. The cull
    /// reads a candidate's record by its draw id, so a frame uploads only the cut's draw ids;
    /// the CPU reads the draw records ([`LodScene::gpu_scene`]), whose index ranges are the same.
    pub cull_records_buffer: wgpu::Buffer,
    /// Per draw id, the draw id of the cluster above it ([`draw_id_parents`]), for the GPU's
    /// "visible last frame" test.
    pub parents_buffer: wgpu::Buffer,
    /// The tree as the GPU's LOD cut reads it ([`crate::hzb::tree_cull`]).
    pub tree_gpu: TreeBuffers,
}

/// One frame's LOD selection.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct LodFrame {
    pub cut: LodCut,
    /// Draw ids into [`LodScene::gpu_scene`].
    pub draw_ids: Vec<u32>,
    /// Triangles of the drawn buildings and clusters.
    pub triangles: u64,
}

/// The buildings one draw id covers ([`LodScene::covered_by`]).
#[derive(Debug, Clone)]
pub enum Covered<'a> {
    Building(Option<u32>),
    Cluster(std::slice::Iter<'a, BuildingId>),
}

impl Iterator for Covered<'_> {
    type Item = u32;

    fn next(&mut self) -> Option<u32> {
        match self {
            Covered::Building(b) => b.take(),
            Covered::Cluster(it) => it.next().map(|b| b.0),
        }
    }
}

/// The buildings drawn id `id` of a combined scene of `building_count` buildings and the
/// cluster meshes of `tree` stands for: the building itself (ids below `building_count`) or every
/// building under cluster node `id - building_count` (none for an id out of range).
pub fn covered_by(tree: &ClusterTree, building_count: u32, id: u32) -> Covered<'_> {
    if id < building_count {
        return Covered::Building(Some(id));
    }
    let range = tree
        .nodes
        .get((id - building_count) as usize)
        .and_then(|node| {
            tree.building_order
                .get(node.buildings.0 as usize..node.buildings.1 as usize)
        })
        .unwrap_or(&[]);
    Covered::Cluster(range.iter())
}

impl LodScene {
    /// Meshes and uploads the buildings of `city` and the cluster meshes of `tree` (built from
    /// `city`), as preprocessing does for a package ([`GpuScene::build`]).
    pub fn upload(
        gpu: &GpuContext,
        city: &City,
        tree: ClusterTree,
    ) -> Result<LodScene, UploadError> {
        let scene = GpuScene::build(city, Some(&tree), None);
        let view = scene.view();
        Self::upload_package(gpu, &SceneGpu::upload_package(gpu, &view)?, &view, tree)
    }

    /// The combined scene of a package's GPU scene `view` (with the package's `tree`), over the
    /// buffers of `buildings`, the plain scene [`SceneGpu::upload_package`] made of the same
    /// view: only the records, cull records and parents are uploaded here.
    pub fn upload_package(
        gpu: &GpuContext,
        buildings: &SceneGpu,
        view: &GpuSceneView<'_>,
        tree: ClusterTree,
    ) -> Result<LodScene, UploadError> {
        let release = |bytes: &[u8]| view.release_resident(bytes);
        // Empty arrays (no tree) are one zeroed record and one parent that names none.
        let cull_records_buffer = array_buffer(
            gpu,
            "lod cull records",
            view.cull_records,
            wgpu::BufferUsages::STORAGE,
            &release,
        )?;
        let no_parent = [NO_PARENT];
        let parents = if view.parents.is_empty() {
            &no_parent[..]
        } else {
            view.parents
        };
        let tree = LodTree::new(tree);
        let tree_gpu = TreeBuffers::upload(gpu, &TreeArrays::build(&tree, view.building_count))?;
        Ok(LodScene {
            tree_gpu,
            parents_buffer: array_buffer(
                gpu,
                "lod draw-id parents",
                parents,
                wgpu::BufferUsages::STORAGE,
                &release,
            )?,
            cull_records_buffer,
            gpu_scene: SceneGpu::sharing(buildings, buildings.records.whole(), view.bounds),
            building_count: view.building_count,
            tree,
            criterion: None,
        })
    }

    /// The buildings drawn id `id` stands for ([`covered_by`]).
    pub fn covered_by(&self, id: u32) -> Covered<'_> {
        covered_by(&self.tree.tree, self.building_count, id)
    }

    /// The cut of `camera` on a `width_px`×`height_px` viewport under `criterion` (frustum
    /// culling on the tree; `visible_blocks` as in [`LodTree::cut`]) and what it draws.
    pub fn select(
        &self,
        camera: &Camera,
        width_px: u32,
        height_px: u32,
        criterion: LodCriterion,
        visible_blocks: Option<&VisibleBlocks>,
    ) -> LodFrame {
        let view = LodView::new(camera, width_px, height_px);
        let cut = self.tree.cut(&view, criterion, visible_blocks);
        let draw_ids = self.draw_ids(&cut);
        LodFrame {
            triangles: self.triangles(&draw_ids),
            draw_ids,
            cut,
        }
    }

    /// Buildings `frame` shows, themselves or through a drawn cluster, ascending
    /// ([`LodCut::covered_buildings`]): as many as the clusters stand for, so not computed per
    /// frame, only where a caller needs the set (the benchmark's oracle check).
    pub fn covered(&self, frame: &LodFrame) -> Vec<u32> {
        frame.cut.covered_buildings(&self.tree.tree)
    }

    /// What the benchmark's `lod` mode uses: [`LodScene::criterion`] if set, else the geometric
    /// preset for `camera` ([`LodCriterion::for_altitude`] against the tallest building).
    pub fn default_criterion(&self, camera: &Camera) -> LodCriterion {
        self.criterion
            .unwrap_or_else(|| LodCriterion::for_altitude(camera.position.z, self.tree.top_m()))
    }

    /// The pixel tolerance a frame from `camera` keeps: that of [`LodScene::default_criterion`]
    /// when it is geometric, else the geometric preset's for the camera's altitude (Chang's and
    /// Yang's criteria bound no distance on screen; the bench measures them against it).
    pub fn bound_px(&self, camera: &Camera) -> f32 {
        self.default_criterion(camera)
            .bound_px()
            .unwrap_or_else(|| {
                LodCriterion::tolerance_for_altitude(camera.position.z, self.tree.top_m())
            })
    }

    /// The draw ids of `cut`: its buildings, then its clusters offset by the building count.
    pub fn draw_ids(&self, cut: &LodCut) -> Vec<u32> {
        let mut ids = cut.buildings.clone();
        ids.extend(cut.clusters.iter().map(|&c| self.building_count + c));
        ids
    }

    /// Triangles drawn for `ids` (buildings' and clusters').
    pub fn triangles(&self, ids: &[u32]) -> u64 {
        ids.iter()
            .filter_map(|&i| self.gpu_scene.records.get(i as usize))
            .map(|r| u64::from(r.index_count / 3))
            .sum()
    }
}
