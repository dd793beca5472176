//! Simplifying a merged hull without creating vertices and without shrinking it.
//!
//! This work is based on:
//! - Chang et al. 2008 §6: repeatedly remove the vertex whose removal adds the smallest
//!   positive area, never self-intersecting; stop at max(2/3 of the children's edges, 1 % of
//!   the input edges, the convex hull's edge count).
//! - Yang et al. 2011 §3.2 (after Visvalingam & Whyatt 1993): remove the smallest concave
//!   triangle while its area is under δa = a_ave/50 (the divisor is a parameter, citywalk's
//!   default 20), then remove vertices between two sides meeting at more than 175°.
//!
//! Only reflex (concave) or collinear vertices are removed, and only when the triangle they
//! cut off holds no other vertex of the ring. The new ring is then the old ring plus that
//! triangle: still simple, and still containing every building (the papers' "non
//! self-intersecting" and "contains its buildings" by construction). A convex vertex at more
//! than 175° is kept: removing it would cut a corner off a building.
//!
//! The hull a node merges upwards stays so; only its cluster mesh is cut further, convex
//! corners included, within the plan slack its geometric error allows ([`cut_corners`]).

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use super::geom::{Pt, orient, point_segment_distance};

#[derive(Debug, Clone, Copy)]
struct Cand {
    /// Smallest first: the area a removal adds, or the depth a corner cut reaches.
    key: f64,
    at: u32,
    stamp: u32,
}

impl PartialEq for Cand {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Cand {}
impl PartialOrd for Cand {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Cand {
    fn cmp(&self, o: &Self) -> Ordering {
        o.key.total_cmp(&self.key).then(o.at.cmp(&self.at))
    }
}

/// A ring as a doubly linked list with a removal heap.
struct Linked<'a> {
    verts: &'a [Pt],
    ring: &'a [u32],
    prev: Vec<u32>,
    next: Vec<u32>,
    alive: Vec<bool>,
    stamp: Vec<u32>,
    len: usize,
}

impl<'a> Linked<'a> {
    fn new(verts: &'a [Pt], ring: &'a [u32]) -> Self {
        let n = ring.len() as u32;
        Linked {
            verts,
            ring,
            prev: (0..n).map(|i| (i + n - 1) % n).collect(),
            next: (0..n).map(|i| (i + 1) % n).collect(),
            alive: vec![true; n as usize],
            stamp: vec![0; n as usize],
            len: n as usize,
        }
    }

    fn p(&self, i: u32) -> Pt {
        self.verts[self.ring[i as usize] as usize]
    }

    /// Area the ring gains when vertex `i` is removed, if it is reflex or collinear between
    /// its neighbours; `None` for a convex vertex.
    fn gain(&self, i: u32) -> Option<f64> {
        let (a, v, b) = (
            self.p(self.prev[i as usize]),
            self.p(i),
            self.p(self.next[i as usize]),
        );
        let o = orient(a, v, b);
        if o > 0.0 {
            return None;
        }
        if o == 0.0 {
            // Collinear: removable only if v lies between a and b (not a spike).
            let dot = (a[0] - v[0]) * (b[0] - v[0]) + (a[1] - v[1]) * (b[1] - v[1]);
            return (dot < 0.0).then_some(0.0);
        }
        Some(0.5 * ((b[0] - a[0]) * (v[1] - a[1]) - (b[1] - a[1]) * (v[0] - a[0])).abs())
    }

    /// Angle at vertex `i` between its two sides, degrees in [0, 180].
    fn angle_deg(&self, i: u32) -> f64 {
        let (a, v, b) = (
            self.p(self.prev[i as usize]),
            self.p(i),
            self.p(self.next[i as usize]),
        );
        let u = [a[0] - v[0], a[1] - v[1]];
        let w = [b[0] - v[0], b[1] - v[1]];
        let cross = u[0] * w[1] - u[1] * w[0];
        let dot = u[0] * w[0] + u[1] * w[1];
        cross.abs().atan2(dot).to_degrees()
    }

