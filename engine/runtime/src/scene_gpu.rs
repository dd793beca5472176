//! A [`City`] on the GPU: one vertex buffer, one index buffer with a contiguous index range per
//! building, and per-building records (bounds and index range) on the CPU and in a storage
//! buffer, laid out so that a culling pass can emit one `DrawIndexedIndirect` per building
//! ([`BuildingRecord::draw_args`]).
//!
//! Each record also names the building's tight cull bounds, oriented prisms around the pieces
//! of its mesh ([`cull_parts`]), kept in a second storage buffer.
//!
//! The layout is computed on the CPU by [`SceneGeometry`]; a scene package holds it ready
//! ([`GpuSceneView`]), and [`SceneGpu::upload_package`] uploads it from the package's mapping.

use citywalk_scenes::City;
use citywalk_scenes::frustum::{Containment, Frustum};
use citywalk_scenes::package::GpuSceneView;
use citywalk_shaders::{BuildingRecord, CullPart, DrawIndexedIndirectArgs, SceneVertex};
use glam::Vec3;
use std::ops::Deref;
use std::sync::Arc;

use crate::cluster_textures::ClusterTexturing;
use crate::gpu::GpuContext;
use crate::upload::{UploadError, array_buffer, buffer_from_chunks};

pub use citywalk_scenes::cull_parts;
pub use citywalk_scenes::scene_geometry::{SceneGeometry, check_layout};

/// The vertex buffer layout of [`SceneVertex`]: `Float32x3` position at location 0, `Uint32`
/// building id at location 1.
pub const SCENE_VERTEX_LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: size_of::<SceneVertex>() as wgpu::BufferAddress,
    step_mode: wgpu::VertexStepMode::Vertex,
    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32],
};

/// The scene's buffers on the GPU, with the CPU copy of the per-building records.
#[derive(Debug)]
pub struct SceneGpu {
    /// [`SceneVertex`] array ([`SCENE_VERTEX_LAYOUT`]).
    pub vertex_buffer: wgpu::Buffer,
    /// Indices relative to each range's `base_vertex`, in [`SceneGpu::index_format`].
    pub index_buffer: wgpu::Buffer,
    /// `Uint16` when every record's vertex range fits 16 bits ([`scene_index_format`]).
    pub index_format: wgpu::IndexFormat,
    /// [`CullPart`] array the records name (storage, read-only); at least one part long.
    pub parts_buffer: wgpu::Buffer,
    /// The records and the brute-force draw list on the GPU, which the cull of every building
    /// and [`SceneGpu::draw_all`] read; `None` for a scene made [`SceneGpu::sharing`] another's
    /// buffers (the LOD scene: its cull reads `LodScene::cull_records_buffer` and nothing draws
    /// all of its draw ids at once; at a million buildings they would be 150 MB).
    pub all: Option<AllDraws>,
    /// CPU copy of the records, indexed by draw id.
    pub records: Records,
    /// CPU copy of the cull parts (shared by the scenes over the same buffers).
    pub parts: Arc<[CullPart]>,
    /// The ground plane's draw.
    pub ground: DrawIndexedIndirectArgs,
    /// Bounds of all buildings.
    pub bounds: (Vec3, Vec3),
    /// Building triangles (the ground excluded).
    pub triangle_count: usize,
    /// The cluster meshes' baked textures, on the LOD scene of a package that has them
    /// ([`crate::drawable::DrawableScene::add_cluster_textures`]): the scene pass draws
    /// textured where this is set.
    pub texturing: Option<ClusterTexturing>,
}

/// A plain scene's records and brute-force draw list on the GPU ([`SceneGpu::all`]).
#[derive(Debug)]
pub struct AllDraws {
    /// [`BuildingRecord`] array (storage, read-only in shaders); at least one record long even
    /// for an empty scene, so it can always be bound.
    pub records_buffer: wgpu::Buffer,
    /// One [`DrawIndexedIndirectArgs`] per building in id order, then the ground's
    /// (`INDIRECT | STORAGE | COPY_SRC`).
    pub all_draws_buffer: wgpu::Buffer,
}

