//! From triangle meshes in the local frame to [`Building`]s: the part of the CityJSON and glTF
//! loaders that does not depend on the file format.
//!
//! Each part's footprint is derived from its mesh ([`crate::mesh_footprint`]), its base and top
//! are the mesh's lowest and highest z. A part that fails (no area, absurd height, a vertex out
//! of range) is dropped with a [`LoadWarning`]; a building with no part left is a
//! [`Rejection`] carrying the first part's reason. The building's mesh is the concatenation of
//! its parts' meshes and its footprint the union of theirs. Finally the frame's origin is
//! raised to the lowest building base, so the city stands on the ground plane z = 0.

use std::collections::{BTreeMap, HashMap};
use std::path::Path;

use glam::{DVec3, Vec3};

use crate::city::{Building, BuildingId, BuildingPart, City, HeightSource, TriangleMesh};
use crate::frame::Frame;
use crate::mesh_footprint::triangulate_planar_polygon;
use crate::mesh_footprint::{footprint_from_mesh, union_footprints};
use crate::report::{LoadError, LoadReport, LoadWarning, RejectReason, Rejection};
use crate::validate::{MAX_LOCAL_COORDINATE_M, check_heights};

/// One part of a mesh building, in the local frame.
#[derive(Debug, Clone)]
pub(crate) struct MeshPart {
    pub source_id: String,
    /// The part's geometry, or why it could not be read.
    pub mesh: Result<TriangleMesh, RejectReason>,
}

/// One building as read from a mesh source.
#[derive(Debug, Clone)]
pub(crate) struct MeshBuilding {
    pub source_id: String,
    pub parts: Vec<MeshPart>,
    pub tags: BTreeMap<String, String>,
}

/// Validates and assembles the buildings of one file into a city. `report` already holds the
/// file's counts of parts and its warnings; this adds found / loaded / rejected buildings.
pub(crate) fn assemble(
    path: &Path,
    format: &'static str,
    frame: Frame,
    buildings: Vec<MeshBuilding>,
    mut report: LoadReport,
) -> Result<City, LoadError> {
    if buildings.is_empty() {
        return Err(LoadError::Malformed {
            path: path.to_path_buf(),
            format,
            reason: "no building found".into(),
        });
    }
    let mut frame = frame;
    let mut buildings = buildings;
    frame.origin[2] += lower_to_ground(&mut buildings);
    let mut out = Vec::with_capacity(buildings.len());
    for raw in buildings {
        report.buildings_found += 1;
        match build_one(path, raw.parts, &mut report.warnings) {
            Ok((parts, mesh)) => match finish(parts) {
                Ok((footprint, base_m, top_m, parts)) => {
                    out.push(Building {
                        id: BuildingId(out.len() as u32),
                        source_id: raw.source_id,
                        footprint,
                        parts,
                        base_m,
                        top_m,
                        height_source: HeightSource::Geometry,
                        mesh: Some(Box::new(mesh)),
                        tags: raw.tags.into(),
                    });
                }
                Err(reason) => report.rejected.push(Rejection {
                    file: path.to_path_buf(),
                    source_id: raw.source_id,
                    reason,
                }),
            },
            Err(reason) => report.rejected.push(Rejection {
                file: path.to_path_buf(),
                source_id: raw.source_id,
                reason,
            }),
        }
    }
    report.buildings_loaded = out.len();
    if out.is_empty() {
        return Err(LoadError::nothing_loaded(path, &report));
    }
    tracing::info!(file = %path.display(), format, "{report}");
    let mut city = City {
        frame,
        buildings: out,
        streets: Vec::new(),
        ground_areas: Vec::new(),
        report,
    };
    rest_on_ground(&mut city);
    city.renumber();
    Ok(city)
}

