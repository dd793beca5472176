//! Z-level identification (Germs & Jansen §3.2).
//!
//! Upward-facing triangles are clustered by height with a low tolerance T_z, so that extra
//! levels appear; then, from the bottom up, each level L2 is compared with the kept level L1
//! below it by its occlusion benefit
//!
//! ```text
//! B_{2,1} = Z2 · P_n + (Z2 − Z1) · P_i
//! ```
//!
//! where P_n and P_i are the perimeters of the convex hulls of the parts of L2 that do not /
//! do intersect L1 (in 2D), and heights are measured from the occluder base. L2 "adds
//! significantly" if B_{2,1} > T_B · A1 with A1 = P1 · Z1 (P1 the perimeter of the convex hull
//! of L1). Then: B high and ΔZ = Z2 − Z1 high → keep both; B high and ΔZ small → merge; B low
//! → delete L2. The paper's defaults are not given; see [`super::OccluderParams`].
//!
//! Hull perimeters are summed over the connected parts (each part its own hull), as in the
//! paper's Fig. 3, where the intersecting and non-intersecting parts are hulled separately.
//!
//! With citywalk's conservative footprints (see the module doc of [`super`]), a level's
//! footprint is everything at least that tall, so L1's footprint already covers L2's and
//! P_n is zero unless an overhang cut L1; merging L2 into L1 (at the conservative height Z1)
//! and deleting L2 then give the same facade — L2's area stays covered by L1 at Z1 — and the
//! two decisions differ only in what is reported.

use geo::{Area, BooleanOps, ConvexHull, Euclidean, Length, MultiPolygon};

use super::OccluderParams;

/// One candidate Z-level: its (conservative) height and footprint region.
#[derive(Debug, Clone, PartialEq)]
pub struct LevelCandidate {
    /// Height of the level (metres, local frame): the lowest point of its triangles.
    pub z_m: f64,
    /// Ground region under which the building is at least `z_m` tall (holes kept).
    pub region: MultiPolygon<f64>,
}

/// What the occlusion-benefit rule decided for a level.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub enum LevelDecision {
    /// The level gets its own facade.
    Keep,
    /// Significant benefit, but too close to the level below: merged into it.
    Merge,
    /// Too little benefit: deleted.
    Delete,
}

/// Clusters heights with tolerance `tolerance_m` (§3.2 step 2: "all polygons in a Z-level are
/// at the same height within a tolerance T_z"): sorted ascending, a level starts at the lowest
/// unassigned height and takes every height within `tolerance_m` above it. Returns the
/// levels' lowest heights, ascending. Non-finite heights are ignored.
pub fn cluster_heights(heights_m: &[f64], tolerance_m: f64) -> Vec<f64> {
    let mut sorted: Vec<f64> = heights_m
        .iter()
        .copied()
        .filter(|h| h.is_finite())
        .collect();
    sorted.sort_by(f64::total_cmp);
    let mut levels = Vec::new();
    let mut start: Option<f64> = None;
    for h in sorted {
        match start {
            Some(s) if h - s <= tolerance_m => {}
            _ => {
                levels.push(h);
                start = Some(h);
            }
        }
    }
    levels
}

/// Sum of the perimeters of the convex hulls of the polygons of `mp`.
pub fn hull_perimeter_m(mp: &MultiPolygon<f64>) -> f64 {
    mp.0.iter()
        .map(|p| Euclidean.length(p.convex_hull().exterior()))
        .sum()
}

/// The occlusion benefit B_{2,1} of level `upper` over level `lower` (§3.2 steps 1–4),
/// heights measured from `base_m`.
pub fn occlusion_benefit(lower: &LevelCandidate, upper: &LevelCandidate, base_m: f64) -> f64 {
    let z1 = lower.z_m - base_m;
    let z2 = upper.z_m - base_m;
    let intersecting = upper.region.intersection(&lower.region);
    let non_intersecting = upper.region.difference(&lower.region);
    let p_i = hull_perimeter_m(&drop_slivers(intersecting));
    let p_n = hull_perimeter_m(&drop_slivers(non_intersecting));
    z2 * p_n + (z2 - z1) * p_i
}

/// Boolean operations leave slivers of rounding size along shared edges; they are not parts.
fn drop_slivers(mp: MultiPolygon<f64>) -> MultiPolygon<f64> {
    const SLIVER_M2: f64 = 1e-3;
    MultiPolygon::new(
        mp.0.into_iter()
            .filter(|p| p.unsigned_area() > SLIVER_M2)
            .collect(),
    )
}

