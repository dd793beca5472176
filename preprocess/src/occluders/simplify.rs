//! Conservative footprint simplification (Germs & Jansen §3.3, Fig. 4).
//!
//! Two rules must hold: "the simplified footprint must be completely contained by the original
//! footprint" and "the occlusion potential ... must be preserved as much as possible". Every
//! step here only removes area:
//!
//! * **Redundant vertex removal** (Fig. 4a): a vertex V whose two edges turn by less than α is
//!   removed — only when V is convex (the solid's interior on the inner side of the turn), so
//!   the cut-off triangle (prev, V, next) leaves the polygon; collinear vertices always go.
//! * **Redundant edge removal** (Fig. 4b): a short edge E = (A, B) is replaced by the point V
//!   where the lines through its neighbouring edges meet — only when V lies beyond A and B on
//!   those lines and on the interior side of E, so the triangle (A, V, B) leaves the polygon,
//!   and only if the distance from V to the midpoint of E is below the threshold (the paper's
//!   constraint that keeps the occlusion potential).
//!
//! A step is taken only if the removed triangle holds no other vertex of the polygon and the
//! new edges cross no other edge (orientation tests with `robust::orient2d`), so rings stay
//! simple and do not touch each other. Finally each simplified polygon is checked with `geo`:
//! valid (`Validation`), covered by the original (`Covers`), no larger; if any check fails the
//! polygon falls back to the unsimplified one. Polygons below the minimum area are dropped
//! (dropping area is conservative).

use geo::{Area, Coord, Covers, LineString, MultiPolygon, Orient, Polygon, Validation, orient};
use robust::{Coord as RCoord, orient2d};

use super::OccluderParams;

/// Simplifies every polygon of `footprint` inward (see the module doc) when `params.simplify`
/// is set, and drops polygons smaller than `params.min_polygon_area_m2`.
pub fn simplify_footprint(
    footprint: &MultiPolygon<f64>,
    params: &OccluderParams,
) -> MultiPolygon<f64> {
    let mut out = Vec::with_capacity(footprint.0.len());
    for polygon in footprint {
        let simplified = if params.simplify {
            simplify_polygon(polygon, params)
        } else {
            polygon.clone()
        };
        if simplified.unsigned_area() >= params.min_polygon_area_m2 {
            out.push(simplified);
        }
    }
    MultiPolygon::new(out)
}

/// Simplifies one polygon inward; returns the original when the result would not be valid,
/// contained and no larger.
pub fn simplify_polygon(polygon: &Polygon<f64>, params: &OccluderParams) -> Polygon<f64> {
    let oriented = polygon.orient(orient::Direction::Default);
    let mut rings: Vec<Vec<Coord<f64>>> = std::iter::once(oriented.exterior())
        .chain(oriented.interiors())
        .map(open_ring)
        .collect();
    if rings.iter().any(|r| r.len() < 3) {
        return polygon.clone();
    }
    let max_turn = params.max_turn_angle_deg.to_radians();
    // Each pass scans every vertex once; stop when a pass changes nothing.
    for _ in 0..64 {
        let mut changed = false;
        for r in 0..rings.len() {
            let mut i = 0;
            while i < rings[r].len() && rings[r].len() > 3 {
                if try_remove_vertex(&mut rings, r, i, max_turn)
                    || try_remove_edge(&mut rings, r, i, params.max_edge_shift_m)
                {
                    changed = true;
                } else {
                    i += 1;
                }
            }
        }
        if !changed {
            break;
        }
    }
    let mut rings = rings.into_iter().map(close_ring);
    let Some(exterior) = rings.next() else {
        return polygon.clone();
    };
    let simplified = Polygon::new(exterior, rings.collect());
    let ok = simplified.is_valid()
        && simplified.unsigned_area() <= polygon.unsigned_area()
        && polygon.covers(&simplified);
    if ok { simplified } else { polygon.clone() }
}

/// Ring vertices without the closing repeat and without consecutive duplicates.
fn open_ring(ring: &LineString<f64>) -> Vec<Coord<f64>> {
    let mut v: Vec<Coord<f64>> = ring.0.clone();
    v.dedup();
    if v.len() > 1 && v.first() == v.last() {
        v.pop();
    }
    v
}

