//! Footprints and triangulations for true 3D building geometry (CityJSON, glTF).
//!
//! * [`footprint_from_mesh`] projects a triangle mesh to the ground plane and takes the outline
//!   of the union: only faces that are not vertical (|n_z| above [`MIN_FACE_NORMAL_Z`], that is
//!   roofs, ground surfaces, overhang undersides) are projected, since a closed building shell
//!   covers its whole plan with them and walls project to zero area. The union is `geo`'s
//!   unary union (i_overlay), holes (courtyards) are kept, and the result goes through
//!   [`crate::validate::clean_footprint`].
//! * [`triangulate_planar_polygon`] triangulates one planar 3D polygon with holes (a CityJSON
//!   surface) by projecting it onto its dominant axis plane and running earcut
//!   (`geo::TriangulateEarcut`).

use geo::{Area, Coord, LineString, MultiPolygon, Polygon, TriangulateEarcut};
use glam::DVec3;
use rstar::primitives::Rectangle;
use rstar::{RTree, RTreeObject};

use crate::city::TriangleMesh;
use crate::overlay_guard::overlay_or_reject;
use crate::report::RejectReason;
use crate::validate::{CleanFootprint, MIN_AREA_M2, clean_footprint};

/// Faces whose unit normal has |z| below this are treated as vertical walls and left out of
/// the footprint union (about 2.9° from vertical). Walls tilted by a few degrees still project
/// to slivers along the outline, which the union absorbs.
pub const MIN_FACE_NORMAL_Z: f64 = 0.05;

/// Projected faces smaller than this (square metres) are skipped: they add nothing to the
/// outline and only slow the union down.
const MIN_FACE_AREA_M2: f64 = 1e-6;

/// Projected faces narrower than this share of their longest edge (twice the area over the
/// longest edge, over that edge) are skipped too: with `f32` positions that is within a few
/// units in the last place of collinear, a line rather than a face. Such needles are what makes
/// the overlay's segment splitting explode: 24 faces, some 15 km long and 0.1 mm wide, took
/// i_overlay 20 s and 68,974 pieces (a fuzzer's GLB, `tests/fuzz/regressions/glb/sliver_faces`).
/// Real roof triangulations keep their thin faces (Den Haag's are 1e-5 of their length or
/// wider): a plain width limit, even 1 mm, split footprints along their ridges.
const MIN_FACE_WIDTH_PER_LENGTH: f64 = 1e-6;

/// Holes smaller than this (square metres) in the union are gaps between adjacent faces left by
/// rounding, not courtyards, and are closed.
pub const MIN_HOLE_AREA_M2: f64 = 0.5;

/// Derives the footprint of a building (or part) from its triangle mesh, in the mesh's own xy
/// frame (metres): the union of the ground projections of its non-vertical faces, holes kept,
/// cleaned and validated like every other footprint.
///
/// Rejects with [`RejectReason::NonFiniteCoordinate`] for a NaN/infinite vertex,
/// [`RejectReason::InvalidGeometry`] for an index out of range, and
/// [`RejectReason::ZeroArea`] when nothing with area remains (an empty mesh, or walls only).
pub fn footprint_from_mesh(mesh: &TriangleMesh) -> Result<CleanFootprint, RejectReason> {
    let mut faces: Vec<Polygon<f64>> = Vec::with_capacity(mesh.triangle_count());
    for tri in mesh.indices.chunks_exact(3) {
        let mut corners = [DVec3::ZERO; 3];
        for (corner, &index) in corners.iter_mut().zip(tri) {
            let p = mesh.positions.get(index as usize).ok_or_else(|| {
                RejectReason::InvalidGeometry(format!(
                    "vertex index {index} out of range ({} vertices)",
                    mesh.positions.len()
                ))
            })?;
            if !p.is_finite() {
                return Err(RejectReason::NonFiniteCoordinate);
            }
            *corner = p.as_dvec3();
        }
        let [a, b, c] = corners;
        let normal = (b - a).cross(c - a);
        let len = normal.length();
        if len <= 0.0 || (normal.z / len).abs() < MIN_FACE_NORMAL_Z {
            continue;
        }
        // Twice the projected area is |normal.z|.
        if normal.z.abs() * 0.5 < MIN_FACE_AREA_M2 {
            continue;
        }
        let longest_edge = [(a, b), (b, c), (c, a)]
            .iter()
            .map(|(p, q)| (p.truncate() - q.truncate()).length())
            .fold(0.0, f64::max);
        let width = normal.z.abs() / longest_edge;
        if width < longest_edge * MIN_FACE_WIDTH_PER_LENGTH {
            continue;
        }
        // Every face counter-clockwise seen from above: unary_union picks its fill rule from
        // the first ring's winding, so the windings must agree.
        let ring = if normal.z > 0.0 { [a, b, c] } else { [a, c, b] };
        faces.push(Polygon::new(
            LineString::new(ring.iter().map(|p| Coord { x: p.x, y: p.y }).collect()),
            vec![],
        ));
    }
    if faces.is_empty() {
        return Err(RejectReason::ZeroArea);
    }
    let union = union_or_reject(&faces)?;
    clean_footprint(&multipolygon_rings(&union, MIN_HOLE_AREA_M2))
}

