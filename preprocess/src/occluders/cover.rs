//! Whether a segment lies wholly in a region (geo's `covers` of a line by a multipolygon, the
//! region closed), with the region's boundary edges in an R-tree built once per region.
//!
//! geo's `relate` labels a whole geometry graph per call, O(n) in the region's vertex count
//! even when prepared; a facade asks it once per footprint edge and candidate level, so a mesh
//! building of thousands of vertices took minutes (issue 14 case 5). Here a query costs the
//! R-tree searches and the k boundary edges near the segment: the segment is cut where it meets
//! the boundary, and it is covered iff the midpoint of every piece is in the region (on an edge,
//! or inside by the crossing number of a ray to +x, half-open in y). Orientations go through
//! `robust::orient2d`; crossing points through geo's `line_intersection` (robust kernel).

use geo::line_intersection::{LineIntersection, line_intersection};
use geo::{Coord, Line, MultiPolygon};
use robust::{Coord as RCoord, orient2d};
use rstar::primitives::Line as RLine;
use rstar::{AABB, RTree};

/// A region's boundary, indexed for [`RegionCover::covers`].
#[derive(Debug, Clone)]
pub struct RegionCover {
    edges: RTree<RLine<[f64; 2]>>,
    /// Largest x of the boundary: where the point-in-region ray ends.
    max_x: f64,
}

impl RegionCover {
    /// Indexes every ring (exteriors and holes) of `region`, whose polygons must not overlap
    /// (a union or difference result): the crossing parity then gives inside and outside.
    pub fn new(region: &MultiPolygon<f64>) -> RegionCover {
        let mut edges = Vec::new();
        let mut max_x = f64::NEG_INFINITY;
        for polygon in region {
            for ring in std::iter::once(polygon.exterior()).chain(polygon.interiors()) {
                for line in ring.lines() {
                    if line.start == line.end {
                        continue;
                    }
                    max_x = max_x.max(line.start.x).max(line.end.x);
                    edges.push(RLine::new(
                        [line.start.x, line.start.y],
                        [line.end.x, line.end.y],
                    ));
                }
            }
        }
        RegionCover {
            edges: RTree::bulk_load(edges),
            max_x,
        }
    }

    /// Whether every point of segment `a`–`b` is in the closed region.
    pub fn covers(&self, a: Coord<f64>, b: Coord<f64>) -> bool {
        if !(a.x.is_finite() && a.y.is_finite() && b.x.is_finite() && b.y.is_finite()) {
            return false;
        }
        if a == b {
            return self.contains(a);
        }
        let segment = Line::new(a, b);
        let d = b - a;
        let length2 = d.x * d.x + d.y * d.y;
        let param = |p: Coord<f64>| (((p - a).x * d.x + (p - a).y * d.y) / length2).clamp(0.0, 1.0);
        let mut cuts = vec![0.0, 1.0];
        let envelope =
            AABB::from_corners([a.x.min(b.x), a.y.min(b.y)], [a.x.max(b.x), a.y.max(b.y)]);
        for edge in self.edges.locate_in_envelope_intersecting(envelope) {
            let edge = Line::new(Coord::from(edge.from), Coord::from(edge.to));
            match line_intersection(segment, edge) {
                Some(LineIntersection::SinglePoint { intersection, .. }) => {
                    cuts.push(param(intersection));
                }
                Some(LineIntersection::Collinear { intersection }) => {
                    cuts.push(param(intersection.start));
                    cuts.push(param(intersection.end));
                }
                None => {}
            }
        }
        cuts.sort_by(f64::total_cmp);
        cuts.dedup();
        cuts.windows(2).all(|w| {
            let t = 0.5 * (w[0] + w[1]);
            self.contains(a + d * t)
        })
    }

