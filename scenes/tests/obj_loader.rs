//! OBJ loader: a 3dfier-style file written here (buildings, terrain, road, water in RD New
//! coordinates), the options (CRS, up axis, markers), malformed files and a mutation property
//! test.

use std::fmt::Write as _;
use std::path::Path;

use citywalk_scenes::load::UpAxis;
use citywalk_scenes::load::obj;
use citywalk_scenes::{City, Crs, GroundClass, LoadError, LoadOptions, RejectReason, load_city};
use fuzz::fixed_runner;
use mutate::mutated;
use proptest::prelude::*;

#[path = "support/files.rs"]
#[expect(dead_code, reason = "this test uses temp_file only")]
mod files;
#[path = "support/fuzz.rs"]
mod fuzz;
#[path = "support/mutate.rs"]
mod mutate;

/// RD New coordinates of the Hague's centre, NAP heights: large absolute values as 3dfier
/// writes them.
const X0: f64 = 81_000.0;
const Y0: f64 = 455_000.0;

/// Appends a closed box (8 vertices, 6 quads) as object `name` with `material`; `v` counts the
/// vertices written so far (OBJ indices are file-global).
fn push_box(
    text: &mut String,
    v: &mut usize,
    name: &str,
    material: &str,
    (x, y): (f64, f64),
    (w, d): (f64, f64),
    (z0, z1): (f64, f64),
) {
    writeln!(text, "o {name}").unwrap();
    writeln!(text, "usemtl {material}").unwrap();
    for z in [z0, z1] {
        for (dx, dy) in [(0.0, 0.0), (w, 0.0), (w, d), (0.0, d)] {
            writeln!(text, "v {:.3} {:.3} {:.3}", X0 + x + dx, Y0 + y + dy, z).unwrap();
        }
    }
    let b = *v + 1;
    let faces = [
        [0, 3, 2, 1],
        [4, 5, 6, 7],
        [0, 1, 5, 4],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 0, 4, 7],
    ];
    for f in faces {
        writeln!(
            text,
            "f {} {} {} {}",
            b + f[0],
            b + f[1],
            b + f[2],
            b + f[3]
        )
        .unwrap();
    }
    *v += 8;
}

/// Appends a flat quad (terrain, road, water) as object `name` with `material`.
fn push_ground(text: &mut String, v: &mut usize, name: &str, material: &str, size: f64) {
    writeln!(text, "o {name}").unwrap();
    writeln!(text, "usemtl {material}").unwrap();
    for (x, y) in [(-size, -size), (size, -size), (size, size), (-size, size)] {
        writeln!(text, "v {:.3} {:.3} 1.000", X0 + x, Y0 + y).unwrap();
    }
    // Negative (relative) indices, as some writers use.
    writeln!(text, "f -4/1/1 -3/2/1 -2/3/1 -1/4/1").unwrap();
    *v += 4;
}

/// Four buildings of known size, terrain, two roads and water.
fn city_obj() -> String {
    let mut t = String::from("# written by the citywalk OBJ test\nmtllib ./3dfier.mtl\n");
    let mut v = 0;
    push_ground(&mut t, &mut v, "t1", "Terrain", 100.0);
    push_box(
        &mut t,
        &mut v,
        "b1",
        "Building",
        (0.0, 0.0),
        (10.0, 8.0),
        (1.0, 13.0),
    );
    push_box(
        &mut t,
        &mut v,
        "b2",
        "Building",
        (20.0, 0.0),
        (12.0, 12.0),
        (1.0, 7.0),
    );
    push_ground(&mut t, &mut v, "r1", "Road", 5.0);
    push_box(
        &mut t,
        &mut v,
        "b3",
        "BuildingRoof",
        (0.0, 30.0),
        (6.0, 6.0),
        (1.5, 21.5),
    );
    push_ground(&mut t, &mut v, "r2", "Road", 4.0);
    push_box(
        &mut t,
        &mut v,
        "b4",
        "Building",
        (-40.0, -40.0),
        (20.0, 5.0),
        (1.0, 4.0),
    );
    push_ground(&mut t, &mut v, "w1", "Water", 50.0);
    t
}

fn load_text(text: &str, options: &LoadOptions) -> Result<City, LoadError> {
    obj::load_reader(Path::new("test.obj"), text.as_bytes(), options)
}

