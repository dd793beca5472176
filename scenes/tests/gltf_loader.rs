//! glTF / b3dm / tileset loader: the Amsterdam pg2b3dm sample, GLBs written here, bad input
//! and a mutation property test.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};

use citywalk_scenes::load::gltf as gltf_loader;
use citywalk_scenes::{City, Crs, LoadError, LoadOptions, load_cities, load_city};
use fuzz::fixed_runner;
use geo::{BoundingRect, Validation};
use proptest::prelude::*;

#[path = "support/fuzz.rs"]
mod fuzz;

const AMSTERDAM: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/gltf_amsterdam_pg2b3dm"
);

fn amsterdam_glbs() -> Vec<PathBuf> {
    (1..=10)
        .map(|i| PathBuf::from(format!("{AMSTERDAM}/glb/{i}.glb")))
        .collect()
}

/// Distinct `blockid`s and batch features over the sidecar batch tables.
fn amsterdam_blockids() -> (BTreeSet<String>, usize) {
    let mut ids = BTreeSet::new();
    let mut features = 0;
    for i in 1..=10 {
        let text = std::fs::read_to_string(format!("{AMSTERDAM}/glb/{i}.batch.json")).unwrap();
        let v: serde_json::Value = serde_json::from_str(&text).unwrap();
        let column = v["batch_table"]["blockid"].as_array().unwrap();
        features += column.len();
        ids.extend(column.iter().map(|s| s.as_str().unwrap().to_string()));
    }
    (ids, features)
}

fn check_amsterdam(city: &City) {
    let (ids, features) = amsterdam_blockids();
    assert_eq!(features, 200);
    let r = &city.report;
    assert_eq!(r.buildings_found, ids.len(), "one building per blockid");
    assert!(r.is_balanced());
    assert!(r.buildings_loaded >= ids.len() * 9 / 10, "{r}");
    city.check_invariants().unwrap();
    let loaded: BTreeSet<String> = city.buildings.iter().map(|b| b.source_id.clone()).collect();
    assert!(loaded.is_subset(&ids));
    assert_eq!(
        loaded.len(),
        city.buildings.len(),
        "blockids are unique buildings"
    );
    assert_eq!(city.frame.crs, Crs::Ecef);
    // 35,102 triangles in the files (README); every building is written twice, as two batch
    // features with identical geometry, and the copies are dropped.
    let triangles: usize = city
        .buildings
        .iter()
        .map(|b| b.mesh.as_ref().map_or(0, |m| m.triangle_count()))
        .sum();
    eprintln!("{triangles} triangles");
    assert!(
        (15_000..=17_551).contains(&triangles),
        "{triangles} triangles"
    );
    // Near lon 4.924, lat 52.388 (README).
    assert!(
        (city.frame.origin[0] - 4.92).abs() < 0.05,
        "{:?}",
        city.frame.origin
    );
    assert!(
        (city.frame.origin[1] - 52.39).abs() < 0.05,
        "{:?}",
        city.frame.origin
    );
    let (lo, hi) = city.bounds().unwrap();
    assert!(hi.x - lo.x < 5_000.0 && hi.y - lo.y < 5_000.0, "{lo} {hi}");
    assert!(lo.x.abs() < 5_000.0 && lo.y.abs() < 5_000.0, "{lo}");
    for b in &city.buildings {
        assert!(b.footprint.is_valid());
        // The smallest are garden sheds of about 1.4 m × 2.2 m.
        assert!(
            b.footprint_area_m2() > 1.0,
            "{} {}",
            b.source_id,
            b.footprint_area_m2()
        );
        // The footprint fills at most the mesh's xy bounds, and at least the projection of the
        // largest upward face.
        let mesh = b.mesh.as_ref().unwrap();
        let (mlo, mhi) = mesh.bounds().unwrap();
        let rect = f64::from((mhi.x - mlo.x) * (mhi.y - mlo.y));
        assert!(b.footprint_area_m2() <= rect * 1.0001, "{}", b.source_id);
        let largest_up = mesh
            .triangles()
            .map(|[p, q, s]| f64::from((q - p).cross(s - p).z) / 2.0)
            .fold(0.0, f64::max);
        assert!(
            b.footprint_area_m2() >= largest_up * 0.999,
            "{}",
            b.source_id
        );
        // Ellipsoidal heights in Amsterdam (ground about 40-45 m above WGS84) are moved down
        // so that the lowest base rests on the ground plane.
        assert!(
            b.base_m >= 0.0 && b.base_m < 30.0,
            "{} base {}",
            b.source_id,
            b.base_m
        );
        assert!(
            b.height_m() > 2.0 && b.height_m() < 200.0,
            "{} {}",
            b.source_id,
            b.height_m()
        );
        assert!(b.mesh.as_ref().unwrap().triangle_count() >= 4);
        assert!(b.tags.contains_key("blockid"));
    }
}

#[test]
fn all_ten_amsterdam_glbs_load_together() {
    let start = std::time::Instant::now();
    let city = load_cities(&amsterdam_glbs(), &LoadOptions::default()).unwrap();
    eprintln!(
        "Amsterdam GLBs loaded in {:?}: {}",
        start.elapsed(),
        city.report
    );
    check_amsterdam(&city);
}

#[test]
fn amsterdam_tileset_loads_every_b3dm_in_the_same_place() {
    let start = std::time::Instant::now();
    let tiles = load_city(
        Path::new(&format!("{AMSTERDAM}/tileset.json")),
        &LoadOptions::default(),
    )
    .unwrap();
    eprintln!(
        "Amsterdam tileset loaded in {:?}: {}",
        start.elapsed(),
        tiles.report
    );
    check_amsterdam(&tiles);
    // The sidecar-placed GLBs and the b3dm tiles give the same buildings in the same frame.
    let glbs = load_cities(&amsterdam_glbs(), &LoadOptions::default()).unwrap();
    assert_eq!(glbs.frame, tiles.frame);
    for b in &tiles.buildings {
        let twin = glbs
            .buildings
            .iter()
            .find(|g| g.source_id == b.source_id)
            .unwrap();
        assert!((twin.footprint_area_m2() - b.footprint_area_m2()).abs() < 1e-6);
        assert!((twin.top_m - b.top_m).abs() < 1e-3);
    }
}