fn close_ring(mut v: Vec<Coord<f64>>) -> LineString<f64> {
    if let Some(&first) = v.first() {
        v.push(first);
    }
    LineString::new(v)
}

fn rc(c: Coord<f64>) -> RCoord<f64> {
    RCoord { x: c.x, y: c.y }
}

/// Positive when a → b → c turns left (counter-clockwise), exactly.
fn orient(a: Coord<f64>, b: Coord<f64>, c: Coord<f64>) -> f64 {
    orient2d(rc(a), rc(b), rc(c))
}

/// Redundant vertex removal at vertex `i` of ring `r`.
fn try_remove_vertex(rings: &mut [Vec<Coord<f64>>], r: usize, i: usize, max_turn_rad: f64) -> bool {
    let ring = &rings[r];
    let n = ring.len();
    let (p, v, q) = (ring[(i + n - 1) % n], ring[i], ring[(i + 1) % n]);
    let o = orient(p, v, q);
    if o < 0.0 {
        return false; // reflex: removing it would add area
    }
    if o > 0.0 {
        let (d1, d2) = (v - p, q - v);
        let turn = (d1.x * d2.y - d1.y * d2.x).atan2(d1.x * d2.x + d1.y * d2.y);
        if turn.is_nan() || turn.abs() >= max_turn_rad {
            return false;
        }
        // The cut-off triangle must hold no other vertex and the new edge cross nothing.
        let (ip, iq) = ((i + n - 1) % n, (i + 1) % n);
        if !triangle_is_empty(rings, [p, v, q], &[(r, ip), (r, i), (r, iq)])
            || crosses_any(rings, p, q, &[(r, ip), (r, i)])
        {
            return false;
        }
    }
    rings[r].remove(i);
    true
}

/// Redundant edge removal of edge (i, i+1) of ring `r`.
fn try_remove_edge(rings: &mut [Vec<Coord<f64>>], r: usize, i: usize, max_shift_m: f64) -> bool {
    let ring = &rings[r];
    let n = ring.len();
    if n < 4 {
        return false;
    }
    let (ip, ia, ib, iq) = ((i + n - 1) % n, i, (i + 1) % n, (i + 2) % n);
    let (p, a, b, q) = (ring[ip], ring[ia], ring[ib], ring[iq]);
    // Meeting point of the lines p→a and q→b: a + t (a − p) = b + s (b − q).
    let (d1, d2) = (a - p, b - q);
    let den = d1.x * d2.y - d1.y * d2.x;
    if den.abs() < 1e-12 * (d1.x.hypot(d1.y) * d2.x.hypot(d2.y)).max(1e-300) {
        return false; // parallel neighbours
    }
    let w = b - a;
    let t = (w.x * d2.y - w.y * d2.x) / den;
    let s = (w.x * d1.y - w.y * d1.x) / den;
    if !(t > 0.0 && s > 0.0 && t.is_finite() && s.is_finite()) {
        return false;
    }
    let v = Coord {
        x: a.x + t * d1.x,
        y: a.y + t * d1.y,
    };
    let mid = Coord {
        x: 0.5 * (a.x + b.x),
        y: 0.5 * (a.y + b.y),
    };
    if (v.x - mid.x).hypot(v.y - mid.y) > max_shift_m {
        return false;
    }
    // V on the interior (left) side of a → b.
    if orient(a, b, v) <= 0.0 {
        return false;
    }
    let skip = [(r, ip), (r, ia), (r, ib)];
    if !triangle_is_empty(rings, [a, v, b], &[(r, ia), (r, ib)])
        || crosses_any(rings, p, v, &skip)
        || crosses_any(rings, v, q, &[(r, ia), (r, ib), (r, iq)])
    {
        return false;
    }
    let ring = &mut rings[r];
    ring[ia] = v;
    ring.remove(ib);
    true
}

