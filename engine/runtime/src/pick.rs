//! What is under a pixel: the drawn building or cluster mesh that the ray from the eye through
//! the pixel meets first.
//!
//! The draws' bounds (one record per building, then per cluster mesh) are indexed once in a
//! BVH (obvhs, PLOC build); a pick walks it front to back and tests the triangles of the draws
//! the caller says were drawn (Möller–Trumbore, obvhs's triangle test), so a pick sees what the
//! user sees: the cluster mesh where the LOD cut drew one, not the buildings under it.

use citywalk_shaders::{BuildingRecord, SceneVertex};
use glam::{Vec3, Vec3A, Vec4Swizzles};
use obvhs::aabb::Aabb;
use obvhs::ray::{Ray, RayHit};
use obvhs::triangle::Triangle;

use crate::camera::Camera;

/// The triangles the records index.
#[derive(Debug, Clone, Copy)]
pub struct PickGeometry<'a> {
    pub records: &'a [BuildingRecord],
    pub vertices: &'a [SceneVertex],
    pub indices: &'a [u32],
}

/// A ray from the eye: origin, unit direction and the distance where it starts (the near
/// plane).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct PickRay {
    pub origin: Vec3,
    pub direction: Vec3,
    pub near_m: f32,
}

/// What a pick hit.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Pick {
    /// The draw id (the record's index).
    pub draw: u32,
    pub distance_m: f32,
}

/// The ray through pixel `(x, y)` (pixels from the top left, fractional) of a `width × height`
/// view from `camera`.
pub fn pixel_ray(camera: &Camera, (width, height): (u32, u32), (x, y): (f32, f32)) -> PickRay {
    let (w, h) = (width.max(1) as f32, height.max(1) as f32);
    let inverse = camera.view_proj(w / h).inverse();
    let ndc = glam::Vec4::new(x / w * 2.0 - 1.0, 1.0 - y / h * 2.0, 1.0, 1.0);
    // Reversed Z: NDC z = 1 is the near plane.
    let near = inverse * ndc;
    let near: Vec3 = near.xyz() / near.w;
    let offset = near - camera.position;
    PickRay {
        origin: camera.position,
        direction: offset.normalize_or(camera.forward()),
        near_m: offset.length(),
    }
}

/// The draws' bounds in a BVH.
pub struct Picker {
    bvh: obvhs::bvh2::Bvh2,
}

impl std::fmt::Debug for Picker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Picker")
            .field("draws", &self.bvh.primitive_indices.len())
            .finish_non_exhaustive()
    }
}

impl Picker {
    /// Indexes the bounds of every record (a draw without triangles is never hit).
    pub fn new(records: &[BuildingRecord]) -> Picker {
        let boxes: Vec<Aabb> = records
            .iter()
            .map(|r| {
                let (lo, hi) = (Vec3A::from(r.bounds_min_m), Vec3A::from(r.bounds_max_m));
                if r.index_count == 0 || !(lo.is_finite() && hi.is_finite()) {
                    // Far away and empty: never reached by a ray from the city.
                    Aabb::new(Vec3A::splat(f32::MAX / 4.0), Vec3A::splat(f32::MAX / 4.0))
                } else {
                    Aabb::new(lo.min(hi), lo.max(hi))
                }
            })
            .collect();
        let mut build_time = std::time::Duration::ZERO;
        let bvh = obvhs::bvh2::builder::build_bvh2(
            &boxes,
            obvhs::BvhBuildParams::fast_build(),
            &mut build_time,
        );
        Picker { bvh }
    }

    /// The first draw that `drawn` accepts hit by `ray`, within `geometry`'s triangles.
    pub fn pick(
        &self,
        ray: PickRay,
        geometry: PickGeometry<'_>,
        drawn: &dyn Fn(u32) -> bool,
    ) -> Option<Pick> {
        let ray = Ray::new(
            ray.origin.into(),
            ray.direction.into(),
            ray.near_m,
            f32::INFINITY,
        );
        let mut hit = RayHit::none();
        let found = self.bvh.ray_traverse(ray, &mut hit, |ray, i| {
            let draw = self.bvh.primitive_indices[i];
            if !drawn(draw) {
                return f32::INFINITY;
            }
            draw_hit(geometry, draw, ray)
        });
        found.then(|| Pick {
            draw: self.bvh.primitive_indices[hit.primitive_id as usize],
            distance_m: hit.t,
        })
    }
}

/// The nearest distance at which `ray` meets a triangle of `draw` (infinity when none).
fn draw_hit(geometry: PickGeometry<'_>, draw: u32, ray: &Ray) -> f32 {
    draw_triangles(geometry, draw)
        .map(|[v0, v1, v2]| {
            Triangle {
                v0: v0.into(),
                v1: v1.into(),
                v2: v2.into(),
            }
            .intersect(ray)
        })
        .fold(f32::INFINITY, f32::min)
}