    /// Whether removing `i` keeps the ring simple: no other vertex in the closed triangle.
    fn removable(&self, i: u32) -> bool {
        if self.len <= 3 {
            return false;
        }
        let (ia, ib) = (self.prev[i as usize], self.next[i as usize]);
        let (a, v, b) = (self.p(ia), self.p(i), self.p(ib));
        let lo = [a[0].min(v[0]).min(b[0]), a[1].min(v[1]).min(b[1])];
        let hi = [a[0].max(v[0]).max(b[0]), a[1].max(v[1]).max(b[1])];
        let mut k = self.next[ib as usize];
        while k != ia {
            let q = self.p(k);
            if q[0] >= lo[0] && q[0] <= hi[0] && q[1] >= lo[1] && q[1] <= hi[1] {
                // In the closed triangle, whichever way round it turns (counter-clockwise
                // for a reflex `v`, clockwise for a convex one); inside the box, a point
                // on the line through a collinear a, v, b is on the segment.
                let turns = [orient(a, v, q), orient(v, b, q), orient(b, a, q)];
                let inside = turns.iter().all(|&o| o >= 0.0) || turns.iter().all(|&o| o <= 0.0);
                if inside || q == a || q == b || q == v {
                    return false;
                }
            }
            k = self.next[k as usize];
        }
        true
    }

    fn remove(&mut self, i: u32) {
        let (a, b) = (self.prev[i as usize], self.next[i as usize]);
        self.next[a as usize] = b;
        self.prev[b as usize] = a;
        self.alive[i as usize] = false;
        self.stamp[a as usize] += 1;
        self.stamp[b as usize] += 1;
        self.len -= 1;
    }

    fn push(&self, heap: &mut BinaryHeap<Cand>, i: u32, filter: &impl Fn(&Self, u32, f64) -> bool) {
        if let Some(area) = self.gain(i)
            && filter(self, i, area)
        {
            heap.push(Cand {
                key: area,
                at: i,
                stamp: self.stamp[i as usize],
            });
        }
    }

    /// Removes admissible vertices smallest gain first until `len <= target`.
    fn run(&mut self, target: usize, filter: impl Fn(&Self, u32, f64) -> bool) {
        let mut heap = BinaryHeap::new();
        for i in 0..self.ring.len() as u32 {
            self.push(&mut heap, i, &filter);
        }
        while self.len > target.max(3) {
            let Some(c) = heap.pop() else { break };
            if !self.alive[c.at as usize] || self.stamp[c.at as usize] != c.stamp {
                continue;
            }
            if !self.removable(c.at) {
                continue;
            }
            let (a, b) = (self.prev[c.at as usize], self.next[c.at as usize]);
            self.remove(c.at);
            self.push(&mut heap, a, &filter);
            self.push(&mut heap, b, &filter);
        }
    }

