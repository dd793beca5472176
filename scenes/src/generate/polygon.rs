//! Convex polygons with tagged edges: clipping by half-planes and per-edge insets.
//!
//! Blocks, lots and the levels of the generated buildings are all convex, so a half-plane
//! clip (one Sutherland–Hodgman stage) is exact and cheap, and an inset by per-edge distances is
//! the intersection of the shifted edge half-planes. Each edge carries a tag saying whether it
//! faces a street, so that front setbacks and side gaps differ.

use geo::{Coord, LineString, Polygon};

/// Coordinates of generated geometry are snapped to this grid (metres), which is also the
/// precision the GeoJSON writer prints; snapping in the model keeps a written city equal to
/// the in-memory one.
pub const GRID_M: f64 = 0.01;
/// Points of a clipped polygon closer than this (metres) are merged.
const MERGE_M: f64 = 1e-6;
/// Vertices closer than this to the previous one (metres) are dropped when converting to
/// `geo`, so that snapping to [`GRID_M`] can never fold an edge.
const MIN_EDGE_M: f64 = 0.05;

/// What an edge of a block, lot or level faces.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum EdgeTag {
    /// A street: front setbacks apply.
    Frontage,
    /// A neighbouring lot or a cut made by the generator: side gaps apply.
    Side,
}

/// A convex polygon, counter-clockwise, without the closing point. `tags[k]` belongs to the
/// edge from `pts[k]` to `pts[k + 1]`.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct ConvexPoly {
    pub pts: Vec<Coord<f64>>,
    pub tags: Vec<EdgeTag>,
}

pub(crate) fn dot(a: Coord<f64>, b: Coord<f64>) -> f64 {
    a.x * b.x + a.y * b.y
}

pub(crate) fn cross(a: Coord<f64>, b: Coord<f64>) -> f64 {
    a.x * b.y - a.y * b.x
}

pub(crate) fn length(a: Coord<f64>) -> f64 {
    dot(a, a).sqrt()
}

/// `a` turned a quarter counter-clockwise.
pub(crate) fn perp(a: Coord<f64>) -> Coord<f64> {
    Coord { x: -a.y, y: a.x }
}

impl ConvexPoly {
    /// A polygon from counter-clockwise, strictly convex corners, or `None` when the corners
    /// are not (too few, clockwise, reflex or folded).
    pub fn from_corners(pts: Vec<Coord<f64>>, tag: EdgeTag) -> Option<ConvexPoly> {
        let poly = ConvexPoly {
            tags: vec![tag; pts.len()],
            pts,
        };
        (poly.pts.len() >= 3 && poly.is_strictly_convex()).then_some(poly)
    }

    pub fn len(&self) -> usize {
        self.pts.len()
    }

    /// The edge `k` as `(from, to)`.
    pub fn edge(&self, k: usize) -> (Coord<f64>, Coord<f64>) {
        (self.pts[k], self.pts[(k + 1) % self.pts.len()])
    }

    /// Every turn is a left turn.
    fn is_strictly_convex(&self) -> bool {
        let n = self.pts.len();
        (0..n).all(|k| {
            let a = self.pts[k];
            let b = self.pts[(k + 1) % n];
            let c = self.pts[(k + 2) % n];
            cross(b - a, c - b) > 0.0
        })
    }

    /// Shoelace area (square metres; positive for counter-clockwise).
    pub fn area_m2(&self) -> f64 {
        let n = self.pts.len();
        0.5 * (0..n)
            .map(|k| cross(self.pts[k], self.pts[(k + 1) % n]))
            .sum::<f64>()
    }

    pub fn perimeter_m(&self) -> f64 {
        (0..self.len())
            .map(|k| {
                let (a, b) = self.edge(k);
                length(b - a)
            })
            .sum()
    }

    /// Radius of a disc of the same area-to-perimeter ratio (exact for squares and discs,
    /// half the short side for long rectangles): a cheap measure of how thick the polygon is.
    pub fn thickness_m(&self) -> f64 {
        2.0 * self.area_m2() / self.perimeter_m().max(f64::MIN_POSITIVE)
    }

