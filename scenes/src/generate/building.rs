//! Buildings on lots: the massing forms and their Z-levels.
//!
//! Each lot is first shrunk by a front setback (deep front yards at the periphery, none in the
//! centre) and by half a side gap on each shared edge, so neighbouring buildings never touch.
//! The form is drawn by intensity:
//! - low-rise: one part on the whole lot;
//! - stepped: 2–4 stacked levels, each set back on all sides from the one below;
//! - podium with tower: a 3–5 storey podium on the lot and a tower set back on top;
//! - courtyard block: a perimeter block with an inner courtyard (a hole);
//! - L- and U-shapes: a street wing and one or two rear wings of their own heights;
//! - landmark: podium, shaft and crown, 3–8× the local typical height.
//!
//! Stacked levels are separate parts whose footprints nest: each level lies inside the one
//! below and starts where it ends. Wings are separate ground parts; the building's footprint
//! is the union of its ground parts.

use std::collections::BTreeMap;

use geo::{BooleanOps, Coord, LineString, MapCoords, MultiPolygon, Polygon, RemoveRepeatedPoints};
use rand::RngExt;
use rand_chacha::ChaCha8Rng;

use super::polygon::{ConvexPoly, EdgeTag, dot, length, perp, snap};
use crate::city::{Building, BuildingId, BuildingPart, HeightSource};

/// The massing form of a generated building.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Form {
    LowRise,
    Stepped,
    PodiumTower,
    Courtyard,
    LShape,
    UShape,
    Landmark,
}

impl Form {
    /// The name written to the `form` property and the `citywalk:form` tag.
    pub fn name(self) -> &'static str {
        match self {
            Form::LowRise => "low_rise",
            Form::Stepped => "stepped",
            Form::PodiumTower => "podium_tower",
            Form::Courtyard => "courtyard",
            Form::LShape => "l_shape",
            Form::UShape => "u_shape",
            Form::Landmark => "landmark",
        }
    }
}

/// What a lot knows about its surroundings.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Site {
    /// Urban intensity in `[0, 1]`.
    pub intensity: f64,
    /// Typical height here (metres).
    pub typical_height_m: f64,
}

/// A building before it is numbered: its form, outline and parts `(footprint, base, top)`.
#[derive(Debug, Clone)]
pub(crate) struct Plan {
    pub form: Form,
    pub footprint: MultiPolygon<f64>,
    pub parts: Vec<(MultiPolygon<f64>, f32, f32)>,
}

impl Plan {
    /// The model building with id `index`.
    pub fn into_building(self, index: usize) -> Building {
        let source_id = format!("b{index}");
        let single = self.parts.len() == 1;
        let top_m = self.parts.iter().map(|p| p.2).fold(f32::MIN, f32::max);
        let parts = self
            .parts
            .into_iter()
            .enumerate()
            .map(|(k, (footprint, base_m, top_m))| BuildingPart {
                source_id: if single {
                    source_id.clone()
                } else {
                    format!("{source_id}/p{k}")
                },
                footprint,
                base_m,
                top_m,
            })
            .collect();
        let mut tags = BTreeMap::new();
        tags.insert("building".to_owned(), "yes".to_owned());
        tags.insert("citywalk:form".to_owned(), self.form.name().to_owned());
        if self.form == Form::Landmark {
            tags.insert("landmark".to_owned(), "yes".to_owned());
        }
        Building {
            id: BuildingId(index as u32),
            source_id,
            footprint: self.footprint,
            parts,
            base_m: 0.0,
            top_m,
            height_source: HeightSource::Tagged,
            mesh: None,
            tags: tags.into(),
        }
    }
}

/// The largest lot for a site (square metres): house plots at the periphery, large plots for
/// towers and perimeter blocks in the centre.
pub(crate) fn max_lot_m2(intensity: f64, rng: &mut ChaCha8Rng) -> f64 {
    (560.0 + 2_500.0 * intensity.powf(1.5)) * rng.random_range(0.75..1.25)
}

/// Smallest footprint of a building or a level (square metres).
const MIN_LEVEL_M2: f64 = 30.0;
/// Smallest lot that may carry a landmark unless one is overdue (square metres).
pub(crate) const MIN_LANDMARK_LOT_M2: f64 = 300.0;