// ---------------------------------------------------------------------------------------------
// GLBs written here.

/// Outward quads (counter-clockwise from outside) of a z-up box.
fn box_quads(lo: [f32; 3], hi: [f32; 3]) -> Vec<[[f32; 3]; 4]> {
    let ([x0, y0, z0], [x1, y1, z1]) = (lo, hi);
    vec![
        [[x0, y0, z0], [x0, y1, z0], [x1, y1, z0], [x1, y0, z0]],
        [[x0, y0, z1], [x1, y0, z1], [x1, y1, z1], [x0, y1, z1]],
        [[x0, y0, z0], [x1, y0, z0], [x1, y0, z1], [x0, y0, z1]],
        [[x1, y0, z0], [x1, y1, z0], [x1, y1, z1], [x1, y0, z1]],
        [[x1, y1, z0], [x0, y1, z0], [x0, y1, z1], [x1, y1, z1]],
        [[x0, y1, z0], [x0, y0, z0], [x0, y0, z1], [x0, y1, z1]],
    ]
}

/// A GLB with one mesh (positions in glTF y-up, u16 indices, optional float `_BATCHID`), one
/// node with `node_json` (e.g. a translation) and one scene.
fn make_glb(boxes: &[([f32; 3], [f32; 3], u32)], batched: bool, node_json: &str) -> Vec<u8> {
    let mut positions: Vec<f32> = Vec::new();
    let mut ids: Vec<f32> = Vec::new();
    let mut indices: Vec<u16> = Vec::new();
    for &(lo, hi, id) in boxes {
        for quad in box_quads(lo, hi) {
            let base = (positions.len() / 3) as u16;
            for [x, y, z] in quad {
                // z-up (x, y, z) is glTF y-up (x, z, −y).
                positions.extend([x, z, -y]);
                ids.push(id as f32);
            }
            indices.extend([base, base + 1, base + 2, base, base + 2, base + 3]);
        }
    }
    let mut bin: Vec<u8> = Vec::new();
    bin.extend(positions.iter().flat_map(|v| v.to_le_bytes()));
    let ids_offset = bin.len();
    bin.extend(ids.iter().flat_map(|v| v.to_le_bytes()));
    let index_offset = bin.len();
    bin.extend(indices.iter().flat_map(|v| v.to_le_bytes()));
    while !bin.len().is_multiple_of(4) {
        bin.push(0);
    }
    let n = positions.len() / 3;
    let batch_attr = if batched { r#","_BATCHID":1"# } else { "" };
    let json = format!(
        r#"{{"asset":{{"version":"2.0"}},"scene":0,"scenes":[{{"nodes":[0]}}],
        "nodes":[{{"mesh":0,"name":"house"{node_json}}}],
        "meshes":[{{"primitives":[{{"attributes":{{"POSITION":0{batch_attr}}},"indices":2}}]}}],
        "buffers":[{{"byteLength":{}}}],
        "bufferViews":[{{"buffer":0,"byteOffset":0,"byteLength":{ids_offset}}},
                       {{"buffer":0,"byteOffset":{ids_offset},"byteLength":{}}},
                       {{"buffer":0,"byteOffset":{index_offset},"byteLength":{}}}],
        "accessors":[{{"bufferView":0,"componentType":5126,"count":{n},"type":"VEC3"}},
                     {{"bufferView":1,"componentType":5126,"count":{n},"type":"SCALAR"}},
                     {{"bufferView":2,"componentType":5123,"count":{},"type":"SCALAR"}}]}}"#,
        bin.len(),
        index_offset - ids_offset,
        indices.len() * 2,
        indices.len()
    );
    glb_container(&json, &bin)
}

fn glb_container(json: &str, bin: &[u8]) -> Vec<u8> {
    let mut json = json.as_bytes().to_vec();
    while !json.len().is_multiple_of(4) {
        json.push(b' ');
    }
    let total = 12 + 8 + json.len() + 8 + bin.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"glTF");
    out.extend(2u32.to_le_bytes());
    out.extend((total as u32).to_le_bytes());
    out.extend((json.len() as u32).to_le_bytes());
    out.extend(0x4E4F_534Au32.to_le_bytes());
    out.extend(&json);
    out.extend((bin.len() as u32).to_le_bytes());
    out.extend(0x004E_4942u32.to_le_bytes());
    out.extend(bin);
    out
}

