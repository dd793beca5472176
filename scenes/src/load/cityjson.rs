//! CityJSON 1.0, 1.1 and 2.0 (<https://www.cityjson.org/specs/>), LoD1 and LoD2 buildings.
//!
//! * Vertices are integers scaled and translated by `transform` (mandatory in 1.1 and 2.0,
//!   optional in 1.0, where vertices may be plain reals).
//! * Every `Building` becomes one [`crate::Building`]. Its parts are its own geometry (when it
//!   has any) and its `BuildingPart` children (followed through `children`, recursively); each
//!   part's mesh is triangulated from the chosen geometry's surfaces, its footprint derived from
//!   the mesh ([`crate::mesh_footprint`]) and its base and top are the mesh's z extent. The
//!   building's mesh is the concatenation of its parts' meshes. A `BuildingPart` that no
//!   `Building` claims becomes a building of its own (counted in `buildings_found` and
//!   `parts_found`, with a warning). Other city objects (terrain, roads, ...) are ignored.
//! * Per object the geometry with the highest LoD below 3 is used (`lod` is a number in 1.0 and
//!   a string such as `"2.2"` in 1.1+); of surface types, `MultiSurface`, `CompositeSurface`,
//!   `Solid` (its outer shell), `MultiSolid` and `CompositeSolid` are read.
//! * Frame: the CRS from `metadata.referenceSystem` (for example `EPSG:7415`), origin at the
//!   centre of the vertices' xy extent and at the height of the lowest building base in the
//!   source's vertical datum (NAP for the Dutch data): the city stands on the ground plane
//!   z = 0, a building's `base_m` is its base above that lowest base, `height_m()` its height
//!   above its own base, and `frame.to_source` gives back the file's coordinates.
//!
//! Malformed files (bad JSON, wrong type or version, missing transform, a vertex that is not
//! three numbers) are a [`LoadError`]. A malformed object (a vertex index out of range,
//! negative, fractional or not a number, wrongly nested boundaries) spoils only itself: its
//! part is dropped and a building with no part left is rejected with its id and the reason
//! (see [`super::mesh_building`]); the file's other objects load.

use std::collections::{BTreeMap, BTreeSet, HashMap};
use std::path::Path;

use glam::DVec3;
use serde_json::{Map, Value};

use super::LoadOptions;
use super::mesh_building::{MeshBuilding, MeshPart, append_surface, assemble, xy_extent_centre};
use crate::city::{City, TriangleMesh};
use crate::frame::{Crs, Frame};
use crate::report::{LoadError, LoadReport, LoadWarning, RejectReason};

const FORMAT: &str = "CityJSON";

/// Geometries with `lod` at or above this are not read (LoD3 facade detail is not needed).
const MAX_LOD_EXCLUSIVE: f64 = 3.0;

/// Loads a CityJSON file.
pub fn load(path: &Path, _options: &LoadOptions) -> Result<City, LoadError> {
    let bytes = std::fs::read(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })?;
    load_bytes(path, &bytes)
}

