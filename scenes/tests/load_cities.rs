//! Several inputs merged into one city (`load_cities`): inputs and buildings read twice.

use std::path::{Path, PathBuf};

use citywalk_scenes::{City, LoadOptions, load_cities};
use serde_json::json;

const AMSTERDAM: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/gltf_amsterdam_pg2b3dm"
);

fn load(paths: &[PathBuf]) -> City {
    let city = load_cities(paths, &LoadOptions::default()).unwrap();
    assert!(city.report.is_balanced(), "{}", city.report);
    city.check_invariants().unwrap();
    city
}

/// Warnings whose message contains `needle`.
fn warnings_with<'a>(city: &'a City, needle: &str) -> Vec<&'a citywalk_scenes::LoadWarning> {
    city.report
        .warnings
        .iter()
        .filter(|w| w.message.contains(needle))
        .collect()
}

/// A local-metres GeoJSON square with feature id `id` at `x`.
fn square(id: &str, x: f64, height: f64) -> serde_json::Value {
    json!({"type": "Feature", "id": id, "properties": {"height": height},
           "geometry": {"type": "Polygon", "coordinates":
               [[[x, 0.0], [x + 10.0, 0.0], [x + 10.0, 10.0], [x, 10.0], [x, 0.0]]]}})
}

fn write_geojson(dir: &Path, name: &str, features: Vec<serde_json::Value>) -> PathBuf {
    let doc = json!({"type": "FeatureCollection", "crs":
        {"type": "name", "properties": {"name": "citywalk:local"}}, "features": features});
    let path = dir.join(name);
    std::fs::write(&path, doc.to_string()).unwrap();
    path
}

/// Issue 14: the same file given twice was kept twice without a warning. It is read once
/// (by any path that names it), with a warning naming it.
#[test]
fn issue14_small_same_file_given_twice_is_read_once() {
    let dir = tempfile::tempdir().unwrap();
    let file = write_geojson(
        dir.path(),
        "a.geojson",
        vec![square("a1", 0.0, 10.0), square("a2", 30.0, 12.0)],
    );
    let again = dir.path().join(".").join("a.geojson");
    let once = load(std::slice::from_ref(&file));
    let twice = load(&[file.clone(), again.clone(), file.clone()]);
    assert_eq!(twice.buildings.len(), once.buildings.len());
    assert_eq!(twice.report.buildings_found, 2, "{}", twice.report);
    assert_eq!(twice.report.files, once.report.files);
    let warned = warnings_with(&twice, "given twice");
    assert_eq!(warned.len(), 2, "{:?}", twice.report.warnings);
    assert_eq!(warned[0].file, again);
    assert!(warned[0].message.contains(&file.display().to_string()));
}

/// Issue 14: a tileset plus one of its own tiles was kept twice. Given after the tileset, the
/// tile is not read again; given before it, the tileset's copies of its buildings are dropped,
/// each with a warning naming its id.
#[test]
fn issue14_small_tileset_and_one_of_its_tiles_are_read_once() {
    let tileset = PathBuf::from(format!("{AMSTERDAM}/tileset.json"));
    let tile = PathBuf::from(format!("{AMSTERDAM}/tiles/4.b3dm"));
    let alone = load(std::slice::from_ref(&tileset));
    let tile_alone = load(std::slice::from_ref(&tile));
    assert!(!tile_alone.buildings.is_empty());

    let after = load(&[tileset.clone(), tile.clone()]);
    assert_eq!(after.buildings.len(), alone.buildings.len());
    assert_eq!(after.report.buildings_found, alone.report.buildings_found);
    let warned = warnings_with(&after, "already read as part of");
    assert_eq!(warned.len(), 1, "{:?}", after.report.warnings);
    assert_eq!(warned[0].file, tile);

    let before = load(&[tile.clone(), tileset.clone()]);
    assert_eq!(before.buildings.len(), alone.buildings.len());
    assert_eq!(before.report.buildings_found, alone.report.buildings_found);
    let dropped = warnings_with(&before, "duplicate dropped");
    assert_eq!(dropped.len(), tile_alone.buildings.len());
    let tile_ids: Vec<&str> = tile_alone
        .buildings
        .iter()
        .map(|b| b.source_id.as_str())
        .collect();
    for w in dropped {
        assert!(tile_ids.contains(&w.source_id.as_str()), "{w}");
        assert_eq!(w.file, tileset);
    }
}

