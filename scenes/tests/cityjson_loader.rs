//! CityJSON loader: the Den Haag sample, hand-written 1.1 / 2.0 files, bad input and a
//! mutation property test.

use std::path::Path;

use citywalk_scenes::load::cityjson;
use citywalk_scenes::{City, Crs, HeightSource, LoadError, LoadOptions, RejectReason, load_city};
use fuzz::fixed_runner;
use geo::{Area, Contains, Point, Validation};
use mutate::mutated;
use proptest::prelude::*;

#[path = "support/fuzz.rs"]
mod fuzz;
#[path = "support/mutate.rs"]
mod mutate;

const DEN_HAAG: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/cityjson_denhaag/DenHaag_01.json"
);

fn load_str(text: &str) -> Result<City, LoadError> {
    cityjson::load_bytes(Path::new("test.city.json"), text.as_bytes())
}

#[test]
fn den_haag_counts_balance_and_spot_checks() {
    let start = std::time::Instant::now();
    let city = load_city(Path::new(DEN_HAAG), &LoadOptions::default()).unwrap();
    eprintln!("Den Haag loaded in {:?}: {}", start.elapsed(), city.report);
    let r = &city.report;
    assert_eq!(r.buildings_found, 844);
    assert_eq!(r.parts_found, 1653);
    assert!(r.is_balanced());
    assert_eq!(r.buildings_loaded, city.buildings.len());
    // A few degenerate objects may be rejected, but nearly all load.
    assert!(r.buildings_loaded >= 800, "{r}");
    city.check_invariants().unwrap();
    assert_eq!(city.frame.crs, Crs::Projected("EPSG:7415".into()));
    // Origin at the centre of the extent (x 78248.7..79036.0, y 457604.6..458276.4), at the
    // height of the lowest building base (NAP): the city stands on the ground plane z = 0.
    assert!(
        (city.frame.origin[0] - 78642.0).abs() < 2.0,
        "{:?}",
        city.frame.origin
    );
    assert!(
        (city.frame.origin[1] - 457940.0).abs() < 2.0,
        "{:?}",
        city.frame.origin
    );
    let lowest_base = city
        .buildings
        .iter()
        .map(|b| b.base_m)
        .fold(f32::INFINITY, f32::min);
    assert_eq!(lowest_base, 0.0);
    assert!(
        (2.5..5.0).contains(&city.frame.origin[2]),
        "{:?}",
        city.frame.origin
    );

    let triangles: usize = city
        .buildings
        .iter()
        .map(|b| b.mesh.as_ref().map_or(0, |m| m.triangle_count()))
        .sum();
    eprintln!("{triangles} triangles");
    // 21,804 surfaces, most of them quads or larger: at least one triangle each, a few each.
    assert!(
        (21_000..120_000).contains(&triangles),
        "{triangles} triangles"
    );

    let parts: usize = city.buildings.iter().map(|b| b.parts.len()).sum();
    assert!(parts >= 1_900, "{parts} parts");
    let (lo, hi) = city.bounds().unwrap();
    // The data spans about 790 m × 670 m, heights 2.5..37.5 m NAP (README).
    assert!(hi.x - lo.x < 820.0 && hi.y - lo.y < 700.0, "{lo} {hi}");
    assert!(
        lo.z == 0.0 && f64::from(hi.z) + city.frame.origin[2] < 40.0,
        "{lo} {hi}"
    );
    for b in &city.buildings {
        assert_eq!(b.height_source, HeightSource::Geometry);
        assert!(b.footprint.is_valid());
        assert!(
            b.footprint_area_m2() > 1.0,
            "{} {}",
            b.source_id,
            b.footprint_area_m2()
        );
        let mesh = b.mesh.as_ref().unwrap();
        assert!(mesh.triangle_count() >= 4);
        assert!(
            b.height_m() > 1.0 && b.height_m() < 40.0,
            "{} {}",
            b.source_id,
            b.height_m()
        );
        assert!(b.tags.contains_key("roofType") || b.tags.contains_key("cityjson:type"));
    }
    // The parts' footprints cover what the file's own GroundSurfaces cover (computed here
    // independently from the semantics, which the loader does not read).
    let parts_area: f64 = city
        .buildings
        .iter()
        .flat_map(|b| &b.parts)
        .map(|p| p.footprint.unsigned_area())
        .sum();
    let ground = ground_surface_area_m2(DEN_HAAG);
    assert!(ground > 10_000.0);
    assert!(
        (parts_area - ground).abs() < 0.02 * ground,
        "parts {parts_area} m², GroundSurface {ground} m²"
    );
    // Buildings with their own geometry carry the source's AbsoluteRidgeHeight (m NAP): the
    // mesh top should match it.
    let ridges: Vec<(f32, f32)> = city
        .buildings
        .iter()
        .filter_map(|b| {
            let ridge: f32 = b.tags.get("AbsoluteRidgeHeight")?.parse().ok()?;
            // Tops are above the ground plane, the ridge heights absolute (NAP).
            Some((b.top_m + city.frame.origin[2] as f32, ridge))
        })
        .collect();
    assert!(
        ridges.len() >= 300,
        "{} buildings with a ridge height",
        ridges.len()
    );
    let close = ridges
        .iter()
        .filter(|(top, ridge)| (top - ridge).abs() < 0.5)
        .count();
    eprintln!(
        "{close} of {} tops within 0.5 m of AbsoluteRidgeHeight",
        ridges.len()
    );
    assert!(
        close * 10 >= ridges.len() * 9,
        "{close} of {}",
        ridges.len()
    );
    for w in &r.warnings {
        eprintln!("warning: {w}");
    }
}

