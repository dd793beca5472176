//! The GPU-ready scene section: the combined LOD scene of buildings and cluster meshes
//! ([`lod_geometry`]) as the GPU reads it — vertices, indices, draw records, cull parts, the
//! occlusion cull's records ([`crate::scene_geometry::cull_records`]) and the draw-id parents
//! ([`draw_id_parents`]) — computed once by preprocessing, so that opening a package uploads
//! these arrays straight from the memory map instead of extruding and measuring every building
//! again.
//!
//! Payload layout (little-endian; every array starts at a multiple of [`ARRAY_ALIGN`] bytes
//! from the payload's start, which lies at a multiple of the section alignment; gaps are zero):
//!
//! ```text
//! Header (96 bytes)
//! [SceneVertex; vertex_count]    buildings' vertices, then clusters', then the ground's 4
//! [u32; index_count]             relative to each record's base_vertex, the ground's 6 last
//! [BuildingRecord; record_count] draw records: building_count buildings, then one per node
//! [CullPart; part_count]         the buildings' cull parts (clusters have none)
//! [BuildingRecord; record_count] the occlusion cull's records (cluster boxes widened)
//! [u32; record_count]            per draw id, the draw id of the cluster above it
//! [SceneVertex; occluder_vertex_count]  the virtual occluders' vertices
//! [u32; occluder_index_count]           relative to each occluder's base_vertex
//! [OccluderRecord; occluder_count]      one per drawable occluder ([`OccluderArrays`])
//! ```
//!
//! Without a cluster tree the scene is the buildings alone (`record_count == building_count`,
//! cull records equal to the draw records, no parents).

use std::fmt;
use std::sync::Arc;

use bytemuck::{Pod, Zeroable};
use citywalk_shaders::constants::NO_PARENT;
use citywalk_shaders::{BuildingRecord, CullPart, DrawIndexedIndirectArgs, SceneVertex};
use glam::Vec3;
use rayon::prelude::*;

use super::map::{MappedPages, RELEASE_PIECE};
use super::scratch::ScratchMap;
use crate::City;
use crate::cluster_tree::ClusterTree;
use crate::occluder::OccluderSet;
use crate::occluder_draws::{OccluderArrays, OccluderArraysView, OccluderRecord};
use crate::scene_geometry::in_place::{LodLayout, SceneSlices, count_lod_layout, write_lod_layout};
use crate::scene_geometry::{ArrayCounts, SceneGeometry, cull_record, draw_id_parents};

// The arrays are the GPU's little-endian layout, read in place.
#[cfg(target_endian = "big")]
compile_error!("scene packages store little-endian GPU arrays read in place");

/// Alignment of each array inside the payload (the widest GPU vector, `vec4<f32>`).
pub const ARRAY_ALIGN: usize = 16;

/// The fixed start of the payload.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
struct Header {
    building_count: u32,
    record_count: u32,
    vertex_count: u32,
    index_count: u32,
    part_count: u32,
    occluder_vertex_count: u32,
    occluder_index_count: u32,
    occluder_count: u32,
    /// Zero: room for later counts without moving the rest.
    reserved: [u32; 4],
    ground: DrawIndexedIndirectArgs,
    bounds_min_m: [f32; 3],
    bounds_max_m: [f32; 3],
    padding: u32,
}

impl Header {
    /// The header of a scene of `counts` arrays (the ground's included) and `occluders`.
    fn of(
        building_count: u32,
        counts: ArrayCounts,
        occluders: OccluderArraysView<'_>,
        ground: DrawIndexedIndirectArgs,
        bounds: (Vec3, Vec3),
    ) -> Header {
        Header {
            building_count,
            record_count: counts.records as u32,
            vertex_count: counts.vertices as u32,
            index_count: counts.indices as u32,
            part_count: counts.parts as u32,
            occluder_vertex_count: occluders.vertices.len() as u32,
            occluder_index_count: occluders.indices.len() as u32,
            occluder_count: occluders.records.len() as u32,
            reserved: [0; 4],
            ground,
            bounds_min_m: bounds.0.to_array(),
            bounds_max_m: bounds.1.to_array(),
            padding: 0,
        }
    }
}

const HEADER_LEN: usize = size_of::<Header>();
const _: () = assert!(HEADER_LEN == 96 && HEADER_LEN.is_multiple_of(ARRAY_ALIGN));

