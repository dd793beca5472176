//! Extrusion of 2.5D footprints into closed-looking triangle meshes: vertical walls for every ring
//! edge (holes included) and a flat roof.
//!
//! The roof is triangulated by a constrained Delaunay triangulation of the footprint's rings
//! (spade), keeping the triangles whose centroid lies inside the polygon (DESIGN.md: "roof
//! triangulated by constrained Delaunay (spade)"). All triangles are counter-clockwise seen from
//! outside, so their geometric normals point out of the building.

use geo::{Contains, Coord, LineString, Polygon};
use glam::Vec3;
use spade::{ConstrainedDelaunayTriangulation, Point2, Triangulation};

use crate::city::{Building, TriangleMesh};

/// What [`extrude_polygon_with`] produces besides walls and roof.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct ExtrudeOptions {
    /// Also emit the bottom face (facing down). Off by default: buildings stand on the ground,
    /// where nobody sees their underside.
    pub bottom_face: bool,
}

/// Extrudes `polygon` between the heights `base_m` and `top_m` into walls and a roof (no bottom
/// face). Non-finite vertices and zero-length edges are skipped; a degenerate polygon gives an
/// empty or partial mesh, never a panic.
pub fn extrude_polygon(polygon: &Polygon<f64>, base_m: f32, top_m: f32) -> TriangleMesh {
    extrude_polygon_with(polygon, base_m, top_m, ExtrudeOptions::default())
}

/// [`extrude_polygon`] with options.
pub fn extrude_polygon_with(
    polygon: &Polygon<f64>,
    base_m: f32,
    top_m: f32,
    options: ExtrudeOptions,
) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    if !(base_m.is_finite() && top_m.is_finite()) || top_m <= base_m {
        return mesh;
    }
    // Finite, deduplicated rings; exterior counter-clockwise, holes clockwise, so the solid is
    // on the left of every edge. Rings of zero area are dropped.
    let mut rings: Vec<Vec<Coord<f64>>> = Vec::with_capacity(1 + polygon.interiors().len());
    for (k, ring) in std::iter::once(polygon.exterior())
        .chain(polygon.interiors())
        .enumerate()
    {
        let mut ring = clean_ring(ring);
        let area2 = signed_area2(&ring);
        if ring.len() < 3 || area2 == 0.0 || !area2.is_finite() {
            if k == 0 {
                return mesh;
            }
            continue;
        }
        let want_ccw = k == 0;
        if (area2 > 0.0) != want_ccw {
            ring.reverse();
        }
        rings.push(ring);
    }
    let polygon = Polygon::new(
        closed(&rings[0]),
        rings[1..].iter().map(|r| closed(r)).collect(),
    );

    // Vertices: for each ring vertex, one at the base and one at the top.
    let mut ring_starts = Vec::with_capacity(rings.len());
    for ring in &rings {
        ring_starts.push(mesh.positions.len() as u32);
        for c in ring {
            mesh.positions
                .push(Vec3::new(c.x as f32, c.y as f32, base_m));
            mesh.positions
                .push(Vec3::new(c.x as f32, c.y as f32, top_m));
        }
    }
    let bottom = |start: u32, i: usize| start + 2 * i as u32;
    let top = |start: u32, i: usize| start + 2 * i as u32 + 1;

    // Walls: edge a→b with the solid on its left; (a0, b0, b1) has its normal to the right.
    for (ring, &start) in rings.iter().zip(&ring_starts) {
        let n = ring.len();
        for i in 0..n {
            let j = (i + 1) % n;
            let (a0, b0, b1, a1) = (
                bottom(start, i),
                bottom(start, j),
                top(start, j),
                top(start, i),
            );
            mesh.indices.extend_from_slice(&[a0, b0, b1, a0, b1, a1]);
        }
    }

    // Roof (and optionally bottom) from the constrained Delaunay triangulation of the rings.
    for [a, b, c] in triangulate_rings(&polygon, &rings) {
        let (ra, rb, rc) = (a, b, c);
        let index = |(r, i): (usize, usize)| top(ring_starts[r], i);
        mesh.indices
            .extend_from_slice(&[index(ra), index(rb), index(rc)]);
        if options.bottom_face {
            let index = |(r, i): (usize, usize)| bottom(ring_starts[r], i);
            mesh.indices
                .extend_from_slice(&[index(ra), index(rc), index(rb)]);
        }
    }
    mesh
}

