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
//! new edges cross no other edge (orientation tests with `robust::orient2d`, over R-trees of
//! the vertices and edges), so rings stay simple and do not touch each other. Finally each
//! simplified polygon is checked: valid (`check_multipolygon`), covered by the original
//! (`geo::Covers`), no larger; if any check fails the polygon falls back to the unsimplified
//! one. Polygons below the minimum area are dropped
//! (dropping area is conservative).

use citywalk_scenes::validate::check_multipolygon;
use geo::{Area, Coord, Covers, LineString, MultiPolygon, Orient, Polygon, orient};
use robust::{Coord as RCoord, orient2d};
use rstar::primitives::{GeomWithData, Line as RLine};
use rstar::{AABB, RTree};

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
    let open: Vec<Vec<Coord<f64>>> = std::iter::once(oriented.exterior())
        .chain(oriented.interiors())
        .map(open_ring)
        .collect();
    if open.iter().any(|r| r.len() < 3) {
        return polygon.clone();
    }
    let mut rings = Rings::new(&open);
    let max_turn = params.max_turn_angle_deg.to_radians();
    // Each pass scans every vertex once; stop when a pass changes nothing.
    for _ in 0..64 {
        let mut changed = false;
        for r in 0..rings.len.len() {
            let (mut v, mut advanced) = (rings.head[r], 0);
            while advanced < rings.len[r] && rings.len[r] > 3 {
                let after = rings.next[v];
                if try_remove_vertex(&mut rings, v, max_turn) {
                    (v, changed) = (after, true);
                } else if try_remove_edge(&mut rings, v, params.max_edge_shift_m) {
                    changed = true;
                } else {
                    (v, advanced) = (after, advanced + 1);
                }
            }
        }
        if !changed {
            break;
        }
    }
    let mut rings = rings.into_rings().into_iter().map(close_ring);
    let Some(exterior) = rings.next() else {
        return polygon.clone();
    };
    let simplified = Polygon::new(exterior, rings.collect());
    let ok = check_multipolygon(&MultiPolygon::new(vec![simplified.clone()])).is_ok()
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

type VertexItem = GeomWithData<[f64; 2], usize>;
type EdgeItem = GeomWithData<RLine<[f64; 2]>, usize>;

/// The rings as linked lists of vertex nodes, with R-trees of the vertices and of the edges
/// (keyed by their first node), so that the emptiness and crossing tests of a step look at the
/// neighbourhood of its triangle instead of every vertex: a pass costs O(n log n), not O(n²).
struct Rings {
    pos: Vec<Coord<f64>>,
    next: Vec<usize>,
    prev: Vec<usize>,
    head: Vec<usize>,
    len: Vec<usize>,
    ring_of: Vec<usize>,
    vertices: RTree<VertexItem>,
    edges: RTree<EdgeItem>,
}

impl Rings {
    fn new(rings: &[Vec<Coord<f64>>]) -> Self {
        let (mut pos, mut next, mut prev, mut ring_of) = (vec![], vec![], vec![], vec![]);
        let (mut head, mut len) = (vec![], vec![]);
        for (r, ring) in rings.iter().enumerate() {
            let (base, n) = (pos.len(), ring.len());
            head.push(base);
            len.push(n);
            for (i, &c) in ring.iter().enumerate() {
                pos.push(c);
                next.push(base + (i + 1) % n);
                prev.push(base + (i + n - 1) % n);
                ring_of.push(r);
            }
        }
        let vertices = RTree::bulk_load(
            (0..pos.len())
                .map(|v| VertexItem::new(pos[v].x_y().into(), v))
                .collect(),
        );
        let mut rings = Self {
            pos,
            next,
            prev,
            head,
            len,
            ring_of,
            vertices,
            edges: RTree::new(),
        };
        rings.edges = RTree::bulk_load((0..rings.pos.len()).map(|v| rings.edge_item(v)).collect());
        rings
    }

    fn edge_item(&self, v: usize) -> EdgeItem {
        let (a, b) = (self.pos[v], self.pos[self.next[v]]);
        EdgeItem::new(RLine::new(a.x_y().into(), b.x_y().into()), v)
    }

    fn vertex_item(&self, v: usize) -> VertexItem {
        VertexItem::new(self.pos[v].x_y().into(), v)
    }

    /// Unlinks node `v`: its neighbours are joined by one edge.
    fn remove(&mut self, v: usize) {
        let (p, q) = (self.prev[v], self.next[v]);
        self.vertices.remove(&self.vertex_item(v));
        self.edges.remove(&self.edge_item(p));
        self.edges.remove(&self.edge_item(v));
        (self.next[p], self.prev[q]) = (q, p);
        self.edges.insert(self.edge_item(p));
        let r = self.ring_of[v];
        self.len[r] -= 1;
        if self.head[r] == v {
            self.head[r] = q;
        }
    }