/// A height rounded to decimetres, as stored and written.
fn h(metres: f64) -> f32 {
    ((metres.max(0.0) * 10.0).round() / 10.0) as f32
}

fn single(poly: &ConvexPoly) -> Option<MultiPolygon<f64>> {
    Some(MultiPolygon::new(vec![Polygon::new(
        poly.to_ring()?,
        vec![],
    )]))
}

/// Plans a building on `lot`, or `None` when the lot is too small after setbacks.
pub(crate) fn plan(
    lot: &ConvexPoly,
    site: &Site,
    landmark: bool,
    rng: &mut ChaCha8Rng,
) -> Option<Plan> {
    let i = site.intensity.clamp(0.0, 1.0);
    let open = (1.0 - i) * (1.0 - i);
    let front_m = if landmark {
        1.0
    } else {
        4.5 * open * rng.random_range(0.5..1.2)
    };
    let side_m = 0.3 + 1.4 * open;
    let region = lot.inset(front_m, side_m)?;
    if region.area_m2() < MIN_LEVEL_M2 {
        return None;
    }
    let t = site.typical_height_m;
    if landmark {
        return landmark_tower(&region, t, rng);
    }
    let r: f64 = rng.random();
    let form = if i > 0.45 {
        match r {
            _ if r < 0.45 => Form::PodiumTower,
            _ if r < 0.65 => Form::Stepped,
            _ if r < 0.82 => Form::Courtyard,
            _ if r < 0.92 => Form::LShape,
            _ => Form::LowRise,
        }
    } else if i > 0.12 {
        match r {
            _ if r < 0.2 => Form::Courtyard,
            _ if r < 0.42 => Form::Stepped,
            _ if r < 0.6 => Form::LShape,
            _ if r < 0.68 => Form::UShape,
            _ if r < 0.76 => Form::PodiumTower,
            _ => Form::LowRise,
        }
    } else {
        match r {
            _ if r < 0.2 => Form::LShape,
            _ if r < 0.25 => Form::UShape,
            _ if r < 0.52 => Form::Stepped,
            _ => Form::LowRise,
        }
    };
    let planned = match form {
        Form::Stepped => stepped(&region, t, rng),
        Form::PodiumTower => podium_tower(&region, t, rng),
        Form::Courtyard => courtyard(&region, t, rng),
        Form::LShape => wings(&region, t, false, rng),
        Form::UShape => wings(&region, t, true, rng),
        Form::LowRise | Form::Landmark => None,
    };
    planned.or_else(|| low_rise(&region, t, rng))
}

fn low_rise(region: &ConvexPoly, t: f64, rng: &mut ChaCha8Rng) -> Option<Plan> {
    let fp = single(region)?;
    let top = h((t * rng.random_range(0.65..1.4)).max(3.5));
    Some(Plan {
        form: Form::LowRise,
        footprint: fp.clone(),
        parts: vec![(fp, 0.0, top)],
    })
}

/// Stacks `levels` (ground first) between the given tops; stops at the first level that
/// degenerates and needs at least two.
fn stack(form: Form, levels: &[ConvexPoly], tops_m: &[f64]) -> Option<Plan> {
    let mut parts = Vec::new();
    let mut base = 0.0_f32;
    for (level, top) in levels.iter().zip(tops_m) {
        let Some(fp) = single(level) else { break };
        let top = h(*top).max(base + 1.0);
        parts.push((fp, base, top));
        base = top;
    }
    if parts.len() < 2 {
        return None;
    }
    Some(Plan {
        form,
        footprint: parts[0].0.clone(),
        parts,
    })
}

fn stepped(region: &ConvexPoly, t: f64, rng: &mut ChaCha8Rng) -> Option<Plan> {
    let count = rng.random_range(2..=4usize);
    let total = (t * rng.random_range(0.9..1.5)).max(8.0);
    let step_m = rng
        .random_range(2.0..4.5_f64)
        .min(region.thickness_m() * 0.3);
    let mut levels = vec![region.clone()];
    for l in 1..count {
        let inner = region.inset(step_m * l as f64, step_m * l as f64);
        match inner {
            Some(p) if p.area_m2() >= MIN_LEVEL_M2 => levels.push(p),
            _ => break,
        }
    }
    let n = levels.len();
    let tops: Vec<f64> = (0..n)
        .map(|l| {
            if n == 1 {
                total
            } else {
                total * (0.5 + 0.5 * l as f64 / (n - 1) as f64)
            }
        })
        .collect();
    stack(Form::Stepped, &levels, &tops)
}

