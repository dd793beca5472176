//! The GeoJSON loader on the real OSM-derived extracts (compared with the PBF loader), on
//! small hand-made files (parts linked by `part_of` or by containment, CRS, streets, bad
//! buildings) and on corrupt files (errors, never panics).

use std::path::Path;
use std::time::Instant;

use citywalk_scenes::load::{geojson, osm};
use citywalk_scenes::{
    Crs, GroundClass, HeightSource, LoadError, LoadOptions, RejectReason, StreetClass,
};
use files::{temp_file, thread_cpu_ns};
use fuzz::fixed_runner;
use proptest::prelude::*;
use serde_json::json;

#[path = "support/files.rs"]
mod files;
#[path = "support/fuzz.rs"]
mod fuzz;

const CHELSEA_DIR: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/osm_nyc_chelsea"
);
const PORTO_DIR: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/osm_porto_center"
);

fn load_json(name: &str, value: &serde_json::Value) -> Result<citywalk_scenes::City, LoadError> {
    let path = temp_file(name, value.to_string().as_bytes());
    geojson::load(&path, &LoadOptions::default())
}

/// A closed square ring `[x, y]` of side `s`.
fn ring(x: f64, y: f64, s: f64) -> serde_json::Value {
    json!([[x, y], [x + s, y], [x + s, y + s], [x, y + s], [x, y]])
}

fn polygon(x: f64, y: f64, s: f64, properties: serde_json::Value) -> serde_json::Value {
    json!({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [ring(x, y, s)]},
           "properties": properties})
}

fn collection(features: Vec<serde_json::Value>) -> serde_json::Value {
    json!({"type": "FeatureCollection", "features": features})
}