#[test]
fn a_3dfier_style_file_loads_its_buildings_and_reports_the_rest() {
    let path = files::temp_file("city.obj", city_obj().as_bytes());
    let options = LoadOptions {
        source_crs: Some("EPSG:7415".into()),
        ..LoadOptions::default()
    };
    let city = load_city(&path, &options).unwrap();
    let r = &city.report;
    assert_eq!(r.buildings_found, 4, "{r}");
    assert_eq!(r.buildings_loaded, 4, "{r}");
    assert!(r.is_balanced());
    city.check_invariants().unwrap();
    assert_eq!(city.frame.crs, Crs::Projected("EPSG:7415".into()));
    // The large absolute coordinates went into the origin (centre of the xy extent, lowest
    // building base): local coordinates are small.
    assert!(
        (city.frame.origin[0] - X0).abs() < 101.0,
        "{:?}",
        city.frame.origin
    );
    assert!(
        (city.frame.origin[1] - Y0).abs() < 101.0,
        "{:?}",
        city.frame.origin
    );
    assert_eq!(city.frame.origin[2], 1.0);
    let by_id = |id: &str| city.buildings.iter().find(|b| b.source_id == id).unwrap();
    for (id, area, height, base) in [
        ("b1", 80.0, 12.0, 0.0),
        ("b2", 144.0, 6.0, 0.0),
        ("b3", 36.0, 20.0, 0.5),
        ("b4", 100.0, 3.0, 0.0),
    ] {
        let b = by_id(id);
        assert!(
            (b.footprint_area_m2() - area).abs() < 0.01,
            "{id} {}",
            b.footprint_area_m2()
        );
        assert!(
            (b.height_m() - height).abs() < 1e-3,
            "{id} {}",
            b.height_m()
        );
        assert!((b.base_m - base).abs() < 1e-3, "{id} {}", b.base_m);
        assert_eq!(b.mesh.as_ref().unwrap().triangle_count(), 12, "{id}");
    }
    assert_eq!(by_id("b3").tags.get("obj:material"), Some("BuildingRoof"));
    // Back to the file's coordinates through the frame.
    let b1 = by_id("b1");
    let lo = b1.mesh.as_ref().unwrap().bounds().unwrap().0;
    let source = city.frame.to_source(lo.as_dvec3());
    assert!(
        (source.x - X0).abs() < 1e-2 && (source.y - Y0).abs() < 1e-2,
        "{source}"
    );
    assert!((source.z - 1.0).abs() < 1e-3, "{source}");
    // The other objects are ground areas of their 3dfier class, in the same frame: each quad
    // is centred on (X0, Y0), 2 × its half size wide.
    use geo::Area;
    let expected = [
        ("t1", GroundClass::Other, 40_000.0),
        ("r1", GroundClass::Paved, 100.0),
        ("r2", GroundClass::Paved, 64.0),
        ("w1", GroundClass::Water, 10_000.0),
    ];
    assert_eq!(city.ground_areas.len(), expected.len());
    for (g, (id, class, area_m2)) in city.ground_areas.iter().zip(expected) {
        assert_eq!((g.source_id.as_str(), g.class), (id, class));
        let got = g.polygon.unsigned_area();
        assert!((got - area_m2).abs() < 1e-6 * area_m2, "{id}: {got} m²");
    }
    assert_eq!((r.ground_areas_found, r.ground_areas_loaded), (4, 4), "{r}");
    let water = city.ground_areas[3].polygon.0[0].exterior().0[0];
    let source = city
        .frame
        .to_source(glam::DVec3::new(water.x, water.y, 0.0));
    assert!(
        ((source.x - X0).abs() - 50.0).abs() < 1e-3 && ((source.y - Y0).abs() - 50.0).abs() < 1e-3,
        "{source}"
    );
    assert!(r.warnings.is_empty(), "{:?}", r.warnings);
}

/// Issue 16: every non-building object is a ground area, its class from its name, group or
/// material (3dfier classes; unknown ones are `Other`), its polygon its plan; one that cannot
/// be used (a broken face, walls only) is rejected with its name.
#[test]
fn other_objects_are_ground_areas_by_class() {
    let mut t = city_obj();
    let mut v = t.lines().filter(|l| l.starts_with("v ")).count();
    push_ground(&mut t, &mut v, "f1", "Forest", 10.0);
    push_ground(&mut t, &mut v, "bridge_7", "Concrete", 3.0);
    push_ground(&mut t, &mut v, "x1", "Mystery", 2.0);
    // Walls only: a box's four sides.
    t.push_str("o wall\nusemtl Separation\n");
    for (x, z) in [(0.0, 0.0), (5.0, 0.0), (5.0, 3.0), (0.0, 3.0)] {
        writeln!(t, "v {} {} {}", X0 + x, Y0 + 200.0, z).unwrap();
    }
    t.push_str("f -4 -3 -2 -1\n");
    // A broken face.
    t.push_str("o canal\nusemtl Water\nf 1 2 0\n");
    let city = load_text(&t, &LoadOptions::default()).unwrap();
    let r = &city.report;
    assert!(r.is_balanced(), "{r}");
    city.check_invariants().unwrap();
    let class = |id: &str| {
        city.ground_areas
            .iter()
            .find(|g| g.source_id == id)
            .map(|g| g.class)
    };
    assert_eq!(class("f1"), Some(GroundClass::Forest));
    assert_eq!(class("bridge_7"), Some(GroundClass::Paved));
    assert_eq!(class("x1"), Some(GroundClass::Other));
    assert_eq!((r.ground_areas_found, r.ground_areas_loaded), (9, 7), "{r}");
    let rejected: Vec<(&str, &RejectReason)> = r
        .ground_areas_rejected
        .iter()
        .map(|x| (x.source_id.as_str(), &x.reason))
        .collect();
    assert_eq!(rejected[0], ("wall", &RejectReason::ZeroArea));
    assert_eq!(rejected[1].0, "canal");
    assert!(
        matches!(rejected[1].1, RejectReason::InvalidGeometry(m) if m.contains("index 0")),
        "{rejected:?}"
    );
}

