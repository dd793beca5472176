//! Ring geometry on the shared vertex array: orientation, simplicity, containment, convex hull,
//! segment intersection. Orientation tests go through `robust::orient2d` (adaptive exact).

use robust::{Coord, orient2d};

pub type Pt = [f64; 2];

/// Sign of the turn a → b → c: > 0 left (counter-clockwise), < 0 right, 0 collinear. Exact.
pub fn orient(a: Pt, b: Pt, c: Pt) -> f64 {
    orient2d(
        Coord { x: a[0], y: a[1] },
        Coord { x: b[0], y: b[1] },
        Coord { x: c[0], y: c[1] },
    )
}

/// Signed area of a ring (positive when counter-clockwise).
pub fn signed_area(verts: &[Pt], ring: &[u32]) -> f64 {
    let n = ring.len();
    let mut s = 0.0;
    for i in 0..n {
        let a = verts[ring[i] as usize];
        let b = verts[ring[(i + 1) % n] as usize];
        s += a[0] * b[1] - b[0] * a[1];
    }
    0.5 * s
}

/// Axis-aligned bounds `(min, max)` of a ring.
pub fn ring_bounds(verts: &[Pt], ring: &[u32]) -> (Pt, Pt) {
    let mut lo = [f64::INFINITY; 2];
    let mut hi = [f64::NEG_INFINITY; 2];
    for &i in ring {
        let p = verts[i as usize];
        lo = [lo[0].min(p[0]), lo[1].min(p[1])];
        hi = [hi[0].max(p[0]), hi[1].max(p[1])];
    }
    (lo, hi)
}

fn on_segment_collinear(a: Pt, b: Pt, p: Pt) -> bool {
    p[0] >= a[0].min(b[0])
        && p[0] <= a[0].max(b[0])
        && p[1] >= a[1].min(b[1])
        && p[1] <= a[1].max(b[1])
}

/// Whether `p` lies on the closed segment `ab`. Exact.
pub fn point_on_segment(a: Pt, b: Pt, p: Pt) -> bool {
    orient(a, b, p) == 0.0 && on_segment_collinear(a, b, p)
}

/// Whether closed segments `ab` and `cd` share any point. Exact.
pub fn segments_touch(a: Pt, b: Pt, c: Pt, d: Pt) -> bool {
    let o1 = orient(a, b, c);
    let o2 = orient(a, b, d);
    let o3 = orient(c, d, a);
    let o4 = orient(c, d, b);
    if ((o1 > 0.0 && o2 < 0.0) || (o1 < 0.0 && o2 > 0.0))
        && ((o3 > 0.0 && o4 < 0.0) || (o3 < 0.0 && o4 > 0.0))
    {
        return true;
    }
    (o1 == 0.0 && on_segment_collinear(a, b, c))
        || (o2 == 0.0 && on_segment_collinear(a, b, d))
        || (o3 == 0.0 && on_segment_collinear(c, d, a))
        || (o4 == 0.0 && on_segment_collinear(c, d, b))
}

/// Whether segments `ab` and `cd` cross at one point interior to both. Exact.
pub fn segments_cross_properly(a: Pt, b: Pt, c: Pt, d: Pt) -> bool {
    let o1 = orient(a, b, c);
    let o2 = orient(a, b, d);
    let o3 = orient(c, d, a);
    let o4 = orient(c, d, b);
    o1 * o2 < 0.0 && o3 * o4 < 0.0
}

/// The crossing point of two properly crossing segments (f64, not exact).
pub fn crossing_point(a: Pt, b: Pt, c: Pt, d: Pt) -> Pt {
    let r = [b[0] - a[0], b[1] - a[1]];
    let s = [d[0] - c[0], d[1] - c[1]];
    let den = r[0] * s[1] - r[1] * s[0];
    if den == 0.0 {
        return a;
    }
    let t = ((c[0] - a[0]) * s[1] - (c[1] - a[1]) * s[0]) / den;
    let t = t.clamp(0.0, 1.0);
    [a[0] + t * r[0], a[1] + t * r[1]]
}

/// Where a point is relative to a ring.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Side {
    Inside,
    Boundary,
    Outside,
}

/// Locates `p` relative to the ring (any orientation). Exact.
pub fn locate(verts: &[Pt], ring: &[u32], p: Pt) -> Side {
    let n = ring.len();
    let mut winding = 0i32;
    for i in 0..n {
        let a = verts[ring[i] as usize];
        let b = verts[ring[(i + 1) % n] as usize];
        if point_on_segment(a, b, p) {
            return Side::Boundary;
        }
        if a[1] <= p[1] {
            if b[1] > p[1] && orient(a, b, p) > 0.0 {
                winding += 1;
            }
        } else if b[1] <= p[1] && orient(a, b, p) < 0.0 {
            winding -= 1;
        }
    }
    if winding != 0 {
        Side::Inside
    } else {
        Side::Outside
    }
}

