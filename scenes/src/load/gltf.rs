//! glTF 2.0 (`.glb`, `.gltf`), 3D Tiles 1.0 b3dm tiles (`.b3dm`) and tilesets
//! (`tileset.json`) of building meshes.
//!
//! * The scene graph is walked with each node's transform; glTF is y-up and is turned z-up with
//!   `(x, y, z) → (x, −z, y)`, the rotation 3D Tiles prescribes for glTF content (3D Tiles 1.0,
//!   "glTF transforms"). Triangles, strips and fans are read; points and lines are ignored.
//! * Buildings: when a primitive has the `_BATCHID` attribute (b3dm batching), one feature per
//!   batch id; otherwise one feature per node instance of a mesh. Feature ids come from the
//!   batch table (the b3dm's own, or a sidecar `NAME.batch.json` beside `NAME.glb` holding
//!   `{"feature_table": …, "batch_table": …}`): the first of the columns [`ID_COLUMNS`] present.
//!   **Features sharing an id are merged into one building**: in the pg2b3dm Amsterdam sample
//!   every building (BAG `blockid`) is written as two batch features with identical geometry,
//!   so merging gives one building per real building; exact duplicate triangles are dropped.
//!   3D Tiles 1.1 content without `_BATCHID` has a feature per `EXT_mesh_features` feature id,
//!   named by its `EXT_structural_metadata` property table ([`features`]).
//!   Without ids (no batch table), features with exactly the same triangles are one building
//!   written twice: kept once, each copy a warning.
//!   Each building has one part, its footprint derived from the mesh
//!   ([`crate::mesh_footprint`]), base and top the mesh's z extent.
//! * Placement: a tileset is used when the input is one, or when a `tileset.json` beside the
//!   file or one folder up lists a content with the file's stem (`glb/7.glb` ↔ `tiles/7.b3dm`);
//!   content is then placed with its tiles' accumulated transforms (plus the b3dm
//!   `RTC_CENTER`) in ECEF, and the frame is [`Frame::ecef`] at the centre of the tileset's
//!   root bounding volume, so every tile of one tileset lands in the same frame and
//!   [`crate::load_cities`] merges them without a shift. Heights are then ellipsoidal (WGS84).
//!   A tileset whose centre is not on the earth (no root transform to ECEF) keeps its own
//!   metres ([`Frame::local`]).
//!   Without a tileset, a b3dm `RTC_CENTER` on the earth places the content in ECEF likewise;
//!   otherwise the glTF's own metres are the local frame ([`Frame::local`]), a b3dm's with a
//!   warning that it is not georeferenced, and content whose walls lean (a tile written in
//!   ECEF axes, copied out of its tileset folder) levelled by its walls ([`level`]), with a
//!   warning.
//!   In every case the origin is then raised to the lowest building base, so the city stands
//!   on the ground plane z = 0 (the origin's height keeps the shift).
//!
//! External files (glTF buffer `uri`s, tileset contents) are read only from inside the naming
//! file's folder, only when regular, and never past their declared length ([`uri`]).
//!
//! Malformed files (bad GLB/b3dm header, invalid glTF JSON, truncated buffers, an accessor or
//! index out of range) are a [`LoadError`]; malformed buildings are rejections (see
//! [`super::mesh_building`]).

use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::Path;

use ::gltf::accessor::Dimensions;
use ::gltf::mesh::Mode;
use ::gltf::{Document, Semantic, buffer};
use glam::{DMat4, DVec3, Vec3};
use serde_json::Value;

use super::LoadOptions;
use super::mesh_building::{MeshBuilding, MeshPart, assemble};
use crate::city::{City, TriangleMesh};
use crate::frame::Frame;
use crate::report::{LoadError, LoadReport, LoadWarning};

mod accessor;
mod b3dm;
mod features;
mod glb;
mod level;
mod tileset;
mod uri;

const FORMAT: &str = "glTF";

/// Batch-table columns taken as the feature id, in order of preference.
pub const ID_COLUMNS: [&str; 6] = ["id", "blockid", "gml_id", "identificatie", "bag_id", "name"];

/// A tile's content is read up to this size: a b3dm's header counts its bytes in a u32.
const MAX_CONTENT_BYTES: u64 = u32::MAX as u64;

/// Node trees deeper than this are not followed (a guard against cyclic node graphs).
const MAX_NODE_DEPTH: usize = 64;
/// At most this many node instances are read per file.
const MAX_NODE_INSTANCES: usize = 1_000_000;

/// Loads a `.glb`, `.gltf`, `.b3dm` or `tileset.json`, placing it with a tileset when one is
/// found (see the module documentation).
pub fn load(path: &Path, _options: &LoadOptions) -> Result<City, LoadError> {
    let bytes = read(path)?;
    load_any(path, &bytes, true)
}

