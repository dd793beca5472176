//! Leaf footprints: one counter-clockwise simple ring per building in the shared vertex array.

use std::collections::HashMap;

use citywalk_scenes::Building;
use geo::{Area, Centroid};

use super::geom::{Pt, convex_hull, ring_is_simple_ccw, signed_area};

/// The shared vertex array (Yang et al. 2011 §3.3.1): equal coordinates get one index, so
/// buildings that share corners share vertices and hull merging finds the contact exactly.
#[derive(Debug, Clone, Default)]
pub struct VertexStore {
    pub verts: Vec<Pt>,
    index: HashMap<(u64, u64), u32>,
}

impl VertexStore {
    /// Index of `p`, inserting it when new. `-0.0` and `0.0` are the same point.
    pub fn intern(&mut self, p: Pt) -> u32 {
        let key = ((p[0] + 0.0).to_bits(), (p[1] + 0.0).to_bits());
        if let Some(&i) = self.index.get(&key) {
            return i;
        }
        let i = self.verts.len() as u32;
        self.verts.push(p);
        self.index.insert(key, i);
        i
    }
}

/// How a building's leaf ring was obtained.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum LeafKind {
    /// The exterior ring of a one-polygon footprint (holes are inside it).
    Exterior,
    /// The convex hull of a multi-polygon footprint, or of a ring that was not simple.
    Hull,
    /// A degenerate footprint (no area): its bounding box grown by 0.25 m.
    Degenerate,
}

/// One building's leaf.
#[derive(Debug, Clone)]
pub struct Leaf {
    pub ring: Vec<u32>,
    pub kind: LeafKind,
    /// Footprint area of the building itself (m²).
    pub area_m2: f64,
    pub centre: Pt,
}

/// Builds the leaf ring of a building.
pub fn leaf_of(store: &mut VertexStore, b: &Building) -> Leaf {
    let area_m2 = b.footprint.unsigned_area();
    let centre = b
        .footprint
        .centroid()
        .map(|c| [c.x(), c.y()])
        .filter(|c| c[0].is_finite() && c[1].is_finite())
        .unwrap_or_else(|| {
            let (lo, hi) = b.bounds();
            [0.5 * f64::from(lo.x + hi.x), 0.5 * f64::from(lo.y + hi.y)]
        });
    let finite = |c: &geo::Coord<f64>| c.x.is_finite() && c.y.is_finite();
    if b.footprint.0.len() == 1 {
        let ext = b.footprint.0[0].exterior();
        let mut ring: Vec<u32> = ext
            .0
            .iter()
            .filter(|c| finite(c))
            .map(|c| store.intern([c.x, c.y]))
            .collect();
        if ring.len() > 1 && ring.first() == ring.last() {
            ring.pop();
        }
        ring.dedup();
        while ring.len() > 1 && ring.first() == ring.last() {
            ring.pop();
        }
        if signed_area(&store.verts, &ring) < 0.0 {
            ring.reverse();
        }
        if ring_is_simple_ccw(&store.verts, &ring) {
            return Leaf {
                ring,
                kind: LeafKind::Exterior,
                area_m2,
                centre,
            };
        }
    }
    let pts: Vec<u32> = b
        .footprint
        .0
        .iter()
        .flat_map(|p| p.exterior().0.iter())
        .filter(|c| finite(c))
        .map(|c| store.intern([c.x, c.y]))
        .collect();
    let hull = convex_hull(&store.verts, pts);
    if hull.len() >= 3 && ring_is_simple_ccw(&store.verts, &hull) {
        return Leaf {
            ring: hull,
            kind: LeafKind::Hull,
            area_m2,
            centre,
        };
    }
    // Degenerate: the footprint's bounding box grown by 0.25 m (so it holds every corner).
    let (mut lo, mut hi) = (centre, centre);
    for c in b
        .footprint
        .0
        .iter()
        .flat_map(|p| p.exterior().0.iter())
        .filter(|c| finite(c))
    {
        lo = [lo[0].min(c.x), lo[1].min(c.y)];
        hi = [hi[0].max(c.x), hi[1].max(c.y)];
    }
    let h = 0.25;
    let ring = [
        [lo[0] - h, lo[1] - h],
        [hi[0] + h, lo[1] - h],
        [hi[0] + h, hi[1] + h],
        [lo[0] - h, hi[1] + h],
    ]
    .iter()
    .map(|&p| store.intern(p))
    .collect();
    Leaf {
        ring,
        kind: LeafKind::Degenerate,
        area_m2,
        centre,
    }
}

/// Leaves of all buildings, in building order.
pub fn build_leaves(store: &mut VertexStore, buildings: &[Building]) -> Vec<Leaf> {
    buildings.iter().map(|b| leaf_of(store, b)).collect()
}