/// Takes the union of several footprints (for a building made of parts) and cleans it.
pub fn union_footprints<'a>(
    footprints: impl IntoIterator<Item = &'a MultiPolygon<f64>>,
) -> Result<CleanFootprint, RejectReason> {
    let polygons: Vec<&Polygon<f64>> = footprints.into_iter().flat_map(|m| &m.0).collect();
    if polygons.is_empty() {
        return Err(RejectReason::MissingGeometry("no footprint".into()));
    }
    let union = union_or_reject(polygons)?;
    clean_footprint(&multipolygon_rings(&union, MIN_HOLE_AREA_M2))
}

/// The union's work budget: pairs of pieces whose bounding boxes overlap, a fixed allowance
/// plus this many per piece. Faces of a real shell touch their neighbours and the ground
/// surface under them, a few pairs per face; a malformed mesh whose faces all cross each
/// other has pairs quadratic in its size, and so has the overlay's output, which no input
/// file may make unbounded.
const UNION_PAIRS_PER_PIECE: usize = 16;
const UNION_PAIRS_ALLOWANCE: usize = 1_000_000;

/// `geo::unary_union` of `polygons`, rejecting what it cannot do in bounded time or without
/// panicking: pieces whose bounding boxes overlap in more pairs than the budget above, and a
/// panic inside the overlay (i_overlay's OGC extraction can panic on self-touching slivers: a
/// debug assertion, and an index out of bounds in release builds; iShape-Rust/iOverlay#78 and
/// #79). One hostile shape must not take the whole load down.
fn union_or_reject<'a>(
    polygons: impl IntoIterator<Item = &'a Polygon<f64>>,
) -> Result<MultiPolygon<f64>, RejectReason> {
    let polygons: Vec<&Polygon<f64>> = polygons.into_iter().collect();
    let budget = UNION_PAIRS_ALLOWANCE + UNION_PAIRS_PER_PIECE * polygons.len();
    let pairs = overlapping_box_pairs(&polygons, budget);
    if pairs > budget {
        return Err(RejectReason::InvalidGeometry(format!(
            "its {} footprint pieces overlap each other in over {budget} pairs: a malformed \
             mesh whose union would take unbounded time",
            polygons.len()
        )));
    }
    overlay_or_reject("the footprint union", || {
        geo::unary_union(polygons.iter().copied())
    })
}

/// How many pairs of `polygons` have overlapping bounding boxes, counted with an R-tree of
/// the boxes and stopped once past `cap`: the count, or `cap + 1`. About O(n log n + cap).
fn overlapping_box_pairs(polygons: &[&Polygon<f64>], cap: usize) -> usize {
    let boxes: Vec<Rectangle<[f64; 2]>> = polygons
        .iter()
        .filter_map(|p| geo::BoundingRect::bounding_rect(*p))
        .map(|r| Rectangle::from_corners([r.min().x, r.min().y], [r.max().x, r.max().y]))
        .collect();
    let tree = RTree::bulk_load(boxes.clone());
    // Each pair is met twice (once from each side) and each box meets itself once.
    let mut meetings = 0;
    for b in &boxes {
        for _ in tree.locate_in_envelope_intersecting(b.envelope()) {
            meetings += 1;
            if meetings > boxes.len() + 2 * cap {
                return cap + 1;
            }
        }
    }
    (meetings - boxes.len()) / 2
}

