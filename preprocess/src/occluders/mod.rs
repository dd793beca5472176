//! Virtual occluders: simplified, occlusion-preserving facades of buildings.
//!
//! This work is based on: G. Germs and F. W. Jansen, *Geometric simplification for efficient
//! occlusion culling in urban scenes* (WSCG 2001). Per building:
//!
//! 1. **Z-levels** ([`zlevels`], paper §3.2): the upward-facing triangles of the mesh
//!    (n_z > ε) are clustered by height with a low tolerance T_z, then the occlusion-benefit
//!    rule keeps, merges or deletes the upper level of each pair. A 2.5D building (no mesh)
//!    has one level per [`citywalk_scenes::BuildingPart`].
//! 2. **A footprint per level** ([`footprint`], §3.3): the ground region under which the
//!    building is at least as tall as the level, holes kept.
//! 3. **Conservative simplification** ([`simplify`], §3.3): redundant vertices and edges are
//!    removed, inward only.
//! 4. **A facade** ([`facade`], §3.4): open, closed or wall-oriented.
//!
//! [`quality`] measures the result as §4.1 does (silhouette pixels of the facade over those of
//! the building), [`gltf_out`] writes occluders as GLB for inspection.
//!
//! # Why the occluders are contained in their buildings
//!
//! The paper requires that "the facade has to be completely contained by the original model"
//! (§3.1) and proves nothing beyond it; this is how citywalk makes sure of it. An occluder of
//! level height Z is a set of vertical walls (and for closed facades a roof at Z) standing on a
//! footprint F, from the building's base b up to Z. It is inside the building if, for every
//! ground point p in F, the building is solid along the whole vertical segment from b to Z
//! above p. For a closed mesh, walk down from any point of an upward-facing (roof) triangle:
//! one is inside the solid until one leaves it through a downward-facing triangle. So if
//!
//! * p lies under an upward triangle at a height h(p) ≥ Z (the union of upward triangles
//!   *clipped to z ≥ Z*, projected; a sloped roof counts only where it is at least Z high), and
//! * p lies under no downward triangle above the ground band (overhang undersides, the
//!   ceilings of passages: their projection is subtracted from every footprint), and
//! * the facade's base is the highest ground triangle (downward, within the ground band)
//!   under its footprint — parts of one building may stand on terrain of different heights,
//!   and a flat floor lying on a flat roof at the same height (one part stacked on another)
//!   is an interface between two solids, not an overhang,
//!
//! then the column above p is solid from the base to Z. The level footprint is exactly this
//! region, so it is the *union of the horizontal surfaces at height ≥ Z*, not only the
//! surfaces of the level itself: a lower level's footprint therefore also covers the area
//! under higher parts (its facade stands inside them), and a deleted or merged level keeps
//! being covered at the height of the level below. Simplification only removes area
//! ([`simplify`]), and a wall-oriented wall is raised above Z only to the height of a higher
//! level whose (conservative) region covers the whole edge, which is the paper's "minimum Z
//! found along the edge", quantised down to the level heights. Faces whose normal is almost
//! horizontal count as walls and are left out, which can only shrink a footprint. An
//! inside-out mesh (negative signed volume) is flipped first. For 2.5D input the part's own
//! prism is the volume, and its occluder is the simplified part footprint between the part's
//! base and top.

pub mod facade;
pub mod footprint;
pub mod gltf_out;
pub mod quality;
pub mod simplify;
pub mod zlevels;

use citywalk_scenes::occluder::{FacadeKind, Occluder, OccluderOutcome, OccluderSet};
use citywalk_scenes::{Building, City, TriangleMesh};
use geo::MultiPolygon;
use serde::{Deserialize, Serialize};

use self::footprint::MeshRegions;
use self::zlevels::LevelDecision;

