//! Polygon counts as Germs & Jansen count them (§4.2, Table 1): a polygon is a planar face —
//! a wall quad is one polygon, a roof polygon one — not a triangle.
//!
//! Meshes in citywalk are triangulated, so polygons are recovered the same way for the source
//! building and for its facade: corners are welded by exact position, and triangles that share
//! an edge and lie in the same plane (same orientation) are one face. Counting both sides with
//! one rule keeps the reduction honest; on Den Haag LoD2 it gives slightly fewer faces than the
//! CityJSON file has surfaces (coplanar neighbouring surfaces, e.g. a wall split at a part
//! boundary, count once).

use std::collections::HashMap;

use citywalk_scenes::TriangleMesh;
use glam::DVec3;

/// Normals closer than this (1 − cos) are parallel (about 0.8°).
const PARALLEL_1_MINUS_COS: f64 = 1e-4;
/// A corner within this of the other triangle's plane lies in it (metres).
const PLANE_TOLERANCE_M: f64 = 0.01;

/// Number of planar faces of `mesh` (see the module doc). Degenerate triangles and triangles
/// with an index out of range are not counted.
pub fn planar_face_count(mesh: &TriangleMesh) -> usize {
    let key = |i: u32| {
        mesh.positions
            .get(i as usize)
            .map(|p| [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()])
    };
    let mut welded: HashMap<[u32; 3], u32> = HashMap::new();
    let mut tris: Vec<([u32; 3], DVec3, DVec3)> = Vec::with_capacity(mesh.triangle_count());
    for t in mesh.indices.chunks_exact(3) {
        let (Some(a), Some(b), Some(c)) = (key(t[0]), key(t[1]), key(t[2])) else {
            continue;
        };
        let corners = [a, b, c].map(|k| {
            let next = welded.len() as u32;
            *welded.entry(k).or_insert(next)
        });
        let p = [t[0], t[1], t[2]].map(|i| mesh.positions[i as usize].as_dvec3());
        let n = (p[1] - p[0]).cross(p[2] - p[0]);
        let len = n.length();
        if corners[0] == corners[1] || corners[1] == corners[2] || corners[0] == corners[2] {
            continue;
        }
        if !(len > 1e-12 && len.is_finite()) {
            continue;
        }
        tris.push((corners, n / len, p[0]));
    }
    let mut parent: Vec<usize> = (0..tris.len()).collect();
    let mut by_edge: HashMap<(u32, u32), Vec<usize>> = HashMap::new();
    for (i, (c, _, _)) in tris.iter().enumerate() {
        for k in 0..3 {
            let (u, v) = (c[k], c[(k + 1) % 3]);
            by_edge.entry((u.min(v), u.max(v))).or_default().push(i);
        }
    }
    for sharing in by_edge.values() {
        for (x, &i) in sharing.iter().enumerate() {
            for &j in &sharing[x + 1..] {
                if coplanar(&tris[i], &tris[j]) {
                    let (ri, rj) = (find(&mut parent, i), find(&mut parent, j));
                    parent[ri] = rj;
                }
            }
        }
    }
    (0..tris.len())
        .filter(|&i| find(&mut parent, i) == i)
        .count()
}

fn coplanar(a: &([u32; 3], DVec3, DVec3), b: &([u32; 3], DVec3, DVec3)) -> bool {
    a.1.dot(b.1) >= 1.0 - PARALLEL_1_MINUS_COS && (b.2 - a.2).dot(a.1).abs() <= PLANE_TOLERANCE_M
}

fn find(parent: &mut [usize], mut i: usize) -> usize {
    while parent[i] != i {
        parent[i] = parent[parent[i]];
        i = parent[i];
    }
    i
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occluders::facade::facade_mesh;
    use citywalk_scenes::occluder::FacadeKind;
    use geo::{MultiPolygon, Rect, coord, polygon};

    #[test]
    fn a_prism_has_five_faces_and_its_open_facade_four() {
        let square = Rect::new(coord! {x: 0.0, y: 0.0}, coord! {x: 10.0, y: 4.0}).to_polygon();
        let prism = citywalk_scenes::extrude::extrude_polygon(&square, 0.0, 9.0);
        // Four walls and a roof (extrusion leaves the floor out).
        assert_eq!(prism.triangle_count(), 10);
        assert_eq!(planar_face_count(&prism), 5);
        let open = facade_mesh(
            &MultiPolygon::new(vec![square]),
            0.0,
            9.0,
            FacadeKind::Open,
            |_, _| 0.0,
        );
        assert_eq!(open.triangle_count(), 8);
        assert_eq!(planar_face_count(&open), 4);
    }

    #[test]
    fn an_l_shaped_prism_roof_is_one_face_however_triangulated() {
        let l = polygon![
            (x: 0.0, y: 0.0), (x: 10.0, y: 0.0), (x: 10.0, y: 4.0), (x: 4.0, y: 4.0),
            (x: 4.0, y: 10.0), (x: 0.0, y: 10.0)
        ];
        let prism = citywalk_scenes::extrude::extrude_polygon(&l, 0.0, 6.0);
        // Six walls and a roof.
        assert!(prism.triangle_count() > 7);
        assert_eq!(planar_face_count(&prism), 7);
    }

    #[test]
    fn bent_and_degenerate_triangles() {
        // Two triangles sharing an edge, folded 90°: two faces. A degenerate one is ignored.
        let mesh = TriangleMesh {
            positions: vec![
                glam::Vec3::new(0.0, 0.0, 0.0),
                glam::Vec3::new(1.0, 0.0, 0.0),
                glam::Vec3::new(0.0, 1.0, 0.0),
                glam::Vec3::new(0.0, 0.0, 1.0),
            ],
            indices: vec![0, 1, 2, 0, 3, 1, 0, 0, 1, 0, 1, 99],
        };
        assert_eq!(planar_face_count(&mesh), 2);
        assert_eq!(planar_face_count(&TriangleMesh::default()), 0);
    }
}
