//! Buildings and cluster meshes in one GPU scene, so a LOD cut is one
//! [`SelectedRenderer`](crate::render::selected::SelectedRenderer) draw list, or one candidate
//! list of the two-phase occlusion-culled frame
//! ([`CullingRenderer::render_lod`](crate::frame::CullingRenderer::render_lod), which culls
//! clusters by [`LodScene::cull_records`]).
//!
//! Layout: draw ids `0..building_count` are the buildings (the same ids and geometry as
//! [`SceneGeometry::from_city`]), then id `building_count + n` is the cluster mesh of tree node
//! `n` (empty for leaves, which draw nothing under that id). One combined scene was chosen
//! over two scenes drawn into the same targets because the selected renderer clears its
//! targets at the start of its pass; the cost is a second copy of the building geometry.

use bytemuck::Zeroable;
use citywalk_scenes::TriangleMesh;
use citywalk_scenes::city::Building;
use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_scenes::extrude::building_mesh;
use citywalk_scenes::{BuildingId, City};
use citywalk_shaders::BuildingRecord;
use citywalk_shaders::constants::NO_PARENT;
use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::lod::{LodCriterion, LodCut, LodTree, LodView};
use crate::scene_gpu::{SceneGeometry, SceneGpu};

/// The combined scene of buildings and cluster meshes, with the tree the cut walks.
#[derive(Debug)]
pub struct LodScene {
    pub gpu_scene: SceneGpu,
    /// Number of buildings; cluster node `n` has draw id `building_count + n`.
    pub building_count: u32,
    pub tree: LodTree,
    /// The criterion of [`LodScene::default_criterion`]; `None` picks the Chang walkthrough or
    /// flyover preset by the camera's altitude.
    pub criterion: Option<LodCriterion>,
    /// Per draw id, the record the occlusion cull of the combined frame tests
    /// ([`crate::frame::CullingRenderer::render_lod`]): a building's own record; a cluster's
    /// record with its bounds widened to contain every building under it (a cluster mesh stops
    /// at the area-weighted mean height, below its tallest buildings, and culling it by its own
    /// box could hide a building the full-detail scene shows). See [`cull_records`].
    pub cull_records: Vec<BuildingRecord>,
    /// [`LodScene::cull_records`] on the GPU: the cull reads a candidate's record by its draw
    /// id, so a frame uploads only the cut's draw ids.
    pub cull_records_buffer: wgpu::Buffer,
    /// Per draw id, the draw id of the cluster above it ([`draw_id_parents`]), for the GPU's
    /// "visible last frame" test.
    pub parents_buffer: wgpu::Buffer,
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

/// The combined geometry on the CPU (see the module documentation for the id layout).
pub fn lod_geometry(city: &City, tree: &ClusterTree) -> SceneGeometry {
    let mut meshes: Vec<TriangleMesh> = city.buildings.iter().map(building_mesh).collect();
    let mut fallback: Vec<(Vec3, Vec3)> = city.buildings.iter().map(Building::bounds).collect();
    for node in &tree.nodes {
        meshes.push(node.mesh.clone());
        fallback.push((
            Vec3::from_array(node.bounds_min),
            Vec3::from_array(node.bounds_max),
        ));
    }
    // Cluster meshes are culled by the box of everything under them (`cull_records`): no parts.
    SceneGeometry::from_meshes_with_parts(&meshes, &fallback, city.buildings.len())
}

/// The occlusion cull's record of every draw id, from `geometry_records` (the records of
/// [`lod_geometry`] of `tree`, whose first `building_count` are the buildings): the same records,
/// each cluster's bounds grown to the union of its mesh's, its node's and the records of the
/// buildings under it, and culled by those bounds alone (no parts).
pub fn cull_records(
    geometry_records: &[BuildingRecord],
    building_count: u32,
    tree: &ClusterTree,
) -> Vec<BuildingRecord> {
    let mut out = geometry_records.to_vec();
    let buildings = geometry_records
        .get(..building_count as usize)
        .unwrap_or(&[]);
    for (n, node) in tree.nodes.iter().enumerate() {
        let Some(record) = out.get_mut(building_count as usize + n) else {
            continue;
        };
        let mut lo = Vec3::from_array(record.bounds_min_m).min(Vec3::from_array(node.bounds_min));
        let mut hi = Vec3::from_array(record.bounds_max_m).max(Vec3::from_array(node.bounds_max));
        let (s, e) = node.buildings;
        for b in tree
            .building_order
            .get(s as usize..e as usize)
            .unwrap_or(&[])
        {
            if let Some(r) = buildings.get(b.index()) {
                lo = lo.min(Vec3::from_array(r.bounds_min_m));
                hi = hi.max(Vec3::from_array(r.bounds_max_m));
            }
        }
        record.bounds_min_m = lo.to_array();
        record.bounds_max_m = hi.to_array();
        // The parts of the cluster mesh alone do not hold its buildings: the box only.
        record.part_count = 0;
    }
    out
}

/// Per draw id of the combined scene (see the module documentation), the draw id of the cluster
/// above it, or [`NO_PARENT`]: a building's is its leaf node's, a node's its parent node's. A
/// building was visible last frame when it or a draw id up this chain was kept (a drawn cluster
/// shows every building under it).
pub fn draw_id_parents(tree: &ClusterTree, building_count: u32) -> Vec<u32> {
    let nodes = tree.nodes.len();
    let mut parents = vec![NO_PARENT; building_count as usize + nodes];
    for (n, node) in tree.nodes.iter().enumerate() {
        for &c in &node.children {
            if (c as usize) < nodes {
                parents[building_count as usize + c as usize] = building_count + n as u32;
            }
        }
        if node.is_leaf()
            && let Some(b) = tree.building_order.get(node.buildings.0 as usize)
            && b.0 < building_count
        {
            parents[b.index()] = building_count + n as u32;
        }
    }
    parents
}

impl LodScene {
    /// Uploads the buildings of `city` and the cluster meshes of `tree` (built from `city`).
    pub fn upload(gpu: &GpuContext, city: &City, tree: ClusterTree) -> LodScene {
        let geometry = lod_geometry(city, &tree);
        let building_count = city.buildings.len() as u32;
        let cull_records = cull_records(&geometry.records, building_count, &tree);
        let storage = |label, contents: &[u8]| {
            gpu.device
                .create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some(label),
                    contents,
                    usage: wgpu::BufferUsages::STORAGE,
                })
        };
        let one_record = [BuildingRecord::zeroed()];
        let cull_records_buffer = storage(
            "lod cull records",
            bytemuck::cast_slice(if cull_records.is_empty() {
                &one_record
            } else {
                &cull_records
            }),
        );
        let mut parents = draw_id_parents(&tree, building_count);
        if parents.is_empty() {
            parents.push(NO_PARENT);
        }
        LodScene {
            parents_buffer: storage("lod draw-id parents", bytemuck::cast_slice(&parents)),
            cull_records_buffer,
            cull_records,
            gpu_scene: SceneGpu::upload(gpu, &geometry),
            building_count,
            tree: LodTree::new(tree),
            criterion: None,
        }
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
        visible_blocks: Option<&[bool]>,
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

    /// What the benchmark's `lod` mode uses: [`LodScene::criterion`] if set, else the Chang
    /// preset for `camera` ([`LodCriterion::chang_for_altitude`] against the tallest building).
    pub fn default_criterion(&self, camera: &Camera) -> LodCriterion {
        self.criterion.unwrap_or_else(|| {
            LodCriterion::chang_for_altitude(camera.position.z, self.tree.top_m())
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
