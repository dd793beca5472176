//! One glTF 2.0 binary (GLB) of buildings and cluster meshes, with per-feature identity:
//! `EXT_mesh_features` feature ids on every vertex, and `EXT_structural_metadata` property
//! tables naming each feature (a building's source id, height, levels and whether its height
//! was estimated; a cluster's tree node, buildings and error).
//!
//! Geometry: the scene's shared vertices are split per face normal (flat shading, as citywalk
//! draws them; a client lights the normals as given), positions relative to the content's
//! centre with the centre in the node's translation (f32 positions keep millimetres), and
//! turned y-up, `(x, y, z) → (x, z, −y)`: 3D Tiles turns glTF content z-up again.
//! Buildings and clusters are two primitives, each with its own property table.

use std::collections::HashMap;

use glam::{DVec3, Vec3};
use serde_json::{Value, json};

/// What a feature of the buildings' table says about one building.
#[derive(Debug, Clone, PartialEq)]
pub struct BuildingFeature {
    pub building_id: u32,
    pub source_id: String,
    pub height_m: f32,
    /// Storeys above ground, when the source says (0: unknown, the property's no-data value).
    pub levels: u16,
    pub height_estimated: bool,
}

/// What a feature of the clusters' table says about one cluster mesh.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterFeature {
    pub node: u32,
    pub building_count: u32,
    pub geometric_error_m: f32,
}

/// One drawn mesh: triangles as index triples into `positions`.
#[derive(Debug)]
pub struct FeatureMesh<'a, F> {
    pub feature: F,
    pub positions: &'a [Vec3],
    pub triangles: &'a [[u32; 3]],
}

/// What goes into one GLB.
#[derive(Debug)]
pub struct GlbContent<'a> {
    pub buildings: Vec<FeatureMesh<'a, BuildingFeature>>,
    pub clusters: Vec<FeatureMesh<'a, ClusterFeature>>,
    /// glTF `asset.copyright` (the data's attribution), if any.
    pub copyright: Option<String>,
    pub generator: String,
}

/// The written GLB and what it holds.
#[derive(Debug, Clone)]
pub struct WrittenGlb {
    pub bytes: Vec<u8>,
    /// Bounds of the content's positions in the local frame (z up, before any y-up turn).
    pub bounds: (DVec3, DVec3),
    pub triangles: u64,
}

const FLOAT: u32 = 5126;
const UNSIGNED_INT: u32 = 5125;
const ARRAY_BUFFER: u32 = 34962;
const ELEMENT_ARRAY_BUFFER: u32 = 34963;

/// Builds the binary chunk and the JSON arrays that index it.
#[derive(Default)]
struct Builder {
    bin: Vec<u8>,
    buffer_views: Vec<Value>,
    accessors: Vec<Value>,
}

impl Builder {
    /// Appends `bytes` as a buffer view (8-byte aligned, as `EXT_structural_metadata` requires
    /// of its views); returns its index.
    fn view(&mut self, bytes: &[u8], target: Option<u32>) -> usize {
        while !self.bin.len().is_multiple_of(8) {
            self.bin.push(0);
        }
        let mut view = json!({
            "buffer": 0,
            "byteOffset": self.bin.len(),
            "byteLength": bytes.len(),
        });
        if let Some(t) = target {
            view["target"] = json!(t);
        }
        self.bin.extend_from_slice(bytes);
        self.buffer_views.push(view);
        self.buffer_views.len() - 1
    }

    fn accessor(&mut self, view: usize, component: u32, count: usize, kind: &str) -> usize {
        self.accessors.push(json!({
            "bufferView": view,
            "componentType": component,
            "count": count,
            "type": kind,
        }));
        self.accessors.len() - 1
    }
}

/// The vertices and triangles of one primitive, split by face normal.
#[derive(Default)]
struct Primitive {
    positions: Vec<[f32; 3]>,
    normals: Vec<[f32; 3]>,
    feature_ids: Vec<f32>,
    indices: Vec<u32>,
}

impl Primitive {
    /// Adds `mesh`'s triangles as feature `feature`, positions minus `centre`, turned y-up.
    /// Degenerate triangles (no normal) are left out.
    fn add<F>(&mut self, mesh: &FeatureMesh<'_, F>, feature: u32, centre: DVec3) {
        let mut welded: HashMap<(u32, [i16; 3]), u32> = HashMap::new();
        for t in mesh.triangles {
            let [Some(a), Some(b), Some(c)] = t.map(|i| mesh.positions.get(i as usize).copied())
            else {
                continue;
            };
            let p = [a, b, c];
            let n = (p[1] - p[0]).cross(p[2] - p[0]).normalize_or_zero();
            if n == Vec3::ZERO {
                continue;
            }
            let key_n = (n * 4096.0).round().as_i16vec3().to_array();
            for (corner, &i) in t.iter().enumerate() {
                let next = self.positions.len() as u32;
                let index = *welded.entry((i, key_n)).or_insert_with(|| {
                    let local = p[corner].as_dvec3() - centre;
                    self.positions
                        .push([local.x as f32, local.z as f32, -local.y as f32]);
                    self.normals.push([n.x, n.z, -n.y]);
                    self.feature_ids.push(feature as f32);
                    next
                });
                self.indices.push(index);
            }
        }
    }

