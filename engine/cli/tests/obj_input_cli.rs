//! OBJ input on the command line (issue 16): `--up`, `--crs` and `--obj-building-marker` reach
//! the loader, the package records them, and options that cannot apply are refused. CPU only.

use std::path::Path;
use std::process::Output;

use citywalk_scenes::package::ScenePackage;

#[path = "support/run_cli.rs"]
mod run_cli;
#[path = "support/scratch.rs"]
mod scratch;
use run_cli::{citywalk, path_str, text};
use scratch::temp_dir;

fn json(out: &Output) -> serde_json::Value {
    assert!(out.status.success(), "{}", text(out));
    serde_json::from_slice(&out.stdout).expect("JSON on stdout")
}

/// An OBJ object `name` using material `material`: a box from `lo` to `hi` given as
/// (east, north, up), written y-up (file x = east, y = up, z = south) with outward faces.
/// `first` is the 1-based index of its first vertex.
fn y_up_box(name: &str, material: &str, lo: [f64; 3], hi: [f64; 3], first: usize) -> String {
    let mut s = format!("o {name}\nusemtl {material}\n");
    for (up, north, east) in [
        (false, false, false),
        (false, false, true),
        (false, true, true),
        (false, true, false),
        (true, false, false),
        (true, false, true),
        (true, true, true),
        (true, true, false),
    ] {
        let pick = |k: usize, high: bool| if high { hi[k] } else { lo[k] };
        let (e, n, u) = (pick(0, east), pick(1, north), pick(2, up));
        s.push_str(&format!("v {e} {u} {}\n", -n));
    }
    for face in [
        [1, 4, 3, 2],
        [5, 6, 7, 8],
        [1, 2, 6, 5],
        [2, 3, 7, 6],
        [3, 4, 8, 7],
        [4, 1, 5, 8],
    ] {
        let corners: Vec<String> = face.iter().map(|i| (i + first - 1).to_string()).collect();
        s.push_str(&format!("f {}\n", corners.join(" ")));
    }
    s
}

/// Two buildings (10 × 20 × 12 m and 6 × 6 × 25 m, both with their south side on north = 0)
/// and a terrain triangle, y-up.
fn write_city(dir: &Path, first_name: &str, second_name: &str) -> String {
    let mut obj = String::from("# y-up test city\n");
    obj += &y_up_box(
        first_name,
        "Building",
        [0.0, 0.0, 0.0],
        [10.0, 20.0, 12.0],
        1,
    );
    obj += &y_up_box(
        second_name,
        "Building",
        [30.0, 0.0, 0.0],
        [36.0, 6.0, 25.0],
        9,
    );
    obj += "o Terrain_1\nusemtl Terrain\nv -20 0 20\nv 60 0 20\nv 60 0 -40\nf 17 18 19\n";
    let path = dir.join("city.obj");
    std::fs::write(&path, obj).expect("write the OBJ");
    path_str(&path).to_string()
}

/// East, north and up extents of a building's footprint and heights.
fn extents(pkg: &ScenePackage, source_id: &str) -> (f64, f64, f32, f32, f64) {
    let b = pkg
        .buildings
        .iter()
        .find(|b| b.source_id == source_id)
        .unwrap_or_else(|| panic!("no building {source_id}"));
    let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
    for c in b.footprint.0.iter().flat_map(|p| p.exterior().0.iter()) {
        lo = [lo[0].min(c.x), lo[1].min(c.y)];
        hi = [hi[0].max(c.x), hi[1].max(c.y)];
    }
    (hi[0] - lo[0], hi[1] - lo[1], b.base_m, b.top_m, lo[1])
}

