//! The LOD scene's arrays ([`super::lod_geometry`]) written where they will stay, on every
//! thread: a first pass counts each chunk of draw ids' vertices, indices, parts and records; the
//! caller allocates the arrays at their exact lengths; a second pass meshes the chunks again
//! and writes each into its own slices. The scene is never held twice, and never grown.

use std::ops::Range;

use citywalk_shaders::{BuildingRecord, CullPart, DrawIndexedIndirectArgs, SceneVertex};
use glam::Vec3;
use rayon::prelude::*;

use super::{
    ArrayCounts, EMPTY_BOUNDS, SceneArraysOut, lay_out_mesh, lod_mesh, push_ground, scene_bounds,
    union,
};
use crate::City;
use crate::cluster_tree::ClusterTree;

/// Draw ids (or occluders) laid out by one task.
pub const CHUNK: usize = 4096;

/// Chunks laid out between two hand-overs of what was written (to a scratch file, to the
/// caller): enough to keep every thread busy, few enough that a batch of a million buildings'
/// scene is tens of megabytes.
pub(crate) fn chunks_per_batch() -> usize {
    (4 * rayon::current_num_threads()).max(16)
}

/// What the first pass found: the arrays' lengths (the ground's included), the scene's bounds,
/// its ground draw, and each chunk's draw ids and lengths.
#[derive(Debug, Clone, PartialEq)]
pub struct LodLayout {
    pub counts: ArrayCounts,
    pub bounds: (Vec3, Vec3),
    pub ground: DrawIndexedIndirectArgs,
    chunks: Vec<(Range<usize>, ArrayCounts)>,
}

/// The arrays of a scene, each of exactly its counted length.
#[derive(Debug)]
pub struct SceneSlices<'a> {
    pub vertices: &'a mut [SceneVertex],
    pub indices: &'a mut [u32],
    pub parts: &'a mut [CullPart],
    pub records: &'a mut [BuildingRecord],
}

/// Counts the arrays of the LOD scene of `city` and `tree` (the buildings alone without one).
pub fn count_lod_layout(city: &City, tree: Option<&ClusterTree>) -> LodLayout {
    let draw_ids = city.buildings.len() + tree.map_or(0, |t| t.nodes.len());
    let chunks: Vec<Range<usize>> = (0..draw_ids)
        .step_by(CHUNK)
        .map(|start| start..(start + CHUNK).min(draw_ids))
        .collect();
    let counted: Vec<(ArrayCounts, (Vec3, Vec3))> = chunks
        .par_iter()
        .map(|range| {
            let mut counts = ArrayCounts::default();
            let bounds = lay_out_range(city, tree, range.clone(), &mut counts);
            (counts, bounds)
        })
        .collect();
    let mut counts = ArrayCounts::default();
    let mut bounds = EMPTY_BOUNDS;
    for (chunk, chunk_bounds) in &counted {
        counts = counts.plus(*chunk);
        bounds = union(bounds, *chunk_bounds);
    }
    let bounds = scene_bounds(bounds);
    let ground = push_ground(&mut counts, bounds);
    LodLayout {
        counts,
        bounds,
        ground,
        chunks: chunks
            .into_iter()
            .zip(counted.into_iter().map(|(c, _)| c))
            .collect(),
    }
}

