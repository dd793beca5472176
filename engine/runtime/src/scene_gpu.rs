//! A [`City`] on the GPU: one vertex buffer, one index buffer with a contiguous index range per
//! building, and per-building records (bounds and index range) on the CPU and in a storage
//! buffer, laid out so that a culling pass can emit one `DrawIndexedIndirect` per building
//! ([`BuildingRecord::draw_args`]).
//!
//! Each record also names the building's tight cull bounds, oriented prisms around the pieces
//! of its mesh ([`cull_parts`]), kept in a second storage buffer.
//!
//! Vertices carry position and building id only; the scene shader computes flat normals from
//! screen-space derivatives, so vertices are shared between triangles.

use bytemuck::Zeroable;
use citywalk_scenes::extrude::building_mesh;
use citywalk_scenes::frustum::{Containment, Frustum};
use citywalk_scenes::{City, TriangleMesh};
use citywalk_shaders::{BuildingRecord, CullPart, DrawIndexedIndirectArgs, GROUND_ID, SceneVertex};
use glam::Vec3;
use wgpu::util::DeviceExt;

use crate::gpu::GpuContext;

pub mod cull_parts;

/// The vertex buffer layout of [`SceneVertex`]: `Float32x3` position at location 0, `Uint32`
/// building id at location 1.
pub const SCENE_VERTEX_LAYOUT: wgpu::VertexBufferLayout<'static> = wgpu::VertexBufferLayout {
    array_stride: size_of::<SceneVertex>() as wgpu::BufferAddress,
    step_mode: wgpu::VertexStepMode::Vertex,
    attributes: &wgpu::vertex_attr_array![0 => Float32x3, 1 => Uint32],
};

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
        let meshes: Vec<TriangleMesh> = city.buildings.iter().map(building_mesh).collect();
        let fallback: Vec<(Vec3, Vec3)> = city.buildings.iter().map(|b| b.bounds()).collect();
        Self::from_meshes(&meshes, &fallback)
    }

    /// One building per mesh, with id = position. `fallback_bounds[i]` is used for a building
    /// whose mesh is empty (it then draws nothing).
    pub fn from_meshes(meshes: &[TriangleMesh], fallback_bounds: &[(Vec3, Vec3)]) -> SceneGeometry {
        Self::from_meshes_with_parts(meshes, fallback_bounds, meshes.len())
    }

    /// As [`SceneGeometry::from_meshes`], with cull parts for the first `with_parts` meshes only
    /// (the others are culled by their boxes, as cluster meshes are:
    /// [`crate::lod::scene::cull_records`]).
    pub fn from_meshes_with_parts(
        meshes: &[TriangleMesh],
        fallback_bounds: &[(Vec3, Vec3)],
        with_parts: usize,
    ) -> SceneGeometry {
        let mut g = SceneGeometry {
            vertices: Vec::with_capacity(
                meshes.iter().map(|m| m.positions.len()).sum::<usize>() + 4,
            ),
            indices: Vec::with_capacity(meshes.iter().map(|m| m.indices.len()).sum::<usize>() + 6),
            records: Vec::with_capacity(meshes.len()),
            ..SceneGeometry::default()
        };
        let mut lo = Vec3::splat(f32::INFINITY);
        let mut hi = Vec3::splat(f32::NEG_INFINITY);
        for (i, mesh) in meshes.iter().enumerate() {
            let (bmin, bmax) = mesh
                .bounds()
                .or_else(|| fallback_bounds.get(i).copied())
                .unwrap_or((Vec3::ZERO, Vec3::ZERO));
            // Indices that point outside the mesh would read other buildings' vertices: drop
            // those triangles.
            let n = mesh.positions.len() as u32;
            let first_index = g.indices.len() as u32;
            for t in mesh.indices.chunks_exact(3) {
                if t.iter().all(|&v| v < n) {
                    g.indices.extend_from_slice(t);
                }
            }
            let first_part = g.parts.len() as u32;
            if i < with_parts {
                g.parts.extend(cull_parts::cull_parts(
                    &mesh.positions,
                    &g.indices[first_index as usize..],
                ));
            }
            g.records.push(BuildingRecord {
                bounds_min_m: bmin.to_array(),
                first_index,
                bounds_max_m: bmax.to_array(),
                index_count: g.indices.len() as u32 - first_index,
                base_vertex: g.vertices.len() as i32,
                vertex_count: n,
                first_part,
                part_count: g.parts.len() as u32 - first_part,
            });
            g.vertices
                .extend(mesh.positions.iter().map(|p| SceneVertex {
                    position_m: p.to_array(),
                    building_id: i as u32,
                }));
            if bmin.cmple(bmax).all() {
                lo = lo.min(bmin);
                hi = hi.max(bmax);
            }
        }
        if !lo.cmple(hi).all() {
            (lo, hi) = (Vec3::ZERO, Vec3::ONE);
        }
        g.bounds = (lo, hi);
        g.push_ground();
        g
    }

    /// A ground quad reaching well past the city (so the horizon is ground, not sky), at the
    /// lowest base height (at most 0).
    fn push_ground(&mut self) {
        let (lo, hi) = self.bounds;
        let centre = (lo + hi) * 0.5;
        let half_m = ((hi - lo).truncate().max_element() * 0.5).max(100.0) * 50.0 + 5_000.0;
        let z = lo.z.min(0.0);
        let base_vertex = self.vertices.len() as i32;
        for (dx, dy) in [(-1.0, -1.0), (1.0, -1.0), (1.0, 1.0), (-1.0, 1.0)] {
            self.vertices.push(SceneVertex {
                position_m: [centre.x + dx * half_m, centre.y + dy * half_m, z],
                building_id: GROUND_ID,
            });
        }
        let first_index = self.indices.len() as u32;
        self.indices.extend_from_slice(&[0, 1, 2, 0, 2, 3]);
        self.ground = DrawIndexedIndirectArgs {
            index_count: 6,
            instance_count: 1,
            first_index,
            base_vertex,
            first_instance: 0,
        };
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

    /// Checks the layout: index ranges are contiguous, in building order, inside the index
    /// buffer, and every index of a building stays within its own vertices.
    pub fn check_invariants(&self) -> Result<(), String> {
        let mut next_index = 0u32;
        let mut next_vertex = 0i32;
        for (i, r) in self.records.iter().enumerate() {
            if r.first_index != next_index || r.base_vertex != next_vertex {
                return Err(format!(
                    "building {i}: range does not follow the previous one"
                ));
            }
            let end = (r.first_index + r.index_count) as usize;
            let range = self
                .indices
                .get(r.first_index as usize..end)
                .ok_or_else(|| format!("building {i}: index range past the buffer"))?;
            if let Some(bad) = range.iter().find(|&&v| v >= r.vertex_count) {
                return Err(format!(
                    "building {i}: index {bad} ≥ vertex count {}",
                    r.vertex_count
                ));
            }
            let verts = &self.vertices[r.base_vertex as usize..][..r.vertex_count as usize];
            if verts.iter().any(|v| v.building_id != i as u32) {
                return Err(format!("building {i}: vertex with another building id"));
            }
            next_index += r.index_count;
            next_vertex += r.vertex_count as i32;
        }
        if self.ground.first_index != next_index || self.ground.base_vertex != next_vertex {
            return Err("ground does not follow the buildings".into());
        }
        Ok(())
    }
}