    /// Moves node `a` to `to` and unlinks its successor `b`.
    fn replace_edge(&mut self, a: usize, to: Coord<f64>) {
        let (p, b) = (self.prev[a], self.next[a]);
        let q = self.next[b];
        self.vertices.remove(&self.vertex_item(a));
        self.vertices.remove(&self.vertex_item(b));
        for e in [p, a, b] {
            self.edges.remove(&self.edge_item(e));
        }
        self.pos[a] = to;
        (self.next[a], self.prev[q]) = (q, a);
        self.vertices.insert(self.vertex_item(a));
        self.edges.insert(self.edge_item(p));
        self.edges.insert(self.edge_item(a));
        let r = self.ring_of[b];
        self.len[r] -= 1;
        if self.head[r] == b {
            self.head[r] = a;
        }
    }

    fn into_rings(self) -> Vec<Vec<Coord<f64>>> {
        (0..self.head.len())
            .map(|r| {
                let mut v = self.head[r];
                (0..self.len[r])
                    .map(|_| {
                        let c = self.pos[v];
                        v = self.next[v];
                        c
                    })
                    .collect()
            })
            .collect()
    }

    /// Whether no vertex (other than the nodes listed) lies in or on the closed triangle.
    fn triangle_is_empty(&self, t: [Coord<f64>; 3], except: &[usize]) -> bool {
        let [a, b, c] = t;
        let ccw = orient(a, b, c) > 0.0;
        let envelope = AABB::from_points(&[a, b, c].map(|p| <[f64; 2]>::from(p.x_y())));
        !self.vertices.locate_in_envelope(envelope).any(|item| {
            if except.contains(&item.data) {
                return false;
            }
            let w = self.pos[item.data];
            let (o1, o2, o3) = (orient(a, b, w), orient(b, c, w), orient(c, a, w));
            if ccw {
                o1 >= 0.0 && o2 >= 0.0 && o3 >= 0.0
            } else {
                o1 <= 0.0 && o2 <= 0.0 && o3 <= 0.0
            }
        })
    }

    /// Whether segment p–q touches any ring edge, except the edges starting at the listed
    /// nodes (the ones it replaces or shares an endpoint with) and their neighbours at the
    /// shared endpoints.
    fn crosses_any(&self, p: Coord<f64>, q: Coord<f64>, except: &[usize]) -> bool {
        let envelope = AABB::from_corners(p.x_y().into(), q.x_y().into());
        self.edges
            .locate_in_envelope_intersecting(envelope)
            .any(|item| {
                if except.contains(&item.data) {
                    return false;
                }
                let (a, b) = (self.pos[item.data], self.pos[self.next[item.data]]);
                // Edges sharing an endpoint with p–q meet it there by construction; they only
                // matter if they overlap it, which the orientation tests catch as collinear.
                let shares = a == p || a == q || b == p || b == q;
                segments_touch(p, q, a, b, shares)
            })
    }
}

/// Redundant vertex removal at node `v`.
fn try_remove_vertex(rings: &mut Rings, v: usize, max_turn_rad: f64) -> bool {
    let (ip, iq) = (rings.prev[v], rings.next[v]);
    let (p, c, q) = (rings.pos[ip], rings.pos[v], rings.pos[iq]);
    let o = orient(p, c, q);
    if o < 0.0 {
        return false; // reflex: removing it would add area
    }
    if o > 0.0 {
        let (d1, d2) = (c - p, q - c);
        let turn = (d1.x * d2.y - d1.y * d2.x).atan2(d1.x * d2.x + d1.y * d2.y);
        if turn.is_nan() || turn.abs() >= max_turn_rad {
            return false;
        }
        // The cut-off triangle must hold no other vertex and the new edge cross nothing.
        if !rings.triangle_is_empty([p, c, q], &[ip, v, iq]) || rings.crosses_any(p, q, &[ip, v]) {
            return false;
        }
    }
    rings.remove(v);
    true
}

/// Redundant edge removal of the edge from node `ia` to its successor.
fn try_remove_edge(rings: &mut Rings, ia: usize, max_shift_m: f64) -> bool {
    let r = rings.ring_of[ia];
    if rings.len[r] < 4 {
        return false;
    }
    let (ip, ib) = (rings.prev[ia], rings.next[ia]);
    let iq = rings.next[ib];
    let [p, a, b, q] = [ip, ia, ib, iq].map(|v| rings.pos[v]);
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
    if !rings.triangle_is_empty([a, v, b], &[ia, ib])
        || rings.crosses_any(p, v, &[ip, ia, ib])
        || rings.crosses_any(v, q, &[ia, ib, iq])
    {
        return false;
    }
    rings.replace_edge(ia, v);
    true
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