/// Byte ranges of the arrays inside the payload.
#[derive(Debug, Clone, Copy, PartialEq)]
struct Layout {
    header: Header,
    vertices: (usize, usize),
    indices: (usize, usize),
    records: (usize, usize),
    parts: (usize, usize),
    cull_records: (usize, usize),
    parents: (usize, usize),
    occluder_vertices: (usize, usize),
    occluder_indices: (usize, usize),
    occluder_records: (usize, usize),
    len: usize,
}

impl Layout {
    /// The ranges the header's counts imply (`None` on overflow).
    fn of(header: Header) -> Option<Layout> {
        let mut at = HEADER_LEN;
        let mut array = |count: u32, size: usize| -> Option<(usize, usize)> {
            let start = at;
            let end = start.checked_add((count as usize).checked_mul(size)?)?;
            at = end.checked_next_multiple_of(ARRAY_ALIGN)?;
            Some((start, end))
        };
        let h = header;
        let vertices = array(h.vertex_count, size_of::<SceneVertex>())?;
        let indices = array(h.index_count, 4)?;
        let records = array(h.record_count, size_of::<BuildingRecord>())?;
        let parts = array(h.part_count, size_of::<CullPart>())?;
        let cull_records = array(h.record_count, size_of::<BuildingRecord>())?;
        let parents = array(h.record_count, 4)?;
        let occluder_vertices = array(h.occluder_vertex_count, size_of::<SceneVertex>())?;
        let occluder_indices = array(h.occluder_index_count, 4)?;
        let occluder_records = array(h.occluder_count, size_of::<OccluderRecord>())?;
        Some(Layout {
            header,
            vertices,
            indices,
            records,
            parts,
            cull_records,
            parents,
            occluder_vertices,
            occluder_indices,
            occluder_records,
            len: at,
        })
    }

    /// Every array's range, in the payload's order.
    fn arrays(&self) -> [(usize, usize); 9] {
        [
            self.vertices,
            self.indices,
            self.records,
            self.parts,
            self.cull_records,
            self.parents,
            self.occluder_vertices,
            self.occluder_indices,
            self.occluder_records,
        ]
    }
}

/// Where the payload's bytes live.
#[derive(Clone)]
enum Storage {
    /// Built in memory, or copied out of bytes that were not mapped (`u32`s, so the arrays,
    /// all of 4-byte alignment, can be viewed in place).
    Owned(Vec<u32>),
    /// A range of the package's memory map (starting at a multiple of the section alignment).
    Mapped {
        map: Arc<memmap2::Mmap>,
        offset: usize,
    },
}

/// The GPU-ready scene of a package (see the module documentation), owned or in the mapping.
#[derive(Clone)]
pub struct GpuScene {
    storage: Storage,
    layout: Layout,
}

/// The arrays of a [`GpuScene`], borrowed from its bytes (no copy).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct GpuSceneView<'a> {
    /// Draw ids below this are buildings; draw id `building_count + n` is tree node `n`.
    pub building_count: u32,
    pub vertices: &'a [SceneVertex],
    pub indices: &'a [u32],
    /// One per draw id.
    pub records: &'a [BuildingRecord],
    pub parts: &'a [CullPart],
    /// One per draw id.
    pub cull_records: &'a [BuildingRecord],
    /// One per draw id, [`NO_PARENT`] at the top (every draw id without a tree).
    pub parents: &'a [u32],
    /// The virtual occluders, as the runtime draws them (empty without the occluder stage).
    pub occluders: OccluderArraysView<'a>,
    pub ground: DrawIndexedIndirectArgs,
    /// Bounds of every record (buildings and cluster meshes).
    pub bounds: (Vec3, Vec3),
    /// The package mapping the arrays lie in, if any ([`GpuSceneView::release_resident`]).
    pages: MappedPages<'a>,
}

impl GpuScene {
    /// Meshes the buildings of `city` and the cluster meshes of `tree` (built from `city`), with
    /// cull parts and records, and lays out the drawable `occluders`: what the runtime would
    /// otherwise compute at load. The scene is held in memory ([`GpuScene::build_in`]).
    pub fn build(
        city: &City,
        tree: Option<&ClusterTree>,
        occluders: Option<&OccluderSet>,
    ) -> GpuScene {
        let occluders = occluders.map(OccluderArrays::of).unwrap_or_default();
        Self::build_in_memory(city, tree, occluders.view())
    }