#[test]
fn chelsea_geojson_agrees_with_the_pbf() {
    let start = Instant::now();
    let cpu = thread_cpu_ns();
    let city = geojson::load(
        &Path::new(CHELSEA_DIR).join("buildings.geojson"),
        &LoadOptions::default(),
    )
    .unwrap();
    let elapsed = start.elapsed();
    let cpu_ms = thread_cpu_ns().saturating_sub(cpu) as f64 * 1e-6;
    let r = &city.report;
    println!("Chelsea GeoJSON: {r} in {elapsed:.2?} (CPU {cpu_ms:.1} ms)");
    assert_eq!(r.buildings_found, 1525, "{r}");
    assert_eq!(r.parts_found, 43, "{r}");
    assert_eq!(r.buildings_with_height, 1514, "{r}");
    assert!(r.is_balanced(), "{r}");
    city.check_invariants().unwrap();
    assert!(matches!(city.frame.crs, Crs::Wgs84));

    let pbf = osm::load(
        &Path::new(CHELSEA_DIR).join("nyc.osm.pbf"),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(r.buildings_loaded, pbf.report.buildings_loaded);
    // Same ids (osm_type/osm_id), same frame, same heights, footprints within centimetres.
    let by_id: std::collections::HashMap<&str, &citywalk_scenes::Building> = pbf
        .buildings
        .iter()
        .map(|b| (b.source_id.as_str(), b))
        .collect();
    assert!((city.frame.origin[0] - pbf.frame.origin[0]).abs() < 1e-9);
    assert!((city.frame.origin[1] - pbf.frame.origin[1]).abs() < 1e-9);
    use geo::Area;
    for b in &city.buildings {
        let other = by_id
            .get(b.source_id.as_str())
            .unwrap_or_else(|| panic!("{} not in the PBF city", b.source_id));
        assert_eq!(
            (b.base_m, b.top_m),
            (other.base_m, other.top_m),
            "{}",
            b.source_id
        );
        assert_eq!(b.parts.len(), other.parts.len(), "{}", b.source_id);
        let (a, o) = (b.footprint.unsigned_area(), other.footprint.unsigned_area());
        assert!(
            (a - o).abs() < 1e-3 * o.max(1.0),
            "{}: {a} vs {o}",
            b.source_id
        );
    }
}

#[test]
fn porto_geojson_agrees_with_the_pbf() {
    let start = Instant::now();
    let cpu = thread_cpu_ns();
    let city = geojson::load(
        &Path::new(PORTO_DIR).join("buildings.geojson"),
        &LoadOptions::default(),
    )
    .unwrap();
    let elapsed = start.elapsed();
    let cpu_ms = thread_cpu_ns().saturating_sub(cpu) as f64 * 1e-6;
    let r = &city.report;
    println!("Porto GeoJSON: {r} in {elapsed:.2?} (CPU {cpu_ms:.1} ms)");
    assert_eq!((r.buildings_found, r.parts_found), (11_404, 61), "{r}");
    assert!(r.is_balanced(), "{r}");
    assert_eq!(r.buildings_with_height, 5, "{r}");
    city.check_invariants().unwrap();
    let pbf = osm::load(
        &Path::new(PORTO_DIR).join("porto.osm.pbf"),
        &LoadOptions::default(),
    )
    .unwrap();
    assert_eq!(r.buildings_loaded, pbf.report.buildings_loaded);
    assert_eq!(
        r.buildings_estimated_height,
        pbf.report.buildings_estimated_height
    );
}

#[test]
fn parts_link_by_part_of_or_by_containment() {
    // Building A (feature id "a") and B (feature id "B", id property "b"), side by side. Part
    // p1 lies inside A but names B by its id property with part_of: the explicit link wins
    // (B's source id is its feature id, the link its other name). Part p2 has no link and
    // lies in A.
    let a = json!({"type": "Feature", "id": "a",
        "geometry": {"type": "Polygon", "coordinates": [ring(0.0, 0.0, 0.0002)]},
        "properties": {"height": 20, "min_height": 0}});
    let mut b = polygon(0.001, 0.0, 0.0002, json!({"id": "b", "height_m": 12.5}));
    b["id"] = json!("B");
    let p1 = polygon(
        0.00005,
        0.00005,
        0.00005,
        json!({"kind": "building:part", "part_of": "b", "height": 10}),
    );
    let p2 = polygon(
        0.00012,
        0.00012,
        0.00005,
        json!({"building:part": "yes", "height": "15 m", "min_height_m": 3}),
    );
    // Through the format dispatch (a `.json` file recognised by its content).
    let path = temp_file(
        "parts.json",
        collection(vec![a, b, p1, p2]).to_string().as_bytes(),
    );
    let city = citywalk_scenes::load_city(&path, &LoadOptions::default()).unwrap();
    let r = &city.report;
    assert_eq!(
        (r.buildings_found, r.parts_found, r.buildings_loaded),
        (2, 2, 2),
        "{r}"
    );
    city.check_invariants().unwrap();
    let a = city.buildings.iter().find(|x| x.source_id == "a").unwrap();
    let b = city.buildings.iter().find(|x| x.source_id == "B").unwrap();
    assert_eq!(a.parts.len(), 1);
    assert_eq!(a.parts[0].source_id, "feature/3");
    assert_eq!((a.parts[0].base_m, a.parts[0].top_m), (3.0, 15.0));
    assert_eq!(b.parts.len(), 1);
    assert_eq!(b.parts[0].source_id, "feature/2");
    assert_eq!((b.base_m, b.top_m), (0.0, 10.0));
    assert_eq!(a.height_source, HeightSource::Tagged);
}

#[test]
fn heights_follow_the_documented_order() {
    let f = |props| polygon(0.0, 0.0, 0.0002, props);
    let features = vec![
        f(json!({"id": "custom", "my_h": 42, "height": 10})),
        f(json!({"id": "height", "height": "40'", "height_m": 3})),
        f(json!({"id": "height_m", "height_m": 7.5, "render_height_m": 3})),
        f(json!({"id": "render", "render_height_m": 8})),
        f(json!({"id": "levels", "levels": 4, "min_level": 1})),
        f(json!({"id": "osm levels", "building:levels": "3"})),
        f(json!({"id": "none"})),
    ];
    let path = temp_file(
        "heights.geojson",
        collection(features).to_string().as_bytes(),
    );
    let options = LoadOptions {
        height_property: Some("my_h".into()),
        ..LoadOptions::default()
    };
    let city = geojson::load(&path, &options).unwrap();
    let get = |id: &str| {
        let b = city.buildings.iter().find(|b| b.source_id == id).unwrap();
        (b.base_m, b.top_m, b.height_source)
    };
    assert_eq!(get("custom"), (0.0, 42.0, HeightSource::Tagged));
    let (_, top, _) = get("height");
    assert!((top - 12.192).abs() < 1e-3);
    assert_eq!(get("height_m"), (0.0, 7.5, HeightSource::Tagged));
    assert_eq!(get("render"), (0.0, 8.0, HeightSource::Tagged));
    assert_eq!(get("levels"), (3.0, 12.0, HeightSource::Levels));
    assert_eq!(get("osm levels"), (0.0, 9.0, HeightSource::Levels));
    assert_eq!(get("none"), (0.0, 9.0, HeightSource::Estimated));
    assert_eq!(city.report.buildings_with_height, 4);
    assert_eq!(city.report.buildings_estimated_height, 1);
}

#[test]
fn streets_crs_and_ids() {
    // Projected metres (EPSG:28992, Dutch RD) with a legacy crs member.
    let doc = json!({"type": "FeatureCollection",
        "features": [
            {"type": "Feature", "id": 7, "geometry": {"type": "MultiPolygon",
              "coordinates": [[ring(85_000.0, 446_000.0, 10.0)], [ring(85_020.0, 446_000.0, 10.0)]]},
             "properties": {"osm_id": 9, "height": 6}},
            {"type": "Feature", "geometry": {"type": "Polygon",
              "coordinates": [ring(85_100.0, 446_100.0, 10.0)]},
             "properties": {"osm_id": 12, "osm_type": "way"}},
            {"type": "Feature", "geometry": {"type": "LineString",
              "coordinates": [[85_000.0, 445_990.0], [85_200.0, 445_990.0]]},
             "properties": {"highway": "primary", "name": "Main"}},
            {"type": "Feature", "geometry": {"type": "MultiLineString",
              "coordinates": [[[85_000.0, 446_200.0], [85_100.0, 446_200.0]],
                              [[85_100.0, 446_200.0], [85_100.0, 446_300.0]]]},
             "properties": {"highway": "footway"}},
            {"type": "Feature", "geometry": {"type": "LineString",
              "coordinates": [[85_000.0, 445_000.0], [85_200.0, 445_000.0]]},
             "properties": {"waterway": "canal"}},
            {"type": "Feature", "geometry": {"type": "Polygon",
              "coordinates": [ring(85_000.0, 445_000.0, 30.0)]},
             "properties": {"highway": "pedestrian", "area": "yes"}}
        ],
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::28992"}}
    });
    let city = load_json("rd.geojson", &doc).unwrap();
    assert_eq!(city.frame.crs, Crs::Projected("EPSG:28992".into()));
    // Centre of the buildings' bounding box: x 85000..85110, y 446000..446110.
    assert_eq!(city.frame.origin, [85_055.0, 446_055.0, 0.0]);
    let ids: Vec<&str> = city
        .buildings
        .iter()
        .map(|b| b.source_id.as_str())
        .collect();
    assert_eq!(ids, ["7", "way/12"]);
    assert_eq!(city.buildings[0].footprint.0.len(), 2);
    assert_eq!(city.buildings[0].tags.get("osm_id"), Some("9"));
    assert_eq!(city.streets.len(), 3);
    assert_eq!(city.streets[0].class, StreetClass::Major);
    assert_eq!(city.streets[0].name.as_deref(), Some("Main"));
    assert_eq!(city.streets[0].line.0[0].x, -55.0);
    assert_eq!(city.streets[1].class, StreetClass::Pedestrian);
    assert_eq!(city.report.streets_loaded, 3);
    // The canal is skipped, with a warning; the pedestrian square is a paved ground area.
    assert_eq!(city.report.buildings_found, 2);
    assert_eq!(city.ground_areas.len(), 1);
    assert_eq!(city.ground_areas[0].class, GroundClass::Paved);
    assert!(
        city.report
            .warnings
            .iter()
            .any(|w| w.message.starts_with("1 feature(s)")),
        "{:?}",
        city.report.warnings
    );
}

#[test]
fn bad_buildings_are_rejected_and_the_rest_load() {
    let f = |id: &str, coords: serde_json::Value, props: serde_json::Value| {
        let mut props = props;
        props["id"] = json!(id);
        json!({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": coords},
               "properties": props})
    };
    let features = vec![
        f("good", json!([ring(0.0, 0.0, 0.0002)]), json!({})),
        f(
            "nan",
            json!([[[0.0, 0.0], [0.0002, null], [0.0002, 0.0002], [0.0, 0.0]]]),
            json!({}),
        ),
        f(
            "two",
            json!([[[0.0, 0.0], [0.0002, 0.0], [0.0, 0.0]]]),
            json!({}),
        ),
        f(
            "flat",
            json!([[[0.0, 0.0], [0.0001, 0.0], [0.0002, 0.0], [0.0, 0.0]]]),
            json!({}),
        ),
        f(
            "tall",
            json!([ring(0.0, 0.0, 0.0002)]),
            json!({"height": 99999}),
        ),
        f(
            "negative",
            json!([ring(0.0, 0.0, 0.0002)]),
            json!({"height": -3}),
        ),
        f("garbage", json!([[[0.0, "x"], [1, 2], [2, 2]]]), json!({})),
        f("far", json!([ring(300.0, 0.0, 0.0002)]), json!({})),
        json!({"type": "Feature", "geometry": null, "properties": {"id": "nogeom"}}),
        json!({"type": "Feature", "geometry": 5, "properties": {"id": "numgeom"}}),
        json!({"type": "Feature", "geometry": {"type": "Polygon", "coordinates": [[
            [0.0, 0.0], [0.0002, 0.0], [0.0002, 0.0002], [0.0, 0.0002],
            [0.0, 0.0], [0.0002, 0.0], [0.0002, 0.0002], [0.0, 0.0002],
            [0.0, 0.0], [0.0002, 0.0], [0.0002, 0.0002], [0.0, 0.0002], [0.0, 0.0]]]},
            "properties": {"id": "thrice"}}),
    ];
    let city = load_json("bad.geojson", &collection(features)).unwrap();
    let r = &city.report;
    assert_eq!(
        (r.buildings_found, r.buildings_loaded),
        (11, 1),
        "{r}: {:?}",
        r.rejected
    );
    assert_eq!(city.buildings[0].source_id, "good");
    let reason = |id: &str| {
        r.rejected
            .iter()
            .find(|x| x.source_id == id)
            .map(|x| x.reason.clone())
            .unwrap_or_else(|| panic!("{id} not rejected"))
    };
    assert_eq!(reason("nan"), RejectReason::NonFiniteCoordinate);
    assert_eq!(reason("two"), RejectReason::TooFewPoints);
    assert_eq!(reason("flat"), RejectReason::ZeroArea);
    assert!(matches!(reason("tall"), RejectReason::AbsurdHeight(_)));
    assert!(matches!(reason("negative"), RejectReason::AbsurdHeight(_)));
    assert!(matches!(
        reason("garbage"),
        RejectReason::InvalidGeometry(_)
    ));
    assert!(matches!(
        reason("far"),
        RejectReason::CoordinateOutOfRange(_)
    ));
    assert!(matches!(reason("nogeom"), RejectReason::MissingGeometry(_)));
    assert!(matches!(
        reason("numgeom"),
        RejectReason::InvalidGeometry(_)
    ));
    assert_eq!(reason("thrice"), RejectReason::SelfIntersection);
}

#[test]
fn malformed_files_are_errors_naming_the_file() {
    let chelsea = std::fs::read(Path::new(CHELSEA_DIR).join("buildings.geojson")).unwrap();
    let cases: Vec<(&str, Vec<u8>)> = vec![
        ("empty.geojson", Vec::new()),
        (
            "invalid.geojson",
            b"{\"type\": \"FeatureCollection\", \"features\": [".to_vec(),
        ),
        ("truncated.geojson", chelsea[..chelsea.len() / 3].to_vec()),
        ("array.geojson", b"[1, 2, 3]".to_vec()),
        (
            "feature.geojson",
            json!({"type": "Feature", "geometry": null, "properties": {}})
                .to_string()
                .into_bytes(),
        ),
        (
            "nofeatures.geojson",
            b"{\"type\": \"FeatureCollection\"}".to_vec(),
        ),
        (
            "trailing.geojson",
            b"{\"type\": \"FeatureCollection\", \"features\": []} x".to_vec(),
        ),
        (
            "nothing.geojson",
            collection(vec![]).to_string().into_bytes(),
        ),
    ];
    for (name, bytes) in cases {
        let path = temp_file(name, &bytes);
        let err = geojson::load(&path, &LoadOptions::default()).expect_err(name);
        assert!(err.to_string().contains(name), "{name}: {err}");
    }
    let missing = geojson::load(Path::new("/nonexistent/x.geojson"), &LoadOptions::default());
    assert!(matches!(missing, Err(LoadError::Io { .. })));
}

#[test]
fn corrupt_geojson_never_panics() {
    let doc = collection(vec![
        polygon(0.0, 0.0, 0.0002, json!({"id": "a", "height": 20})),
        polygon(
            0.00005,
            0.00005,
            0.0001,
            json!({"kind": "building:part", "part_of": "a", "height": "25 m"}),
        ),
        polygon(0.001, 0.0, 0.0002, json!({"building:levels": "4"})),
        json!({"type": "Feature", "geometry": {"type": "LineString",
               "coordinates": [[0.0, -0.0001], [0.001, -0.0001]]},
               "properties": {"highway": "residential"}}),
    ])
    .to_string()
    .into_bytes();
    let mut runner = fixed_runner(96, 11);
    let strategy = (
        prop::collection::vec(
            (
                any::<prop::sample::Index>(),
                prop::sample::select(b"0123456789.-,[]{}\":nulE e".to_vec()),
            ),
            0..4,
        ),
        any::<prop::sample::Index>(),
        any::<bool>(),
    );
    runner
        .run(&strategy, |(edits, cut, truncate)| {
            let mut bytes = doc.clone();
            for (at, ch) in &edits {
                let i = at.index(bytes.len());
                bytes[i] = *ch;
            }
            if truncate {
                bytes.truncate(cut.index(bytes.len()));
            }
            let path = temp_file("fuzz.geojson", &bytes);
            match geojson::load(&path, &LoadOptions::default()) {
                Err(e) => prop_assert!(e.to_string().contains(&*path.to_string_lossy()), "{e}"),
                Ok(city) => {
                    prop_assert!(city.report.is_balanced(), "{}", city.report);
                    prop_assert!(city.check_invariants().is_ok());
                }
            }
            Ok(())
        })
        .unwrap();
    std::fs::remove_file(temp_file("fuzz.geojson", b"")).ok();
}

#[test]
fn generated_city_loads_fast_and_whole() {
    // The procedural generator's GeoJSON (local metres, parts linked by `part_of`), big enough
    // to time: the printed rate is the number to compare with the 100k features/s target.
    use citywalk_scenes::generate::{GenerateParams, write_geojson_file};
    let path = temp_file("generated-20k.geojson", b"");
    let params = GenerateParams::new(20_000, 5);
    write_geojson_file(&params, &path, &mut |_| {}).unwrap();
    let start = Instant::now();
    let cpu = thread_cpu_ns();
    let city = geojson::load(&path, &LoadOptions::default()).unwrap();
    let elapsed = start.elapsed();
    let cpu_s = thread_cpu_ns().saturating_sub(cpu) as f64 * 1e-9;
    let r = &city.report;
    let features = r.buildings_found + r.parts_found + r.streets_loaded;
    println!(
        "generated GeoJSON: {r} in {elapsed:.2?} (CPU {cpu_s:.3} s, {:.0} features/s)",
        features as f64 / cpu_s.max(1e-9)
    );
    assert_eq!(city.frame.crs, Crs::Local);
    assert_eq!(
        (r.buildings_found, r.buildings_loaded),
        (20_000, 20_000),
        "{r}"
    );
    assert!(r.rejected.is_empty() && r.is_balanced());
    let parts: usize = city.buildings.iter().map(|b| b.parts.len()).sum();
    assert!(parts >= 20_000, "{parts}");
    assert!(r.warnings.is_empty(), "{:?}", r.warnings.first());
    std::fs::remove_file(&path).ok();
}

/// Issue 14 case 6: one building at 1e15 m in an EPSG:3857 file moved the frame's origin to
/// half-way there, and every building was rejected ("no buildings could be loaded (5 found,
/// all rejected)"). The frame comes from the good buildings; the outlier alone is rejected,
/// with its id and how far it is.
#[test]
fn one_far_outlier_is_rejected_and_the_city_keeps_its_frame() {
    let mut features: Vec<serde_json::Value> = (0..4)
        .map(|k| {
            let x = -8_237_000.0 + 40.0 * k as f64;
            polygon(
                x,
                4_970_000.0,
                20.0,
                json!({"id": format!("b{k}"), "height": 10}),
            )
        })
        .collect();
    features.insert(
        2,
        polygon(1e15, 1e15, 20.0, json!({"id": "far", "height": 10})),
    );
    features.push(polygon(
        -8_237_000.0,
        -1e15,
        20.0,
        json!({"id": "south", "height": 10}),
    ));
    let mut doc = collection(features);
    doc["crs"] = json!({"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3857"}});
    let city = load_json("outlier.geojson", &doc).unwrap();
    let r = &city.report;
    assert_eq!((r.buildings_found, r.buildings_loaded), (6, 4), "{r}");
    assert_eq!(city.frame.origin, [-8_236_930.0, 4_970_010.0, 0.0]);
    for id in ["far", "south"] {
        let rejection = r.rejected.iter().find(|x| x.source_id == id).expect(id);
        assert!(
            matches!(&rejection.reason, RejectReason::CoordinateOutOfRange(m) if m.contains("km from")),
            "{rejection}"
        );
    }
    city.check_invariants().unwrap();
}

