//! Virtual occluders as stored in the scene package and read by the runtime.
//!
//! They are built offline by `citywalk_preprocess::occluders::build_occluders` after
//! Germs & Jansen, *Geometric simplification for efficient occlusion culling in urban scenes*
//! (§3): per building, Z-levels → one footprint per level → conservative (inward-only)
//! simplification → a facade. This module holds only the data, so that the runtime engine can
//! read occluders from a package without linking the preprocessing geometry.
//!
//! Every occluder is *contained in* its building: its footprint lies within the building's
//! outline at every height up to `z_m`, so it never hides what the building would not hide.

use std::ops::Range;

use geo::MultiPolygon;
use serde::{Deserialize, Serialize};

use crate::city::{BuildingId, TriangleMesh};

/// The three facade types of Germs & Jansen §3.4 (Fig. 5).
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, Serialize, Deserialize)]
pub enum FacadeKind {
    /// Walls only: each footprint edge extruded from the base to the level height (Fig. 5b).
    Open,
    /// Walls and a triangulated roof at the level height (Fig. 5c).
    Closed,
    /// Walls only, each as high as the minimum height of the building along its edge (Fig. 5d);
    /// never lower than the level height.
    WallOriented,
}

impl FacadeKind {
    /// A short stable name, used in files and on the command line.
    pub fn name(self) -> &'static str {
        match self {
            FacadeKind::Open => "open",
            FacadeKind::Closed => "closed",
            FacadeKind::WallOriented => "wall-oriented",
        }
    }

    /// Inverse of [`FacadeKind::name`].
    pub fn from_name(name: &str) -> Option<FacadeKind> {
        [
            FacadeKind::Open,
            FacadeKind::Closed,
            FacadeKind::WallOriented,
        ]
        .into_iter()
        .find(|k| k.name() == name)
    }
}

/// One facade: the (simplified) footprint of one Z-level, extruded from the building's base.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct Occluder {
    /// The building this occluder stands for.
    pub building: BuildingId,
    /// Index of the Z-level among the building's kept levels, 0 = lowest.
    pub level: u32,
    pub kind: FacadeKind,
    /// Height of the Z-level (metres, local frame): the top of every wall of an open or closed
    /// facade, and the lowest wall top of a wall-oriented one.
    pub z_m: f32,
    /// Height of the bottom of the walls (metres, local frame).
    pub base_m: f32,
    /// The simplified footprint of the level in the local frame (holes kept).
    pub footprint: MultiPolygon<f64>,
    /// The facade geometry (f32, z up).
    pub mesh: TriangleMesh,
}

/// What happened to one building: its occluders and the polygon counts, or why it has none.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct OccluderOutcome {
    pub building: BuildingId,
    /// Indices of this building's occluders in [`OccluderSet::occluders`]; empty when none.
    pub occluder_range: Range<u32>,
    /// Triangles of the source geometry (the mesh, or the 2.5D parts as extruded prisms).
    pub source_polygons: u32,
    /// Triangles of all this building's occluder meshes.
    pub occluder_polygons: u32,
    /// Why the building has no occluder; `None` exactly when it has at least one.
    pub reason_if_none: Option<String>,
}

/// All virtual occluders of a city: one outcome per building, in building order, and the
/// occluders grouped by building in the same order.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct OccluderSet {
    pub occluders: Vec<Occluder>,
    pub per_building: Vec<OccluderOutcome>,
}

impl OccluderSet {
    /// The occluders of one building (empty if the id is unknown).
    pub fn occluders_of(&self, building: BuildingId) -> &[Occluder] {
        self.per_building
            .get(building.index())
            .and_then(|o| {
                self.occluders
                    .get(o.occluder_range.start as usize..o.occluder_range.end as usize)
            })
            .unwrap_or(&[])
    }

    /// Total triangles of all occluder meshes.
    pub fn triangle_count(&self) -> usize {
        self.occluders.iter().map(|o| o.mesh.triangle_count()).sum()
    }

    /// Checks the structure: outcomes are in building order with ids equal to positions,
    /// ranges tile `occluders` in order, an outcome has a reason exactly when its range is
    /// empty, occluders belong to their outcome's building with levels 0.. in order, heights
    /// are finite with `base_m < z_m`, footprints are valid, meshes are finite, index within
    /// range, lie between `base_m` and the building's top and count as the outcome says.
    /// Returns the first violation found.
    pub fn check_invariants(&self) -> Result<(), String> {
        let mut next = 0u32;
        for (i, outcome) in self.per_building.iter().enumerate() {
            let id = outcome.building;
            if id.index() != i {
                return Err(format!("outcome {i} is for building {}", id.0));
            }
            let range = &outcome.occluder_range;
            if range.start != next || range.end < range.start {
                return Err(format!(
                    "building {i}: occluder range {range:?} does not start at {next}"
                ));
            }
            if range.end as usize > self.occluders.len() {
                return Err(format!(
                    "building {i}: occluder range {range:?} beyond {} occluders",
                    self.occluders.len()
                ));
            }
            next = range.end;
            match (&outcome.reason_if_none, range.is_empty()) {
                (Some(r), false) => {
                    return Err(format!("building {i}: has occluders and a reason ({r})"));
                }
                (None, true) => return Err(format!("building {i}: no occluder and no reason")),
                _ => {}
            }
            let mut triangles = 0usize;
            for (level, o) in self.occluders[range.start as usize..range.end as usize]
                .iter()
                .enumerate()
            {
                if o.building != id {
                    return Err(format!(
                        "building {i}: occluder level {level} belongs to building {}",
                        o.building.0
                    ));
                }
                if o.level as usize != level {
                    return Err(format!(
                        "building {i}: occluder {level} has level {}",
                        o.level
                    ));
                }
                check_occluder(o).map_err(|e| format!("building {i} level {level}: {e}"))?;
                triangles += o.mesh.triangle_count();
            }
            if triangles != outcome.occluder_polygons as usize {
                return Err(format!(
                    "building {i}: {triangles} occluder triangles, outcome says {}",
                    outcome.occluder_polygons
                ));
            }
        }
        if next as usize != self.occluders.len() {
            return Err(format!(
                "{} occluders, outcomes cover {next}",
                self.occluders.len()
            ));
        }
        Ok(())
    }
}

