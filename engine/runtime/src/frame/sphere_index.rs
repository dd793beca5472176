//! Bounding spheres indexed for "which spheres in the frustum project to more than N pixels
//! from here": a sphere of radius r projects to more than `min_px` only within `r · k` of the eye
//! (`k` from the viewport, the field of view and `min_px`), so the spheres are binned by radius
//! (half powers of two) and each bin's centres kept in an R-tree (`rstar`); a query walks, per
//! bin, the nodes whose centres lie within the bin's largest radius times `k` and whose boxes,
//! grown by that radius, are not outside the frustum. The occluder selection's work per frame
//! then follows the occluders near the eye and in view, not the city's size.

use citywalk_scenes::frustum::{Containment, Frustum};
use glam::Vec3;
use rstar::primitives::GeomWithData;
use rstar::{AABB, RTree, SelectionFunction};

type Centre = GeomWithData<[f32; 3], u32>;

/// Bins per doubling of the radius: a bin's largest radius is at most √2 times any of its
/// spheres', so a query's reach overshoots a sphere's own by at most √2 (twice the area with
/// powers of two: 22,000 candidates for 3,000 selected on a 1M street walk).
const BINS_PER_OCTAVE: f32 = 2.0;

/// The spheres of one radius bin.
#[derive(Debug)]
struct Bin {
    max_radius_m: f32,
    centres: RTree<Centre>,
}

/// Spheres (centre, radius) binned by radius, centres in R-trees.
#[derive(Debug, Default)]
pub(super) struct SphereIndex {
    bins: Vec<Bin>,
    len: usize,
}

impl SphereIndex {
    /// Indexes `spheres` (centre, radius in metres); entry `i` is reported as `i`. Spheres with a
    /// non-finite centre or radius are left out (no query can want them).
    pub fn new(spheres: impl IntoIterator<Item = (Vec3, f32)>) -> SphereIndex {
        let mut by_bin: std::collections::BTreeMap<i32, (f32, Vec<Centre>)> = Default::default();
        let mut len = 0;
        for (i, (centre, radius)) in spheres.into_iter().enumerate() {
            len += 1;
            if !(centre.is_finite() && radius.is_finite()) {
                continue;
            }
            let radius = radius.max(0.0);
            let bin = (radius.max(1e-3).log2() * BINS_PER_OCTAVE).ceil() as i32;
            let entry = by_bin.entry(bin).or_insert((0.0, Vec::new()));
            entry.0 = entry.0.max(radius);
            entry.1.push(GeomWithData::new(centre.to_array(), i as u32));
        }
        SphereIndex {
            bins: by_bin
                .into_values()
                .map(|(max_radius_m, centres)| Bin {
                    max_radius_m,
                    centres: RTree::bulk_load(centres),
                })
                .collect(),
            len,
        }
    }

    /// How many spheres were given.
    pub fn len(&self) -> usize {
        self.len
    }

    /// Every sphere whose centre lies within `radius · reach_per_radius` of `eye` and that is
    /// not outside `frustum` (and some others of its bin: the exact tests are the caller's),
    /// ascending.
    pub fn near(&self, eye: Vec3, reach_per_radius: f32, frustum: &Frustum) -> Vec<usize> {
        let mut out: Vec<usize> = Vec::new();
        for bin in &self.bins {
            let reach_m = bin.max_radius_m * reach_per_radius;
            let select = InReachAndView {
                eye: eye.to_array(),
                reach_m2: reach_m * reach_m,
                grow_m: bin.max_radius_m,
                frustum,
            };
            out.extend(
                bin.centres
                    .locate_with_selection_function(select)
                    .map(|c| c.data as usize),
            );
        }
        out.sort_unstable();
        out
    }
}

/// The R-tree walk of [`SphereIndex::near`]: a node is opened when its centres' box comes within
/// the reach of the eye and, grown by the bin's largest radius (so that it holds every sphere's
/// box), is not outside the frustum; a centre is taken within the reach.
struct InReachAndView<'a> {
    eye: [f32; 3],
    reach_m2: f32,
    grow_m: f32,
    frustum: &'a Frustum,
}

impl SelectionFunction<Centre> for InReachAndView<'_> {
    fn should_unpack_parent(&self, envelope: &AABB<[f32; 3]>) -> bool {
        envelope.distance_2(&self.eye) <= self.reach_m2
            && self.frustum.classify_aabb(
                Vec3::from_array(envelope.lower()) - self.grow_m,
                Vec3::from_array(envelope.upper()) + self.grow_m,
            ) != Containment::Outside
    }

    fn should_unpack_leaf(&self, leaf: &Centre) -> bool {
        Vec3::from_array(*leaf.geom()).distance_squared(Vec3::from_array(self.eye)) <= self.reach_m2
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn near_holds_every_sphere_within_its_reach() {
        let mut state = 7u64;
        let mut next = || {
            state = state
                .wrapping_mul(6_364_136_223_846_793_005)
                .wrapping_add(1_442_695_040_888_963_407);
            (state >> 40) as f32 / (1u64 << 24) as f32
        };
        let spheres: Vec<(Vec3, f32)> = (0..3000)
            .map(|_| {
                let c = Vec3::new(
                    next() * 2000.0 - 1000.0,
                    next() * 2000.0 - 1000.0,
                    next() * 50.0,
                );
                (c, next() * next() * 80.0)
            })
            .chain([(Vec3::NAN, 1.0), (Vec3::ZERO, f32::INFINITY)])
            .collect();
        let index = SphereIndex::new(spheres.iter().copied());
        assert_eq!(index.len(), spheres.len());
        for (eye, k, yaw) in [
            (Vec3::new(0.0, 0.0, 1.7), 20.0, 0.0),
            (Vec3::new(300.0, -200.0, 1.7), 5.0, 2.0),
            (Vec3::new(0.0, 0.0, 30.0), 1.0, 4.0),
            (Vec3::new(-900.0, 900.0, 1.7), 50.0, 5.5),
        ] {
            let camera = crate::camera::Camera::new(eye, yaw, -0.1);
            let frustum = Frustum::from_view_proj(camera.view_proj(16.0 / 9.0));
            let near = index.near(eye, k, &frustum);
            // Within reach, and the sphere's cube (which holds the occluder's box) in view.
            let exact = |in_view: &dyn Fn(Vec3, f32) -> bool| -> Vec<usize> {
                (0..spheres.len())
                    .filter(|&i| {
                        let (c, r) = spheres[i];
                        c.is_finite() && r.is_finite() && c.distance(eye) <= r * k && in_view(c, r)
                    })
                    .collect()
            };
            let wanted = exact(&|c, r| frustum.classify_aabb(c - r, c + r) != Containment::Outside);
            assert!(!wanted.is_empty(), "k {k}: nothing to find");
            assert!(
                wanted.iter().all(|i| near.binary_search(i).is_ok()),
                "k {k}"
            );
            assert!(near.len() < spheres.len(), "the index prunes");
            assert!(near.windows(2).all(|w| w[0] < w[1]));
        }
    }
}
