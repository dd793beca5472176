//! The virtual occluders on the GPU and their per-frame selection by projected size (Germs &
//! Jansen 2001 build them offline; the pre-pass draws the ones near the camera).

use citywalk_scenes::frustum::{Containment, Frustum};
use citywalk_scenes::occluder::OccluderSet;
use citywalk_shaders::{DrawIndexedIndirectArgs, SceneVertex};
use glam::Vec3;

use crate::camera::Camera;
use crate::gpu::GpuContext;

/// One occluder on the GPU: its draw and its bounds for the CPU selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OccluderDraw {
    pub building: u32,
    pub draw: DrawIndexedIndirectArgs,
    pub bounds_min_m: Vec3,
    pub bounds_max_m: Vec3,
    pub triangles: u32,
}

/// Every occluder mesh of a scene in one vertex and one index buffer, with per-occluder ranges.
#[derive(Debug)]
pub struct OccluderMeshes {
    pub(super) vertex_buffer: wgpu::Buffer,
    pub(super) index_buffer: wgpu::Buffer,
    /// One entry per occluder with a non-empty mesh.
    pub occluders: Vec<OccluderDraw>,
}

impl OccluderMeshes {
    /// Uploads every occluder of `set` (vertices carry the occluder's building id). Triangles
    /// with an index outside their mesh and non-finite meshes are left out.
    pub fn upload(gpu: &GpuContext, set: &OccluderSet) -> OccluderMeshes {
        let mut vertices: Vec<SceneVertex> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut occluders = Vec::new();
        for o in &set.occluders {
            let Some((lo, hi)) = o.mesh.bounds() else {
                continue;
            };
            if !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            let n = o.mesh.positions.len() as u32;
            let first_index = indices.len() as u32;
            for t in o.mesh.indices.chunks_exact(3) {
                if t.iter().all(|&v| v < n) {
                    indices.extend_from_slice(t);
                }
            }
            let index_count = indices.len() as u32 - first_index;
            if index_count == 0 {
                continue;
            }
            let base_vertex = vertices.len() as i32;
            vertices.extend(o.mesh.positions.iter().map(|p| SceneVertex {
                position_m: p.to_array(),
                building_id: o.building.0,
            }));
            occluders.push(OccluderDraw {
                building: o.building.0,
                draw: DrawIndexedIndirectArgs {
                    index_count,
                    instance_count: 1,
                    first_index,
                    base_vertex,
                    first_instance: 0,
                },
                bounds_min_m: lo,
                bounds_max_m: hi,
                triangles: index_count / 3,
            });
        }
        // Buffers are never empty, so they can always be bound.
        let (vertex_buffer, index_buffer) =
            crate::render::mesh_buffers(&gpu.device, "occluder", vertices, indices);
        OccluderMeshes {
            vertex_buffer,
            index_buffer,
            occluders,
        }
    }

    /// The occluders to draw for `camera` on a viewport `height_px` tall: in the frustum, of a
    /// building not drawn by the early pass (its own geometry hides at least as much), and whose
    /// bounding sphere projects to more than `min_px` pixels (or contains the eye).
    pub fn select(
        &self,
        camera: &Camera,
        frustum: &Frustum,
        height_px: u32,
        min_px: f32,
        drawn_early: &[bool],
    ) -> Vec<usize> {
        let px_per_rad = height_px as f32 / (camera.fov_y_rad * 0.5).tan();
        self.occluders
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                !drawn_early
                    .get(o.building as usize)
                    .copied()
                    .unwrap_or(false)
            })
            .filter(|(_, o)| occluder_wanted(o, camera.position, frustum, px_per_rad, min_px))
            .map(|(i, _)| i)
            .collect()
    }
}

/// Whether an occluder is near enough to draw: its bounding sphere contains the eye or projects
/// to more than `min_px` pixels (`px_per_rad`: viewport height over `tan(fov_y / 2)`), and its
/// box is not outside the frustum.
fn occluder_wanted(
    o: &OccluderDraw,
    eye: Vec3,
    frustum: &Frustum,
    px_per_rad: f32,
    min_px: f32,
) -> bool {
    let centre = (o.bounds_min_m + o.bounds_max_m) * 0.5;
    let radius_m = (o.bounds_max_m - o.bounds_min_m).length() * 0.5;
    let distance_m = centre.distance(eye);
    (distance_m <= radius_m || radius_m / distance_m * px_per_rad > min_px)
        && frustum.classify_aabb(o.bounds_min_m, o.bounds_max_m) != Containment::Outside
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::frame::DEFAULT_OCCLUDER_MIN_PX;

    #[test]
    fn occluders_are_wanted_by_projected_size_and_frustum() {
        let camera = Camera::new(Vec3::ZERO, 0.0, 0.0);
        let height_px = 720;
        let px_per_rad = height_px as f32 / (camera.fov_y_rad * 0.5).tan();
        let frustum = Frustum::from_view_proj(camera.view_proj(16.0 / 9.0));
        // A 10 m cube (radius ≈ 8.66 m) straight ahead at distance d projects to
        // 8.66 / d · 1247 px: more than 24 px up to d ≈ 450 m.
        let cube = |centre: Vec3| OccluderDraw {
            building: 0,
            draw: DrawIndexedIndirectArgs {
                index_count: 3,
                instance_count: 1,
                first_index: 0,
                base_vertex: 0,
                first_instance: 0,
            },
            bounds_min_m: centre - Vec3::splat(5.0),
            bounds_max_m: centre + Vec3::splat(5.0),
            triangles: 1,
        };
        let wanted = |centre: Vec3| {
            occluder_wanted(
                &cube(centre),
                camera.position,
                &frustum,
                px_per_rad,
                DEFAULT_OCCLUDER_MIN_PX,
            )
        };
        assert!(wanted(Vec3::new(50.0, 0.0, 0.0)));
        assert!(wanted(Vec3::new(400.0, 0.0, 0.0)));
        assert!(!wanted(Vec3::new(470.0, 0.0, 0.0)));
        // Behind the eye: outside the frustum however large.
        assert!(!wanted(Vec3::new(-20.0, 0.0, 0.0)));
        // Around the eye: always.
        assert!(wanted(Vec3::new(1.0, 0.0, 0.0)));
    }
}
