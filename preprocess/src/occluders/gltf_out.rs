//! Triangle meshes as a binary glTF (GLB) for inspection in any glTF viewer: the virtual
//! occluders ([`occluders_to_glb`]) and any list of named meshes ([`meshes_to_glb`], used for
//! the cluster meshes of `citywalk inspect tree --gltf`).
//!
//! One mesh and one node per input mesh (occluders are named `building <id> level <k>`); one
//! binary buffer holding all positions (f32 × 3), then all normals when asked for, then all
//! indices (u32). glTF is y-up, the city frame z-up: a point (x, y, z) is written as
//! (x, z, −y), so east stays +x and north is −z (a rotation: windings and normals survive).
//!
//! With [`GlbOptions::flat_normals`] every triangle gets its own three vertices carrying its
//! geometric normal (flat shading, as the faces of a cluster hull are planar); a degenerate
//! triangle gets the up normal so that every normal stays of unit length.

use std::borrow::Cow;
use std::collections::BTreeMap;

use citywalk_scenes::TriangleMesh;
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

/// How [`meshes_to_glb`] writes its meshes.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct GlbOptions<'a> {
    /// `asset.generator` of the file.
    pub generator: &'a str,
    /// Name of the one scene.
    pub scene_name: &'a str,
    /// Vertices duplicated per triangle, each with the triangle's normal (`NORMAL`).
    pub flat_normals: bool,
}

/// Encodes all occluders of `set` as one GLB file. Occluders with empty meshes are skipped.
pub fn occluders_to_glb(set: &OccluderSet) -> Result<Vec<u8>, GlbError> {
    meshes_to_glb(
        set.occluders.iter().map(|o| {
            (
                format!("building {} level {}", o.building.0, o.level),
                &o.mesh,
            )
        }),
        GlbOptions {
            generator: "citywalk occluders",
            scene_name: "occluders",
            flat_normals: false,
        },
    )
}

/// glTF's y-up frame from the city's z-up one.
fn to_gltf(p: glam::Vec3) -> [f32; 3] {
    [p.x, p.z, -p.y]
}