/// The triangles of draw `draw` (corner positions, metres); none for a draw out of range, and
/// a triangle with a corner outside the arrays is left out.
pub(crate) fn draw_triangles(
    geometry: PickGeometry<'_>,
    draw: u32,
) -> impl Iterator<Item = [Vec3; 3]> + '_ {
    let record = geometry.records.get(draw as usize);
    let indices = record
        .and_then(|r| {
            let first = r.first_index as usize;
            geometry
                .indices
                .get(first..first.saturating_add(r.index_count as usize))
        })
        .unwrap_or(&[]);
    let base = record.map_or(0, |r| i64::from(r.base_vertex));
    let vertex = move |i: u32| -> Option<Vec3> {
        let at = usize::try_from(base + i64::from(i)).ok()?;
        geometry.vertices.get(at).map(|v| Vec3::from(v.position_m))
    };
    indices
        .chunks_exact(3)
        .filter_map(move |t| Some([vertex(t[0])?, vertex(t[1])?, vertex(t[2])?]))
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Unit-ish boxes as records over shared arrays: `(min, max)` per draw.
    fn scene(boxes: &[(Vec3, Vec3)]) -> (Vec<BuildingRecord>, Vec<SceneVertex>, Vec<u32>) {
        let (mut records, mut vertices, mut indices) = (Vec::new(), Vec::new(), Vec::new());
        for (id, &(lo, hi)) in boxes.iter().enumerate() {
            let base = vertices.len() as i32;
            let first = indices.len() as u32;
            for i in 0..8u32 {
                let p = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                vertices.push(SceneVertex {
                    position_m: p.to_array(),
                    building_id: id as u32,
                });
            }
            indices.extend_from_slice(&[
                0, 2, 1, 1, 2, 3, 4, 5, 6, 5, 7, 6, 0, 1, 4, 1, 5, 4, 2, 6, 3, 3, 6, 7, 0, 4, 2, 2,
                4, 6, 1, 3, 5, 3, 7, 5,
            ]);
            records.push(BuildingRecord {
                bounds_min_m: lo.to_array(),
                first_index: first,
                bounds_max_m: hi.to_array(),
                index_count: 36,
                base_vertex: base,
                vertex_count: 8,
                first_part: 0,
                part_count: 0,
            });
        }
        (records, vertices, indices)
    }

    #[test]
    fn the_nearest_drawn_draw_under_the_pixel_is_picked() {
        // Two buildings on the view axis (x), one behind the other, and a cluster mesh (draw 2)
        // around both, as a LOD scene lays them out.
        let (records, vertices, indices) = scene(&[
            (Vec3::new(20.0, -5.0, 0.0), Vec3::new(30.0, 5.0, 10.0)),
            (Vec3::new(50.0, -5.0, 0.0), Vec3::new(60.0, 5.0, 30.0)),
            (Vec3::new(19.0, -6.0, 0.0), Vec3::new(61.0, 6.0, 30.0)),
        ]);
        let geometry = PickGeometry {
            records: &records,
            vertices: &vertices,
            indices: &indices,
        };
        let picker = Picker::new(&records);
        let camera = Camera::new(Vec3::new(0.0, 0.0, 5.0), 0.0, 0.0);
        let size = (64, 48);
        let centre = pixel_ray(&camera, size, (32.0, 24.0));
        assert!((centre.direction - Vec3::X).length() < 0.03, "{centre:?}");
        let buildings = |d: u32| d < 2;
        let hit = picker.pick(centre, geometry, &buildings).unwrap();
        assert_eq!(hit.draw, 0);
        assert!((hit.distance_m - 20.0).abs() < 0.2, "{hit:?}");
        // Above the first building (z > 10 at 20–30 m), the taller one behind.
        let high = pixel_ray(&camera, size, (32.0, 12.0));
        assert_eq!(picker.pick(high, geometry, &buildings).unwrap().draw, 1);
        // Where the cut drew the cluster, the cluster is what is picked.
        let cluster = |d: u32| d == 2;
        let hit = picker.pick(centre, geometry, &cluster).unwrap();
        assert_eq!(hit.draw, 2);
        assert!((hit.distance_m - 19.0).abs() < 0.2);
        // The sky, and nothing drawn.
        let sky = pixel_ray(&camera, size, (32.0, 0.5));
        assert_eq!(picker.pick(sky, geometry, &buildings), None);
        assert_eq!(picker.pick(centre, geometry, &|_| false), None);
    }
}
