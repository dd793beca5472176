//! The 3D Tiles export (`citywalk_scenes::export`): the tileset obeys the 3D Tiles 1.1 rules a
//! validator applies (checked here), every content and the tileset pass the ecosystem's own
//! tools (the Khronos glTF validator and loaders.gl, through `.ci/export-check`), cities in a
//! geographic and in a projected CRS land where they are on the globe, and an exported GLB reads
//! back through citywalk's own glTF loader as the same buildings.

use std::collections::BTreeSet;
use std::path::{Path, PathBuf};
use std::process::Command;

use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_scenes::export::{ExportOptions, write_3d_tiles, write_glb};
use citywalk_scenes::frame::ecef_to_geodetic;
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_scenes::package::ScenePackage;
use citywalk_scenes::{LoadOptions, load_cities};
use glam::{DMat4, DVec3};
use serde_json::Value;

const CHELSEA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenes/data/chelsea.osm.pbf"
);
const DEN_HAAG: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cityjson_denhaag/DenHaag_01.json"
);
const CHECK: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../.ci/export-check");

fn package_of(input: &str) -> ScenePackage {
    let city = load_cities(&[PathBuf::from(input)], &LoadOptions::default()).expect("load");
    preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess")
}

fn generated(buildings: usize) -> ScenePackage {
    let city = generate_city(&GenerateParams {
        buildings,
        seed: 3,
        ..GenerateParams::default()
    })
    .expect("generate");
    preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess")
}

fn json_of(path: &Path) -> Value {
    serde_json::from_slice(&std::fs::read(path).expect("read")).expect("JSON")
}

/// A GLB's JSON chunk and binary chunk.
fn glb_parts(bytes: &[u8]) -> (Value, Vec<u8>) {
    assert_eq!(&bytes[..4], b"glTF");
    let json_len = u32::from_le_bytes(bytes[12..16].try_into().unwrap()) as usize;
    let json: Value = serde_json::from_slice(&bytes[20..20 + json_len]).expect("JSON chunk");
    let bin_at = 20 + json_len;
    let bin = if bytes.len() > bin_at + 8 {
        let len = u32::from_le_bytes(bytes[bin_at..bin_at + 4].try_into().unwrap()) as usize;
        bytes[bin_at + 8..bin_at + 8 + len].to_vec()
    } else {
        Vec::new()
    };
    (json, bin)
}

/// The u32 values of property `name` of property table `table`.
fn table_u32(json: &Value, bin: &[u8], table: &Value, name: &str) -> Vec<u32> {
    let view = &json["bufferViews"][table["properties"][name]["values"].as_u64().unwrap() as usize];
    let at = view["byteOffset"].as_u64().unwrap() as usize;
    let len = view["byteLength"].as_u64().unwrap() as usize;
    assert_eq!(at % 8, 0, "property views are 8-byte aligned");
    bin[at..at + len]
        .chunks_exact(4)
        .map(|c| u32::from_le_bytes(c.try_into().unwrap()))
        .collect()
}

/// What the rules check found.
#[derive(Default)]
struct Walk {
    tiles: usize,
    /// Building ids in the contents of tiles without children (the city at full detail).
    finest: Vec<u32>,
}