/// Checks one occluder on its own (heights, footprint, mesh).
fn check_occluder(o: &Occluder) -> Result<(), String> {
    if !(o.base_m.is_finite() && o.z_m.is_finite() && o.base_m < o.z_m) {
        return Err(format!("heights {}..{}", o.base_m, o.z_m));
    }
    crate::validate::check_multipolygon(&o.footprint).map_err(|r| format!("footprint {r}"))?;
    if !o.mesh.indices.len().is_multiple_of(3) || o.mesh.indices.is_empty() {
        return Err(format!("mesh has {} indices", o.mesh.indices.len()));
    }
    let n = o.mesh.positions.len();
    if let Some(bad) = o.mesh.indices.iter().find(|&&i| i as usize >= n) {
        return Err(format!("mesh index {bad} beyond {n} positions"));
    }
    // A centimetre of slack for f32 rounding of the heights.
    const SLACK_M: f32 = 0.01;
    for p in &o.mesh.positions {
        if !p.is_finite() {
            return Err(format!("mesh position {p} is not finite"));
        }
        if p.z < o.base_m - SLACK_M {
            return Err(format!("mesh vertex at z {} below base {}", p.z, o.base_m));
        }
        if o.kind != FacadeKind::WallOriented && p.z > o.z_m + SLACK_M {
            return Err(format!("mesh vertex at z {} above level {}", p.z, o.z_m));
        }
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;
    use geo::polygon;
    use glam::Vec3;

    fn occluder(building: u32, level: u32) -> Occluder {
        let square =
            polygon![(x: 0.0, y: 0.0), (x: 1.0, y: 0.0), (x: 1.0, y: 1.0), (x: 0.0, y: 1.0)];
        Occluder {
            building: BuildingId(building),
            level,
            kind: FacadeKind::Open,
            z_m: 5.0,
            base_m: 0.0,
            footprint: MultiPolygon::new(vec![square]),
            mesh: TriangleMesh {
                positions: vec![
                    Vec3::new(0.0, 0.0, 0.0),
                    Vec3::new(1.0, 0.0, 0.0),
                    Vec3::new(1.0, 0.0, 5.0),
                ],
                indices: vec![0, 1, 2],
            },
        }
    }

    fn set() -> OccluderSet {
        OccluderSet {
            occluders: vec![occluder(0, 0), occluder(0, 1)],
            per_building: vec![
                OccluderOutcome {
                    building: BuildingId(0),
                    occluder_range: 0..2,
                    source_polygons: 12,
                    occluder_polygons: 2,
                    reason_if_none: None,
                },
                OccluderOutcome {
                    building: BuildingId(1),
                    occluder_range: 2..2,
                    source_polygons: 0,
                    occluder_polygons: 0,
                    reason_if_none: Some("too small".into()),
                },
            ],
        }
    }

    #[test]
    fn a_consistent_set_passes_and_breaks_are_found() {
        let good = set();
        assert_eq!(good.check_invariants(), Ok(()));
        assert_eq!(good.occluders_of(BuildingId(0)).len(), 2);
        assert!(good.occluders_of(BuildingId(1)).is_empty());

        let mut no_reason = set();
        no_reason.per_building[1].reason_if_none = None;
        assert!(no_reason.check_invariants().is_err());

        let mut wrong_count = set();
        wrong_count.per_building[0].occluder_polygons = 3;
        assert!(wrong_count.check_invariants().is_err());

        let mut too_high = set();
        too_high.occluders[1].mesh.positions[2].z = 6.0;
        assert!(too_high.check_invariants().is_err());

        let mut gap = set();
        gap.per_building[0].occluder_range = 0..1;
        assert!(gap.check_invariants().is_err());
    }

    #[test]
    fn facade_kind_names_round_trip() {
        for k in [
            FacadeKind::Open,
            FacadeKind::Closed,
            FacadeKind::WallOriented,
        ] {
            assert_eq!(FacadeKind::from_name(k.name()), Some(k));
        }
    }
}