    /// [`GpuScene::build`] with the drawable occluders already laid out, where `store` says: in
    /// memory, or in an unnamed scratch file whose written pages leave the process's resident
    /// memory batch by batch (a million buildings' scene is a gigabyte the process need not
    /// hold while it writes the package). Fails only where the scratch file cannot be made or
    /// mapped.
    pub fn build_in(
        city: &City,
        tree: Option<&ClusterTree>,
        occluders: OccluderArraysView<'_>,
        store: SceneStore<'_>,
    ) -> std::io::Result<GpuScene> {
        let SceneStore::ScratchFileIn(dir) = store else {
            return Ok(Self::build_in_memory(city, tree, occluders));
        };
        let (header, layout, lod) = Self::count(city, tree, occluders);
        let mut scratch = ScratchMap::new_in(dir, layout.len)?;
        let parts = SceneParts {
            city,
            tree,
            lod: &lod,
            occluders,
        };
        scratch.fill_with(|bytes, pages| {
            parts.write(&header, &layout, bytes, &|| pages.release());
        });
        Ok(GpuScene {
            storage: Storage::Mapped {
                map: Arc::new(scratch.into_read_only()?),
                offset: 0,
            },
            layout,
        })
    }

    fn build_in_memory(
        city: &City,
        tree: Option<&ClusterTree>,
        occluders: OccluderArraysView<'_>,
    ) -> GpuScene {
        let (header, layout, lod) = Self::count(city, tree, occluders);
        let mut words = vec![0u32; layout.len / 4];
        let parts = SceneParts {
            city,
            tree,
            lod: &lod,
            occluders,
        };
        parts.write(
            &header,
            &layout,
            bytemuck::cast_slice_mut(&mut words),
            &|| {},
        );
        GpuScene {
            storage: Storage::Owned(words),
            layout,
        }
    }

    /// The first pass of a build: the LOD scene's counts, and from them and the occluders'
    /// the header and the payload's layout.
    fn count(
        city: &City,
        tree: Option<&ClusterTree>,
        occluders: OccluderArraysView<'_>,
    ) -> (Header, Layout, LodLayout) {
        let n = city.buildings.len() as u32;
        // Twice over the meshes: once to count the arrays, once to write them where the scene
        // keeps them, so they are never held twice (a gigabyte at a million buildings, where
        // extruding the buildings again takes a few seconds).
        let lod = count_lod_layout(city, tree);
        let header = Header::of(n, lod.counts, occluders, lod.ground, lod.bounds);
        let layout = Layout::of(header).expect("a scene that fits in memory fits its layout");
        (header, layout, lod)
    }

    /// Lays out `geometry` (whose first `building_count` records are buildings) with its cull
    /// records and parents (one per record; without a tree, none: the draw records cull, and
    /// every draw id is a building at the top), and the occluders. Each array is released as
    /// soon as it is copied, and the scene's zeroed pages are only committed as they are
    /// written, so the peak is the arrays and one copy of the largest, not twice the scene (a
    /// gigabyte at a million buildings).
    pub fn from_arrays(
        building_count: u32,
        mut geometry: SceneGeometry,
        cull_records: Option<Vec<BuildingRecord>>,
        parents: Option<Vec<u32>>,
        mut occluders: OccluderArrays,
    ) -> GpuScene {
        let counts = ArrayCounts {
            vertices: geometry.vertices.len(),
            indices: geometry.indices.len(),
            parts: geometry.parts.len(),
            records: geometry.records.len(),
        };
        let header = Header::of(
            building_count,
            counts,
            occluders.view(),
            geometry.ground,
            geometry.bounds,
        );
        let layout = Layout::of(header).expect("a scene that fits in memory fits its layout");
        // Written straight into the `u32`s the scene keeps (the length is a multiple of 16).
        let mut words = vec![0u32; layout.len / 4];
        let bytes: &mut [u8] = bytemuck::cast_slice_mut(&mut words);
        let mut put = |(start, end): (usize, usize), data: &[u8]| {
            bytes[start..end].copy_from_slice(data);
        };
        put((0, HEADER_LEN), bytemuck::bytes_of(&header));
        let cull = cull_records.as_deref().unwrap_or(&geometry.records);
        put(layout.cull_records, bytemuck::cast_slice(cull));
        drop(cull_records);
        match parents {
            Some(parents) => put(layout.parents, bytemuck::cast_slice(&parents)),
            None => {
                let no_parents = NO_PARENT.to_le_bytes().repeat(geometry.records.len());
                put(layout.parents, &no_parents);
            }
        }
        put(
            layout.records,
            bytemuck::cast_slice(&std::mem::take(&mut geometry.records)),
        );
        put(
            layout.vertices,
            bytemuck::cast_slice(&std::mem::take(&mut geometry.vertices)),
        );
        put(
            layout.indices,
            bytemuck::cast_slice(&std::mem::take(&mut geometry.indices)),
        );
        put(
            layout.parts,
            bytemuck::cast_slice(&std::mem::take(&mut geometry.parts)),
        );
        put(
            layout.occluder_vertices,
            bytemuck::cast_slice(&std::mem::take(&mut occluders.vertices)),
        );
        put(
            layout.occluder_indices,
            bytemuck::cast_slice(&std::mem::take(&mut occluders.indices)),
        );
        put(
            layout.occluder_records,
            bytemuck::cast_slice(&occluders.records),
        );
        GpuScene {
            storage: Storage::Owned(words),
            layout,
        }
    }

