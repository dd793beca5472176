//! Merging two cluster hulls into one simple counter-clockwise ring that contains both.
//!
//! This work is based on:
//! - Yang et al. 2011 §3.2: a constrained Delaunay triangulation of the two footprints;
//!   connection pairs (two triangles sharing a side that joins the footprints, the other
//!   sides s1 ⊂ p1, s2 ⊂ p2); strict pairs (s1, s2 both footprint sides) before non-strict,
//!   the pair of minimum adjacent distance first; intersection points inserted for
//!   overlapping footprints; inclusion keeps the outer footprint.
//! - Chang et al. 2008 §5: four cases — disjoint (the two shortest non-intersecting
//!   connection edges, then a trace along both hulls), bisecting and intersecting (here: the
//!   exact outline of the union with intersection points inserted, which is where Chang's
//!   "full hull search" by inverse simplification converges; the n×m ≤ 12 candidate heuristic
//!   is not implemented), contained (the outer hull).
//!
//! No vertex is created except intersection points. Every result is checked (simple,
//! contains both inputs); when the chosen construction fails, the convex hull of the union is
//! used and counted as a fallback.

use citywalk_scenes::cluster_tree::HullMerge;
use spade::{ConstrainedDelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::geom::{
    Pt, convex_hull, crossing_point, orient, point_on_segment, point_segment_distance,
    ring_contains_ring, ring_is_simple_ccw, segments_cross_properly, signed_area,
    touching_edge_pairs,
};
use super::leaves::VertexStore;

/// A merged ring and whether it needed the convex-hull fallback.
#[derive(Debug, Clone)]
pub struct Merged {
    pub ring: Vec<u32>,
    pub fallback: bool,
}

fn valid(verts: &[Pt], ring: &[u32], a: &[u32], b: &[u32]) -> bool {
    ring_is_simple_ccw(verts, ring)
        && ring_contains_ring(verts, ring, a)
        && ring_contains_ring(verts, ring, b)
}

/// Merges rings `a` and `b` (simple, counter-clockwise).
pub fn merge_rings(
    store: &mut VertexStore,
    a: &[u32],
    b: &[u32],
    method: HullMerge,
    lambda: f64,
) -> Merged {
    if ring_contains_ring(&store.verts, a, b) {
        return Merged {
            ring: a.to_vec(),
            fallback: false,
        };
    }
    if ring_contains_ring(&store.verts, b, a) {
        return Merged {
            ring: b.to_vec(),
            fallback: false,
        };
    }
    let touching = touching_edge_pairs(&store.verts, a, b);
    let candidate = if touching.is_empty() {
        bridge_disjoint(&store.verts, a, b, method, lambda)
    } else {
        union_outline(store, a, b, &touching).filter(|r| valid(&store.verts, r, a, b))
    };
    match candidate {
        Some(ring) => Merged {
            ring,
            fallback: false,
        },
        None => Merged {
            ring: convex_hull(&store.verts, a.iter().chain(b.iter()).copied()),
            fallback: true,
        },
    }
}

/// The ring A[r..=p] (cyclic, counter-clockwise) + B[q..=s], closed by the connection edges
/// p→q and s→r.
fn bridged(a: &[u32], b: &[u32], (p, q): (usize, usize), (r, s): (usize, usize)) -> Vec<u32> {
    let (na, nb) = (a.len(), b.len());
    let mut ring = Vec::with_capacity(na + nb);
    let mut i = r;
    loop {
        ring.push(a[i]);
        if i == p {
            break;
        }
        i = (i + 1) % na;
    }
    let mut j = q;
    loop {
        ring.push(b[j]);
        if j == s {
            break;
        }
        j = (j + 1) % nb;
    }
    ring
}

/// Tries the two ways to join A and B by two connection edges (ring positions `(ia, ib)`).
fn try_bridge(
    verts: &[Pt],
    a: &[u32],
    b: &[u32],
    e1: (usize, usize),
    e2: (usize, usize),
) -> Option<Vec<u32>> {
    if e1.0 == e2.0 || e1.1 == e2.1 {
        return None;
    }
    let mut best: Option<(f64, Vec<u32>)> = None;
    for (x, y) in [(e1, e2), (e2, e1)] {
        let ring = bridged(a, b, x, y);
        if valid(verts, &ring, a, b) {
            let area = signed_area(verts, &ring);
            if best.as_ref().is_none_or(|(ba, _)| area < *ba) {
                best = Some((area, ring));
            }
        }
    }
    best.map(|(_, r)| r)
}

#[derive(Debug, Clone, Copy)]
struct Cv {
    pos: Point2<f64>,
    /// 0 for ring A, 1 for ring B; position in that ring.
    side: u8,
    at: u32,
}

impl HasPosition for Cv {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.pos
    }
}