/// Issue 14 case 12: malformed highway lines (one point, zero length, a 1e300 coordinate)
/// gave "0 streets; 0 warnings". Each is counted and rejected with its id and reason, like a
/// building; the good street loads.
#[test]
fn malformed_streets_are_counted_and_rejected_with_their_ids() {
    let street = |id: &str, coords: serde_json::Value| {
        json!({"type": "Feature", "geometry": {"type": "LineString", "coordinates": coords},
               "properties": {"id": id, "highway": "residential"}})
    };
    let features = vec![
        polygon(0.0, 0.0, 0.0002, json!({"id": "house", "height": 9})),
        street("good", json!([[0.0, -0.0001], [0.0003, -0.0001]])),
        street("one", json!([[0.0, 0.0]])),
        street("zero", json!([[0.0001, 0.0], [0.0001, 0.0], [0.0001, 0.0]])),
        street("huge", json!([[0.0, 0.0], [1e300, 0.0]])),
        street("null", json!([[0.0, 0.0], [null, 0.0]])),
        street("text", json!("nowhere")),
    ];
    let city = load_json("streets.geojson", &collection(features)).unwrap();
    let r = &city.report;
    assert_eq!((r.streets_found, r.streets_loaded), (6, 1), "{r}");
    assert!(r.is_balanced(), "{r}");
    assert!(r.to_string().contains("1 streets (5 rejected)"), "{r}");
    assert_eq!(city.streets[0].source_id, "good");
    let reason = |id: &str| {
        let x = r.streets_rejected.iter().find(|x| x.source_id == id);
        x.unwrap_or_else(|| panic!("{id} not rejected: {:?}", r.streets_rejected))
            .reason
            .to_string()
    };
    assert!(reason("one").contains("2 distinct points, it has 1"));
    assert!(reason("zero").contains("2 distinct points, it has 1"));
    assert!(
        reason("huge").contains("out of range"),
        "{}",
        reason("huge")
    );
    assert!(!reason("null").is_empty() && !reason("text").is_empty());
}