/// A multipolygon as rings for [`clean_footprint`], dropping holes under `min_hole_area_m2`
/// and pieces under the validator's zero area ([`MIN_AREA_M2`]) while a larger piece remains:
/// slivers the union leaves between faces that meet at rounded corners (one of 0.009 m² beside
/// a 469 m² roof rejected a whole Amsterdam building as "zero area").
fn multipolygon_rings(mp: &MultiPolygon<f64>, min_hole_area_m2: f64) -> Vec<Vec<Vec<Coord<f64>>>> {
    let has_area = |polygon: &&Polygon<f64>| polygon.unsigned_area() >= MIN_AREA_M2;
    let keep_all = !mp.0.iter().any(|p| has_area(&p));
    mp.0.iter()
        .filter(|polygon| keep_all || has_area(polygon))
        .map(|polygon| {
            std::iter::once(polygon.exterior().0.clone())
                .chain(
                    polygon
                        .interiors()
                        .iter()
                        .filter(|hole| {
                            Polygon::new((*hole).clone(), vec![]).unsigned_area()
                                >= min_hole_area_m2
                        })
                        .map(|hole| hole.0.clone()),
                )
                .collect()
        })
        .collect()
}

/// Why a planar polygon could not be triangulated.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum TriangulateError {
    #[error("non-finite vertex")]
    NonFinite,
    #[error("outer ring has fewer than 3 distinct points")]
    TooFewPoints,
    #[error("polygon has zero area")]
    ZeroArea,
}

/// Triangulates a planar (or nearly planar) 3D polygon with holes.
///
/// `rings[0]` is the outer ring, the others are holes; rings are open or closed (a repeated
/// first point at the end is ignored, as are consecutive duplicates). The polygon is projected
/// onto the axis plane its Newell normal is most aligned with, triangulated with earcut, and
/// every triangle is returned with the winding of the outer ring (so a surface that is
/// counter-clockwise seen from outside gives triangles facing outside).
///
/// Returns triangles as indices into the concatenation of `rings` (ring 0's points first, then
/// ring 1's, ...). Holes with fewer than 3 distinct points are ignored.
pub fn triangulate_planar_polygon(
    rings: &[Vec<DVec3>],
) -> Result<Vec<[usize; 3]>, TriangulateError> {
    let Some(outer) = rings.first() else {
        return Err(TriangulateError::TooFewPoints);
    };
    if rings.iter().flatten().any(|p| !p.is_finite()) {
        return Err(TriangulateError::NonFinite);
    }
    let normal = newell_normal(outer);
    // Finite inputs give a finite normal; a zero one means no area.
    if normal.length() <= 0.0 {
        return Err(TriangulateError::ZeroArea);
    }
    // Drop the axis the normal is most aligned with.
    let a = normal.abs();
    let project: fn(DVec3) -> Coord<f64> = if a.z >= a.x && a.z >= a.y {
        |p| Coord { x: p.x, y: p.y }
    } else if a.x >= a.y {
        |p| Coord { x: p.y, y: p.z }
    } else {
        |p| Coord { x: p.z, y: p.x }
    };

    // Clean rings, remembering where each kept point came from in the flattened input.
    let mut offset = 0;
    let mut cleaned: Vec<(Vec<Coord<f64>>, Vec<usize>)> = Vec::with_capacity(rings.len());
    for (ring_index, ring) in rings.iter().enumerate() {
        let mut coords: Vec<Coord<f64>> = Vec::with_capacity(ring.len());
        let mut origin: Vec<usize> = Vec::with_capacity(ring.len());
        for (i, p) in ring.iter().enumerate() {
            let c = project(*p);
            if coords.last() == Some(&c) {
                continue;
            }
            coords.push(c);
            origin.push(offset + i);
        }
        while coords.len() > 1 && coords.first() == coords.last() {
            coords.pop();
            origin.pop();
        }
        offset += ring.len();
        if coords.len() < 3 {
            if ring_index == 0 {
                return Err(TriangulateError::TooFewPoints);
            }
            continue;
        }
        cleaned.push((coords, origin));
    }
    let Some(((outer_coords, _), holes)) = cleaned.split_first() else {
        return Err(TriangulateError::TooFewPoints);
    };
    let polygon = Polygon::new(
        LineString::new(outer_coords.clone()),
        holes
            .iter()
            .map(|(c, _)| LineString::new(c.clone()))
            .collect(),
    );
    if polygon.unsigned_area() <= 0.0 {
        return Err(TriangulateError::ZeroArea);
    }
    let origin: Vec<usize> = cleaned
        .iter()
        .flat_map(|(_, o)| o.iter().copied())
        .collect();
    let flat: Vec<DVec3> = rings.iter().flatten().copied().collect();
    let raw = polygon.earcut_triangles_raw();
    let mut triangles = Vec::with_capacity(raw.triangle_indices.len() / 3);
    for t in raw.triangle_indices.chunks_exact(3) {
        let (Some(&i), Some(&j), Some(&k)) = (origin.get(t[0]), origin.get(t[1]), origin.get(t[2]))
        else {
            continue;
        };
        let (Some(&pi), Some(&pj), Some(&pk)) = (flat.get(i), flat.get(j), flat.get(k)) else {
            continue;
        };
        let facing = (pj - pi).cross(pk - pi).dot(normal);
        if facing == 0.0 {
            continue;
        }
        triangles.push(if facing > 0.0 { [i, j, k] } else { [i, k, j] });
    }
    if triangles.is_empty() {
        return Err(TriangulateError::ZeroArea);
    }
    Ok(triangles)
}

