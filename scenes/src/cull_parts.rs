//! A building's tight cull bounds ([`CullPart`]s): one oriented prism per connected piece of
//! its mesh (a tower and its podium are two), each the minimum-area rectangle of the piece's
//! vertices in plan (Freeman & Shapira, *Determining the minimum-area encasing rectangle for an
//! arbitrary closed curve*, CACM 1975: a side lies on an edge of the convex hull), found by
//! rotating calipers in time linear in the hull (Toussaint, *Solving geometric problems with
//! the rotating calipers*, MELECON 1983 §3; `geo`'s `MinimumRotatedRect` measures the whole hull
//! for each edge, quadratic on a round 40,000-vertex stadium) and extruded over the piece's
//! height range.
//!
//! Why: the occlusion cull tests a building by the screen rectangle and nearest depth of its
//! bounds. City blocks are rarely aligned with the axes, and the axis-aligned box of a rotated
//! footprint covers about twice its area (the generated city: median footprint / box area
//! 0.46), reaching into the street and above the roofline beside it; the box of a tower on a
//! podium carries the tower's height over the whole podium.
//!
//! Conservative: each prism contains every vertex of its piece, so (convex) every triangle of
//! it. The rectangle is measured in `f64` and grown by [`margin_m`] before its corners are
//! rounded to `f32`, so the rounding cannot move a side inside a vertex.

use citywalk_shaders::CullPart;
use geo::{ConvexHull, Coord, MultiPoint, Point};
use glam::Vec3;
use petgraph::unionfind::UnionFind;

/// More pieces than this and the building gets one prism around all of them: an unwelded
/// mesh (one piece per face, as some CityJSON and glTF files are) would otherwise cost a part
/// per face in the cull for little gain.
pub const MAX_PARTS_PER_BUILDING: usize = 8;

/// The parts of one mesh (`positions`, triangle list `indices` into them; indices out of range
/// are ignored, as the scene drops those triangles), or none when a vertex is not finite (the
/// building is then culled by its axis-aligned box alone).
pub fn cull_parts(positions: &[Vec3], indices: &[u32]) -> Vec<CullPart> {
    let n = positions.len();
    let mut pieces = UnionFind::<usize>::new(n);
    let mut used = vec![false; n];
    for t in indices.chunks_exact(3) {
        if t.iter().any(|&v| v as usize >= n) {
            continue;
        }
        for &v in t {
            used[v as usize] = true;
        }
        pieces.union(t[0] as usize, t[1] as usize);
        pieces.union(t[0] as usize, t[2] as usize);
    }
    // Vertices by piece, pieces in the order of their first vertex.
    let mut piece_of_root = vec![usize::MAX; n];
    let mut groups: Vec<Vec<Vec3>> = Vec::new();
    for v in (0..n).filter(|&v| used[v]) {
        let root = pieces.find_mut(v);
        if piece_of_root[root] == usize::MAX {
            piece_of_root[root] = groups.len();
            groups.push(Vec::new());
        }
        groups[piece_of_root[root]].push(positions[v]);
    }
    if groups.len() > MAX_PARTS_PER_BUILDING {
        groups = vec![groups.concat()];
    }
    groups
        .iter()
        .map(|points| enclosing_prism(points))
        .collect::<Option<Vec<_>>>()
        .unwrap_or_default()
}

/// How far the rectangle is grown before rounding: many times the largest rounding of a
/// coordinate of magnitude `max_abs_m` to `f32` (half an ulp, 6e-8 relative), plus 0.1 mm.
pub fn margin_m(max_abs_m: f64) -> f64 {
    4e-7 * max_abs_m + 1e-4
}

