//! Validation and repair of building footprints and heights, shared by every loader.
//!
//! Every ring is checked on entry: finite coordinates within range, at least three distinct
//! points, non-zero area. A ring that crosses itself is repaired by re-noding it through `geo`'s
//! boolean operations (non-zero fill: a bow-tie becomes two triangles); the repair is accepted
//! only if it keeps most of the ring's area and the ring crosses itself at few points (a star
//! crossing itself everywhere would be re-noded into thousands of slivers), otherwise the
//! building is rejected. The result is a valid `geo` multipolygon (OGC rules), checked by
//! [`check_multipolygon`] in O(n log n) ([`crossings`]).

pub mod crossings;

use std::panic::{AssertUnwindSafe, catch_unwind};

use geo::{
    Area, BooleanOps, BoundingRect, Contains, Coord, LineString, MultiPolygon, Polygon,
    RemoveRepeatedPoints, Validation, Winding,
};

use crate::overlay_guard::overlay_or_reject;
use crate::report::RejectReason;
use crossings::{contacts, pair_budget};

/// Local coordinates beyond this many metres from the origin are rejected: a city spans tens of
/// kilometres, and f32 meshes lose centimetres beyond a few hundred.
pub const MAX_LOCAL_COORDINATE_M: f64 = 200_000.0;
/// Smallest footprint area kept (square metres); anything smaller is a degenerate sliver.
pub const MIN_AREA_M2: f64 = 0.01;
/// Tallest building accepted (metres); the tallest on earth is 828 m.
pub const MAX_HEIGHT_M: f32 = 1_000.0;
/// Lowest base accepted (metres below the frame's ground), for terrain and NAP offsets.
pub const MIN_BASE_M: f32 = -500.0;

/// The least extent (metres) a building or part has from base to top. Less is not a building,
/// and it keeps the extent positive when a mesh source's heights are shifted onto the ground
/// later in `f32`: a fuzzed b3dm with a part one unit in the last place tall came out of the
/// shift with its top equal to its base.
pub const MIN_HEIGHT_EXTENT_M: f32 = 0.01;
/// A self-intersecting ring is repaired only if the repair keeps this share of its area
/// (shoelace area of the original ring vs. area of the re-noded polygon).
const MIN_REPAIR_AREA_RATIO: f64 = 0.5;
/// A footprint whose rings cross (properly, inside both edges) at more points than this is
/// rejected, not re-noded: a digitising slip crosses once or twice, and re-noding costs time
/// and pieces per crossing. Rings that only touch (parts sharing walls) are always re-noded.
pub const MAX_REPAIR_CROSSINGS: usize = 64;
/// Footprints whose rings touch (at a vertex, as OGC allows a hole to touch its outer ring) are
/// judged by `geo`'s validation, which tests every pair of edges; above this many vertices such
/// a footprint is reported invalid instead (and re-noded by the loaders).
pub const MAX_TOUCHING_VERTICES: usize = 4_096;

/// A cleaned footprint and the repairs made to it (empty when none was needed).
#[derive(Debug, Clone, PartialEq)]
pub struct CleanFootprint {
    pub footprint: MultiPolygon<f64>,
    pub repairs: Vec<String>,
}