/// Encodes named meshes as one GLB file, in order. Meshes without triangles are skipped.
pub fn meshes_to_glb<'m>(
    meshes: impl IntoIterator<Item = (String, &'m TriangleMesh)>,
    options: GlbOptions<'_>,
) -> Result<Vec<u8>, GlbError> {
    let mut positions: Vec<u8> = Vec::new();
    let mut normals: Vec<u8> = Vec::new();
    let mut indices: Vec<u8> = Vec::new();
    // (name, first vertex, vertex count, first index, index count, min, max)
    let mut spans = Vec::new();
    for (name, mesh) in meshes {
        if mesh.indices.is_empty() || mesh.positions.is_empty() {
            continue;
        }
        let first_vertex = positions.len() / 12;
        let first_index = indices.len() / 4;
        let (mut lo, mut hi) = ([f32::MAX; 3], [f32::MIN; 3]);
        let mut push = |q: [f32; 3], out: &mut Vec<u8>| {
            for k in 0..3 {
                lo[k] = lo[k].min(q[k]);
                hi[k] = hi[k].max(q[k]);
                out.extend_from_slice(&q[k].to_le_bytes());
            }
        };
        let vertex_count = if options.flat_normals {
            let mut count = 0u32;
            for t in mesh.indices.chunks_exact(3) {
                let Some(corners) = t
                    .iter()
                    .map(|&i| mesh.positions.get(i as usize).copied().map(to_gltf))
                    .collect::<Option<Vec<[f32; 3]>>>()
                else {
                    continue;
                };
                let [a, b, c] = [0, 1, 2].map(|k| glam::Vec3::from_array(corners[k]));
                let n = (b - a).cross(c - a).normalize_or_zero();
                let n = if n == glam::Vec3::ZERO {
                    glam::Vec3::Y
                } else {
                    n
                };
                for q in corners {
                    push(q, &mut positions);
                    for k in n.to_array() {
                        normals.extend_from_slice(&k.to_le_bytes());
                    }
                    indices.extend_from_slice(&count.to_le_bytes());
                    count += 1;
                }
            }
            count as usize
        } else {
            for p in &mesh.positions {
                push(to_gltf(*p), &mut positions);
            }
            for i in &mesh.indices {
                indices.extend_from_slice(&i.to_le_bytes());
            }
            mesh.positions.len()
        };
        if vertex_count == 0 {
            continue;
        }
        spans.push((
            name,
            first_vertex,
            vertex_count,
            first_index,
            indices.len() / 4 - first_index,
            lo,
            hi,
        ));
    }
    let (positions_len, normals_len) = (positions.len(), normals.len());
    let mut bin = positions;
    bin.extend_from_slice(&normals);
    bin.extend_from_slice(&indices);
    let indices_len = bin.len() - positions_len - normals_len;

    let mut root = json::Root::default();
    root.asset.generator = Some(options.generator.to_owned());
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
        let normal_view = (normals_len > 0).then(|| {
            view(
                &mut root,
                positions_len,
                normals_len,
                json::buffer::Target::ArrayBuffer,
            )
        });
        let idx_view = view(
            &mut root,
            positions_len + normals_len,
            indices_len,
            json::buffer::Target::ElementArrayBuffer,
        );
        for (name, first_vertex, vertex_count, first_index, index_count, lo, hi) in spans {
            let pos = root.push(accessor(
                pos_view,
                first_vertex * 12,
                vertex_count,
                json::accessor::ComponentType::F32,
                json::accessor::Type::Vec3,
                Some((Vec::from(lo), Vec::from(hi))),
            ));
            let idx = root.push(accessor(
                idx_view,
                first_index * 4,
                index_count,
                json::accessor::ComponentType::U32,
                json::accessor::Type::Scalar,
                None,
            ));
            let mut attributes = BTreeMap::from([(Valid(json::mesh::Semantic::Positions), pos)]);
            if let Some(normal_view) = normal_view {
                let normal = root.push(accessor(
                    normal_view,
                    first_vertex * 12,
                    vertex_count,
                    json::accessor::ComponentType::F32,
                    json::accessor::Type::Vec3,
                    None,
                ));
                attributes.insert(Valid(json::mesh::Semantic::Normals), normal);
            }
            let primitive = json::mesh::Primitive {
                attributes,
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
            name: Some(options.scene_name.to_owned()),
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

/// An accessor of `count` elements of `type_` from `byte_offset` in `view` (`min_max`: the
/// per-component bounds glTF requires on positions).
fn accessor(
    view: json::Index<json::buffer::View>,
    byte_offset: usize,
    count: usize,
    component: json::accessor::ComponentType,
    type_: json::accessor::Type,
    min_max: Option<(Vec<f32>, Vec<f32>)>,
) -> json::Accessor {
    let (min, max) = match min_max {
        Some((lo, hi)) => (Some(json::Value::from(lo)), Some(json::Value::from(hi))),
        None => (None, None),
    };
    json::Accessor {
        buffer_view: Some(view),
        byte_offset: Some(USize64::from(byte_offset)),
        count: USize64::from(count),
        component_type: Valid(json::accessor::GenericComponentType(component)),
        extensions: Default::default(),
        extras: Default::default(),
        type_: Valid(type_),
        min,
        max,
        name: None,
        normalized: false,
        sparse: None,
    }
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
        assert!(
            gltf.meshes()
                .flat_map(|m| m.primitives())
                .all(|p| p.get(&gltf::Semantic::Normals).is_none())
        );
        let empty = occluders_to_glb(&OccluderSet::default()).unwrap();
        if let Err(e) = gltf::Gltf::from_slice(&empty) {
            panic!("empty GLB does not load: {e}");
        }
    }

    #[test]
    fn flat_normals_duplicate_vertices_per_triangle() {
        let square = geo::Rect::new(geo::coord! {x: 0.0, y: 0.0}, geo::coord! {x: 10.0, y: 4.0})
            .to_polygon();
        let prism = citywalk_scenes::extrude::extrude_polygon(&square, 0.0, 9.0);
        let options = GlbOptions {
            generator: "test",
            scene_name: "test",
            flat_normals: true,
        };
        let bytes = meshes_to_glb(
            [
                ("prism".to_owned(), &prism),
                ("empty".to_owned(), &TriangleMesh::default()),
            ],
            options,
        )
        .unwrap();
        let gltf = gltf::Gltf::from_slice(&bytes).unwrap();
        assert_eq!(gltf.meshes().count(), 1);
        let blob = gltf.blob.as_deref().unwrap();
        let prim = gltf.meshes().next().unwrap().primitives().next().unwrap();
        let reader = prim.reader(|_| Some(blob));
        let pos: Vec<[f32; 3]> = reader.read_positions().unwrap().collect();
        let nor: Vec<[f32; 3]> = reader.read_normals().unwrap().collect();
        let idx: Vec<u32> = reader.read_indices().unwrap().into_u32().collect();
        assert_eq!(pos.len(), 3 * prism.triangle_count());
        assert_eq!(nor.len(), pos.len());
        assert_eq!(idx, (0..pos.len() as u32).collect::<Vec<_>>());
        let v = |a: [f32; 3]| glam::Vec3::from_array(a);
        let mut up = 0;
        for (t, n) in pos.chunks_exact(3).zip(nor.chunks_exact(3)) {
            assert!(n[0] == n[1] && n[1] == n[2], "one normal per triangle");
            let geometric = (v(t[1]) - v(t[0])).cross(v(t[2]) - v(t[0])).normalize();
            assert!(v(n[0]).dot(geometric) > 0.9999 && (v(n[0]).length() - 1.0).abs() < 1e-6);
            // Walls are horizontal normals, the roof faces glTF's +y.
            assert!(n[0][1].abs() < 1e-6 || n[0][1] > 0.9999);
            up += usize::from(n[0][1] > 0.9999);
        }
        assert_eq!(up, 2, "the roof is two triangles facing up");
    }
}