/// Checks one tile and its subtree against the 3D Tiles 1.1 rules (required properties,
/// `refine` values, child geometric error ≤ parent's, every content inside its tile's box,
/// URIs resolve) and gathers the buildings of the finest tiles.
fn check_tile(dir: &Path, tile: &Value, parent_error: f64, walk: &mut Walk) {
    walk.tiles += 1;
    let error = tile["geometricError"].as_f64().expect("geometricError");
    assert!(error.is_finite() && error >= 0.0);
    assert!(
        error <= parent_error + 1e-9,
        "child {error} > parent {parent_error}"
    );
    if let Some(r) = tile.get("refine") {
        assert!(r == "REPLACE" || r == "ADD", "refine {r}");
    }
    let b: Vec<f64> = tile["boundingVolume"]["box"]
        .as_array()
        .expect("a box")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    assert_eq!(b.len(), 12);
    let (centre, half) = (DVec3::new(b[0], b[1], b[2]), DVec3::new(b[3], b[7], b[11]));
    assert!(half.min_element() > 0.0, "{half}");
    let children = tile["children"].as_array().cloned().unwrap_or_default();
    if let Some(uri) = tile["content"]["uri"].as_str() {
        let bytes = std::fs::read(dir.join(uri)).expect("the content URI resolves");
        let (json, bin) = glb_parts(&bytes);
        // Content bounds: accessor min/max of POSITION, plus the node's translation, y-up.
        let t = &json["nodes"][0]["translation"];
        let translation = DVec3::new(
            t[0].as_f64().unwrap(),
            t[1].as_f64().unwrap(),
            t[2].as_f64().unwrap(),
        );
        for prim in json["meshes"][0]["primitives"].as_array().unwrap() {
            let acc = &json["accessors"][prim["attributes"]["POSITION"].as_u64().unwrap() as usize];
            for corner in ["min", "max"] {
                let c = &acc[corner];
                let y_up = translation
                    + DVec3::new(
                        c[0].as_f64().unwrap(),
                        c[1].as_f64().unwrap(),
                        c[2].as_f64().unwrap(),
                    );
                let z_up = DVec3::new(y_up.x, -y_up.z, y_up.y);
                let outside = ((z_up - centre).abs() - half).max_element();
                assert!(
                    outside <= 1e-3,
                    "{uri}: content {outside} m outside its tile"
                );
            }
        }
        if children.is_empty() {
            let tables = json["extensions"]["EXT_structural_metadata"]["propertyTables"]
                .as_array()
                .unwrap();
            for table in tables {
                assert_eq!(
                    table["class"], "building",
                    "finest tiles hold buildings only"
                );
                walk.finest
                    .extend(table_u32(&json, &bin, table, "building_id"));
            }
        }
    } else {
        assert!(!children.is_empty(), "a tile without content has children");
    }
    for child in &children {
        check_tile(dir, child, error, walk);
    }
}

/// Runs the ecosystem's checks on `target` (a tileset.json or a GLB). Without Node.js or the
/// packages the test fails under CI (`.ci/setup.sh` installs them) and says so elsewhere.
fn ecosystem_check(target: &Path) {
    let script = Path::new(CHECK).join("check.mjs");
    let installed = Path::new(CHECK).join("node_modules").is_dir();
    let out = Command::new("node").arg(&script).arg(target).output();
    match out {
        Ok(out) if installed => {
            let stdout = String::from_utf8_lossy(&out.stdout);
            assert!(
                out.status.success(),
                "{}: {stdout}{}",
                target.display(),
                String::from_utf8_lossy(&out.stderr)
            );
            let summary: Value = serde_json::from_str(stdout.trim()).expect("a JSON summary");
            assert_eq!(summary["validator_errors"], 0, "{summary}");
            assert_eq!(summary["validator_warnings"], 0, "{summary}");
            assert_eq!(summary["loader_errors"], 0, "{summary}");
            assert!(summary["contents"].as_u64().unwrap() > 0);
        }
        _ => {
            assert!(
                std::env::var_os("CI").is_none(),
                "node or {CHECK}/node_modules missing: run .ci/setup.sh"
            );
            eprintln!("skipping the ecosystem check: node or the npm packages are missing");
        }
    }
}

fn root_lon_lat(tileset: &Value) -> (f64, f64) {
    let t: Vec<f64> = tileset["root"]["transform"]
        .as_array()
        .expect("a root transform")
        .iter()
        .map(|v| v.as_f64().unwrap())
        .collect();
    let m = DMat4::from_cols_array(&t.try_into().unwrap());
    let (lon, lat, _) = ecef_to_geodetic(m.transform_point3(DVec3::ZERO));
    (lon, lat)
}