/// Loads CityJSON from bytes; `path` names the source in errors and the report.
pub fn load_bytes(path: &Path, bytes: &[u8]) -> Result<City, LoadError> {
    let malformed = |reason: String| LoadError::Malformed {
        path: path.to_path_buf(),
        format: FORMAT,
        reason,
    };
    let root: Value = serde_json::from_slice(super::without_bom(bytes))
        .map_err(|e| malformed(format!("invalid JSON: {e}")))?;
    let root = root
        .as_object()
        .ok_or_else(|| malformed("top level is not an object".into()))?;
    if root.get("type").and_then(Value::as_str) != Some("CityJSON") {
        return Err(malformed("\"type\" is not \"CityJSON\"".into()));
    }
    // The CityJSON specification makes "version" a string ("1.1"); a number (1.1) is refused
    // saying so and what was found, not taken for a missing member.
    let version = match root.get("version") {
        Some(Value::String(v)) => v.as_str(),
        Some(other) => {
            return Err(malformed(format!(
                "\"version\" must be a string such as \"1.1\", found {} {other}",
                json_kind(other)
            )));
        }
        None => return Err(malformed("no \"version\"".into())),
    };
    let major_minor = supported_version(version).ok_or_else(|| LoadError::Unsupported {
        path: path.to_path_buf(),
        reason: format!("CityJSON version {version:?} (1.0, 1.1 and 2.0 are supported)"),
    })?;

    let transform = match root.get("transform") {
        Some(t) => Some(parse_transform(t).map_err(malformed)?),
        None if major_minor != (1, 0) => {
            return Err(malformed(format!(
                "no \"transform\" (mandatory in CityJSON {version})"
            )));
        }
        None => None,
    };
    let vertices = parse_vertices(root.get("vertices"), transform.as_ref()).map_err(malformed)?;
    let objects = root
        .get("CityObjects")
        .and_then(Value::as_object)
        .ok_or_else(|| malformed("no \"CityObjects\" object".into()))?;

    let crs = reference_system(root).map_err(|reason| LoadError::Unsupported {
        path: path.to_path_buf(),
        reason,
    })?;
    let origin = xy_extent_centre(&vertices);
    let frame = match crs {
        Some(name) => Frame::projected(name, origin),
        None => Frame {
            crs: Crs::Local,
            origin,
        },
    };
    let origin = DVec3::from_array(origin);

    let mut report = LoadReport {
        files: vec![path.to_path_buf()],
        ..LoadReport::default()
    };
    report.parts_found = objects
        .values()
        .filter(|o| object_type(o) == Some("BuildingPart"))
        .count();

    let reader = Reader {
        objects,
        vertices: &vertices,
        origin,
    };
    let mut claimed: BTreeSet<&str> = BTreeSet::new();
    let mut buildings = Vec::new();
    for (id, object) in objects {
        if object_type(object) != Some("Building") {
            continue;
        }
        let mut part_ids = Vec::new();
        reader.collect_parts(id, &mut part_ids, &mut claimed, 0);
        buildings.push(reader.building(id, object, &part_ids));
    }
    for (id, object) in objects {
        if object_type(object) == Some("BuildingPart") && !claimed.contains(id.as_str()) {
            report.warnings.push(LoadWarning {
                file: path.to_path_buf(),
                source_id: id.clone(),
                message: "BuildingPart of no Building: loaded as a building of its own".into(),
            });
            buildings.push(reader.building(id, object, &[]));
        }
    }
    assemble(path, FORMAT, frame, buildings, report)
}

/// `(major, minor)` of a supported version string (`"1.0"`, `"1.0.3"`, `"1.1"`, `"2.0"`).
fn supported_version(version: &str) -> Option<(u32, u32)> {
    let mut it = version.split('.');
    let major = it.next()?.parse().ok()?;
    let minor = it.next()?.parse().ok()?;
    matches!((major, minor), (1, 0) | (1, 1) | (2, 0)).then_some((major, minor))
}

struct Transform {
    scale: DVec3,
    translate: DVec3,
}

fn parse_transform(t: &Value) -> Result<Transform, String> {
    let vec3 = |key: &str| -> Result<DVec3, String> {
        let v = t
            .get(key)
            .and_then(Value::as_array)
            .ok_or_else(|| format!("\"transform\" has no \"{key}\" array"))?;
        let p = number3(v).ok_or_else(|| format!("\"transform.{key}\" is not 3 numbers"))?;
        if !p.is_finite() {
            return Err(format!("\"transform.{key}\" is not finite"));
        }
        Ok(p)
    };
    Ok(Transform {
        scale: vec3("scale")?,
        translate: vec3("translate")?,
    })
}

/// What kind of JSON value `v` is, for messages.
fn json_kind(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "the boolean",
        Value::Number(_) => "the number",
        Value::String(_) => "the string",
        Value::Array(_) => "an array",
        Value::Object(_) => "an object",
    }
}

fn number3(v: &[Value]) -> Option<DVec3> {
    match v {
        [x, y, z] => Some(DVec3::new(x.as_f64()?, y.as_f64()?, z.as_f64()?)),
        _ => None,
    }
}

/// The vertices in source coordinates (transform applied). Non-finite results are kept and
/// rejected with the buildings that use them.
fn parse_vertices(v: Option<&Value>, transform: Option<&Transform>) -> Result<Vec<DVec3>, String> {
    let list = v
        .and_then(Value::as_array)
        .ok_or_else(|| "no \"vertices\" array".to_string())?;
    list.iter()
        .enumerate()
        .map(|(i, v)| {
            let p = v
                .as_array()
                .and_then(|a| number3(a))
                .ok_or_else(|| format!("vertex {i} is not [x, y, z]"))?;
            Ok(match transform {
                Some(t) => p * t.scale + t.translate,
                None => p,
            })
        })
        .collect()
}