/// Sum of the projected areas of the GroundSurface faces of Building and BuildingPart solids.
fn ground_surface_area_m2(path: &str) -> f64 {
    let v: serde_json::Value = serde_json::from_slice(&std::fs::read(path).unwrap()).unwrap();
    let scale = &v["transform"]["scale"];
    let (sx, sy) = (scale[0].as_f64().unwrap(), scale[1].as_f64().unwrap());
    let vertices = v["vertices"].as_array().unwrap();
    let xy = |i: &serde_json::Value| {
        let p = &vertices[i.as_u64().unwrap() as usize];
        (p[0].as_f64().unwrap() * sx, p[1].as_f64().unwrap() * sy)
    };
    let ring_area = |ring: &serde_json::Value| {
        let r = ring.as_array().unwrap();
        let mut a = 0.0;
        for k in 0..r.len() {
            let (x1, y1) = xy(&r[k]);
            let (x2, y2) = xy(&r[(k + 1) % r.len()]);
            a += x1 * y2 - x2 * y1;
        }
        (a / 2.0).abs()
    };
    let mut total = 0.0;
    for o in v["CityObjects"].as_object().unwrap().values() {
        if !matches!(o["type"].as_str(), Some("Building" | "BuildingPart")) {
            continue;
        }
        for g in o["geometry"].as_array().into_iter().flatten() {
            let (Some(shells), Some(sem)) = (g["boundaries"].as_array(), g.get("semantics")) else {
                continue;
            };
            for (s, shell) in shells.iter().enumerate() {
                for (f, face) in shell.as_array().unwrap().iter().enumerate() {
                    let Some(k) = sem["values"][s][f].as_u64() else {
                        continue;
                    };
                    if sem["surfaces"][k as usize]["type"] == "GroundSurface" {
                        let rings = face.as_array().unwrap();
                        total += ring_area(&rings[0]);
                        total -= rings[1..].iter().map(ring_area).sum::<f64>();
                    }
                }
            }
        }
    }
    total
}

/// A 10 × 10 × 10 m cube as a Solid with integer vertices in millimetres.
fn cube_1_1() -> String {
    r#"{"type":"CityJSON","version":"1.1",
        "transform":{"scale":[0.001,0.001,0.001],"translate":[1000.0,2000.0,5.0]},
        "metadata":{"referenceSystem":"https://www.opengis.net/def/crs/EPSG/0/7415"},
        "CityObjects":{"cube":{"type":"Building","attributes":{"name":"Cube","storeys":3},
          "geometry":[{"type":"Solid","lod":"2.2","boundaries":[[
            [[0,3,2,1]],[[4,5,6,7]],[[0,1,5,4]],[[1,2,6,5]],[[2,3,7,6]],[[3,0,4,7]]]]}]}},
        "vertices":[[0,0,0],[10000,0,0],[10000,10000,0],[0,10000,0],
                    [0,0,10000],[10000,0,10000],[10000,10000,10000],[0,10000,10000]]}"#
        .to_string()
}