/// The scene's buffers on the GPU, with the CPU copy of the per-building records.
#[derive(Debug)]
pub struct SceneGpu {
    /// [`SceneVertex`] array ([`SCENE_VERTEX_LAYOUT`]).
    pub vertex_buffer: wgpu::Buffer,
    /// `u32` indices, relative to each range's `base_vertex`.
    pub index_buffer: wgpu::Buffer,
    /// [`BuildingRecord`] array (storage, read-only in shaders); at least one record long even
    /// for an empty scene, so it can always be bound.
    pub records_buffer: wgpu::Buffer,
    /// [`CullPart`] array the records name (storage, read-only); at least one part long.
    pub parts_buffer: wgpu::Buffer,
    /// One [`DrawIndexedIndirectArgs`] per building in id order, then the ground's: the
    /// brute-force draw list (`INDIRECT | STORAGE | COPY_SRC`).
    pub all_draws_buffer: wgpu::Buffer,
    /// CPU copy of the records, indexed by building id.
    pub records: Vec<BuildingRecord>,
    /// CPU copy of the cull parts.
    pub parts: Vec<CullPart>,
    /// The ground plane's draw.
    pub ground: DrawIndexedIndirectArgs,
    /// Bounds of all buildings.
    pub bounds: (Vec3, Vec3),
    /// Building triangles (the ground excluded).
    pub triangle_count: usize,
}

impl SceneGpu {
    /// Meshes and uploads `city`.
    pub fn upload_city(gpu: &GpuContext, city: &City) -> SceneGpu {
        Self::upload(gpu, &SceneGeometry::from_city(city))
    }

    /// Uploads prepared geometry.
    pub fn upload(gpu: &GpuContext, geometry: &SceneGeometry) -> SceneGpu {
        let device = &gpu.device;
        let vertex_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("scene vertices"),
            contents: bytemuck::cast_slice(&geometry.vertices),
            usage: wgpu::BufferUsages::VERTEX | wgpu::BufferUsages::STORAGE,
        });
        let index_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("scene indices"),
            contents: bytemuck::cast_slice(&geometry.indices),
            usage: wgpu::BufferUsages::INDEX | wgpu::BufferUsages::STORAGE,
        });
        let padded;
        let records: &[BuildingRecord] = if geometry.records.is_empty() {
            padded = [BuildingRecord::zeroed()];
            &padded
        } else {
            &geometry.records
        };
        let records_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("building records"),
            contents: bytemuck::cast_slice(records),
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
        });
        let no_parts = [CullPart::zeroed()];
        let parts_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("building cull parts"),
            contents: bytemuck::cast_slice(if geometry.parts.is_empty() {
                &no_parts
            } else {
                &geometry.parts
            }),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let all_draws: Vec<DrawIndexedIndirectArgs> = geometry
            .records
            .iter()
            .map(BuildingRecord::draw_args)
            .chain(std::iter::once(geometry.ground))
            .collect();
        let all_draws_buffer = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("all building draws"),
            contents: bytemuck::cast_slice(&all_draws),
            usage: wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC,
        });
        SceneGpu {
            vertex_buffer,
            index_buffer,
            records_buffer,
            parts_buffer,
            all_draws_buffer,
            records: geometry.records.clone(),
            parts: geometry.parts.clone(),
            ground: geometry.ground,
            bounds: geometry.bounds,
            triangle_count: geometry.building_triangle_count(),
        }
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
        pass.set_index_buffer(self.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
    }

    /// Draws every building and the ground with one multi-draw over
    /// [`SceneGpu::all_draws_buffer`] (one indirect draw per building, so the per-building
    /// ranges are exercised exactly as a culling pass will emit them). Call after
    /// [`SceneGpu::bind`].
    pub fn draw_all(&self, pass: &mut wgpu::RenderPass<'_>) {
        pass.multi_draw_indexed_indirect(&self.all_draws_buffer, 0, self.records.len() as u32 + 1);
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