    /// Vertex average (inside, as the polygon is convex).
    pub fn centre(&self) -> Coord<f64> {
        let n = self.pts.len() as f64;
        let sum = self
            .pts
            .iter()
            .fold(Coord { x: 0.0, y: 0.0 }, |s, p| s + *p);
        sum / n
    }

    /// Total length of the edges that face a street (metres).
    pub fn frontage_m(&self) -> f64 {
        (0..self.len())
            .filter(|&k| self.tags[k] == EdgeTag::Frontage)
            .map(|k| {
                let (a, b) = self.edge(k);
                length(b - a)
            })
            .sum()
    }

    /// The part where `normal · p ≥ offset`; the new edge along the clip line gets `tag`.
    /// `None` when nothing of positive area is left.
    pub fn clip(&self, normal: Coord<f64>, offset: f64, tag: EdgeTag) -> Option<ConvexPoly> {
        let n = self.pts.len();
        let mut pts = Vec::with_capacity(n + 1);
        let mut tags = Vec::with_capacity(n + 1);
        let mut push = |p: Coord<f64>, t: EdgeTag, pts: &mut Vec<Coord<f64>>| {
            if let Some(last) = pts.last()
                && length(p - *last) < MERGE_M
            {
                // Keep the later tag: the edge leaving the merged point is the new one.
                *tags.last_mut().expect("tags follow points") = t;
                return;
            }
            pts.push(p);
            tags.push(t);
        };
        for k in 0..n {
            let (a, b) = self.edge(k);
            let da = dot(normal, a) - offset;
            let db = dot(normal, b) - offset;
            if da >= 0.0 {
                push(a, self.tags[k], &mut pts);
                if db < 0.0 {
                    let p = a + (b - a) * (da / (da - db));
                    push(p, tag, &mut pts);
                }
            } else if db >= 0.0 {
                let p = a + (b - a) * (da / (da - db));
                push(p, self.tags[k], &mut pts);
            }
        }
        if pts.len() >= 2 && length(pts[0] - pts[pts.len() - 1]) < MERGE_M {
            pts.pop();
            let t = tags.pop().expect("tags follow points");
            tags[0] = if tags[0] == t { t } else { tags[0] };
        }
        let poly = ConvexPoly { pts, tags };
        (poly.pts.len() >= 3 && poly.area_m2() > 1e-6).then_some(poly)
    }

    /// The part at least `distance_m` inside the line through edge `k`.
    pub fn clip_edge(
        &self,
        a: Coord<f64>,
        b: Coord<f64>,
        distance_m: f64,
        tag: EdgeTag,
    ) -> Option<ConvexPoly> {
        let d = b - a;
        let len = length(d);
        if len <= 0.0 {
            return Some(self.clone());
        }
        let normal = perp(d) / len;
        self.clip(normal, dot(normal, a) + distance_m, tag)
    }

    /// Shrinks the polygon by a distance per edge (metres), chosen from the edge's tag.
    pub fn inset(&self, frontage_m: f64, side_m: f64) -> Option<ConvexPoly> {
        let mut out = self.clone();
        for k in 0..self.len() {
            let (a, b) = self.edge(k);
            let tag = self.tags[k];
            let d = match tag {
                EdgeTag::Frontage => frontage_m,
                EdgeTag::Side => side_m,
            };
            out = out.clip_edge(a, b, d, tag)?;
        }
        Some(out)
    }

