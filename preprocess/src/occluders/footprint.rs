//! Footprints of Z-levels of a mesh building (Germs & Jansen §3.3), made conservative.
//!
//! The paper traces the outer contour of a level's projected polygons with a quadtree. Here
//! the contour comes from `geo`'s unary union (i_overlay), and the region is the one argued in
//! the module doc of [`super`]: the union of the upward-facing triangles *clipped to z ≥ Z*,
//! projected, minus the projection of every overhang underside, holes kept. Regions are built
//! from the top level down, each adding the newly exposed triangle pieces to the one above.

use geo::{
    Area, BooleanOps, BoundingRect, Coord, Intersects, LineString, MultiPolygon, Polygon,
    unary_union,
};
use glam::DVec3;

use super::OccluderParams;
use super::cover::RegionCover;
use super::shell::{self, Closure};
use super::zlevels::{LevelCandidate, cluster_heights};
use citywalk_scenes::TriangleMesh;

/// Holes smaller than this (m²) in a union are gaps between adjacent triangles left by f32
/// rounding, not courtyards; they are closed. Real holes are kept.
const ROUNDING_GAP_M2: f64 = 0.01;

/// Triangles of a building mesh sorted for footprint work.
#[derive(Debug, Clone)]
pub struct MeshRegions {
    /// The shell when it has gaps that rays may pass through ([`shell::closure`]); `None` for
    /// a closed shell.
    pub open_shell: Option<OpenShell>,
    /// Upward-facing triangles (corners in f64), with their lowest and highest z.
    roofs: Vec<([DVec3; 3], f64, f64)>,
    /// Projection of the downward-facing triangles above the ground band (overhangs).
    overhang: MultiPolygon<f64>,
    /// The building's groundplane: the mesh's lowest point.
    pub base_m: f64,
    /// Ground faces (downward, within the ground band), projected, with their highest z.
    grounds: Vec<(Polygon<f64>, f64)>,
    level_tolerance_m: f64,
    min_level_height_m: f64,
    sloped_roof_step_m: f64,
}

/// A building shell with gaps, kept for [`shell::walls_on_faces`].
#[derive(Debug, Clone)]
pub struct OpenShell {
    /// Gaps found (see [`shell::Closure::Open`]).
    pub holes: usize,
    /// The mesh's triangles, wound outward.
    pub triangles: Vec<shell::Tri>,
}

/// Bound on candidate heights per building (sloped-roof samples included), so a huge mesh
/// cannot make level identification quadratic.
const MAX_KEYS: usize = 100_000;

/// Bound on candidate levels per building (a citywalk choice). Each level costs a union of the
/// region with the triangle pieces reaching it and a facade; a mesh whose faces are all sloped
/// (a tile read without its placement, tilted by its Earth-centred axes: issue 14 case 5)
/// otherwise gets a level every `level_tolerance_m` of its height. Every kept level's region
/// is still exact and conservative, so thinning only coarsens the occluders.
pub const MAX_CANDIDATE_LEVELS: usize = 32;

/// At most `max` (≥ 2) of the ascending `heights`: the highest, then downward each one at least
/// (highest − lowest) / (max − 1) below the last kept; ascending.
fn thin_heights(heights: Vec<f64>, max: usize) -> Vec<f64> {
    let (Some(&lowest), Some(&highest)) = (heights.first(), heights.last()) else {
        return heights;
    };
    if heights.len() <= max {
        return heights;
    }
    let spacing = (highest - lowest) / (max.max(2) - 1) as f64;
    let mut kept: Vec<f64> = Vec::with_capacity(max);
    for &z in heights.iter().rev() {
        if kept.len() == max {
            break;
        }
        if kept.last().is_none_or(|&last| last - z >= spacing) {
            kept.push(z);
        }
    }
    kept.reverse();
    kept
}