/// Edges of a ring as `(a, b)` coordinate pairs with their ring positions.
fn edges(verts: &[Pt], ring: &[u32]) -> Vec<(Pt, Pt, usize)> {
    let n = ring.len();
    (0..n)
        .map(|i| {
            (
                verts[ring[i] as usize],
                verts[ring[(i + 1) % n] as usize],
                i,
            )
        })
        .collect()
}

/// Calls `f(i, j)` for every pair of edges (from `ea`, `eb`) whose x-ranges overlap; stops
/// early when `f` returns true, and then returns true.
fn sweep_pairs(
    ea: &[(Pt, Pt, usize)],
    eb: &[(Pt, Pt, usize)],
    same: bool,
    mut f: impl FnMut(&(Pt, Pt, usize), &(Pt, Pt, usize)) -> bool,
) -> bool {
    let key = |e: &(Pt, Pt, usize)| e.0[0].min(e.1[0]);
    let maxx = |e: &(Pt, Pt, usize)| e.0[0].max(e.1[0]);
    let ybox = |e: &(Pt, Pt, usize)| (e.0[1].min(e.1[1]), e.0[1].max(e.1[1]));
    // Tagged merged list sorted by min x.
    let mut all: Vec<(f64, bool, usize)> = ea
        .iter()
        .enumerate()
        .map(|(i, e)| (key(e), false, i))
        .collect();
    if !same {
        all.extend(eb.iter().enumerate().map(|(i, e)| (key(e), true, i)));
    }
    all.sort_by(|x, y| x.0.total_cmp(&y.0));
    for s in 0..all.len() {
        let (_, tag_s, is) = all[s];
        let es = if tag_s { &eb[is] } else { &ea[is] };
        let xs = maxx(es);
        let (ys0, ys1) = ybox(es);
        for &(kx, tag_t, it) in &all[s + 1..] {
            if kx > xs {
                break;
            }
            if !same && tag_s == tag_t {
                continue;
            }
            let et = if tag_t { &eb[it] } else { &ea[it] };
            let (yt0, yt1) = ybox(et);
            if yt1 < ys0 || yt0 > ys1 {
                continue;
            }
            let (x, y) = if same || !tag_s { (es, et) } else { (et, es) };
            if f(x, y) {
                return true;
            }
        }
    }
    false
}

/// Whether a ring is a simple polygon with positive (counter-clockwise) area: at least three
/// distinct vertices, no edge touching a non-adjacent edge, adjacent edges meeting only at
/// their shared vertex.
pub fn ring_is_simple_ccw(verts: &[Pt], ring: &[u32]) -> bool {
    let n = ring.len();
    if n < 3 || signed_area(verts, ring) <= 0.0 {
        return false;
    }
    let es = edges(verts, ring);
    if es.iter().any(|e| e.0 == e.1) {
        return false;
    }
    !sweep_pairs(&es, &es, true, |x, y| {
        let (i, j) = (x.2.min(y.2), x.2.max(y.2));
        let adjacent = j == i + 1 || (i == 0 && j == n - 1);
        if adjacent {
            // Adjacent edges share exactly one vertex: fail on overlap (spike).
            let (shared, p, q) = if j == i + 1 {
                (es[i].1, es[i].0, es[j].1)
            } else {
                (es[i].0, es[i].1, es[j].0)
            };
            if n == 3 {
                return orient(p, shared, q) == 0.0;
            }
            orient(p, shared, q) == 0.0
                && ((q[0] - shared[0]) * (p[0] - shared[0])
                    + (q[1] - shared[1]) * (p[1] - shared[1]))
                    > 0.0
        } else {
            segments_touch(x.0, x.1, y.0, y.1)
        }
    })
}

/// Tolerance of [`ring_contains_ring`] (metres): how far a vertex may stray outside after
/// an intersection point was rounded to f64, or where OSM's shared walls are a rounding error
/// from collinear. Far below anything a renderer can show.
pub const CONTAIN_TOL_M: f64 = 1e-6;

fn line_distance(p: Pt, a: Pt, b: Pt) -> f64 {
    let d = [b[0] - a[0], b[1] - a[1]];
    let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
    if len == 0.0 {
        return ((p[0] - a[0]).powi(2) + (p[1] - a[1]).powi(2)).sqrt();
    }
    ((p[0] - a[0]) * d[1] - (p[1] - a[1]) * d[0]).abs() / len
}