fn podium_tower(region: &ConvexPoly, t: f64, rng: &mut ChaCha8Rng) -> Option<Plan> {
    let podium = rng.random_range(8.0..16.0);
    let tower = region.inset(rng.random_range(5.0..10.0), rng.random_range(3.0..6.0))?;
    if tower.area_m2() < 100.0 {
        return None;
    }
    let top = (t * rng.random_range(1.0..1.8)).max(podium + 12.0);
    stack(Form::PodiumTower, &[region.clone(), tower], &[podium, top])
}

fn courtyard(region: &ConvexPoly, t: f64, rng: &mut ChaCha8Rng) -> Option<Plan> {
    if region.area_m2() < 700.0 || region.thickness_m() < 12.0 {
        return None;
    }
    let depth = rng
        .random_range(8.0..13.0_f64)
        .min(region.thickness_m() * 0.6);
    let yard = region.inset(depth, depth)?;
    if yard.area_m2() < 60.0 {
        return None;
    }
    let outer = region.to_ring()?;
    let mut hole = yard.to_ring()?;
    hole.0.reverse();
    let fp = MultiPolygon::new(vec![Polygon::new(outer, vec![hole])]);
    let top = h((t * rng.random_range(0.75..1.15)).max(6.0));
    Some(Plan {
        form: Form::Courtyard,
        footprint: fp.clone(),
        parts: vec![(fp, 0.0, top)],
    })
}

/// An L (one rear wing) or U (two rear wings) on the region's longest street edge.
fn wings(region: &ConvexPoly, t: f64, two: bool, rng: &mut ChaCha8Rng) -> Option<Plan> {
    let front = (0..region.len())
        .filter(|&k| region.tags[k] == EdgeTag::Frontage)
        .max_by(|&a, &b| {
            let (a0, a1) = region.edge(a);
            let (b0, b1) = region.edge(b);
            length(a1 - a0).total_cmp(&length(b1 - b0))
        })?;
    let (a, b) = region.edge(front);
    let u = (b - a) / length(b - a);
    let v = perp(u);
    let (mut u_lo, mut u_hi, mut v_hi) = (f64::MAX, f64::MIN, 0.0_f64);
    for p in &region.pts {
        let d = *p - a;
        u_lo = u_lo.min(dot(u, d));
        u_hi = u_hi.max(dot(u, d));
        v_hi = v_hi.max(dot(v, d));
    }
    let width = u_hi - u_lo;
    if v_hi < 12.0 || width < if two { 15.0 } else { 8.0 } {
        return None;
    }
    let split = dot(v, a) + v_hi * rng.random_range(0.35..0.55);
    let street_wing = region.clip(v * -1.0, -split, EdgeTag::Side)?;
    let rear = region.clip(v, split, EdgeTag::Side)?;
    let origin = dot(u, a);
    let left = |share: f64| rear.clip(u * -1.0, -(origin + u_lo + width * share), EdgeTag::Side);
    let right = |share: f64| rear.clip(u, origin + u_hi - width * share, EdgeTag::Side);
    let rear_wings: Vec<ConvexPoly> = if two {
        vec![
            left(rng.random_range(0.25..0.35))?,
            right(rng.random_range(0.25..0.35))?,
        ]
    } else if rng.random_bool(0.5) {
        vec![left(rng.random_range(0.35..0.6))?]
    } else {
        vec![right(rng.random_range(0.35..0.6))?]
    };
    if std::iter::once(&street_wing)
        .chain(&rear_wings)
        .any(|w| w.area_m2() < MIN_LEVEL_M2)
    {
        return None;
    }
    let street_top = (t * rng.random_range(0.7..1.3)).max(4.0);
    // The rear wings meet the street wing's back edge at points that are not its corners:
    // they become vertices of the street wing too, so that after snapping every wing shares
    // exact vertices with its neighbour and the union has no slivers.
    let junctions: Vec<Coord<f64>> = rear_wings
        .iter()
        .flat_map(|w| w.pts.iter().copied())
        .filter(|p| (dot(v, *p) - split).abs() < 1e-6)
        .collect();
    let street_ring = ring_through(&street_wing.pts, &junctions)?;
    let mut parts = vec![(
        MultiPolygon::new(vec![Polygon::new(street_ring, vec![])]),
        0.0,
        h(street_top),
    )];
    for w in &rear_wings {
        let top = (street_top * rng.random_range(0.6..1.0)).max(3.5);
        parts.push((single(w)?, 0.0, h(top)));
    }
    let mut outline = parts[0].0.clone();
    for p in &parts[1..] {
        outline = outline.union(&p.0);
    }
    let outline = snap_all(&outline);
    // Boolean output is checked here rather than trusted: wings that do not union into one
    // valid polygon fall back to a plain building.
    if outline.0.len() != 1 || crate::validate::check_multipolygon(&outline).is_err() {
        return None;
    }
    Some(Plan {
        form: if two { Form::UShape } else { Form::LShape },
        footprint: outline,
        parts,
    })
}