/// Loads glTF, b3dm or tileset bytes; `path` names the source in errors and resolves relative
/// URIs, but no tileset or sidecar is searched for: a lone glTF or b3dm stays in its own metres.
pub fn load_bytes(path: &Path, bytes: &[u8]) -> Result<City, LoadError> {
    load_any(path, bytes, false)
}

fn read(path: &Path) -> Result<Vec<u8>, LoadError> {
    std::fs::read(path).map_err(|source| LoadError::Io {
        path: path.to_path_buf(),
        source,
    })
}

fn malformed(path: &Path, reason: impl Into<String>) -> LoadError {
    LoadError::Malformed {
        path: path.to_path_buf(),
        format: FORMAT,
        reason: reason.into(),
    }
}

/// Where content goes: content z-up coordinates → the frame's source coordinates (ECEF for a
/// tileset on the earth), and the frame.
#[derive(Debug, Clone)]
struct Placement {
    to_source: DMat4,
    frame: Frame,
}

impl Placement {
    fn local(&self, p: DVec3) -> DVec3 {
        self.frame.to_local(self.to_source.transform_point3(p))
    }
}

/// Batch information of one glTF: its batch table and RTC centre.
#[derive(Debug, Clone, Default)]
struct BatchInfo {
    table: Option<serde_json::Map<String, Value>>,
    rtc_center: DVec3,
}

impl BatchInfo {
    fn from_tables(feature_table: &Value, batch_table: Option<Value>) -> BatchInfo {
        let rtc_center = feature_table
            .get("RTC_CENTER")
            .and_then(Value::as_array)
            .and_then(|a| match a.as_slice() {
                [x, y, z] => Some(DVec3::new(x.as_f64()?, y.as_f64()?, z.as_f64()?)),
                _ => None,
            })
            .filter(|p| p.is_finite())
            .unwrap_or(DVec3::ZERO);
        BatchInfo {
            table: batch_table.and_then(|t| match t {
                Value::Object(m) => Some(m),
                _ => None,
            }),
            rtc_center,
        }
    }
}

fn load_any(path: &Path, bytes: &[u8], search: bool) -> Result<City, LoadError> {
    let bytes = super::without_bom(bytes);
    if bytes.starts_with(b"b3dm") {
        let placement = if search {
            find_placement(path)?
        } else {
            (None, Vec::new())
        };
        let tile = b3dm::parse(bytes).map_err(|r| malformed(path, r))?;
        let batch = BatchInfo::from_tables(&tile.feature_table, tile.batch_table);
        return load_single(path, tile.glb, batch, Content::B3dm, placement);
    }
    if !bytes.starts_with(b"glTF") {
        // JSON: a tileset, or a .gltf.
        let json: Value = serde_json::from_slice(bytes)
            .map_err(|e| malformed(path, format!("neither GLB, b3dm nor JSON: {e}")))?;
        if tileset::looks_like_tileset(&json) {
            return load_tileset(path, &json);
        }
    }
    let (placement, batch) = if search {
        (find_placement(path)?, find_sidecar(path)?)
    } else {
        ((None, Vec::new()), BatchInfo::default())
    };
    load_single(path, bytes, batch, Content::Gltf, placement)
}

/// A tileset beside `path` or one folder up that lists a content named like `path`.
fn find_placement(path: &Path) -> Result<(Option<Placement>, Vec<LoadWarning>), LoadError> {
    let mut warnings = Vec::new();
    let Some(stem) = path.file_stem() else {
        return Ok((None, warnings));
    };
    let dir = path.parent().unwrap_or(Path::new(""));
    let candidates = [
        Some(dir.join("tileset.json")),
        dir.parent().map(|d| d.join("tileset.json")),
    ];
    for candidate in candidates.into_iter().flatten() {
        if !candidate.is_file() || candidate == path {
            continue;
        }
        let text = read(&candidate)?;
        let Ok(json) = serde_json::from_slice::<Value>(super::without_bom(&text)) else {
            continue;
        };
        if !tileset::looks_like_tileset(&json) {
            continue;
        }
        let set = match tileset::parse(&candidate, &json) {
            Ok(set) => set,
            Err(reason) => {
                warnings.push(LoadWarning {
                    file: path.to_path_buf(),
                    source_id: String::new(),
                    message: format!("{} ignored: {reason}", candidate.display()),
                });
                continue;
            }
        };
        let hit = set.contents.iter().find(|c| c.path == path).or_else(|| {
            set.contents
                .iter()
                .find(|c| c.path.file_stem() == Some(stem))
        });
        match hit {
            Some(content) => {
                return Ok((
                    Some(Placement {
                        to_source: content.to_ecef,
                        frame: tileset_frame(set.centre_ecef),
                    }),
                    warnings,
                ));
            }
            None => warnings.push(LoadWarning {
                file: path.to_path_buf(),
                source_id: String::new(),
                message: format!(
                    "{} lists no content named {}: kept in the glTF's own metres",
                    candidate.display(),
                    stem.to_string_lossy()
                ),
            }),
        }
    }
    Ok((None, warnings))
}