/// Parameters of occluder generation. The paper gives no numeric values for its thresholds
/// (§3.2, §3.3 name ε, T_z, T_B, ΔZ, α and the distance threshold only); the defaults below
/// are ours, chosen for metre-scale city models, and each says why.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OccluderParams {
    /// Facade type (§3.4). Default: wall-oriented, which the paper expects to "perform best"
    /// for occlusion culling.
    pub facade: FacadeKind,
    /// ε of §3.2/§3.3: a triangle is upward-facing when its unit normal has n_z above this.
    /// Default 0.1 (faces steeper than about 84° count as walls and are left out, which only
    /// shrinks footprints).
    pub up_normal_min_z: f64,
    /// T_z of §3.2: the height tolerance of one Z-level, in metres. The paper starts low "such
    /// that extra Z-levels are generated" and lets the benefit rule prune them. Default 0.5 m.
    pub level_tolerance_m: f64,
    /// T_B of §3.2: an upper level L2 adds significantly to L1 if B_{2,1} > T_B · A1.
    /// Default 0.15 (the upper level must add 15 % of the lower facade's hull wall area).
    pub benefit_threshold: f64,
    /// Extra candidate heights on sloped roofs, every this many metres above a sloped
    /// triangle's lowest point (0 = off). The paper clusters polygons by height and says
    /// nothing of slopes; a sloped triangle's conservative height is its lowest point, so
    /// without samples a gabled roof yields only its eaves level. The samples are candidates
    /// like any other and go through the same benefit rule. Default 2 m: on Den Haag LoD2 it
    /// raises the mean quality from 84 % to 91 % (0 gives the paper's method).
    pub sloped_roof_step_m: f64,
    /// ΔZ of §3.2: a significant upper level closer than this to the level below is merged into
    /// it rather than kept. Default 2.0 m (about two thirds of a storey).
    pub merge_delta_z_m: f64,
    /// Levels at most this high above the occluder base are dropped (terraces, steps): their
    /// walls would occlude almost nothing. Default 1.5 m (below eye height, 1.7 m).
    pub min_level_height_m: f64,
    /// Downward-facing triangles whose highest corner is within this of the mesh's lowest
    /// point are ground surfaces; higher ones are overhang undersides. Default 2.0 m (terrain
    /// slope under one building; Den Haag has buildings whose parts stand 1.4 m apart). A
    /// facade's base is the highest ground face under its footprint.
    pub ground_tolerance_m: f64,
    /// α of §3.3: a convex vertex whose edges turn by less than this is removed (redundant
    /// vertex removal). Default 5°.
    pub max_turn_angle_deg: f64,
    /// The distance threshold of §3.3: a short edge is replaced by the meeting point V of its
    /// neighbours' lines only if V lies inside and within this of the edge's midpoint
    /// (redundant edge removal). Default 0.5 m.
    pub max_edge_shift_m: f64,
    /// Whether to simplify footprints at all (§3.3; the paper's own tests did not).
    pub simplify: bool,
    /// Footprint polygons smaller than this are dropped (removing area is conservative).
    /// Default 1 m².
    pub min_polygon_area_m2: f64,
}

impl Default for OccluderParams {
    fn default() -> Self {
        OccluderParams {
            facade: FacadeKind::WallOriented,
            up_normal_min_z: 0.1,
            level_tolerance_m: 0.5,
            sloped_roof_step_m: 2.0,
            benefit_threshold: 0.15,
            merge_delta_z_m: 2.0,
            min_level_height_m: 1.5,
            ground_tolerance_m: 2.0,
            max_turn_angle_deg: 5.0,
            max_edge_shift_m: 0.5,
            simplify: true,
            min_polygon_area_m2: 1.0,
        }
    }
}

/// The occluders of one building before they are numbered into a set, with what happened to
/// its levels (for reports and tests).
#[derive(Debug, Clone, PartialEq)]
pub struct BuildingOccluders {
    pub occluders: Vec<Occluder>,
    /// Triangles of the source geometry.
    pub source_polygons: u32,
    /// The candidate levels found and the rule's decision on each, lowest first (empty for
    /// 2.5D buildings).
    pub decisions: Vec<(f64, LevelDecision)>,
    /// Why there is no occluder (when `occluders` is empty).
    pub reason_if_none: Option<String>,
}

/// Builds the virtual occluders of every building of `city`. Never panics: a building
/// without an occluder gets a reason in its [`OccluderOutcome`].
pub fn build_occluders(city: &City, params: &OccluderParams) -> OccluderSet {
    let mut set = OccluderSet::default();
    for building in &city.buildings {
        // The geometry kernels underneath (boolean operations, relate) are third-party code;
        // should one of them panic on some degenerate input, that building is reported with
        // the reason instead of taking the whole city down.
        let built = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
            occluders_for_building(building, params)
        }))
        .unwrap_or_else(|panic| {
            let what = panic
                .downcast_ref::<&str>()
                .map(|s| (*s).to_owned())
                .or_else(|| panic.downcast_ref::<String>().cloned())
                .unwrap_or_else(|| "unknown".to_owned());
            tracing::warn!(building = %building.source_id, %what, "occluder generation panicked");
            BuildingOccluders {
                occluders: Vec::new(),
                source_polygons: 0,
                decisions: Vec::new(),
                reason_if_none: Some(format!("geometry kernel failed: {what}")),
            }
        });
        let start = set.occluders.len() as u32;
        let occluder_polygons = built
            .occluders
            .iter()
            .map(|o| o.mesh.triangle_count() as u32)
            .sum();
        set.occluders.extend(built.occluders);
        let end = set.occluders.len() as u32;
        let reason_if_none = if start == end {
            Some(
                built
                    .reason_if_none
                    .unwrap_or_else(|| "no occluder was produced".to_owned()),
            )
        } else {
            None
        };
        set.per_building.push(OccluderOutcome {
            building: building.id,
            occluder_range: start..end,
            source_polygons: built.source_polygons,
            occluder_polygons,
            reason_if_none,
        });
    }
    tracing::debug!(
        buildings = city.buildings.len(),
        occluders = set.occluders.len(),
        "built virtual occluders"
    );
    set
}