/// A landmark: a podium, a shaft set back on it and a slimmer crown, `3.2..8` times the local
/// typical height `t` (capped at 850 m).
fn landmark_tower(region: &ConvexPoly, t: f64, rng: &mut ChaCha8Rng) -> Option<Plan> {
    let top = (t * rng.random_range(3.2..8.0)).min(850.0);
    let podium = rng.random_range(12.0..24.0_f64).min(top * 0.3);
    let shaft = region.inset(region.thickness_m() * 0.3, region.thickness_m() * 0.3);
    let Some(shaft) = shaft.filter(|s| s.area_m2() >= MIN_LEVEL_M2) else {
        let fp = single(region)?;
        return Some(Plan {
            form: Form::Landmark,
            footprint: fp.clone(),
            parts: vec![(fp, 0.0, h(top))],
        });
    };
    let crown = shaft
        .inset(shaft.thickness_m() * 0.35, shaft.thickness_m() * 0.35)
        .filter(|c| c.area_m2() >= MIN_LEVEL_M2 * 0.5);
    let mut plan = match crown {
        Some(crown) => stack(
            Form::Landmark,
            &[region.clone(), shaft, crown],
            &[podium, top * 0.85, top],
        ),
        None => stack(Form::Landmark, &[region.clone(), shaft], &[podium, top]),
    }?;
    plan.form = Form::Landmark;
    Some(plan)
}

/// The closed ring through `corners` (counter-clockwise) with the `extra` points that lie on
/// its edges inserted in order, snapped to the grid, near-duplicates dropped. Collinear points
/// are kept on purpose.
fn ring_through(corners: &[Coord<f64>], extra: &[Coord<f64>]) -> Option<LineString<f64>> {
    let n = corners.len();
    let mut pts: Vec<Coord<f64>> = Vec::with_capacity(n + extra.len() + 1);
    for k in 0..n {
        let a = corners[k];
        let b = corners[(k + 1) % n];
        pts.push(a);
        let d = b - a;
        let len2 = dot(d, d);
        if len2 <= 0.0 {
            continue;
        }
        let mut on: Vec<(f64, Coord<f64>)> = extra
            .iter()
            .filter_map(|p| {
                let t = dot(*p - a, d) / len2;
                let off = (*p - (a + d * t)).x.hypot((*p - (a + d * t)).y);
                (t > 1e-9 && t < 1.0 - 1e-9 && off < 1e-6).then_some((t, *p))
            })
            .collect();
        on.sort_by(|x, y| x.0.total_cmp(&y.0));
        pts.extend(on.into_iter().map(|(_, p)| p));
    }
    let mut ring: Vec<Coord<f64>> = Vec::with_capacity(pts.len() + 1);
    for p in pts {
        let q = snap(p);
        if ring.last().is_none_or(|l| length(q - *l) >= 0.05) {
            ring.push(q);
        }
    }
    while ring.len() >= 2 && length(ring[0] - ring[ring.len() - 1]) < 0.05 {
        ring.pop();
    }
    if ring.len() < 3 {
        return None;
    }
    ring.push(ring[0]);
    let ring = LineString::new(ring);
    (geo::Area::signed_area(&Polygon::new(ring.clone(), vec![])) >= 1.0).then_some(ring)
}

