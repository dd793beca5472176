//! The virtual occluders (Germs & Jansen 2001) as the runtime draws them: one vertex array, one
//! index array and a record per occluder (its building, index range and bounds).
//!
//! Preprocessing computes these arrays once into the package's GPU scene
//! ([`crate::package::GpuScene`]), so that opening a package neither decodes the occluder set
//! (a million buildings' facades, footprints and reasons) nor rebuilds the arrays: the runtime
//! uploads them straight from the mapping. The runtime computes the same for inputs loaded on
//! the fly, so both paths draw the same occluders.

use std::collections::HashMap;
use std::io::Write;
use std::path::Path;

use bytemuck::{Pod, Zeroable};
use citywalk_shaders::SceneVertex;
use glam::Vec3;
use rayon::prelude::*;

use crate::TriangleMesh;
use crate::occluder::{Occluder, OccluderSet};
use crate::package::MappedPages;
use crate::package::scratch::{ScratchBytes, ScratchWriter};
use crate::scene_geometry::in_place::{CHUNK, chunks_per_batch};

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
    /// The record with its ranges moved `vertices` and `indices` on (its chunk placed after
    /// that many of each).
    fn moved(&self, vertices: u32, indices: u32) -> OccluderRecord {
        OccluderRecord {
            base_vertex: self.base_vertex + vertices,
            first_index: self.first_index + indices,
            ..*self
        }
    }

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
    ///
    /// Each occluder's vertices are welded: a facade's walls are quads of their own, so every
    /// corner came twice (24.6 M vertices for 12.3 M distinct ones in the generated 1M city,
    /// 188 MiB of GPU memory). Only bit-identical positions are merged, so every triangle keeps
    /// exactly its corners.
    pub fn of(set: &OccluderSet) -> OccluderArrays {
        let mut out = OccluderArrays::default();
        for_each_chunk(&set.occluders, |chunk| {
            let (vertices, indices) = (out.vertices.len() as u32, out.indices.len() as u32);
            out.records
                .extend(chunk.records.iter().map(|r| r.moved(vertices, indices)));
            out.vertices.extend_from_slice(&chunk.vertices);
            out.indices.extend_from_slice(&chunk.indices);
        });
        out
    }

    /// The drawable occluders of `occluders` alone, numbered from 0 (see [`OccluderArrays::of`]).
    fn of_occluders(occluders: &[Occluder]) -> OccluderArrays {
        let mut out = OccluderArrays::default();
        let mut welded = Welder::default();
        for o in occluders {
            let Some((lo, hi)) = o.mesh.bounds() else {
                continue;
            };
            if !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            let first_index = out.indices.len() as u32;
            welded.weld(&o.mesh, &mut out.indices);
            let index_count = out.indices.len() as u32 - first_index;
            if index_count == 0 {
                continue;
            }
            let base_vertex = out.vertices.len() as u32;
            out.vertices
                .extend(welded.positions.iter().map(|p| SceneVertex {
                    position_m: p.to_array(),
                    building_id: o.building.0,
                }));
            out.records.push(OccluderRecord {
                building: o.building.0,
                first_index,
                index_count,
                base_vertex,
                vertex_count: welded.positions.len() as u32,
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
            pages: MappedPages::default(),
        }
    }
}

/// Lays out the occluders of `set` chunk by chunk on every thread, a batch at a time, and hands
/// each chunk's arrays (numbered from 0) to `take` in the set's order.
fn for_each_chunk(occluders: &[Occluder], mut take: impl FnMut(OccluderArrays)) {
    let batch = CHUNK * chunks_per_batch();
    for occluders in occluders.chunks(batch) {
        let chunks: Vec<OccluderArrays> = occluders
            .par_chunks(CHUNK)
            .map(OccluderArrays::of_occluders)
            .collect();
        chunks.into_iter().for_each(&mut take);
    }
}

/// [`OccluderArrays`] written to three scratch files as a set's occluders come, in order and
/// a piece at a time ([`OccluderArraysSpill::push`]): the arrays of the whole set, which is
/// never whole in memory when its occluders are spilled as they are built.
#[derive(Debug)]
pub struct OccluderArraysSpill {
    vertices: ScratchWriter,
    indices: ScratchWriter,
    records: ScratchWriter,
    vertex_count: u32,
    index_count: u32,
}

impl OccluderArraysSpill {
    /// Three unnamed files in `dir`.
    pub fn new_in(dir: &Path) -> std::io::Result<OccluderArraysSpill> {
        Ok(OccluderArraysSpill {
            vertices: ScratchWriter::new_in(dir)?,
            indices: ScratchWriter::new_in(dir)?,
            records: ScratchWriter::new_in(dir)?,
            vertex_count: 0,
            index_count: 0,
        })
    }

    /// Appends the drawable occluders of `occluders`, the set's next ones.
    pub fn push(&mut self, occluders: &[Occluder]) -> std::io::Result<()> {
        let mut written = Ok(());
        for_each_chunk(occluders, |chunk| {
            let moved: Vec<OccluderRecord> = chunk
                .records
                .iter()
                .map(|r| r.moved(self.vertex_count, self.index_count))
                .collect();
            self.vertex_count += chunk.vertices.len() as u32;
            self.index_count += chunk.indices.len() as u32;
            if written.is_ok() {
                written = self
                    .vertices
                    .write_all(bytemuck::cast_slice(&chunk.vertices))
                    .and_then(|()| self.indices.write_all(bytemuck::cast_slice(&chunk.indices)))
                    .and_then(|()| self.records.write_all(bytemuck::cast_slice(&moved)));
            }
        });
        written
    }

    /// The arrays written, mapped.
    pub fn finish(self) -> std::io::Result<SpilledOccluderArrays> {
        Ok(SpilledOccluderArrays {
            vertices: self.vertices.finish()?,
            indices: self.indices.finish()?,
            records: self.records.finish()?,
        })
    }
}

/// The drawable occluders' arrays in scratch files ([`OccluderArraysSpill`]).
#[derive(Clone)]
pub struct SpilledOccluderArrays {
    vertices: ScratchBytes,
    indices: ScratchBytes,
    records: ScratchBytes,
}

impl SpilledOccluderArrays {
    /// The arrays, read from the files' mappings (their pages leave resident memory when the
    /// arrays are dropped).
    pub fn view(&self) -> OccluderArraysView<'_> {
        // Each mapping starts at a page boundary and holds whole elements (written as such).
        OccluderArraysView {
            vertices: bytemuck::cast_slice(self.vertices.bytes()),
            indices: bytemuck::cast_slice(self.indices.bytes()),
            records: bytemuck::cast_slice(self.records.bytes()),
            pages: MappedPages::of([self.vertices.map(), self.indices.map(), self.records.map()]),
        }
    }
}