/// `EPSG:NNNN` from `metadata.referenceSystem` (`urn:ogc:def:crs:EPSG::7415` in 1.0,
/// `https://www.opengis.net/def/crs/EPSG/0/7415` in 1.1+), `None` if absent. Geographic CRSs
/// (degrees) are refused: CityJSON buildings are expected in metres.
fn reference_system(root: &Map<String, Value>) -> Result<Option<String>, String> {
    let Some(rs) = root
        .get("metadata")
        .and_then(|m| m.get("referenceSystem"))
        .and_then(Value::as_str)
    else {
        return Ok(None);
    };
    let code = rs
        .rsplit([':', '/'])
        .find(|s| !s.is_empty())
        .and_then(|s| s.parse::<u32>().ok());
    match code {
        Some(4326 | 4979 | 4258 | 4937 | 7912 | 4289) => Err(format!(
            "geographic reference system {rs} (CityJSON in degrees is not supported)"
        )),
        Some(code) if rs.to_ascii_uppercase().contains("EPSG") => Ok(Some(format!("EPSG:{code}"))),
        _ => Ok(Some(rs.to_string())),
    }
}

fn object_type(object: &Value) -> Option<&str> {
    object.get("type").and_then(Value::as_str)
}

/// Reads city objects into mesh buildings.
struct Reader<'a> {
    objects: &'a Map<String, Value>,
    vertices: &'a [DVec3],
    origin: DVec3,
}

/// Children deeper than this are not followed (a guard against cyclic `children` links).
const MAX_PART_DEPTH: usize = 16;

impl<'a> Reader<'a> {
    /// The `BuildingPart` descendants of `id`, each once.
    fn collect_parts(
        &self,
        id: &str,
        out: &mut Vec<&'a str>,
        claimed: &mut BTreeSet<&'a str>,
        depth: usize,
    ) {
        if depth > MAX_PART_DEPTH {
            return;
        }
        let Some(children) = self
            .objects
            .get(id)
            .and_then(|o| o.get("children"))
            .and_then(Value::as_array)
        else {
            return;
        };
        for child in children.iter().filter_map(Value::as_str) {
            let Some((key, object)) = self.objects.get_key_value(child) else {
                continue;
            };
            if object_type(object) == Some("BuildingPart") && claimed.insert(key.as_str()) {
                out.push(key.as_str());
                self.collect_parts(key, out, claimed, depth + 1);
            }
        }
    }

    fn building(&self, id: &str, object: &Value, part_ids: &[&str]) -> MeshBuilding {
        let mut parts = Vec::with_capacity(part_ids.len() + 1);
        let own = self.part_mesh(id, object);
        let has_own = !matches!(own, Err(RejectReason::MissingGeometry(_)));
        if has_own || part_ids.is_empty() {
            parts.push(MeshPart {
                source_id: id.to_string(),
                mesh: own,
            });
        }
        for part_id in part_ids {
            if let Some(part) = self.objects.get(*part_id) {
                parts.push(MeshPart {
                    source_id: (*part_id).to_string(),
                    mesh: self.part_mesh(part_id, part),
                });
            }
        }
        let mut tags = BTreeMap::new();
        if let Some(t) = object_type(object) {
            tags.insert("cityjson:type".to_string(), t.to_string());
        }
        if let Some(attributes) = object.get("attributes").and_then(Value::as_object) {
            for (k, v) in attributes {
                let s = match v {
                    Value::String(s) => s.clone(),
                    Value::Null => continue,
                    other => other.to_string(),
                };
                tags.insert(k.clone(), s);
            }
        }
        MeshBuilding {
            source_id: id.to_string(),
            parts,
            tags,
        }
    }

    /// The mesh of one object's best geometry, or why this object has none (a bad index or
    /// nesting is [`RejectReason::InvalidGeometry`] of this object only).
    fn part_mesh(&self, id: &str, object: &Value) -> Result<TriangleMesh, RejectReason> {
        self.read_mesh(id, object)
            .unwrap_or_else(|malformed| Err(RejectReason::InvalidGeometry(malformed)))
    }