/// Snaps every coordinate to the output grid and drops repeated points.
fn snap_all(mp: &MultiPolygon<f64>) -> MultiPolygon<f64> {
    let snapped: MultiPolygon<f64> = mp.map_coords(|c: Coord<f64>| snap(c));
    let cleaned = snapped.remove_repeated_points();
    MultiPolygon::new(
        cleaned
            .0
            .into_iter()
            .filter(|p| p.exterior().0.len() >= 4)
            .map(|p| {
                let (ext, holes) = p.into_inner();
                let holes: Vec<LineString<f64>> =
                    holes.into_iter().filter(|r| r.0.len() >= 4).collect();
                Polygon::new(ext, holes)
            })
            .collect(),
    )
}

#[cfg(test)]
mod tests {
    use geo::{Area, BooleanOps};
    use rand::SeedableRng;

    use super::*;
    use crate::validate::check_multipolygon;

    fn lot(w: f64, d: f64) -> ConvexPoly {
        let c = |x, y| Coord { x, y };
        let mut p = ConvexPoly::from_corners(
            vec![c(0.0, 0.0), c(w, 0.0), c(w, d), c(0.0, d)],
            EdgeTag::Side,
        )
        .unwrap();
        p.tags[0] = EdgeTag::Frontage;
        p
    }

    fn check(plan: &Plan) {
        check_multipolygon(&plan.footprint).unwrap();
        let outline = plan.footprint.unsigned_area();
        for (k, (fp, base, top)) in plan.parts.iter().enumerate() {
            check_multipolygon(fp).unwrap();
            assert!(top > base, "{plan:?}");
            let inside = fp.intersection(&plan.footprint).unsigned_area();
            assert!(
                (inside - fp.unsigned_area()).abs() < 1e-3,
                "part {k} leaves the outline"
            );
            if *base > 0.0 {
                let below = &plan.parts[k - 1];
                assert_eq!(below.2, *base);
                let on = fp.intersection(&below.0).unsigned_area();
                assert!((on - fp.unsigned_area()).abs() < 1e-3);
            }
        }
        assert!(outline > 0.0);
    }

    #[test]
    fn every_form_is_valid_and_nested() {
        let mut rng = ChaCha8Rng::seed_from_u64(9);
        let region = lot(40.0, 50.0);
        let t = 30.0;
        let plans = [
            stepped(&region, t, &mut rng).unwrap(),
            podium_tower(&region, t, &mut rng).unwrap(),
            courtyard(&region, t, &mut rng).unwrap(),
            wings(&region, t, false, &mut rng).unwrap(),
            wings(&region, t, true, &mut rng).unwrap(),
            landmark_tower(&region, t, &mut rng).unwrap(),
            low_rise(&region, t, &mut rng).unwrap(),
        ];
        for p in &plans {
            check(p);
        }
        assert_eq!(plans[2].footprint.0[0].interiors().len(), 1);
        assert!(plans[3].footprint.unsigned_area() < region.area_m2() - 1.0);
        assert!(plans[5].parts.iter().map(|p| p.2).fold(0.0, f32::max) >= 96.0);
        let b = plans[5].clone().into_building(7);
        assert_eq!(b.source_id, "b7");
        assert_eq!(b.tags.get("landmark"), Some("yes"));
        assert_eq!(b.parts[1].source_id, "b7/p1");
    }

    #[test]
    fn tiny_lots_get_nothing_or_something_valid() {
        let mut rng = ChaCha8Rng::seed_from_u64(3);
        let site = Site {
            intensity: 0.1,
            typical_height_m: 8.0,
        };
        assert!(plan(&lot(4.0, 4.0), &site, false, &mut rng).is_none());
        for _ in 0..50 {
            if let Some(p) = plan(&lot(15.0, 25.0), &site, false, &mut rng) {
                check(&p);
            }
        }
    }
}