impl MeshRegions {
    /// Classifies the mesh's triangles. Fails (with a reason) on a mesh with an index out of
    /// range or a non-finite vertex.
    pub fn new(mesh: &TriangleMesh, params: &OccluderParams) -> Result<MeshRegions, String> {
        let mut tris = Vec::with_capacity(mesh.triangle_count());
        for t in mesh.indices.chunks_exact(3) {
            let mut c = [DVec3::ZERO; 3];
            for (corner, &i) in c.iter_mut().zip(t) {
                let p = mesh.positions.get(i as usize).ok_or_else(|| {
                    format!(
                        "mesh index {i} out of range ({} vertices)",
                        mesh.positions.len()
                    )
                })?;
                if !p.is_finite() {
                    return Err("mesh has a non-finite vertex".to_owned());
                }
                *corner = p.as_dvec3();
            }
            tris.push(c);
        }
        if tris.is_empty() {
            return Err("mesh has no triangles".to_owned());
        }
        // Faces wound inward, one by one or all together, are turned outward first: up and
        // down below are read from the winding.
        shell::orient(&mut tris);
        let closure = shell::closure(&tris);
        let min_z = tris
            .iter()
            .flat_map(|t| t.iter().map(|p| p.z))
            .fold(f64::INFINITY, f64::min);
        let mut roofs = Vec::new();
        let mut grounds = Vec::new();
        let mut overhangs = Vec::new();
        for &t in &tris {
            let n = (t[1] - t[0]).cross(t[2] - t[0]);
            let len = n.length();
            if len <= 1e-12 {
                continue;
            }
            let nz = n.z / len;
            let lo = t[0].z.min(t[1].z).min(t[2].z);
            let hi = t[0].z.max(t[1].z).max(t[2].z);
            if nz > params.up_normal_min_z {
                roofs.push((t, lo, hi));
            } else if nz < -params.up_normal_min_z {
                if hi <= min_z + params.ground_tolerance_m {
                    if let Some(p) = ccw_polygon(&[t[0], t[1], t[2]]) {
                        grounds.push((p, hi));
                    }
                } else {
                    overhangs.push((t, lo, hi));
                }
            }
        }
        let overhang = overhang_region(&overhangs, &roofs);
        // Heights of levels are measured from the lowest point (the paper's groundplane); each
        // facade then stands on the ground faces under it (`base_under`).
        let base_m = min_z;
        let open_shell = match closure {
            Closure::Closed => None,
            Closure::Open { holes } => Some(OpenShell {
                holes,
                triangles: tris,
            }),
        };
        Ok(MeshRegions {
            open_shell,
            roofs,
            overhang,
            base_m,
            grounds,
            level_tolerance_m: params.level_tolerance_m,
            min_level_height_m: params.min_level_height_m,
            sloped_roof_step_m: params.sloped_roof_step_m,
        })
    }

    /// The base of a facade standing on `region`: the highest ground face under it (parts of
    /// one building may stand on terrain of different heights; below its own floor a part is
    /// not solid), or the building's base when no ground face lies under it.
    pub fn base_under(&self, region: &MultiPolygon<f64>) -> f64 {
        let bounds = region.bounding_rect();
        self.grounds
            .iter()
            .filter(|(g, _)| match (bounds, g.bounding_rect()) {
                (Some(a), Some(b)) => {
                    a.min().x <= b.max().x
                        && b.min().x <= a.max().x
                        && a.min().y <= b.max().y
                        && b.min().y <= a.max().y
                }
                _ => false,
            })
            .filter(|(g, _)| region.intersects(g))
            .map(|(_, z)| *z)
            .fold(None, |acc: Option<f64>, z| {
                Some(acc.map_or(z, |a| a.max(z)))
            })
            .unwrap_or(self.base_m)
    }

    /// Number of upward-facing triangles.
    pub fn roof_triangle_count(&self) -> usize {
        self.roofs.len()
    }

    /// The candidate Z-levels (§3.2 step 2), ascending, with their conservative regions;
    /// levels within `min_level_height_m` of the base and empty regions are left out.
    pub fn candidate_levels(&self) -> Vec<LevelCandidate> {
        let mut keys: Vec<f64> = self.roofs.iter().map(|r| r.1).collect();
        if self.sloped_roof_step_m > 0.0 {
            for &(_, lo, hi) in &self.roofs {
                let mut z = lo + self.sloped_roof_step_m;
                while z < hi && keys.len() < MAX_KEYS {
                    keys.push(z);
                    z += self.sloped_roof_step_m;
                }
            }
        }
        let heights: Vec<f64> = cluster_heights(&keys, self.level_tolerance_m)
            .into_iter()
            .filter(|z| *z > self.base_m + self.min_level_height_m)
            .collect();
        if heights.len() > MAX_CANDIDATE_LEVELS {
            tracing::debug!(
                levels = heights.len(),
                kept = MAX_CANDIDATE_LEVELS,
                "candidate levels thinned"
            );
        }
        let heights = thin_heights(heights, MAX_CANDIDATE_LEVELS);
        let mut out = Vec::with_capacity(heights.len());
        let mut region = MultiPolygon::<f64>::new(Vec::new());
        let mut upper = f64::INFINITY;
        for &z in heights.iter().rev() {
            // Pieces that change between the level above and this one: triangles reaching
            // above z and not already wholly above the level above.
            let pieces: Vec<Polygon<f64>> = self
                .roofs
                .iter()
                .filter(|(_, lo, hi)| *hi >= z && *lo < upper)
                .filter_map(|(t, _, _)| clip_above(t, z))
                .collect();
            let mut all: Vec<&Polygon<f64>> = region.0.iter().collect();
            all.extend(pieces.iter());
            region = clean(unary_union(all));
            upper = z;
            let mut conservative = if self.overhang.0.is_empty() {
                region.clone()
            } else {
                clean(region.difference(&self.overhang))
            };
            conservative
                .0
                .retain(|p| p.unsigned_area() > ROUNDING_GAP_M2);
            if !conservative.0.is_empty() {
                out.push(LevelCandidate {
                    z_m: z,
                    region: conservative,
                });
            }
        }
        out.reverse();
        out
    }
}