/// Yang et al. 2011 §3.1 eq. 1–2 applied to two segments (the adjacent sides s1 and s2).
fn segment_adjacent_distance(s1: (Pt, Pt), s2: (Pt, Pt), lambda: f64) -> f64 {
    let d_min = point_segment_distance(s1.0, s2.0, s2.1)
        .min(point_segment_distance(s1.1, s2.0, s2.1))
        .min(point_segment_distance(s2.0, s1.0, s1.1))
        .min(point_segment_distance(s2.1, s1.0, s1.1));
    let len = |s: (Pt, Pt)| ((s.1[0] - s.0[0]).powi(2) + (s.1[1] - s.0[1]).powi(2)).sqrt();
    let overlap = |s: (Pt, Pt), onto: (Pt, Pt)| {
        let d = [onto.1[0] - onto.0[0], onto.1[1] - onto.0[1]];
        let l = len(onto);
        if l == 0.0 {
            return 0.0;
        }
        let t = |p: Pt| ((p[0] - onto.0[0]) * d[0] + (p[1] - onto.0[1]) * d[1]) / l;
        let (t0, t1) = (t(s.0), t(s.1));
        (t0.max(t1).min(l) - t0.min(t1).max(0.0)).max(0.0)
    };
    let (l1, l2) = (len(s1), len(s2));
    if l1 == 0.0 || l2 == 0.0 {
        return d_min;
    }
    let n = 0.5 * (overlap(s2, s1) / l1 + overlap(s1, s2) / l2);
    d_min * (1.0 - n.clamp(0.0, 1.0) * lambda)
}

/// A connection edge: (position in ring A, position in ring B).
type Link = (usize, usize);