/// Builds the occluders of one building (mesh buildings through Z-levels, 2.5D buildings one
/// level per part).
pub fn occluders_for_building(building: &Building, params: &OccluderParams) -> BuildingOccluders {
    match &building.mesh {
        Some(mesh) if !mesh.indices.is_empty() => mesh_occluders(building, mesh, params),
        _ => part_occluders(building, params),
    }
}

/// One simplified, non-empty level ready for its facade.
struct PlannedLevel {
    z_m: f64,
    footprint: MultiPolygon<f64>,
}

fn mesh_occluders(
    building: &Building,
    mesh: &TriangleMesh,
    params: &OccluderParams,
) -> BuildingOccluders {
    let source_polygons = mesh.triangle_count() as u32;
    let fail = |reason: String| BuildingOccluders {
        occluders: Vec::new(),
        source_polygons,
        decisions: Vec::new(),
        reason_if_none: Some(reason),
    };
    let regions = match MeshRegions::new(mesh, params) {
        Ok(r) => r,
        Err(reason) => return fail(reason),
    };
    let candidates = regions.candidate_levels();
    if candidates.is_empty() {
        return fail(format!(
            "no upward-facing surface more than {} m above the base",
            params.min_level_height_m
        ));
    }
    let decisions = zlevels::select_levels(&candidates, regions.base_m, params);
    let mut planned = Vec::new();
    for (candidate, decision) in candidates.iter().zip(&decisions) {
        if *decision != LevelDecision::Keep {
            continue;
        }
        let footprint = simplify::simplify_footprint(&candidate.region, params);
        if footprint.0.is_empty() {
            continue;
        }
        planned.push(PlannedLevel {
            z_m: candidate.z_m,
            footprint,
        });
    }
    let decisions_out = candidates
        .iter()
        .zip(&decisions)
        .map(|(c, d)| (c.z_m, *d))
        .collect();
    if planned.is_empty() {
        let mut out = fail(format!(
            "every level footprint was smaller than {} m² after simplification",
            params.min_polygon_area_m2
        ));
        out.decisions = decisions_out;
        return out;
    }
    let mut occluders: Vec<Occluder> = Vec::with_capacity(planned.len());
    for p in planned {
        let base_m = regions.base_under(&p.footprint);
        let mesh = facade::facade_mesh(&p.footprint, base_m, p.z_m, params.facade, |a, b| {
            footprint::edge_height(&candidates, p.z_m, a, b)
        });
        // A level no higher than the ground under it has no facade.
        if mesh.indices.is_empty() {
            continue;
        }
        occluders.push(Occluder {
            building: building.id,
            level: occluders.len() as u32,
            kind: params.facade,
            z_m: p.z_m as f32,
            base_m: base_m as f32,
            footprint: p.footprint,
            mesh,
        });
    }
    if occluders.is_empty() {
        let mut out = fail("every level is as low as the ground under it".to_owned());
        out.decisions = decisions_out;
        return out;
    }
    BuildingOccluders {
        occluders,
        source_polygons,
        decisions: decisions_out,
        reason_if_none: None,
    }
}

fn part_occluders(building: &Building, params: &OccluderParams) -> BuildingOccluders {
    let source_polygons = citywalk_scenes::extrude::building_mesh(building).triangle_count() as u32;
    let mut parts: Vec<_> = building.parts.iter().collect();
    parts.sort_by(|a, b| a.top_m.total_cmp(&b.top_m));
    let mut occluders = Vec::new();
    let mut reasons = Vec::new();
    for part in parts {
        let (base_m, top_m) = (f64::from(part.base_m), f64::from(part.top_m));
        if !(base_m.is_finite() && top_m.is_finite()) || top_m - base_m < params.min_level_height_m
        {
            reasons.push(format!(
                "part {} is {:.1} m tall, below {} m",
                part.source_id,
                top_m - base_m,
                params.min_level_height_m
            ));
            continue;
        }
        let footprint = simplify::simplify_footprint(&part.footprint, params);
        if footprint.0.is_empty() {
            reasons.push(format!(
                "part {} is smaller than {} m²",
                part.source_id, params.min_polygon_area_m2
            ));
            continue;
        }
        // The prism of a part has the same height along every edge: a wall-oriented facade
        // is the open one here.
        let mesh = facade::facade_mesh(&footprint, base_m, top_m, params.facade, |_, _| top_m);
        if mesh.indices.is_empty() {
            continue;
        }
        occluders.push(Occluder {
            building: building.id,
            level: occluders.len() as u32,
            kind: params.facade,
            z_m: part.top_m,
            base_m: part.base_m,
            footprint,
            mesh,
        });
    }
    let reason_if_none = occluders.is_empty().then(|| {
        if reasons.is_empty() {
            "no part produced an occluder".to_owned()
        } else {
            reasons.join("; ")
        }
    });
    BuildingOccluders {
        occluders,
        source_polygons,
        decisions: Vec::new(),
        reason_if_none,
    }
}

#[cfg(test)]
pub(crate) mod tests;