/// Two horizontal faces closer than this in height are the same interface (metres).
const STACKING_TOLERANCE_M: f64 = 0.05;

/// The ground region under downward faces above the ground band, where the building is not
/// solid down to its base. A flat downward face lying on a flat upward face at the same height
/// is not an overhang but the interface of two stacked solids (a CityJSON building part on
/// top of another, with its own floor): walking down through it one enters the lower solid at
/// once, so the area where such pairs coincide is taken out of the overhang region again.
/// Sloped downward faces always count as overhangs (conservative).
fn overhang_region(
    downs: &[([DVec3; 3], f64, f64)],
    roofs: &[([DVec3; 3], f64, f64)],
) -> MultiPolygon<f64> {
    if downs.is_empty() {
        return MultiPolygon::new(Vec::new());
    }
    let flat = |(_, lo, hi): &&([DVec3; 3], f64, f64)| hi - lo <= STACKING_TOLERANCE_M;
    let project = |t: &[DVec3; 3]| ccw_polygon(&[t[0], t[1], t[2]]);
    let mut parts: Vec<Polygon<f64>> = downs
        .iter()
        .filter(|d| !flat(d))
        .filter_map(|(t, _, _)| project(t))
        .collect();
    let heights: Vec<f64> = downs.iter().filter(flat).map(|d| d.1).collect();
    for h in cluster_heights(&heights, STACKING_TOLERANCE_M) {
        let in_band = |lo: f64, hi: f64| {
            lo >= h - STACKING_TOLERANCE_M && hi <= h + 2.0 * STACKING_TOLERANCE_M
        };
        let floors: Vec<Polygon<f64>> = downs
            .iter()
            .filter(|d| flat(d) && in_band(d.1, d.2))
            .filter_map(|(t, _, _)| project(t))
            .collect();
        let tops: Vec<Polygon<f64>> = roofs
            .iter()
            .filter(|r| flat(r) && in_band(r.1, r.2))
            .filter_map(|(t, _, _)| project(t))
            .collect();
        let floors = unary_union(floors.iter());
        let open = if tops.is_empty() {
            floors
        } else {
            floors.difference(&unary_union(tops.iter()))
        };
        parts.extend(open.0);
    }
    clean(unary_union(parts.iter()))
}

/// The part of triangle `t` at height ≥ `z`, projected to the ground, counter-clockwise; `None`
/// when it is empty or degenerate. Edge crossings are computed from the edge's endpoints in a
/// canonical order so that triangles sharing an edge get bit-identical crossing points.
fn clip_above(t: &[DVec3; 3], z: f64) -> Option<Polygon<f64>> {
    let mut pts: Vec<DVec3> = Vec::with_capacity(4);
    for i in 0..3 {
        let (p, q) = (t[i], t[(i + 1) % 3]);
        if p.z >= z {
            pts.push(p);
        }
        if (p.z >= z) != (q.z >= z) {
            let (a, b) = if (p.x, p.y, p.z) < (q.x, q.y, q.z) {
                (p, q)
            } else {
                (q, p)
            };
            let s = (z - a.z) / (b.z - a.z);
            pts.push(a + (b - a) * s);
        }
    }
    if pts.len() < 3 {
        return None;
    }
    let poly = ccw_polygon(&pts)?;
    (poly.unsigned_area() > 1e-9).then_some(poly)
}

/// The ground projection of a 3D ring as a counter-clockwise polygon.
fn ccw_polygon(pts: &[DVec3]) -> Option<Polygon<f64>> {
    let mut ring: Vec<Coord<f64>> = pts.iter().map(|p| Coord { x: p.x, y: p.y }).collect();
    let signed = Polygon::new(LineString::from(ring.clone()), Vec::new()).signed_area();
    if signed.abs() <= 1e-12 {
        return None;
    }
    if signed < 0.0 {
        ring.reverse();
    }
    Some(Polygon::new(LineString::from(ring), Vec::new()))
}