    fn into_ring(self) -> Vec<u32> {
        let Some(start) = (0..self.ring.len()).find(|&i| self.alive[i]) else {
            return Vec::new();
        };
        let mut out = Vec::with_capacity(self.len);
        let mut k = start as u32;
        loop {
            out.push(self.ring[k as usize]);
            k = self.next[k as usize];
            if k as usize == start {
                break;
            }
        }
        out
    }
}

/// Cuts convex corners off a simplified hull for its cluster mesh while every point cut away
/// stays within `max_depth_m` of the new ring, the flattest cut first.
///
/// Both simplifications above only grow a hull, so a coarse node keeps every corner of its
/// convex hull (about 20 at any depth of a generated city) and its mesh as many triangles as
/// a fine one. The slack is what the node's geometric error already allows
/// ([`super::error::fill_errors`]): a building point the cut leaves outside the mesh lies
/// within it of a wall, so the error, and the cut's bound, are unchanged.
///
/// What a new side `a b` cuts away is the region between it and the input ring's vertices
/// from `a` to `b`: within the convex hull of those vertices, so no farther from `a b` than
/// the farthest of them (the distance to a segment is convex). Past [`CHAIN_SCAN`] of them
/// the depth is bounded in O(1) instead: the larger depth of sides `a v` and `v b` plus the
/// distance from `v` to `a b` (what lies behind those sides is that close to the triangle,
/// the triangle that close to `a b`), so a ring of thousands of vertices costs no more than
/// linear time. Only a corner whose triangle holds no other vertex is cut, so the ring stays
/// simple.
pub fn cut_corners(verts: &[Pt], ring: &[u32], max_depth_m: f64) -> Vec<u32> {
    cut_corners_scanning(verts, ring, max_depth_m, CHAIN_SCAN)
}

/// Input vertices a corner cut measures exactly before it bounds its depth instead.
const CHAIN_SCAN: usize = 32;

fn cut_corners_scanning(verts: &[Pt], ring: &[u32], max_depth_m: f64, scan: usize) -> Vec<u32> {
    let n = ring.len();
    let mut l = Linked::new(verts, ring);
    // depth[i]: how far behind the side from vertex i to its successor a cut-away point lies.
    let mut depth = vec![0.0f64; n];
    let cut_depth = |l: &Linked, depth: &[f64], i: u32| -> Option<f64> {
        let (ia, ib) = (l.prev[i as usize], l.next[i as usize]);
        let (a, v, b) = (l.p(ia), l.p(i), l.p(ib));
        if orient(a, v, b) <= 0.0 {
            return None;
        }
        // The input ring's vertices strictly between a and b (the linked list keeps
        // positions in the input ring).
        let chain = (ib as usize + n - ia as usize) % n;
        let d = if chain <= scan + 1 {
            (1..chain)
                .map(|k| point_segment_distance(l.p(((ia as usize + k) % n) as u32), a, b))
                .fold(0.0f64, f64::max)
        } else {
            depth[ia as usize].max(depth[i as usize]) + point_segment_distance(v, a, b)
        };
        (d <= max_depth_m).then_some(d)
    };
    let push = |heap: &mut BinaryHeap<Cand>, l: &Linked, depth: &[f64], i: u32| {
        if let Some(d) = cut_depth(l, depth, i) {
            heap.push(Cand {
                key: d,
                at: i,
                stamp: l.stamp[i as usize],
            });
        }
    };
    let mut heap = BinaryHeap::new();
    for i in 0..n as u32 {
        push(&mut heap, &l, &depth, i);
    }
    while let Some(c) = heap.pop() {
        if !l.alive[c.at as usize] || l.stamp[c.at as usize] != c.stamp || !l.removable(c.at) {
            continue;
        }
        let (a, b) = (l.prev[c.at as usize], l.next[c.at as usize]);
        depth[a as usize] = c.key;
        l.remove(c.at);
        push(&mut heap, &l, &depth, a);
        push(&mut heap, &l, &depth, b);
    }
    l.into_ring()
}

/// Chang et al. 2008 §6: removes smallest-gain vertices until the ring has `target` vertices
/// or no vertex can be removed.
pub fn simplify_chang(verts: &[Pt], ring: &[u32], target: usize) -> Vec<u32> {
    let mut l = Linked::new(verts, ring);
    l.run(target, |_, _, _| true);
    l.into_ring()
}

/// Yang et al. 2011 §3.2: removes concave triangles under `delta_a_m2` (smallest first), then
/// reflex or straight vertices whose sides meet at more than `straight_deg`.
pub fn simplify_yang(verts: &[Pt], ring: &[u32], delta_a_m2: f64, straight_deg: f64) -> Vec<u32> {
    let mut l = Linked::new(verts, ring);
    l.run(3, |_, _, area| area < delta_a_m2);
    let ring2 = l.into_ring();
    let mut l = Linked::new(verts, &ring2);
    l.run(3, |l, i, _| l.angle_deg(i) > straight_deg);
    l.into_ring()
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::geom::{Side, locate, ring_contains_ring, ring_is_simple_ccw, signed_area};

    /// A comb: a 10 × 2 bar with three 1 m wide teeth of height 3 and notches between.
    fn comb() -> (Vec<Pt>, Vec<u32>) {
        let pts: Vec<Pt> = vec![
            [0.0, 0.0],
            [10.0, 0.0],
            [10.0, 5.0],
            [9.0, 5.0],
            [9.0, 2.0],
            [5.5, 2.0],
            [5.5, 5.0],
            [4.5, 5.0],
            [4.5, 2.0],
            [1.0, 2.0],
            [1.0, 5.0],
            [0.0, 5.0],
        ];
        let ring = (0..pts.len() as u32).collect();
        (pts, ring)
    }

    /// How far a point of `ring` lies outside `cut`: 0 inside or on it, else its distance to
    /// the nearest side; sampled along every side of `ring`.
    fn farthest_outside(v: &[Pt], ring: &[u32], cut: &[u32]) -> f64 {
        let mut worst = 0.0f64;
        for k in 0..ring.len() {
            let (a, b) = (v[ring[k] as usize], v[ring[(k + 1) % ring.len()] as usize]);
            for t in 0..=16 {
                let t = f64::from(t) / 16.0;
                let p = [a[0] + t * (b[0] - a[0]), a[1] + t * (b[1] - a[1])];
                if locate(v, cut, p) != Side::Outside {
                    continue;
                }
                let d = (0..cut.len())
                    .map(|j| {
                        let (c, e) = (v[cut[j] as usize], v[cut[(j + 1) % cut.len()] as usize]);
                        point_segment_distance(p, c, e)
                    })
                    .fold(f64::INFINITY, f64::min);
                worst = worst.max(d);
            }
        }
        worst
    }

    /// A 24-gon of radius 100 m: every corner 3.4 m above the chord of its neighbours.
    fn round() -> (Vec<Pt>, Vec<u32>) {
        let pts: Vec<Pt> = (0..24)
            .map(|k| {
                let a = f64::from(k) * std::f64::consts::TAU / 24.0;
                [100.0 * a.cos(), 100.0 * a.sin()]
            })
            .collect();
        let ring = (0..pts.len() as u32).collect();
        (pts, ring)
    }

    #[test]
    fn corners_are_cut_only_within_the_depth() {
        let (v, r) = round();
        assert_eq!(cut_corners(&v, &r, 3.0), r, "no corner is 3 m deep");
        for depth in [4.0, 8.0, 30.0] {
            let cut = cut_corners(&v, &r, depth);
            assert!(cut.len() < r.len(), "{depth} m cuts a corner");
            assert!(ring_is_simple_ccw(&v, &cut));
            assert!(ring_contains_ring(&v, &r, &cut), "cutting only removes");
            let out = farthest_outside(&v, &r, &cut);
            assert!(out <= depth + 1e-9, "{out} m cut away at {depth} m");
        }
        assert!(cut_corners(&v, &r, 30.0).len() < cut_corners(&v, &r, 8.0).len());
        let (v, r) = comb();
        let cut = cut_corners(&v, &r, 0.4);
        assert_eq!(cut, r, "the comb's corners are deeper than 0.4 m");
    }

    proptest::proptest! {
        /// Star-shaped random rings cut at random depths stay simple, inside the ring, and
        /// leave no point of it farther than the depth outside.
        #[test]
        fn cut_rings_stay_simple_and_within_their_depth(
            radii in proptest::collection::vec(20.0f64..100.0, 5..40),
            depth in 0.0f64..40.0,
        ) {
            let n = radii.len();
            let v: Vec<Pt> = radii
                .iter()
                .enumerate()
                .map(|(k, r)| {
                    let a = k as f64 * std::f64::consts::TAU / n as f64;
                    [r * a.cos(), r * a.sin()]
                })
                .collect();
            let r: Vec<u32> = (0..n as u32).collect();
            // Measured exactly, and bounded past two vertices (the long-chain fallback).
            for scan in [CHAIN_SCAN, 2] {
                let cut = cut_corners_scanning(&v, &r, depth, scan);
                proptest::prop_assert!(cut.len() >= 3);
                proptest::prop_assert!(ring_is_simple_ccw(&v, &cut));
                proptest::prop_assert!(ring_contains_ring(&v, &r, &cut));
                let out = farthest_outside(&v, &r, &cut);
                proptest::prop_assert!(out <= depth + 1e-6, "{} m cut away at {} m", out, depth);
            }
        }
    }

    #[test]
    fn chang_grows_and_stops_at_target() {
        let (v, r) = comb();
        let s = simplify_chang(&v, &r, 8);
        assert!(s.len() <= 8 && s.len() >= 4, "{s:?}");
        assert!(ring_is_simple_ccw(&v, &s));
        assert!(ring_contains_ring(&v, &s, &r));
        assert!(signed_area(&v, &s) > signed_area(&v, &r));
        let all = simplify_chang(&v, &r, 3);
        assert_eq!(all.len(), 4, "converges to the convex hull: {all:?}");
    }

    #[test]
    fn yang_removes_only_small_concavities() {
        let (v, r) = comb();
        // Notch triangles: (9,2),(5.5,2),(5.5,5) = 5.25 m²; a threshold of 1 m² keeps them.
        let s = simplify_yang(&v, &r, 1.0, 175.0);
        assert_eq!(s.len(), r.len());
        let s = simplify_yang(&v, &r, 6.0, 175.0);
        assert!(s.len() < r.len());
        assert!(ring_is_simple_ccw(&v, &s));
        assert!(ring_contains_ring(&v, &s, &r));
    }
}