/// ECEF radii accepted as a place on the earth (metres): the ellipsoid's polar and equatorial
/// radii (6,356,752 m and 6,378,137 m) widened by the deepest trench and the highest orbit a
/// city model might use.
const EARTH_RADIUS_RANGE_M: std::ops::RangeInclusive<f64> = 6_300_000.0..=6_500_000.0;

/// The frame of a tileset centred on `centre_ecef`: east-north-up there when the centre is on
/// the earth; otherwise the tileset is not georeferenced (no root transform to ECEF) and its
/// own metres are the local frame.
fn tileset_frame(centre_ecef: DVec3) -> Frame {
    if EARTH_RADIUS_RANGE_M.contains(&centre_ecef.length()) {
        Frame::ecef(centre_ecef)
    } else {
        Frame::local()
    }
}

/// The sidecar `NAME.batch.json` beside `NAME.glb`, if any.
fn find_sidecar(path: &Path) -> Result<BatchInfo, LoadError> {
    let Some(stem) = path.file_stem() else {
        return Ok(BatchInfo::default());
    };
    let sidecar = path.with_file_name(format!("{}.batch.json", stem.to_string_lossy()));
    if !sidecar.is_file() {
        return Ok(BatchInfo::default());
    }
    let text = read(&sidecar)?;
    let json: Value = serde_json::from_slice(super::without_bom(&text))
        .map_err(|e| malformed(&sidecar, format!("batch table sidecar is not JSON: {e}")))?;
    if !json.is_object() {
        return Err(malformed(&sidecar, "batch table sidecar is not an object"));
    }
    Ok(match (json.get("feature_table"), json.get("batch_table")) {
        (None, None) => BatchInfo::from_tables(&Value::Null, Some(json)),
        (ft, bt) => BatchInfo::from_tables(ft.unwrap_or(&Value::Null), bt.cloned()),
    })
}

/// One glTF (standalone, or the content of one b3dm) to a city. Without a tileset's placement,
/// see [`own_placement`].
fn load_single(
    path: &Path,
    glb: &[u8],
    batch: BatchInfo,
    content: Content,
    (placement, warnings): (Option<Placement>, Vec<LoadWarning>),
) -> Result<City, LoadError> {
    let features = read_features(path, glb, &batch)?;
    let mut warnings = warnings;
    let placement = match placement {
        Some(p) => Some(p),
        None => own_placement(path, &features, &batch, content, &mut warnings),
    };
    let frame = placement
        .as_ref()
        .map_or_else(Frame::local, |p| p.frame.clone());
    let buildings =
        buildings_from_features(path, features, &batch, placement.as_ref(), &mut warnings);
    let report = LoadReport {
        files: vec![path.to_path_buf()],
        parts_found: buildings.len(),
        warnings,
        ..LoadReport::default()
    };
    assemble(path, FORMAT, frame, buildings, report)
}

/// What a file read alone holds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Content {
    /// A 3D Tiles tile, made to be placed by a tileset.
    B3dm,
    /// A glTF, whose metres are its own.
    Gltf,
}

/// Where a glTF or b3dm that no tileset places goes. An `RTC_CENTER` on the earth is ECEF (the
/// tileset's transforms were the identity): the content is placed as its tileset would place
/// it, east-north-up at that centre. Otherwise nothing says where it is: for a b3dm, made to be
/// placed by a tileset, that is a warning naming the file. Content whose walls lean (written as
/// ECEF offsets from its tileset's root, see [`level`]) is levelled, with a warning saying by
/// how much, so that heights are judged upright: a silently tilted city is wrong everywhere.
fn own_placement(
    path: &Path,
    features: &[Feature],
    batch: &BatchInfo,
    content: Content,
    warnings: &mut Vec<LoadWarning>,
) -> Option<Placement> {
    if EARTH_RADIUS_RANGE_M.contains(&batch.rtc_center.length()) {
        return Some(Placement {
            to_source: DMat4::IDENTITY,
            frame: Frame::ecef(batch.rtc_center),
        });
    }
    let upright = level::uprightness(features.iter().flat_map(|f| &f.triangles));
    let leaning = upright.filter(level::Uprightness::leans);
    let unplaced = match content {
        Content::B3dm => {
            "not georeferenced: no tileset.json beside it or one folder up lists it and its \
             RTC_CENTER is not on the earth, so it is loaded in its own metres"
        }
        Content::Gltf if leaning.is_some() => "not georeferenced",
        Content::Gltf => return None,
    };
    let message = match &leaning {
        Some(u) => format!(
            "{unplaced}; its walls lean {:.1}° from its z axis (content written in ECEF axes, \
             whose tileset is missing?), so it is levelled to stand on them (its coordinates are \
             no longer the file's)",
            u.tilt_deg
        ),
        None => unplaced.to_string(),
    };
    warnings.push(LoadWarning {
        file: path.to_path_buf(),
        source_id: String::new(),
        message,
    });
    leaning.map(|u| Placement {
        to_source: u.levelling(),
        frame: Frame::local(),
    })
}