#[test]
fn cube_solid_with_transform() {
    let city = load_str(&cube_1_1()).unwrap();
    assert_eq!(city.buildings.len(), 1);
    let b = &city.buildings[0];
    assert_eq!(b.source_id, "cube");
    assert!(
        (b.footprint_area_m2() - 100.0).abs() < 1e-6,
        "{}",
        b.footprint_area_m2()
    );
    // Translate z 5 m: the base (5 m in the source) rests on the ground, the origin keeps 5 m.
    assert_eq!((b.base_m, b.top_m), (0.0, 10.0));
    assert_eq!(b.tags.get("name"), Some("Cube"));
    assert_eq!(b.tags.get("storeys"), Some("3"));
    assert_eq!(b.mesh.as_ref().unwrap().triangle_count(), 12);
    assert_eq!(city.frame.crs, Crs::Projected("EPSG:7415".into()));
    // Origin at the centre of the extent: the cube spans 1000..1010, 2000..2010.
    assert_eq!(city.frame.origin, [1005.0, 2005.0, 5.0]);
    // Source coordinates are unchanged: the top corner maps back to the file's (1010, 2010, 15).
    let top = city.frame.to_source(glam::DVec3::new(5.0, 5.0, 10.0));
    assert_eq!(top, glam::DVec3::new(1010.0, 2010.0, 15.0));
    let f = &b.footprint;
    assert!(f.contains(&Point::new(0.0, 0.0)) && !f.contains(&Point::new(6.0, 0.0)));
    // Every triangle faces out of the cube.
    let mesh = b.mesh.as_ref().unwrap();
    for [a, b2, c] in mesh.triangles() {
        let n = (b2 - a).cross(c - a);
        let centre = (a + b2 + c) / 3.0 - glam::Vec3::new(0.0, 0.0, 5.0);
        assert!(n.dot(centre) > 0.0, "inward triangle {a} {b2} {c}");
    }
}

#[test]
fn multisurface_lod1_block_2_0_picks_highest_lod() {
    // An LoD1 box 20 × 6 × 12 m and an LoD0 footprint; the LoD1 MultiSurface is used.
    let text = r#"{"type":"CityJSON","version":"2.0",
        "transform":{"scale":[0.01,0.01,0.01],"translate":[0,0,0]},
        "CityObjects":{"block":{"type":"Building","geometry":[
          {"type":"MultiSurface","lod":"0","boundaries":[[[0,1,2,3]]]},
          {"type":"MultiSurface","lod":"1","boundaries":[
            [[0,3,2,1]],[[4,5,6,7]],[[0,1,5,4]],[[1,2,6,5]],[[2,3,7,6]],[[3,0,4,7]]]}]}},
        "vertices":[[0,0,0],[2000,0,0],[2000,600,0],[0,600,0],
                    [0,0,1200],[2000,0,1200],[2000,600,1200],[0,600,1200]]}"#;
    let city = load_str(text).unwrap();
    let b = &city.buildings[0];
    assert!((b.footprint_area_m2() - 120.0).abs() < 1e-6);
    assert_eq!((b.base_m, b.top_m), (0.0, 12.0));
    assert_eq!(city.frame.crs, Crs::Local);
    assert_eq!(b.parts.len(), 1);
    assert_eq!(b.parts[0].source_id, "block");
}

#[test]
fn building_with_two_parts() {
    // A 10 × 10 m part 0..6 m and a 10 × 5 m part on its east side 0..15 m.
    let text = r#"{"type":"CityJSON","version":"2.0",
        "transform":{"scale":[1,1,1],"translate":[0,0,0]},
        "CityObjects":{
          "b":{"type":"Building","children":["p1","p2"],"attributes":{"function":"office"}},
          "p1":{"type":"BuildingPart","parents":["b"],"geometry":[{"type":"Solid","lod":"1.2",
            "boundaries":[[[[0,3,2,1]],[[4,5,6,7]],[[0,1,5,4]],[[1,2,6,5]],[[2,3,7,6]],[[3,0,4,7]]]]}]},
          "p2":{"type":"BuildingPart","parents":["b"],"geometry":[{"type":"MultiSolid","lod":"1",
            "boundaries":[[[[[8,11,10,9]],[[12,13,14,15]],[[8,9,13,12]],[[9,10,14,13]],[[10,11,15,14]],[[11,8,12,15]]]]]}]}},
        "vertices":[[0,0,0],[10,0,0],[10,10,0],[0,10,0],[0,0,6],[10,0,6],[10,10,6],[0,10,6],
                    [10,0,0],[15,0,0],[15,10,0],[10,10,0],[10,0,15],[15,0,15],[15,10,15],[10,10,15]]}"#;
    let city = load_str(text).unwrap();
    assert_eq!(city.report.buildings_found, 1);
    assert_eq!(city.report.parts_found, 2);
    let b = &city.buildings[0];
    assert_eq!(b.parts.len(), 2);
    let p1 = b.parts.iter().find(|p| p.source_id == "p1").unwrap();
    let p2 = b.parts.iter().find(|p| p.source_id == "p2").unwrap();
    assert!((p1.footprint.unsigned_area() - 100.0).abs() < 1e-6);
    assert!((p2.footprint.unsigned_area() - 50.0).abs() < 1e-6);
    assert_eq!((p1.base_m, p1.top_m), (0.0, 6.0));
    assert_eq!((p2.base_m, p2.top_m), (0.0, 15.0));
    assert_eq!((b.base_m, b.top_m), (0.0, 15.0));
    // The union of the two parts is one 15 × 10 rectangle.
    assert_eq!(b.footprint.0.len(), 1);
    assert!((b.footprint_area_m2() - 150.0).abs() < 1e-6);
    assert_eq!(b.mesh.as_ref().unwrap().triangle_count(), 24);
    assert_eq!(b.tags.get("function"), Some("office"));
    city.check_invariants().unwrap();
}