    /// Checks the payload's structure (header, lengths, padding, every record's ranges inside
    /// its arrays) and copies it.
    pub fn from_payload(payload: &[u8]) -> Result<GpuScene, String> {
        let layout = validate(payload)?;
        Ok(GpuScene {
            storage: Storage::Owned(bytemuck::pod_collect_to_vec(payload)),
            layout,
        })
    }

    /// Checks the payload at `map[offset..offset + len]` as [`GpuScene::from_payload`] does and
    /// keeps it in the mapping.
    pub(super) fn mapped(
        map: &Arc<memmap2::Mmap>,
        offset: usize,
        len: usize,
    ) -> Result<GpuScene, String> {
        let payload = map
            .get(offset..offset + len)
            .ok_or("section outside the file")?;
        if !(payload.as_ptr() as usize).is_multiple_of(4) {
            return Err("payload not aligned to 4 bytes".into());
        }
        let layout = validate(payload)?;
        Ok(GpuScene {
            storage: Storage::Mapped {
                map: Arc::clone(map),
                offset,
            },
            layout,
        })
    }

    /// The payload's bytes.
    pub fn bytes(&self) -> &[u8] {
        match &self.storage {
            Storage::Owned(words) => &bytemuck::cast_slice(words)[..self.layout.len],
            Storage::Mapped { map, offset } => &map[*offset..*offset + self.layout.len],
        }
    }

    /// Writes the payload to `out` a few megabytes at a time; where the scene lies in a mapping
    /// (a package's, or the scratch file of [`GpuScene::build_in`]) each piece's pages leave
    /// resident memory once written.
    pub fn write_payload(&self, out: &mut impl std::io::Write) -> std::io::Result<()> {
        super::map::write_releasing(self.view().pages.first(), self.bytes(), out)
    }

    /// Whether the arrays are read in place from a memory map (a package's, or a scratch file's).
    pub fn is_mapped(&self) -> bool {
        matches!(self.storage, Storage::Mapped { .. })
    }

    /// The arrays, borrowed.
    pub fn view(&self) -> GpuSceneView<'_> {
        let bytes = self.bytes();
        let l = &self.layout;
        // Validated at construction: the ranges are in the payload and the payload is 4-byte
        // aligned (a `Vec<u32>` or a mapping at a section boundary), so the casts hold.
        fn cast<T: Pod>(bytes: &[u8], (start, end): (usize, usize)) -> &[T] {
            bytemuck::cast_slice(&bytes[start..end])
        }
        let pages = match &self.storage {
            Storage::Mapped { map, .. } => MappedPages::one(map),
            Storage::Owned(_) => MappedPages::default(),
        };
        GpuSceneView {
            building_count: l.header.building_count,
            vertices: cast(bytes, l.vertices),
            indices: cast(bytes, l.indices),
            records: cast(bytes, l.records),
            parts: cast(bytes, l.parts),
            cull_records: cast(bytes, l.cull_records),
            parents: cast(bytes, l.parents),
            occluders: OccluderArraysView {
                vertices: cast(bytes, l.occluder_vertices),
                indices: cast(bytes, l.occluder_indices),
                records: cast(bytes, l.occluder_records),
                pages,
            },
            ground: l.header.ground,
            bounds: (
                Vec3::from_array(l.header.bounds_min_m),
                Vec3::from_array(l.header.bounds_max_m),
            ),
            pages,
        }
    }

    /// An owned copy of the geometry (the draw records, with the ground and bounds).
    pub fn geometry(&self) -> SceneGeometry {
        let v = self.view();
        SceneGeometry {
            vertices: v.vertices.to_vec(),
            indices: v.indices.to_vec(),
            records: v.records.to_vec(),
            parts: v.parts.to_vec(),
            ground: v.ground,
            bounds: v.bounds,
        }
    }
}