/// Every b3dm (or glTF) content of a tileset, in the tileset's ECEF frame.
fn load_tileset(path: &Path, json: &Value) -> Result<City, LoadError> {
    let set = tileset::parse(path, json).map_err(|r| malformed(path, r))?;
    let frame = tileset_frame(set.centre_ecef);
    let mut report = LoadReport {
        files: vec![path.to_path_buf()],
        ..LoadReport::default()
    };
    let mut buildings = Vec::new();
    for content in &set.contents {
        let lower = content.uri.to_ascii_lowercase();
        let placement = Placement {
            to_source: content.to_ecef,
            frame: frame.clone(),
        };
        let bytes =
            if lower.ends_with(".b3dm") || lower.ends_with(".glb") || lower.ends_with(".gltf") {
                uri::read_inside(uri::base_dir(path), &content.path, MAX_CONTENT_BYTES, false)
                    .map_err(|r| malformed(path, format!("content {:?}: {r}", content.uri)))?
            } else {
                report.warnings.push(LoadWarning {
                    file: path.to_path_buf(),
                    source_id: content.uri.clone(),
                    message: "content skipped (only b3dm and glTF contents are read)".into(),
                });
                continue;
            };
        let (glb, batch) = if bytes.starts_with(b"b3dm") {
            let tile = b3dm::parse(&bytes).map_err(|r| malformed(&content.path, r))?;
            let batch = BatchInfo::from_tables(&tile.feature_table, tile.batch_table);
            (tile.glb, batch)
        } else {
            (bytes.as_slice(), BatchInfo::default())
        };
        let features = read_features(&content.path, glb, &batch)?;
        buildings.extend(buildings_from_features(
            &content.path,
            features,
            &batch,
            Some(&placement),
            &mut report.warnings,
        ));
        report.files.push(content.path.clone());
    }
    report.parts_found = buildings.len();
    assemble(path, FORMAT, frame, buildings, report)
}

/// The triangles of one feature (one batch id, or one node instance), in content z-up
/// coordinates, corners counter-clockwise seen from outside.
#[derive(Debug, Default)]
struct Feature {
    /// The batch id, or `None` for a node instance.
    batch_id: Option<u32>,
    /// Name for a node instance (node or mesh name, or `node/N`).
    name: String,
    /// The source id a 3D Tiles 1.1 property table gives the feature ([`features`]).
    source_id: Option<String>,
    triangles: Vec<[DVec3; 3]>,
}