#[test]
fn the_default_frame_is_local_and_y_up_is_turned() {
    let city = load_text(&city_obj(), &LoadOptions::default()).unwrap();
    assert_eq!(city.frame.crs, Crs::Local);
    // The same city written y-up (file y = up, file z = south) and read with `UpAxis::Y`.
    let mut turned = String::new();
    for line in city_obj().lines() {
        match line.strip_prefix("v ") {
            Some(rest) => {
                let p: Vec<f64> = rest.split(' ').map(|s| s.parse().unwrap()).collect();
                writeln!(turned, "v {} {} {}", p[0], p[2], -p[1]).unwrap();
            }
            None => writeln!(turned, "{line}").unwrap(),
        }
    }
    let y_up = LoadOptions {
        up_axis: UpAxis::Y,
        ..LoadOptions::default()
    };
    let turned_city = load_text(&turned, &y_up).unwrap();
    assert_eq!(turned_city.buildings.len(), 4);
    for (a, b) in city.buildings.iter().zip(&turned_city.buildings) {
        assert_eq!(a.source_id, b.source_id);
        assert!((a.height_m() - b.height_m()).abs() < 1e-3);
        assert!((a.footprint_area_m2() - b.footprint_area_m2()).abs() < 1e-2);
    }
    // Read with the wrong axis, b1 (10 × 8 m, 12 m tall) stands on its side: 8 m "tall".
    let wrong = load_text(&turned, &LoadOptions::default()).unwrap();
    let b1 = wrong
        .buildings
        .iter()
        .find(|b| b.source_id == "b1")
        .unwrap();
    assert!((b1.height_m() - 8.0).abs() < 1e-3, "{}", b1.height_m());
}

#[test]
fn markers_choose_the_buildings() {
    let options = LoadOptions {
        obj_building_markers: vec!["ROAD".into()],
        ..LoadOptions::default()
    };
    // Roads are flat: both are found as buildings and rejected for their zero height, and the
    // load fails as nothing is left.
    match load_text(&city_obj(), &options) {
        Err(LoadError::NothingLoaded { found, .. }) => assert_eq!(found, 2),
        other => panic!("{other:?}"),
    }
    // Groups mark buildings in a file without objects.
    let text = "v 0 0 0\nv 4 0 0\nv 4 4 0\nv 0 4 0\nv 0 0 5\nv 4 0 5\nv 4 4 5\nv 0 4 5\n\
                g house_1\nf 1 4 3 2\nf 5 6 7 8\nf 1 2 6 5\nf 2 3 7 6\nf 3 4 8 7\nf 4 1 5 8\n";
    let options = LoadOptions {
        obj_building_markers: vec!["house".into()],
        ..LoadOptions::default()
    };
    let city = load_text(text, &options).unwrap();
    assert_eq!(city.buildings.len(), 1);
    assert_eq!(city.buildings[0].source_id, "house_1");
    assert!((city.buildings[0].height_m() - 5.0).abs() < 1e-4);
    // With the default marker the same file has no building: the error says what it found.
    let err = load_text(text, &LoadOptions::default())
        .unwrap_err()
        .to_string();
    assert!(
        err.contains("no object marked as a building") && err.contains("1 other"),
        "{err}"
    );
}