/// Moves the local frame's origin up to the lowest base of the mesh buildings, so that z = 0
/// is the ground the engine draws and walks on. Mesh sources give absolute heights (a vertical
/// datum such as NAP, or ellipsoid heights for ECEF tiles), which leave the buildings floating
/// metres above the local ground plane. The origin's height records the shift, so source
/// coordinates are unchanged: `frame.to_source` of a moved point is the point the file holds.
/// Buildings without a mesh (footprints with heights above their ground, from a merged OSM or
/// GeoJSON file) already stand on the ground and stay. A lowest base far below the others (an
/// underground part, a stray vertex) lifts the whole city: it is logged.
pub(crate) fn rest_on_ground(city: &mut City) {
    let mut bases: Vec<f32> = city
        .buildings
        .iter()
        .filter(|b| b.mesh.is_some())
        .map(|b| b.base_m)
        .filter(|z| z.is_finite())
        .collect();
    if bases.is_empty() {
        return;
    }
    bases.sort_by(f32::total_cmp);
    let lowest_m = bases[0];
    let low_percentile_m = bases[bases.len() / 100];
    if low_percentile_m - lowest_m > OUTLIER_BASE_M {
        tracing::warn!(
            lowest_m,
            low_percentile_m,
            "the lowest building base lies far below the others: the city floats above the \
             ground plane by up to the difference"
        );
    }
    if lowest_m == 0.0 {
        return;
    }
    city.frame.origin[2] += f64::from(lowest_m);
    for b in city.buildings.iter_mut().filter(|b| b.mesh.is_some()) {
        b.base_m -= lowest_m;
        b.top_m -= lowest_m;
        for part in &mut b.parts {
            part.base_m -= lowest_m;
            part.top_m -= lowest_m;
        }
        if let Some(mesh) = &mut b.mesh {
            mesh.positions.iter_mut().for_each(|p| p.z -= lowest_m);
        }
    }
}

/// Moves every part's mesh down by the median of the parts' lowest z and returns that shift,
/// before any height is judged: mesh sources give absolute heights (a vertical datum, or
/// ellipsoid heights for a b3dm read without its tileset, where a city 947 m above the
/// ellipsoid looked like 1,150 m tall buildings). The median, not the lowest, so that one stray
/// vertex far below cannot make every other building too tall; [`rest_on_ground`] then sets the
/// ground to the lowest base that survived.
fn lower_to_ground(buildings: &mut [MeshBuilding]) -> f64 {
    let mut bases: Vec<f32> = buildings
        .iter()
        .flat_map(|b| &b.parts)
        .filter_map(|p| p.mesh.as_ref().ok()?.bounds())
        .map(|(lo, _)| lo.z)
        .filter(|z| z.is_finite())
        .collect();
    if bases.is_empty() {
        return 0.0;
    }
    let mid = bases.len() / 2;
    let ground_m = *bases.select_nth_unstable_by(mid, f32::total_cmp).1;
    if ground_m == 0.0 {
        return 0.0;
    }
    let meshes = buildings.iter_mut().flat_map(|b| &mut b.parts);
    for mesh in meshes.filter_map(|p| p.mesh.as_mut().ok()) {
        mesh.positions.iter_mut().for_each(|p| p.z -= ground_m);
    }
    f64::from(ground_m)
}

/// How far the lowest base may lie below the 1st percentile of the bases before
/// [`rest_on_ground`] warns.
const OUTLIER_BASE_M: f32 = 5.0;

/// Validates each part; returns the surviving parts and the building's mesh.
fn build_one(
    path: &Path,
    parts: Vec<MeshPart>,
    warnings: &mut Vec<LoadWarning>,
) -> Result<(Vec<BuildingPart>, TriangleMesh), RejectReason> {
    let mut first_reason = None;
    let mut kept = Vec::with_capacity(parts.len());
    let mut mesh = TriangleMesh::default();
    let several = parts.len() > 1;
    for part in parts {
        match part.mesh.and_then(|m| build_part(&part.source_id, m)) {
            Ok((p, m)) => {
                mesh.append(&m);
                kept.push(p);
            }
            Err(reason) => {
                if several {
                    warnings.push(LoadWarning {
                        file: path.to_path_buf(),
                        source_id: part.source_id.clone(),
                        message: format!("part dropped: {reason}"),
                    });
                }
                first_reason.get_or_insert(reason);
            }
        }
    }
    if kept.is_empty() {
        return Err(first_reason.unwrap_or_else(|| RejectReason::MissingGeometry("no part".into())));
    }
    Ok((kept, mesh))
}

