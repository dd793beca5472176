//! The scene's GPU-ready geometry on the CPU, in exactly the layout uploaded: one vertex array,
//! one index array with a contiguous index range per building, per-building records (bounds,
//! index range, cull parts) laid out so that a culling pass can emit one `DrawIndexedIndirect`
//! per building ([`BuildingRecord::draw_args`]), and the combined LOD layout of buildings and
//! cluster meshes ([`lod_geometry`]).
//!
//! It lives here, not in the runtime, because preprocessing computes it once into the package
//! ([`crate::package::GpuScene`]) and the runtime computes the same for inputs loaded on the fly.
//! Vertices carry position and building id only; the scene shader computes flat normals from
//! screen-space derivatives, so vertices are shared between triangles.

use std::borrow::Cow;

use citywalk_shaders::constants::NO_PARENT;
use citywalk_shaders::{BuildingRecord, CullPart, DrawIndexedIndirectArgs, GROUND_ID, SceneVertex};
use glam::Vec3;
use rayon::prelude::*;

use crate::cluster_tree::ClusterTree;
use crate::cull_parts;
use crate::extrude::building_mesh;
use crate::{City, TriangleMesh};

pub mod in_place;

/// The scene's geometry on the CPU, in exactly the layout uploaded to the GPU.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct SceneGeometry {
    /// All buildings' vertices, building after building, then the ground's 4.
    pub vertices: Vec<SceneVertex>,
    /// Indices relative to each building's `base_vertex`.
    pub indices: Vec<u32>,
    /// One record per building, indexed by building id.
    pub records: Vec<BuildingRecord>,
    /// The buildings' cull parts, building after building (each record names its range).
    pub parts: Vec<CullPart>,
    /// The ground plane's draw (a quad well beyond the city, at the lowest base height).
    pub ground: DrawIndexedIndirectArgs,
    /// Bounds of all buildings `(min, max)`; a 1 m cube at the origin for an empty scene.
    pub bounds: (Vec3, Vec3),
}

impl SceneGeometry {
    /// Meshes every building of `city` ([`building_mesh`]: its own mesh, else extruded parts).
    pub fn from_city(city: &City) -> SceneGeometry {
        Self::from_mesh_iter(building_meshes(city), city.buildings.len())
    }

    /// One building per mesh, with id = position. `fallback_bounds[i]` is used for a building
    /// whose mesh is empty (it then draws nothing).
    pub fn from_meshes(meshes: &[TriangleMesh], fallback_bounds: &[(Vec3, Vec3)]) -> SceneGeometry {
        Self::from_meshes_with_parts(meshes, fallback_bounds, meshes.len())
    }

    /// As [`SceneGeometry::from_meshes`], with cull parts for the first `with_parts` meshes only
    /// (the others are culled by their boxes, as cluster meshes are: [`cull_records`]).
    pub fn from_meshes_with_parts(
        meshes: &[TriangleMesh],
        fallback_bounds: &[(Vec3, Vec3)],
        with_parts: usize,
    ) -> SceneGeometry {
        Self::from_mesh_iter(
            meshes.iter().enumerate().map(|(i, m)| {
                let fallback = fallback_bounds.get(i).copied();
                (
                    Cow::Borrowed(m),
                    fallback.unwrap_or((Vec3::ZERO, Vec3::ZERO)),
                )
            }),
            with_parts,
        )
    }

    /// [`SceneGeometry::from_meshes_with_parts`] over meshes made one at a time, so a million
    /// extruded buildings are never held as meshes all at once.
    pub fn from_mesh_iter<'m>(
        meshes: impl Iterator<Item = (Cow<'m, TriangleMesh>, (Vec3, Vec3))>,
        with_parts: usize,
    ) -> SceneGeometry {
        let mut g = SceneGeometry::default();
        let (bounds, ground) = lay_out_meshes(meshes, with_parts, &mut g);
        g.bounds = bounds;
        g.ground = ground;
        g.vertices.shrink_to_fit();
        g.indices.shrink_to_fit();
        g
    }

    /// Number of buildings.
    pub fn building_count(&self) -> usize {
        self.records.len()
    }