/// Parses the glTF and gathers its triangles by feature.
fn read_features(path: &Path, bytes: &[u8], batch: &BatchInfo) -> Result<Vec<Feature>, LoadError> {
    // A tileset's .gltf content may carry a byte order mark too.
    let bytes = super::without_bom(bytes);
    if bytes.starts_with(b"glTF") {
        glb::check_header(bytes, false).map_err(|r| malformed(path, r))?;
    }
    let gltf = ::gltf::Gltf::from_slice_without_validation(bytes)
        .map_err(|e| malformed(path, e.to_string()))?;
    glb::check_asset_version(&gltf.document.as_json().asset.version)
        .map_err(|r| malformed(path, r))?;
    validate(&gltf.document).map_err(|r| malformed(path, r))?;
    let buffers = import_buffers(path, &gltf.document, gltf.blob.as_deref())
        .map_err(|r| malformed(path, r))?;
    let doc = &gltf.document;
    let mut walker = Walker {
        buffers: &buffers,
        batched: HashMap::new(),
        featured: HashMap::new(),
        instances: Vec::new(),
        visited: 0,
    };
    for (node, matrix) in root_nodes(doc) {
        walker
            .node(node, matrix, 0)
            .map_err(|r| malformed(path, r))?;
    }
    let Walker {
        batched,
        featured,
        instances,
        ..
    } = walker;
    let mut features: Vec<Feature> = batched
        .into_iter()
        .map(|(id, triangles)| Feature {
            batch_id: Some(id),
            name: String::new(),
            source_id: None,
            triangles,
        })
        .collect();
    features.sort_by_key(|f| f.batch_id);
    // 3D Tiles 1.1 features, named by their property tables.
    let root_metadata = doc
        .as_json()
        .extensions
        .as_ref()
        .and_then(|e| e.others.get("EXT_structural_metadata"));
    let names = features::table_names(root_metadata, doc, &buffers);
    let mut identified: Vec<_> = featured.into_iter().collect();
    identified.sort_by_key(|(key, _)| *key);
    features.extend(identified.into_iter().map(|((table, id), triangles)| {
        let name = names
            .get(table)
            .and_then(Option::as_ref)
            .and_then(|n| n.get(id as usize))
            .cloned()
            .unwrap_or_else(|| format!("{table}#{id}"));
        Feature {
            batch_id: None,
            name: String::new(),
            source_id: Some(name),
            triangles,
        }
    }));
    features.extend(instances);
    // Shift by the b3dm RTC centre (in content z-up coordinates).
    if batch.rtc_center != DVec3::ZERO {
        for f in &mut features {
            for t in &mut f.triangles {
                t.iter_mut().for_each(|p| *p += batch.rtc_center);
            }
        }
    }
    Ok(features)
}

/// The data of every buffer, `byteLength` bytes each: the GLB's binary chunk, a base64 `data:`
/// URI, or a file inside the glTF's folder ([`uri`]); never more than `byteLength` is read.
fn import_buffers(
    path: &Path,
    doc: &Document,
    blob: Option<&[u8]>,
) -> Result<Vec<buffer::Data>, String> {
    let mut out = Vec::new();
    for b in doc.buffers() {
        let length = b.length();
        let what = format!("buffer {} (byteLength {length})", b.index());
        let mut data = match b.source() {
            buffer::Source::Bin => {
                let blob = blob.ok_or_else(|| format!("{what}: the file has no binary chunk"))?;
                if blob.len() < length {
                    return Err(format!("{what}: the binary chunk has {} bytes", blob.len()));
                }
                blob[..length].to_vec()
            }
            buffer::Source::Uri(u) if u.starts_with("data:") => {
                // The gltf crate decodes data URIs without touching the file system.
                let data = buffer::Data::from_source(buffer::Source::Uri(u), None)
                    .map_err(|e| format!("{what}: {e}"))?
                    .0;
                if data.len() < length {
                    return Err(format!("{what}: its data: uri holds {} bytes", data.len()));
                }
                data
            }
            buffer::Source::Uri(u) => {
                let file = uri::resolve(path, u).map_err(|r| format!("{what}: {r}"))?;
                uri::read_inside(uri::base_dir(path), &file, length as u64, true)
                    .map_err(|r| format!("{what}: {r}"))?
            }
        };
        data.truncate(length);
        // As the gltf crate does: buffer data padded to a multiple of four bytes.
        data.resize(length.div_ceil(4) * 4, 0);
        out.push(buffer::Data(data));
    }
    Ok(out)
}

/// Runs the `gltf` crate's validation (every index between objects in range, which the
/// crate's accessors rely on), tolerating only a POSITION accessor without `min`/`max`: the
/// spec requires them, but they are not needed here and some exporters omit them.
fn validate(doc: &Document) -> Result<(), String> {
    use ::gltf::json::validation::{Error, Validate};
    let root = doc.as_json();
    // gltf-json 1.4.1 indexes the POSITION accessor in its primitive check without a bounds
    // check (mesh.rs, `primitive_validate_hook`): check attribute indices first.
    for (m, mesh) in root.meshes.iter().enumerate() {
        for (p, primitive) in mesh.primitives.iter().enumerate() {
            for index in primitive.attributes.values() {
                if index.value() >= root.accessors.len() {
                    return Err(format!(
                        "invalid glTF: meshes[{m}].primitives[{p}] names accessor {} of {}",
                        index.value(),
                        root.accessors.len()
                    ));
                }
            }
        }
    }
    let mut errors: Vec<String> = Vec::new();
    root.validate(root, ::gltf::json::Path::new, &mut |path, error| {
        let path = path();
        let p = path.as_str();
        let bounds = p.ends_with(".min") || p.ends_with(".max");
        if !(bounds && matches!(error, Error::Missing)) {
            errors.push(format!("{p}: {error}"));
        }
    });
    if errors.is_empty() {
        Ok(())
    } else {
        Err(format!("invalid glTF: {}", errors.join("; ")))
    }
}