    /// [`Self::part_mesh`]: `Err(String)` for a malformed geometry (bad index or nesting), the
    /// inner `Err(RejectReason)` for a well-formed one that gives no mesh.
    fn read_mesh(
        &self,
        id: &str,
        object: &Value,
    ) -> Result<Result<TriangleMesh, RejectReason>, String> {
        let Some(geometry) = best_geometry(object) else {
            return Ok(Err(RejectReason::MissingGeometry(
                "no MultiSurface, CompositeSurface, Solid, MultiSolid or CompositeSolid below \
                 LoD3"
                    .into(),
            )));
        };
        let kind = geometry.get("type").and_then(Value::as_str).unwrap_or("");
        let boundaries = geometry
            .get("boundaries")
            .ok_or_else(|| format!("CityObject {id}: geometry without \"boundaries\""))?;
        let mut surfaces: Vec<&Value> = Vec::new();
        match kind {
            "MultiSurface" | "CompositeSurface" => {
                surfaces.extend(nested_array(boundaries, id, kind, "surface list")?);
            }
            "Solid" => {
                if let Some(outer) = nested_array(boundaries, id, kind, "shell list")?.first() {
                    surfaces.extend(nested_array(outer, id, kind, "shell")?);
                }
            }
            _ => {
                for solid in nested_array(boundaries, id, kind, "solid list")? {
                    if let Some(outer) = nested_array(solid, id, kind, "shell list")?.first() {
                        surfaces.extend(nested_array(outer, id, kind, "shell")?);
                    }
                }
            }
        }
        let mut mesh = TriangleMesh::default();
        let mut local_index: HashMap<usize, u32> = HashMap::new();
        let mut non_finite = false;
        let mut rings: Vec<Vec<DVec3>> = Vec::new();
        let mut ids: Vec<usize> = Vec::new();
        for surface in surfaces {
            rings.clear();
            ids.clear();
            for ring in nested_array(surface, id, kind, "surface")? {
                let mut points = Vec::new();
                for index in nested_array(ring, id, kind, "ring")? {
                    let i = index
                        .as_u64()
                        .and_then(|i| usize::try_from(i).ok())
                        .filter(|&i| i < self.vertices.len())
                        .ok_or_else(|| {
                            format!(
                                "CityObject {id}: vertex index {index} is not an index of the \
                                 {} vertices",
                                self.vertices.len()
                            )
                        })?;
                    let p = self.vertices[i] - self.origin;
                    non_finite |= !p.is_finite();
                    points.push(p);
                    ids.push(i);
                }
                rings.push(points);
            }
            if non_finite {
                continue;
            }
            append_surface(&mut mesh, &mut local_index, &rings, &ids, |v| {
                self.vertices[v] - self.origin
            });
        }
        if non_finite {
            return Ok(Err(RejectReason::NonFiniteCoordinate));
        }
        if mesh.indices.is_empty() {
            return Ok(Err(RejectReason::ZeroArea));
        }
        Ok(Ok(mesh))
    }
}

/// `v` as an array, or a description of the broken nesting.
fn nested_array<'v>(
    v: &'v Value,
    id: &str,
    kind: &str,
    what: &str,
) -> Result<&'v Vec<Value>, String> {
    v.as_array()
        .ok_or_else(|| format!("CityObject {id}: {kind} boundaries: {what} is not an array"))
}

/// The geometry with the highest LoD below 3 among the surface types read.
fn best_geometry(object: &Value) -> Option<&Value> {
    let list = object.get("geometry")?.as_array()?;
    let mut best: Option<(f64, &Value)> = None;
    for g in list {
        let kind = g.get("type").and_then(Value::as_str);
        if !matches!(
            kind,
            Some("MultiSurface" | "CompositeSurface" | "Solid" | "MultiSolid" | "CompositeSolid")
        ) {
            continue;
        }
        let lod = match g.get("lod") {
            Some(Value::Number(n)) => n.as_f64(),
            Some(Value::String(s)) => s.trim().parse::<f64>().ok(),
            _ => None,
        };
        let Some(lod) = lod.filter(|l| l.is_finite() && *l < MAX_LOD_EXCLUSIVE) else {
            continue;
        };
        if best.is_none_or(|(b, _)| lod > b) {
            best = Some((lod, g));
        }
    }
    best.map(|(_, g)| g)
}