#[test]
fn cityjson_1_0_without_transform_and_numeric_lod() {
    let text = r#"{"type":"CityJSON","version":"1.0",
        "metadata":{"referenceSystem":"urn:ogc:def:crs:EPSG::28992"},
        "CityObjects":{"x":{"type":"Building","geometry":[{"type":"MultiSurface","lod":1,
          "boundaries":[[[0,3,2,1]],[[4,5,6,7]],[[0,1,5,4]],[[1,2,6,5]],[[2,3,7,6]],[[3,0,4,7]]]}]},
          "t":{"type":"TINRelief","geometry":[]}},
        "vertices":[[0.5,0.5,1],[4.5,0.5,1],[4.5,3.5,1],[0.5,3.5,1],
                    [0.5,0.5,8],[4.5,0.5,8],[4.5,3.5,8],[0.5,3.5,8]]}"#;
    let city = load_str(text).unwrap();
    assert_eq!(city.report.buildings_found, 1);
    assert_eq!(city.frame.crs, Crs::Projected("EPSG:28992".into()));
    let b = &city.buildings[0];
    assert!((b.footprint_area_m2() - 12.0).abs() < 1e-6);
    assert_eq!((b.base_m, b.top_m), (0.0, 7.0));
    assert_eq!(city.frame.origin[2], 1.0);
}

fn expect_error(text: &str, needle: &str) {
    match load_str(text) {
        Err(e) => {
            let msg = e.to_string();
            assert!(msg.contains("test.city.json"), "{msg}");
            assert!(msg.contains(needle), "{msg} lacks {needle}");
        }
        Ok(city) => panic!("loaded ({needle}): {}", city.report),
    }
}

