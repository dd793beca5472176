//! The five roof views of a cluster mesh, and the one a look vector picks.
//!
//! Chang et al. 2008 §7: the roof is textured from five views of the cluster's buildings
//! (scaled to the cluster's height), top-down and 45° down from the north, east, south and
//! west; at run time the view closest to the look vector is used. A view is an orthographic
//! projection along its direction whose image spans the projection of the cluster's box, so
//! the texture coordinate of a roof point is where that view sees it. Axes: x east, y north,
//! z up.

use glam::Vec3;

/// One of the five views.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum RoofView {
    Top,
    /// From the north, looking south and 45° down.
    North,
    East,
    South,
    West,
}

impl RoofView {
    /// The five, in the order of their textures.
    pub const ALL: [RoofView; 5] = [
        RoofView::Top,
        RoofView::North,
        RoofView::East,
        RoofView::South,
        RoofView::West,
    ];

    /// The unit direction the view looks along.
    pub fn direction(self) -> Vec3 {
        let h = std::f32::consts::FRAC_1_SQRT_2;
        match self {
            RoofView::Top => Vec3::NEG_Z,
            RoofView::North => Vec3::new(0.0, -h, -h),
            RoofView::East => Vec3::new(-h, 0.0, -h),
            RoofView::South => Vec3::new(0.0, h, -h),
            RoofView::West => Vec3::new(h, 0.0, -h),
        }
    }

    /// The view whose direction is closest to `look` (largest cosine; the first in
    /// [`Self::ALL`] on a tie). A look vector of no length or direction picks the top view.
    pub fn closest_to(look: Vec3) -> RoofView {
        let look = look.normalize_or_zero();
        let mut best = (RoofView::Top, look.dot(RoofView::Top.direction()));
        for view in &RoofView::ALL[1..] {
            let cosine = look.dot(view.direction());
            if cosine > best.1 {
                best = (*view, cosine);
            }
        }
        best.0
    }

    /// The image's unit axes: right, and down (v grows down the texture). The top view has
    /// north up and east right; an oblique view is level, its up tilted away from the eye.
    fn image_axes(self) -> (Vec3, Vec3) {
        if self == RoofView::Top {
            return (Vec3::X, Vec3::NEG_Y);
        }
        let direction = self.direction();
        let right = direction.cross(Vec3::Z).normalize();
        let up = right.cross(direction);
        (right, -up)
    }

    /// The texture coordinate (0..1, v down) at which this view sees `point` of a cluster
    /// whose box is `lo`..`hi`. A box of no extent across the view maps to the middle.
    pub fn uv(self, point: Vec3, lo: Vec3, hi: Vec3) -> [f32; 2] {
        self.frame(lo, hi).uv(point)
    }

    /// The orthographic image of the box `lo`..`hi` seen from this view: what [`Self::uv`]
    /// reads and the baker renders.
    pub fn frame(self, lo: Vec3, hi: Vec3) -> ViewFrame {
        let (right, down) = self.image_axes();
        let depth = self.direction();
        let corners = (0..8).map(|i| {
            Vec3::new(
                if i & 1 == 0 { lo.x } else { hi.x },
                if i & 2 == 0 { lo.y } else { hi.y },
                if i & 4 == 0 { lo.z } else { hi.z },
            )
        });
        let mut ranges = [(f32::MAX, f32::MIN); 3];
        for c in corners {
            for (range, axis) in ranges.iter_mut().zip([right, down, depth]) {
                let x = c.dot(axis);
                *range = (range.0.min(x), range.1.max(x));
            }
        }
        ViewFrame {
            axes: [right, down, depth],
            ranges,
        }
    }
}

/// An orthographic view of a box: the image's right and down axes and the view direction,
/// each with the range the box's corners span along it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct ViewFrame {
    /// Right, down (in the image) and the direction of view, unit vectors.
    pub axes: [Vec3; 3],
    /// The box's extent along each axis, `(min, max)`.
    pub ranges: [(f32, f32); 3],
}

impl ViewFrame {
    /// Where `point` lies along axis `k`, 0 at the range's start and 1 at its end; 0.5 for a
    /// range of no extent.
    pub fn along(&self, k: usize, point: Vec3) -> f32 {
        let (min, max) = self.ranges[k];
        if max > min {
            (point.dot(self.axes[k]) - min) / (max - min)
        } else {
            0.5
        }
    }