/// Disjoint rings: connection edges from a constrained Delaunay triangulation of both.
fn bridge_disjoint(
    verts: &[Pt],
    a: &[u32],
    b: &[u32],
    method: HullMerge,
    lambda: f64,
) -> Option<Vec<u32>> {
    let mut cvs = Vec::with_capacity(a.len() + b.len());
    let mut edges = Vec::with_capacity(a.len() + b.len());
    for (side, ring) in [(0u8, a), (1u8, b)] {
        let base = cvs.len();
        for (k, &i) in ring.iter().enumerate() {
            let p = verts[i as usize];
            cvs.push(Cv {
                pos: Point2::new(p[0], p[1]),
                side,
                at: k as u32,
            });
            edges.push([base + k, base + (k + 1) % ring.len()]);
        }
    }
    let cdt = ConstrainedDelaunayTriangulation::<Cv>::try_bulk_load_cdt(cvs, edges, |_| {}).ok()?;
    let ring_of = |side: u8| if side == 0 { a } else { b };
    let adjacent_in = |side: u8, x: u32, y: u32| {
        let n = ring_of(side).len() as u32;
        (x + 1) % n == y || (y + 1) % n == x
    };
    let pt = |side: u8, at: u32| verts[ring_of(side)[at as usize] as usize];
    // (key, strictness rank, e1, e2) with e = (position in A, position in B).
    let mut cands: Vec<(f64, u8, Link, Link)> = Vec::new();
    let mut links: Vec<(f64, (usize, usize))> = Vec::new();
    for e in cdt.directed_edges() {
        let (u, v) = (*e.from().data(), *e.to().data());
        if !(u.side == 0 && v.side == 1) {
            continue;
        }
        let len = {
            let (p, q) = (pt(0, u.at), pt(1, v.at));
            ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
        };
        links.push((len, (u.at as usize, v.at as usize)));
        let (Some(c1), Some(c2)) = (e.opposite_vertex(), e.rev().opposite_vertex()) else {
            continue;
        };
        let (c1, c2) = (*c1.data(), *c2.data());
        let (ca, cb) = match (c1.side, c2.side) {
            (0, 1) => (c1, c2),
            (1, 0) => (c2, c1),
            _ => continue,
        };
        let s1 = (pt(0, u.at), pt(0, ca.at));
        let s2 = (pt(1, v.at), pt(1, cb.at));
        let strict = adjacent_in(0, u.at, ca.at) && adjacent_in(1, v.at, cb.at);
        let d = segment_adjacent_distance(s1, s2, lambda);
        // Quad u, ca, v, cb: connection edges ca–v and u–cb.
        cands.push((
            d,
            u8::from(!strict),
            (ca.at as usize, v.at as usize),
            (u.at as usize, cb.at as usize),
        ));
    }
    match method {
        HullMerge::YangDelaunay => {
            cands.sort_by(|x, y| x.1.cmp(&y.1).then(x.0.total_cmp(&y.0)));
            for &(_, _, e1, e2) in cands.iter().take(12) {
                if let Some(r) = try_bridge(verts, a, b, e1, e2) {
                    return Some(r);
                }
            }
            None
        }
        HullMerge::ChangCases => {
            links.sort_by(|x, y| x.0.total_cmp(&y.0));
            links.dedup_by(|x, y| x.1 == y.1);
            let k = links.len().min(8);
            let mut pairs: Vec<(f64, usize, usize)> = Vec::new();
            for i in 0..k {
                for j in i + 1..k {
                    pairs.push((links[i].0 + links[j].0, i, j));
                }
            }
            pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
            for (_, i, j) in pairs {
                let (e1, e2) = (links[i].1, links[j].1);
                let (p1, q1) = (pt(0, e1.0 as u32), pt(1, e1.1 as u32));
                let (p2, q2) = (pt(0, e2.0 as u32), pt(1, e2.1 as u32));
                if segments_cross_properly(p1, q1, p2, q2) {
                    continue;
                }
                if let Some(r) = try_bridge(verts, a, b, e1, e2) {
                    return Some(r);
                }
            }
            None
        }
    }
}

/// The crossing point of edge `a0a1` of one counter-clockwise ring and edge `b0b1` of another,
/// moved (when f64 rounding put it inside either ring) along the outward bisector of the two
/// edges until it lies on or to the right of both edge lines (exact orientation). The outline
/// through it then contains both rings exactly, not just up to rounding, so containment stays
/// exact however many levels of the tree are stacked above it (depth reduction makes a node
/// the direct parent of hulls many merges below it). Returns the rounded point when no such
/// point is found within 1 mm; the merge's validity check then decides.
fn crossing_outside(a0: Pt, a1: Pt, b0: Pt, b1: Pt) -> Pt {
    let x = crossing_point(a0, a1, b0, b1);
    let outside = |p: Pt| orient(a0, a1, p) <= 0.0 && orient(b0, b1, p) <= 0.0;
    if outside(x) {
        return x;
    }
    // Outward (right-hand) unit normals of the two counter-clockwise edges.
    let normal = |p: Pt, q: Pt| {
        let n = [q[1] - p[1], p[0] - q[0]];
        let len = n[0].hypot(n[1]);
        if len > 0.0 {
            [n[0] / len, n[1] / len]
        } else {
            [0.0, 0.0]
        }
    };
    let (na, nb) = (normal(a0, a1), normal(b0, b1));
    let dir = [na[0] + nb[0], na[1] + nb[1]];
    let scale = x[0].abs().max(x[1].abs()).max(1.0);
    let mut step = scale * f64::EPSILON;
    while step < 1e-3 {
        let p = [x[0] + dir[0] * step, x[1] + dir[1] * step];
        if outside(p) {
            return p;
        }
        step *= 2.0;
    }
    x
}