impl std::fmt::Debug for SpilledOccluderArrays {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let v = self.view();
        f.debug_struct("SpilledOccluderArrays")
            .field("vertices", &v.vertices.len())
            .field("indices", &v.indices.len())
            .field("records", &v.records.len())
            .finish()
    }
}

/// Welds one mesh at a time, reusing its buffers.
#[derive(Debug, Default)]
struct Welder {
    /// The last mesh's distinct positions, in order of first use.
    positions: Vec<Vec3>,
    slot_of: HashMap<[u32; 3], u32>,
}

impl Welder {
    /// Appends to `indices` the whole triangles of `mesh` (every index inside it), numbered over
    /// the distinct positions they use, which are left in `positions`.
    fn weld(&mut self, mesh: &TriangleMesh, indices: &mut Vec<u32>) {
        self.positions.clear();
        self.slot_of.clear();
        let n = mesh.positions.len();
        for t in mesh.indices.chunks_exact(3) {
            if t.iter().any(|&v| v as usize >= n) {
                continue;
            }
            for &v in t {
                let p = mesh.positions[v as usize];
                let slot = *self
                    .slot_of
                    .entry(p.to_array().map(f32::to_bits))
                    .or_insert_with(|| {
                        self.positions.push(p);
                        self.positions.len() as u32 - 1
                    });
                indices.push(slot);
            }
        }
    }
}

/// [`OccluderArrays`], borrowed (from a package's mapping or an owned set).
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct OccluderArraysView<'a> {
    pub vertices: &'a [SceneVertex],
    pub indices: &'a [u32],
    pub records: &'a [OccluderRecord],
    /// The mappings the arrays lie in, if any ([`OccluderArraysView::release_resident`]).
    pub(crate) pages: MappedPages<'a>,
}