/// Where [`GpuScene::build_in`] lays a scene out.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SceneStore<'a> {
    /// In the process's memory.
    Memory,
    /// In an unnamed scratch file of this folder, mapped ([`super::scratch`]).
    ScratchFileIn(&'a std::path::Path),
}

/// What a built scene is made of, counted ([`GpuScene::count`]).
struct SceneParts<'a> {
    city: &'a City,
    tree: Option<&'a ClusterTree>,
    lod: &'a LodLayout,
    occluders: OccluderArraysView<'a>,
}

impl SceneParts<'_> {
    /// The second pass: writes the payload of `layout` into `bytes` (zeroed, of its length),
    /// calling `settle` whenever what was written may leave resident memory.
    fn write(
        &self,
        header: &Header,
        layout: &Layout,
        bytes: &mut [u8],
        settle: &(dyn Fn() + Sync),
    ) {
        let SceneParts {
            city,
            tree,
            lod,
            occluders,
        } = *self;
        let n = header.building_count;
        bytes[..HEADER_LEN].copy_from_slice(bytemuck::bytes_of(header));
        let [
            vertices,
            indices,
            records,
            parts,
            cull_out,
            parents_out,
            occluder_vertices,
            occluder_indices,
            occluder_records,
        ] = split_regions(bytes, layout.arrays());
        let records: &mut [BuildingRecord] = bytemuck::cast_slice_mut(records);
        write_lod_layout(
            city,
            tree,
            lod,
            SceneSlices {
                vertices: bytemuck::cast_slice_mut(vertices),
                indices: bytemuck::cast_slice_mut(indices),
                parts: bytemuck::cast_slice_mut(parts),
                records: &mut *records,
            },
            settle,
        );
        let records: &[BuildingRecord] = records;
        // Copied a piece at a time, each piece's source handed to `copied` (the occluders'
        // arrays may lie in scratch files' mappings, whose pages then leave resident memory
        // too: 0.4 GB at a million buildings) and the written pages settled.
        let copy = |to: &mut [u8], from: &[u8], copied: &dyn Fn(&[u8])| {
            for (to, from) in to.chunks_mut(RELEASE_PIECE).zip(from.chunks(RELEASE_PIECE)) {
                to.copy_from_slice(from);
                copied(from);
                settle();
            }
        };
        let in_memory = |_: &[u8]| {};
        match tree {
            Some(tree) => {
                let per_piece = (RELEASE_PIECE / size_of::<BuildingRecord>()).max(1);
                let cull_out = bytemuck::cast_slice_mut(cull_out);
                write_cull_records(cull_out, records, n, tree, per_piece, settle);
                let parents = draw_id_parents(tree, n);
                copy(parents_out, bytemuck::cast_slice(&parents), &in_memory);
            }
            None => {
                copy(cull_out, bytemuck::cast_slice(records), &in_memory);
                bytemuck::cast_slice_mut::<u8, u32>(parents_out).fill(NO_PARENT);
            }
        }
        let mapped = |bytes: &[u8]| occluders.release_resident(bytes);
        copy(
            occluder_vertices,
            bytemuck::cast_slice(occluders.vertices),
            &mapped,
        );
        copy(
            occluder_indices,
            bytemuck::cast_slice(occluders.indices),
            &mapped,
        );
        copy(
            occluder_records,
            bytemuck::cast_slice(occluders.records),
            &mapped,
        );
        settle();
    }
}

/// Writes [`crate::scene_geometry::cull_records`] of `records` into `out` (as long), `per_piece`
/// records at a time, each piece on every thread and then settled: no copy of every record is
/// made (1.1 GB at ten million buildings).
fn write_cull_records(
    out: &mut [BuildingRecord],
    records: &[BuildingRecord],
    building_count: u32,
    tree: &ClusterTree,
    per_piece: usize,
    settle: &(dyn Fn() + Sync),
) {
    for (p, piece) in out.chunks_mut(per_piece).enumerate() {
        piece.par_iter_mut().enumerate().for_each(|(i, out)| {
            *out = cull_record(records, p * per_piece + i, building_count, tree);
        });
        settle();
    }
}

