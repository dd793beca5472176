//! The virtual occluders (Germs & Jansen 2001) as the runtime draws them: one vertex array, one
//! index array and a record per occluder (its building, index range and bounds).
//!
//! Preprocessing computes these arrays once into the package's GPU scene
//! ([`crate::package::GpuScene`]), so that opening a package neither decodes the occluder set
//! (a million buildings' facades, footprints and reasons) nor rebuilds the arrays: the runtime
//! uploads them straight from the mapping. The runtime computes the same for inputs loaded on
//! the fly, so both paths draw the same occluders.

use bytemuck::{Pod, Zeroable};
use citywalk_shaders::SceneVertex;
use glam::Vec3;

use crate::occluder::OccluderSet;

/// One drawable occluder: indices `first_index .. first_index + index_count` of the index
/// array, relative to `base_vertex`; the box of its mesh.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct OccluderRecord {
    /// The building the occluder stands for.
    pub building: u32,
    pub first_index: u32,
    pub index_count: u32,
    pub base_vertex: u32,
    pub vertex_count: u32,
    pub bounds_min_m: [f32; 3],
    pub bounds_max_m: [f32; 3],
}

impl OccluderRecord {
    pub fn bounds(&self) -> (Vec3, Vec3) {
        (
            Vec3::from_array(self.bounds_min_m),
            Vec3::from_array(self.bounds_max_m),
        )
    }
}

/// The arrays of every drawable occluder, in the set's order.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct OccluderArrays {
    /// Each occluder's vertices in turn, carrying its building's id.
    pub vertices: Vec<SceneVertex>,
    /// Relative to each record's `base_vertex`.
    pub indices: Vec<u32>,
    pub records: Vec<OccluderRecord>,
}

impl OccluderArrays {
    /// The occluders of `set` with at least one whole triangle and a finite box; triangles with
    /// an index outside their mesh are left out (the set's invariants forbid both, but a set
    /// built in memory is not checked).
    pub fn of(set: &OccluderSet) -> OccluderArrays {
        let mut out = OccluderArrays::default();
        for o in &set.occluders {
            let Some((lo, hi)) = o.mesh.bounds() else {
                continue;
            };
            if !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            let n = o.mesh.positions.len() as u32;
            let first_index = out.indices.len() as u32;
            for t in o.mesh.indices.chunks_exact(3) {
                if t.iter().all(|&v| v < n) {
                    out.indices.extend_from_slice(t);
                }
            }
            let index_count = out.indices.len() as u32 - first_index;
            if index_count == 0 {
                continue;
            }
            let base_vertex = out.vertices.len() as u32;
            out.vertices
                .extend(o.mesh.positions.iter().map(|p| SceneVertex {
                    position_m: p.to_array(),
                    building_id: o.building.0,
                }));
            out.records.push(OccluderRecord {
                building: o.building.0,
                first_index,
                index_count,
                base_vertex,
                vertex_count: n,
                bounds_min_m: lo.to_array(),
                bounds_max_m: hi.to_array(),
            });
        }
        out
    }

    pub fn view(&self) -> OccluderArraysView<'_> {
        OccluderArraysView {
            vertices: &self.vertices,
            indices: &self.indices,
            records: &self.records,
        }
    }
}

/// [`OccluderArrays`], borrowed (from a package's mapping or an owned set).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OccluderArraysView<'a> {
    pub vertices: &'a [SceneVertex],
    pub indices: &'a [u32],
    pub records: &'a [OccluderRecord],
}

impl OccluderArraysView<'_> {
    /// Checks that every record's ranges lie in the arrays, its indices in its vertex range,
    /// its vertices carry its building, below `building_count`, and its box is finite and
    /// holds its vertices. O(indices): run by the package's `--check`, not on every open.
    pub fn check_invariants(&self, building_count: u32) -> Result<(), String> {
        for (i, r) in self.records.iter().enumerate() {
            let fail = |why: &str| Err(format!("occluder record {i}: {why}"));
            if r.building >= building_count {
                return fail("building past the buildings");
            }
            let (Some(indices), Some(vertices)) = (
                self.indices
                    .get(r.first_index as usize..(r.first_index as usize + r.index_count as usize)),
                self.vertices.get(
                    r.base_vertex as usize..(r.base_vertex as usize + r.vertex_count as usize),
                ),
            ) else {
                return fail("ranges past the arrays");
            };
            if r.index_count == 0 || !r.index_count.is_multiple_of(3) {
                return fail("not whole triangles");
            }
            if indices.iter().any(|&v| v >= r.vertex_count) {
                return fail("an index past its vertices");
            }
            let (lo, hi) = r.bounds();
            if !(lo.is_finite() && hi.is_finite()) {
                return fail("bounds not finite");
            }
            for v in vertices {
                let p = Vec3::from_array(v.position_m);
                if v.building_id != r.building || !(p.cmpge(lo).all() && p.cmple(hi).all()) {
                    return fail("a vertex of another building or outside the box");
                }
            }
        }
        Ok(())
    }
}