    /// The primitive's JSON (attributes, indices, feature ids of property table `table`).
    fn write(&self, b: &mut Builder, features: usize, table: usize) -> Value {
        let count = self.positions.len();
        let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
        for p in &self.positions {
            for k in 0..3 {
                lo[k] = lo[k].min(p[k]);
                hi[k] = hi[k].max(p[k]);
            }
        }
        let view = b.view(bytemuck::cast_slice(&self.positions), Some(ARRAY_BUFFER));
        let position = b.accessor(view, FLOAT, count, "VEC3");
        b.accessors[position]["min"] = json!(lo);
        b.accessors[position]["max"] = json!(hi);
        let view = b.view(bytemuck::cast_slice(&self.normals), Some(ARRAY_BUFFER));
        let normal = b.accessor(view, FLOAT, count, "VEC3");
        let view = b.view(bytemuck::cast_slice(&self.feature_ids), Some(ARRAY_BUFFER));
        let feature_id = b.accessor(view, FLOAT, count, "SCALAR");
        let view = b.view(
            bytemuck::cast_slice(&self.indices),
            Some(ELEMENT_ARRAY_BUFFER),
        );
        let indices = b.accessor(view, UNSIGNED_INT, self.indices.len(), "SCALAR");
        json!({
            "attributes": {"POSITION": position, "NORMAL": normal, "_FEATURE_ID_0": feature_id},
            "indices": indices,
            "material": 0,
            "mode": 4,
            "extensions": {"EXT_mesh_features": {"featureIds": [
                {"featureCount": features, "attribute": 0, "propertyTable": table}
            ]}},
        })
    }
}

/// The metadata schema: one class per kind of feature.
fn schema() -> Value {
    json!({
        "id": "citywalk",
        "classes": {
            "building": {
                "description": "One building of the source city.",
                "properties": {
                    "building_id": {"type": "SCALAR", "componentType": "UINT32", "required": true,
                        "description": "citywalk's building id in the scene package"},
                    "source_id": {"type": "STRING", "required": true,
                        "description": "identifier in the source (OSM way/123, CityJSON object id, ...)"},
                    "height_m": {"type": "SCALAR", "componentType": "FLOAT32", "required": true,
                        "description": "top above base, metres"},
                    "levels": {"type": "SCALAR", "componentType": "UINT16", "noData": 0,
                        "description": "storeys above ground, where the source says"},
                    "height_estimated": {"type": "SCALAR", "componentType": "UINT8", "required": true,
                        "description": "1: no height in the source, a documented default was used; 0: a source height"}
                }
            },
            "cluster": {
                "description": "A simplified cluster mesh standing for several buildings (legibility cluster tree).",
                "properties": {
                    "node": {"type": "SCALAR", "componentType": "UINT32", "required": true},
                    "building_count": {"type": "SCALAR", "componentType": "UINT32", "required": true},
                    "geometric_error_m": {"type": "SCALAR", "componentType": "FLOAT32", "required": true}
                }
            }
        }
    })
}

fn buildings_table(b: &mut Builder, features: &[&BuildingFeature]) -> Value {
    let ids: Vec<u32> = features.iter().map(|f| f.building_id).collect();
    let heights: Vec<f32> = features.iter().map(|f| f.height_m).collect();
    let levels: Vec<u16> = features.iter().map(|f| f.levels).collect();
    // UINT8 0/1, not BOOLEAN: loaders.gl (4.5) refuses boolean properties.
    let estimated: Vec<u8> = features
        .iter()
        .map(|f| u8::from(f.height_estimated))
        .collect();
    let mut strings = Vec::new();
    let mut offsets = vec![0u32];
    for f in features {
        strings.extend_from_slice(f.source_id.as_bytes());
        offsets.push(strings.len() as u32);
    }
    json!({
        "class": "building",
        "count": features.len(),
        "properties": {
            "building_id": {"values": b.view(bytemuck::cast_slice(&ids), None)},
            "source_id": {
                "values": b.view(&strings, None),
                "stringOffsets": b.view(bytemuck::cast_slice(&offsets), None),
                "stringOffsetType": "UINT32"
            },
            "height_m": {"values": b.view(bytemuck::cast_slice(&heights), None)},
            "levels": {"values": b.view(bytemuck::cast_slice(&levels), None)},
            "height_estimated": {"values": b.view(&estimated, None)}
        }
    })
}