/// Cleans a footprint given as polygons of rings (the first ring of each polygon is the outer
/// one, the rest holes), in local metres. Degenerate holes are dropped with a repair note;
/// a degenerate or irreparable outer ring rejects the footprint.
pub fn clean_footprint(polygons: &[Vec<Vec<Coord<f64>>>]) -> Result<CleanFootprint, RejectReason> {
    let mut repairs = Vec::new();
    let mut out: Vec<Polygon<f64>> = Vec::new();
    if polygons.is_empty() {
        return Err(RejectReason::MissingGeometry("no polygon".into()));
    }
    for rings in polygons {
        let Some((outer, holes)) = rings.split_first() else {
            return Err(RejectReason::MissingGeometry(
                "polygon without rings".into(),
            ));
        };
        let outer = clean_ring(outer)?;
        let mut kept_holes = Vec::new();
        for (i, hole) in holes.iter().enumerate() {
            match clean_ring(hole) {
                Ok(h) => kept_holes.push(h),
                Err(reason) => repairs.push(format!("dropped hole {}: {reason}", i + 1)),
            }
        }
        let mut polygon = Polygon::new(outer, kept_holes);
        orient(&mut polygon);
        out.push(polygon);
    }
    let mut footprint = MultiPolygon::new(out);
    if check_multipolygon(&footprint).is_err() {
        let rings: Vec<&[Coord<f64>]> = rings_of(&footprint).collect();
        let edges: usize = rings.iter().map(|r| r.len() - 1).sum();
        let met = contacts(
            &rings,
            usize::MAX,
            MAX_REPAIR_CROSSINGS + 1,
            pair_budget(edges),
        )
        .map_err(|e| {
            RejectReason::InvalidGeometry(format!(
                "footprint too complex to check: {} edges overlap in more than {} pairs",
                e.edges, e.pairs_tested
            ))
        })?;
        if met.iter().filter(|c| c.proper).count() > MAX_REPAIR_CROSSINGS {
            return Err(RejectReason::InvalidGeometry(format!(
                "footprint crosses itself at more than {MAX_REPAIR_CROSSINGS} points \
                 ({edges} edges): not repaired"
            )));
        }
        let before: f64 = footprint.0.iter().map(signed_ring_area_abs).sum();
        let repaired = overlay_or_reject("the footprint repair", || renode(&footprint))?;
        let after = repaired.unsigned_area();
        if repaired.0.is_empty() || after < MIN_AREA_M2 {
            return Err(RejectReason::SelfIntersection);
        }
        if after < before * MIN_REPAIR_AREA_RATIO {
            return Err(RejectReason::SelfIntersection);
        }
        if check_multipolygon(&repaired).is_err() {
            return Err(RejectReason::SelfIntersection);
        }
        repairs.push(format!(
            "repaired invalid footprint ({:.1} m² → {:.1} m²)",
            before, after
        ));
        footprint = repaired;
    }
    if footprint.unsigned_area() < MIN_AREA_M2 {
        return Err(RejectReason::ZeroArea);
    }
    Ok(CleanFootprint { footprint, repairs })
}

/// Checks one ring: finite, in range, at least three distinct points, non-zero area. Returns
/// it closed, without repeated consecutive points.
fn clean_ring(ring: &[Coord<f64>]) -> Result<LineString<f64>, RejectReason> {
    for c in ring {
        if !(c.x.is_finite() && c.y.is_finite()) {
            return Err(RejectReason::NonFiniteCoordinate);
        }
        if c.x.abs() > MAX_LOCAL_COORDINATE_M || c.y.abs() > MAX_LOCAL_COORDINATE_M {
            return Err(RejectReason::CoordinateOutOfRange(format!(
                "({:.0}, {:.0}) m from the origin",
                c.x, c.y
            )));
        }
    }
    let mut line = LineString::new(ring.to_vec());
    line.close();
    let line = line.remove_repeated_points();
    // A closed ring of n distinct points has n + 1 coordinates.
    if line.0.len() < 4 {
        return Err(RejectReason::TooFewPoints);
    }
    let polygon = Polygon::new(line, vec![]);
    // A crossing ring (a bow-tie) can have zero signed area and still enclose some: it is left
    // to the repair in `clean_footprint`.
    if polygon.unsigned_area() < MIN_AREA_M2
        && check_valid(&MultiPolygon::new(vec![polygon.clone()])).is_ok()
    {
        return Err(RejectReason::ZeroArea);
    }
    let (line, _) = polygon.into_inner();
    Ok(line)
}

/// Outer rings counter-clockwise, holes clockwise.
fn orient(polygon: &mut Polygon<f64>) {
    polygon.exterior_mut(|r| r.make_ccw_winding());
    polygon.interiors_mut(|rs| rs.iter_mut().for_each(|r| r.make_cw_winding()));
}

fn signed_ring_area_abs(p: &Polygon<f64>) -> f64 {
    p.unsigned_area()
}

/// Re-nodes a possibly self-intersecting multipolygon into a valid one (union with nothing,
/// which resolves crossings by `geo`'s overlay).
fn renode(mp: &MultiPolygon<f64>) -> MultiPolygon<f64> {
    let mut acc = MultiPolygon::new(vec![]);
    for polygon in &mp.0 {
        let single = MultiPolygon::new(vec![polygon.clone()]);
        let fixed = single.union(&MultiPolygon::new(vec![]));
        acc = acc.union(&fixed);
    }
    acc
}

