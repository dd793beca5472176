//! View-frustum planes and the sphere / box tests of hierarchical frustum culling.
//!
//! Planes are extracted from a view-projection matrix after Gribb & Hartmann, *Fast
//! extraction of viewing frustum planes from the world-view-projection matrix* (2001), for
//! wgpu clip space (`-w ≤ x, y ≤ w`, `0 ≤ z ≤ w`). Both ordinary and reversed-Z projections
//! work; an infinite projection (reversed-Z infinite far, or a standard infinite far) yields a
//! far plane with no normal (`0·p + d`), which is dropped, leaving 5 planes.

use glam::{Mat4, Vec3, Vec4};

/// Where a volume lies with respect to the frustum.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Containment {
    Outside,
    Intersecting,
    Inside,
}

/// Up to six planes `(n, d)`, `|n| = 1`, the inside being `n·p + d ≥ 0`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Frustum {
    planes: [Vec4; 6],
    count: usize,
    /// A degenerate matrix can produce a plane that nothing satisfies.
    empty: bool,
}

impl Frustum {
    /// The frustum of the view-projection matrix `view_proj` (clip = `view_proj · world`).
    pub fn from_view_proj(view_proj: Mat4) -> Frustum {
        let r0 = view_proj.row(0);
        let r1 = view_proj.row(1);
        let r2 = view_proj.row(2);
        let r3 = view_proj.row(3);
        let raw = [r3 + r0, r3 - r0, r3 + r1, r3 - r1, r2, r3 - r2];
        let mut planes = [Vec4::ZERO; 6];
        let mut count = 0;
        let mut empty = false;
        for p in raw {
            let n = p.truncate().length();
            if !n.is_finite() || !p.w.is_finite() {
                empty = true;
                continue;
            }
            // A plane without a normal: always true (infinite far plane) or never true.
            if n <= 1e-7 * p.w.abs().max(1.0) {
                if p.w < 0.0 {
                    empty = true;
                }
                continue;
            }
            planes[count] = p / n;
            count += 1;
        }
        Frustum {
            planes,
            count,
            empty,
        }
    }

    /// The planes in use.
    pub fn planes(&self) -> &[Vec4] {
        &self.planes[..self.count]
    }

    fn distance(plane: Vec4, p: Vec3) -> f32 {
        plane.truncate().dot(p) + plane.w
    }

    /// Classifies a sphere.
    pub fn classify_sphere(&self, centre: Vec3, radius: f32) -> Containment {
        if self.empty {
            return Containment::Outside;
        }
        let mut inside = true;
        for &plane in self.planes() {
            let d = Self::distance(plane, centre);
            if d < -radius {
                return Containment::Outside;
            }
            if d < radius {
                inside = false;
            }
        }
        if inside {
            Containment::Inside
        } else {
            Containment::Intersecting
        }
    }

    /// Classifies an axis-aligned box by its nearest and farthest corners along each plane's
    /// normal (the box is outside when its farthest corner is behind one plane).
    pub fn classify_aabb(&self, min: Vec3, max: Vec3) -> Containment {
        if self.empty {
            return Containment::Outside;
        }
        let mut inside = true;
        for &plane in self.planes() {
            let n = plane.truncate();
            let far = Vec3::select(n.cmpge(Vec3::ZERO), max, min);
            let near = Vec3::select(n.cmpge(Vec3::ZERO), min, max);
            if Self::distance(plane, far) < 0.0 {
                return Containment::Outside;
            }
            if Self::distance(plane, near) < 0.0 {
                inside = false;
            }
        }
        if inside {
            Containment::Inside
        } else {
            Containment::Intersecting
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn reversed_z_infinite(fov_y: f32, aspect: f32, near: f32) -> Mat4 {
        glam::camera::rh::proj::directx::perspective_infinite_reverse(fov_y, aspect, near)
    }

    #[test]
    fn a_standard_perspective_has_six_planes_and_classifies_points() {
        let proj = glam::camera::rh::proj::directx::perspective(1.0, 1.5, 0.5, 100.0);
        let view =
            glam::camera::rh::view::look_at_mat4(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), Vec3::Z);
        let f = Frustum::from_view_proj(proj * view);
        assert_eq!(f.planes().len(), 6);
        assert_eq!(
            f.classify_sphere(Vec3::new(0.0, 10.0, 0.0), 0.1),
            Containment::Inside
        );
        assert_eq!(
            f.classify_sphere(Vec3::new(0.0, -10.0, 0.0), 1.0),
            Containment::Outside
        );
        assert_eq!(
            f.classify_sphere(Vec3::new(0.0, 200.0, 0.0), 1.0),
            Containment::Outside
        );
        assert_eq!(
            f.classify_aabb(Vec3::new(-1.0, 99.0, -1.0), Vec3::new(1.0, 101.0, 1.0)),
            Containment::Intersecting
        );
    }

    #[test]
    fn a_reversed_z_infinite_projection_drops_the_far_plane() {
        let proj = reversed_z_infinite(1.0, 1.5, 0.5);
        let view =
            glam::camera::rh::view::look_at_mat4(Vec3::ZERO, Vec3::new(0.0, 1.0, 0.0), Vec3::Z);
        let f = Frustum::from_view_proj(proj * view);
        assert_eq!(f.planes().len(), 5);
        // Arbitrarily far ahead is inside; behind the camera is outside.
        assert_eq!(
            f.classify_sphere(Vec3::new(0.0, 1.0e6, 0.0), 1.0),
            Containment::Inside
        );
        assert_eq!(
            f.classify_aabb(Vec3::new(-1.0, -5.0, -1.0), Vec3::new(1.0, -3.0, 1.0)),
            Containment::Outside
        );
        assert_eq!(
            f.classify_aabb(Vec3::new(-1.0, 0.1, -1.0), Vec3::new(1.0, 3.0, 1.0)),
            Containment::Intersecting
        );
    }
}