/// Each kind of bad face or vertex spoils only its object, which is rejected with the line. The
/// bad lines come at the end of the file, in object b2 entered again (so that no index of the
/// other objects moves).
#[test]
fn bad_faces_and_vertices_reject_their_object_with_its_line() {
    let good = city_obj();
    let cases: [(&str, &str, &str); 8] = [
        (
            "f 1 2 99999",
            "not one of the file's",
            "index past the last vertex",
        ),
        ("f 1 2 99999999999", "is too large", "huge index"),
        ("f 1 0 2", "index 0", "zero index"),
        (
            "f -1000 1 2",
            "refers before the first vertex",
            "negative beyond start",
        ),
        ("f 1 2 x", "is not a vertex index", "not a number"),
        ("f 1 2", "a face of 2 corner(s)", "too few corners"),
        ("v nan 0 0\nf -1 1 2", "is not finite", "NaN vertex"),
        ("v 1 2 inf\nf -1 1 2", "is not finite", "infinite vertex"),
    ];
    for (bad, expected, what) in cases {
        let text = format!("{good}o b2\n{bad}\n");
        let bad_line = good.lines().count() + 1 + bad.lines().count();
        let city = load_text(&text, &LoadOptions::default()).unwrap();
        let r = &city.report;
        assert!(r.is_balanced(), "{what}");
        assert_eq!(
            (r.buildings_found, r.buildings_loaded),
            (4, 3),
            "{what}: {r}"
        );
        let rejection = &r.rejected[0];
        assert_eq!(rejection.source_id, "b2", "{what}");
        assert_eq!(rejection.file, Path::new("test.obj"));
        let RejectReason::InvalidGeometry(reason) = &rejection.reason else {
            panic!("{what}: {:?}", rejection.reason);
        };
        assert!(reason.contains(expected), "{what}: {reason}");
        assert!(
            reason.starts_with(&format!("line {bad_line}:")),
            "{what}: {reason}"
        );
    }
}

#[test]
fn unreadable_lines_are_warnings_with_their_line() {
    let mut text = city_obj();
    text.push_str("v 1 2\nbogus statement\n");
    text.push_str(&"x".repeat(obj::MAX_LINE_BYTES + 1));
    text.push('\n');
    let lines = city_obj().lines().count();
    let city = load_text(&text, &LoadOptions::default()).unwrap();
    let messages: Vec<&str> = city
        .report
        .warnings
        .iter()
        .map(|w| w.message.as_str())
        .collect();
    assert!(
        messages.contains(&format!("line {}: vertex is not three numbers", lines + 1).as_str()),
        "{messages:?}"
    );
    assert!(
        messages
            .iter()
            .any(|m| m.starts_with(&format!("line {}: unknown statement", lines + 2))),
        "{messages:?}"
    );
    assert!(
        messages
            .iter()
            .any(|m| m.starts_with(&format!("line {}: longer than", lines + 3))),
        "{messages:?}"
    );
    assert_eq!(city.buildings.len(), 4);
    // Many bad lines: a bounded list and a count of the rest.
    let mut text = city_obj();
    for _ in 0..1000 {
        text.push_str("junk\n");
    }
    let city = load_text(&text, &LoadOptions::default()).unwrap();
    let r = &city.report;
    assert!(r.warnings.len() < 40, "{}", r.warnings.len());
    assert!(
        r.warnings
            .iter()
            .any(|w| w.message == "968 more unreadable lines not listed")
    );
}

#[test]
fn files_without_buildings_are_errors() {
    for text in [
        "",
        "# nothing\n",
        "v 1 2 3\n",
        "o t\nusemtl Terrain\nv 0 0 0\nv 1 0 0\nv 0 1 0\nf 1 2 3\n",
    ] {
        let err = load_text(text, &LoadOptions::default()).unwrap_err();
        assert!(
            matches!(err, LoadError::Malformed { format: "OBJ", .. }),
            "{err}"
        );
        assert!(err.to_string().contains("test.obj"), "{err}");
    }
}

/// Mutations of a valid file (truncation, byte flips, numbers replaced by huge, negative or
/// fractional ones) never panic; a successful load is balanced and sound.
#[test]
fn mutated_files_never_panic() {
    let base = city_obj().into_bytes();
    let mut runner = fixed_runner(200, 11);
    let len = base.len();
    let strategy = (
        0..len,
        prop::collection::vec((0..len, any::<u8>()), 0..6),
        prop::collection::vec(
            (
                0..len,
                prop_oneof![
                    -1e12f64..1e12,
                    Just(f64::NAN),
                    Just(-1.0),
                    Just(0.0),
                    Just(4e9)
                ],
            ),
            0..4,
        ),
    );
    runner
        .run(&strategy, |(cut, flips, numbers)| {
            let bytes = mutated(&base, cut, &flips, &numbers);
            if let Ok(city) = obj::load_reader(
                Path::new("m.obj"),
                bytes.as_slice(),
                &LoadOptions::default(),
            ) {
                prop_assert!(city.report.is_balanced());
                // Eight `o` statements, and faces whose `o` line was spoiled.
                prop_assert!(city.report.buildings_found <= 9);
                prop_assert!(city.check_invariants().is_ok());
            }
            Ok(())
        })
        .unwrap();
}