/// Checks one part's mesh and derives its footprint and heights.
fn build_part(
    source_id: &str,
    mesh: TriangleMesh,
) -> Result<(BuildingPart, TriangleMesh), RejectReason> {
    let Some((lo, hi)) = mesh.bounds() else {
        return Err(RejectReason::MissingGeometry("empty mesh".into()));
    };
    if !(lo.is_finite() && hi.is_finite()) {
        return Err(RejectReason::NonFiniteCoordinate);
    }
    let limit = MAX_LOCAL_COORDINATE_M as f32;
    if lo.abs().max(hi.abs()).max_element() > limit {
        return Err(RejectReason::CoordinateOutOfRange(format!(
            "mesh spans ({:.0}, {:.0}, {:.0})..({:.0}, {:.0}, {:.0}) m",
            lo.x, lo.y, lo.z, hi.x, hi.y, hi.z
        )));
    }
    check_heights(lo.z, hi.z)?;
    let footprint = footprint_from_mesh(&mesh)?.footprint;
    Ok((
        BuildingPart {
            source_id: source_id.to_string(),
            footprint,
            base_m: lo.z,
            top_m: hi.z,
        },
        mesh,
    ))
}

type Finished = (geo::MultiPolygon<f64>, f32, f32, Vec<BuildingPart>);

/// The building's footprint (union of the parts') and height range.
fn finish(parts: Vec<BuildingPart>) -> Result<Finished, RejectReason> {
    let footprint = match parts.as_slice() {
        [single] => single.footprint.clone(),
        _ => union_footprints(parts.iter().map(|p| &p.footprint))?.footprint,
    };
    let base_m = parts.iter().map(|p| p.base_m).fold(f32::INFINITY, f32::min);
    let top_m = parts
        .iter()
        .map(|p| p.top_m)
        .fold(f32::NEG_INFINITY, f32::max);
    check_heights(base_m, top_m)?;
    Ok((footprint, base_m, top_m, parts))
}

/// Centre of the vertices' xy extent, z = 0. An outlier further than the local range from the
/// bulk of the data would drag the centre away from every building, so when the extent is
/// wider than that the per-axis median is used instead.
pub(crate) fn xy_extent_centre(vertices: &[DVec3]) -> [f64; 3] {
    let finite: Vec<DVec3> = vertices.iter().copied().filter(|p| p.is_finite()).collect();
    let Some(&first) = finite.first() else {
        return [0.0; 3];
    };
    let (lo, hi) = finite
        .iter()
        .fold((first, first), |(lo, hi), p| (lo.min(*p), hi.max(*p)));
    let span = hi - lo;
    if span.x.max(span.y) <= MAX_LOCAL_COORDINATE_M {
        let c = (lo + hi) * 0.5;
        return [c.x.round(), c.y.round(), 0.0];
    }
    let median = |f: fn(&DVec3) -> f64| {
        let mut v: Vec<f64> = finite.iter().map(f).collect();
        v.sort_by(f64::total_cmp);
        v.get(v.len() / 2).copied().unwrap_or(0.0)
    };
    [median(|p| p.x).round(), median(|p| p.y).round(), 0.0]
}

/// Appends one planar surface (outer ring, then holes, in the local frame) to a building's
/// `mesh`, triangulated; `corner_ids` are the surface's source vertex ids in ring order, so a
/// vertex shared by several surfaces is stored once (`local` maps source id to mesh index).
/// `position` gives a source vertex in the local frame. A degenerate surface (a sliver,
/// repeated corners) carries no area and adds nothing.
pub(crate) fn append_surface<K: Copy + Eq + std::hash::Hash>(
    mesh: &mut TriangleMesh,
    local: &mut HashMap<K, u32>,
    rings: &[Vec<DVec3>],
    corner_ids: &[K],
    position: impl Fn(K) -> DVec3,
) {
    let Ok(triangles) = triangulate_planar_polygon(rings) else {
        return;
    };
    for flat in triangles.into_iter().flatten() {
        let Some(&vertex) = corner_ids.get(flat) else {
            continue;
        };
        let next = mesh.positions.len() as u32;
        let index = *local.entry(vertex).or_insert_with(|| {
            let p = position(vertex);
            mesh.positions
                .push(Vec3::new(p.x as f32, p.y as f32, p.z as f32));
            next
        });
        mesh.indices.push(index);
    }
}