    /// The image coordinate of `point`, 0..1 across the image, v down.
    pub fn uv(&self, point: Vec3) -> [f32; 2] {
        [self.along(0, point), self.along(1, point)]
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_look_vector_picks_the_nearest_view() {
        let cases = [
            (Vec3::new(0.0, 0.0, -1.0), RoofView::Top),
            (Vec3::new(0.1, -0.2, -1.0), RoofView::Top),
            (Vec3::new(0.0, -1.0, -1.0), RoofView::North),
            // Level, looking south: the view from the north is the nearest of the five.
            (Vec3::new(0.0, -1.0, 0.0), RoofView::North),
            (Vec3::new(-1.0, 0.2, -0.8), RoofView::East),
            (Vec3::new(0.3, 1.0, -0.5), RoofView::South),
            (Vec3::new(5.0, 0.0, -4.0), RoofView::West),
            // A look of no length or direction.
            (Vec3::ZERO, RoofView::Top),
            (Vec3::NAN, RoofView::Top),
        ];
        for (look, view) in cases {
            assert_eq!(RoofView::closest_to(look), view, "{look}");
        }
        for view in RoofView::ALL {
            assert_eq!(RoofView::closest_to(view.direction()), view);
            assert!((view.direction().length() - 1.0).abs() < 1e-6);
        }
    }

    #[test]
    fn the_top_view_maps_the_plan_with_north_up() {
        let (lo, hi) = (Vec3::new(10.0, 20.0, 0.0), Vec3::new(30.0, 60.0, 15.0));
        let top = RoofView::Top;
        assert_eq!(top.uv(Vec3::new(10.0, 60.0, 15.0), lo, hi), [0.0, 0.0]);
        assert_eq!(top.uv(Vec3::new(30.0, 20.0, 15.0), lo, hi), [1.0, 1.0]);
        assert_eq!(top.uv(Vec3::new(20.0, 40.0, 3.0), lo, hi), [0.5, 0.5]);
    }

    #[test]
    fn every_view_sees_the_whole_box_across_its_image() {
        let (lo, hi) = (Vec3::new(-5.0, 2.0, 0.0), Vec3::new(40.0, 17.0, 22.0));
        for view in RoofView::ALL {
            let (mut u, mut v) = ((1.0f32, 0.0f32), (1.0f32, 0.0f32));
            for i in 0..8 {
                let c = Vec3::new(
                    if i & 1 == 0 { lo.x } else { hi.x },
                    if i & 2 == 0 { lo.y } else { hi.y },
                    if i & 4 == 0 { lo.z } else { hi.z },
                );
                let [cu, cv] = view.uv(c, lo, hi);
                assert!((-1e-6..=1.0 + 1e-6).contains(&cu), "{view:?}: {cu}");
                assert!((-1e-6..=1.0 + 1e-6).contains(&cv), "{view:?}: {cv}");
                u = (u.0.min(cu), u.1.max(cu));
                v = (v.0.min(cv), v.1.max(cv));
            }
            assert!(
                u.0.abs() < 1e-6 && (u.1 - 1.0).abs() < 1e-6,
                "{view:?} {u:?}"
            );
            assert!(
                v.0.abs() < 1e-6 && (v.1 - 1.0).abs() < 1e-6,
                "{view:?} {v:?}"
            );
        }
    }

    #[test]
    fn an_oblique_view_puts_the_far_side_of_the_roof_at_the_top() {
        // From the north, looking south: the roof's south edge is farther from the eye and
        // higher in the image (smaller v) than its north edge; east is on the image's left.
        let (lo, hi) = (Vec3::ZERO, Vec3::new(20.0, 20.0, 10.0));
        let north = RoofView::North;
        let far = north.uv(Vec3::new(10.0, 0.0, 10.0), lo, hi);
        let near = north.uv(Vec3::new(10.0, 20.0, 10.0), lo, hi);
        assert!(far[1] < near[1], "{far:?} {near:?}");
        let east = north.uv(Vec3::new(20.0, 10.0, 10.0), lo, hi);
        let west = north.uv(Vec3::new(0.0, 10.0, 10.0), lo, hi);
        assert!(east[0] < west[0], "{east:?} {west:?}");
        // A wall's foot is below its top in the image.
        let foot = north.uv(Vec3::new(10.0, 20.0, 0.0), lo, hi);
        assert!(foot[1] > near[1]);
    }
}