fn clusters_table(b: &mut Builder, features: &[&ClusterFeature]) -> Value {
    let nodes: Vec<u32> = features.iter().map(|f| f.node).collect();
    let counts: Vec<u32> = features.iter().map(|f| f.building_count).collect();
    let errors: Vec<f32> = features.iter().map(|f| f.geometric_error_m).collect();
    json!({
        "class": "cluster",
        "count": features.len(),
        "properties": {
            "node": {"values": b.view(bytemuck::cast_slice(&nodes), None)},
            "building_count": {"values": b.view(bytemuck::cast_slice(&counts), None)},
            "geometric_error_m": {"values": b.view(bytemuck::cast_slice(&errors), None)}
        }
    })
}

/// Writes `content` as one GLB.
pub fn write_glb(content: &GlbContent<'_>) -> WrittenGlb {
    let all = content
        .buildings
        .iter()
        .flat_map(|m| m.positions)
        .chain(content.clusters.iter().flat_map(|m| m.positions));
    let (mut lo, mut hi) = (DVec3::INFINITY, DVec3::NEG_INFINITY);
    for p in all {
        lo = lo.min(p.as_dvec3());
        hi = hi.max(p.as_dvec3());
    }
    if lo.x > hi.x {
        (lo, hi) = (DVec3::ZERO, DVec3::ZERO);
    }
    let centre = (lo + hi) * 0.5;
    let mut b = Builder::default();
    let mut primitives = Vec::new();
    let mut tables = Vec::new();
    let mut triangles = 0u64;
    if !content.buildings.is_empty() {
        let mut p = Primitive::default();
        for (i, mesh) in content.buildings.iter().enumerate() {
            p.add(mesh, i as u32, centre);
        }
        triangles += p.indices.len() as u64 / 3;
        let features: Vec<&BuildingFeature> =
            content.buildings.iter().map(|m| &m.feature).collect();
        if !p.indices.is_empty() {
            primitives.push(p.write(&mut b, features.len(), tables.len()));
            tables.push(buildings_table(&mut b, &features));
        }
    }
    if !content.clusters.is_empty() {
        let mut p = Primitive::default();
        for (i, mesh) in content.clusters.iter().enumerate() {
            p.add(mesh, i as u32, centre);
        }
        triangles += p.indices.len() as u64 / 3;
        let features: Vec<&ClusterFeature> = content.clusters.iter().map(|m| &m.feature).collect();
        if !p.indices.is_empty() {
            primitives.push(p.write(&mut b, features.len(), tables.len()));
            tables.push(clusters_table(&mut b, &features));
        }
    }
    while !b.bin.len().is_multiple_of(4) {
        b.bin.push(0);
    }
    let mut asset = json!({"version": "2.0", "generator": content.generator});
    if let Some(c) = &content.copyright {
        asset["copyright"] = json!(c);
    }
    let mut doc = json!({
        "asset": asset,
        "scene": 0,
        "scenes": [{"nodes": [0]}],
        "nodes": [{"translation": [centre.x, centre.z, -centre.y]}],
        "materials": [{
            "name": "building",
            "pbrMetallicRoughness": {
                "baseColorFactor": [0.82, 0.80, 0.76, 1.0],
                "metallicFactor": 0.0,
                "roughnessFactor": 1.0
            }
        }],
    });
    if !primitives.is_empty() {
        doc["nodes"][0]["mesh"] = json!(0);
        doc["meshes"] = json!([{"primitives": primitives}]);
        doc["accessors"] = json!(b.accessors);
        doc["bufferViews"] = json!(b.buffer_views);
        doc["buffers"] = json!([{"byteLength": b.bin.len()}]);
        doc["extensionsUsed"] = json!(["EXT_mesh_features", "EXT_structural_metadata"]);
        doc["extensions"] = json!({"EXT_structural_metadata": {
            "schema": schema(),
            "propertyTables": tables,
        }});
    }
    WrittenGlb {
        bytes: glb_container(&doc, &b.bin),
        bounds: (lo, hi),
        triangles,
    }
}