/// Writes the LOD scene `layout` counted into `slices`, each chunk on its own thread, a batch
/// of chunks at a time; `settle` runs after each batch (a scene written to a scratch file gives
/// the batch's pages back there).
///
/// Panics if `slices` are not of `layout`'s lengths (a bug in the caller).
pub fn write_lod_layout(
    city: &City,
    tree: Option<&ClusterTree>,
    layout: &LodLayout,
    slices: SceneSlices<'_>,
    settle: &(dyn Fn() + Sync),
) {
    let SceneSlices {
        vertices,
        indices,
        parts,
        records,
    } = slices;
    let mut rest = ArraysInPlace {
        base: ArrayCounts::default(),
        lens: ArrayCounts::default(),
        vertices,
        indices,
        parts,
        records,
    };
    let mut writers: Vec<_> = layout
        .chunks
        .iter()
        .map(|(range, counts)| (range.clone(), rest.split_front(*counts)))
        .collect();
    for writers in writers.chunks_mut(chunks_per_batch()) {
        writers.par_iter_mut().for_each(|(range, writer)| {
            lay_out_range(city, tree, range.clone(), writer);
        });
        settle();
    }
    for ((_, counts), (_, writer)) in layout.chunks.iter().zip(&writers) {
        assert_eq!(
            writer.lens, *counts,
            "a chunk is laid out as it was counted"
        );
    }
    // What is left after the chunks is the ground's.
    push_ground(&mut rest, layout.bounds);
}

/// Lays out draw ids `range` into `out`; returns the union of their bounds.
fn lay_out_range(
    city: &City,
    tree: Option<&ClusterTree>,
    range: Range<usize>,
    out: &mut impl SceneArraysOut,
) -> (Vec3, Vec3) {
    let mut kept = Vec::new();
    let mut bounds = EMPTY_BOUNDS;
    for id in range {
        let (mesh, fallback) = lod_mesh(city, tree, id);
        let with_parts = id < city.buildings.len();
        let mesh_bounds = lay_out_mesh(id as u32, &mesh, fallback, with_parts, out, &mut kept);
        bounds = union(bounds, mesh_bounds);
    }
    bounds
}

/// One chunk's slices of the scene's arrays, which start at `base` in the whole arrays.
struct ArraysInPlace<'a> {
    base: ArrayCounts,
    lens: ArrayCounts,
    vertices: &'a mut [SceneVertex],
    indices: &'a mut [u32],
    parts: &'a mut [CullPart],
    records: &'a mut [BuildingRecord],
}

impl<'a> ArraysInPlace<'a> {
    /// The first `counts` of each array, as a writer of its own; `self` keeps the rest.
    fn split_front(&mut self, counts: ArrayCounts) -> ArraysInPlace<'a> {
        let (vertices, rest) = std::mem::take(&mut self.vertices).split_at_mut(counts.vertices);
        self.vertices = rest;
        let (indices, rest) = std::mem::take(&mut self.indices).split_at_mut(counts.indices);
        self.indices = rest;
        let (parts, rest) = std::mem::take(&mut self.parts).split_at_mut(counts.parts);
        self.parts = rest;
        let (records, rest) = std::mem::take(&mut self.records).split_at_mut(counts.records);
        self.records = rest;
        let front = ArraysInPlace {
            base: self.base,
            lens: ArrayCounts::default(),
            vertices,
            indices,
            parts,
            records,
        };
        self.base = self.base.plus(counts);
        front
    }
}

impl SceneArraysOut for ArraysInPlace<'_> {
    fn lens(&self) -> (usize, usize, usize) {
        self.base.plus(self.lens).lens()
    }

    fn push_vertices(&mut self, id: u32, positions: &[Vec3]) {
        let at = self.lens.vertices;
        for (v, p) in self.vertices[at..at + positions.len()]
            .iter_mut()
            .zip(positions)
        {
            *v = SceneVertex {
                position_m: p.to_array(),
                building_id: id,
            };
        }
        self.lens.push_vertices(id, positions);
    }

    fn push_indices(&mut self, indices: &[u32]) {
        let at = self.lens.indices;
        self.indices[at..at + indices.len()].copy_from_slice(indices);
        self.lens.push_indices(indices);
    }

    fn push_parts(&mut self, parts: &[CullPart]) {
        let at = self.lens.parts;
        self.parts[at..at + parts.len()].copy_from_slice(parts);
        self.lens.push_parts(parts);
    }

    fn push_record(&mut self, record: BuildingRecord) {
        self.records[self.lens.records] = record;
        self.lens.push_record(record);
    }
}