/// Whether no vertex of any ring (other than those listed) lies in or on the closed triangle.
fn triangle_is_empty(
    rings: &[Vec<Coord<f64>>],
    t: [Coord<f64>; 3],
    except: &[(usize, usize)],
) -> bool {
    let [a, b, c] = t;
    let ccw = orient(a, b, c) > 0.0;
    for (r, ring) in rings.iter().enumerate() {
        for (i, &w) in ring.iter().enumerate() {
            if except.contains(&(r, i)) {
                continue;
            }
            let (o1, o2, o3) = (orient(a, b, w), orient(b, c, w), orient(c, a, w));
            let inside = if ccw {
                o1 >= 0.0 && o2 >= 0.0 && o3 >= 0.0
            } else {
                o1 <= 0.0 && o2 <= 0.0 && o3 <= 0.0
            };
            if inside {
                return false;
            }
        }
    }
    true
}

/// Whether segment p–q touches any ring edge, except the edges starting at the listed
/// vertices (the ones it replaces or shares an endpoint with) and their neighbours at the
/// shared endpoints.
fn crosses_any(
    rings: &[Vec<Coord<f64>>],
    p: Coord<f64>,
    q: Coord<f64>,
    except: &[(usize, usize)],
) -> bool {
    for (r, ring) in rings.iter().enumerate() {
        let n = ring.len();
        for i in 0..n {
            if except.contains(&(r, i)) {
                continue;
            }
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            // Edges sharing an endpoint with p–q meet it there by construction; they only
            // matter if they overlap it, which the orientation tests below catch as collinear.
            let shares = a == p || a == q || b == p || b == q;
            if segments_touch(p, q, a, b, shares) {
                return true;
            }
        }
    }
    false
}

/// Closed-segment intersection test with exact orientations. With `shares_endpoint`, touching
/// at the shared endpoint alone does not count.
fn segments_touch(
    p: Coord<f64>,
    q: Coord<f64>,
    a: Coord<f64>,
    b: Coord<f64>,
    shares_endpoint: bool,
) -> bool {
    let (o1, o2) = (orient(p, q, a), orient(p, q, b));
    let (o3, o4) = (orient(a, b, p), orient(a, b, q));
    if shares_endpoint {
        // Only a collinear overlap beyond the shared point counts.
        if o1 == 0.0 && o2 == 0.0 {
            let inside = |s0: Coord<f64>, s1: Coord<f64>, u: Coord<f64>| {
                u != s0 && u != s1 && on_segment(s0, s1, u)
            };
            return inside(p, q, a) || inside(p, q, b) || inside(a, b, p) || inside(a, b, q);
        }
        return false;
    }
    if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
        return true;
    }
    (o1 == 0.0 && on_segment(p, q, a))
        || (o2 == 0.0 && on_segment(p, q, b))
        || (o3 == 0.0 && on_segment(a, b, p))
        || (o4 == 0.0 && on_segment(a, b, q))
}

