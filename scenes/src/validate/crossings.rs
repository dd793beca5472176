//! Where a footprint's rings meet, found in O(n log n) for footprints whose edges are short
//! against the footprint (every real one), and within a stated budget for any other.
//!
//! Sort and sweep (Chen & Chan 2003, as `geo::algorithm::sweep`): the edges are sorted by their
//! smallest x, and each is tested against the later edges whose x-interval starts before its
//! own ends (with exact orientations, `robust::orient2d`). `geo`'s OGC validation instead tests
//! every pair of a ring's edges, which takes minutes on a 40,000-vertex stadium. The sweep
//! stops at the first `max_contacts` contacts or `max_crossings` proper crossings, so a ring
//! crossing itself everywhere (a star) costs no more than a few crossings; and after `max_pairs` tested pairs it gives up
//! ([`TooComplex`]), which the callers turn into a rejection with that reason.

use geo::Coord;
use robust::{Coord as RCoord, orient2d};

/// The sweep tested more candidate pairs than its budget: the edges overlap far more than any
/// footprint's (long edges criss-crossing one another).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct TooComplex {
    pub edges: usize,
    pub pairs_tested: usize,
}

/// Two edges that meet other than where consecutive edges of one ring share their vertex.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Contact {
    /// The rings of the two edges (equal when a ring meets itself).
    pub rings: (usize, usize),
    /// The edges cross at a point inside both; otherwise they touch or overlap.
    pub proper: bool,
}

/// The budget of candidate pairs for `edges` edges: many times what a footprint needs (a
/// smooth 40,000-vertex ring tests about three pairs per edge).
pub fn pair_budget(edges: usize) -> usize {
    64 * edges + 1_000_000
}

/// The contacts between the edges of `rings` (each closed: first point equal to the last, as
/// `geo::LineString` rings are), up to `max_contacts` of them or `max_crossings` proper
/// crossings, or [`TooComplex`] after `max_pairs` pairs.
pub fn contacts(
    rings: &[&[Coord<f64>]],
    max_contacts: usize,
    max_crossings: usize,
    max_pairs: usize,
) -> Result<Vec<Contact>, TooComplex> {
    struct Edge {
        ring: usize,
        index: usize,
        a: Coord<f64>,
        b: Coord<f64>,
        x0: f64,
        x1: f64,
    }
    let mut edges = Vec::new();
    let mut ring_edges = Vec::with_capacity(rings.len());
    for (ring, coords) in rings.iter().enumerate() {
        let n = coords.len().saturating_sub(1);
        ring_edges.push(n);
        for index in 0..n {
            let (a, b) = (coords[index], coords[index + 1]);
            edges.push(Edge {
                ring,
                index,
                a,
                b,
                x0: a.x.min(b.x),
                x1: a.x.max(b.x),
            });
        }
    }
    edges.sort_unstable_by(|e, f| e.x0.total_cmp(&f.x0));
    let mut found = Vec::new();
    let (mut pairs_tested, mut crossings) = (0usize, 0usize);
    for (i, e) in edges.iter().enumerate() {
        for f in edges[i + 1..].iter().take_while(|f| f.x0 <= e.x1) {
            pairs_tested += 1;
            if pairs_tested > max_pairs {
                return Err(TooComplex {
                    edges: edges.len(),
                    pairs_tested,
                });
            }
            if e.a.y.max(e.b.y) < f.a.y.min(f.b.y) || f.a.y.max(f.b.y) < e.a.y.min(e.b.y) {
                continue;
            }
            let n = ring_edges[e.ring];
            let consecutive = e.ring == f.ring
                && n > 2
                && ((e.index + 1) % n == f.index || (f.index + 1) % n == e.index);
            let contact = if consecutive {
                // They share one vertex; only folding back over each other (a spike) counts.
                overlap_beyond_shared(e.a, e.b, f.a, f.b).then_some(false)
            } else {
                touch(e.a, e.b, f.a, f.b)
            };
            if let Some(proper) = contact {
                found.push(Contact {
                    rings: (e.ring, f.ring),
                    proper,
                });
                crossings += usize::from(proper);
                if found.len() >= max_contacts || crossings >= max_crossings {
                    return Ok(found);
                }
            }
        }
    }
    Ok(found)
}

fn orient(a: Coord<f64>, b: Coord<f64>, c: Coord<f64>) -> f64 {
    orient2d(
        RCoord { x: a.x, y: a.y },
        RCoord { x: b.x, y: b.y },
        RCoord { x: c.x, y: c.y },
    )
}