#[test]
fn y_up_obj_preprocesses_with_its_heights_and_keeps_the_terrain() {
    let dir = temp_dir("obj-y-up");
    let obj = write_city(&dir, "Building_A", "Building_B");
    let package = dir.join("city.cwk");
    let pre = json(&citywalk(&[
        "preprocess",
        &obj,
        "--up",
        "y",
        "-o",
        path_str(&package),
        "--json",
    ]));
    assert_eq!(pre["buildings_found"], 2, "{pre}");
    assert_eq!(pre["buildings_loaded"], 2, "{pre}");
    // The memory after each step: the load, the stages in order, the write; peaks never fall.
    let steps = pre["step_memory"].as_array().expect("step_memory");
    let names: Vec<&str> = steps.iter().filter_map(|m| m["step"].as_str()).collect();
    assert_eq!(names.first(), Some(&"load"), "{names:?}");
    assert_eq!(names.last(), Some(&"write"), "{names:?}");
    let tree = names.iter().position(|&n| n == "cluster tree");
    let occluders = names.iter().position(|&n| n == "occluders");
    assert!(occluders.is_some() && occluders < tree, "{names:?}");
    let mib = |m: &serde_json::Value, key: &str| m[key].as_f64().expect("memory on Linux");
    let peaks: Vec<f64> = steps.iter().map(|m| mib(m, "peak_mib")).collect();
    assert!(peaks.windows(2).all(|w| w[0] <= w[1]), "{peaks:?}");
    assert!(
        steps
            .iter()
            .all(|m| mib(m, "resident_mib") <= mib(m, "peak_mib"))
    );

    let inspected = json(&citywalk(&["inspect", path_str(&package), "--json"]));
    assert_eq!(inspected["buildings"], 2, "{inspected}");
    assert_eq!(inspected["buildings_rejected"], 0, "{inspected}");
    // The terrain is a ground area of class `other` (3dfier's Terrain), kept in the package.
    assert_eq!(inspected["ground_areas"], 1, "{inspected}");
    assert_eq!(
        inspected["ground_areas_by_class"]["other"], 1,
        "{inspected}"
    );
    assert_eq!(
        inspected["ground_areas_by_class"]["water"], 0,
        "{inspected}"
    );
    let parameters = inspected["parameters_json"].as_str().expect("parameters");
    assert!(parameters.contains(r#""up_axis":"Y""#), "{parameters}");

    // y-up mapped to z-up: file y is the height, file -z is north.
    let pkg = ScenePackage::read(&package).expect("the package reads");
    // Its plan: the triangle (-20, -20), (60, -20), (60, 40) of 2400 m².
    let ring = &pkg.ground_areas[0].polygon.0[0].exterior().0;
    let twice: f64 = ring
        .windows(2)
        .map(|w| w[0].x * w[1].y - w[1].x * w[0].y)
        .sum();
    assert!((0.5 * twice.abs() - 2400.0).abs() < 1e-3, "{ring:?}");
    let (east_a, north_a, base_a, top_a, south_a) = extents(&pkg, "Building_A");
    let (east_b, north_b, base_b, top_b, south_b) = extents(&pkg, "Building_B");
    let near = |a: f64, b: f64| (a - b).abs() < 1e-3;
    assert!(
        near(east_a, 10.0) && near(north_a, 20.0),
        "A: {east_a} × {north_a}"
    );
    assert!(
        near(east_b, 6.0) && near(north_b, 6.0),
        "B: {east_b} × {north_b}"
    );
    assert!(
        near(f64::from(top_a - base_a), 12.0),
        "A: {base_a}..{top_a}"
    );
    assert!(
        near(f64::from(top_b - base_b), 25.0),
        "B: {base_b}..{top_b}"
    );
    assert!(
        near(f64::from(base_a), f64::from(base_b)),
        "{base_a} vs {base_b}"
    );
    assert!(near(south_a, south_b), "south sides {south_a} vs {south_b}");
}

#[test]
fn geographic_crs_is_refused_and_a_projected_one_is_recorded() {
    let dir = temp_dir("obj-crs");
    let obj = write_city(&dir, "Building_A", "Building_B");
    let refused = dir.join("refused.cwk");
    let out = citywalk(&[
        "preprocess",
        &obj,
        "--up",
        "y",
        "--crs",
        "EPSG:4326",
        "-o",
        path_str(&refused),
    ]);
    assert!(!out.status.success(), "{}", text(&out));
    let message = text(&out);
    assert!(
        message.contains("EPSG:4326 is geographic") && message.contains("--crs"),
        "{message}"
    );
    assert!(!refused.exists());

    let package = dir.join("rd.cwk");
    json(&citywalk(&[
        "preprocess",
        &obj,
        "--up",
        "y",
        "--crs",
        "epsg:28992",
        "-o",
        path_str(&package),
        "--json",
    ]));
    let pkg = ScenePackage::read(&package).expect("the package reads");
    assert!(
        format!("{:?}", pkg.frame.crs).contains("EPSG:28992"),
        "{:?}",
        pkg.frame.crs
    );
    let parameters = &pkg.provenance.parameters_json;
    assert!(
        parameters.contains(r#""source_crs":"EPSG:28992""#),
        "{parameters}"
    );
}

#[test]
fn building_markers_are_a_list_and_replace_the_default() {
    let dir = temp_dir("obj-markers");
    let obj = write_city(&dir, "house_1", "shed_2");
    let package = dir.join("city.cwk");
    // The material `Building` marks both; with other markers only the names count.
    let only_house = json(&citywalk(&[
        "inspect",
        &obj,
        "--up",
        "y",
        "--obj-building-marker",
        "house",
        "--json",
    ]));
    assert_eq!(only_house["buildings"], 1, "{only_house}");
    let pre = json(&citywalk(&[
        "preprocess",
        &obj,
        "--up",
        "y",
        "--obj-building-marker",
        "house,shed",
        "--obj-building-marker",
        "terrain",
        "-o",
        path_str(&package),
        "--json",
    ]));
    // The terrain triangle is now a building candidate too, and rejected with its id.
    assert_eq!(pre["buildings_found"], 3, "{pre}");
    assert_eq!(pre["buildings_loaded"], 2, "{pre}");
    let rejected = pre["rejected"].as_array().expect("rejections");
    assert!(
        rejected.iter().any(|r| r["source_id"] == "Terrain_1"),
        "{rejected:?}"
    );
    let empty = citywalk(&["inspect", &obj, "--obj-building-marker", ",", "--json"]);
    assert!(!empty.status.success());
    assert!(text(&empty).contains("empty marker"), "{}", text(&empty));
}

#[test]
fn obj_options_without_an_obj_input_are_refused() {
    let dir = temp_dir("obj-options-refused");
    let geojson = dir.join("city.geojson");
    let out = citywalk(&[
        "generate",
        "--buildings",
        "4",
        "--seed",
        "1",
        "-o",
        path_str(&geojson),
    ]);
    assert!(out.status.success(), "{}", text(&out));
    let out = citywalk(&[
        "preprocess",
        path_str(&geojson),
        "--up",
        "y",
        "--crs",
        "EPSG:28992",
        "-o",
        path_str(&dir.join("x.cwk")),
    ]);
    assert!(!out.status.success());
    let message = text(&out);
    assert!(
        message.contains("--crs, --up apply to OBJ inputs only")
            && message.contains("city.geojson"),
        "{message}"
    );
    assert!(!dir.join("x.cwk").exists());
}