/// For collinear u: whether it lies on the closed segment p–q.
fn on_segment(p: Coord<f64>, q: Coord<f64>, u: Coord<f64>) -> bool {
    u.x >= p.x.min(q.x) && u.x <= p.x.max(q.x) && u.y >= p.y.min(q.y) && u.y <= p.y.max(q.y)
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::polygon;

    fn params() -> OccluderParams {
        OccluderParams::default()
    }

    #[test]
    fn nearly_collinear_convex_vertex_is_removed() {
        // A 10 × 10 square with an extra vertex bulging 0.1 m out of the south edge (convex
        // w.r.t. the interior: the bulge points outward), turn about 2.3°.
        let p = polygon![(x: 0.0, y: 0.0), (x: 5.0, y: -0.1), (x: 10.0, y: 0.0), (x: 10.0, y: 10.0), (x: 0.0, y: 10.0)];
        let s = simplify_polygon(&p, &params());
        assert_eq!(s.exterior().0.len(), 5, "{s:?}");
        assert!(p.covers(&s));
        assert!(s.unsigned_area() < p.unsigned_area());
    }

    #[test]
    fn reflex_vertex_is_never_removed() {
        // The same vertex dented inward: removing it would add area.
        let p = polygon![(x: 0.0, y: 0.0), (x: 5.0, y: 0.1), (x: 10.0, y: 0.0), (x: 10.0, y: 10.0), (x: 0.0, y: 10.0)];
        let s = simplify_polygon(&p, &params());
        assert_eq!(s.exterior().0.len(), 6);
        assert!((s.unsigned_area() - p.unsigned_area()).abs() < 1e-12);
    }

    #[test]
    fn a_short_chamfer_in_a_notch_is_replaced_by_the_corner() {
        // An L shape whose inner (reflex) corner is chamfered by a 0.3 m edge: the neighbours
        // meet at (5, 5), inside the polygon, 0.1 m from the chamfer's midpoint.
        let p = polygon![
            (x: 0.0, y: 0.0), (x: 10.0, y: 0.0), (x: 10.0, y: 5.0), (x: 5.2, y: 5.0),
            (x: 5.0, y: 5.2), (x: 5.0, y: 10.0), (x: 0.0, y: 10.0)
        ];
        let s = simplify_polygon(&p, &params());
        assert_eq!(s.exterior().0.len(), 7, "{s:?}");
        assert!(s.exterior().0.contains(&Coord { x: 5.0, y: 5.0 }));
        assert!(p.covers(&s));
        assert!(s.unsigned_area() < p.unsigned_area());
    }

    #[test]
    fn an_outer_chamfer_is_kept() {
        // A chamfered convex corner: the neighbours meet outside, which would add area.
        let p = polygon![(x: 0.0, y: 0.0), (x: 9.8, y: 0.0), (x: 10.0, y: 0.2), (x: 10.0, y: 10.0), (x: 0.0, y: 10.0)];
        let s = simplify_polygon(&p, &params());
        assert_eq!(s.exterior().0.len(), 6);
    }

    #[test]
    fn holes_are_simplified_inward_too() {
        // A hole with a vertex dented into it (the solid pokes 0.1 m into the hole): removing
        // the vertex enlarges the hole, which is inward for the polygon.
        let p = polygon![
            exterior: [(x: 0.0, y: 0.0), (x: 20.0, y: 0.0), (x: 20.0, y: 20.0), (x: 0.0, y: 20.0)],
            interiors: [[(x: 5.0, y: 5.0), (x: 10.0, y: 5.1), (x: 15.0, y: 5.0), (x: 15.0, y: 15.0), (x: 5.0, y: 15.0)]],
        ];
        let s = simplify_polygon(&p, &params());
        assert_eq!(s.interiors()[0].0.len(), 5, "{s:?}");
        assert!(p.covers(&s));
        assert!(s.unsigned_area() < p.unsigned_area());
        // Bulging out of the hole into the solid instead: removing it would shrink the hole
        // and grow the polygon, so it is kept.
        let p = polygon![
            exterior: [(x: 0.0, y: 0.0), (x: 20.0, y: 0.0), (x: 20.0, y: 20.0), (x: 0.0, y: 20.0)],
            interiors: [[(x: 5.0, y: 5.0), (x: 10.0, y: 4.9), (x: 15.0, y: 5.0), (x: 15.0, y: 15.0), (x: 5.0, y: 15.0)]],
        ];
        assert_eq!(simplify_polygon(&p, &params()).interiors()[0].0.len(), 6);
    }

    #[test]
    fn small_polygons_are_dropped_and_simplify_can_be_off() {
        let tiny = polygon![(x: 0.0, y: 0.0), (x: 0.5, y: 0.0), (x: 0.5, y: 0.5)];
        let big = polygon![(x: 0.0, y: 0.0), (x: 5.0, y: -0.1), (x: 10.0, y: 0.0), (x: 10.0, y: 10.0), (x: 0.0, y: 10.0)];
        let mp = MultiPolygon::new(vec![tiny, big.clone()]);
        let s = simplify_footprint(&mp, &params());
        assert_eq!(s.0.len(), 1);
        let off = OccluderParams {
            simplify: false,
            ..params()
        };
        assert_eq!(simplify_footprint(&mp, &off).0, vec![big]);
    }
}