/// The scene's root nodes (the default scene, else the first, else every node that is no
/// node's child) with the y-up to z-up rotation as their parent transform.
fn root_nodes(doc: &Document) -> Vec<(::gltf::Node<'_>, DMat4)> {
    // (x, y, z) → (x, −z, y), as columns.
    let y_up_to_z_up = DMat4::from_cols_array(&[
        1.0, 0.0, 0.0, 0.0, //
        0.0, 0.0, 1.0, 0.0, //
        0.0, -1.0, 0.0, 0.0, //
        0.0, 0.0, 0.0, 1.0,
    ]);
    let scene = doc.default_scene().or_else(|| doc.scenes().next());
    let roots: Vec<::gltf::Node<'_>> = match scene {
        Some(scene) => scene.nodes().collect(),
        None => {
            let children: HashSet<usize> = doc
                .nodes()
                .flat_map(|n| n.children().map(|c| c.index()).collect::<Vec<_>>())
                .collect();
            doc.nodes()
                .filter(|n| !children.contains(&n.index()))
                .collect()
        }
    };
    roots.into_iter().map(|n| (n, y_up_to_z_up)).collect()
}

struct Walker<'a> {
    buffers: &'a [buffer::Data],
    /// Triangles by batch id.
    batched: HashMap<u32, Vec<[DVec3; 3]>>,
    /// Triangles by `EXT_mesh_features` property table and feature id.
    featured: HashMap<(usize, u32), Vec<[DVec3; 3]>>,
    /// Features of meshes without `_BATCHID`, one per node instance.
    instances: Vec<Feature>,
    visited: usize,
}

impl Walker<'_> {
    fn node(&mut self, node: ::gltf::Node<'_>, parent: DMat4, depth: usize) -> Result<(), String> {
        if depth > MAX_NODE_DEPTH {
            return Err(format!(
                "node graph deeper than {MAX_NODE_DEPTH} (a cycle?)"
            ));
        }
        self.visited += 1;
        if self.visited > MAX_NODE_INSTANCES {
            return Err(format!("more than {MAX_NODE_INSTANCES} node instances"));
        }
        let local = node.transform().matrix();
        let local = DMat4::from_cols_array_2d(&local.map(|c| c.map(f64::from)));
        if !local.is_finite() {
            return Err(format!("node {} has a non-finite transform", node.index()));
        }
        let world = parent * local;
        if let Some(mesh) = node.mesh() {
            let name = node
                .name()
                .or_else(|| mesh.name())
                .map_or_else(|| format!("node/{}", node.index()), str::to_string);
            let mut instance = Feature {
                batch_id: None,
                name,
                source_id: None,
                triangles: Vec::new(),
            };
            for primitive in mesh.primitives() {
                self.primitive(&primitive, world, &mut instance)
                    .map_err(|r| {
                        format!("mesh {} primitive {}: {r}", mesh.index(), primitive.index())
                    })?;
            }
            if !instance.triangles.is_empty() {
                self.instances.push(instance);
            }
        }
        for child in node.children() {
            self.node(child, world, depth + 1)?;
        }
        Ok(())
    }

    fn primitive(
        &mut self,
        primitive: &::gltf::Primitive<'_>,
        world: DMat4,
        instance: &mut Feature,
    ) -> Result<(), String> {
        let mode = primitive.mode();
        if !matches!(
            mode,
            Mode::Triangles | Mode::TriangleStrip | Mode::TriangleFan
        ) {
            return Ok(());
        }
        let Some(positions) = primitive.get(&Semantic::Positions) else {
            return Err("no POSITION attribute".into());
        };
        let coords = accessor::read_f64(&positions, self.buffers, Dimensions::Vec3)?;
        let points: Vec<DVec3> = coords
            .chunks_exact(3)
            .map(|c| world.transform_point3(DVec3::new(c[0], c[1], c[2])))
            .collect();
        let batch_ids = match primitive.get(&Semantic::Extras("BATCHID".into())) {
            Some(a) => {
                let ids = accessor::read_u32(&a, self.buffers)?;
                if ids.len() != points.len() {
                    return Err(format!(
                        "_BATCHID has {} values for {} positions",
                        ids.len(),
                        points.len()
                    ));
                }
                Some(ids)
            }
            None => None,
        };
        // Without `_BATCHID`, the 3D Tiles 1.1 feature ids, if any: (table, id per vertex).
        let feature_ids = match (
            &batch_ids,
            features::primitive_feature_ids(primitive.extension_value("EXT_mesh_features")),
        ) {
            (None, Some((attribute, table))) => {
                match primitive.get(&Semantic::Extras(format!("FEATURE_ID_{attribute}"))) {
                    Some(a) => {
                        let ids = accessor::read_f64(&a, self.buffers, Dimensions::Scalar)?;
                        if ids.len() != points.len() {
                            return Err(format!(
                                "_FEATURE_ID_{attribute} has {} values for {} positions",
                                ids.len(),
                                points.len()
                            ));
                        }
                        let ids: Vec<u32> = ids
                            .iter()
                            .map(|&v| {
                                if v.is_finite() && v >= 0.0 {
                                    v as u32
                                } else {
                                    u32::MAX
                                }
                            })
                            .collect();
                        Some((table, ids))
                    }
                    None => None,
                }
            }
            _ => None,
        };
        let indices: Vec<u32> = match primitive.indices() {
            Some(a) => accessor::read_u32(&a, self.buffers)?,
            None => (0..points.len() as u32).collect(),
        };
        if let Some(&bad) = indices.iter().find(|&&i| i as usize >= points.len()) {
            return Err(format!(
                "index {bad} out of range ({} positions)",
                points.len()
            ));
        }
        let flip = world.determinant() < 0.0;
        for [a, b, c] in triangle_corners(mode, &indices) {
            let (a, b, c) = (a as usize, b as usize, c as usize);
            let (Some(&pa), Some(&pb), Some(&pc)) = (points.get(a), points.get(b), points.get(c))
            else {
                continue;
            };
            let tri = if flip { [pa, pc, pb] } else { [pa, pb, pc] };
            if let Some(&id) = batch_ids.as_ref().and_then(|ids| ids.get(a)) {
                self.batched.entry(id).or_default().push(tri);
            } else if let Some((table, ids)) = &feature_ids {
                let id = ids.get(a).copied().unwrap_or(u32::MAX);
                self.featured.entry((*table, id)).or_default().push(tri);
            } else {
                instance.triangles.push(tri);
            }
        }
        Ok(())
    }
}