/// The walls of a mesh that [`extrude_polygon`] made of a polygon without holes (a cluster
/// hull): its ring, counter-clockwise (wall `i` runs from ring vertex `i` to `i + 1`, the last
/// back to the first), the walls' foot and their top. It reads the layout above (a base and a
/// top vertex per ring vertex, in ring order, the walls first); `None` for a mesh not laid out
/// that way.
pub fn extruded_walls(mesh: &TriangleMesh) -> Option<(Vec<[f32; 2]>, f32, f32)> {
    let p = &mesh.positions;
    let n = p.len() / 2;
    if n < 3 || !p.len().is_multiple_of(2) || mesh.indices.len() < 6 * n {
        return None;
    }
    let (base, top) = (p[0].z, p[1].z);
    let mut ring = Vec::with_capacity(n);
    for i in 0..n {
        let (b, t) = (p[2 * i], p[2 * i + 1]);
        if b.x != t.x || b.y != t.y || b.z != base || t.z != top {
            return None;
        }
        let j = ((i + 1) % n) as u32;
        let i = i as u32;
        let wall = [2 * i, 2 * j, 2 * j + 1, 2 * i, 2 * j + 1, 2 * i + 1];
        if mesh.indices[6 * i as usize..6 * i as usize + 6] != wall {
            return None;
        }
        ring.push([b.x, b.y]);
    }
    (top > base).then_some((ring, base, top))
}

/// The mesh of a building: its own mesh when the source had 3D geometry, else its parts
/// extruded (every polygon of every part between the part's base and top).
pub fn building_mesh(b: &Building) -> TriangleMesh {
    if let Some(mesh) = &b.mesh
        && !mesh.indices.is_empty()
    {
        return TriangleMesh::clone(mesh);
    }
    let mut mesh = TriangleMesh::default();
    for part in &b.parts {
        for polygon in &part.footprint {
            mesh.append(&extrude_polygon(polygon, part.base_m, part.top_m));
        }
    }
    mesh
}

/// Ring vertices without the closing repeat, non-finite coordinates and consecutive duplicates.
fn clean_ring(ring: &LineString<f64>) -> Vec<Coord<f64>> {
    let mut out: Vec<Coord<f64>> = Vec::with_capacity(ring.0.len());
    for c in &ring.0 {
        if !(c.x.is_finite() && c.y.is_finite()) {
            continue;
        }
        if out.last() != Some(c) {
            out.push(*c);
        }
    }
    while out.len() > 1 && out.first() == out.last() {
        out.pop();
    }
    out
}

/// Twice the signed area of an open ring (positive counter-clockwise).
fn signed_area2(ring: &[Coord<f64>]) -> f64 {
    let n = ring.len();
    (0..n)
        .map(|i| {
            let (a, b) = (ring[i], ring[(i + 1) % n]);
            a.x * b.y - b.x * a.y
        })
        .sum()
}

/// The closed `LineString` of an open ring.
fn closed(ring: &[Coord<f64>]) -> LineString<f64> {
    let mut coords = ring.to_vec();
    if let Some(&first) = ring.first() {
        coords.push(first);
    }
    LineString::new(coords)
}