impl OccluderArraysView<'_> {
    /// Tells the system that `bytes` (part of one of the arrays, already copied) will not be
    /// read again soon: where the arrays lie in a mapping (a package's, or scratch files'),
    /// their pages leave the process's resident memory; arrays in memory are left as they are.
    pub fn release_resident(&self, bytes: &[u8]) {
        self.pages.release_resident(bytes);
    }

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

#[cfg(test)]
mod tests {
    use geo::MultiPolygon;

    use super::*;
    use crate::BuildingId;
    use crate::occluder::{FacadeKind, Occluder, OccluderOutcome};
    use crate::package::{SectionKind, SpilledOccluderSection, SpilledSection};

    /// An open facade as the occluder stage builds it: one quad of its own per footprint edge.
    fn open_facade(corners: &[(f32, f32)], base_m: f32, top_m: f32) -> TriangleMesh {
        let mut mesh = TriangleMesh::default();
        for (k, &(ax, ay)) in corners.iter().enumerate() {
            let (bx, by) = corners[(k + 1) % corners.len()];
            let i = mesh.positions.len() as u32;
            mesh.positions.extend_from_slice(&[
                Vec3::new(ax, ay, base_m),
                Vec3::new(bx, by, base_m),
                Vec3::new(bx, by, top_m),
                Vec3::new(ax, ay, top_m),
            ]);
            mesh.indices
                .extend_from_slice(&[i, i + 1, i + 2, i, i + 2, i + 3]);
        }
        mesh
    }

    /// An open-facade occluder of `building` at Z-level `level`, its walls `mesh`.
    fn occluder(building: u32, level: u32, z_m: f32, mesh: TriangleMesh) -> Occluder {
        Occluder {
            building: BuildingId(building),
            level,
            kind: FacadeKind::Open,
            z_m,
            base_m: 0.0,
            footprint: MultiPolygon::new(Vec::new()),
            mesh,
        }
    }

    fn corners_of(positions: &[Vec3], indices: &[u32]) -> Vec<[Vec3; 3]> {
        indices
            .chunks_exact(3)
            .map(|t| [0, 1, 2].map(|k| positions[t[k] as usize]))
            .collect()
    }

    /// Laid out chunk by chunk on every thread, in memory or in scratch files, the arrays are
    /// those of one pass over the whole set; an occluder left out (no whole triangle) shifts
    /// the later chunks' ranges.
    #[test]
    fn chunked_and_spilled_arrays_equal_one_pass() {
        let set = OccluderSet {
            occluders: (0..2 * CHUNK + 777)
                .map(|i| {
                    let x = (i % 97) as f32 * 20.0;
                    let corners = [(x, 0.0), (x + 10.0, 0.0), (x + 5.0, 3.0 + (i % 5) as f32)];
                    let mut mesh = open_facade(&corners[..3 - usize::from(i % 11 == 0)], 0.0, 9.0);
                    if i % 13 == 0 {
                        mesh.indices.clear();
                    }
                    occluder(i as u32 / 2, i as u32 % 2, 9.0, mesh)
                })
                .collect(),
            ..OccluderSet::default()
        };
        let one_pass = OccluderArrays::of_occluders(&set.occluders);
        assert!(one_pass.records.len() < set.occluders.len());
        let chunked = OccluderArrays::of(&set);
        assert!(chunked == one_pass);
        let dir = tempfile::tempdir().expect("temp dir");
        // Spilled whole, and in uneven pieces as they are built (an empty one among them).
        let spill = |pieces: Vec<&[Occluder]>| {
            let mut spill = OccluderArraysSpill::new_in(dir.path()).expect("scratch files");
            for piece in pieces {
                spill.push(piece).expect("written");
            }
            spill.finish().expect("mapped")
        };
        let whole = spill(vec![&set.occluders]);
        assert!(whole.view() == one_pass.view());
        let pushed = spill(pieces_of(&set.occluders));
        assert!(pushed.view() == one_pass.view());
        drop((whole, pushed));
        assert!(
            std::fs::read_dir(dir.path())
                .expect("list")
                .next()
                .is_none()
        );
    }