/// Draw records on the CPU: one copy shared by the plain scene (the buildings, a prefix) and the
/// LOD scene over the same buffers (every draw id).
#[derive(Debug, Clone)]
pub struct Records {
    array: Arc<[BuildingRecord]>,
    len: usize,
}

impl Records {
    /// The first `len` records of `array` (all of them when `len` is larger).
    pub fn prefix(array: Arc<[BuildingRecord]>, len: usize) -> Records {
        let len = len.min(array.len());
        Records { array, len }
    }

    /// Every record of the array these are a prefix of.
    pub fn whole(&self) -> Records {
        Records::prefix(Arc::clone(&self.array), usize::MAX)
    }
}

impl From<&[BuildingRecord]> for Records {
    fn from(records: &[BuildingRecord]) -> Records {
        Records::prefix(records.into(), usize::MAX)
    }
}

impl PartialEq for Records {
    fn eq(&self, other: &Records) -> bool {
        **self == **other
    }
}

impl Deref for Records {
    type Target = [BuildingRecord];
    fn deref(&self) -> &[BuildingRecord] {
        &self.array[..self.len]
    }
}

impl SceneGpu {
    /// Meshes and uploads `city` (an error when an array does not fit the GPU).
    pub fn upload_city(gpu: &GpuContext, city: &City) -> Result<SceneGpu, UploadError> {
        Self::upload(gpu, &SceneGeometry::from_city(city))
    }

    /// Uploads prepared geometry.
    pub fn upload(gpu: &GpuContext, geometry: &SceneGeometry) -> Result<SceneGpu, UploadError> {
        let arrays = (
            &geometry.vertices[..],
            &geometry.indices[..],
            &geometry.parts[..],
        );
        let geometry_buffers = GeometryBuffers::upload(gpu, arrays, &geometry.records, &|_| {})?;
        Self::with_records(
            gpu,
            geometry_buffers,
            geometry.records.as_slice().into(),
            geometry.parts.as_slice().into(),
            geometry.ground,
            geometry.bounds,
        )
    }

    /// Uploads the buildings of a package's GPU scene straight from its bytes (no meshing):
    /// the records of draw ids `0..building_count` (a prefix of the CPU copy of every draw
    /// id's), with the whole vertex, index and part arrays, which
    /// [`crate::lod::scene::LodScene::upload_package`] then shares. The view's pages are
    /// released as they are uploaded ([`GpuSceneView::release_resident`]).
    pub fn upload_package(
        gpu: &GpuContext,
        view: &GpuSceneView<'_>,
    ) -> Result<SceneGpu, UploadError> {
        let release = |bytes: &[u8]| view.release_resident(bytes);
        // The CPU copies first: the mapping's pages they read then leave resident memory with
        // the records' release here and the parts' upload below, not at the end of the load.
        let records = Records::prefix(view.records.into(), view.building_count as usize);
        release(bytemuck::cast_slice(view.records));
        let parts: Arc<[CullPart]> = view.parts.into();
        let arrays = (view.vertices, view.indices, view.parts);
        // Every draw id's record (the whole array behind the buildings' prefix): the cluster
        // meshes share the index buffer.
        let geometry_buffers = GeometryBuffers::upload(gpu, arrays, &records.array, &release)?;
        let bounds = records_bounds(&records);
        Self::with_records(gpu, geometry_buffers, records, parts, view.ground, bounds)
    }

    /// A scene over the vertex, index and part buffers (and ground) of `shared`, with other
    /// records into them (`records` must index `shared`'s arrays), and no records or draw list
    /// of its own on the GPU ([`SceneGpu::all`]).
    pub(crate) fn sharing(shared: &SceneGpu, records: Records, bounds: (Vec3, Vec3)) -> SceneGpu {
        SceneGpu {
            vertex_buffer: shared.vertex_buffer.clone(),
            index_buffer: shared.index_buffer.clone(),
            index_format: shared.index_format,
            parts_buffer: shared.parts_buffer.clone(),
            all: None,
            triangle_count: triangles(&records),
            records,
            parts: Arc::clone(&shared.parts),
            ground: shared.ground,
            bounds,
            texturing: None,
        }
    }