/// The minimum-area oriented prism around `points` (non-empty); `None` if one is not finite.
fn enclosing_prism(points: &[Vec3]) -> Option<CullPart> {
    if points.is_empty() || points.iter().any(|p| !p.is_finite()) {
        return None;
    }
    let plan: MultiPoint<f64> = points
        .iter()
        .map(|p| Point::new(f64::from(p.x), f64::from(p.y)))
        .collect();
    // The best hull edge gives the rectangle's axes; every point coincides in plan (a vertical
    // needle) or the hull is degenerate: the axes of the scene.
    let (ux, uy) = min_area_axis(&plan.convex_hull().exterior().0).unwrap_or((1.0, 0.0));
    let (vx, vy) = (-uy, ux);
    let (mut a0, mut a1, mut b0, mut b1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
    let mut max_abs = 0.0f64;
    for p in &plan {
        let (x, y) = p.x_y();
        let (a, b) = (x * ux + y * uy, x * vx + y * vy);
        (a0, a1, b0, b1) = (a0.min(a), a1.max(a), b0.min(b), b1.max(b));
        max_abs = max_abs.max(x.abs()).max(y.abs());
    }
    let m = margin_m(max_abs);
    let (a0, a1, b0, b1) = (a0 - m, a1 + m, b0 - m, b1 + m);
    let corner = |a: f64, b: f64| [(ux * a + vx * b) as f32, (uy * a + vy * b) as f32];
    let [c0, c1, c2, c3] = [
        corner(a0, b0),
        corner(a1, b0),
        corner(a1, b1),
        corner(a0, b1),
    ];
    let z_min = points.iter().map(|p| p.z).fold(f32::INFINITY, f32::min);
    let z_max = points.iter().map(|p| p.z).fold(f32::NEG_INFINITY, f32::max);
    Some(CullPart {
        corners_xy: [[c0[0], c0[1], c1[0], c1[1]], [c2[0], c2[1], c3[0], c3[1]]],
        z_min_m: z_min,
        z_max_m: z_max,
        _pad0: 0,
        _pad1: 0,
    })
}

/// The unit direction of the hull edge on which the minimum-area rectangle lies (`hull`
/// closed, either orientation), by rotating calipers: for each edge in turn, the farthest
/// points along it, against it and away from it move forward monotonically around the hull.
fn min_area_axis(hull: &[Coord<f64>]) -> Option<(f64, f64)> {
    let mut h: Vec<Coord<f64>> = hull.get(..hull.len().saturating_sub(1))?.to_vec();
    h.dedup();
    let m = h.len();
    if m < 3 {
        // Collinear points (a wall sheet): the line's direction.
        let (dx, dy) = (h.get(1)?.x - h[0].x, h[1].y - h[0].y);
        let length = dx.hypot(dy);
        return (length > 0.0 && length.is_finite()).then(|| (dx / length, dy / length));
    }
    // Relative to one vertex, for precision; counter-clockwise.
    let o = h[0];
    h.iter_mut().for_each(|c| *c = *c - o);
    let twice_area: f64 = (0..m)
        .map(|i| h[i].x * h[(i + 1) % m].y - h[(i + 1) % m].x * h[i].y)
        .sum();
    if twice_area < 0.0 {
        h.reverse();
    }
    let dot = |u: (f64, f64), c: Coord<f64>| u.0 * c.x + u.1 * c.y;
    // Advances `k` while the next vertex scores higher (at most one lap).
    let advance = |k: &mut usize, score: &dyn Fn(Coord<f64>) -> f64| {
        for _ in 0..m {
            if score(h[(*k + 1) % m]) > score(h[*k]) {
                *k = (*k + 1) % m;
            } else {
                break;
            }
        }
    };
    let argmax = |score: &dyn Fn(Coord<f64>) -> f64| {
        (0..m)
            .max_by(|&a, &b| score(h[a]).total_cmp(&score(h[b])))
            .unwrap_or(0)
    };
    let mut best: Option<(f64, (f64, f64))> = None;
    let (mut far, mut ahead, mut behind) = (0, 0, 0);
    for i in 0..m {
        let (a, b) = (h[i], h[(i + 1) % m]);
        let (dx, dy) = (b.x - a.x, b.y - a.y);
        let length = dx.hypot(dy);
        if !(length > 0.0 && length.is_finite()) {
            continue;
        }
        let u = (dx / length, dy / length);
        let along = |c: Coord<f64>| dot(u, c);
        let against = |c: Coord<f64>| -dot(u, c);
        let away = |c: Coord<f64>| dot((-u.1, u.0), c);
        if best.is_none() {
            (ahead, behind, far) = (argmax(&along), argmax(&against), argmax(&away));
        }
        advance(&mut ahead, &along);
        advance(&mut behind, &against);
        advance(&mut far, &away);
        let area = (along(h[ahead]) - along(h[behind])) * (away(h[far]) - away(a));
        if best.is_none_or(|(min, _)| area < min) {
            best = Some((area, u));
        }
    }
    best.map(|(_, u)| u)
}

/// Whether `p` lies in `part` (in plan: on the inner side of all four sides, computed in
/// `f64`; in height: between its floor and roof).
pub fn part_contains(part: &CullPart, p: Vec3) -> bool {
    let c = part.corners();
    if p.z < part.z_min_m || p.z > part.z_max_m {
        return false;
    }
    let (px, py) = (f64::from(p.x), f64::from(p.y));
    // Corners run counter-clockwise (the rectangle's axes u, v = u rotated by +90°).
    (0..4).all(|k| {
        let (ax, ay) = (f64::from(c[k][0]), f64::from(c[k][1]));
        let (bx, by) = (f64::from(c[(k + 1) % 4][0]), f64::from(c[(k + 1) % 4][1]));
        (bx - ax) * (py - ay) - (by - ay) * (px - ax) >= 0.0
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// A closed prism over `ring` (counter-clockwise), walls and caps sharing vertices.
    fn prism(ring: &[(f32, f32)], z0: f32, z1: f32, base: u32) -> (Vec<Vec3>, Vec<u32>) {
        let n = ring.len() as u32;
        let mut positions: Vec<Vec3> = ring.iter().map(|&(x, y)| Vec3::new(x, y, z0)).collect();
        positions.extend(ring.iter().map(|&(x, y)| Vec3::new(x, y, z1)));
        let mut indices = Vec::new();
        for i in 0..n {
            let j = (i + 1) % n;
            indices.extend([i, j, n + j, i, n + j, n + i].map(|v| v + base));
        }
        for i in 1..n - 1 {
            indices.extend([0, i, i + 1].map(|v| v + base));
            indices.extend([n, n + i + 1, n + i].map(|v| v + base));
        }
        (positions, indices)
    }

    #[test]
    fn a_rotated_tower_on_a_podium_gets_two_tight_prisms() {
        let (c, s) = (30f32.to_radians().cos(), 30f32.to_radians().sin());
        let rotated = |w: f32, d: f32| -> Vec<(f32, f32)> {
            [(0.0, 0.0), (w, 0.0), (w, d), (0.0, d)]
                .iter()
                .map(|&(x, y)| (4000.0 + c * x - s * y, -2500.0 + s * x + c * y))
                .collect()
        };
        let (mut positions, mut indices) = prism(&rotated(40.0, 30.0), 0.0, 12.0, 0);
        let (tower, tower_indices) = prism(&rotated(10.0, 10.0), 12.0, 120.0, 8);
        positions.extend(tower);
        indices.extend(tower_indices);
        let parts = cull_parts(&positions, &indices);
        assert_eq!(parts.len(), 2);
        let area = |p: &CullPart| {
            let c = p.corners();
            let side = |a: usize, b: usize| {
                ((c[a][0] - c[b][0]).powi(2) + (c[a][1] - c[b][1]).powi(2)).sqrt()
            };
            side(0, 1) * side(1, 2)
        };
        // Each prism is its footprint grown by the margin, far below the axis-aligned box's
        // (40 × 30 rotated by 30°: 49.6 × 46.0).
        assert!(
            (area(&parts[0]) - 1200.0).abs() < 1.0,
            "{}",
            area(&parts[0])
        );
        assert!((area(&parts[1]) - 100.0).abs() < 0.5, "{}", area(&parts[1]));
        assert_eq!((parts[0].z_min_m, parts[0].z_max_m), (0.0, 12.0));
        assert_eq!((parts[1].z_min_m, parts[1].z_max_m), (12.0, 120.0));
        for (i, p) in positions.iter().enumerate() {
            let part = &parts[usize::from(i >= 8)];
            assert!(part_contains(part, *p), "vertex {i} {p}");
        }
    }

    #[test]
    fn rotating_calipers_match_geo_on_random_hulls() {
        use geo::{Area, MinimumRotatedRect};
        use rand::{RngExt, SeedableRng};
        let mut rng = rand_chacha::ChaCha8Rng::seed_from_u64(14);
        for _ in 0..200 {
            let n = rng.random_range(3..60);
            let points: MultiPoint<f64> = (0..n)
                .map(|_| Point::new(rng.random_range(-50.0..50.0), rng.random_range(-20.0..20.0)))
                .collect();
            let Some(expected) = points.minimum_rotated_rect() else {
                continue;
            };
            let (ux, uy) = min_area_axis(&points.convex_hull().exterior().0).unwrap();
            let (mut a0, mut a1, mut b0, mut b1) = (f64::MAX, f64::MIN, f64::MAX, f64::MIN);
            for p in &points {
                let (a, b) = (p.x() * ux + p.y() * uy, p.y() * ux - p.x() * uy);
                (a0, a1, b0, b1) = (a0.min(a), a1.max(a), b0.min(b), b1.max(b));
            }
            let area = (a1 - a0) * (b1 - b0);
            let want = expected.unsigned_area();
            assert!(
                (area - want).abs() <= 1e-9 * want.max(1.0),
                "{area} vs {want}"
            );
        }
    }

    #[test]
    fn a_round_40000_vertex_hull_is_linear() {
        // Issue 14 case 3: `geo`'s rectangle measured the whole hull for each of its edges.
        let n = 40_000;
        let ring: Vec<(f32, f32)> = (0..n)
            .map(|i| {
                let t = std::f32::consts::TAU * i as f32 / n as f32;
                (60.0 * t.cos(), 60.0 * t.sin())
            })
            .collect();
        let (positions, indices) = prism(&ring, 0.0, 10.0, 0);
        let start = std::time::Instant::now();
        let parts = cull_parts(&positions, &indices);
        assert!(start.elapsed().as_secs_f64() < 2.0, "{:?}", start.elapsed());
        assert!(positions.iter().all(|p| part_contains(&parts[0], *p)));
    }

    #[test]
    fn degenerate_and_bad_meshes() {
        // A vertical needle (every vertex at one plan point) and a wall sheet (collinear in
        // plan): thin prisms that still contain them.
        let needle = [
            Vec3::new(5.0, 5.0, 0.0),
            Vec3::new(5.0, 5.0, 9.0),
            Vec3::new(5.0, 5.0, 3.0),
        ];
        let wall = [
            Vec3::new(0.0, 0.0, 0.0),
            Vec3::new(10.0, 10.0, 0.0),
            Vec3::new(10.0, 10.0, 8.0),
        ];
        for mesh in [&needle, &wall] {
            let parts = cull_parts(mesh, &[0, 1, 2]);
            assert_eq!(parts.len(), 1);
            assert!(mesh.iter().all(|p| part_contains(&parts[0], *p)));
        }
        // Not finite: no parts (the axis-aligned box alone); no triangles: no parts.
        let bad = [Vec3::ZERO, Vec3::new(f32::NAN, 0.0, 0.0), Vec3::ONE];
        assert!(cull_parts(&bad, &[0, 1, 2]).is_empty());
        assert!(cull_parts(&needle, &[]).is_empty());
        // Indices out of range are skipped, as the scene skips their triangles.
        assert_eq!(cull_parts(&needle, &[0, 1, 7, 0, 1, 2]).len(), 1);
        // Many pieces (an unwelded mesh): one prism around all.
        let mut positions = Vec::new();
        let mut indices = Vec::new();
        for k in 0..(MAX_PARTS_PER_BUILDING as u32 + 3) {
            let x = k as f32 * 3.0;
            positions.extend([
                Vec3::new(x, 0.0, 0.0),
                Vec3::new(x + 1.0, 0.0, 0.0),
                Vec3::new(x, 1.0, 4.0),
            ]);
            indices.extend([3 * k, 3 * k + 1, 3 * k + 2]);
        }
        let parts = cull_parts(&positions, &indices);
        assert_eq!(parts.len(), 1);
        assert!(positions.iter().all(|p| part_contains(&parts[0], *p)));
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(11), ..ProptestConfig::default() })]
        /// Every vertex of every triangle lies in a part, and the triangle's three vertices in
        /// the same one: random pieces (rotated prisms and loose triangles) anywhere in a city
        /// up to 50 km across.
        #[test]
        fn parts_contain_every_triangle(
            pieces in proptest::collection::vec(
                (-25_000.0f32..25_000.0, -25_000.0f32..25_000.0, 0.0f32..6.3, 0.01f32..80.0,
                 0.01f32..80.0, -5.0f32..50.0, 0.0f32..200.0, 3usize..9, any::<bool>()),
                1..12,
            ),
        ) {
            let mut positions = Vec::new();
            let mut indices = Vec::new();
            for &(x, y, angle, w, d, z, h, sides, loose) in &pieces {
                // Pieces near one another, as the parts of one building are.
                let (x, y) = (x * 1e-3 + pieces[0].0, y * 1e-3 + pieces[0].1);
                let ring: Vec<(f32, f32)> = (0..sides)
                    .map(|i| {
                        let t = angle + i as f32 * std::f32::consts::TAU / sides as f32;
                        (x + w * t.cos(), y + d * t.sin())
                    })
                    .collect();
                let base = positions.len() as u32;
                if loose {
                    positions.extend(ring.iter().take(3).enumerate().map(|(i, &(px, py))| {
                        Vec3::new(px, py, z + h * i as f32 / 2.0)
                    }));
                    indices.extend([base, base + 1, base + 2]);
                } else {
                    let (p, i) = prism(&ring, z, z + h, base);
                    positions.extend(p);
                    indices.extend(i);
                }
            }
            let parts = cull_parts(&positions, &indices);
            prop_assert!(!parts.is_empty() && parts.len() <= MAX_PARTS_PER_BUILDING);
            for t in indices.chunks_exact(3) {
                let inside = parts.iter().any(|part| {
                    t.iter().all(|&v| part_contains(part, positions[v as usize]))
                });
                prop_assert!(inside, "triangle {t:?} outside every part");
            }
        }
    }
}
