//! Merging two cluster hulls into one simple counter-clockwise ring that contains both.
//!
//! This work is based on:
//! - Yang et al. 2011 §3.2 ([`HullMerge::YangDelaunay`], the default): a constrained
//!   Delaunay triangulation of the two footprints; connection pairs (two triangles sharing a
//!   side that joins the footprints, the other sides s1 ⊂ p1, s2 ⊂ p2); strict pairs (s1, s2
//!   both footprint sides) before non-strict, the pair of minimum adjacent distance first;
//!   intersection points inserted for overlapping footprints (the outline of the union);
//!   inclusion keeps the outer footprint.
//! - Chang et al. 2008 §5 ([`HullMerge::ChangCases`]), four cases: disjoint (the two shortest
//!   non-crossing connection edges, then a trace along both hulls); bisecting (no vertex of
//!   either inside the other: the full hull search, [`full_hull_search`]: the convex hull,
//!   then recursive subdivision of its edges, the inverse of the §6 simplification);
//!   intersecting with intruding vertices (candidate connection edges between the vertices of
//!   the edges that meet the other hull, tried pairwise when n×m ≤ 12, else or on failure the
//!   full hull search); contained (the outer hull).
//!
//! No vertex is created except intersection points. Every result is checked (simple,
//! contains both inputs). When the construction that the method and case call for fails, the
//! reason is recorded ([`MergeFailure`]) and Chang's full hull search builds the ring; its
//! result is only the plain convex hull when it cannot carve anything valid either. On the
//! real extracts the failures are Yang's union outlines of hulls touching at isolated points
//! (the outline passes a vertex twice: not a simple polygon), all carved by the full hull
//! search; no merge ends as a convex hull.

use std::collections::{HashMap, HashSet};

use citywalk_scenes::cluster_tree::{HullMerge, MergeFailure};
use spade::{ConstrainedDelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::geom::{
    Pt, Side, convex_hull, crossing_point, locate, orient, point_on_segment,
    point_segment_distance, ring_contains_ring, ring_is_simple_ccw, segments_cross_properly,
    signed_area, touching_edge_pairs,
};
use super::leaves::VertexStore;

/// A merged ring, and why its first construction failed (if it did).
#[derive(Debug, Clone)]
pub struct Merged {
    pub ring: Vec<u32>,
    /// Why the construction that the method and case call for failed; Chang's full hull
    /// search then carved the ring.
    pub failure: Option<MergeFailure>,
    /// Whether the ring is the plain convex hull of both inputs (even the full hull search
    /// failed).
    pub convex_hull: bool,
}

fn valid(verts: &[Pt], ring: &[u32], a: &[u32], b: &[u32]) -> bool {
    ring_is_simple_ccw(verts, ring)
        && ring_contains_ring(verts, ring, a)
        && ring_contains_ring(verts, ring, b)
}

/// Chang et al. 2008 §5: how two touching hulls meet.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum OverlapCase {
    /// Edges touch or cross, but no vertex of either hull lies strictly inside the other
    /// (two bars crossing like a plus sign; two houses sharing a wall).
    Bisecting,
    /// Some vertex of one hull lies strictly inside the other ("intruding vertices").
    Intersecting,
}

/// The axis-aligned bounds of a ring, `[min x, min y, max x, max y]`: a point outside them is
/// not inside the ring, so the exact (linear) point location can be skipped.
fn ring_box(verts: &[Pt], ring: &[u32]) -> [f64; 4] {
    ring.iter().map(|&i| verts[i as usize]).fold(
        [
            f64::INFINITY,
            f64::INFINITY,
            f64::NEG_INFINITY,
            f64::NEG_INFINITY,
        ],
        |b, p| {
            [
                b[0].min(p[0]),
                b[1].min(p[1]),
                b[2].max(p[0]),
                b[3].max(p[1]),
            ]
        },
    )
}