/// Checks that `base_m..top_m` is a plausible building extent.
pub fn check_heights(base_m: f32, top_m: f32) -> Result<(), RejectReason> {
    if !(base_m.is_finite() && top_m.is_finite()) {
        return Err(RejectReason::AbsurdHeight(format!(
            "non-finite ({base_m}..{top_m})"
        )));
    }
    if top_m - base_m < MIN_HEIGHT_EXTENT_M {
        return Err(RejectReason::AbsurdHeight(format!(
            "top {top_m} m not {MIN_HEIGHT_EXTENT_M} m above base {base_m} m"
        )));
    }
    if top_m > MAX_HEIGHT_M || base_m < MIN_BASE_M {
        return Err(RejectReason::AbsurdHeight(format!(
            "{base_m} m .. {top_m} m outside {MIN_BASE_M} m .. {MAX_HEIGHT_M} m"
        )));
    }
    Ok(())
}

/// Checks a footprint already in the model: valid by OGC rules and with positive area.
pub fn check_multipolygon(mp: &MultiPolygon<f64>) -> Result<(), String> {
    if mp.0.is_empty() {
        return Err("is empty".into());
    }
    check_valid(mp).map_err(|e| format!("is invalid: {e}"))?;
    if mp.unsigned_area() < MIN_AREA_M2 {
        return Err("has zero area".into());
    }
    Ok(())
}

/// The closed rings of a multipolygon, outer ring of each polygon first.
fn rings_of(mp: &MultiPolygon<f64>) -> impl Iterator<Item = &[Coord<f64>]> {
    mp.0.iter().flat_map(|p| {
        std::iter::once(p.exterior())
            .chain(p.interiors())
            .map(|r| r.0.as_slice())
    })
}