/// Newell's normal of a ring (robust for non-convex and slightly non-planar rings); its length
/// is twice the ring's area.
pub fn newell_normal(ring: &[DVec3]) -> DVec3 {
    let Some(&first) = ring.first() else {
        return DVec3::ZERO;
    };
    // Subtract the first point to keep the products small for georeferenced coordinates.
    let mut n = DVec3::ZERO;
    for (i, p) in ring.iter().enumerate() {
        let q = ring.get(i + 1).copied().unwrap_or(first) - first;
        let p = *p - first;
        n.x += (p.y - q.y) * (p.z + q.z);
        n.y += (p.z - q.z) * (p.x + q.x);
        n.z += (p.x - q.x) * (p.y + q.y);
    }
    n
}

#[cfg(test)]
mod tests {
    use geo::{Contains, Point, Validation};
    use glam::Vec3;

    use super::*;

    /// A closed extrusion of a polygon with holes between z0 and z1, triangulated with
    /// [`triangulate_planar_polygon`] (roof up, floor down, walls out).
    fn extrude(rings: &[Vec<(f64, f64)>], z0: f64, z1: f64) -> TriangleMesh {
        let mut mesh = TriangleMesh::default();
        let mut add = |poly: Vec<Vec<DVec3>>| {
            let tris = triangulate_planar_polygon(&poly).unwrap();
            let base = mesh.positions.len() as u32;
            mesh.positions
                .extend(poly.iter().flatten().map(|p| p.as_vec3()));
            mesh.indices
                .extend(tris.iter().flatten().map(|&i| base + i as u32));
        };
        // Outer ring counter-clockwise from above, holes clockwise.
        let at = |z: f64, ring: &Vec<(f64, f64)>| -> Vec<DVec3> {
            ring.iter().map(|&(x, y)| DVec3::new(x, y, z)).collect()
        };
        add(rings.iter().map(|r| at(z1, r)).collect());
        add(rings
            .iter()
            .map(|r| at(z0, r).into_iter().rev().collect())
            .collect());
        for ring in rings {
            for i in 0..ring.len() {
                let (a, b) = (ring[i], ring[(i + 1) % ring.len()]);
                add(vec![vec![
                    DVec3::new(a.0, a.1, z0),
                    DVec3::new(b.0, b.1, z0),
                    DVec3::new(b.0, b.1, z1),
                    DVec3::new(a.0, a.1, z1),
                ]]);
            }
        }
        mesh
    }