/// An id shared by two different buildings (here two files numbering their features alike)
/// keeps both, with a warning naming the id; the same id on the same building is dropped.
#[test]
fn issue14_small_shared_id_of_different_buildings_keeps_both() {
    let dir = tempfile::tempdir().unwrap();
    let a = write_geojson(dir.path(), "a.geojson", vec![square("f1", 0.0, 10.0)]);
    let b = write_geojson(
        dir.path(),
        "b.geojson",
        vec![square("f1", 50.0, 10.0), square("f1", 50.0, 10.0)],
    );
    let city = load(&[a.clone(), b.clone()]);
    assert_eq!(city.buildings.len(), 2, "{}", city.report);
    let shared = warnings_with(&city, "different building");
    assert_eq!(shared.len(), 1, "{:?}", city.report.warnings);
    assert_eq!((shared[0].source_id.as_str(), &shared[0].file), ("f1", &b));
    assert!(shared[0].message.contains("a.geojson"), "{}", shared[0]);
    // b's own repeat of its f1 is that building again: dropped.
    let dropped = warnings_with(&city, "duplicate dropped");
    assert_eq!(dropped.len(), 1, "{:?}", city.report.warnings);
    assert!(
        dropped[0].message.contains("earlier in this file"),
        "{}",
        dropped[0]
    );
    assert_eq!(city.report.buildings_found, 2, "{}", city.report);
}

/// Issue 14: two cities 4,375 km apart merged into one frame without a warning. An input whose
/// buildings lie more than 100 km from every earlier input's gets a warning naming both files
/// and the distance; inputs side by side get none.
#[test]
fn issue14_small_inputs_far_apart_are_warned_of() {
    let dir = tempfile::tempdir().unwrap();
    let lonlat = |name: &str, lon: f64, lat: f64| {
        let s = 0.0002;
        let feature = json!({"type": "Feature", "id": format!("{name}1"),
            "properties": {"height": 10},
            "geometry": {"type": "Polygon", "coordinates": [[[lon, lat], [lon + s, lat],
                [lon + s, lat + s], [lon, lat + s], [lon, lat]]]}});
        let path = dir.path().join(format!("{name}.geojson"));
        let doc = json!({"type": "FeatureCollection", "features": [feature]});
        std::fs::write(&path, doc.to_string()).unwrap();
        path
    };
    // New York and Porto, about 5,300 km apart; a second New York block 1 km away.
    let nyc = lonlat("nyc", -74.0, 40.74);
    let nyc_east = lonlat("nyc_east", -73.988, 40.74);
    let porto = lonlat("porto", -8.61, 41.15);
    let near = load(&[nyc.clone(), nyc_east.clone()]);
    assert!(
        warnings_with(&near, "km from").is_empty(),
        "{:?}",
        near.report.warnings
    );
    let far = load(&[nyc.clone(), nyc_east, porto.clone()]);
    let warned = warnings_with(&far, "km from");
    assert_eq!(warned.len(), 1, "{:?}", far.report.warnings);
    assert_eq!(warned[0].file, porto);
    // The nearest earlier input is named, with the distance (the frame is centred on New York;
    // great-circle distance 5,300 km, the planar one differs by the projection's scale).
    let msg = &warned[0].message;
    assert!(msg.contains("nyc"), "{msg}");
    let km: f64 = msg
        .split(" km from")
        .next()
        .and_then(|s| s.rsplit(' ').next())
        .and_then(|s| s.parse().ok())
        .unwrap_or_else(|| panic!("no distance in {msg}"));
    assert!((4_000.0..7_000.0).contains(&km), "{msg}");
    // In local metres: 150 km apart warns, 50 km does not.
    let a = write_geojson(dir.path(), "a.geojson", vec![square("a", 0.0, 10.0)]);
    let b = write_geojson(dir.path(), "b.geojson", vec![square("b", 50_000.0, 10.0)]);
    let c = write_geojson(dir.path(), "c.geojson", vec![square("c", -150_000.0, 10.0)]);
    assert!(warnings_with(&load(&[a.clone(), b.clone()]), "km from").is_empty());
    let city = load(&[a, b, c.clone()]);
    let warned = warnings_with(&city, "km from");
    assert_eq!(warned.len(), 1, "{:?}", city.report.warnings);
    assert_eq!(warned[0].file, c);
    assert!(warned[0].message.contains("150 km from"), "{}", warned[0]);
}