/// Closes rounding gaps (holes below [`ROUNDING_GAP_M2`]) and drops slivers.
fn clean(mp: MultiPolygon<f64>) -> MultiPolygon<f64> {
    MultiPolygon::new(
        mp.0.into_iter()
            .filter(|p| p.unsigned_area() > ROUNDING_GAP_M2)
            .map(|p| {
                let (ext, holes) = p.into_inner();
                let holes = holes
                    .into_iter()
                    .filter(|h| {
                        Polygon::new(h.clone(), Vec::new()).unsigned_area() > ROUNDING_GAP_M2
                    })
                    .collect();
                Polygon::new(ext, holes)
            })
            .collect(),
    )
}

/// The candidate levels with their regions' boundaries indexed ([`RegionCover`]) once, for the
/// many edge tests of [`edge_height`].
#[derive(Debug)]
pub struct PreparedLevels {
    levels: Vec<(f64, RegionCover)>,
}

impl PreparedLevels {
    pub fn new(candidates: &[LevelCandidate]) -> PreparedLevels {
        PreparedLevels {
            levels: candidates
                .iter()
                .map(|c| (c.z_m, RegionCover::new(&c.region)))
                .collect(),
        }
    }
}

/// Height of the wall-oriented facade wall on edge `a`–`b` of the footprint of the level at
/// `level_z_m` (§3.4: "the minimum Z found along the edge"), quantised down to the candidate
/// level heights: the highest candidate whose conservative region covers the whole edge, or
/// the level's own height. Candidates are ascending and their regions nested, so a binary
/// search finds it.
pub fn edge_height(
    candidates: &PreparedLevels,
    level_z_m: f64,
    a: Coord<f64>,
    b: Coord<f64>,
) -> f64 {
    let higher: Vec<_> = candidates
        .levels
        .iter()
        .filter(|(z, _)| *z > level_z_m)
        .collect();
    // Largest k such that higher[..k] all cover the edge.
    let (mut lo, mut hi) = (0usize, higher.len());
    while lo < hi {
        let mid = (lo + hi).div_ceil(2);
        if higher[mid - 1].1.covers(a, b) {
            lo = mid;
        } else {
            hi = mid - 1;
        }
    }
    if lo == 0 { level_z_m } else { higher[lo - 1].0 }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use glam::Vec3;

    #[test]
    fn thinned_heights_keep_the_top_and_at_most_the_bound() {
        let heights: Vec<f64> = (0..200).map(|i| 3.0 + 0.5 * f64::from(i)).collect();
        let kept = thin_heights(heights.clone(), 32);
        assert!((24..=32).contains(&kept.len()), "{}", kept.len());
        assert_eq!(kept.last(), heights.last());
        assert!(kept.windows(2).all(|w| w[0] < w[1]));
        assert!(kept.iter().all(|z| heights.contains(z)));
        let few = vec![1.0, 2.0, 5.0];
        assert_eq!(thin_heights(few.clone(), 32), few);
        assert!(thin_heights(Vec::new(), 32).is_empty());
    }

    /// A closed box mesh (12 triangles, outward CCW) from `lo` to `hi`.
    pub(crate) fn box_mesh(lo: Vec3, hi: Vec3) -> TriangleMesh {
        let p = |x: bool, y: bool, z: bool| {
            Vec3::new(
                if x { hi.x } else { lo.x },
                if y { hi.y } else { lo.y },
                if z { hi.z } else { lo.z },
            )
        };
        let positions = vec![
            p(false, false, false),
            p(true, false, false),
            p(true, true, false),
            p(false, true, false),
            p(false, false, true),
            p(true, false, true),
            p(true, true, true),
            p(false, true, true),
        ];
        #[rustfmt::skip]
        let indices = vec![
            0, 2, 1, 0, 3, 2, // bottom (down)
            4, 5, 6, 4, 6, 7, // top (up)
            0, 1, 5, 0, 5, 4, // south
            1, 2, 6, 1, 6, 5, // east
            2, 3, 7, 2, 7, 6, // north
            3, 0, 4, 3, 4, 7, // west
        ];
        TriangleMesh { positions, indices }
    }

    #[test]
    fn a_box_has_one_level_covering_its_plan() {
        let mesh = box_mesh(Vec3::new(0.0, 0.0, 2.0), Vec3::new(10.0, 5.0, 12.0));
        let r = MeshRegions::new(&mesh, &OccluderParams::default()).unwrap();
        assert_eq!(r.base_m, 2.0);
        assert_eq!(r.base_under(&MultiPolygon::new(vec![])), 2.0);
        assert_eq!(r.roof_triangle_count(), 2);
        let levels = r.candidate_levels();
        assert_eq!(levels.len(), 1);
        assert_eq!(levels[0].z_m, 12.0);
        assert!((levels[0].region.unsigned_area() - 50.0).abs() < 1e-9);
    }

    #[test]
    fn an_inside_out_box_is_flipped() {
        let mut mesh = box_mesh(Vec3::ZERO, Vec3::new(4.0, 4.0, 6.0));
        for t in mesh.indices.chunks_exact_mut(3) {
            t.swap(1, 2);
        }
        let levels = MeshRegions::new(&mesh, &OccluderParams::default())
            .unwrap()
            .candidate_levels();
        assert_eq!(levels.len(), 1);
        assert!((levels[0].region.unsigned_area() - 16.0).abs() < 1e-9);
    }

    #[test]
    fn a_sloped_roof_counts_only_where_it_is_high_enough() {
        // A shed roof over 0 ≤ x ≤ 10 rising from 10 m at x = 0 to 20 m at x = 10, as one
        // upward quad; with a clip at 15 m only x ≥ 5 remains.
        let t = [
            DVec3::new(0.0, 0.0, 10.0),
            DVec3::new(10.0, 0.0, 20.0),
            DVec3::new(10.0, 10.0, 20.0),
        ];
        let clipped = clip_above(&t, 15.0).unwrap();
        // The triangle's part with x ≥ 5: a triangle of legs 5 and 5 (above the diagonal).
        assert!(
            (clipped.unsigned_area() - 37.5).abs() < 1e-9,
            "{}",
            clipped.unsigned_area()
        );
        assert!(clip_above(&t, 25.0).is_none());
        assert!((clip_above(&t, 5.0).unwrap().unsigned_area() - 50.0).abs() < 1e-9);
    }

    #[test]
    fn overhangs_are_cut_out_of_every_level() {
        // A 10 × 10 × 10 block with a 10 × 4 slab cantilevered at 6..10 m on its east side.
        let mut mesh = box_mesh(Vec3::ZERO, Vec3::new(10.0, 10.0, 10.0));
        mesh.append(&box_mesh(
            Vec3::new(10.0, 0.0, 6.0),
            Vec3::new(14.0, 10.0, 10.0),
        ));
        let levels = MeshRegions::new(&mesh, &OccluderParams::default())
            .unwrap()
            .candidate_levels();
        assert_eq!(levels.len(), 1);
        assert!((levels[0].region.unsigned_area() - 100.0).abs() < 1e-6);
    }

    #[test]
    fn a_part_stacked_on_another_is_not_an_overhang() {
        // A 10 × 10 × 8 block with a closed 4 × 4 × 12 part standing on its roof (own floor).
        let mut mesh = box_mesh(Vec3::ZERO, Vec3::new(10.0, 10.0, 8.0));
        mesh.append(&box_mesh(
            Vec3::new(3.0, 3.0, 8.0),
            Vec3::new(7.0, 7.0, 20.0),
        ));
        let levels = MeshRegions::new(&mesh, &OccluderParams::default())
            .unwrap()
            .candidate_levels();
        assert_eq!(levels.len(), 2);
        assert!((levels[0].region.unsigned_area() - 100.0).abs() < 1e-6);
        assert!((levels[1].region.unsigned_area() - 16.0).abs() < 1e-6);
        // The same part floating 1 m above the block is an overhang: cut out everywhere.
        let mut mesh = box_mesh(Vec3::ZERO, Vec3::new(10.0, 10.0, 8.0));
        mesh.append(&box_mesh(
            Vec3::new(3.0, 3.0, 9.0),
            Vec3::new(7.0, 7.0, 20.0),
        ));
        let levels = MeshRegions::new(&mesh, &OccluderParams::default())
            .unwrap()
            .candidate_levels();
        assert_eq!(levels.len(), 1);
        assert!((levels[0].region.unsigned_area() - 84.0).abs() < 1e-6);
    }

    #[test]
    fn bad_meshes_give_reasons() {
        let mut mesh = box_mesh(Vec3::ZERO, Vec3::ONE);
        mesh.indices[0] = 99;
        assert!(MeshRegions::new(&mesh, &OccluderParams::default()).is_err());
        let mut mesh = box_mesh(Vec3::ZERO, Vec3::ONE);
        mesh.positions[0].x = f32::NAN;
        assert!(MeshRegions::new(&mesh, &OccluderParams::default()).is_err());
    }
}