    /// `occluders` cut into pieces of uneven sizes (one empty).
    fn pieces_of(occluders: &[Occluder]) -> Vec<&[Occluder]> {
        let cuts = [0, 0, 1, CHUNK + 5, occluders.len() - 3, occluders.len()];
        cuts.windows(2).map(|w| &occluders[w[0]..w[1]]).collect()
    }

    #[test]
    fn the_section_spilled_in_pieces_is_the_sets_encoding() {
        let occluders: Vec<Occluder> = (0..CHUNK + 40)
            .map(|i| {
                let x = (i % 31) as f32 * 15.0;
                let corners = [(x, 0.0), (x + 10.0, 0.0), (x + 5.0, 4.0)];
                occluder(
                    i as u32 / 2,
                    i as u32 % 2,
                    7.5,
                    open_facade(&corners, 0.0, 7.5),
                )
            })
            .collect();
        let buildings = occluders.len() as u32 / 2;
        let per_building = (0..buildings + 1)
            .map(|b| OccluderOutcome {
                building: BuildingId(b),
                occluder_range: if b < buildings {
                    2 * b..2 * b + 2
                } else {
                    2 * b..2 * b
                },
                source_polygons: 3 + b % 4,
                occluder_polygons: 2,
                reason_if_none: (b == buildings).then(|| "no level".to_string()),
            })
            .collect();
        let set = OccluderSet {
            occluders,
            per_building,
        };
        let dir = tempfile::tempdir().expect("temp dir");
        let whole =
            SpilledSection::encode(SectionKind::Occluders, &set, dir.path()).expect("encoded");
        let mut pieces = SpilledOccluderSection::new_in(dir.path()).expect("scratch file");
        for piece in pieces_of(&set.occluders) {
            pieces.push(piece).expect("encoded");
        }
        let pushed = pieces.finish(&set.per_building).expect("encoded");
        assert_eq!(pushed, whole);
        let decoded: OccluderSet = postcard::from_bytes(pushed.bytes()).expect("decoded");
        assert_eq!(decoded, set);
    }

    #[test]
    fn facades_are_welded_and_keep_every_triangle() {
        let square = [(0.0, 0.0), (10.0, 0.0), (10.0, 8.0), (0.0, 8.0)];
        let mut broken = open_facade(&[(20.0, 0.0), (30.0, 0.0), (25.0, 5.0)], 0.0, 6.0);
        // A triangle past the mesh is left out, as before.
        broken.indices.extend_from_slice(&[0, 1, 99]);
        let set = OccluderSet {
            occluders: [open_facade(&square, 0.0, 12.0), broken]
                .into_iter()
                .enumerate()
                .map(|(i, mesh)| occluder(i as u32 + 3, 0, 12.0, mesh))
                .collect(),
            ..OccluderSet::default()
        };
        let arrays = OccluderArrays::of(&set);
        assert_eq!(arrays.records.len(), 2);
        // Four corners twice (base and top) instead of four per wall.
        assert_eq!(
            arrays
                .records
                .iter()
                .map(|r| r.vertex_count)
                .collect::<Vec<_>>(),
            [8, 6]
        );
        for (record, occluder) in arrays.records.iter().zip(&set.occluders) {
            let vertices =
                &arrays.vertices[record.base_vertex as usize..][..record.vertex_count as usize];
            assert!(vertices.iter().all(|v| v.building_id == record.building));
            let positions: Vec<Vec3> = vertices
                .iter()
                .map(|v| Vec3::from_array(v.position_m))
                .collect();
            let indices =
                &arrays.indices[record.first_index as usize..][..record.index_count as usize];
            let whole = &occluder.mesh.indices[..occluder.mesh.indices.len() / 3 * 3];
            let kept: Vec<u32> = whole
                .chunks_exact(3)
                .filter(|t| {
                    t.iter()
                        .all(|&v| (v as usize) < occluder.mesh.positions.len())
                })
                .flatten()
                .copied()
                .collect();
            assert_eq!(
                corners_of(&positions, indices),
                corners_of(&occluder.mesh.positions, &kept)
            );
        }
        assert_eq!(arrays.view().check_invariants(5), Ok(()));
    }
}