    /// Whether `p` is in the closed region: on a boundary edge, or an odd number of edges cross
    /// the ray from `p` to +x (an edge counts when its end points lie on either side of the
    /// ray's line, one of them possibly on it and below: each vertex is counted once).
    fn contains(&self, p: Coord<f64>) -> bool {
        if p.x.is_nan() || p.x > self.max_x {
            return false;
        }
        let ray = AABB::from_corners([p.x, p.y], [self.max_x, p.y]);
        let at = RCoord { x: p.x, y: p.y };
        let mut inside = false;
        for edge in self.edges.locate_in_envelope_intersecting(ray) {
            let (s, e) = (edge.from, edge.to);
            let side = orient2d(RCoord { x: s[0], y: s[1] }, RCoord { x: e[0], y: e[1] }, at);
            let within = s[0].min(e[0]) <= p.x
                && p.x <= s[0].max(e[0])
                && s[1].min(e[1]) <= p.y
                && p.y <= s[1].max(e[1]);
            if side == 0.0 && within {
                return true;
            }
            // Upward edges pass right of p when p is on their left; downward ones when on
            // their right.
            if (s[1] > p.y) != (e[1] > p.y) && (e[1] > s[1]) == (side > 0.0) {
                inside = !inside;
            }
        }
        inside
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{Relate, coord, polygon};

    fn c(x: f64, y: f64) -> Coord<f64> {
        coord! { x: x, y: y }
    }

    /// An L-shaped building with a courtyard, and a separate square.
    fn region() -> MultiPolygon<f64> {
        MultiPolygon::new(vec![
            polygon!(
                exterior: [(x: 0., y: 0.), (x: 20., y: 0.), (x: 20., y: 10.), (x: 10., y: 10.),
                           (x: 10., y: 20.), (x: 0., y: 20.), (x: 0., y: 0.)],
                interiors: [[(x: 2., y: 2.), (x: 2., y: 6.), (x: 6., y: 6.), (x: 6., y: 2.),
                             (x: 2., y: 2.)]],
            ),
            polygon![(x: 30., y: 0.), (x: 35., y: 0.), (x: 35., y: 5.), (x: 30., y: 5.)],
        ])
    }

    #[test]
    fn boundary_pieces_concave_corners_holes_and_gaps() {
        let cover = RegionCover::new(&region());
        // Along the boundary, inside, across the concave corner, across the courtyard.
        assert!(cover.covers(c(0., 0.), c(20., 0.)));
        assert!(cover.covers(c(5., 0.), c(15., 0.)));
        assert!(cover.covers(c(7., 1.), c(19., 9.)));
        assert!(!cover.covers(c(1., 1.), c(19., 9.)));
        assert!(!cover.covers(c(19., 9.), c(9., 19.)));
        assert!(cover.covers(c(12., 8.), c(8., 12.)));
        assert!(!cover.covers(c(1., 4.), c(8., 4.)));
        assert!(cover.covers(c(2., 2.), c(6., 2.)));
        // Between the two polygons, and from one to the other.
        assert!(!cover.covers(c(20., 1.), c(30., 1.)));
        assert!(!cover.covers(c(19., 1.), c(31., 1.)));
        assert!(cover.covers(c(30., 0.), c(35., 5.)));
        // Touching the region from outside at one vertex only.
        assert!(!cover.covers(c(25., 15.), c(10., 10.)));
        // A point.
        assert!(cover.covers(c(10., 10.), c(10., 10.)));
        assert!(!cover.covers(c(4., 4.), c(4., 4.)));
    }

    /// The same answers as geo's `relate(..).is_covers()` on random segments, many of them
    /// through the region's vertices (seeded).
    #[test]
    fn agrees_with_geo_relate() {
        let region = region();
        let cover = RegionCover::new(&region);
        let vertices: Vec<Coord<f64>> = region
            .0
            .iter()
            .flat_map(|p| std::iter::once(p.exterior()).chain(p.interiors()))
            .flat_map(|r| r.0.iter().copied())
            .collect();
        // splitmix64, seeded: a fixed sequence of cases.
        let mut state = 14u64;
        let mut next = |n: u64| {
            state = state.wrapping_add(0x9e37_79b9_7f4a_7c15);
            let mut z = state;
            z = (z ^ (z >> 30)).wrapping_mul(0xbf58_476d_1ce4_e5b9);
            z = (z ^ (z >> 27)).wrapping_mul(0x94d0_49bb_1331_11eb);
            (z ^ (z >> 31)) % n
        };
        let mut checked = 0;
        for i in 0..4000 {
            let mut pick = || {
                if next(5) < 2 {
                    vertices[next(vertices.len() as u64) as usize]
                } else {
                    // Whole and half metres land on edges and their lines.
                    c(next(84) as f64 * 0.5 - 2.0, next(52) as f64 * 0.5 - 2.0)
                }
            };
            let (a, b) = (pick(), pick());
            if a == b {
                continue;
            }
            checked += 1;
            let expected = region.relate(&Line::new(a, b)).is_covers();
            assert_eq!(cover.covers(a, b), expected, "case {i}: {a:?} -> {b:?}");
        }
        assert!(checked > 3000);
    }
}