/// Issue 14: a UTF-8 byte order mark before a GeoJSON gave "expected value at line 1 column 1".
#[test]
fn issue14_small_geojson_with_bom_loads() {
    let text = collection(vec![
        polygon(0.0, 0.0, 0.0001, json!({"height": 10})),
        polygon(0.001, 0.0, 0.0001, json!({"height": 12})),
    ])
    .to_string();
    let bytes = [b"\xEF\xBB\xBF".as_slice(), text.as_bytes()].concat();
    // Both by extension and, as `.json`, by content.
    for name in ["bom.geojson", "bom.json"] {
        let path = temp_file(name, &bytes);
        let city = citywalk_scenes::load_city(&path, &LoadOptions::default()).unwrap();
        assert_eq!(city.buildings.len(), 2, "{name}");
        assert!(city.report.is_balanced());
    }
}

/// Issue 16: polygons that are not buildings and carry OSM area tags are ground areas, with
/// the OSM loader's classes; a building tagged `landuse`, or a polygon with a height or storeys of
/// its own, stays a building; a bad ground area is
/// rejected with its id; a street area without `area=yes` is still skipped.
#[test]
fn ground_areas_load_by_class() {
    let f = |id: &str, coords: serde_json::Value, props: serde_json::Value| {
        json!({"type": "Feature", "id": id, "geometry": {"type": "Polygon",
               "coordinates": coords}, "properties": props})
    };
    let doc = json!({"type": "FeatureCollection",
        "crs": {"type": "name", "properties": {"name": "citywalk:local"}},
        "features": [
            f("house", json!([ring(0.0, 0.0, 10.0)]),
              json!({"building": "yes", "landuse": "retail", "height": 9})),
            f("untagged", json!([ring(20.0, 0.0, 10.0)]), json!({})),
            // A footprint dataset's building with a land-use attribute and a height of its own.
            f("footprint", json!([ring(40.0, 0.0, 10.0)]),
              json!({"landuse": "residential", "height": 12})),
            f("storeys", json!([ring(60.0, 0.0, 10.0)]),
              json!({"landuse": "commercial", "building:levels": 4})),
            f("pond", json!([ring(100.0, 0.0, 40.0)]), json!({"natural": "water"})),
            f("park", json!([ring(200.0, 0.0, 30.0), ring(210.0, 10.0, 5.0)]),
              json!({"tags": {"leisure": "park", "name": "Green"}})),
            f("square", json!([ring(300.0, 0.0, 20.0)]), json!({"place": "square"})),
            f("plaza", json!([ring(400.0, 0.0, 15.0)]),
              json!({"highway": "pedestrian", "area": "yes"})),
            f("street-area", json!([ring(500.0, 0.0, 15.0)]), json!({"highway": "pedestrian"})),
            f("sliver", json!([[[600.0, 0.0], [610.0, 0.0], [600.0, 0.0]]]),
              json!({"landuse": "grass"})),
            {"type": "Feature", "id": "woods", "geometry": {"type": "MultiPolygon",
              "coordinates": [[ring(700.0, 0.0, 10.0)], [ring(720.0, 0.0, 10.0)]]},
             "properties": {"landuse": "forest"}},
        ]
    });
    let city = load_json("ground.geojson", &doc).unwrap();
    let r = &city.report;
    assert!(r.is_balanced(), "{r}");
    city.check_invariants().unwrap();
    let ids: Vec<&str> = city
        .buildings
        .iter()
        .map(|b| b.source_id.as_str())
        .collect();
    assert_eq!(ids, ["house", "untagged", "footprint", "storeys"]);
    assert_eq!((r.ground_areas_found, r.ground_areas_loaded), (6, 5), "{r}");
    use geo::Area;
    let got: Vec<(&str, GroundClass, f64)> = city
        .ground_areas
        .iter()
        .map(|g| (g.source_id.as_str(), g.class, g.polygon.unsigned_area()))
        .collect();
    assert_eq!(
        got,
        [
            ("pond", GroundClass::Water, 1600.0),
            ("park", GroundClass::Park, 875.0),
            ("square", GroundClass::Paved, 400.0),
            ("plaza", GroundClass::Paved, 225.0),
            ("woods", GroundClass::Forest, 200.0),
        ]
    );
    let rejected = &r.ground_areas_rejected;
    assert_eq!(rejected.len(), 1);
    assert_eq!(rejected[0].source_id, "sliver");
    assert_eq!(rejected[0].reason, RejectReason::TooFewPoints);
    assert!(rejected[0].file.ends_with("ground.geojson"));
    // The street area alone is skipped.
    assert!(
        r.warnings
            .iter()
            .any(|w| w.message.starts_with("1 feature(s)")),
        "{:?}",
        r.warnings
    );
}

