//! The shell of a building mesh: which way its faces point and whether it encloses a volume.
//!
//! The containment argument of [`super`] walks down from an upward-facing triangle through a
//! *closed* solid, so it needs every triangle wound outward and a shell without gaps. LoD2
//! data guarantee neither: faces wound clockwise beside counter-clockwise ones, shells with a
//! missing face, terraced houses whose party walls are stored once or not at all.
//!
//! * **Orientation** ([`orient`]): the winding is made consistent by propagating it across
//!   edges shared by exactly two triangles (the breadth-first step of mesh repair, as in
//!   Botsch et al., *Polygon Mesh Processing*, 2010, on orientation), then each connected piece
//!   is turned outward: a closed one by the sign of its volume (about its own centroid), an
//!   open one by the winding of most of its area, and the open ones together by their volume
//!   about the mesh's centroid. The plain signed volume Σ a·(b×c)/6 of the whole mesh, used
//!   before, is measured about the frame's origin; for an open shell it depends on where the
//!   building stands in the city, and it turned whole houses upside down.
//! * **Closure** ([`closure`]): boundary edges (used by an odd number of triangles) are split at
//!   the boundary vertices lying on them, so a T-junction (one long edge against two short
//!   ones) closes, and the rest are chained into holes. No hole: closed. One planar hole (a
//!   missing face): as good as closed, since a ray entering through the hole crosses its plane
//!   once and must leave through a face, so every view sees the silhouette of the solid with
//!   the hole capped. Two holes or more let rays pass through (an inner terraced house without
//!   its party walls is a tube): no region under the roof is safe to fill, and the facade may
//!   keep only walls lying on the building's own wall faces ([`walls_on_faces`]).

use std::collections::{HashMap, VecDeque};

use citywalk_scenes::TriangleMesh;
use geo::{Area, BooleanOps, Coord, LineString, MultiPolygon, Polygon, Rect, unary_union};
use glam::DVec3;

/// A triangle's corners in f64.
pub type Tri = [DVec3; 3];

/// Corners closer than this (m) to a plane or line lie on it; larger than f32 rounding at city
/// coordinates, smaller than any wall thickness.
const ON_TOLERANCE_M: f64 = 0.01;

/// Shells with more boundary edges than this are not searched for T-junctions (quadratic);
/// their edges count as they are, which can only report more holes (the safe side).
const MAX_BOUNDARY_EDGES: usize = 4096;

/// Whether a shell encloses a volume.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Closure {
    /// No gap, or one planar gap: the solid is well defined.
    Closed,
    /// This many gaps (or one that is not planar): rays may pass through the shell.
    Open { holes: usize },
}

/// Exact weld key of a corner (corners come from f32, so equal points have equal bits).
fn key(p: DVec3) -> [u64; 3] {
    [p.x.to_bits(), p.y.to_bits(), p.z.to_bits()]
}

/// Vertex ids of the triangles after welding equal corners; degenerate triangles (two equal
/// corners) get `None`.
fn welded(tris: &[Tri]) -> (Vec<Option<[usize; 3]>>, Vec<DVec3>) {
    let mut ids: HashMap<[u64; 3], usize> = HashMap::new();
    let mut points = Vec::new();
    let faces = tris
        .iter()
        .map(|t| {
            let v = t.map(|p| {
                *ids.entry(key(p)).or_insert_with(|| {
                    points.push(p);
                    points.len() - 1
                })
            });
            (v[0] != v[1] && v[1] != v[2] && v[0] != v[2]).then_some(v)
        })
        .collect();
    (faces, points)
}

/// Undirected edge key.
fn edge(a: usize, b: usize) -> (usize, usize) {
    (a.min(b), a.max(b))
}