fn make_b3dm(batch_table: &str, glb: &[u8]) -> Vec<u8> {
    make_b3dm_with(r#"{"BATCH_LENGTH":3}"#, batch_table, glb)
}

/// A b3dm of `feature_table` and `batch_table` (JSON) around `glb`.
fn make_b3dm_with(feature_table: &str, batch_table: &str, glb: &[u8]) -> Vec<u8> {
    let mut ft = feature_table.as_bytes().to_vec();
    while !(28 + ft.len()).is_multiple_of(8) {
        ft.push(b' ');
    }
    let mut bt = batch_table.as_bytes().to_vec();
    while !(28 + ft.len() + bt.len()).is_multiple_of(8) {
        bt.push(b' ');
    }
    let total = 28 + ft.len() + bt.len() + glb.len();
    let mut out = Vec::new();
    out.extend_from_slice(b"b3dm");
    for w in [1, total, ft.len(), 0, bt.len(), 0] {
        out.extend((w as u32).to_le_bytes());
    }
    out.extend(ft);
    out.extend(bt);
    out.extend(glb);
    out
}

#[test]
fn y_up_to_z_up_and_node_transform() {
    // A 2 × 4 × 10 m box (z-up) in a node translated by glTF (100, 3, 0): z-up (100, 0, 3).
    let glb = make_glb(
        &[([0.0, 0.0, 0.0], [2.0, 4.0, 10.0], 0)],
        false,
        r#","translation":[100,3,0]"#,
    );
    let city = gltf_loader::load_bytes(Path::new("box.glb"), &glb).unwrap();
    assert_eq!(city.frame.crs, Crs::Local);
    assert_eq!(city.buildings.len(), 1);
    let b = &city.buildings[0];
    assert_eq!(b.source_id, "box/house");
    assert!(
        (b.footprint_area_m2() - 8.0).abs() < 1e-4,
        "{}",
        b.footprint_area_m2()
    );
    let r = b.footprint.bounding_rect().unwrap();
    assert!(
        (r.min().x - 100.0).abs() < 1e-4 && (r.max().x - 102.0).abs() < 1e-4,
        "{r:?}"
    );
    assert!(
        (r.min().y - 0.0).abs() < 1e-4 && (r.max().y - 4.0).abs() < 1e-4,
        "{r:?}"
    );
    // The box stood 3 m up in the glTF: it rests on the ground, the frame's origin keeps 3 m.
    assert!(b.base_m.abs() < 1e-5 && (b.top_m - 10.0).abs() < 1e-5);
    assert!((city.frame.origin[2] - 3.0).abs() < 1e-5);
    assert_eq!(b.mesh.as_ref().unwrap().triangle_count(), 12);
    // Winding survives: every triangle faces away from the box centre.
    let centre = glam::Vec3::new(101.0, 2.0, 5.0);
    for [p, q, s] in b.mesh.as_ref().unwrap().triangles() {
        assert!((q - p).cross(s - p).dot((p + q + s) / 3.0 - centre) > 0.0);
    }
}

#[test]
fn mirrored_node_keeps_outward_winding() {
    let glb = make_glb(
        &[([0.0, 0.0, 0.0], [2.0, 4.0, 10.0], 0)],
        false,
        r#","scale":[-1,1,1]"#,
    );
    let city = gltf_loader::load_bytes(Path::new("m.glb"), &glb).unwrap();
    let b = &city.buildings[0];
    assert!((b.footprint_area_m2() - 8.0).abs() < 1e-4);
    let centre = glam::Vec3::new(-1.0, 2.0, 5.0);
    for [p, q, s] in b.mesh.as_ref().unwrap().triangles() {
        assert!((q - p).cross(s - p).dot((p + q + s) / 3.0 - centre) > 0.0);
    }
}

#[test]
fn b3dm_batches_with_the_same_id_merge() {
    // Three boxes, batch ids 0, 1, 2; ids 0 and 2 share blockid "A", and box 2 repeats box 0.
    let glb = make_glb(
        &[
            ([0.0, 0.0, 0.0], [10.0, 10.0, 6.0], 0),
            ([20.0, 0.0, 0.0], [25.0, 5.0, 9.0], 1),
            ([0.0, 0.0, 0.0], [10.0, 10.0, 6.0], 2),
        ],
        true,
        "",
    );
    let tile = make_b3dm(r#"{"blockid":["A","B","A"],"height":[6,9,6]}"#, &glb);
    let city = gltf_loader::load_bytes(Path::new("t.b3dm"), &tile).unwrap();
    assert_eq!(city.report.buildings_found, 2);
    let a = city.buildings.iter().find(|b| b.source_id == "A").unwrap();
    let b = city.buildings.iter().find(|b| b.source_id == "B").unwrap();
    assert!((a.footprint_area_m2() - 100.0).abs() < 1e-4);
    assert!((b.footprint_area_m2() - 25.0).abs() < 1e-4);
    assert_eq!(a.tags.get("gltf:batch_ids"), Some("0,2"));
    assert_eq!(a.tags.get("height"), Some("6"));
    // The repeated box's triangles are dropped.
    assert_eq!(a.mesh.as_ref().unwrap().triangle_count(), 12);
    assert!((b.height_m() - 9.0).abs() < 1e-5);
}

fn expect_error(name: &str, bytes: &[u8], needle: &str) {
    match gltf_loader::load_bytes(Path::new(name), bytes) {
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains(name), "{msg}");
            assert!(msg.to_lowercase().contains(needle), "{msg} lacks {needle}");
        }
        Ok(city) => panic!("loaded: {}", city.report),
    }
}