    /// Total triangles of all buildings (the ground excluded).
    pub fn building_triangle_count(&self) -> usize {
        self.records
            .iter()
            .map(|r| r.index_count as usize / 3)
            .sum()
    }

    /// Checks the layout ([`check_layout`]).
    pub fn check_invariants(&self) -> Result<(), String> {
        check_layout(
            &self.vertices,
            &self.indices,
            &self.records,
            &self.parts,
            self.ground,
        )
    }
}

/// Where [`lay_out_mesh`] puts the scene's arrays, in order: growable vectors
/// ([`SceneGeometry`]), the counts alone ([`ArrayCounts`]), or slices of arrays of exactly the
/// counted length ([`in_place`], for the package's GPU scene).
pub trait SceneArraysOut {
    /// The vertices, indices and cull parts so far.
    fn lens(&self) -> (usize, usize, usize);
    /// One vertex per position, all with `id`.
    fn push_vertices(&mut self, id: u32, positions: &[Vec3]);
    fn push_indices(&mut self, indices: &[u32]);
    fn push_parts(&mut self, parts: &[CullPart]);
    fn push_record(&mut self, record: BuildingRecord);
}

impl SceneArraysOut for SceneGeometry {
    fn lens(&self) -> (usize, usize, usize) {
        (self.vertices.len(), self.indices.len(), self.parts.len())
    }

    fn push_vertices(&mut self, id: u32, positions: &[Vec3]) {
        self.vertices.extend(positions.iter().map(|p| SceneVertex {
            position_m: p.to_array(),
            building_id: id,
        }));
    }

    fn push_indices(&mut self, indices: &[u32]) {
        self.indices.extend_from_slice(indices);
    }

    fn push_parts(&mut self, parts: &[CullPart]) {
        self.parts.extend_from_slice(parts);
    }

    fn push_record(&mut self, record: BuildingRecord) {
        self.records.push(record);
    }
}

/// The lengths of a scene's arrays, counted by a [`lay_out_meshes`] that keeps nothing.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct ArrayCounts {
    pub vertices: usize,
    pub indices: usize,
    pub parts: usize,
    pub records: usize,
}

impl ArrayCounts {
    /// The lengths of two arrays one after the other.
    pub fn plus(self, other: ArrayCounts) -> ArrayCounts {
        ArrayCounts {
            vertices: self.vertices + other.vertices,
            indices: self.indices + other.indices,
            parts: self.parts + other.parts,
            records: self.records + other.records,
        }
    }
}

impl SceneArraysOut for ArrayCounts {
    fn lens(&self) -> (usize, usize, usize) {
        (self.vertices, self.indices, self.parts)
    }

    fn push_vertices(&mut self, _id: u32, positions: &[Vec3]) {
        self.vertices += positions.len();
    }

    fn push_indices(&mut self, indices: &[u32]) {
        self.indices += indices.len();
    }

    fn push_parts(&mut self, parts: &[CullPart]) {
        self.parts += parts.len();
    }

    fn push_record(&mut self, _record: BuildingRecord) {
        self.records += 1;
    }
}

/// Lays out one building per mesh (id = position), with cull parts for the first `with_parts`,
/// then the ground quad, into `out`. Returns the bounds of every mesh (a 1 m cube at the origin
/// when there are none) and the ground's draw. `meshes` gives each mesh with the box to use
/// when it is empty (it then draws nothing).
pub fn lay_out_meshes<'m>(
    meshes: impl Iterator<Item = (Cow<'m, TriangleMesh>, (Vec3, Vec3))>,
    with_parts: usize,
    out: &mut impl SceneArraysOut,
) -> ((Vec3, Vec3), DrawIndexedIndirectArgs) {
    let mut bounds = EMPTY_BOUNDS;
    let mut kept = Vec::new();
    for (i, (mesh, fallback)) in meshes.enumerate() {
        let mesh_bounds = lay_out_mesh(i as u32, &mesh, fallback, i < with_parts, out, &mut kept);
        bounds = union(bounds, mesh_bounds);
    }
    let bounds = scene_bounds(bounds);
    (bounds, push_ground(out, bounds))
}

/// Bounds that contain nothing yet ([`union`]).
pub const EMPTY_BOUNDS: (Vec3, Vec3) = (Vec3::INFINITY, Vec3::NEG_INFINITY);