fn near_boundary(verts: &[Pt], ring: &[u32], p: Pt, tol: f64) -> bool {
    let m = ring.len();
    (0..m).any(|k| {
        let (a, b) = (verts[ring[k] as usize], verts[ring[(k + 1) % m] as usize]);
        point_segment_distance(p, a, b) <= tol
    })
}

/// Whether ring `inner` lies inside the closed region of ring `outer` (both simple), up to
/// [`CONTAIN_TOL_M`]: every vertex of `inner` is inside, on or within the tolerance of
/// `outer`; so is the midpoint of every piece of an `inner` edge between the vertices of
/// `outer` that lie on it (an edge can leave and re-enter through vertices of `outer` without
/// any proper crossing); and every proper crossing of edges is within the tolerance of
/// touching.
pub fn ring_contains_ring(verts: &[Pt], outer: &[u32], inner: &[u32]) -> bool {
    let tol = CONTAIN_TOL_M;
    let (olo, ohi) = ring_bounds(verts, outer);
    let (ilo, ihi) = ring_bounds(verts, inner);
    if ilo[0] < olo[0] - tol
        || ilo[1] < olo[1] - tol
        || ihi[0] > ohi[0] + tol
        || ihi[1] > ohi[1] + tol
    {
        return false;
    }
    let outside =
        |p: Pt| locate(verts, outer, p) == Side::Outside && !near_boundary(verts, outer, p, tol);
    // Positions of `outer`'s vertex indices: on the shared vertex array a vertex of `outer` is
    // on its boundary and an edge of `outer` lies on it, so neither needs locating (hulls
    // reuse most of their children's vertices and edges).
    let mut at: Vec<(u32, u32)> = outer
        .iter()
        .enumerate()
        .map(|(k, &o)| (o, k as u32))
        .collect();
    at.sort_unstable();
    let find = |x: u32| at.binary_search_by_key(&x, |e| e.0).ok().map(|k| at[k].1);
    let m = outer.len() as u32;
    let n = inner.len();
    let mut cuts: Vec<f64> = Vec::new();
    for i in 0..n {
        let (ia, ib) = (inner[i], inner[(i + 1) % n]);
        let (pa, pb) = (find(ia), find(ib));
        if let (Some(x), Some(y)) = (pa, pb)
            && ((x + 1) % m == y || (y + 1) % m == x)
        {
            continue;
        }
        let a = verts[ia as usize];
        let b = verts[ib as usize];
        if pa.is_none() && outside(a) {
            return false;
        }
        // Parameters along a→b of the vertices of `outer` lying exactly on the edge.
        let d = [b[0] - a[0], b[1] - a[1]];
        let len2 = d[0] * d[0] + d[1] * d[1];
        let (lo, hi) = (
            [a[0].min(b[0]), a[1].min(b[1])],
            [a[0].max(b[0]), a[1].max(b[1])],
        );
        cuts.clear();
        cuts.extend([0.0, 1.0]);
        if len2 > 0.0 {
            for &o in outer {
                let c = verts[o as usize];
                if c[0] >= lo[0]
                    && c[0] <= hi[0]
                    && c[1] >= lo[1]
                    && c[1] <= hi[1]
                    && c != a
                    && c != b
                    && orient(a, b, c) == 0.0
                {
                    cuts.push(((c[0] - a[0]) * d[0] + (c[1] - a[1]) * d[1]) / len2);
                }
            }
        }
        if cuts.len() > 2 {
            cuts.sort_by(f64::total_cmp);
        }
        for w in cuts.windows(2) {
            let t = 0.5 * (w[0] + w[1]);
            if outside([a[0] + t * d[0], a[1] + t * d[1]]) {
                return false;
            }
        }
    }
    let eo = edges(verts, outer);
    let ei = edges(verts, inner);
    !sweep_pairs(&eo, &ei, false, |f, e| {
        segments_cross_properly(f.0, f.1, e.0, e.1)
            && line_distance(e.0, f.0, f.1).min(line_distance(e.1, f.0, f.1)) > tol
            && line_distance(f.0, e.0, e.1).min(line_distance(f.1, e.0, e.1)) > tol
    })
}

/// Whether any edge of ring `a` touches any edge of ring `b`.
pub fn rings_touch(verts: &[Pt], a: &[u32], b: &[u32]) -> bool {
    let ea = edges(verts, a);
    let eb = edges(verts, b);
    sweep_pairs(&ea, &eb, false, |x, y| segments_touch(x.0, x.1, y.0, y.1))
}