/// Whether `p` lies strictly inside the ring (with its bounds [`ring_box`] as a first test).
fn strictly_inside(verts: &[Pt], ring: &[u32], bounds: &[f64; 4], p: Pt) -> bool {
    p[0] > bounds[0]
        && p[1] > bounds[1]
        && p[0] < bounds[2]
        && p[1] < bounds[3]
        && locate(verts, ring, p) == Side::Inside
}

/// Classifies two touching, not nested hulls (Chang et al. 2008 §5).
pub fn overlap_case(verts: &[Pt], a: &[u32], b: &[u32]) -> OverlapCase {
    let intrudes = |r: &[u32], into: &[u32]| {
        let bounds = ring_box(verts, into);
        r.iter()
            .any(|&i| strictly_inside(verts, into, &bounds, verts[i as usize]))
    };
    if intrudes(a, b) || intrudes(b, a) {
        OverlapCase::Intersecting
    } else {
        OverlapCase::Bisecting
    }
}

/// Merges rings `a` and `b` (simple, counter-clockwise).
///
/// - Contained: the outer ring (both methods).
/// - Disjoint: connection edges from a constrained Delaunay triangulation (Yang's connection
///   pairs, or Chang's two shortest non-crossing connection edges).
/// - Touching or overlapping: Yang: the outline of the union with intersection points;
///   Chang: bisecting → full hull search, intersecting → candidate-list heuristic when
///   n×m ≤ 12, else (or when it fails) full hull search.
///
/// When the construction fails, Chang's full hull search is used (logged with the reason);
/// when even that fails, the convex hull.
pub fn merge_rings(
    store: &mut VertexStore,
    a: &[u32],
    b: &[u32],
    method: HullMerge,
    lambda: f64,
) -> Merged {
    let done = |ring: Vec<u32>| Merged {
        ring,
        failure: None,
        convex_hull: false,
    };
    if ring_contains_ring(&store.verts, a, b) {
        return done(a.to_vec());
    }
    if ring_contains_ring(&store.verts, b, a) {
        return done(b.to_vec());
    }
    let touching = touching_edge_pairs(&store.verts, a, b);
    let first: Result<Vec<u32>, MergeFailure> = if touching.is_empty() {
        bridge_disjoint(&store.verts, a, b, method, lambda).ok_or(MergeFailure::NoValidBridge)
    } else {
        match method {
            HullMerge::YangDelaunay => union_outline(store, a, b, &touching).and_then(|r| {
                if !ring_is_simple_ccw(&store.verts, &r) {
                    Err(MergeFailure::UnionNotSimple)
                } else if !(ring_contains_ring(&store.verts, &r, a)
                    && ring_contains_ring(&store.verts, &r, b))
                {
                    Err(MergeFailure::UnionMissesChild)
                } else {
                    Ok(r)
                }
            }),
            HullMerge::ChangCases => match overlap_case(&store.verts, a, b) {
                OverlapCase::Bisecting => {
                    return match full_hull_search(store, a, b, &touching) {
                        Some(ring) => done(ring),
                        None => Merged {
                            ring: convex_hull(&store.verts, a.iter().chain(b.iter()).copied()),
                            failure: Some(MergeFailure::CarvingFailed),
                            convex_hull: true,
                        },
                    };
                }
                OverlapCase::Intersecting => {
                    match chang_candidates(&store.verts, a, b, &touching) {
                        Candidates::Found(ring) => Ok(ring),
                        Candidates::Failed => Err(MergeFailure::HeuristicFailed),
                        // Chang: lists over n×m ≤ 12 go to the full hull search directly.
                        Candidates::TooMany => {
                            return match full_hull_search(store, a, b, &touching) {
                                Some(ring) => done(ring),
                                None => Merged {
                                    ring: convex_hull(
                                        &store.verts,
                                        a.iter().chain(b.iter()).copied(),
                                    ),
                                    failure: Some(MergeFailure::CarvingFailed),
                                    convex_hull: true,
                                },
                            };
                        }
                    }
                }
            },
        }
    };
    match first {
        Ok(ring) => done(ring),
        Err(reason) => match full_hull_search(store, a, b, &touching) {
            Some(ring) => Merged {
                ring,
                failure: Some(reason),
                convex_hull: false,
            },
            None => Merged {
                ring: convex_hull(&store.verts, a.iter().chain(b.iter()).copied()),
                failure: Some(reason),
                convex_hull: true,
            },
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
/// points inserted (Yang et al. 2011 §3.2, Figure 4a). The trace may pass a vertex twice
/// where the rings touch at isolated points; the caller checks simplicity.
fn union_outline(
    store: &mut VertexStore,
    a: &[u32],
    b: &[u32],
    touching: &[(usize, usize)],
) -> Result<Vec<u32>, MergeFailure> {
    let (x, verts) = (intersection_splits(store, a, b, touching), &store.verts);
    trace_outline(verts, a, b, x).ok_or(MergeFailure::UnionTraceFailed)
}

/// Split points per edge of `a` and of `b`: intersection points (inserted into the store) and
/// vertices of the other ring lying on the edge.
fn intersection_splits(
    store: &mut VertexStore,
    a: &[u32],
    b: &[u32],
    touching: &[(usize, usize)],
) -> (Vec<Vec<u32>>, Vec<Vec<u32>>) {
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
    (split_a, split_b)
}

/// Traces the outer outline of the planar graph of both rings' edges split at `splits`.
fn trace_outline(
    verts: &[Pt],
    a: &[u32],
    b: &[u32],
    (mut split_a, mut split_b): (Vec<Vec<u32>>, Vec<Vec<u32>>),
) -> Option<Vec<u32>> {
    let mut adj: HashMap<u32, Vec<u32>> = HashMap::new();
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

/// What Chang's candidate-list heuristic gave.
enum Candidates {
    Found(Vec<u32>),
    Failed,
    TooMany,
}

/// Chang et al. 2008 §5, intersecting hulls: the candidate connection edges join the
/// vertices of the edges of one hull that intersect the other (touching it or lying inside
/// it: CandidateList1, CandidateList2); two distinct candidate edges are tried as connection
/// edges, each pair traced as in the disjoint case and rejected when the ring is not simple
/// or does not contain both hulls. Shortest pairs first. Only when n×m ≤ 12 (Chang's bound,
/// the search is O(n²m²)).
fn chang_candidates(verts: &[Pt], a: &[u32], b: &[u32], touching: &[(usize, usize)]) -> Candidates {
    let list = |r: &[u32], other: &[u32], touching_edges: &mut dyn Iterator<Item = usize>| {
        let n = r.len();
        let bounds = ring_box(verts, other);
        let mut hit = vec![false; n];
        for e in touching_edges {
            hit[e] = true;
        }
        for (e, h) in hit.iter_mut().enumerate() {
            if !*h {
                let (p, q) = (verts[r[e] as usize], verts[r[(e + 1) % n] as usize]);
                let mid = [0.5 * (p[0] + q[0]), 0.5 * (p[1] + q[1])];
                *h = strictly_inside(verts, other, &bounds, mid);
            }
        }
        let mut out: Vec<usize> = Vec::new();
        for (e, &h) in hit.iter().enumerate() {
            if h {
                out.extend([e, (e + 1) % n]);
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    };
    let la = list(a, b, &mut touching.iter().map(|t| t.0));
    let lb = list(b, a, &mut touching.iter().map(|t| t.1));
    if la.len() * lb.len() > 12 {
        return Candidates::TooMany;
    }
    let len = |e: Link| {
        let (p, q) = (verts[a[e.0] as usize], verts[b[e.1] as usize]);
        (p[0] - q[0]).hypot(p[1] - q[1])
    };
    let edges: Vec<Link> = la
        .iter()
        .flat_map(|&i| lb.iter().map(move |&j| (i, j)))
        .collect();
    let mut pairs: Vec<(f64, Link, Link)> = Vec::new();
    for (k, &e1) in edges.iter().enumerate() {
        for &e2 in &edges[k + 1..] {
            if e1.0 != e2.0 && e1.1 != e2.1 {
                pairs.push((len(e1) + len(e2), e1, e2));
            }
        }
    }
    pairs.sort_by(|x, y| x.0.total_cmp(&y.0));
    for (_, e1, e2) in pairs {
        if let Some(r) = try_bridge(verts, a, b, e1, e2) {
            return Candidates::Found(r);
        }
    }
    Candidates::Failed
}

/// Most candidate vertices tried per edge by the full hull search before the edge is left
/// as it is (bounds the search at O(N·k) per edge; the result stays valid, only less tight).
const CARVE_TRIES: usize = 24;

/// Chang et al. 2008 §5, the full hull search: start from the convex hull of both hulls and
/// subdivide each edge recursively, the inverse of the simplification of §6: the vertex
/// inserted is the one whose insertion removes the largest area (Chang removes the vertex
/// adding the smallest), taken from the boundary the edge spans — the outline of the union
/// (with its intersection points) for touching hulls, the hull itself between two of its
/// vertices for disjoint ones. An insertion is admissible when the removed triangle holds no
/// boundary of either hull (no vertex in it, no edge crossing its new sides, its interior
/// outside both), so the ring keeps containing both; it stays simple. An edge is subdivided
/// until it lies on the boundary or nothing can be inserted ([`CARVE_TRIES`] candidates per
/// edge at most). Where the outline passes a vertex twice (hulls touching at a point) the
/// second visit is not inserted, so a thin pocket stays filled and the ring stays simple;
/// where the union's outline cannot be traced, the two hulls' own boundaries are carved
/// towards. `touching` are the [`touching_edge_pairs`] of `a` and `b` (empty when disjoint).
/// `None` when the result is not a simple ring containing both (the caller then takes the
/// convex hull).
pub fn full_hull_search(
    store: &mut VertexStore,
    a: &[u32],
    b: &[u32],
    touching: &[(usize, usize)],
) -> Option<Vec<u32>> {
    let outline = if touching.is_empty() {
        None
    } else {
        let splits = intersection_splits(store, a, b, touching);
        trace_outline(&store.verts, a, b, splits)
    };
    let verts = &store.verts;
    let loops: Vec<&[u32]> = match &outline {
        Some(u) => vec![u.as_slice()],
        None => vec![a, b],
    };
    let hull = convex_hull(verts, loops.iter().flat_map(|l| l.iter().copied()));
    if hull.len() < 3 {
        return None;
    }
    // Every boundary edge, for the admissibility tests.
    let mut boundary: Vec<(Pt, Pt)> = Vec::new();
    for l in &loops {
        for k in 0..l.len() {
            boundary.push((verts[l[k] as usize], verts[l[(k + 1) % l.len()] as usize]));
        }
    }
    let mut pos: HashMap<u32, (usize, usize)> = HashMap::new();
    for (li, l) in loops.iter().enumerate() {
        for (k, &v) in l.iter().enumerate() {
            pos.entry(v).or_insert((li, k));
        }
    }
    let mut used: HashSet<u32> = hull.iter().copied().collect();
    let mut ring: Vec<u32> = Vec::with_capacity(hull.len() * 2);
    let h = hull.len();
    for e in 0..h {
        let (p, q) = (hull[e], hull[(e + 1) % h]);
        ring.push(p);
        // The boundary the hull edge spans: the walk along p's loop from p to q.
        let chain: Vec<u32> = match (pos.get(&p), pos.get(&q)) {
            (Some(&(lp, kp)), Some(&(lq, _))) if lp == lq => {
                let l = loops[lp];
                let mut c = vec![p];
                let mut k = kp;
                loop {
                    k = (k + 1) % l.len();
                    c.push(l[k]);
                    if l[k] == q || c.len() > l.len() {
                        break;
                    }
                }
                if c.last() == Some(&q) { c } else { vec![p, q] }
            }
            _ => vec![p, q],
        };
        carve(verts, &chain, &boundary, a, b, &mut used, &mut ring);
    }
    let ok = ring_is_simple_ccw(verts, &ring)
        && ring_contains_ring(verts, &ring, a)
        && ring_contains_ring(verts, &ring, b);
    ok.then_some(ring)
}

/// Recursive subdivision of the edge `chain[0] → chain[last]` towards `chain`; pushes the
/// inserted vertices in ring order (not the end point).
fn carve(
    verts: &[Pt],
    chain: &[u32],
    boundary: &[(Pt, Pt)],
    a: &[u32],
    b: &[u32],
    used: &mut HashSet<u32>,
    ring: &mut Vec<u32>,
) {
    let last = chain.len() - 1;
    // keep[k]: chain position k is a ring vertex. Explicit stack of (lo, hi) position ranges.
    let mut keep = vec![false; chain.len()];
    let mut stack = vec![(0usize, last)];
    while let Some((lo, hi)) = stack.pop() {
        if hi <= lo + 1 {
            continue;
        }
        let (p, q) = (verts[chain[lo] as usize], verts[chain[hi] as usize]);
        let mut cands: Vec<(f64, usize)> = (lo + 1..hi)
            .filter(|&k| !used.contains(&chain[k]))
            .map(|k| (orient(p, q, verts[chain[k] as usize]), k))
            .filter(|c| c.0 >= 0.0)
            .collect();
        cands.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
        let pick = cands
            .iter()
            .take(CARVE_TRIES)
            .find(|&&(_, k)| admissible(verts, p, q, verts[chain[k] as usize], boundary, a, b))
            .map(|&(_, k)| k);
        if let Some(k) = pick {
            keep[k] = true;
            used.insert(chain[k]);
            stack.push((k, hi));
            stack.push((lo, k));
        }
    }
    ring.extend((1..last).filter(|&k| keep[k]).map(|k| chain[k]));
}

/// Whether cutting the triangle (p, q, w) off the ring (w left of p → q) keeps both hulls
/// inside: no boundary vertex inside the closed triangle (other than p, q, w), no boundary
/// edge crossing its new sides p–w, w–q, and its interior outside both hulls.
fn admissible(
    verts: &[Pt],
    p: Pt,
    q: Pt,
    w: Pt,
    boundary: &[(Pt, Pt)],
    a: &[u32],
    b: &[u32],
) -> bool {
    if orient(p, q, w) == 0.0 {
        // A vertex on the edge: inserting it removes nothing.
        return w != p && w != q && point_on_segment(p, q, w);
    }
    let lo = [p[0].min(q[0]).min(w[0]), p[1].min(q[1]).min(w[1])];
    let hi = [p[0].max(q[0]).max(w[0]), p[1].max(q[1]).max(w[1])];
    let in_box = |c: Pt| c[0] >= lo[0] && c[0] <= hi[0] && c[1] >= lo[1] && c[1] <= hi[1];
    for &(s, t) in boundary {
        if s[0].max(t[0]) < lo[0]
            || s[0].min(t[0]) > hi[0]
            || s[1].max(t[1]) < lo[1]
            || s[1].min(t[1]) > hi[1]
        {
            continue;
        }
        if segments_cross_properly(p, w, s, t) || segments_cross_properly(w, q, s, t) {
            return false;
        }
        if in_box(s) && s != p && s != q && s != w {
            // Closed triangle p, q, w (counter-clockwise: w is left of p → q).
            if orient(p, q, s) >= 0.0 && orient(q, w, s) >= 0.0 && orient(w, p, s) >= 0.0 {
                return false;
            }
        }
    }
    let c = [(p[0] + q[0] + w[0]) / 3.0, (p[1] + q[1] + w[1]) / 3.0];
    locate(verts, a, c) == Side::Outside && locate(verts, b, c) == Side::Outside
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
            assert!(m.failure.is_none() && !m.convex_hull, "{method:?}");
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
        assert!(m.failure.is_none() && !m.convex_hull);
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

    fn ring_of(store: &mut VertexStore, pts: &[[f64; 2]]) -> Vec<u32> {
        pts.iter().map(|&p| store.intern(p)).collect()
    }

    /// Every vertex of `m` is a vertex of `a` or `b`, or a new point on both boundaries.
    fn only_intersections_added(store: &VertexStore, m: &[u32], a: &[u32], b: &[u32]) {
        let on = |r: &[u32], p: Pt| {
            (0..r.len()).any(|k| {
                let (s, t) = (
                    store.verts[r[k] as usize],
                    store.verts[r[(k + 1) % r.len()] as usize],
                );
                point_segment_distance(p, s, t) <= 1e-6
            })
        };
        for &v in m {
            if !a.contains(&v) && !b.contains(&v) {
                let p = store.verts[v as usize];
                assert!(on(a, p) && on(b, p), "vertex {v} at {p:?} is new");
            }
        }
    }

    #[test]
    fn chang_bisecting_bars_full_hull_search_gives_the_cross() {
        // A plus sign: no vertex of either bar inside the other (Chang's Figure 7a).
        let mut s = VertexStore::default();
        let a = rect(&mut s, 0.0, 4.0, 12.0, 8.0);
        let b = rect(&mut s, 4.0, 0.0, 8.0, 12.0);
        assert_eq!(overlap_case(&s.verts, &a, &b), OverlapCase::Bisecting);
        let m = merge_rings(&mut s, &a, &b, HullMerge::ChangCases, 0.6);
        check(&s, &m, &a, &b);
        assert!(m.failure.is_none() && !m.convex_hull, "{m:?}");
        only_intersections_added(&s, &m.ring, &a, &b);
        // Carved down to the cross (12 corners, area 48 + 48 − 16), not the convex hull.
        assert_eq!(m.ring.len(), 12, "{:?}", m.ring);
        assert!((signed_area(&s.verts, &m.ring) - 80.0).abs() < 1e-9);
    }

    #[test]
    fn chang_intersecting_uses_the_candidate_lists() {
        // B's corner (6, 6) intrudes into A; one edge pair each: 2 × 2 candidate vertices.
        let mut s = VertexStore::default();
        let a = rect(&mut s, 0.0, 0.0, 8.0, 8.0);
        let b = rect(&mut s, 6.0, 6.0, 14.0, 10.0);
        assert_eq!(overlap_case(&s.verts, &a, &b), OverlapCase::Intersecting);
        let before = s.verts.len();
        let m = merge_rings(&mut s, &a, &b, HullMerge::ChangCases, 0.6);
        check(&s, &m, &a, &b);
        assert!(m.failure.is_none() && !m.convex_hull, "{m:?}");
        assert_eq!(s.verts.len(), before, "the heuristic adds no vertex");
        let hull = convex_hull(&s.verts, a.iter().chain(&b).copied());
        assert!(signed_area(&s.verts, &m.ring) <= signed_area(&s.verts, &hull) + 1e-9);
        // Larger lists (n × m > 12) go to the full hull search: a comb over a bar.
        let comb = ring_of(
            &mut s,
            &[
                [0.0, 0.0],
                [20.0, 0.0],
                [20.0, 6.0],
                [17.0, 6.0],
                [17.0, 2.0],
                [13.0, 2.0],
                [13.0, 6.0],
                [7.0, 6.0],
                [7.0, 2.0],
                [3.0, 2.0],
                [3.0, 6.0],
                [0.0, 6.0],
            ],
        );
        // The bar's left end intrudes into the first tooth.
        let bar = rect(&mut s, 1.5, 4.0, 22.0, 5.0);
        assert_eq!(
            overlap_case(&s.verts, &comb, &bar),
            OverlapCase::Intersecting
        );
        let m = merge_rings(&mut s, &comb, &bar, HullMerge::ChangCases, 0.6);
        check(&s, &m, &comb, &bar);
        assert!(m.failure.is_none() && !m.convex_hull, "{m:?}");
        only_intersections_added(&s, &m.ring, &comb, &bar);
    }

    #[test]
    fn corner_touching_pinch_is_carved_not_convex() {
        // Two squares touching at one corner: the union's outline passes (10, 10) twice.
        for method in [HullMerge::YangDelaunay, HullMerge::ChangCases] {
            let mut s = VertexStore::default();
            let a = rect(&mut s, 0.0, 0.0, 10.0, 10.0);
            let b = rect(&mut s, 10.0, 10.0, 20.0, 20.0);
            let m = merge_rings(&mut s, &a, &b, method, 0.6);
            check(&s, &m, &a, &b);
            assert!(!m.convex_hull, "{method:?}");
            if method == HullMerge::YangDelaunay {
                assert_eq!(m.failure, Some(MergeFailure::UnionNotSimple));
            }
            only_intersections_added(&s, &m.ring, &a, &b);
            // One side of the pinch carved: less than the hexagonal convex hull (300 m²).
            assert!(signed_area(&s.verts, &m.ring) < 300.0 - 1.0);
        }
    }

    /// Random pairs of rectangles and L shapes on a coarse grid (so corners and edges touch
    /// exactly, bars cross, one lies inside the other): both methods give a simple ring that
    /// contains both, with no new vertex but intersection points, and never the convex hull.
    #[test]
    fn random_pairs_merge_validly() {
        use proptest::prelude::*;
        use proptest::test_runner::{Config, RngAlgorithm, TestRng, TestRunner};
        let shape = (0u8..3, -4i32..5, -4i32..5, 1i32..7, 1i32..7);
        let config = Config {
            cases: 400,
            failure_persistence: None,
            ..Config::default()
        };
        let rng = TestRng::from_seed(RngAlgorithm::ChaCha, &[11; 32]);
        let mut runner = TestRunner::new_with_rng(config, rng);
        let make = |s: &mut VertexStore, (kind, x, y, w, h): (u8, i32, i32, i32, i32)| {
            let (x, y, w, h) = (
                f64::from(x) * 0.5,
                f64::from(y) * 0.5,
                f64::from(w),
                f64::from(h),
            );
            match kind {
                0 => rect(s, x, y, x + w, y + h),
                // A thin bar (crosses others).
                1 => rect(s, x, y, x + w + 3.0, y + 0.5),
                _ => ring_of(
                    s,
                    &[
                        [x, y],
                        [x + w + 1.0, y],
                        [x + w + 1.0, y + 1.0],
                        [x + 1.0, y + 1.0],
                        [x + 1.0, y + h + 1.0],
                        [x, y + h + 1.0],
                    ],
                ),
            }
        };
        let convex = std::cell::Cell::new(0usize);
        runner
            .run(&(shape.clone(), shape, any::<bool>()), |(sa, sb, chang)| {
                let mut s = VertexStore::default();
                let a = make(&mut s, sa);
                let b = make(&mut s, sb);
                let method = if chang {
                    HullMerge::ChangCases
                } else {
                    HullMerge::YangDelaunay
                };
                let m = merge_rings(&mut s, &a, &b, method, 0.6);
                prop_assert!(ring_is_simple_ccw(&s.verts, &m.ring), "{:?}", m);
                prop_assert!(ring_contains_ring(&s.verts, &m.ring, &a));
                prop_assert!(ring_contains_ring(&s.verts, &m.ring, &b));
                only_intersections_added(&s, &m.ring, &a, &b);
                convex.set(convex.get() + usize::from(m.convex_hull));
                Ok(())
            })
            .expect("random pairs");
        assert_eq!(convex.get(), 0, "convex-hull fallbacks");
    }
}