    /// The polygon as a closed `geo` ring on the [`GRID_M`] grid, counter-clockwise, with
    /// near-duplicate and collinear vertices removed; `None` if it degenerates.
    pub fn to_ring(&self) -> Option<LineString<f64>> {
        let mut pts: Vec<Coord<f64>> = Vec::with_capacity(self.len() + 1);
        for p in &self.pts {
            let q = snap(*p);
            if pts.last().is_none_or(|l| length(q - *l) >= MIN_EDGE_M) {
                pts.push(q);
            }
        }
        while pts.len() >= 2 && length(pts[0] - pts[pts.len() - 1]) < MIN_EDGE_M {
            pts.pop();
        }
        // Drop vertices where the ring does not turn (or turns back) after snapping.
        let mut k = 0;
        while pts.len() >= 3 && k < pts.len() {
            let n = pts.len();
            let a = pts[(k + n - 1) % n];
            let b = pts[k];
            let c = pts[(k + 1) % n];
            if cross(b - a, c - b) <= 1e-9 {
                pts.remove(k);
                k = k.saturating_sub(1);
            } else {
                k += 1;
            }
        }
        if pts.len() < 3 {
            return None;
        }
        pts.push(pts[0]);
        let ring = LineString::new(pts);
        let area = Polygon::new(ring.clone(), vec![]);
        (geo::Area::signed_area(&area) >= 1.0).then_some(ring)
    }
}

/// Rounds a point to the [`GRID_M`] grid.
pub(crate) fn snap(p: Coord<f64>) -> Coord<f64> {
    Coord {
        x: (p.x / GRID_M).round() * GRID_M,
        y: (p.y / GRID_M).round() * GRID_M,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(x: f64, y: f64) -> Coord<f64> {
        Coord { x, y }
    }

    fn square(s: f64) -> ConvexPoly {
        ConvexPoly::from_corners(
            vec![c(0.0, 0.0), c(s, 0.0), c(s, s), c(0.0, s)],
            EdgeTag::Frontage,
        )
        .unwrap()
    }

    #[test]
    fn clip_halves_a_square_and_tags_the_cut() {
        let sq = square(10.0);
        let right = sq.clip(c(1.0, 0.0), 4.0, EdgeTag::Side).unwrap();
        assert!((right.area_m2() - 60.0).abs() < 1e-9);
        assert_eq!(right.len(), 4);
        assert_eq!(
            right.tags.iter().filter(|t| **t == EdgeTag::Side).count(),
            1
        );
        assert!((right.frontage_m() - 6.0 - 10.0 - 6.0).abs() < 1e-9);
        assert!(sq.clip(c(1.0, 0.0), 11.0, EdgeTag::Side).is_none());
    }

    #[test]
    fn inset_uses_the_tag_distances() {
        let sq = square(10.0);
        let cut = sq.clip(c(-1.0, 0.0), -5.0, EdgeTag::Side).unwrap(); // x <= 5
        let inner = cut.inset(2.0, 1.0).unwrap();
        // Frontage on three sides moves 2 m, the side cut 1 m: x in [2, 4], y in [2, 8].
        assert!(
            (inner.area_m2() - 2.0 * 6.0).abs() < 1e-9,
            "{}",
            inner.area_m2()
        );
        assert!(square(3.0).inset(2.0, 2.0).is_none());
    }

    #[test]
    fn rejects_reflex_and_clockwise_corners() {
        let cw = vec![c(0.0, 0.0), c(0.0, 1.0), c(1.0, 1.0), c(1.0, 0.0)];
        assert!(ConvexPoly::from_corners(cw, EdgeTag::Side).is_none());
        let dart = vec![c(0.0, 0.0), c(4.0, 0.0), c(1.0, 1.0), c(0.0, 4.0)];
        assert!(ConvexPoly::from_corners(dart, EdgeTag::Side).is_none());
    }

    #[test]
    fn ring_is_snapped_closed_and_drops_near_duplicates() {
        let p = ConvexPoly::from_corners(
            vec![
                c(0.004, 0.0),
                c(10.0, 0.0),
                c(10.001, 0.001),
                c(10.0, 10.0),
                c(0.0, 10.0),
            ],
            EdgeTag::Side,
        )
        .unwrap();
        let ring = p.to_ring().unwrap();
        assert_eq!(ring.0.len(), 5, "{ring:?}");
        assert_eq!(ring.0[0], ring.0[4]);
        assert_eq!(ring.0[0], c(0.0, 0.0));
    }
}