/// Every pair `(edge index in a, edge index in b)` of touching edges.
pub fn touching_edge_pairs(verts: &[Pt], a: &[u32], b: &[u32]) -> Vec<(usize, usize)> {
    let ea = edges(verts, a);
    let eb = edges(verts, b);
    let mut out = Vec::new();
    sweep_pairs(&ea, &eb, false, |x, y| {
        if segments_touch(x.0, x.1, y.0, y.1) {
            out.push((x.2, y.2));
        }
        false
    });
    out
}

/// Counter-clockwise convex hull of the given vertex indices (Andrew's monotone chain with
/// exact orientation; collinear points dropped). Fewer than three entries when degenerate.
pub fn convex_hull(verts: &[Pt], idx: impl IntoIterator<Item = u32>) -> Vec<u32> {
    let mut pts: Vec<u32> = idx.into_iter().collect();
    pts.sort_by(|&a, &b| {
        let (pa, pb) = (verts[a as usize], verts[b as usize]);
        pa[0].total_cmp(&pb[0]).then(pa[1].total_cmp(&pb[1]))
    });
    pts.dedup_by(|a, b| verts[*a as usize] == verts[*b as usize]);
    if pts.len() < 3 {
        return pts;
    }
    let mut hull: Vec<u32> = Vec::with_capacity(pts.len() + 1);
    for pass in 0..2 {
        let start = hull.len();
        let iter: Box<dyn Iterator<Item = &u32>> = if pass == 0 {
            Box::new(pts.iter())
        } else {
            Box::new(pts.iter().rev())
        };
        for &p in iter {
            while hull.len() >= start + 2 {
                let a = verts[hull[hull.len() - 2] as usize];
                let b = verts[hull[hull.len() - 1] as usize];
                if orient(a, b, verts[p as usize]) <= 0.0 {
                    hull.pop();
                } else {
                    break;
                }
            }
            hull.push(p);
        }
        hull.pop();
    }
    hull
}

/// The point of segment `ab` nearest `p` (`a` for a segment of no length).
pub fn closest_point_on_segment(p: Pt, a: Pt, b: Pt) -> Pt {
    let ab = [b[0] - a[0], b[1] - a[1]];
    let len2 = ab[0] * ab[0] + ab[1] * ab[1];
    let t = if len2 > 0.0 {
        (((p[0] - a[0]) * ab[0] + (p[1] - a[1]) * ab[1]) / len2).clamp(0.0, 1.0)
    } else {
        0.0
    };
    [a[0] + t * ab[0], a[1] + t * ab[1]]
}

/// Distance from `p` to segment `ab`.
pub fn point_segment_distance(p: Pt, a: Pt, b: Pt) -> f64 {
    let q = closest_point_on_segment(p, a, b);
    ((p[0] - q[0]).powi(2) + (p[1] - q[1]).powi(2)).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn square() -> Vec<Pt> {
        vec![
            [0.0, 0.0],
            [2.0, 0.0],
            [2.0, 2.0],
            [0.0, 2.0],
            [1.0, 1.0],
            [3.0, 1.0],
        ]
    }

    #[test]
    fn simple_and_orientation() {
        let v = square();
        assert!(ring_is_simple_ccw(&v, &[0, 1, 2, 3]));
        assert!(!ring_is_simple_ccw(&v, &[3, 2, 1, 0]), "clockwise rejected");
        assert!(!ring_is_simple_ccw(&v, &[0, 2, 1, 3]), "bow tie rejected");
        assert!(!ring_is_simple_ccw(&v, &[0, 1]));
    }

    #[test]
    fn locate_and_contains() {
        let v = square();
        assert_eq!(locate(&v, &[0, 1, 2, 3], [1.0, 1.0]), Side::Inside);
        assert_eq!(locate(&v, &[0, 1, 2, 3], [2.0, 1.0]), Side::Boundary);
        assert_eq!(locate(&v, &[0, 1, 2, 3], [3.0, 1.0]), Side::Outside);
        assert!(ring_contains_ring(&v, &[0, 1, 2, 3], &[0, 1, 2, 3]));
        assert!(ring_contains_ring(&v, &[0, 1, 2, 3], &[0, 1, 4]));
        assert!(!ring_contains_ring(&v, &[0, 1, 2, 3], &[0, 5, 2]));
    }

    #[test]
    fn hull_drops_interior_and_collinear() {
        let mut v = square();
        v.push([1.0, 0.0]);
        let h = convex_hull(&v, 0..v.len() as u32);
        assert_eq!(h.len(), 5, "hull {h:?}");
        assert!(ring_is_simple_ccw(&v, &h));
        assert!(!h.contains(&4) && !h.contains(&6));
    }
}