#[test]
fn bad_files_are_errors_naming_file_and_problem() {
    let good = make_glb(&[([0.0, 0.0, 0.0], [2.0, 4.0, 10.0], 0)], false, "");
    // Broken GLB header (version 7).
    let mut header = good.clone();
    header[4] = 7;
    expect_error("header.glb", &header, "version");
    // Truncated buffer: the BIN chunk is cut short (shorter than the GLB header says).
    expect_error("cut.glb", &good[..good.len() - 40], "length");
    // Not glTF at all.
    expect_error("junk.glb", b"hello world", "json");
    // An index out of range.
    let json = r#"{"asset":{"version":"2.0"},"scenes":[{"nodes":[0]}],"nodes":[{"mesh":0}],
        "meshes":[{"primitives":[{"attributes":{"POSITION":0},"indices":1}]}],
        "buffers":[{"byteLength":40}],
        "bufferViews":[{"buffer":0,"byteLength":36},{"buffer":0,"byteOffset":36,"byteLength":4}],
        "accessors":[{"bufferView":0,"componentType":5126,"count":3,"type":"VEC3"},
                     {"bufferView":1,"componentType":5123,"count":2,"type":"SCALAR"}]}"#;
    let mut bin: Vec<u8> = [0f32, 0., 0., 1., 0., 0., 0., 0., 1.]
        .iter()
        .flat_map(|v| v.to_le_bytes())
        .collect();
    bin.extend([0u16, 9].iter().flat_map(|v| v.to_le_bytes()));
    expect_error("index.glb", &glb_container(json, &bin), "out of range");
    // A well-formed container whose BIN chunk is shorter than the buffer it declares.
    let short = json.replace(r#""byteLength":40}"#, r#""byteLength":400}"#);
    expect_error("short.glb", &glb_container(&short, &bin), "buffer");
    // An accessor running past its buffer view.
    let lying = json.replace(r#""count":3,"#, r#""count":30,"#);
    expect_error("view.glb", &glb_container(&lying, &bin), "past");
    // A b3dm whose lengths lie.
    let mut tile = make_b3dm(r#"{"blockid":["A"]}"#, &good);
    tile[12] = 0xff;
    expect_error("bad.b3dm", &tile, "b3dm");
}

/// Issue 14: a GLB whose header `length` is not the file's length was accepted.
#[test]
fn issue14_small_glb_length_must_match_the_file() {
    let good = make_glb(&[([0.0, 0.0, 0.0], [2.0, 4.0, 10.0], 0)], false, "");
    let set_length = |bytes: &mut Vec<u8>, length: usize| {
        bytes[8..12].copy_from_slice(&(length as u32).to_le_bytes());
    };
    // Header smaller than the file: the tail after it would be ignored.
    let mut short_header = good.clone();
    set_length(&mut short_header, good.len() - 8);
    expect_error("short_header.glb", &short_header, "length");
    // Extra bytes after a correct header (a concatenated or damaged file).
    let mut trailing = good.clone();
    trailing.extend([0u8; 16]);
    expect_error("trailing.glb", &trailing, "length");
    // Header larger than the file.
    let mut long_header = good.clone();
    set_length(&mut long_header, good.len() + 4);
    expect_error("long_header.glb", &long_header, "length");
    // A length below the header itself.
    let mut tiny = good.clone();
    set_length(&mut tiny, 4);
    expect_error("tiny.glb", &tiny, "length");
    // Inside a b3dm: 8-byte alignment padding after the GLB is allowed, more is not.
    let mut padded = good.clone();
    padded.extend([0u8; 4]);
    let tile = make_b3dm(r#"{"blockid":["A"]}"#, &padded);
    assert!(gltf_loader::load_bytes(Path::new("padded.b3dm"), &tile).is_ok());
    let tile = make_b3dm(r#"{"blockid":["A"]}"#, &short_header);
    expect_error("short_header.b3dm", &tile, "length");
    // The file name reaches the error through `load_city` as well.
    let dir = tempfile::tempdir().unwrap();
    let file = dir.path().join("on_disk.glb");
    std::fs::write(&file, &trailing).unwrap();
    let msg = load_city(&file, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        msg.contains("on_disk.glb") && msg.contains("length"),
        "{msg}"
    );
}

/// Issue 14: `asset.version "3.0"` was accepted; a reader must refuse a major version it does
/// not know.
#[test]
fn issue14_small_gltf_asset_version_other_than_2_is_refused() {
    let good = make_glb(&[([0.0, 0.0, 0.0], [2.0, 4.0, 10.0], 0)], false, "");
    let with_version = |version: &[u8; 3]| {
        let needle = br#""version":"2.0""#;
        let at = good
            .windows(needle.len())
            .position(|w| w == needle)
            .unwrap();
        let mut bytes = good.clone();
        bytes[at + 11..at + 14].copy_from_slice(version);
        bytes
    };
    assert!(gltf_loader::load_bytes(Path::new("v21.glb"), &with_version(b"2.1")).is_ok());
    for version in [b"3.0", b"1.0", b"9.9"] {
        let name = format!("v{}.glb", String::from_utf8_lossy(version));
        let bytes = with_version(version);
        let msg = gltf_loader::load_bytes(Path::new(&name), &bytes)
            .unwrap_err()
            .to_string();
        assert!(msg.contains(&name), "{msg}");
        assert!(
            msg.contains(&format!("{:?}", String::from_utf8_lossy(version))),
            "{msg}"
        );
    }
    // A .gltf (JSON) file says the same.
    let json = r#"{"asset":{"version":"3.0"},"scenes":[{"nodes":[]}]}"#;
    expect_error("three.gltf", json.as_bytes(), "3.0");
}

/// Found by the `glb` and `b3dm` fuzz targets (tests/fuzz/regressions/{glb,b3dm}/): a GLB
/// header whose `length` is under the header's own 12 bytes made `gltf` subtract past zero.
#[test]
fn fuzz_glb_length_under_its_header_is_an_error() {
    let mut glb = b"glTF".to_vec();
    glb.extend(2u32.to_le_bytes());
    glb.extend(4u32.to_le_bytes());
    expect_error("short-header.glb", &glb, "less than the header");
    expect_error(
        "short-header.b3dm",
        &make_b3dm("", &glb),
        "less than the header",
    );
    // A header cut short.
    expect_error("cut-header.glb", &glb[..10], "needs 12 bytes");
}

#[test]
fn degenerate_building_is_rejected_and_others_load() {
    // A flat box (zero height) and a good one, as two batches.
    let glb = make_glb(
        &[
            ([0.0, 0.0, 0.0], [10.0, 10.0, 0.0], 0),
            ([20.0, 0.0, 0.0], [25.0, 5.0, 9.0], 1),
        ],
        true,
        "",
    );
    let city = gltf_loader::load_bytes(Path::new("d.glb"), &glb).unwrap();
    assert_eq!(city.report.buildings_found, 2);
    assert_eq!(city.buildings.len(), 1);
    assert_eq!(city.report.rejected[0].source_id, "d#0");
    assert!(city.report.is_balanced());
}

#[test]
fn mutated_glbs_never_panic() {
    let base = make_glb(
        &[
            ([0.0, 0.0, 0.0], [10.0, 10.0, 6.0], 0),
            ([20.0, 0.0, 0.0], [25.0, 5.0, 9.0], 1),
        ],
        true,
        r#","translation":[1,2,3]"#,
    );
    let tile = make_b3dm(r#"{"blockid":["A","B"]}"#, &base);
    let mut runner = fixed_runner(300, 11);
    let strategy = (
        any::<bool>(),
        0..tile.len(),
        prop::collection::vec((0..tile.len(), any::<u8>()), 0..6),
        prop::collection::vec((0..tile.len(), any::<f32>()), 0..3),
    );
    runner
        .run(&strategy, |(as_tile, cut, flips, floats)| {
            let mut bytes = if as_tile { tile.clone() } else { base.clone() };
            for (at, value) in floats {
                // Overwrite four bytes with a float (a coordinate, a count, a length ...).
                let at = at % bytes.len().saturating_sub(4).max(1);
                if let Some(slot) = bytes.get_mut(at..at + 4) {
                    slot.copy_from_slice(&value.to_le_bytes());
                }
            }
            for (at, value) in flips {
                let at = at % bytes.len();
                bytes[at] = value;
            }
            if cut % 4 == 0 {
                bytes.truncate(cut % bytes.len());
            }
            let name = if as_tile { "m.b3dm" } else { "m.glb" };
            match gltf_loader::load_bytes(Path::new(name), &bytes) {
                Ok(city) => {
                    prop_assert!(city.report.is_balanced());
                    prop_assert!(city.check_invariants().is_ok());
                }
                Err(LoadError::Io { .. }) => prop_assert!(false, "no file is read"),
                Err(_) => {}
            }
            Ok(())
        })
        .unwrap();
}

#[test]
fn gltf_with_external_buffer_and_no_tileset_stays_local() {
    // Split a GLB written here into a .gltf and a .bin in a fresh folder.
    let glb = make_glb(
        &[([0.0, 0.0, 0.0], [3.0, 3.0, 7.0], 0)],
        false,
        r#","translation":[0,0,-50]"#,
    );
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
    let bin = &glb[20 + json_len + 8..];
    let json = json.replace(
        r#""buffers":[{"byteLength""#,
        r#""buffers":[{"uri":"box.bin","byteLength""#,
    );
    let dir = std::env::temp_dir().join(format!("citywalk-gltf-test-{}", std::process::id()));
    std::fs::create_dir_all(&dir).unwrap();
    std::fs::write(dir.join("box.gltf"), json).unwrap();
    std::fs::write(dir.join("box.bin"), bin).unwrap();
    let city = load_city(&dir.join("box.gltf"), &LoadOptions::default()).unwrap();
    std::fs::remove_dir_all(&dir).unwrap();
    assert_eq!(city.frame.crs, Crs::Local);
    let b = &city.buildings[0];
    assert!((b.footprint_area_m2() - 9.0).abs() < 1e-4);
    // glTF z −50 is 50 m north in z-up.
    let r = b.footprint.bounding_rect().unwrap();
    assert!((r.min().y - 50.0).abs() < 1e-4, "{r:?}");
    assert!((b.top_m - 7.0).abs() < 1e-5);
}

#[test]
fn local_tileset_applies_tile_transforms() {
    // A tileset with no georeference: one b3dm tile translated by (10, 20, 0) (z-up tile
    // coordinates), holding two batches of one building.
    let glb = make_glb(
        &[
            ([0.0, 0.0, 0.0], [4.0, 4.0, 3.0], 0),
            ([4.0, 0.0, 0.0], [6.0, 4.0, 5.0], 1),
        ],
        true,
        "",
    );
    let tile = make_b3dm(r#"{"id":["house","house"]}"#, &glb);
    let tileset = r#"{"asset":{"version":"1.0"},"geometricError":10,"root":{
        "boundingVolume":{"box":[0,0,0, 100,0,0, 0,100,0, 0,0,100]},"geometricError":10,
        "children":[{"boundingVolume":{"box":[0,0,0, 100,0,0, 0,100,0, 0,0,100]},
          "geometricError":0,"content":{"uri":"t/a.b3dm"},
          "transform":[1,0,0,0, 0,1,0,0, 0,0,1,0, 10,20,0,1]}]}}"#;
    let dir = std::env::temp_dir().join(format!("citywalk-tileset-test-{}", std::process::id()));
    std::fs::create_dir_all(dir.join("t")).unwrap();
    std::fs::write(dir.join("tileset.json"), tileset).unwrap();
    std::fs::write(dir.join("t/a.b3dm"), &tile).unwrap();
    let from_tileset = load_city(&dir.join("tileset.json"), &LoadOptions::default());
    // The tile on its own finds the tileset one folder up and lands in the same place.
    let from_tile = load_city(&dir.join("t/a.b3dm"), &LoadOptions::default());
    std::fs::remove_dir_all(&dir).unwrap();
    for city in [from_tileset.unwrap(), from_tile.unwrap()] {
        assert_eq!(city.frame, citywalk_scenes::Frame::local());
        assert_eq!(city.buildings.len(), 1);
        let b = &city.buildings[0];
        assert_eq!(b.source_id, "house");
        assert!((b.footprint_area_m2() - 24.0).abs() < 1e-4);
        let r = b.footprint.bounding_rect().unwrap();
        assert!(
            (r.min().x - 10.0).abs() < 1e-4 && (r.min().y - 20.0).abs() < 1e-4,
            "{r:?}"
        );
        assert!((b.top_m - 5.0).abs() < 1e-5 && b.base_m.abs() < 1e-5);
    }
}

/// Replaces numbers in the glTF JSON (counts, offsets, strides, indices, transforms) and
/// rebuilds a consistent container, so the mutations reach the accessor and scene code.
#[test]
fn glb_json_number_mutations_never_panic() {
    let glb = make_glb(
        &[
            ([0.0, 0.0, 0.0], [10.0, 10.0, 6.0], 0),
            ([20.0, 0.0, 0.0], [25.0, 5.0, 9.0], 1),
        ],
        true,
        r#","translation":[1,2,3]"#,
    );
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = std::str::from_utf8(&glb[20..20 + json_len])
        .unwrap()
        .to_string();
    let bin = glb[20 + json_len + 8..].to_vec();
    // Start of every run of digits in the JSON.
    let runs: Vec<usize> = (0..json.len())
        .filter(|&i| {
            json.as_bytes()[i].is_ascii_digit()
                && (i == 0 || !json.as_bytes()[i - 1].is_ascii_digit())
        })
        .collect();
    let mut runner = fixed_runner(300, 5);
    let value = prop_oneof![
        0u64..8,
        0u64..2000,
        Just(u64::from(u32::MAX)),
        Just(u64::MAX / 3),
    ];
    let strategy = prop::collection::vec((0..runs.len(), value), 1..4);
    let loaded = std::cell::Cell::new(0);
    runner
        .run(&strategy, |edits| {
            let mut text = json.clone();
            // Edit from the back so earlier run positions stay valid.
            let mut edits = edits;
            edits.sort_by_key(|(k, _)| std::cmp::Reverse(*k));
            edits.dedup_by_key(|(k, _)| *k);
            for (k, v) in edits {
                let start = runs[k];
                let end = (start..text.len())
                    .find(|&i| !text.as_bytes()[i].is_ascii_digit())
                    .unwrap_or(text.len());
                text.replace_range(start..end, &v.to_string());
            }
            let bytes = glb_container(&text, &bin);
            match gltf_loader::load_bytes(Path::new("n.glb"), &bytes) {
                Ok(city) => {
                    loaded.set(loaded.get() + 1);
                    prop_assert!(city.report.is_balanced());
                    prop_assert!(city.check_invariants().is_ok());
                }
                Err(e) => prop_assert!(e.to_string().contains("n.glb"), "{e}"),
            }
            Ok(())
        })
        .unwrap();
    eprintln!("{} mutated GLBs loaded", loaded.get());
}

/// A `.gltf` (one 3 × 3 × 7 m box) whose buffer is the file `uri` with `byteLength` as
/// written, and the binary data it needs.
fn split_gltf(uri: &str) -> (String, Vec<u8>) {
    let glb = make_glb(&[([0.0, 0.0, 0.0], [3.0, 3.0, 7.0], 0)], false, "");
    let json_len = u32::from_le_bytes(glb[12..16].try_into().unwrap()) as usize;
    let json = std::str::from_utf8(&glb[20..20 + json_len]).unwrap();
    let bin = glb[20 + json_len + 8..].to_vec();
    let json = json.replace(
        r#""buffers":[{"byteLength""#,
        &format!(
            r#""buffers":[{{"uri":{},"byteLength""#,
            serde_json::json!(uri)
        ),
    );
    (json, bin)
}

/// Issue 14 case 2: a buffer `uri` of `/dev/zero` (byteLength 4,140) grew to 24 GB, and one of
/// `/etc/passwd` was read. Only regular files inside the glTF's folder are read, never past
/// `byteLength`; everything else is an error naming the file, the buffer and the reason, at
/// once.
#[test]
fn gltf_buffer_uris_outside_the_folder_or_not_regular_files_are_refused() {
    let root = tempfile::tempdir().unwrap();
    let dir = root.path().join("model");
    std::fs::create_dir_all(dir.join("sub")).unwrap();
    let (_, bin) = split_gltf("x");
    std::fs::write(root.path().join("outside.bin"), &bin).unwrap();
    #[cfg(unix)]
    {
        std::os::unix::fs::symlink("/dev/zero", dir.join("zero.bin")).unwrap();
        std::os::unix::fs::symlink(root.path().join("outside.bin"), dir.join("out.bin")).unwrap();
    }
    let cases = [
        ("/dev/zero", "absolute"),
        ("/etc/passwd", "absolute"),
        ("file:///etc/passwd", "only relative"),
        ("../outside.bin", "leaves the folder"),
        ("sub/../../outside.bin", "leaves the folder"),
        ("sub", "not a regular file"),
        ("missing.bin", "missing.bin"),
        #[cfg(unix)]
        ("zero.bin", "outside the folder"),
        #[cfg(unix)]
        ("out.bin", "outside the folder"),
    ];
    for (k, (uri, needle)) in cases.iter().enumerate() {
        let (json, _) = split_gltf(uri);
        let file = dir.join(format!("case{k}.gltf"));
        std::fs::write(&file, json).unwrap();
        let start = std::time::Instant::now();
        let err = load_city(&file, &LoadOptions::default()).expect_err(uri);
        assert!(
            start.elapsed().as_secs() < 5,
            "{uri}: took {:?}",
            start.elapsed()
        );
        let text = err.to_string();
        assert!(text.contains(&format!("case{k}.gltf")), "{uri}: {text}");
        assert!(
            text.contains("buffer 0") && text.contains(needle),
            "{uri}: {text}"
        );
    }

    // A file shorter than byteLength is refused; a longer one is read up to byteLength only.
    std::fs::write(dir.join("short.bin"), &bin[..bin.len() - 4]).unwrap();
    let (json, _) = split_gltf("short.bin");
    std::fs::write(dir.join("short.gltf"), json).unwrap();
    let err = load_city(&dir.join("short.gltf"), &LoadOptions::default()).unwrap_err();
    assert!(err.to_string().contains("declared"), "{err}");
    let mut long = bin.clone();
    long.extend_from_slice(&[0xAB; 1000]);
    std::fs::write(dir.join("sub/long%.bin"), &long).unwrap();
    let (json, _) = split_gltf("sub/long%25.bin");
    std::fs::write(dir.join("long.gltf"), json).unwrap();
    let city = load_city(&dir.join("long.gltf"), &LoadOptions::default()).unwrap();
    assert_eq!(city.buildings.len(), 1);
    assert!((city.buildings[0].top_m - 7.0).abs() < 1e-5);
}

/// Issue 14 case 10 (the datum part): heights were judged in the file's absolute metres
/// before the origin was raised, so a lone glTF standing 1,100 m up (a city high above its
/// datum) lost every building as "absurd height". Heights are judged above the file's ground.
#[test]
fn heights_are_judged_above_the_files_ground() {
    let glb = make_glb(
        &[([0.0, 0.0, 0.0], [3.0, 3.0, 7.0], 0)],
        false,
        r#","translation":[0,1100,0]"#,
    );
    let path = Path::new("high.glb");
    let city = gltf_loader::load_bytes(path, &glb).unwrap();
    assert_eq!(city.buildings.len(), 1, "{}", city.report);
    let b = &city.buildings[0];
    assert_eq!((b.base_m, b.top_m), (0.0, 7.0));
    assert!(
        (city.frame.origin[2] - 1100.0).abs() < 1e-3,
        "{:?}",
        city.frame.origin
    );
}

/// Issue 14: a UTF-8 byte order mark before the JSON of a .gltf, a tileset or a batch-table
/// sidecar gave "expected value at line 1 column 1".
#[test]
fn issue14_small_gltf_tileset_and_sidecar_json_with_bom_load() {
    const BOM: &[u8] = b"\xEF\xBB\xBF";
    let with_bom = |text: &[u8]| [BOM, text].concat();
    let root = tempfile::tempdir().unwrap();
    // A .gltf with an external buffer.
    let (json, bin) = split_gltf("box.bin");
    std::fs::write(root.path().join("box.gltf"), with_bom(json.as_bytes())).unwrap();
    std::fs::write(root.path().join("box.bin"), &bin).unwrap();
    let city = load_city(&root.path().join("box.gltf"), &LoadOptions::default()).unwrap();
    assert_eq!(city.buildings.len(), 1);
    // A GLB with a sidecar batch table naming its batch.
    let glb = make_glb(&[([0.0, 0.0, 0.0], [4.0, 4.0, 3.0], 0)], true, "");
    std::fs::write(root.path().join("b.glb"), &glb).unwrap();
    std::fs::write(
        root.path().join("b.batch.json"),
        with_bom(br#"{"batch_table":{"id":["named"]}}"#),
    )
    .unwrap();
    let city = load_city(&root.path().join("b.glb"), &LoadOptions::default()).unwrap();
    assert_eq!(city.buildings[0].source_id, "named");
    // A tileset of one b3dm, read as the input and found beside its tile.
    let dir = root.path().join("set");
    std::fs::create_dir_all(dir.join("t")).unwrap();
    let tileset = r#"{"asset":{"version":"1.0"},"geometricError":10,"root":{
        "boundingVolume":{"box":[0,0,0, 100,0,0, 0,100,0, 0,0,100]},"geometricError":10,
        "children":[{"boundingVolume":{"box":[0,0,0, 100,0,0, 0,100,0, 0,0,100]},
          "geometricError":0,"content":{"uri":"t/a.b3dm"},
          "transform":[1,0,0,0, 0,1,0,0, 0,0,1,0, 10,20,0,1]}]}}"#;
    std::fs::write(dir.join("tileset.json"), with_bom(tileset.as_bytes())).unwrap();
    std::fs::write(dir.join("t/a.b3dm"), make_b3dm(r#"{"id":["house"]}"#, &glb)).unwrap();
    for input in [dir.join("tileset.json"), dir.join("t/a.b3dm")] {
        let city = load_city(&input, &LoadOptions::default()).unwrap();
        assert_eq!(city.buildings.len(), 1, "{}", input.display());
        // Placed by the tileset's transform: the tile was found and read.
        let r = city.buildings[0].footprint.bounding_rect().unwrap();
        assert!(
            (r.min().x - 10.0).abs() < 1e-3,
            "{}: {r:?}",
            input.display()
        );
        assert!(
            city.report.warnings.is_empty(),
            "{:?}",
            city.report.warnings
        );
    }
}

/// Issue 14 case 5: `glb/2.glb` copied without its batch-table sidecar loaded every building
/// twice, once per batch feature (pg2b3dm writes each as two features with the same triangles,
/// which the sidecar's `blockid` names as one). Features with exactly the same triangles are
/// one building, kept once, and each copy dropped is a warning naming both.
#[test]
fn issue14_case5_features_with_the_same_triangles_are_one_building() {
    let sidecar = std::fs::read_to_string(format!("{AMSTERDAM}/glb/2.batch.json")).unwrap();
    let sidecar: serde_json::Value = serde_json::from_str(&sidecar).unwrap();
    let blockids = sidecar["batch_table"]["blockid"].as_array().unwrap();
    let unique: BTreeSet<&str> = blockids.iter().map(|v| v.as_str().unwrap()).collect();
    assert!(
        unique.len() < blockids.len(),
        "the sample repeats its buildings"
    );
    let dir = tempfile::tempdir().unwrap();
    let lone = dir.path().join("2.glb");
    std::fs::copy(format!("{AMSTERDAM}/glb/2.glb"), &lone).unwrap();
    let city = load_city(&lone, &LoadOptions::default()).unwrap();
    let r = &city.report;
    assert_eq!(r.buildings_found, unique.len(), "{r}");
    assert!(r.is_balanced(), "{r}");
    let copies: Vec<_> = r
        .warnings
        .iter()
        .filter(|w| w.message.contains("the same triangles as building"))
        .collect();
    assert_eq!(copies.len(), blockids.len() - unique.len(), "{r}");
    assert!(copies.iter().all(|w| w.source_id.starts_with("2#")));
    // With its sidecar the file loads the same buildings, by their blockids, without a warning.
    let with_sidecar = load_city(
        Path::new(&format!("{AMSTERDAM}/glb/2.glb")),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(with_sidecar.report.buildings_found, unique.len());
    assert!(
        !with_sidecar
            .report
            .warnings
            .iter()
            .any(|w| w.message.contains("the same triangles")),
        "{}",
        with_sidecar.report
    );
}

/// Issue 14 case 10: a `.b3dm` copied out of its tileset folder rejected a building as "absurd
/// height 1124.7 m .. 1204.6 m": without its tileset, pg2b3dm's content is ECEF offsets from a
/// lost root translation, whose z axis leans 37.6° from up at Amsterdam, so every height was
/// judged in a tilted frame. Every sample tile, copied alone, loads the buildings it loads beside
/// `tileset.json`, with the same heights and footprint areas (levelled by its walls, in a
/// local frame), and a warning that names the file and says it is not georeferenced.
#[test]
fn issue14_case10_a_lone_tile_loads_as_beside_its_tileset() {
    let dir = tempfile::tempdir().unwrap();
    for i in 1..=10 {
        let placed_path = PathBuf::from(format!("{AMSTERDAM}/tiles/{i}.b3dm"));
        let placed = load_city(&placed_path, &LoadOptions::default()).unwrap();
        assert_eq!(placed.frame.crs, Crs::Ecef, "tile {i} beside its tileset");
        let lone_path = dir.path().join(format!("{i}.b3dm"));
        std::fs::copy(&placed_path, &lone_path).unwrap();
        let lone = load_city(&lone_path, &LoadOptions::default()).unwrap();
        let (r, p) = (&lone.report, &placed.report);
        assert!(
            r.rejected.is_empty(),
            "tile {i} alone: {r}: {:?}",
            r.rejected
        );
        assert_eq!(
            (r.buildings_found, r.buildings_loaded),
            (p.buildings_found, p.buildings_loaded),
            "tile {i}"
        );
        assert_eq!(lone.frame.crs, Crs::Local);
        let warning = r
            .warnings
            .iter()
            .map(ToString::to_string)
            .find(|w| w.contains("not georeferenced"))
            .unwrap_or_else(|| panic!("tile {i}: no warning in {:?}", r.warnings));
        assert!(
            warning.contains(&format!("{i}.b3dm")) && warning.contains("levelled"),
            "{warning}"
        );
        for b in &placed.buildings {
            let twin = (lone.buildings.iter())
                .find(|l| l.source_id == b.source_id)
                .unwrap_or_else(|| panic!("tile {i}: {} not loaded alone", b.source_id));
            // ENU at the tileset's centre and the tile's own floors differ by the earth's
            // curvature over at most 2.5 km (0.02°): centimetres on these buildings.
            assert!(
                (twin.height_m() - b.height_m()).abs() < 0.1,
                "tile {i} {}: {} m alone, {} m placed",
                b.source_id,
                twin.height_m(),
                b.height_m()
            );
            let (a, a_placed) = (twin.footprint_area_m2(), b.footprint_area_m2());
            assert!(
                (a - a_placed).abs() <= 0.01 * a_placed + 0.5,
                "tile {i} {}: footprint {a} m² alone, {a_placed} m² placed",
                b.source_id
            );
        }
        lone.check_invariants().unwrap();
    }
}

/// A lone b3dm whose `RTC_CENTER` lies on the earth is georeferenced by it (its tileset's
/// transforms were the identity): placed east-north-up there, as its tileset would place it,
/// without a warning; one whose `RTC_CENTER` is a small offset is not, and says so.
#[test]
fn issue14_case10_a_lone_tile_with_an_ecef_rtc_centre_is_placed_by_it() {
    let glb = make_glb(&[([0.0, 0.0, 0.0], [10.0, 8.0, 12.0], 0)], true, "");
    let centre = citywalk_scenes::frame::geodetic_to_ecef(4.9, 52.37, 40.0);
    let feature_table = format!(
        r#"{{"BATCH_LENGTH":1,"RTC_CENTER":[{},{},{}]}}"#,
        centre.x, centre.y, centre.z
    );
    let tile = make_b3dm_with(&feature_table, r#"{"id":["house"]}"#, &glb);
    let city = gltf_loader::load_bytes(Path::new("geo.b3dm"), &tile).unwrap();
    assert_eq!(city.frame.crs, Crs::Ecef);
    assert!(
        (city.frame.origin[0] - 4.9).abs() < 1e-6 && (city.frame.origin[1] - 52.37).abs() < 1e-6,
        "{:?}",
        city.frame.origin
    );
    assert!(
        city.report.warnings.is_empty(),
        "{:?}",
        city.report.warnings
    );
    assert_eq!(city.buildings.len(), 1);
    // The content's axes are ECEF's, as its tileset would have them: the box's height is its
    // extent along the earth's up there.
    let (lon, lat) = (4.9f64.to_radians(), 52.37f64.to_radians());
    let up = [lat.cos() * lon.cos(), lat.cos() * lon.sin(), lat.sin()];
    let expected = 10.0 * up[0].abs() + 8.0 * up[1].abs() + 12.0 * up[2].abs();
    let height = f64::from(city.buildings[0].height_m());
    assert!(
        (height - expected).abs() < 1e-3,
        "{height} m, not {expected} m"
    );

    let offset = make_b3dm_with(
        r#"{"BATCH_LENGTH":1,"RTC_CENTER":[100,200,0]}"#,
        r#"{"id":["house"]}"#,
        &glb,
    );
    let city = gltf_loader::load_bytes(Path::new("offset.b3dm"), &offset).unwrap();
    assert_eq!(city.frame.crs, Crs::Local);
    let warnings: Vec<String> = city
        .report
        .warnings
        .iter()
        .map(ToString::to_string)
        .collect();
    assert!(
        warnings.len() == 1
            && warnings[0].contains("offset.b3dm")
            && warnings[0].contains("not georeferenced")
            && !warnings[0].contains("levelled"),
        "{warnings:?}"
    );
    assert!((city.buildings[0].height_m() - 12.0).abs() < 1e-4);
}