/// Applies the occlusion-benefit rule (§3.2 step 3 and steps 1–5 of the benefit) from the
/// bottom up: the lowest level is kept; each higher level is compared with the last kept one.
/// `levels` must be sorted by height, ascending. Returns one decision per level.
pub fn select_levels(
    levels: &[LevelCandidate],
    base_m: f64,
    params: &OccluderParams,
) -> Vec<LevelDecision> {
    let mut decisions = Vec::with_capacity(levels.len());
    let mut last_kept: Option<&LevelCandidate> = None;
    for level in levels {
        let decision = match last_kept {
            None => LevelDecision::Keep,
            Some(lower) => {
                let benefit = occlusion_benefit(lower, level, base_m);
                let a1 = hull_perimeter_m(&lower.region) * (lower.z_m - base_m);
                if benefit <= params.benefit_threshold * a1 {
                    LevelDecision::Delete
                } else if level.z_m - lower.z_m < params.merge_delta_z_m {
                    LevelDecision::Merge
                } else {
                    LevelDecision::Keep
                }
            }
        };
        if decision == LevelDecision::Keep {
            last_kept = Some(level);
        }
        decisions.push(decision);
    }
    decisions
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{Rect, coord};

    fn rect(x0: f64, y0: f64, x1: f64, y1: f64) -> MultiPolygon<f64> {
        MultiPolygon::new(vec![
            Rect::new(coord! {x: x0, y: y0}, coord! {x: x1, y: y1}).to_polygon(),
        ])
    }

    fn level(z_m: f64, region: MultiPolygon<f64>) -> LevelCandidate {
        LevelCandidate { z_m, region }
    }

    #[test]
    fn clustering_respects_the_tolerance() {
        let levels = cluster_heights(&[10.0, 3.0, 10.2, 3.4, 10.6, f64::NAN, 25.0], 0.5);
        assert_eq!(levels, vec![3.0, 10.0, 10.6, 25.0]);
        assert!(cluster_heights(&[], 0.5).is_empty());
    }

    #[test]
    fn benefit_matches_the_formula_for_nested_and_disjoint_levels() {
        // L1: 20 × 20 at 10 m; L2 a 4 × 4 tower inside at 30 m: P_i = 16, P_n = 0.
        let l1 = level(10.0, rect(0.0, 0.0, 20.0, 20.0));
        let tower = level(30.0, rect(8.0, 8.0, 12.0, 12.0));
        let b = occlusion_benefit(&l1, &tower, 0.0);
        assert!((b - 20.0 * 16.0).abs() < 1e-9, "{b}");
        // A disjoint L2 (4 × 4 beside L1) at 30 m: P_n = 16, P_i = 0.
        let beside = level(30.0, rect(30.0, 0.0, 34.0, 4.0));
        let b = occlusion_benefit(&l1, &beside, 0.0);
        assert!((b - 30.0 * 16.0).abs() < 1e-9, "{b}");
        // Base offset: heights are measured from the base.
        let b = occlusion_benefit(&l1, &tower, 5.0);
        assert!((b - 20.0 * 16.0).abs() < 1e-9, "{b}");
    }

    #[test]
    fn a_small_chimney_level_is_deleted() {
        // A 20 × 20 house roof at 10 m; a 1 × 1 chimney top at 11.5 m:
        // B = 1.5 · 4 = 6, A1 = 80 · 10 = 800, T_B · A1 = 120 → delete.
        let params = OccluderParams::default();
        let levels = [
            level(10.0, rect(0.0, 0.0, 20.0, 20.0)),
            level(11.5, rect(5.0, 5.0, 6.0, 6.0)),
        ];
        assert_eq!(
            select_levels(&levels, 0.0, &params),
            vec![LevelDecision::Keep, LevelDecision::Delete]
        );
    }

    #[test]
    fn a_tall_tower_level_is_kept() {
        // A 30 × 30 podium at 8 m; a 12 × 12 tower at 60 m: B = 52 · 48 = 2496,
        // A1 = 120 · 8 = 960 → significant, ΔZ = 52 m → keep.
        let params = OccluderParams::default();
        let levels = [
            level(8.0, rect(0.0, 0.0, 30.0, 30.0)),
            level(60.0, rect(9.0, 9.0, 21.0, 21.0)),
        ];
        assert_eq!(
            select_levels(&levels, 0.0, &params),
            vec![LevelDecision::Keep, LevelDecision::Keep]
        );
    }

    #[test]
    fn close_heights_are_merged() {
        // Two halves of a roof at 10 m and 11 m. L1 covers 20 × 10 (everything ≥ 10 m), L2 the
        // half 10 × 10 at 11 m: B = 1 · 40 = 40, A1 = 60 · 10 = 600. With T_B = 0.05 the level
        // is significant (40 > 30) and ΔZ = 1 m < 2 m merges it.
        let params = OccluderParams {
            benefit_threshold: 0.05,
            ..OccluderParams::default()
        };
        let levels = [
            level(10.0, rect(0.0, 0.0, 20.0, 10.0)),
            level(11.0, rect(10.0, 0.0, 20.0, 10.0)),
        ];
        assert_eq!(
            select_levels(&levels, 0.0, &params),
            vec![LevelDecision::Keep, LevelDecision::Merge]
        );
        // The same pair 5 m apart is kept.
        let levels = [
            level(10.0, rect(0.0, 0.0, 20.0, 10.0)),
            level(15.0, rect(10.0, 0.0, 20.0, 10.0)),
        ];
        assert_eq!(
            select_levels(&levels, 0.0, &params),
            vec![LevelDecision::Keep, LevelDecision::Keep]
        );
    }

    #[test]
    fn later_levels_compare_with_the_last_kept_level() {
        // Podium 8 m, chimney 9 m (deleted), tower 60 m compared with the podium (kept).
        let params = OccluderParams::default();
        let levels = [
            level(8.0, rect(0.0, 0.0, 30.0, 30.0)),
            level(9.0, rect(1.0, 1.0, 2.0, 2.0)),
            level(60.0, rect(9.0, 9.0, 21.0, 21.0)),
        ];
        assert_eq!(
            select_levels(&levels, 0.0, &params),
            vec![
                LevelDecision::Keep,
                LevelDecision::Delete,
                LevelDecision::Keep
            ]
        );
    }
}