/// Triangle corner indices of a triangle list, strip or fan (glTF 2.0 §3.7.2.1).
fn triangle_corners(mode: Mode, indices: &[u32]) -> Vec<[u32; 3]> {
    match mode {
        Mode::TriangleStrip => indices
            .windows(3)
            .enumerate()
            .map(|(i, w)| {
                if i % 2 == 0 {
                    [w[0], w[1], w[2]]
                } else {
                    [w[1], w[0], w[2]]
                }
            })
            .collect(),
        Mode::TriangleFan => match indices.split_first() {
            Some((&first, rest)) => rest.windows(2).map(|w| [first, w[0], w[1]]).collect(),
            None => Vec::new(),
        },
        _ => indices
            .chunks_exact(3)
            .map(|t| [t[0], t[1], t[2]])
            .collect(),
    }
}

/// The id column of a batch table: the first of [`ID_COLUMNS`] that is an array.
fn id_column(table: &serde_json::Map<String, Value>) -> Option<&Vec<Value>> {
    ID_COLUMNS
        .iter()
        .find_map(|c| table.get(*c).and_then(Value::as_array))
}

fn value_string(v: &Value) -> Option<String> {
    match v {
        Value::String(s) => Some(s.clone()),
        Value::Null => None,
        other => Some(other.to_string()),
    }
}

/// Groups features into buildings (by batch-table id, see the module documentation), drops
/// exact duplicate triangles and places them in the local frame.
fn buildings_from_features(
    path: &Path,
    features: Vec<Feature>,
    batch: &BatchInfo,
    placement: Option<&Placement>,
    warnings: &mut Vec<LoadWarning>,
) -> Vec<MeshBuilding> {
    let stem = path
        .file_stem()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    let ids = batch.table.as_ref().and_then(id_column);
    // Building key → (source id, batch ids, triangles), in first-seen order.
    let mut order: Vec<(String, Vec<u32>, Vec<[DVec3; 3]>)> = Vec::new();
    let mut by_key: HashMap<String, usize> = HashMap::new();
    for f in features {
        let key = match (f.source_id, f.batch_id) {
            (Some(source_id), _) => source_id,
            (None, Some(b)) => ids
                .and_then(|col| col.get(b as usize))
                .and_then(value_string)
                .unwrap_or_else(|| format!("{stem}#{b}")),
            (None, None) => format!("{stem}/{}", f.name),
        };
        let slot = *by_key.entry(key.clone()).or_insert_with(|| {
            order.push((key, Vec::new(), Vec::new()));
            order.len() - 1
        });
        if let Some((_, batch_ids, triangles)) = order.get_mut(slot) {
            batch_ids.extend(f.batch_id);
            triangles.extend(f.triangles);
        }
    }
    let order = without_geometry_copies(path, order, warnings);
    let file_name = path
        .file_name()
        .map(|s| s.to_string_lossy().into_owned())
        .unwrap_or_default();
    order
        .into_iter()
        .map(|(source_id, batch_ids, triangles)| {
            let mut tags = BTreeMap::new();
            tags.insert("gltf:file".to_string(), file_name.clone());
            if !batch_ids.is_empty() {
                let list: Vec<String> = batch_ids.iter().map(u32::to_string).collect();
                tags.insert("gltf:batch_ids".to_string(), list.join(","));
            }
            if let (Some(table), Some(&first)) = (&batch.table, batch_ids.first()) {
                for (column, values) in table {
                    if let Some(v) = values.as_array().and_then(|a| a.get(first as usize)) {
                        if let Some(s) = value_string(v) {
                            tags.insert(column.clone(), s);
                        }
                    }
                }
            }
            let mesh = local_mesh(&triangles, placement);
            MeshBuilding {
                parts: vec![MeshPart {
                    source_id: source_id.clone(),
                    mesh: Ok(mesh),
                }],
                source_id,
                tags,
            }
        })
        .collect()
}