#[test]
fn bad_files_are_errors_naming_file_and_problem() {
    expect_error("{not json", "invalid JSON");
    expect_error(r#"{"type":"FeatureCollection"}"#, "CityJSON");
    expect_error(
        &cube_1_1().replace(r#""version":"1.1""#, r#""version":"3.0""#),
        "version",
    );
    expect_error(
        &cube_1_1().replace(
            r#""transform":{"scale":[0.001,0.001,0.001],"translate":[1000.0,2000.0,5.0]},"#,
            "",
        ),
        "transform",
    );
    // A file whose only building is broken loads nothing, naming that building's problem.
    expect_error(
        &cube_1_1().replace("[3,0,4,7]", "[3,0,4,70]"),
        "cube: vertex index 70 is not an index",
    );
    expect_error(
        &cube_1_1().replace("[3,0,4,7]", "[3,0,4,-7]"),
        "vertex index -7 is not an index",
    );
    expect_error(
        &cube_1_1().replace("[0,10000,10000]]", "[0,10000]]"),
        "vertex 7",
    );
    let broken = cube_1_1().replace("[[0,3,2,1]]", "0");
    assert_ne!(broken, cube_1_1());
    expect_error(&broken, "not an array");
    expect_error(
        r#"{"type":"CityJSON","version":"2.0","transform":{"scale":[1,1,1],"translate":[0,0,0]},
            "CityObjects":{},"vertices":[]}"#,
        "no building",
    );
}

#[test]
fn bad_buildings_are_rejected_and_the_rest_load() {
    // Three buildings: the cube, a flat (zero-volume, zero-area) one and one far away.
    let text = r#"{"type":"CityJSON","version":"2.0",
        "transform":{"scale":[1,1,1],"translate":[0,0,0]},
        "CityObjects":{
          "good":{"type":"Building","geometry":[{"type":"Solid","lod":"2","boundaries":[[
            [[0,3,2,1]],[[4,5,6,7]],[[0,1,5,4]],[[1,2,6,5]],[[2,3,7,6]],[[3,0,4,7]]]]}]},
          "flat":{"type":"Building","geometry":[{"type":"MultiSurface","lod":"1",
            "boundaries":[[[0,1,5,4]],[[1,2,6,5]]]}]},
          "tall":{"type":"Building","geometry":[{"type":"MultiSurface","lod":"1",
            "boundaries":[[[0,1,2,3]],[[8,9,10]]]}]},
          "far":{"type":"Building","geometry":[{"type":"MultiSurface","lod":"1",
            "boundaries":[[[11,12,13]]]}]},
          "none":{"type":"Building","geometry":[{"type":"MultiPoint","lod":"1","boundaries":[0]}]}},
        "vertices":[[0,0,0],[10,0,0],[10,10,0],[0,10,0],[0,0,10],[10,0,10],[10,10,10],[0,10,10],
          [0,0,5000],[10,0,5000],[10,10,5000],
          [900000,0,0],[900010,0,0],[900010,10,0]]}"#;
    let city = load_str(text).unwrap();
    let r = &city.report;
    assert_eq!(r.buildings_found, 5);
    assert!(r.is_balanced());
    assert_eq!(city.buildings.len(), 1);
    assert_eq!(city.buildings[0].source_id, "good");
    let reason = |id: &str| {
        r.rejected
            .iter()
            .find(|x| x.source_id == id)
            .map(|x| x.reason.clone())
            .unwrap()
    };
    assert_eq!(reason("flat"), RejectReason::ZeroArea);
    assert!(matches!(reason("tall"), RejectReason::AbsurdHeight(_)));
    assert!(matches!(
        reason("far"),
        RejectReason::CoordinateOutOfRange(_)
    ));
    assert!(matches!(reason("none"), RejectReason::MissingGeometry(_)));
    assert!(
        r.rejected
            .iter()
            .all(|x| x.file == Path::new("test.city.json"))
    );
}

#[test]
fn non_finite_vertex_is_a_rejection() {
    // A scale this large overflows one vertex to infinity.
    let text = cube_1_1()
        .replace(
            r#""scale":[0.001,0.001,0.001]"#,
            r#""scale":[1e305,0.001,0.001]"#,
        )
        .replace("[10000,10000,10000]", "[10000000,10000,10000]");
    let err_or_city = load_str(&text);
    match err_or_city {
        Err(LoadError::NothingLoaded { first, .. }) => {
            assert!(
                first.contains("non-finite") || first.contains("out of range"),
                "{first}"
            )
        }
        other => panic!("{other:?}"),
    }
}

/// Mutations of a small valid file: truncation, byte flips and number replacement never
/// panic, and a successful load is balanced.
#[test]
fn mutated_files_never_panic() {
    let base = cube_1_1().into_bytes();
    let mut runner = fixed_runner(300, 7);
    let len = base.len();
    let strategy = (
        0..len,
        prop::collection::vec((0..len, any::<u8>()), 0..4),
        prop::collection::vec((0..len, -1e12f64..1e12), 0..3),
    );
    runner
        .run(&strategy, |(cut, flips, numbers)| {
            let bytes = mutated(&base, cut, &flips, &numbers);
            if let Ok(city) = cityjson::load_bytes(Path::new("m.json"), &bytes) {
                prop_assert!(city.report.is_balanced());
                prop_assert!(city.check_invariants().is_ok());
            }
            Ok(())
        })
        .unwrap();
}