/// The GLB container: header, JSON chunk (space-padded), binary chunk (zero-padded).
fn glb_container(doc: &Value, bin: &[u8]) -> Vec<u8> {
    let mut json = serde_json::to_vec(doc).expect("JSON values serialise");
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let bin_chunk = !bin.is_empty();
    let length = 12 + 8 + json.len() + if bin_chunk { 8 + bin.len() } else { 0 };
    let mut out = Vec::with_capacity(length);
    out.extend_from_slice(b"glTF");
    out.extend_from_slice(&2u32.to_le_bytes());
    out.extend_from_slice(&(length as u32).to_le_bytes());
    out.extend_from_slice(&(json.len() as u32).to_le_bytes());
    out.extend_from_slice(b"JSON");
    out.extend_from_slice(&json);
    if bin_chunk {
        out.extend_from_slice(&(bin.len() as u32).to_le_bytes());
        out.extend_from_slice(b"BIN\0");
        out.extend_from_slice(bin);
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A unit cube's 8 corners and 12 triangles (counter-clockwise from outside).
    fn cube(at: Vec3) -> (Vec<Vec3>, Vec<[u32; 3]>) {
        let p: Vec<Vec3> = (0..8)
            .map(|i| at + Vec3::new((i & 1) as f32, ((i >> 1) & 1) as f32, (i >> 2) as f32))
            .collect();
        let t = vec![
            [0, 2, 1],
            [1, 2, 3],
            [4, 5, 6],
            [5, 7, 6],
            [0, 1, 4],
            [1, 5, 4],
            [2, 6, 3],
            [3, 6, 7],
            [0, 4, 2],
            [2, 4, 6],
            [1, 3, 5],
            [3, 7, 5],
        ];
        (p, t)
    }

    #[test]
    fn a_glb_reads_back_with_its_features_and_metadata() {
        let (p0, t0) = cube(Vec3::new(1000.0, 2000.0, 0.0));
        let (p1, t1) = cube(Vec3::new(1003.0, 2000.0, 0.0));
        let building = |id: u32, s: &str| BuildingFeature {
            building_id: id,
            source_id: s.into(),
            height_m: 1.0,
            levels: 0,
            height_estimated: id == 7,
        };
        let content = GlbContent {
            buildings: vec![
                FeatureMesh {
                    feature: building(3, "way/3"),
                    positions: &p0,
                    triangles: &t0,
                },
                FeatureMesh {
                    feature: building(7, "way/7"),
                    positions: &p1,
                    triangles: &t1,
                },
            ],
            clusters: Vec::new(),
            copyright: Some("© OpenStreetMap contributors".into()),
            generator: "test".into(),
        };
        let glb = write_glb(&content);
        assert_eq!(glb.triangles, 24);
        assert_eq!(glb.bounds.0, DVec3::new(1000.0, 2000.0, 0.0));
        // Read by the gltf crate: one primitive, flat normals (3 faces meet at each corner:
        // 24 vertices a cube), feature ids 0 and 1, positions within a few metres.
        let (doc, buffers, _) = ::gltf::import_slice(&glb.bytes).expect("a valid GLB");
        let prim = doc.meshes().next().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|b| Some(&buffers[b.index()]));
        let positions: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        assert_eq!(positions.len(), 48);
        assert!(positions.iter().all(|p| p.iter().all(|c| c.abs() <= 3.0)));
        let normals: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
        assert!(
            normals
                .iter()
                .all(|n| (Vec3::from(*n).length() - 1.0).abs() < 1e-5)
        );
        let json: Value = {
            let len = u32::from_le_bytes(glb.bytes[12..16].try_into().unwrap()) as usize;
            serde_json::from_slice(&glb.bytes[20..20 + len]).unwrap()
        };
        let table = &json["extensions"]["EXT_structural_metadata"]["propertyTables"][0];
        assert_eq!(table["count"], 2);
        let view = |i: &Value| {
            let v = &json["bufferViews"][i.as_u64().unwrap() as usize];
            let at = v["byteOffset"].as_u64().unwrap() as usize;
            assert_eq!(at % 8, 0, "metadata views are 8-byte aligned");
            &buffers[0][at..at + v["byteLength"].as_u64().unwrap() as usize]
        };
        assert_eq!(
            view(&table["properties"]["source_id"]["values"]),
            b"way/3way/7"
        );
        assert_eq!(
            view(&table["properties"]["height_estimated"]["values"]),
            [0, 1]
        );
        assert_eq!(json["asset"]["copyright"], "© OpenStreetMap contributors");
        // The node's translation puts the centre back, y-up.
        let t = &json["nodes"][0]["translation"];
        assert_eq!(t[0].as_f64().unwrap(), 1002.0);
        assert_eq!(t[2].as_f64().unwrap(), -2000.5);
    }

    #[test]
    fn degenerate_triangles_and_bad_indices_are_left_out() {
        let p = vec![Vec3::ZERO, Vec3::X, Vec3::Y, Vec3::X * 2.0];
        let t = vec![[0, 1, 2], [0, 1, 3], [0, 1, 9]];
        let content = GlbContent {
            buildings: vec![FeatureMesh {
                feature: BuildingFeature {
                    building_id: 0,
                    source_id: String::new(),
                    height_m: 0.0,
                    levels: 0,
                    height_estimated: false,
                },
                positions: &p,
                triangles: &t,
            }],
            clusters: Vec::new(),
            copyright: None,
            generator: "test".into(),
        };
        assert_eq!(write_glb(&content).triangles, 1);
    }
}