/// The buildings of `order` (source id, batch ids, triangles) without those whose triangles are
/// exactly an earlier building's: two features with the same geometry are one building written
/// twice (pg2b3dm writes every Amsterdam building as two batch features; without the batch table
/// that names both by one `blockid`, each would be a building of its own, drawn twice in one
/// place). Each copy dropped is a warning naming it and the building it repeats.
fn without_geometry_copies(
    path: &Path,
    order: Vec<(String, Vec<u32>, Vec<[DVec3; 3]>)>,
    warnings: &mut Vec<LoadWarning>,
) -> Vec<(String, Vec<u32>, Vec<[DVec3; 3]>)> {
    // A building's geometry as a set: its triangles, each by the bits of its corners turned to
    // start at the smallest, sorted, repeats removed.
    let geometry = |triangles: &[[DVec3; 3]]| -> Vec<[[u64; 3]; 3]> {
        let mut out: Vec<[[u64; 3]; 3]> = triangles
            .iter()
            .map(|t| {
                let c = t.map(|p| p.to_array().map(f64::to_bits));
                let first = (0..3).min_by_key(|&i| c[i]).unwrap_or(0);
                [c[first], c[(first + 1) % 3], c[(first + 2) % 3]]
            })
            .collect();
        out.sort_unstable();
        out.dedup();
        out
    };
    let mut first_with: HashMap<Vec<[[u64; 3]; 3]>, String> = HashMap::new();
    let mut kept = Vec::with_capacity(order.len());
    for (source_id, batch_ids, triangles) in order {
        let key = geometry(&triangles);
        if key.is_empty() {
            kept.push((source_id, batch_ids, triangles));
            continue;
        }
        match first_with.get(&key) {
            Some(original) => warnings.push(LoadWarning {
                file: path.to_path_buf(),
                source_id: source_id.clone(),
                message: format!(
                    "the same triangles as building {original}: one building, kept once"
                ),
            }),
            None => {
                first_with.insert(key, source_id.clone());
                kept.push((source_id, batch_ids, triangles));
            }
        }
    }
    kept
}

/// The triangles in the local frame as an indexed mesh (vertices shared by exact position),
/// without exact duplicate triangles.
fn local_mesh(triangles: &[[DVec3; 3]], placement: Option<&Placement>) -> TriangleMesh {
    let mut mesh = TriangleMesh::default();
    let mut vertex: HashMap<[u32; 3], u32> = HashMap::new();
    let mut seen: HashSet<[u32; 3]> = HashSet::new();
    for tri in triangles {
        let mut corners = [0u32; 3];
        for (slot, p) in corners.iter_mut().zip(tri) {
            let local = placement.map_or(*p, |pl| pl.local(*p));
            let v = Vec3::new(local.x as f32, local.y as f32, local.z as f32);
            let key = v.to_array().map(f32::to_bits);
            *slot = *vertex.entry(key).or_insert_with(|| {
                mesh.positions.push(v);
                (mesh.positions.len() - 1) as u32
            });
        }
        // Same corners in the same cyclic order = the same triangle.
        let [a, b, c] = corners;
        let canonical = if a <= b && a <= c {
            [a, b, c]
        } else if b <= c {
            [b, c, a]
        } else {
            [c, a, b]
        };
        if a == b || b == c || a == c || !seen.insert(canonical) {
            continue;
        }
        mesh.indices.extend(corners);
    }
    mesh
}
