//! Facades from simplified footprints (Germs & Jansen §3.4, Fig. 5).
//!
//! * open: one vertical wall (two triangles) per footprint edge, from the base to Z;
//! * closed: the open walls and a roof at Z (the footprint extruded by
//!   [`citywalk_scenes::extrude::extrude_polygon`], roof by constrained Delaunay);
//! * wall-oriented: open walls, each as high as the building is along its edge ("the minimum Z
//!   found along the edge defining the wall"), never lower than Z.
//!
//! Triangles are counter-clockwise seen from outside the building (holes' walls face into the
//! courtyard), like every mesh of the city model.

use citywalk_scenes::TriangleMesh;
use citywalk_scenes::extrude::extrude_polygon;
use citywalk_scenes::occluder::FacadeKind;
use geo::{Coord, MultiPolygon, Orient, orient::Direction};
use glam::Vec3;

/// Builds the facade of one level: `footprint` between `base_m` and `z_m`. For wall-oriented
/// facades, `edge_top_m(a, b)` gives the wall height of edge a→b (it is clamped to at least
/// `z_m`); other kinds ignore it.
pub fn facade_mesh(
    footprint: &MultiPolygon<f64>,
    base_m: f64,
    z_m: f64,
    kind: FacadeKind,
    mut edge_top_m: impl FnMut(Coord<f64>, Coord<f64>) -> f64,
) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    if !(base_m.is_finite() && z_m.is_finite()) || z_m <= base_m {
        return mesh;
    }
    for polygon in footprint {
        match kind {
            FacadeKind::Closed => {
                mesh.append(&extrude_polygon(polygon, base_m as f32, z_m as f32));
            }
            FacadeKind::Open | FacadeKind::WallOriented => {
                // Exterior counter-clockwise, holes clockwise: the solid is left of each edge.
                let polygon = polygon.orient(Direction::Default);
                for ring in std::iter::once(polygon.exterior()).chain(polygon.interiors()) {
                    for line in ring.lines() {
                        let (a, b) = (line.start, line.end);
                        if a == b || !(a.x.is_finite() && a.y.is_finite()) {
                            continue;
                        }
                        let top = match kind {
                            FacadeKind::WallOriented => edge_top_m(a, b).max(z_m),
                            _ => z_m,
                        };
                        push_wall(&mut mesh, a, b, base_m as f32, top as f32);
                    }
                }
            }
        }
    }
    mesh
}

/// One wall quad over edge a→b with the solid on the edge's left: its normal points right.
fn push_wall(mesh: &mut TriangleMesh, a: Coord<f64>, b: Coord<f64>, base_m: f32, top_m: f32) {
    let i = mesh.positions.len() as u32;
    let (ax, ay, bx, by) = (a.x as f32, a.y as f32, b.x as f32, b.y as f32);
    mesh.positions.extend_from_slice(&[
        Vec3::new(ax, ay, base_m),
        Vec3::new(bx, by, base_m),
        Vec3::new(bx, by, top_m),
        Vec3::new(ax, ay, top_m),
    ]);
    mesh.indices
        .extend_from_slice(&[i, i + 1, i + 2, i, i + 2, i + 3]);
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::{Rect, coord};

    fn square() -> MultiPolygon<f64> {
        MultiPolygon::new(vec![
            Rect::new(coord! {x: 0.0, y: 0.0}, coord! {x: 10.0, y: 10.0}).to_polygon(),
        ])
    }

    fn outward_normals_point_away_from_centre(mesh: &TriangleMesh, centre: Vec3) {
        for [a, b, c] in mesh.triangles() {
            let n = (b - a).cross(c - a);
            let mid = (a + b + c) / 3.0;
            if n.z.abs() < 1e-6 {
                let out = Vec3::new(mid.x - centre.x, mid.y - centre.y, 0.0);
                assert!(n.dot(out) > 0.0, "wall normal {n} at {mid}");
            } else {
                assert!(n.z > 0.0, "roof normal {n}");
            }
        }
    }

    #[test]
    fn open_facade_has_two_triangles_per_edge() {
        let m = facade_mesh(&square(), 0.0, 8.0, FacadeKind::Open, |_, _| 99.0);
        assert_eq!(m.triangle_count(), 8);
        let (lo, hi) = m.bounds().unwrap();
        assert_eq!((lo.z, hi.z), (0.0, 8.0));
        outward_normals_point_away_from_centre(&m, Vec3::new(5.0, 5.0, 0.0));
    }

    #[test]
    fn closed_facade_adds_a_roof() {
        let m = facade_mesh(&square(), 0.0, 8.0, FacadeKind::Closed, |_, _| 99.0);
        assert_eq!(m.triangle_count(), 10);
        outward_normals_point_away_from_centre(&m, Vec3::new(5.0, 5.0, 0.0));
    }

    #[test]
    fn wall_oriented_walls_take_their_edge_height_but_not_less_than_z() {
        let m = facade_mesh(&square(), 0.0, 8.0, FacadeKind::WallOriented, |a, b| {
            if a.y == 0.0 && b.y == 0.0 { 12.0 } else { 3.0 }
        });
        assert_eq!(m.triangle_count(), 8);
        let south_top = m
            .positions
            .iter()
            .filter(|p| p.y == 0.0)
            .map(|p| p.z)
            .fold(0.0, f32::max);
        let north_top = m
            .positions
            .iter()
            .filter(|p| p.y == 10.0)
            .map(|p| p.z)
            .fold(0.0, f32::max);
        assert_eq!(south_top, 12.0);
        assert_eq!(north_top, 8.0);
    }

    #[test]
    fn degenerate_heights_give_an_empty_mesh() {
        assert!(
            facade_mesh(&square(), 5.0, 5.0, FacadeKind::Open, |_, _| 0.0)
                .indices
                .is_empty()
        );
        assert!(
            facade_mesh(&square(), 0.0, f64::NAN, FacadeKind::Closed, |_, _| 0.0)
                .indices
                .is_empty()
        );
    }
}