/// For collinear `u`: whether it lies on the closed segment `p`–`q`.
fn on_segment(p: Coord<f64>, q: Coord<f64>, u: Coord<f64>) -> bool {
    u.x >= p.x.min(q.x) && u.x <= p.x.max(q.x) && u.y >= p.y.min(q.y) && u.y <= p.y.max(q.y)
}

/// Whether closed segments p–q and a–b meet: `Some(true)` when they cross at a point inside
/// both, `Some(false)` when they touch or overlap, `None` when they are apart.
fn touch(p: Coord<f64>, q: Coord<f64>, a: Coord<f64>, b: Coord<f64>) -> Option<bool> {
    let (o1, o2) = (orient(p, q, a), orient(p, q, b));
    let (o3, o4) = (orient(a, b, p), orient(a, b, q));
    if o1 * o2 < 0.0 && o3 * o4 < 0.0 {
        return Some(true);
    }
    let touches = (o1 == 0.0 && on_segment(p, q, a))
        || (o2 == 0.0 && on_segment(p, q, b))
        || (o3 == 0.0 && on_segment(a, b, p))
        || (o4 == 0.0 && on_segment(a, b, q));
    touches.then_some(false)
}

/// For segments sharing an endpoint: whether they are collinear and overlap beyond it.
fn overlap_beyond_shared(p: Coord<f64>, q: Coord<f64>, a: Coord<f64>, b: Coord<f64>) -> bool {
    if orient(p, q, a) != 0.0 || orient(p, q, b) != 0.0 {
        return false;
    }
    let inside =
        |s0: Coord<f64>, s1: Coord<f64>, u: Coord<f64>| u != s0 && u != s1 && on_segment(s0, s1, u);
    inside(p, q, a) || inside(p, q, b) || inside(a, b, p) || inside(a, b, q)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn ring(points: &[(f64, f64)]) -> Vec<Coord<f64>> {
        let mut v: Vec<Coord<f64>> = points.iter().map(|&(x, y)| Coord { x, y }).collect();
        v.push(v[0]);
        v
    }

    #[test]
    fn a_square_has_no_contacts_and_a_bow_tie_one_crossing() {
        let square = ring(&[(0.0, 0.0), (1.0, 0.0), (1.0, 1.0), (0.0, 1.0)]);
        assert_eq!(contacts(&[&square], 8, 8, 1_000), Ok(vec![]));
        let bow = ring(&[(0.0, 0.0), (1.0, 1.0), (1.0, 0.0), (0.0, 1.0)]);
        assert_eq!(
            contacts(&[&bow], 8, 8, 1_000),
            Ok(vec![Contact {
                rings: (0, 0),
                proper: true
            }])
        );
    }

    #[test]
    fn a_spike_a_pinch_and_touching_rings_are_contacts() {
        let spike = ring(&[(0.0, 0.0), (2.0, 0.0), (1.0, 0.0), (1.0, 1.0)]);
        assert!(!contacts(&[&spike], 8, 8, 1_000).unwrap().is_empty());
        let pinch = ring(&[
            (0.0, 0.0),
            (1.0, 1.0),
            (2.0, 0.0),
            (2.0, 2.0),
            (1.0, 1.0),
            (0.0, 2.0),
        ]);
        assert!(!contacts(&[&pinch], 8, 8, 1_000).unwrap().is_empty());
        let outer = ring(&[(0.0, 0.0), (4.0, 0.0), (4.0, 4.0), (0.0, 4.0)]);
        let hole = ring(&[(0.0, 2.0), (1.0, 1.0), (1.0, 3.0)]);
        let c = contacts(&[&outer, &hole], 8, 8, 1_000).unwrap();
        assert!(c.iter().all(|c| c.rings == (0, 1) || c.rings == (1, 0)));
        assert!(!c.is_empty() && c.iter().all(|c| !c.proper));
    }

    #[test]
    fn a_star_stops_at_the_contact_limit_and_the_pair_budget_holds() {
        let n = 3001;
        let k = 1500;
        let star: Vec<(f64, f64)> = (0..n)
            .map(|i| {
                let t = std::f64::consts::TAU * (i * k % n) as f64 / n as f64;
                (t.cos(), t.sin())
            })
            .collect();
        let star = ring(&star);
        assert_eq!(
            contacts(&[&star], 5, usize::MAX, usize::MAX).unwrap().len(),
            5
        );
        let crossings = contacts(&[&star], usize::MAX, 5, usize::MAX).unwrap();
        assert_eq!(crossings.iter().filter(|c| c.proper).count(), 5);
        assert!(contacts(&[&star], usize::MAX, usize::MAX, 10_000).is_err());
    }
}