impl GpuSceneView<'_> {
    /// Tells the system that `bytes` (part of one of the view's arrays, already copied to the
    /// GPU) will not be read again soon: where the scene lies in a package's memory map their
    /// pages leave the process's resident memory (they are read again from the page cache if
    /// needed); an owned scene is left as it is.
    pub fn release_resident(&self, bytes: &[u8]) {
        self.pages.release_resident(bytes);
    }

    /// Number of cluster-node draw ids after the buildings.
    pub fn cluster_count(&self) -> usize {
        self.records.len() - self.building_count as usize
    }

    /// Checks everything [`validate`] does not: the layout of the records
    /// ([`crate::scene_geometry::check_layout`]), that the cull records keep the draw records'
    /// ranges, the parents point up to cluster draw ids, that `building_count` buildings and
    /// `nodes` tree nodes make the records, and the occluders' arrays
    /// ([`OccluderArraysView::check_invariants`]).
    pub fn check_invariants(&self, buildings: usize, nodes: usize) -> Result<(), String> {
        if self.building_count as usize != buildings || self.cluster_count() != nodes {
            return Err(format!(
                "{} buildings and {} clusters, the package has {buildings} and {nodes}",
                self.building_count,
                self.cluster_count()
            ));
        }
        crate::scene_geometry::check_layout(
            self.vertices,
            self.indices,
            self.records,
            self.parts,
            self.ground,
        )?;
        for (i, (r, c)) in self.records.iter().zip(self.cull_records).enumerate() {
            let same_draw = (r.first_index, r.index_count, r.base_vertex, r.vertex_count)
                == (c.first_index, c.index_count, c.base_vertex, c.vertex_count);
            let parts_ok = c.first_part == r.first_part && c.part_count <= r.part_count;
            if !same_draw || !parts_ok {
                return Err(format!("cull record {i} does not match its draw record"));
            }
        }
        let n = self.building_count;
        if let Some((i, p)) = (self.parents.iter().enumerate()).find(|&(i, &p)| {
            p != NO_PARENT && (p < n || p as usize >= self.records.len() || p as usize == i)
        }) {
            return Err(format!("draw id {i}: parent {p} is not a cluster above it"));
        }
        self.occluders.check_invariants(self.building_count)
    }
}

/// Checks a payload's structure; O(records), not O(indices) (that is
/// [`GpuSceneView::check_invariants`]), so opening a package stays fast.
fn validate(payload: &[u8]) -> Result<Layout, String> {
    let header: Header = payload
        .get(..HEADER_LEN)
        .map(bytemuck::pod_read_unaligned)
        .ok_or_else(|| format!("{} bytes, shorter than the header", payload.len()))?;
    if header.reserved != [0; 4] || header.padding != 0 {
        return Err("reserved header fields set".into());
    }
    if header.building_count > header.record_count {
        return Err(format!(
            "{} buildings but {} records",
            header.building_count, header.record_count
        ));
    }
    let layout = Layout::of(header).ok_or("counts overflow")?;
    if layout.len != payload.len() {
        return Err(format!(
            "the counts need {} bytes, the section has {}",
            layout.len,
            payload.len()
        ));
    }
    let mut end = HEADER_LEN;
    for (start, stop) in layout.arrays() {
        if payload[end..start].iter().any(|&b| b != 0) {
            return Err("non-zero padding between arrays".into());
        }
        end = stop;
    }
    if payload[end..].iter().any(|&b| b != 0) {
        return Err("non-zero padding after the arrays".into());
    }
    let h = header;
    let records = |(start, end): (usize, usize)| {
        payload[start..end]
            .chunks_exact(size_of::<BuildingRecord>())
            .map(bytemuck::pod_read_unaligned::<BuildingRecord>)
    };
    for (i, r) in records(layout.records)
        .chain(records(layout.cull_records))
        .enumerate()
    {
        let inside = |first: u64, count: u64, len: u32| first + count <= u64::from(len);
        let base =
            u64::try_from(r.base_vertex).map_err(|_| format!("record {i}: negative base"))?;
        if !inside(r.first_index.into(), r.index_count.into(), h.index_count)
            || !inside(base, r.vertex_count.into(), h.vertex_count)
            || !inside(r.first_part.into(), r.part_count.into(), h.part_count)
        {
            return Err(format!(
                "record {}: ranges past the arrays",
                i % h.record_count.max(1) as usize
            ));
        }
    }
    let occluders = payload[layout.occluder_records.0..layout.occluder_records.1]
        .chunks_exact(size_of::<OccluderRecord>())
        .map(bytemuck::pod_read_unaligned::<OccluderRecord>);
    for (i, r) in occluders.enumerate() {
        let inside = |first: u32, count: u32, len: u32| {
            u64::from(first) + u64::from(count) <= u64::from(len)
        };
        if !inside(r.first_index, r.index_count, h.occluder_index_count)
            || !inside(r.base_vertex, r.vertex_count, h.occluder_vertex_count)
            || r.building >= h.building_count
        {
            return Err(format!("occluder {i}: ranges past the arrays"));
        }
    }
    let g = h.ground;
    if u64::from(g.first_index) + u64::from(g.index_count) > u64::from(h.index_count)
        || g.base_vertex < 0
        || g.base_vertex as u64 + 4 > u64::from(h.vertex_count)
    {
        return Err("ground draw past the arrays".into());
    }
    Ok(layout)
}

