//! The baseline a user would pick instead of occlusion culling: generic mesh decimation of the
//! whole city to a triangle budget, drawn without any culling.
//!
//! Chang et al. 2008 (§9) compare their legibility-driven hierarchy with QSlim (Garland and
//! Heckbert 1997) run over the whole city. We use meshoptimizer's quadric edge-collapse
//! simplifier (`meshopt_simplify`, the same error metric family as QSlim) through the `meshopt`
//! crate, on the whole city as one mesh:
//!
//! - Buildings are separate meshes; vertices are shared within a building (flat shading comes
//!   from screen-space derivatives, so positions alone are enough) and are *not* welded across
//!   buildings, so every vertex keeps its building id.
//! - First the topology-preserving edge collapse with an unbounded error (`target_error` 1.0,
//!   relative to the city's extent) and no border locks. Closed building shells cannot collapse
//!   below a few triangles each, so at low budgets it stops above the target; when it ends more
//!   than [`TOLERANCE`] above, the city is decimated again with meshoptimizer's sloppy
//!   simplifier (`meshopt_simplifySloppy`: vertex clustering on a grid that merges neighbouring
//!   buildings and removes small ones), which reaches any budget.
//! - Each output triangle belongs to the building of its first corner; a corner from another
//!   building (a sloppy cluster spanning buildings) is copied into that building's mesh. So the
//!   result is again one mesh per building id and the oracle-style accounting works: a building
//!   that is visible in the full city but has no triangles left counts as a false cull of the
//!   baseline.

use citywalk_scenes::TriangleMesh;
use glam::Vec3;

use citywalk_runtime::scene_gpu::SceneGeometry;

/// How far above the target the edge collapse may end before the sloppy simplifier is used.
pub const TOLERANCE: f64 = 0.1;

/// Which simplifier produced a decimation.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum DecimationMethod {
    /// The target was at or above the city's triangle count: nothing removed.
    Unchanged,
    /// Quadric edge collapse (`meshopt_simplify`).
    EdgeCollapse,
    /// Vertex clustering (`meshopt_simplifySloppy`).
    Sloppy,
}

/// A decimated city: one mesh per building id of the input.
#[derive(Debug, Clone)]
pub struct DecimatedCity {
    pub meshes: Vec<TriangleMesh>,
    pub triangles: usize,
    pub method: DecimationMethod,
}

impl DecimatedCity {
    /// The decimated city in the GPU layout, with the input's building bounds for buildings
    /// left without triangles.
    pub fn geometry(&self, original: &SceneGeometry) -> SceneGeometry {
        let fallback: Vec<(Vec3, Vec3)> = original
            .records
            .iter()
            .map(|r| {
                (
                    Vec3::from_array(r.bounds_min_m),
                    Vec3::from_array(r.bounds_max_m),
                )
            })
            .collect();
        SceneGeometry::from_meshes(&self.meshes, &fallback)
    }
}

/// Decimates every building of `geometry` (the ground excluded) together to about
/// `target_triangles` (see the module documentation for the method).
pub fn decimate_city(geometry: &SceneGeometry, target_triangles: usize) -> DecimatedCity {
    // The whole city as one indexed mesh over the buildings' vertices.
    let mut positions: Vec<[f32; 3]> = Vec::new();
    let mut owner: Vec<u32> = Vec::new();
    let mut indices: Vec<u32> = Vec::new();
    for (b, r) in geometry.records.iter().enumerate() {
        let first_vertex = positions.len() as u32;
        let base = usize::try_from(r.base_vertex).unwrap_or(usize::MAX);
        let Some(vertices) = geometry
            .vertices
            .get(base..base.saturating_add(r.vertex_count as usize))
        else {
            continue;
        };
        positions.extend(vertices.iter().map(|v| v.position_m));
        owner.extend(std::iter::repeat_n(b as u32, vertices.len()));
        let range = r.first_index as usize..(r.first_index + r.index_count) as usize;
        if let Some(local) = geometry.indices.get(range) {
            for t in local.chunks_exact(3) {
                if t.iter().all(|&i| i < r.vertex_count) {
                    indices.extend(t.iter().map(|&i| i + first_vertex));
                }
            }
        }
    }
    let total = indices.len() / 3;
    let (kept, method) = if target_triangles >= total {
        (indices, DecimationMethod::Unchanged)
    } else {
        let collapsed = meshopt::simplify_decoder(
            &indices,
            &positions,
            target_triangles * 3,
            1.0,
            meshopt::SimplifyOptions::None,
            None,
        );
        let limit = (target_triangles as f64 * (1.0 + TOLERANCE)).ceil() as usize;
        if collapsed.len() / 3 <= limit {
            (collapsed, DecimationMethod::EdgeCollapse)
        } else {
            (
                sloppy_closest(&indices, &positions, target_triangles),
                DecimationMethod::Sloppy,
            )
        }
    };
    let meshes = split_by_building(&kept, &positions, &owner, geometry.records.len());
    DecimatedCity {
        triangles: kept.len() / 3,
        meshes,
        method,
    }
}

/// The sloppy simplifier's grid is discrete, so asking for `target` can return well below it;
/// bisects the requested count for the result closest to `target` (at most 17 runs).
fn sloppy_closest(indices: &[u32], positions: &[[f32; 3]], target: usize) -> Vec<u32> {
    let run = |requested: usize| {
        meshopt::simplify_sloppy_decoder(indices, positions, requested * 3, 1.0, None)
    };
    let distance = |r: &[u32]| (r.len() / 3).abs_diff(target);
    let mut best = run(target);
    let (mut lo, mut hi) = (target, indices.len() / 3);
    for _ in 0..16 {
        let got = best.len() / 3;
        if (got as f64) >= target as f64 * (1.0 - TOLERANCE) || lo + 1 >= hi {
            break;
        }
        let mid = lo + (hi - lo) / 2;
        let result = run(mid);
        if result.len() / 3 > target {
            hi = mid;
        } else {
            lo = mid;
        }
        if distance(&result) < distance(&best) {
            best = result;
        }
    }
    best
}