/// Winds every triangle outward (see the module doc): consistently across shared edges; a
/// closed piece so that it encloses a positive volume; an open piece (a shell with a gap, or a
/// fragment joined to the rest only at T-junctions) as most of its area was wound in the file,
/// and all open pieces together so that they enclose a positive volume about the mesh's
/// centroid.
pub fn orient(tris: &mut [Tri]) {
    let (faces, _) = welded(tris);
    let mut uses: HashMap<(usize, usize), Vec<usize>> = HashMap::new();
    for (t, f) in faces.iter().enumerate() {
        if let Some(v) = f {
            for k in 0..3 {
                uses.entry(edge(v[k], v[(k + 1) % 3])).or_default().push(t);
            }
        }
    }
    let mut flip: Vec<Option<bool>> = vec![None; tris.len()];
    let mut open_pieces: Vec<usize> = Vec::new();
    for seed in 0..tris.len() {
        if flip[seed].is_some() || faces[seed].is_none() {
            continue;
        }
        flip[seed] = Some(false);
        let mut piece = vec![seed];
        let mut closed = true;
        let mut queue = VecDeque::from([seed]);
        while let Some(t) = queue.pop_front() {
            let (Some(v), Some(flipped)) = (faces[t], flip[t]) else {
                continue;
            };
            for k in 0..3 {
                // This triangle's edge as wound after its flip; a consistent neighbour runs it
                // the other way.
                let (a, b) = if flipped {
                    (v[(k + 1) % 3], v[k])
                } else {
                    (v[k], v[(k + 1) % 3])
                };
                let users = uses.get(&edge(a, b)).map_or(&[][..], Vec::as_slice);
                let [one, other] = users[..] else {
                    closed = false;
                    continue;
                };
                let n = if one == t { other } else { one };
                if flip[n].is_some() {
                    continue;
                }
                let Some(w) = faces[n] else { continue };
                let same_way = (0..3).any(|j| w[j] == a && w[(j + 1) % 3] == b);
                flip[n] = Some(same_way);
                piece.push(n);
                queue.push_back(n);
            }
        }
        let kept_area: f64 = piece
            .iter()
            .map(|&t| area(&tris[t]) * if flip[t] == Some(true) { -1.0 } else { 1.0 })
            .sum();
        for &t in &piece {
            if flip[t] == Some(true) {
                tris[t].swap(1, 2);
            }
        }
        let turn = if closed {
            signed_volume(tris, &piece, None) < 0.0
        } else {
            kept_area < 0.0
        };
        if turn {
            for &t in &piece {
                tris[t].swap(1, 2);
            }
        }
        if !closed {
            open_pieces.extend(piece);
        }
    }
    let all: Vec<usize> = (0..tris.len()).collect();
    let centre = centroid(tris, &all);
    if signed_volume(tris, &open_pieces, Some(centre)) < 0.0 {
        for &t in &open_pieces {
            tris[t].swap(1, 2);
        }
    }
}

fn area(t: &Tri) -> f64 {
    0.5 * (t[1] - t[0]).cross(t[2] - t[0]).length()
}

/// Mean corner of the triangles `piece` of `tris`.
fn centroid(tris: &[Tri], piece: &[usize]) -> DVec3 {
    let corners = piece.len() as f64 * 3.0;
    piece
        .iter()
        .flat_map(|&t| tris[t])
        .fold(DVec3::ZERO, |s, p| s + p)
        / corners.max(1.0)
}

/// Signed volume of the triangles `piece` of `tris` about `centre` (their own centroid when
/// `None`): exact for a closed piece wherever it stands; for an open one, the volume of the
/// cone from the centre. The plain Σ a·(b×c)/6 is taken about the frame's origin, which for an
/// open piece depends on where the building stands.
fn signed_volume(tris: &[Tri], piece: &[usize], centre: Option<DVec3>) -> f64 {
    let centre = centre.unwrap_or_else(|| centroid(tris, piece));
    piece
        .iter()
        .map(|&t| {
            let [a, b, c] = tris[t].map(|p| p - centre);
            a.dot(b.cross(c))
        })
        .sum::<f64>()
        / 6.0
}