/// Counter-clockwise roof triangles as (ring, vertex) pairs. Ring edges are constraints, and a
/// triangle is inside when a walk from the outer face to it crosses them an odd number of times
/// (one pass over the faces). A constraint that would cross another (self-touching input) is
/// left out, and then a centroid test decides instead (linear in the ring per triangle).
fn triangulate_rings(
    polygon: &Polygon<f64>,
    rings: &[Vec<Coord<f64>>],
) -> Vec<[(usize, usize); 3]> {
    let mut cdt = ConstrainedDelaunayTriangulation::<Point2<f64>>::new();
    // spade merges coincident points into one vertex; remember the first (ring, index) of each.
    let mut owner: Vec<Option<(usize, usize)>> = Vec::new();
    let mut handles = Vec::with_capacity(rings.len());
    for (r, ring) in rings.iter().enumerate() {
        let mut ring_handles = Vec::with_capacity(ring.len());
        for (i, c) in ring.iter().enumerate() {
            match cdt.insert(Point2::new(c.x, c.y)) {
                Ok(h) => {
                    if owner.len() <= h.index() {
                        owner.resize(h.index() + 1, None);
                    }
                    owner[h.index()].get_or_insert((r, i));
                    ring_handles.push(Some(h));
                }
                Err(e) => {
                    tracing::debug!("roof vertex ({}, {}) skipped: {e:?}", c.x, c.y);
                    ring_handles.push(None);
                }
            }
        }
        handles.push(ring_handles);
    }
    let mut all_constrained = true;
    for ring_handles in &handles {
        let n = ring_handles.len();
        for i in 0..n {
            if let (Some(a), Some(b)) = (ring_handles[i], ring_handles[(i + 1) % n])
                && a != b
                && cdt.try_add_constraint(a, b).is_empty()
            {
                all_constrained = false;
            }
        }
    }
    let inside = all_constrained.then(|| inside_by_parity(&cdt));
    let mut triangles = Vec::new();
    for face in cdt.inner_faces() {
        let [p, q, s] = face.positions();
        let is_inside = match &inside {
            Some(inside) => inside[face.fix().index()],
            None => polygon.contains(&geo::Point::new(
                (p.x + q.x + s.x) / 3.0,
                (p.y + q.y + s.y) / 3.0,
            )),
        };
        if !is_inside {
            continue;
        }
        let vs = face.vertices();
        let ids = vs.map(|v| owner.get(v.fix().index()).copied().flatten());
        let [Some(a), Some(b), Some(c)] = ids else {
            continue;
        };
        let area2 = (q.x - p.x) * (s.y - p.y) - (q.y - p.y) * (s.x - p.x);
        if area2 > 0.0 {
            triangles.push([a, b, c]);
        } else if area2 < 0.0 {
            triangles.push([a, c, b]);
        }
    }
    triangles
}

