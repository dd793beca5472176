//! Subdivision of a block into lots along its street frontage.
//!
//! Parish & Müller, "Procedural Modeling of Cities", SIGGRAPH 2001, §4.2 (Division into lots):
//! a block is split recursively across its longest edge, near the middle, until the pieces are
//! below a target area; pieces without street access are discarded. The target area and the
//! spread of the split position (0.38..0.62 of the edge) are this generator's own choices; the
//! target comes from the district's intensity (small lots at the periphery, large ones in the
//! centre, see `super::building`).

use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::polygon::{ConvexPoly, EdgeTag, dot, length};

/// Pieces smaller than this are not lots (square metres).
const MIN_LOT_M2: f64 = 60.0;
/// A lot needs at least this much street frontage (metres).
const MIN_FRONTAGE_M: f64 = 4.0;
/// Recursion guard: 2^24 lots per block is far beyond any target area.
const MAX_DEPTH: usize = 24;

/// Splits `block` into lots of at most `max_lot_m2` (square metres), keeping only lots with
/// street frontage. The order is deterministic for a given random stream.
pub(crate) fn subdivide(
    block: &ConvexPoly,
    max_lot_m2: f64,
    rng: &mut ChaCha8Rng,
) -> Vec<ConvexPoly> {
    let mut lots = Vec::new();
    let mut stack = vec![(block.clone(), 0usize)];
    while let Some((poly, depth)) = stack.pop() {
        let area = poly.area_m2();
        if area < MIN_LOT_M2 {
            continue;
        }
        if area <= max_lot_m2 || depth >= MAX_DEPTH {
            if poly.frontage_m() >= MIN_FRONTAGE_M {
                lots.push(poly);
            }
            continue;
        }
        // Across the longest edge, unless that leaves a half without frontage and a shorter
        // edge does not (the "approximately parallel" edges of Parish & Müller).
        let mut order: Vec<usize> = (0..poly.len()).collect();
        order.sort_by(|&a, &b| {
            let (a0, a1) = poly.edge(a);
            let (b0, b1) = poly.edge(b);
            length(b1 - b0).total_cmp(&length(a1 - a0))
        });
        if order.is_empty() {
            continue;
        }
        let t = rng.random_range(0.38..0.62);
        let mut chosen = None;
        let edge_m = |k: usize| {
            let (a, b) = poly.edge(k);
            length(b - a)
        };
        let longest_m = edge_m(order[0]);
        for &k in order.iter().take_while(|&&k| edge_m(k) >= 0.4 * longest_m) {
            let Some(halves) = split_across(&poly, k, t) else {
                continue;
            };
            let fronted = halves
                .iter()
                .all(|h| h.as_ref().is_none_or(|h| h.frontage_m() >= MIN_FRONTAGE_M));
            if chosen.is_none() || fronted {
                chosen = Some(halves);
            }
            if fronted {
                break;
            }
        }
        let Some([front, back]) = chosen else {
            continue;
        };
        // Pushed in reverse so lots come out in order along the edge.
        for half in [front, back].into_iter().flatten() {
            stack.push((half, depth + 1));
        }
    }
    lots
}

/// The two halves of `poly` cut perpendicular to edge `k` at the fraction `t` along it.
fn split_across(poly: &ConvexPoly, k: usize, t: f64) -> Option<[Option<ConvexPoly>; 2]> {
    let (a, b) = poly.edge(k);
    let along = b - a;
    let len = length(along);
    if len <= 0.0 {
        return None;
    }
    let direction = along / len;
    let cut = dot(direction, a + along * t);
    Some([
        poly.clip(direction, cut, EdgeTag::Side),
        poly.clip(direction * -1.0, -cut, EdgeTag::Side),
    ])
}

#[cfg(test)]
mod tests {
    use geo::Coord;
    use rand::SeedableRng;

    use super::*;

    #[test]
    fn lots_tile_the_block_and_face_a_street() {
        let c = |x, y| Coord { x, y };
        let block = ConvexPoly::from_corners(
            vec![c(0.0, 0.0), c(150.0, 0.0), c(150.0, 60.0), c(0.0, 60.0)],
            EdgeTag::Frontage,
        )
        .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(1);
        let lots = subdivide(&block, 600.0, &mut rng);
        assert!(lots.len() >= 15, "{}", lots.len());
        let total: f64 = lots.iter().map(ConvexPoly::area_m2).sum();
        // A 60 m deep block is two lots deep: almost every piece reaches a street.
        assert!(total > 0.9 * 150.0 * 60.0, "{total}");
        assert!(
            lots.iter()
                .all(|l| l.area_m2() <= 600.0 && l.frontage_m() >= 4.0)
        );
    }

    #[test]
    fn interior_pieces_of_deep_blocks_are_dropped() {
        let c = |x, y| Coord { x, y };
        let block = ConvexPoly::from_corners(
            vec![c(0.0, 0.0), c(200.0, 0.0), c(200.0, 200.0), c(0.0, 200.0)],
            EdgeTag::Frontage,
        )
        .unwrap();
        let mut rng = ChaCha8Rng::seed_from_u64(2);
        let lots = subdivide(&block, 300.0, &mut rng);
        let total: f64 = lots.iter().map(ConvexPoly::area_m2).sum();
        assert!(total < 200.0 * 200.0 - 1_000.0, "{total}");
        assert!(lots.iter().all(|l| l.frontage_m() >= 4.0));
    }
}