/// Whether the shell of `tris` encloses a volume (see the module doc).
pub fn closure(tris: &[Tri]) -> Closure {
    let (faces, points) = welded(tris);
    let mut count: HashMap<(usize, usize), usize> = HashMap::new();
    for v in faces.iter().flatten() {
        for k in 0..3 {
            *count.entry(edge(v[k], v[(k + 1) % 3])).or_default() += 1;
        }
    }
    let boundary: Vec<(usize, usize)> = count
        .into_iter()
        .filter(|(_, n)| n % 2 == 1)
        .map(|(e, _)| e)
        .collect();
    if boundary.is_empty() {
        return Closure::Closed;
    }
    let open = split_at_t_junctions(&boundary, &points);
    if open.is_empty() {
        return Closure::Closed;
    }
    let holes = chain(&open);
    match holes.as_slice() {
        [one] if planar(one.iter().map(|&i| points[i])) => Closure::Closed,
        _ => Closure::Open { holes: holes.len() },
    }
}

/// The boundary edges left unmatched once every edge is split at the boundary vertices lying
/// on it: pieces used an odd number of times.
fn split_at_t_junctions(boundary: &[(usize, usize)], points: &[DVec3]) -> Vec<(usize, usize)> {
    if boundary.len() > MAX_BOUNDARY_EDGES {
        return boundary.to_vec();
    }
    let mut on_boundary: Vec<usize> = boundary.iter().flat_map(|&(a, b)| [a, b]).collect();
    on_boundary.sort_unstable();
    on_boundary.dedup();
    let mut count: HashMap<(usize, usize), usize> = HashMap::new();
    for &(a, b) in boundary {
        let (pa, pb) = (points[a], points[b]);
        let d = pb - pa;
        let len2 = d.length_squared();
        let mut stops: Vec<(f64, usize)> = vec![(0.0, a), (1.0, b)];
        for &v in &on_boundary {
            if v == a || v == b {
                continue;
            }
            let s = (points[v] - pa).dot(d) / len2;
            if s > 0.0 && s < 1.0 && (pa + d * s).distance(points[v]) <= ON_TOLERANCE_M {
                stops.push((s, v));
            }
        }
        stops.sort_by(|x, y| x.0.total_cmp(&y.0));
        for w in stops.windows(2) {
            *count.entry(edge(w[0].1, w[1].1)).or_default() += 1;
        }
    }
    count
        .into_iter()
        .filter(|(_, n)| n % 2 == 1)
        .map(|(e, _)| e)
        .collect()
}

/// Groups edges into connected chains (the holes), each as its vertex ids.
fn chain(edges: &[(usize, usize)]) -> Vec<Vec<usize>> {
    let mut parent: HashMap<usize, usize> = HashMap::new();
    fn root(parent: &mut HashMap<usize, usize>, v: usize) -> usize {
        let mut r = v;
        while let Some(&p) = parent.get(&r) {
            if p == r {
                break;
            }
            r = p;
        }
        parent.insert(v, r);
        r
    }
    for &(a, b) in edges {
        parent.entry(a).or_insert(a);
        parent.entry(b).or_insert(b);
        let (ra, rb) = (root(&mut parent, a), root(&mut parent, b));
        if ra != rb {
            parent.insert(ra, rb);
        }
    }
    let mut groups: HashMap<usize, Vec<usize>> = HashMap::new();
    let vertices: Vec<usize> = parent.keys().copied().collect();
    for v in vertices {
        let r = root(&mut parent, v);
        groups.entry(r).or_default().push(v);
    }
    let mut holes: Vec<Vec<usize>> = groups.into_values().collect();
    holes.iter_mut().for_each(|h| h.sort_unstable());
    holes
}

/// Whether the points lie in one plane (within [`ON_TOLERANCE_M`]).
fn planar(points: impl Iterator<Item = DVec3>) -> bool {
    let pts: Vec<DVec3> = points.collect();
    let Some(&p0) = pts.first() else { return true };
    let far = |from: &dyn Fn(DVec3) -> f64| {
        pts.iter()
            .copied()
            .max_by(|a, b| from(*a).total_cmp(&from(*b)))
            .unwrap_or(p0)
    };
    let p1 = far(&|p| p.distance(p0));
    let axis = (p1 - p0).normalize_or_zero();
    let p2 = far(&|p| (p - p0).reject_from_normalized(axis).length());
    let normal = axis.cross(p2 - p0).normalize_or_zero();
    if normal == DVec3::ZERO {
        return true;
    }
    pts.iter()
        .all(|p| (*p - p0).dot(normal).abs() <= ON_TOLERANCE_M)
}