/// OGC validity in O(n log n) when no two rings meet: rings closed, finite, of three distinct
/// points, meeting nowhere ([`crossings`]); each hole inside its outer ring and outside the
/// others; no polygon's outer ring inside another polygon. Rings that do touch are judged by
/// `geo::Validation` up to [`MAX_TOUCHING_VERTICES`].
fn check_valid(mp: &MultiPolygon<f64>) -> Result<(), String> {
    let rings: Vec<&[Coord<f64>]> = rings_of(mp).collect();
    let edges: usize = rings.iter().map(|r| r.len()).sum();
    for ring in &rings {
        if ring.len() < 4 || ring.first() != ring.last() {
            return Err("a ring is not closed or has fewer than 3 points".into());
        }
        if ring.iter().any(|c| !(c.x.is_finite() && c.y.is_finite())) {
            return Err("a coordinate is not finite".into());
        }
    }
    let met = contacts(&rings, 1, 1, pair_budget(edges)).map_err(|e| {
        format!(
            "too complex to check: {} edges overlap in more than {} pairs",
            e.edges, e.pairs_tested
        )
    })?;
    if let Some(contact) = met.first() {
        if edges <= MAX_TOUCHING_VERTICES {
            // A debug assertion in geo's relate graph fires on nearly coincident edges (found
            // by fuzzing, `tests/fuzz/README.md` run 9): such a footprint is invalid with that
            // reason, never a crash.
            return catch_unwind(AssertUnwindSafe(|| mp.check_validation()))
                .map_err(|panic| {
                    let why = crate::panic_message(panic.as_ref());
                    format!("its validity cannot be decided (geo's check failed: {why})")
                })?
                .map_err(|e| e.to_string());
        }
        let (a, b) = contact.rings;
        return Err(if a == b {
            format!("ring {a} meets itself")
        } else {
            format!("rings {a} and {b} meet")
        });
    }
    // No ring meets another: each lies wholly inside or outside each other ring, which its
    // first vertex tells (after a test of bounding boxes, so that P parts cost P² box tests).
    let boxes: Vec<Vec<geo::Rect<f64>>> =
        mp.0.iter()
            .map(|p| {
                std::iter::once(p.exterior())
                    .chain(p.interiors())
                    .filter_map(|r| r.bounding_rect())
                    .collect()
            })
            .collect();
    let inside = |ring: &LineString<f64>, rect: &geo::Rect<f64>, c: Coord<f64>| {
        rect.contains(&c) && Polygon::new(ring.clone(), vec![]).contains(&c)
    };
    for (i, polygon) in mp.0.iter().enumerate() {
        let (holes, rects) = (polygon.interiors(), &boxes[i]);
        for (h, hole) in holes.iter().enumerate() {
            if !inside(polygon.exterior(), &rects[0], hole.0[0]) {
                return Err(format!(
                    "hole {h} of polygon {i} lies outside its outer ring"
                ));
            }
            if let Some(g) = (0..h).find(|&g| {
                inside(&holes[g], &rects[g + 1], hole.0[0])
                    || inside(hole, &rects[h + 1], holes[g].0[0])
            }) {
                return Err(format!("holes {g} and {h} of polygon {i} are nested"));
            }
        }
    }
    let in_polygon = |k: usize, c: Coord<f64>| {
        let p = &mp.0[k];
        inside(p.exterior(), &boxes[k][0], c)
            && !p
                .interiors()
                .iter()
                .zip(&boxes[k][1..])
                .any(|(h, r)| inside(h, r, c))
    };
    for i in 0..mp.0.len() {
        for j in 0..i {
            if !geo::Intersects::intersects(&boxes[i][0], &boxes[j][0]) {
                continue;
            }
            if in_polygon(i, mp.0[j].exterior().0[0]) || in_polygon(j, mp.0[i].exterior().0[0]) {
                return Err(format!("polygons {j} and {i} overlap"));
            }
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    fn c(x: f64, y: f64) -> Coord<f64> {
        Coord { x, y }
    }

    fn square(s: f64) -> Vec<Coord<f64>> {
        vec![c(0.0, 0.0), c(s, 0.0), c(s, s), c(0.0, s)]
    }

    #[test]
    fn clean_square_passes() {
        let f = clean_footprint(&[vec![square(10.0)]]).unwrap();
        assert!(f.repairs.is_empty());
        assert!((f.footprint.unsigned_area() - 100.0).abs() < 1e-9);
    }

    #[test]
    fn rejects_each_degenerate_case() {
        let nan = vec![c(0.0, 0.0), c(f64::NAN, 0.0), c(1.0, 1.0)];
        assert_eq!(
            clean_footprint(&[vec![nan]]),
            Err(RejectReason::NonFiniteCoordinate)
        );
        let two = vec![c(0.0, 0.0), c(1.0, 0.0), c(1.0, 0.0), c(0.0, 0.0)];
        assert_eq!(
            clean_footprint(&[vec![two]]),
            Err(RejectReason::TooFewPoints)
        );
        let line = vec![c(0.0, 0.0), c(1.0, 0.0), c(2.0, 0.0)];
        assert_eq!(clean_footprint(&[vec![line]]), Err(RejectReason::ZeroArea));
        let far = vec![c(0.0, 0.0), c(1e9, 0.0), c(0.0, 1.0)];
        assert!(matches!(
            clean_footprint(&[vec![far]]),
            Err(RejectReason::CoordinateOutOfRange(_))
        ));
    }

    #[test]
    fn bow_tie_is_repaired_into_two_triangles() {
        let bow = vec![c(0.0, 0.0), c(10.0, 10.0), c(10.0, 0.0), c(0.0, 10.0)];
        let f = clean_footprint(&[vec![bow]]).unwrap();
        assert_eq!(f.repairs.len(), 1, "{:?}", f.repairs);
        assert!(f.footprint.is_valid());
        assert!((f.footprint.unsigned_area() - 50.0).abs() < 1e-6);
    }

    #[test]
    fn heights() {
        assert!(check_heights(0.0, 10.0).is_ok());
        assert!(check_heights(10.0, 10.0).is_err());
        // One unit in the last place is not a building (a fuzzed b3dm part).
        assert!(check_heights(103.500_244, 103.500_275).is_err());
        assert!(check_heights(103.5, 103.52).is_ok());
        assert!(check_heights(0.0, 5_000.0).is_err());
        assert!(check_heights(0.0, f32::NAN).is_err());
    }
}