/// The union of two bounds, either of which may be empty (min above max).
pub fn union(a: (Vec3, Vec3), b: (Vec3, Vec3)) -> (Vec3, Vec3) {
    if !b.0.cmple(b.1).all() {
        return a;
    }
    (a.0.min(b.0), a.1.max(b.1))
}

/// The scene's bounds from the union of its meshes': a 1 m cube at the origin when empty.
pub fn scene_bounds(bounds: (Vec3, Vec3)) -> (Vec3, Vec3) {
    if bounds.0.cmple(bounds.1).all() {
        bounds
    } else {
        (Vec3::ZERO, Vec3::ONE)
    }
}

/// Lays out draw id `id`'s mesh, with its cull parts if `with_parts`, at the end of `out`: the
/// one place the scene's layout of a mesh is decided. `kept` is scratch space. Returns the
/// mesh's bounds (`fallback` when it is empty).
pub fn lay_out_mesh(
    id: u32,
    mesh: &TriangleMesh,
    fallback: (Vec3, Vec3),
    with_parts: bool,
    out: &mut impl SceneArraysOut,
    kept: &mut Vec<u32>,
) -> (Vec3, Vec3) {
    let (bmin, bmax) = mesh.bounds().unwrap_or(fallback);
    // Indices that point outside the mesh would read other buildings' vertices: drop those
    // triangles.
    let n = mesh.positions.len() as u32;
    kept.clear();
    kept.extend(
        mesh.indices
            .chunks_exact(3)
            .filter(|t| t.iter().all(|&v| v < n))
            .flatten(),
    );
    let parts = if with_parts {
        cull_parts::cull_parts(&mesh.positions, kept)
    } else {
        Vec::new()
    };
    let (vertices, indices, first_part) = out.lens();
    out.push_record(BuildingRecord {
        bounds_min_m: bmin.to_array(),
        first_index: indices as u32,
        bounds_max_m: bmax.to_array(),
        index_count: kept.len() as u32,
        base_vertex: vertices as i32,
        vertex_count: n,
        first_part: first_part as u32,
        part_count: parts.len() as u32,
    });
    out.push_indices(kept);
    out.push_parts(&parts);
    out.push_vertices(id, &mesh.positions);
    (bmin, bmax)
}

/// A ground quad reaching well past the city (so the horizon is ground, not sky), at the lowest
/// base height (at most 0), after the buildings.
pub fn push_ground(
    out: &mut impl SceneArraysOut,
    (lo, hi): (Vec3, Vec3),
) -> DrawIndexedIndirectArgs {
    let centre = (lo + hi) * 0.5;
    let half_m = ((hi - lo).truncate().max_element() * 0.5).max(100.0) * 50.0 + 5_000.0;
    let z = ground_plane_z(lo.z);
    let (base_vertex, first_index, _) = out.lens();
    let corners = [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)]
        .map(|(dx, dy)| Vec3::new(centre.x + dx * half_m, centre.y + dy * half_m, z));
    out.push_vertices(GROUND_ID, &corners);
    out.push_indices(&[0, 1, 2, 0, 2, 3]);
    DrawIndexedIndirectArgs {
        index_count: 6,
        instance_count: 1,
        first_index: first_index as u32,
        base_vertex: base_vertex as i32,
        first_instance: 0,
    }
}

/// The height of the ground plane under a scene whose lowest point is at `min_z` (metres): sea
/// level, or lower where the scene goes below it. The ground quad and the surfaces laid over it
/// read it here.
pub fn ground_plane_z(min_z: f32) -> f32 {
    min_z.min(0.0)
}