/// The wall quads of `facade` (two triangles each, as [`super::facade::facade_mesh`] writes
/// open and wall-oriented walls) that lie on the wall faces of the building `tris`: each quad's
/// rectangle is covered by the building's triangles in its plane. Such a wall is part of the
/// building's own surface, so it can hide nothing the building does not, whatever the shell.
/// Anything else (a roof, a wall standing in a gap or inside) is left out.
pub fn walls_on_faces(tris: &[Tri], facade: &TriangleMesh) -> TriangleMesh {
    let mut out = TriangleMesh::default();
    for quad in facade.indices.chunks_exact(6) {
        let corners: Option<Vec<DVec3>> = quad
            .iter()
            .map(|&i| facade.positions.get(i as usize).map(|p| p.as_dvec3()))
            .collect();
        let Some(c) = corners else { continue };
        // push_wall's layout: a and b at the base, then b and a at the top.
        let (a, b, top) = (c[0], c[1], c[2].z);
        if wall_on_faces(tris, a, b, top) {
            let positions = quad.iter().map(|&i| facade.positions[i as usize]).collect();
            out.append(&TriangleMesh {
                positions,
                indices: (0..6).collect(),
            });
        }
    }
    out
}

/// Whether the vertical rectangle over `a`–`b` (at the base height `a.z`) up to `top` is
/// covered by triangles of `tris` lying in its plane.
fn wall_on_faces(tris: &[Tri], a: DVec3, b: DVec3, top: f64) -> bool {
    let along = DVec3::new(b.x - a.x, b.y - a.y, 0.0);
    let length = along.length();
    if length <= ON_TOLERANCE_M || top - a.z <= ON_TOLERANCE_M {
        return false;
    }
    let dir = along / length;
    let normal = DVec3::new(-dir.y, dir.x, 0.0);
    let in_plane = |p: DVec3| ((p - a).dot(normal)).abs() <= ON_TOLERANCE_M;
    let to_plane = |p: DVec3| Coord {
        x: (p - a).dot(dir),
        y: p.z,
    };
    let pieces: Vec<Polygon<f64>> = tris
        .iter()
        .filter(|t| t.iter().all(|p| in_plane(*p)))
        .map(|t| {
            Polygon::new(
                LineString::from(t.iter().map(|p| to_plane(*p)).collect::<Vec<_>>()),
                Vec::new(),
            )
        })
        .filter(|p| p.unsigned_area() > 1e-9)
        .collect();
    if pieces.is_empty() {
        return false;
    }
    let cover = unary_union(pieces.iter());
    // Shrunk by the tolerance so that rounding along shared edges does not count as a gap.
    let wall = MultiPolygon::new(vec![
        Rect::new(
            Coord {
                x: ON_TOLERANCE_M,
                y: a.z + ON_TOLERANCE_M,
            },
            Coord {
                x: length - ON_TOLERANCE_M,
                y: top - ON_TOLERANCE_M,
            },
        )
        .to_polygon(),
    ]);
    wall.difference(&cover).unsigned_area() <= ON_TOLERANCE_M * ON_TOLERANCE_M
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occluders::facade::facade_mesh;
    use crate::occluders::footprint::tests::box_mesh;
    use citywalk_scenes::occluder::FacadeKind;
    use glam::Vec3;

    fn tris_of(mesh: &TriangleMesh) -> Vec<Tri> {
        mesh.triangles().map(|t| t.map(|p| p.as_dvec3())).collect()
    }

    fn volume(tris: &[Tri]) -> f64 {
        tris.iter().map(|[a, b, c]| a.dot(b.cross(*c))).sum::<f64>() / 6.0
    }

    /// A 10 × 8 × 6 box far from the origin, as the frame places most buildings of a city.
    fn far_box() -> Vec<Tri> {
        tris_of(&box_mesh(
            Vec3::new(400.0, -300.0, 0.0),
            Vec3::new(410.0, -292.0, 6.0),
        ))
    }

    #[test]
    fn mixed_windings_are_made_outward() {
        let closed = far_box();
        let mut mixed = closed.clone();
        for t in [0, 3, 4, 9] {
            mixed[t].swap(1, 2);
        }
        orient(&mut mixed);
        assert!((volume(&mixed) - 480.0).abs() < 1e-6, "{}", volume(&mixed));
        let mut inside_out: Vec<Tri> = closed.iter().map(|t| [t[0], t[2], t[1]]).collect();
        orient(&mut inside_out);
        assert_eq!(inside_out, closed);
    }

    #[test]
    fn an_open_box_far_from_the_origin_keeps_its_roof_up() {
        // Without its east wall (triangles 6, 7 of box_mesh's order: bottom, top, south, east),
        // the volume about the origin is negative here; about its centroid it is not.
        let mut open = far_box();
        open.drain(6..8);
        assert!(volume(&open) < 0.0);
        let mut flipped: Vec<Tri> = open.iter().map(|t| [t[0], t[2], t[1]]).collect();
        orient(&mut flipped);
        assert_eq!(flipped, open);
        orient(&mut open);
        let roof_up =
            open[2][0].z == 6.0 && (open[2][1] - open[2][0]).cross(open[2][2] - open[2][0]).z > 0.0;
        assert!(roof_up, "{:?}", open[2]);
    }

    #[test]
    fn closure_counts_planar_holes() {
        let closed = far_box();
        assert_eq!(closure(&closed), Closure::Closed);
        // One missing face: as good as closed.
        let mut one = closed.clone();
        one.drain(6..8);
        assert_eq!(closure(&one), Closure::Closed);
        // Two opposite walls missing: a tube.
        let mut tube = closed.clone();
        tube.drain(10..12);
        tube.drain(6..8);
        assert_eq!(closure(&tube), Closure::Open { holes: 2 });
        // Half a face missing leaves a hole too.
        let mut half = closed;
        half.remove(6);
        assert_eq!(closure(&half), Closure::Closed);
    }

    #[test]
    fn a_t_junction_is_not_a_hole() {
        // The box's top split into two squares, each split into triangles, the walls whole:
        // the south wall's top edge meets two roof edges.
        let mut tris = far_box();
        tris.drain(2..4);
        let z = 6.0;
        let p = |x: f64, y: f64| DVec3::new(x, y, z);
        for (x0, x1) in [(400.0, 405.0), (405.0, 410.0)] {
            tris.push([p(x0, -300.0), p(x1, -300.0), p(x1, -292.0)]);
            tris.push([p(x0, -300.0), p(x1, -292.0), p(x0, -292.0)]);
        }
        assert_eq!(closure(&tris), Closure::Closed);
    }

    /// The open facade of the rectangle `[x0, x1] × [y0, y1]` from the ground up to `top`.
    fn rect_facade(x0: f64, y0: f64, x1: f64, y1: f64, top: f64) -> TriangleMesh {
        let plan = Rect::new(Coord { x: x0, y: y0 }, Coord { x: x1, y: y1 }).to_polygon();
        facade_mesh(
            &MultiPolygon::new(vec![plan]),
            0.0,
            top,
            FacadeKind::Open,
            |_, _| top,
        )
    }

    #[test]
    fn only_walls_on_the_buildings_faces_are_kept() {
        let tris = far_box();
        let on = rect_facade(400.0, -300.0, 410.0, -292.0, 6.0);
        assert_eq!(walls_on_faces(&tris, &on).triangle_count(), 8);
        // Without the east wall, its quad goes; a wall inside the box has no face under it.
        let mut open = tris.clone();
        open.drain(6..8);
        assert_eq!(walls_on_faces(&open, &on).triangle_count(), 6);
        let inside = rect_facade(402.0, -298.0, 408.0, -294.0, 6.0);
        assert_eq!(walls_on_faces(&tris, &inside).triangle_count(), 0);
        // A wall taller than the face under it is left out.
        let tall = rect_facade(400.0, -300.0, 410.0, -292.0, 7.0);
        assert_eq!(walls_on_faces(&tris, &tall).triangle_count(), 0);
    }
}
