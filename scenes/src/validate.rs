//! Validation and repair of building footprints and heights, shared by every loader.
//!
//! Every ring is checked on entry: finite coordinates within range, at least three distinct
//! points, non-zero area. A ring that crosses itself is repaired by re-noding it through `geo`'s
//! boolean operations (non-zero fill: a bow-tie becomes two triangles); the repair is accepted
//! only if it keeps most of the ring's area, otherwise the building is rejected. The result is
//! a valid `geo` multipolygon (OGC rules, checked with `geo::Validation`).

use geo::{
    Area, BooleanOps, Coord, LineString, MultiPolygon, Polygon, RemoveRepeatedPoints, Validation,
    Winding,
};

use crate::report::RejectReason;

/// Local coordinates beyond this many metres from the origin are rejected: a city spans tens of
/// kilometres, and f32 meshes lose centimetres beyond a few hundred.
pub const MAX_LOCAL_COORDINATE_M: f64 = 200_000.0;
/// Smallest footprint area kept (square metres); anything smaller is a degenerate sliver.
pub const MIN_AREA_M2: f64 = 0.01;
/// Tallest building accepted (metres); the tallest on earth is 828 m.
pub const MAX_HEIGHT_M: f32 = 1_000.0;
/// Lowest base accepted (metres below the frame's ground), for terrain and NAP offsets.
pub const MIN_BASE_M: f32 = -500.0;
/// A self-intersecting ring is repaired only if the repair keeps this share of its area
/// (shoelace area of the original ring vs. area of the re-noded polygon).
const MIN_REPAIR_AREA_RATIO: f64 = 0.5;

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
    if !footprint.is_valid() {
        let before: f64 = footprint.0.iter().map(signed_ring_area_abs).sum();
        let repaired = renode(&footprint);
        let after = repaired.unsigned_area();
        if repaired.0.is_empty() || after < MIN_AREA_M2 {
            return Err(RejectReason::SelfIntersection);
        }
        if after < before * MIN_REPAIR_AREA_RATIO {
            return Err(RejectReason::SelfIntersection);
        }
        if !repaired.is_valid() {
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
    if polygon.unsigned_area() < MIN_AREA_M2 && polygon.is_valid() {
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
    if top_m <= base_m {
        return Err(RejectReason::AbsurdHeight(format!(
            "top {top_m} m not above base {base_m} m"
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
    if let Err(e) = mp.check_validation() {
        return Err(format!("is invalid: {e}"));
    }
    if mp.unsigned_area() < MIN_AREA_M2 {
        return Err("has zero area".into());
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
        assert!(check_heights(0.0, 5_000.0).is_err());
        assert!(check_heights(0.0, f32::NAN).is_err());
    }
}