/// Checks a scene layout: index ranges are contiguous, in record order, inside the index array,
/// every index of a record stays within its own vertices, which carry its id; part ranges are
/// contiguous and inside `parts`; the ground follows the last record.
pub fn check_layout(
    vertices: &[SceneVertex],
    indices: &[u32],
    records: &[BuildingRecord],
    parts: &[CullPart],
    ground: DrawIndexedIndirectArgs,
) -> Result<(), String> {
    let mut next_index = 0u32;
    let mut next_vertex = 0i32;
    let mut next_part = 0u32;
    for (i, r) in records.iter().enumerate() {
        if r.first_index != next_index || r.base_vertex != next_vertex {
            return Err(format!(
                "record {i}: range does not follow the previous one"
            ));
        }
        if r.first_part != next_part {
            return Err(format!("record {i}: parts do not follow the previous ones"));
        }
        let end = r.first_index as usize + r.index_count as usize;
        let range = indices
            .get(r.first_index as usize..end)
            .ok_or_else(|| format!("record {i}: index range past the buffer"))?;
        if let Some(bad) = range.iter().find(|&&v| v >= r.vertex_count) {
            return Err(format!(
                "record {i}: index {bad} ≥ vertex count {}",
                r.vertex_count
            ));
        }
        let verts = vertices
            .get(r.base_vertex as usize..r.base_vertex as usize + r.vertex_count as usize)
            .ok_or_else(|| format!("record {i}: vertex range past the buffer"))?;
        if verts.iter().any(|v| v.building_id != i as u32) {
            return Err(format!("record {i}: vertex with another id"));
        }
        next_index += r.index_count;
        next_vertex += r.vertex_count as i32;
        next_part += r.part_count;
    }
    if next_part as usize != parts.len() {
        return Err(format!(
            "records name {next_part} cull parts, there are {}",
            parts.len()
        ));
    }
    if ground.first_index != next_index
        || ground.base_vertex != next_vertex
        || ground.index_count != 6
        || indices.len() != next_index as usize + 6
        || vertices.len() != next_vertex as usize + 4
    {
        return Err("ground does not follow the records, or arrays continue past it".into());
    }
    if vertices[next_vertex as usize..]
        .iter()
        .any(|v| v.building_id != GROUND_ID)
        || indices[next_index as usize..].iter().any(|&v| v >= 4)
    {
        return Err("ground vertices or indices out of place".into());
    }
    Ok(())
}

/// Buildings meshed at a time by [`building_meshes`].
const MESH_CHUNK: usize = 4096;

/// Every building's mesh ([`building_mesh`]: its own mesh, else extruded parts) and box, in
/// building order: made on every thread a chunk at a time, so the geometry is the same on any
/// number of threads and one chunk of meshes is held at once.
fn building_meshes<'m>(city: &City) -> impl Iterator<Item = (Cow<'m, TriangleMesh>, (Vec3, Vec3))> {
    city.buildings
        .chunks(MESH_CHUNK)
        .flat_map(|chunk| chunk.par_iter().map(building_draw).collect::<Vec<_>>())
}

/// The combined geometry of buildings and cluster meshes, so a LOD cut is one draw list. Draw
/// ids `0..building_count` are the buildings (the same ids and geometry as
/// [`SceneGeometry::from_city`]), then id `building_count + n` is the cluster mesh of tree node
/// `n` (empty for leaves, which draw nothing under that id).
pub fn lod_geometry(city: &City, tree: &ClusterTree) -> SceneGeometry {
    // Cluster meshes are culled by the box of everything under them (`cull_records`): no parts.
    SceneGeometry::from_mesh_iter(lod_meshes(city, Some(tree)), city.buildings.len())
}

/// The meshes of [`lod_geometry`] in draw-id order, made a chunk at a time: every building's,
/// then every node's cluster mesh of `tree` (none without a tree: [`SceneGeometry::from_city`]).
pub fn lod_meshes<'m>(
    city: &City,
    tree: Option<&'m ClusterTree>,
) -> impl Iterator<Item = (Cow<'m, TriangleMesh>, (Vec3, Vec3))> {
    let clusters = tree.into_iter().flat_map(|tree| &tree.nodes).map(node_mesh);
    building_meshes(city).chain(clusters)
}

/// Draw id `id`'s mesh and box of [`lod_meshes`]: building `id`'s, else the cluster mesh of node
/// `id - building_count` of `tree`; an empty mesh past the last.
pub fn lod_mesh<'m>(
    city: &City,
    tree: Option<&'m ClusterTree>,
    id: usize,
) -> (Cow<'m, TriangleMesh>, (Vec3, Vec3)) {
    match city.buildings.get(id) {
        Some(b) => building_draw(b),
        None => tree
            .and_then(|t| t.nodes.get(id - city.buildings.len()))
            .map_or_else(
                || {
                    (
                        Cow::Owned(TriangleMesh::default()),
                        (Vec3::ZERO, Vec3::ZERO),
                    )
                },
                node_mesh,
            ),
    }
}