#[test]
fn chelsea_exports_a_tileset_that_obeys_the_rules_and_the_ecosystem_reads() {
    let package = package_of(CHELSEA);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("chelsea");
    let options = ExportOptions {
        max_tile_triangles: 4_000,
        ..ExportOptions::default()
    };
    let report = write_3d_tiles(&package, &out, &options).expect("export");
    let tileset = json_of(&out.join("tileset.json"));
    assert_eq!(tileset["asset"]["version"], "1.1");
    assert_eq!(tileset["root"]["refine"], "REPLACE");
    let root_error = tileset["root"]["geometricError"].as_f64().unwrap();
    assert!(root_error > 0.0, "cluster tiles above the buildings");
    let mut walk = Walk::default();
    check_tile(
        &out,
        &tileset["root"],
        tileset["geometricError"].as_f64().unwrap(),
        &mut walk,
    );
    assert_eq!(walk.tiles, report.tiles);
    assert!(report.tiles > 5 && report.clusters_written > 0);
    // At full detail every building once.
    walk.finest.sort_unstable();
    assert_eq!(
        walk.finest,
        (0..package.buildings.len() as u32).collect::<Vec<_>>()
    );
    // On the globe where Chelsea is, with OpenStreetMap's attribution.
    let (lon, lat) = root_lon_lat(&tileset);
    assert!(
        (lon + 74.0).abs() < 0.02 && (lat - 40.745).abs() < 0.02,
        "{lon}, {lat}"
    );
    assert!(
        tileset["asset"]["extras"]["citywalk"]["attribution"]
            .as_str()
            .unwrap()
            .contains("OpenStreetMap")
    );
    ecosystem_check(&out.join("tileset.json"));
    // Exporting again into the same folder replaces the earlier tileset.
    write_3d_tiles(&package, &out, &options).expect("export again");
    let other = dir.path().join("other");
    std::fs::create_dir_all(&other).unwrap();
    std::fs::write(other.join("notes.txt"), "mine").unwrap();
    let err = write_3d_tiles(&package, &other, &options).unwrap_err();
    assert!(err.to_string().contains("not empty"), "{err}");
}

#[test]
fn den_haag_in_rd_new_lands_in_the_hague() {
    let package = package_of(DEN_HAAG);
    let dir = tempfile::tempdir().unwrap();
    let out = dir.path().join("denhaag");
    write_3d_tiles(&package, &out, &ExportOptions::default()).expect("export");
    let tileset = json_of(&out.join("tileset.json"));
    let (lon, lat) = root_lon_lat(&tileset);
    assert!(
        (lon - 4.3).abs() < 0.1 && (lat - 52.07).abs() < 0.1,
        "{lon}, {lat}"
    );
    let mut walk = Walk::default();
    check_tile(&out, &tileset["root"], f64::INFINITY, &mut walk);
    ecosystem_check(&out.join("tileset.json"));
}

#[test]
fn a_generated_city_needs_a_place_and_its_glb_reads_back_as_the_same_buildings() {
    let package = generated(300);
    let dir = tempfile::tempdir().unwrap();
    // A procedural city is nowhere until told.
    let err = write_3d_tiles(&package, &dir.path().join("t"), &ExportOptions::default())
        .unwrap_err()
        .to_string();
    assert!(err.contains("--place"), "{err}");
    let options = ExportOptions {
        place: Some((-0.1276, 51.5072)),
        max_tile_triangles: 1_000,
        ..ExportOptions::default()
    };
    let out = dir.path().join("t");
    write_3d_tiles(&package, &out, &options).expect("export");
    let tileset = json_of(&out.join("tileset.json"));
    let (lon, lat) = root_lon_lat(&tileset);
    assert!((lon + 0.1276).abs() < 1e-6 && (lat - 51.5072).abs() < 1e-6);
    ecosystem_check(&out.join("tileset.json"));

    // The whole city as one GLB, read back by citywalk's glTF loader: the same buildings, by
    // source id, with the same triangles.
    let glb = dir.path().join("city.glb");
    write_glb(&package, &glb, None, &options).expect("glb");
    ecosystem_check(&glb);
    let back = load_cities(std::slice::from_ref(&glb), &LoadOptions::default()).expect("read back");
    let ids = |names: Vec<&str>| {
        names
            .into_iter()
            .map(str::to_string)
            .collect::<BTreeSet<_>>()
    };
    assert_eq!(
        ids(back
            .buildings
            .iter()
            .map(|b| b.source_id.as_str())
            .collect()),
        ids(package
            .buildings
            .iter()
            .map(|b| b.source_id.as_str())
            .collect())
    );
    assert_eq!(back.buildings.len(), package.buildings.len());
    for b in &back.buildings {
        let original = package
            .buildings
            .iter()
            .find(|o| o.source_id == b.source_id)
            .unwrap();
        assert!(
            (b.height_m() - original.height_m()).abs() < 0.01,
            "{}: {} against {}",
            b.source_id,
            b.height_m(),
            original.height_m()
        );
    }
    // One level of the tree: cluster meshes, fewer triangles than full detail.
    let level = dir.path().join("level.glb");
    let full = write_glb(&package, &glb, None, &options).unwrap();
    let cut = write_glb(&package, &level, Some(2), &options).unwrap();
    assert!(cut.clusters_written > 0 && cut.triangles < full.triangles);
    assert!(write_glb(&package, &level, Some(10_000), &options).is_err());
}