    fn with_records(
        gpu: &GpuContext,
        buffers: GeometryBuffers,
        records: Records,
        parts: Arc<[CullPart]>,
        ground: DrawIndexedIndirectArgs,
        bounds: (Vec3, Vec3),
    ) -> Result<SceneGpu, UploadError> {
        // At least one record long (zeroed), so the buffer can always be bound.
        let records_buffer = array_buffer(
            gpu,
            "building records",
            &records,
            wgpu::BufferUsages::STORAGE,
            &|_| {},
        )?;
        // One draw per record, then the ground's, made chunk by chunk.
        const DRAW: usize = size_of::<DrawIndexedIndirectArgs>();
        let all_draws_buffer = buffer_from_chunks(
            gpu,
            "all building draws",
            (records.len() + 1) * DRAW,
            wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC,
            |range, out| {
                let draws = range.start / DRAW..range.end / DRAW;
                for (slot, id) in out.chunks_exact_mut(DRAW).zip(draws) {
                    let draw = records.get(id).map_or(ground, BuildingRecord::draw_args);
                    slot.copy_from_slice(bytemuck::bytes_of(&draw));
                }
            },
        )?;
        Ok(SceneGpu {
            vertex_buffer: buffers.vertex_buffer,
            index_buffer: buffers.index_buffer,
            index_format: buffers.index_format,
            parts_buffer: buffers.parts_buffer,
            all: Some(AllDraws {
                records_buffer,
                all_draws_buffer,
            }),
            triangle_count: triangles(&records),
            records,
            parts,
            ground,
            bounds,
            texturing: None,
        })
    }

    /// Number of buildings.
    pub fn building_count(&self) -> usize {
        self.records.len()
    }

    /// The buildings whose box is not outside `frustum`, in id order (per-building frustum
    /// culling on the CPU).
    pub fn buildings_in_frustum(&self, frustum: &Frustum) -> Vec<u32> {
        (self.records.iter().enumerate())
            .filter(|(_, r)| {
                frustum.classify_aabb(
                    Vec3::from_array(r.bounds_min_m),
                    Vec3::from_array(r.bounds_max_m),
                ) != Containment::Outside
            })
            .map(|(i, _)| i as u32)
            .collect()
    }

    /// Binds the vertex and index buffers to `pass`.
    pub fn bind<'a>(&'a self, pass: &mut wgpu::RenderPass<'a>) {
        pass.set_vertex_buffer(0, self.vertex_buffer.slice(..));
        pass.set_index_buffer(self.index_buffer.slice(..), self.index_format);
    }

    /// Draws every building and the ground with one multi-draw over
    /// [`AllDraws::all_draws_buffer`] (one indirect draw per building, so the per-building
    /// ranges are exercised exactly as a culling pass will emit them). Call after
    /// [`SceneGpu::bind`]. A scene without a draw list of its own (the LOD scene, whose draw
    /// ids overlap: every building and every cluster above it) draws the ground only.
    pub fn draw_all(&self, pass: &mut wgpu::RenderPass<'_>) {
        match &self.all {
            Some(all) => pass.multi_draw_indexed_indirect(
                &all.all_draws_buffer,
                0,
                self.records.len() as u32 + 1,
            ),
            None => {
                tracing::error!("draw_all of a scene without a draw list: the ground only");
                self.draw_ground(pass);
            }
        }
    }

    /// Draws the ground plane only.
    pub fn draw_ground(&self, pass: &mut wgpu::RenderPass<'_>) {
        let g = self.ground;
        pass.draw_indexed(
            g.first_index..g.first_index + g.index_count,
            g.base_vertex,
            0..1,
        );
    }
}

/// The arrays a scene's records index into, on the GPU.
#[derive(Debug)]
struct GeometryBuffers {
    vertex_buffer: wgpu::Buffer,
    index_buffer: wgpu::Buffer,
    index_format: wgpu::IndexFormat,
    parts_buffer: wgpu::Buffer,
}