impl PartialEq for GpuScene {
    fn eq(&self, other: &GpuScene) -> bool {
        self.bytes() == other.bytes()
    }
}

impl fmt::Debug for GpuScene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let h = &self.layout.header;
        f.debug_struct("GpuScene")
            .field("buildings", &h.building_count)
            .field("records", &h.record_count)
            .field("vertices", &h.vertex_count)
            .field("indices", &h.index_count)
            .field("parts", &h.part_count)
            .field("occluders", &h.occluder_count)
            .field("mapped", &self.is_mapped())
            .finish()
    }
}

/// `bytes` cut into the `N` disjoint `ranges` (in increasing order), each mutable on its own.
fn split_regions<const N: usize>(
    mut bytes: &mut [u8],
    ranges: [(usize, usize); N],
) -> [&mut [u8]; N] {
    let mut consumed = 0;
    ranges.map(|(start, end)| {
        let rest = std::mem::take(&mut bytes);
        let (_, rest) = rest.split_at_mut(start - consumed);
        let (region, rest) = rest.split_at_mut(end - start);
        bytes = rest;
        consumed = end;
        region
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::BuildingId;
    use crate::cluster_tree::{ClusterNode, ClusterParams, ClusterStats};
    use crate::scene_geometry::cull_records;

    #[test]
    fn cull_records_written_in_pieces_are_the_whole_arrays() {
        // Six buildings under two leaves under a root; a record per building, then per node.
        let mut nodes = vec![
            ClusterNode::bare(vec![1, 2], (0, 6), 4.0),
            ClusterNode::bare(Vec::new(), (0, 3), 0.0),
            ClusterNode::bare(Vec::new(), (3, 6), 0.0),
        ];
        nodes[0].bounds_max = [1.0, 1.0, 50.0];
        let tree = ClusterTree {
            vertices: Vec::new(),
            nodes,
            root: 0,
            building_order: [5, 0, 3, 1, 4, 2].map(BuildingId).to_vec(),
            params: ClusterParams::default(),
            stats: ClusterStats::default(),
        };
        let records: Vec<BuildingRecord> = (0..9u32)
            .map(|i| BuildingRecord {
                bounds_min_m: [i as f32, -(i as f32), 0.0],
                bounds_max_m: [i as f32 + 2.0, 1.0, 10.0 + i as f32],
                first_part: i,
                part_count: 1 + i % 2,
                ..BuildingRecord::zeroed()
            })
            .collect();
        let whole = cull_records(&records, 6, &tree);
        assert_ne!(whole, records, "the clusters' records grow");
        for per_piece in [1, 2, 4, 9, 100] {
            let settled = std::sync::atomic::AtomicUsize::new(0);
            let mut out = vec![BuildingRecord::zeroed(); records.len()];
            write_cull_records(&mut out, &records, 6, &tree, per_piece, &|| {
                settled.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
            });
            assert_eq!(out, whole, "{per_piece} per piece");
            assert_eq!(settled.into_inner(), records.len().div_ceil(per_piece));
        }
    }
}