    /// A sliver the union leaves beside a roof (here a stray face of 0.005 m²) is dropped, not
    /// a rejection of the building; a mesh of nothing but such a sliver is still zero area.
    #[test]
    fn a_sliver_piece_beside_a_roof_is_dropped() {
        let square = vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)];
        let mut mesh = extrude(&[square], 0.0, 6.0);
        let sliver = TriangleMesh {
            positions: vec![
                Vec3::new(12.0, 0.0, 6.0),
                Vec3::new(12.1, 0.0, 6.0),
                Vec3::new(12.0, 0.1, 6.0),
            ],
            indices: vec![0, 1, 2],
        };
        mesh.append(&sliver);
        let footprint = footprint_from_mesh(&mesh).expect("the roof").footprint;
        assert_eq!(footprint.0.len(), 1);
        assert!((footprint.unsigned_area() - 100.0).abs() < 1e-9);
        assert!(matches!(
            footprint_from_mesh(&sliver),
            Err(RejectReason::ZeroArea)
        ));
    }

    #[test]
    fn l_shaped_extrusion_gives_the_l() {
        let l = vec![
            (0.0, 0.0),
            (20.0, 0.0),
            (20.0, 8.0),
            (8.0, 8.0),
            (8.0, 20.0),
            (0.0, 20.0),
        ];
        let mesh = extrude(&[l], 0.0, 12.0);
        let f = footprint_from_mesh(&mesh).unwrap().footprint;
        assert!(f.is_valid());
        assert!(
            (f.unsigned_area() - (20.0 * 8.0 + 8.0 * 12.0)).abs() < 1e-3,
            "{}",
            f.unsigned_area()
        );
        assert!(f.contains(&Point::new(4.0, 16.0)));
        assert!(f.contains(&Point::new(16.0, 4.0)));
        assert!(!f.contains(&Point::new(14.0, 14.0)));
    }

    #[test]
    fn courtyard_keeps_its_hole() {
        let outer = vec![(0.0, 0.0), (30.0, 0.0), (30.0, 30.0), (0.0, 30.0)];
        let hole = vec![(10.0, 10.0), (10.0, 20.0), (20.0, 20.0), (20.0, 10.0)];
        let mesh = extrude(&[outer, hole], 2.0, 20.0);
        let f = footprint_from_mesh(&mesh).unwrap().footprint;
        assert!(f.is_valid());
        assert_eq!(f.0.len(), 1);
        assert_eq!(f.0[0].interiors().len(), 1);
        assert!((f.unsigned_area() - 800.0).abs() < 1e-3);
        assert!(!f.contains(&Point::new(15.0, 15.0)));
    }

    #[test]
    fn walls_only_and_bad_indices_are_rejected() {
        let wall = TriangleMesh {
            positions: vec![
                Vec3::new(0.0, 0.0, 0.0),
                Vec3::new(5.0, 0.0, 0.0),
                Vec3::new(5.0, 0.0, 5.0),
            ],
            indices: vec![0, 1, 2],
        };
        assert_eq!(footprint_from_mesh(&wall), Err(RejectReason::ZeroArea));
        let bad = TriangleMesh {
            indices: vec![0, 1, 7],
            ..wall.clone()
        };
        assert!(matches!(
            footprint_from_mesh(&bad),
            Err(RejectReason::InvalidGeometry(_))
        ));
        let nan = TriangleMesh {
            positions: vec![Vec3::ZERO, Vec3::X, Vec3::new(f32::NAN, 1.0, 0.0)],
            indices: vec![0, 1, 2],
        };
        assert_eq!(
            footprint_from_mesh(&nan),
            Err(RejectReason::NonFiniteCoordinate)
        );
    }

    #[test]
    fn triangulation_keeps_winding_and_area_on_a_vertical_face() {
        // A wall in the xz plane, facing -y (counter-clockwise seen from -y).
        let ring = vec![
            DVec3::new(0.0, 0.0, 0.0),
            DVec3::new(4.0, 0.0, 0.0),
            DVec3::new(4.0, 0.0, 3.0),
            DVec3::new(0.0, 0.0, 3.0),
            DVec3::new(0.0, 0.0, 0.0),
        ];
        let n = newell_normal(&ring);
        assert!(n.y < 0.0);
        let tris = triangulate_planar_polygon(std::slice::from_ref(&ring)).unwrap();
        assert_eq!(tris.len(), 2);
        let mut area = 0.0;
        for t in &tris {
            assert!(t.iter().all(|&i| i < 4), "closing point never used: {t:?}");
            let c = (ring[t[1]] - ring[t[0]]).cross(ring[t[2]] - ring[t[0]]);
            assert!(c.dot(n) > 0.0);
            area += c.length() / 2.0;
        }
        assert!((area - 12.0).abs() < 1e-9);
    }

    #[test]
    fn triangulation_rejects_degenerate_rings() {
        let line = vec![DVec3::ZERO, DVec3::X, DVec3::X * 2.0];
        assert_eq!(
            triangulate_planar_polygon(&[line]),
            Err(TriangulateError::ZeroArea)
        );
        assert_eq!(
            triangulate_planar_polygon(&[vec![DVec3::ZERO, DVec3::X]]),
            Err(TriangulateError::ZeroArea)
        );
        assert_eq!(
            triangulate_planar_polygon(&[]),
            Err(TriangulateError::TooFewPoints)
        );
        assert_eq!(
            triangulate_planar_polygon(&[vec![DVec3::ZERO, DVec3::X, DVec3::NAN]]),
            Err(TriangulateError::NonFinite)
        );
    }

    /// A mesh of `n` flat triangles (z = 5): a fan of thin wedges through one centre, every
    /// one crossing every other in plan.
    fn crossing_star(n: usize) -> TriangleMesh {
        let mut mesh = TriangleMesh::default();
        for i in 0..n {
            let angle = std::f32::consts::PI * i as f32 / n as f32;
            let (s, c) = angle.sin_cos();
            let base = mesh.positions.len() as u32;
            mesh.positions.extend([
                Vec3::new(-50.0 * c, -50.0 * s, 5.0),
                Vec3::new(50.0 * c + 0.5 * s, 50.0 * s - 0.5 * c, 5.0),
                Vec3::new(50.0 * c - 0.5 * s, 50.0 * s + 0.5 * c, 5.0),
            ]);
            mesh.indices.extend([base, base + 1, base + 2]);
        }
        mesh
    }

    /// Faces that all cross each other are over the union's budget: rejected, quickly, saying
    /// why (the fuzzers found GLBs whose union ran for minutes); a few of them still union.
    #[test]
    fn faces_crossing_each_other_past_the_budget_are_rejected_quickly() {
        let start = std::time::Instant::now();
        let rejected = footprint_from_mesh(&crossing_star(2_000));
        assert!(
            start.elapsed() < std::time::Duration::from_secs(5),
            "{:?}",
            start.elapsed()
        );
        match rejected {
            Err(RejectReason::InvalidGeometry(why)) => {
                assert!(why.contains("2000 footprint pieces overlap"), "{why}")
            }
            other => panic!("expected a rejection, got {other:?}"),
        }
        let few = footprint_from_mesh(&crossing_star(12)).expect("12 wedges union");
        assert!(few.footprint.unsigned_area() > 100.0);
    }

    /// A finely triangulated roof (80,000 faces on a 200 m × 100 m grid, plus its floor) is
    /// within the budget: the budget grows with the faces, and neighbours only touch.
    #[test]
    fn a_finely_triangulated_roof_is_within_the_union_budget() {
        let (nx, ny) = (200, 100);
        let mut mesh = TriangleMesh::default();
        for z in [0.0, 8.0] {
            let base = mesh.positions.len() as u32;
            for j in 0..=ny {
                for i in 0..=nx {
                    mesh.positions.push(Vec3::new(i as f32, j as f32, z));
                }
            }
            let at = |i: u32, j: u32| base + j * (nx + 1) + i;
            for j in 0..ny {
                for i in 0..nx {
                    mesh.indices
                        .extend([at(i, j), at(i + 1, j), at(i + 1, j + 1)]);
                    mesh.indices
                        .extend([at(i, j), at(i + 1, j + 1), at(i, j + 1)]);
                }
            }
        }
        let footprint = footprint_from_mesh(&mesh).expect("a regular roof unions");
        assert!((footprint.footprint.unsigned_area() - 20_000.0).abs() < 1.0);
    }

    /// A needle, a face within `f32` precision of collinear, is a line and is left out: a 100 m
    /// long, 10 µm wide face beside a roof does not stretch the footprint.
    #[test]
    fn a_needle_face_is_left_out() {
        let square = vec![(0.0, 0.0), (10.0, 0.0), (10.0, 10.0), (0.0, 10.0)];
        let mut mesh = extrude(&[square], 0.0, 6.0);
        let base = mesh.positions.len() as u32;
        mesh.positions.extend([
            Vec3::new(5.0, 5.0, 6.0),
            Vec3::new(105.0, 5.0, 6.0),
            Vec3::new(105.0, 5.000_01, 6.0),
        ]);
        mesh.indices.extend([base, base + 1, base + 2]);
        let footprint = footprint_from_mesh(&mesh).expect("the roof unions");
        assert!((footprint.footprint.unsigned_area() - 100.0).abs() < 0.01);
    }
}
