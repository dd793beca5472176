//! Occluders as a binary glTF (GLB) for inspection in any glTF viewer.
//!
//! One mesh and one node per occluder, named `building <id> level <k>`; one binary buffer
//! holding all positions (f32 × 3) and then all indices (u32). glTF is y-up, the city frame
//! z-up: a point (x, y, z) is written as (x, z, −y), so east stays +x and north is −z.

use std::borrow::Cow;
use std::collections::BTreeMap;

use citywalk_scenes::occluder::OccluderSet;
use gltf::json;
use json::validation::Checked::Valid;
use json::validation::USize64;

/// Why a GLB could not be written.
#[derive(Debug, thiserror::Error)]
pub enum GlbError {
    #[error("glTF JSON serialisation failed: {0}")]
    Json(#[from] serde_json::Error),
    #[error("GLB larger than 4 GiB ({0} bytes)")]
    TooLarge(usize),
    #[error("GLB encoding failed: {0}")]
    Encode(String),
}

/// Encodes all occluders of `set` as one GLB file. Occluders with empty meshes are skipped.
pub fn occluders_to_glb(set: &OccluderSet) -> Result<Vec<u8>, GlbError> {
    let mut positions: Vec<u8> = Vec::new();
    let mut indices: Vec<u8> = Vec::new();
    // (name, first vertex, vertex count, first index, index count, min, max)
    let mut spans = Vec::new();
    for o in &set.occluders {
        if o.mesh.indices.is_empty() || o.mesh.positions.is_empty() {
            continue;
        }
        let first_vertex = positions.len() / 12;
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        for p in &o.mesh.positions {
            let q = [p.x, p.z, -p.y];
            for k in 0..3 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
                positions.extend_from_slice(&q[k].to_le_bytes());
            }
        }
        let first_index = indices.len() / 4;
        for i in &o.mesh.indices {
            indices.extend_from_slice(&i.to_le_bytes());
        }
        spans.push((
            format!("building {} level {}", o.building.0, o.level),
            first_vertex,
            o.mesh.positions.len(),
            first_index,
            o.mesh.indices.len(),
            lo,
            hi,
        ));
    }
    let positions_len = positions.len();
    let mut bin = positions;
    bin.extend_from_slice(&indices);
    let indices_len = bin.len() - positions_len;

    let mut root = json::Root::default();
    root.asset.generator = Some("citywalk occluders".to_owned());
    let mut nodes = Vec::new();
    if !spans.is_empty() {
        // glTF requires byteLength ≥ 1: an empty set gets no buffer at all.
        let buffer = root.push(json::Buffer {
            byte_length: USize64::from(bin.len()),
            extensions: Default::default(),
            extras: Default::default(),
            name: None,
            uri: None,
        });
        let view = |root: &mut json::Root, offset: usize, len: usize, target| {
            root.push(json::buffer::View {
                buffer,
                byte_length: USize64::from(len),
                byte_offset: Some(USize64::from(offset)),
                byte_stride: None,
                extensions: Default::default(),
                extras: Default::default(),
                name: None,
                target: Some(Valid(target)),
            })
        };
        let pos_view = view(
            &mut root,
            0,
            positions_len,
            json::buffer::Target::ArrayBuffer,
        );
        let idx_view = view(
            &mut root,
            positions_len,
            indices_len,
            json::buffer::Target::ElementArrayBuffer,
        );
        for (name, first_vertex, vertex_count, first_index, index_count, lo, hi) in spans {
            let pos = root.push(json::Accessor {
                buffer_view: Some(pos_view),
                byte_offset: Some(USize64::from(first_vertex * 12)),
                count: USize64::from(vertex_count),
                component_type: Valid(json::accessor::GenericComponentType(
                    json::accessor::ComponentType::F32,
                )),
                extensions: Default::default(),
                extras: Default::default(),
                type_: Valid(json::accessor::Type::Vec3),
                min: Some(json::Value::from(Vec::from(lo))),
                max: Some(json::Value::from(Vec::from(hi))),
                name: None,
                normalized: false,
                sparse: None,
            });
            let idx = root.push(json::Accessor {
                buffer_view: Some(idx_view),
                byte_offset: Some(USize64::from(first_index * 4)),
                count: USize64::from(index_count),
                component_type: Valid(json::accessor::GenericComponentType(
                    json::accessor::ComponentType::U32,
                )),
                extensions: Default::default(),
                extras: Default::default(),
                type_: Valid(json::accessor::Type::Scalar),
                min: None,
                max: None,
                name: None,
                normalized: false,
                sparse: None,
            });
            let primitive = json::mesh::Primitive {
                attributes: BTreeMap::from([(Valid(json::mesh::Semantic::Positions), pos)]),
                extensions: Default::default(),
                extras: Default::default(),
                indices: Some(idx),
                material: None,
                mode: Valid(json::mesh::Mode::Triangles),
                targets: None,
            };
            let mesh = root.push(json::Mesh {
                extensions: Default::default(),
                extras: Default::default(),
                name: Some(name.clone()),
                primitives: vec![primitive],
                weights: None,
            });
            nodes.push(root.push(json::Node {
                mesh: Some(mesh),
                name: Some(name),
                ..Default::default()
            }));
        }
    }
    // gltf-json cannot read back a scene without nodes: an empty set has no scene.
    if !nodes.is_empty() {
        let scene = root.push(json::Scene {
            extensions: Default::default(),
            extras: Default::default(),
            name: Some("occluders".to_owned()),
            nodes,
        });
        root.scene = Some(scene);
    }

    let mut json_bytes = json::serialize::to_vec(&root)?;
    while !json_bytes.len().is_multiple_of(4) {
        json_bytes.push(b' ');
    }
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    // Header (12) + JSON chunk header (8) + JSON + BIN chunk header (8) + BIN.
    let total = 12 + 8 + json_bytes.len() + 8 + bin.len();
    let length = u32::try_from(total).map_err(|_| GlbError::TooLarge(total))?;
    let glb = gltf::binary::Glb {
        header: gltf::binary::Header {
            magic: *b"glTF",
            version: 2,
            length,
        },
        json: Cow::Owned(json_bytes),
        bin: (!bin.is_empty()).then_some(Cow::Owned(bin)),
    };
    glb.to_vec().map_err(|e| GlbError::Encode(e.to_string()))
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::occluders::{OccluderParams, build_occluders};

    #[test]
    fn the_glb_loads_back_with_every_occluder() {
        let city = crate::occluders::tests::stepped_city();
        let set = build_occluders(&city, &OccluderParams::default());
        assert!(!set.occluders.is_empty());
        let bytes = occluders_to_glb(&set).unwrap();
        let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
        assert_eq!(gltf.meshes().count(), set.occluders.len());
        let blob = gltf.blob.as_deref().unwrap();
        for (mesh, o) in gltf.meshes().zip(&set.occluders) {
            let prim = mesh.primitives().next().unwrap();
            let reader = prim.reader(|_| Some(blob));
            let pos: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
            assert_eq!(pos.len(), o.mesh.positions.len());
            assert_eq!(
                pos[0],
                [
                    o.mesh.positions[0].x,
                    o.mesh.positions[0].z,
                    -o.mesh.positions[0].y
                ]
            );
            let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
            assert_eq!(idx, o.mesh.indices);
        }
        let empty = occluders_to_glb(&OccluderSet::default()).unwrap();
        if let Err(e) = gltf::Gltf::from_slice(&empty) {
            panic!("empty GLB does not load: {e}");
        }
    }
}