/// Splits a city-wide triangle list back into one mesh per building: a triangle goes to the
/// building of its first corner; corners of other buildings are copied in.
fn split_by_building(
    indices: &[u32],
    positions: &[[f32; 3]],
    owner: &[u32],
    building_count: usize,
) -> Vec<TriangleMesh> {
    let mut meshes = vec![
        TriangleMesh {
            positions: Vec::new(),
            indices: Vec::new(),
        };
        building_count
    ];
    // City vertex → index in its own building's mesh, once used.
    let mut local = vec![u32::MAX; positions.len()];
    for t in indices.chunks_exact(3) {
        let Some(&b) = owner.get(t[0] as usize) else {
            continue;
        };
        let Some(mesh) = meshes.get_mut(b as usize) else {
            continue;
        };
        for &v in t {
            let v = v as usize;
            if owner.get(v) == Some(&b) {
                if local[v] == u32::MAX {
                    local[v] = mesh.positions.len() as u32;
                    mesh.positions.push(Vec3::from_array(positions[v]));
                }
                mesh.indices.push(local[v]);
            } else {
                mesh.indices.push(mesh.positions.len() as u32);
                mesh.positions.push(Vec3::from_array(positions[v]));
            }
        }
    }
    meshes
}

#[cfg(test)]
mod tests {
    use super::*;

    fn block_city() -> SceneGeometry {
        // 12 × 12 buildings: boxes with a subdivided roof so the edge collapse has work.
        let mut meshes = Vec::new();
        for i in 0..12 {
            for j in 0..12 {
                let (x, y) = (i as f32 * 30.0, j as f32 * 30.0);
                let h = 10.0 + ((i * 7 + j * 3) % 5) as f32 * 6.0;
                let mut m = TriangleMesh {
                    positions: Vec::new(),
                    indices: Vec::new(),
                };
                // A 5 × 5 vertex grid roof and four walls.
                let n = 5;
                for a in 0..n {
                    for c in 0..n {
                        m.positions.push(Vec3::new(
                            x + 20.0 * a as f32 / (n - 1) as f32,
                            y + 20.0 * c as f32 / (n - 1) as f32,
                            h,
                        ));
                    }
                }
                for a in 0..n - 1 {
                    for c in 0..n - 1 {
                        let v = (a * n + c) as u32;
                        let n = n as u32;
                        m.indices.extend([v, v + n, v + 1, v + 1, v + n, v + n + 1]);
                    }
                }
                let base = m.positions.len() as u32;
                for (px, py) in [(0.0, 0.0), (20.0, 0.0), (20.0, 20.0), (0.0, 20.0)] {
                    m.positions.push(Vec3::new(x + px, y + py, 0.0));
                }
                let corners = [
                    0u32,
                    ((n - 1) * n) as u32,
                    (n * n - 1) as u32,
                    (n - 1) as u32,
                ];
                for k in 0..4 {
                    let (a, b) = (corners[k], corners[(k + 1) % 4]);
                    let (ga, gb) = (base + k as u32, base + ((k + 1) % 4) as u32);
                    m.indices.extend([ga, gb, b, ga, b, a]);
                }
                meshes.push(m);
            }
        }
        SceneGeometry::from_meshes(&meshes, &[])
    }

    fn generated_city() -> SceneGeometry {
        use citywalk_scenes::generate::{GenerateParams, generate_city};
        SceneGeometry::from_city(&generate_city(&GenerateParams::new(300, 11)).unwrap())
    }

    #[test]
    fn reaches_targets_and_keeps_ids() {
        // A perfectly regular layout: the sloppy grid removes the same share of every building
        // at once, so very low budgets land in coarse steps; stay with the edge collapse's range.
        check_targets(&block_city(), &[0.8, 0.5, 0.25]);
    }

    #[test]
    fn reaches_targets_on_a_generated_city() {
        check_targets(&generated_city(), &[0.8, 0.5, 0.25, 0.1, 0.05]);
    }

    fn check_targets(city: &SceneGeometry, shares: &[f64]) {
        let total = city.building_triangle_count();
        for &share in shares {
            let target = (total as f64 * share) as usize;
            let d = decimate_city(city, target);
            let off = (d.triangles as f64 - target as f64).abs() / target as f64;
            assert!(
                off <= TOLERANCE,
                "target {target}, got {} ({:?})",
                d.triangles,
                d.method
            );
            assert_eq!(d.meshes.len(), city.building_count());
            assert_eq!(
                d.meshes
                    .iter()
                    .map(TriangleMesh::triangle_count)
                    .sum::<usize>(),
                d.triangles
            );
            let g = d.geometry(city);
            g.check_invariants().unwrap();
            assert_eq!(g.building_triangle_count(), d.triangles);
            // Every building's triangles stay where that building was (edge collapse) or
            // nearby (sloppy clusters span at most neighbouring buildings).
            for (b, m) in d.meshes.iter().enumerate() {
                let r = &city.records[b];
                for p in &m.positions {
                    let lo = Vec3::from_array(r.bounds_min_m) - Vec3::splat(40.0);
                    let hi = Vec3::from_array(r.bounds_max_m) + Vec3::splat(40.0);
                    assert!(p.cmpge(lo).all() && p.cmple(hi).all(), "building {b}");
                }
            }
        }
        let d = decimate_city(city, total * 2);
        assert_eq!(d.method, DecimationMethod::Unchanged);
        assert_eq!(d.triangles, total);
    }
}