/// A file that cannot be memory-mapped (a named pipe) is read through a buffered reader
/// instead, BOM and all, into the same city as the mapped file.
#[cfg(unix)]
#[test]
fn a_pipe_loads_like_the_mapped_file() {
    let text = collection(vec![
        polygon(0.0, 0.0, 0.0001, json!({"height": 10, "name": "a"})),
        polygon(0.001, 0.0, 0.0001, json!({"building:levels": 3})),
    ])
    .to_string();
    let bytes = [b"\xEF\xBB\xBF".as_slice(), text.as_bytes()].concat();
    let mapped = geojson::load(
        &temp_file("mapped.geojson", &bytes),
        &LoadOptions::default(),
    )
    .expect("the mapped file");
    let fifo = std::env::temp_dir().join(format!("citywalk-pipe-{}.geojson", std::process::id()));
    let _ = std::fs::remove_file(&fifo);
    let made = std::process::Command::new("mkfifo").arg(&fifo).status();
    assert!(made.is_ok_and(|s| s.success()), "mkfifo failed");
    let writer = {
        let (fifo, bytes) = (fifo.clone(), bytes.clone());
        std::thread::spawn(move || std::fs::write(&fifo, &bytes))
    };
    let piped = geojson::load(&fifo, &LoadOptions::default());
    writer.join().expect("the writer").expect("written");
    let _ = std::fs::remove_file(&fifo);
    let piped = piped.expect("the pipe");
    assert_eq!(piped.buildings.len(), 2);
    assert!(piped.buildings == mapped.buildings);
}