/// For each face index of `cdt`, whether it lies inside its constraint rings: a breadth-first
/// walk from the outer face, flipping at each constraint edge crossed.
fn inside_by_parity(cdt: &ConstrainedDelaunayTriangulation<Point2<f64>>) -> Vec<bool> {
    let faces = cdt.num_all_faces();
    let mut inside = vec![false; faces];
    let mut seen = vec![false; faces];
    let outer = cdt.outer_face();
    seen[outer.fix().index()] = true;
    let mut queue = std::collections::VecDeque::from([outer.fix()]);
    while let Some(f) = queue.pop_front() {
        let face = cdt.face(f);
        let here = inside[f.index()];
        let edges: Vec<_> = match face.as_inner() {
            Some(inner) => inner.adjacent_edges().to_vec(),
            // The hull edges, turned to have the outer face on their side.
            None => cdt
                .convex_hull()
                .map(|e| if e.face().is_outer() { e } else { e.rev() })
                .collect(),
        };
        for e in edges {
            let next = e.rev().face();
            let g = next.fix().index();
            if !seen[g] {
                seen[g] = true;
                inside[g] = here ^ cdt.is_constraint_edge(e.as_undirected().fix());
                queue.push_back(next.fix());
            }
        }
    }
    inside
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{Area, polygon};

    fn normal(t: [Vec3; 3]) -> Vec3 {
        (t[1] - t[0]).cross(t[2] - t[0])
    }

    #[test]
    fn the_walls_of_a_hull_come_back_from_its_mesh() {
        // Clockwise, with a repeated vertex: extrusion cleans and turns it.
        let hull = polygon![(x: 0.0, y: 0.0), (x: 0.0, y: 5.0), (x: 0.0, y: 5.0), (x: 8.0, y: 5.0), (x: 8.0, y: 0.0)];
        let mesh = extrude_polygon(&hull, 1.0, 9.0);
        let (ring, base, top) = extruded_walls(&mesh).unwrap();
        assert_eq!((base, top), (1.0, 9.0));
        assert_eq!(ring.len(), 4);
        let area2: f32 = (0..4)
            .map(|i| {
                let (a, b) = (ring[i], ring[(i + 1) % 4]);
                a[0] * b[1] - b[0] * a[1]
            })
            .sum();
        assert_eq!(area2, 80.0, "counter-clockwise, 40 m²: {ring:?}");
        // A polygon with a hole has walls the ring does not close over.
        let holed = Polygon::new(
            hull.exterior().clone(),
            vec![LineString::from(vec![
                (2.0, 1.0),
                (3.0, 1.0),
                (3.0, 2.0),
                (2.0, 1.0),
            ])],
        );
        assert!(extruded_walls(&extrude_polygon(&holed, 0.0, 3.0)).is_none());
        assert!(extruded_walls(&TriangleMesh::default()).is_none());
    }

    /// Sum of triangle areas whose normal points along `dir`.
    fn area_facing(mesh: &TriangleMesh, dir: Vec3) -> f32 {
        mesh.triangles()
            .map(normal)
            .filter(|n| n.normalize_or_zero().dot(dir) > 0.99)
            .map(|n| n.length() * 0.5)
            .sum()
    }

    /// Every triangle's normal points away from the given interior point (horizontally for walls).
    fn assert_outward(mesh: &TriangleMesh, inside: Vec3) {
        for t in mesh.triangles() {
            let n = normal(t);
            assert!(n.length() > 1e-6, "degenerate triangle {t:?}");
            let centre = (t[0] + t[1] + t[2]) / 3.0;
            let to_centre = centre - inside;
            let to_centre = if n.z.abs() > 1e-3 {
                to_centre
            } else {
                Vec3::new(to_centre.x, to_centre.y, 0.0)
            };
            assert!(n.dot(to_centre) > 0.0, "inward triangle {t:?}");
        }
    }

    #[test]
    fn unit_square_gives_four_walls_and_two_roof_triangles() {
        let square =
            polygon![(x: 0.0, y: 0.0), (x: 1.0, y: 0.0), (x: 1.0, y: 1.0), (x: 0.0, y: 1.0)];
        let mesh = extrude_polygon(&square, 0.0, 10.0);
        assert_eq!(mesh.triangle_count(), 4 * 2 + 2);
        assert_outward(&mesh, Vec3::new(0.5, 0.5, 5.0));
        for dir in [Vec3::X, -Vec3::X, Vec3::Y, -Vec3::Y] {
            assert!(
                (area_facing(&mesh, dir) - 10.0).abs() < 1e-4,
                "wall facing {dir}"
            );
        }
        assert!((area_facing(&mesh, Vec3::Z) - 1.0).abs() < 1e-5);
        assert_eq!(area_facing(&mesh, -Vec3::Z), 0.0);

        // A clockwise input is reoriented; the bottom face is there on request.
        let clockwise =
            polygon![(x: 0.0, y: 0.0), (x: 0.0, y: 1.0), (x: 1.0, y: 1.0), (x: 1.0, y: 0.0)];
        let mesh = extrude_polygon_with(&clockwise, 2.0, 5.0, ExtrudeOptions { bottom_face: true });
        assert_eq!(mesh.triangle_count(), 12);
        assert_outward(&mesh, Vec3::new(0.5, 0.5, 3.0));
        assert!((area_facing(&mesh, -Vec3::Z) - 1.0).abs() < 1e-5);
    }

    #[test]
    fn polygon_with_hole_has_inner_walls_and_a_ring_roof() {
        let courtyard = Polygon::new(
            LineString::from(vec![
                (0.0, 0.0),
                (10.0, 0.0),
                (10.0, 10.0),
                (0.0, 10.0),
                (0.0, 0.0),
            ]),
            vec![LineString::from(vec![
                (3.0, 3.0),
                (7.0, 3.0),
                (7.0, 7.0),
                (3.0, 7.0),
                (3.0, 3.0),
            ])],
        );
        let mesh = extrude_polygon(&courtyard, 0.0, 6.0);
        let roof = area_facing(&mesh, Vec3::Z);
        assert!(
            (roof as f64 - courtyard.unsigned_area()).abs() < 1e-3,
            "roof area {roof}"
        );
        // Outer walls face away from the centre, courtyard walls face towards it.
        let centre = Vec3::new(5.0, 5.0, 3.0);
        let mut inner_walls = 0;
        for t in mesh.triangles() {
            let n = normal(t);
            if n.z.abs() > 1e-3 {
                continue;
            }
            let c = (t[0] + t[1] + t[2]) / 3.0;
            let is_inner = (c.x - 5.0).abs() < 2.5 && (c.y - 5.0).abs() < 2.5;
            let away = n.dot(Vec3::new(c.x - centre.x, c.y - centre.y, 0.0)) > 0.0;
            assert_eq!(away, !is_inner, "wall {t:?}");
            inner_walls += usize::from(is_inner);
        }
        assert_eq!(inner_walls, 8);
        // No roof triangle covers the courtyard.
        for t in mesh.triangles().filter(|t| normal(*t).z > 0.0) {
            let c = (t[0] + t[1] + t[2]) / 3.0;
            assert!(
                !((3.0..7.0).contains(&c.x) && (3.0..7.0).contains(&c.y)),
                "{t:?}"
            );
        }
    }

    #[test]
    fn collinear_and_duplicate_points_and_concave_shapes() {
        // An L shape with collinear points along edges and a repeated vertex.
        let l_shape = polygon![
            (x: 0.0, y: 0.0), (x: 2.0, y: 0.0), (x: 4.0, y: 0.0), (x: 4.0, y: 2.0),
            (x: 2.0, y: 2.0), (x: 2.0, y: 2.0), (x: 2.0, y: 4.0), (x: 0.0, y: 4.0), (x: 0.0, y: 2.0),
        ];
        let mesh = extrude_polygon(&l_shape, 0.0, 3.0);
        let roof = area_facing(&mesh, Vec3::Z);
        assert!((roof - 12.0).abs() < 1e-4, "roof area {roof}");
        for t in mesh.triangles() {
            assert!(normal(t).length() > 1e-6, "degenerate triangle {t:?}");
        }
        // Walls: 8 distinct edges × 3 m high, perimeter 16 m.
        let walls: f32 = mesh
            .triangles()
            .map(normal)
            .filter(|n| n.z.abs() < 1e-3)
            .map(|n| n.length() * 0.5)
            .sum();
        assert!((walls - 16.0 * 3.0).abs() < 1e-3, "wall area {walls}");
        // Degenerate input never panics.
        let line = polygon![(x: 0.0, y: 0.0), (x: 1.0, y: 0.0), (x: 2.0, y: 0.0)];
        let mesh = extrude_polygon(&line, 0.0, 1.0);
        assert_eq!(area_facing(&mesh, Vec3::Z), 0.0);
        let bad = polygon![(x: 0.0, y: 0.0), (x: f64::NAN, y: 0.0), (x: 1.0, y: 1.0)];
        let _ = extrude_polygon(&bad, 0.0, 1.0);
        assert!(extrude_polygon(&l_shape, 3.0, 3.0).indices.is_empty());
    }
}