/// A building's mesh ([`building_mesh`]: its own mesh, else extruded parts), with its box.
fn building_draw<'m>(b: &crate::Building) -> (Cow<'m, TriangleMesh>, (Vec3, Vec3)) {
    (Cow::Owned(building_mesh(b)), b.bounds())
}

/// A tree node's cluster mesh, with the node's box.
fn node_mesh(node: &crate::cluster_tree::ClusterNode) -> (Cow<'_, TriangleMesh>, (Vec3, Vec3)) {
    let bounds = (
        Vec3::from_array(node.bounds_min),
        Vec3::from_array(node.bounds_max),
    );
    (Cow::Borrowed(&node.mesh), bounds)
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
    (0..geometry_records.len())
        .map(|draw_id| cull_record(geometry_records, draw_id, building_count, tree))
        .collect()
}

/// [`cull_records`]' record of one draw id (`draw_id < geometry_records.len()`): a building's
/// record as it is; a cluster's grown to its node's and its buildings' bounds, without parts.
/// One at a time, so that a package's scene can be written piece by piece without a copy of
/// every record (1.1 GB at ten million buildings).
pub fn cull_record(
    geometry_records: &[BuildingRecord],
    draw_id: usize,
    building_count: u32,
    tree: &ClusterTree,
) -> BuildingRecord {
    let mut record = geometry_records[draw_id];
    let Some(node) = draw_id
        .checked_sub(building_count as usize)
        .and_then(|n| tree.nodes.get(n))
    else {
        return record;
    };
    let buildings = geometry_records
        .get(..building_count as usize)
        .unwrap_or(&[]);
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
    record
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

#[cfg(test)]
mod tests {
    use super::*;

    fn tetra(offset: Vec3) -> TriangleMesh {
        TriangleMesh {
            positions: vec![offset, offset + Vec3::X, offset + Vec3::Y, offset + Vec3::Z],
            indices: vec![0, 2, 1, 0, 1, 3, 0, 3, 2, 1, 2, 3],
        }
    }

    #[test]
    fn ranges_are_per_building_and_checked() {
        let mut bad = tetra(Vec3::new(5.0, 0.0, 0.0));
        bad.indices.extend_from_slice(&[0, 1, 9]); // points past the mesh: dropped
        let meshes = [tetra(Vec3::ZERO), TriangleMesh::default(), bad];
        let fallback = [(Vec3::ZERO, Vec3::ONE); 3];
        let g = SceneGeometry::from_meshes(&meshes, &fallback);
        g.check_invariants().expect("valid layout");
        assert_eq!(g.building_count(), 3);
        assert_eq!(g.records[1].index_count, 0);
        assert_eq!(g.records[2].index_count, 12);
        assert_eq!(g.records[2].base_vertex, 4);
        assert_eq!(g.records[2].first_index, 12);
        assert_eq!(g.records[2].bounds_min_m, [5.0, 0.0, 0.0]);
        assert_eq!(g.building_triangle_count(), 8);
        let args = g.records[2].draw_args();
        assert_eq!(
            (args.first_index, args.index_count, args.base_vertex),
            (12, 12, 4)
        );
        // The ground lies under the city and reaches far beyond it.
        let ground = &g.vertices[g.ground.base_vertex as usize..];
        assert!(
            ground
                .iter()
                .all(|v| v.building_id == GROUND_ID && v.position_m[2] <= 0.0)
        );
        assert!(ground.iter().any(|v| v.position_m[0] < -1000.0));
        assert_eq!(g.bounds, (Vec3::ZERO, Vec3::new(6.0, 1.0, 1.0)));

        // A corrupted layout is reported.
        let mut broken = g.clone();
        broken.records[2].first_index += 3;
        assert!(broken.check_invariants().is_err());
        let mut broken = g;
        broken.vertices[0].building_id = 2;
        assert!(broken.check_invariants().is_err());
    }
}