/// The outer outline of the union of two touching or overlapping rings, with intersection
/// points inserted (Yang et al. 2011 §3.2, Figure 4a). `None` when the trace fails.
fn union_outline(
    store: &mut VertexStore,
    a: &[u32],
    b: &[u32],
    touching: &[(usize, usize)],
) -> Option<Vec<u32>> {
    let (na, nb) = (a.len(), b.len());
    let mut split_a: Vec<Vec<u32>> = vec![Vec::new(); na];
    let mut split_b: Vec<Vec<u32>> = vec![Vec::new(); nb];
    for &(i, j) in touching {
        let (a0, a1) = (a[i], a[(i + 1) % na]);
        let (b0, b1) = (b[j], b[(j + 1) % nb]);
        let v = &store.verts;
        let (pa0, pa1, pb0, pb1) = (
            v[a0 as usize],
            v[a1 as usize],
            v[b0 as usize],
            v[b1 as usize],
        );
        if segments_cross_properly(pa0, pa1, pb0, pb1) {
            let x = store.intern(crossing_outside(pa0, pa1, pb0, pb1));
            split_a[i].push(x);
            split_b[j].push(x);
            continue;
        }
        for (p, pp) in [(b0, pb0), (b1, pb1)] {
            if point_on_segment(pa0, pa1, pp) {
                split_a[i].push(p);
            }
        }
        for (p, pp) in [(a0, pa0), (a1, pa1)] {
            if point_on_segment(pb0, pb1, pp) {
                split_b[j].push(p);
            }
        }
    }
    let verts = &store.verts;
    let mut adj: std::collections::HashMap<u32, Vec<u32>> = std::collections::HashMap::new();
    let mut add_chain = |ring: &[u32], splits: &mut [Vec<u32>]| {
        let n = ring.len();
        for i in 0..n {
            let (s, e) = (ring[i], ring[(i + 1) % n]);
            let ps = verts[s as usize];
            let d = [verts[e as usize][0] - ps[0], verts[e as usize][1] - ps[1]];
            let t = |x: u32| {
                let q = verts[x as usize];
                (q[0] - ps[0]) * d[0] + (q[1] - ps[1]) * d[1]
            };
            let sp = &mut splits[i];
            sp.sort_by(|&x, &y| t(x).total_cmp(&t(y)));
            let mut chain = vec![s];
            chain.extend(sp.iter().copied());
            chain.push(e);
            chain.dedup();
            for w in chain.windows(2) {
                if w[0] != w[1] {
                    adj.entry(w[0]).or_default().push(w[1]);
                    adj.entry(w[1]).or_default().push(w[0]);
                }
            }
        }
    };
    add_chain(a, &mut split_a);
    add_chain(b, &mut split_b);
    for l in adj.values_mut() {
        l.sort_unstable();
        l.dedup();
    }
    let start = *adj.keys().min_by(|&&x, &&y| {
        let (p, q) = (verts[x as usize], verts[y as usize]);
        p[1].total_cmp(&q[1]).then(p[0].total_cmp(&q[0]))
    })?;
    let angle = |from: Pt, to: Pt| (to[1] - from[1]).atan2(to[0] - from[0]);
    let tau = std::f64::consts::TAU;
    let mut ring = vec![start];
    let mut prev_dir = -std::f64::consts::FRAC_PI_2; // arrive "from below"
    let mut cur = start;
    let mut prev: Option<u32> = None;
    let total: usize = adj.values().map(Vec::len).sum();
    for _ in 0..=total {
        let pc = verts[cur as usize];
        let nbrs = adj.get(&cur)?;
        // Rightmost turn: the first neighbour counter-clockwise from the way back.
        let next = *nbrs.iter().min_by(|&&x, &&y| {
            let key = |w: u32| {
                if Some(w) == prev {
                    return tau;
                }
                let mut d = angle(pc, verts[w as usize]) - prev_dir;
                while d <= 0.0 {
                    d += tau;
                }
                while d > tau {
                    d -= tau;
                }
                d
            };
            key(x).total_cmp(&key(y))
        })?;
        if next == start {
            return Some(ring);
        }
        prev_dir = angle(verts[next as usize], pc);
        prev = Some(cur);
        cur = next;
        ring.push(cur);
    }
    None
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster::geom::ring_is_simple_ccw;

    fn rect(store: &mut VertexStore, x0: f64, y0: f64, x1: f64, y1: f64) -> Vec<u32> {
        [[x0, y0], [x1, y0], [x1, y1], [x0, y1]]
            .iter()
            .map(|&p| store.intern(p))
            .collect()
    }

    fn check(store: &VertexStore, m: &Merged, a: &[u32], b: &[u32]) {
        assert!(ring_is_simple_ccw(&store.verts, &m.ring), "{:?}", m.ring);
        assert!(ring_contains_ring(&store.verts, &m.ring, a));
        assert!(ring_contains_ring(&store.verts, &m.ring, b));
    }

    #[test]
    fn disjoint_both_methods_bridge_without_fallback() {
        for method in [HullMerge::YangDelaunay, HullMerge::ChangCases] {
            let mut s = VertexStore::default();
            let a = rect(&mut s, 0.0, 0.0, 10.0, 10.0);
            let b = rect(&mut s, 12.0, 2.0, 20.0, 8.0);
            let m = merge_rings(&mut s, &a, &b, method, 0.6);
            check(&s, &m, &a, &b);
            assert!(!m.fallback, "{method:?}");
            assert_eq!(s.verts.len(), 8, "no new vertices");
            let area = signed_area(&s.verts, &m.ring);
            let hull = convex_hull(&s.verts, a.iter().chain(&b).copied());
            assert!(area <= signed_area(&s.verts, &hull) + 1e-9);
            assert!(area > 100.0 + 48.0);
        }
    }

    #[test]
    fn overlapping_inserts_intersections_and_contained_keeps_outer() {
        let mut s = VertexStore::default();
        let a = rect(&mut s, 0.0, 0.0, 10.0, 10.0);
        let b = rect(&mut s, 5.0, 5.0, 15.0, 15.0);
        let m = merge_rings(&mut s, &a, &b, HullMerge::YangDelaunay, 0.6);
        check(&s, &m, &a, &b);
        assert!(!m.fallback);
        assert_eq!(
            m.ring.len(),
            8,
            "two intersection points inserted: {:?}",
            m.ring
        );
        assert!((signed_area(&s.verts, &m.ring) - 175.0).abs() < 1e-9);
        let c = rect(&mut s, 1.0, 1.0, 2.0, 2.0);
        let m = merge_rings(&mut s, &a, &c, HullMerge::ChangCases, 0.6);
        assert_eq!(m.ring, a);
    }

    #[test]
    fn touching_along_an_edge_gives_the_union() {
        let mut s = VertexStore::default();
        let a = rect(&mut s, 0.0, 0.0, 10.0, 10.0);
        let b = rect(&mut s, 10.0, 3.0, 14.0, 7.0);
        let m = merge_rings(&mut s, &a, &b, HullMerge::YangDelaunay, 0.6);
        check(&s, &m, &a, &b);
        assert!((signed_area(&s.verts, &m.ring) - 116.0).abs() < 1e-9);
    }
}
