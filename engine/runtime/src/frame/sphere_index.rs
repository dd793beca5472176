//! Bounding spheres indexed for "which spheres project to more than N pixels from here": a
//! sphere of radius r projects to more than `min_px` only within `r · k` of the eye (`k` from
//! the viewport, the field of view and `min_px`), so the spheres are binned by radius (powers of
//! two) and each bin's centres kept in an R-tree (`rstar`); a query visits, per bin, the centres
//! within the bin's largest radius times `k`. The occluder selection's work per frame then
//! follows the occluders near the eye, not the city's size.

use glam::Vec3;
use rstar::RTree;
use rstar::primitives::GeomWithData;

type Centre = GeomWithData<[f32; 3], u32>;

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
            let bin = radius.max(1e-3).log2().ceil() as i32;
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

    /// Every sphere whose centre lies within `radius · reach_per_radius` of `eye` (and some
    /// others of its bin: the exact test is the caller's), ascending.
    pub fn near(&self, eye: Vec3, reach_per_radius: f32) -> Vec<usize> {
        let mut out: Vec<usize> = Vec::new();
        for bin in &self.bins {
            let reach_m = bin.max_radius_m * reach_per_radius;
            out.extend(
                bin.centres
                    .locate_within_distance(eye.to_array(), reach_m * reach_m)
                    .map(|c| c.data as usize),
            );
        }
        out.sort_unstable();
        out
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
                let c = Vec3::new(next(), next(), next() * 0.05) * 2000.0 - 1000.0;
                (c, next() * next() * 80.0)
            })
            .chain([(Vec3::NAN, 1.0), (Vec3::ZERO, f32::INFINITY)])
            .collect();
        let index = SphereIndex::new(spheres.iter().copied());
        assert_eq!(index.len(), spheres.len());
        for (eye, k) in [
            (Vec3::ZERO, 20.0),
            (Vec3::new(300.0, -200.0, 1.7), 5.0),
            (Vec3::ZERO, 1.0),
        ] {
            let near = index.near(eye, k);
            let exact: Vec<usize> = (0..spheres.len())
                .filter(|&i| {
                    let (c, r) = spheres[i];
                    c.is_finite() && r.is_finite() && c.distance(eye) <= r * k
                })
                .collect();
            assert!(exact.iter().all(|i| near.binary_search(i).is_ok()), "k {k}");
            assert!(near.len() < spheres.len(), "the index prunes");
            assert!(near.windows(2).all(|w| w[0] < w[1]));
        }
    }
}