/// Issue 14 case 7: one CityObject with a vertex index out of range (or -1, 1.5, a string
/// boundary) made the whole file invalid. The other objects load; each bad one is rejected with
/// its id and the reason; a bad `BuildingPart` drops only that part of its building.
#[test]
fn one_bad_object_is_rejected_and_the_others_load() {
    let cube = |id: &str, first: &str| {
        format!(
            r#""{id}":{{"type":"Building","geometry":[{{"type":"Solid","lod":"2","boundaries":[[
            [{first}],[[4,5,6,7]],[[0,1,5,4]],[[1,2,6,5]],[[2,3,7,6]],[[3,0,4,7]]]]}}]}}"#
        )
    };
    let objects = [
        cube("good", "[0,3,2,1]"),
        cube("beyond", "[0,3,2,99]"),
        cube("minus", "[0,3,2,-1]"),
        cube("half", "[0,3,2,1.5]"),
        cube("text", r#"[0,3,2,"1"]"#),
        cube("string", r#""[0,3,2,1]""#),
        r#""whole":{"type":"Building","geometry":[{"type":"Solid","lod":"2","boundaries":"x"}]}"#
            .to_string(),
        r#""house":{"type":"Building","children":["p1","p2"]},
        "p2":{"type":"BuildingPart","parents":["house"],"geometry":[{"type":"MultiSurface",
          "lod":"1","boundaries":[[[0,1,2,1e9]]]}]}"#
            .to_string(),
        cube("p1", "[0,3,2,1]").replace(r#""type":"Building""#, r#""type":"BuildingPart""#),
    ];
    let text = format!(
        r#"{{"type":"CityJSON","version":"2.0",
        "transform":{{"scale":[1,1,1],"translate":[0,0,0]}},"CityObjects":{{{}}},
        "vertices":[[0,0,0],[10,0,0],[10,10,0],[0,10,0],[0,0,10],[10,0,10],[10,10,10],[0,10,10]]}}"#,
        objects.join(",")
    );
    let city = load_str(&text).unwrap();
    let r = &city.report;
    assert_eq!((r.buildings_found, r.buildings_loaded), (8, 2), "{r}");
    assert!(r.is_balanced());
    let loaded: Vec<&str> = city
        .buildings
        .iter()
        .map(|b| b.source_id.as_str())
        .collect();
    assert_eq!(loaded, ["good", "house"]);
    for (id, needle) in [
        (
            "beyond",
            "vertex index 99 is not an index of the 8 vertices",
        ),
        ("minus", "vertex index -1"),
        ("half", "vertex index 1.5"),
        ("text", "vertex index \"1\""),
        ("string", "is not an array"),
        ("whole", "is not an array"),
    ] {
        let x = r.rejected.iter().find(|x| x.source_id == id).expect(id);
        assert!(
            matches!(&x.reason, RejectReason::InvalidGeometry(m) if m.contains(id) && m.contains(needle)),
            "{x}"
        );
    }
    // The house keeps its good part; the bad one is a warning naming it.
    assert_eq!(city.buildings[1].parts.len(), 1);
    assert!(
        r.warnings
            .iter()
            .any(|w| w.source_id == "p2" && w.message.contains("vertex index 1000000000")),
        "{:?}",
        r.warnings
    );
    city.check_invariants().unwrap();
}

/// Issue 14: a UTF-8 byte order mark before a CityJSON gave "expected value at line 1 column 1".
#[test]
fn issue14_small_cityjson_with_bom_loads() {
    let bytes = [b"\xEF\xBB\xBF".as_slice(), cube_1_1().as_bytes()].concat();
    let city = cityjson::load_bytes(Path::new("bom.city.json"), &bytes).unwrap();
    assert_eq!(city.buildings.len(), 1);
    // As `.json`, detected by content and loaded from a file.
    let dir = tempfile::tempdir().unwrap();
    let path = dir.path().join("bom.json");
    std::fs::write(&path, &bytes).unwrap();
    let city = load_city(&path, &LoadOptions::default()).unwrap();
    assert_eq!(city.buildings.len(), 1);
}

/// Issue 14: `"version": 1.1` (a number) said `no "version"`; the version must be a string, and
/// the error says so and what it found.
#[test]
fn issue14_small_cityjson_numeric_version_says_it_must_be_a_string() {
    let numeric = cube_1_1().replace(r#""version":"1.1""#, r#""version":1.1"#);
    assert_ne!(numeric, cube_1_1());
    expect_error(&numeric, "must be a string");
    expect_error(&numeric, "found the number 1.1");
    let array = cube_1_1().replace(r#""version":"1.1""#, r#""version":[1,1]"#);
    expect_error(&array, "found an array [1,1]");
    // Still: no version at all is named as such.
    let missing = cube_1_1().replace(r#""version":"1.1","#, "");
    expect_error(&missing, "no \"version\"");
}