impl GeometryBuffers {
    /// Uploads vertices, indices (in the [`scene_index_format`] of `records`, every record that
    /// indexes them) and cull parts (each at least one zeroed item long, so it can always be
    /// bound), handing their bytes to `release` as they reach the GPU.
    fn upload(
        gpu: &GpuContext,
        (vertices, indices, parts): (&[SceneVertex], &[u32], &[CullPart]),
        records: &[BuildingRecord],
        release: &dyn Fn(&[u8]),
    ) -> Result<GeometryBuffers, UploadError> {
        use wgpu::BufferUsages as U;
        let index_format = scene_index_format(records);
        let index_buffer = match index_format {
            wgpu::IndexFormat::Uint16 => short_index_buffer(gpu, indices, release)?,
            wgpu::IndexFormat::Uint32 => {
                array_buffer(gpu, "scene indices", indices, U::INDEX, release)?
            }
        };
        Ok(GeometryBuffers {
            vertex_buffer: array_buffer(gpu, "scene vertices", vertices, U::VERTEX, release)?,
            index_buffer,
            index_format,
            parts_buffer: array_buffer(gpu, "building cull parts", parts, U::STORAGE, release)?,
        })
    }
}

/// The index format of a scene whose draws are `records` (and the ground's quad): `Uint16` when
/// every record's vertices fit 16-bit indices relative to its base vertex, as every building
/// and cluster mesh of the generated cities does (3,160 vertices at most in the 1M city), which
/// halves the index buffer (177 MiB there); `Uint32` otherwise.
pub fn scene_index_format(records: &[BuildingRecord]) -> wgpu::IndexFormat {
    let short = usize::from(u16::MAX) + 1;
    if records.iter().all(|r| r.vertex_count as usize <= short) {
        wgpu::IndexFormat::Uint16
    } else {
        wgpu::IndexFormat::Uint32
    }
}

/// The scene's indices as `u16`, made chunk by chunk from the `u32` array. Every index of a
/// record is below its vertex count ([`scene_index_format`]); one that is not (a damaged
/// package) is clamped, and draws some vertex of the scene, as it would have drawn a wrong one
/// in 32 bits.
fn short_index_buffer(
    gpu: &GpuContext,
    indices: &[u32],
    release: &dyn Fn(&[u8]),
) -> Result<wgpu::Buffer, UploadError> {
    const U16: usize = size_of::<u16>();
    let len = indices.len().max(1) * U16;
    buffer_from_chunks(
        gpu,
        "scene indices",
        len,
        wgpu::BufferUsages::INDEX,
        |bytes, out| {
            let range = bytes.start / U16..bytes.end / U16;
            let source = indices.get(range).unwrap_or(&[]);
            let out: &mut [u16] = bytemuck::cast_slice_mut(out);
            for (short, &index) in out.iter_mut().zip(source) {
                *short = u16::try_from(index).unwrap_or(u16::MAX);
            }
            release(bytemuck::cast_slice(source));
        },
    )
}

/// Triangles of `records`.
fn triangles(records: &[BuildingRecord]) -> usize {
    records.iter().map(|r| r.index_count as usize / 3).sum()
}

/// The union of the records' boxes (those not inverted), as [`SceneGeometry`] computes its
/// bounds; a 1 m cube at the origin when there is none.
fn records_bounds(records: &[BuildingRecord]) -> (Vec3, Vec3) {
    let mut lo = Vec3::splat(f32::INFINITY);
    let mut hi = Vec3::splat(f32::NEG_INFINITY);
    for r in records {
        let (bmin, bmax) = (
            Vec3::from_array(r.bounds_min_m),
            Vec3::from_array(r.bounds_max_m),
        );
        if bmin.cmple(bmax).all() {
            lo = lo.min(bmin);
            hi = hi.max(bmax);
        }
    }
    if lo.cmple(hi).all() {
        (lo, hi)
    } else {
        (Vec3::ZERO, Vec3::ONE)
    }
}
