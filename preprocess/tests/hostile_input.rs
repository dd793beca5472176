//! Issue 14's hostile inputs that reach preprocessing: a 40,000-vertex footprint, a star that
//! crosses itself everywhere, and packages whose sections come from another package. Each
//! input is built here; the time bounds are many times what a fixed debug build needs.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_scenes::generate::{GenerateParams, generate_city};
use citywalk_scenes::package::{Decode, PackageError, PackageFile, ScenePackage, WriteOptions};
use citywalk_scenes::{City, LoadOptions, RejectReason, load_cities};
use serde_json::json;

/// Writes a GeoJSON collection (local metres, EPSG:3857) of `rings` (id, closed ring) with a
/// height of 20 m each, and loads it.
fn load_rings(name: &str, rings: &[(&str, Vec<[f64; 2]>)]) -> City {
    let features: Vec<_> = rings
        .iter()
        .map(|(id, ring)| {
            json!({"type": "Feature", "id": id,
                   "geometry": {"type": "Polygon", "coordinates": [ring]},
                   "properties": {"building": "yes", "height": 20}})
        })
        .collect();
    let doc = json!({"type": "FeatureCollection",
        "crs": {"type": "name", "properties": {"name": "urn:ogc:def:crs:EPSG::3857"}},
        "features": features});
    let path = std::env::temp_dir().join(format!(
        "citywalk-hostile-{}-{name}.geojson",
        std::process::id()
    ));
    std::fs::write(&path, doc.to_string()).unwrap();
    let city = load_cities(&[PathBuf::from(&path)], &LoadOptions::default());
    let _ = std::fs::remove_file(&path);
    city.expect("load")
}

/// `n` points on a circle of radius `r_m`, visited `step` at a time (1: a circle; about n/2: a
/// star crossing itself everywhere), closed.
fn polygram(n: usize, step: usize, r_m: f64) -> Vec<[f64; 2]> {
    let mut ring: Vec<[f64; 2]> = (0..n)
        .map(|i| {
            let t = std::f64::consts::TAU * ((i * step) % n) as f64 / n as f64;
            [r_m * t.cos(), r_m * t.sin()]
        })
        .collect();
    ring.push(ring[0]);
    ring
}

fn square(x: f64, y: f64) -> Vec<[f64; 2]> {
    vec![
        [x, y],
        [x + 10.0, y],
        [x + 10.0, y + 10.0],
        [x, y + 10.0],
        [x, y],
    ]
}

fn run(city: City) -> (ScenePackage, Duration) {
    let start = Instant::now();
    let pkg = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    (pkg, start.elapsed())
}

#[test]
fn issue14_case3_a_40000_vertex_footprint_loads_and_preprocesses_in_seconds() {
    // Was quadratic: 2.5k vertices 0.3 s, 20k 19 s, 40k past 60 s (geo's ring validation, the
    // occluder simplification, the cull rectangle and the roof's inside test).
    let start = Instant::now();
    let city = load_rings("stadium", &[("stadium", polygram(40_000, 1, 120.0))]);
    assert_eq!(city.buildings.len(), 1, "{:?}", city.report.rejected);
    let (pkg, preprocess_time) = run(city);
    let elapsed = start.elapsed();
    assert!(
        elapsed < Duration::from_secs(30),
        "{elapsed:?} ({preprocess_time:?} preprocessing)"
    );
    let occ = pkg.occluders.as_ref().expect("occluders");
    assert_eq!(occ.per_building.len(), 1);
    assert!(
        !occ.occluders_of(pkg.buildings[0].id).is_empty(),
        "{:?}",
        occ.per_building[0].reason_if_none
    );
}

#[test]
fn issue14_case4_a_star_crossing_itself_everywhere_is_rejected_by_id_and_the_rest_load_fast() {
    // Was: 301 vertices loaded (re-noded into thousands of slivers) and preprocessing ran past
    // 60 s; 3,001 vertices hung inside the load at 713 MB.
    for n in [301, 3_001] {
        let start = Instant::now();
        let mut rings: Vec<(&str, Vec<[f64; 2]>)> = vec![("star", polygram(n, n / 2, 40.0))];
        let ids = ["b0", "b1", "b2", "b3", "b4"];
        for (i, id) in ids.iter().enumerate() {
            rings.push((id, square(100.0 + 20.0 * i as f64, 100.0)));
        }
        let city = load_rings(&format!("star{n}"), &rings);
        assert_eq!(city.buildings.len(), 5);
        let rejected = &city.report.rejected;
        assert_eq!(rejected.len(), 1);
        assert_eq!(rejected[0].source_id, "star");
        assert!(
            matches!(&rejected[0].reason, RejectReason::InvalidGeometry(r) if r.contains("crosses itself")),
            "{:?}",
            rejected[0].reason
        );
        let (pkg, _) = run(city);
        assert_eq!(pkg.buildings.len(), 5);
        let elapsed = start.elapsed();
        assert!(
            elapsed < Duration::from_secs(20),
            "{n} vertices: {elapsed:?}"
        );
    }
}

#[test]
fn issue14_case4_a_bow_tie_is_still_repaired() {
    let bow = vec![
        [0.0, 0.0],
        [10.0, 10.0],
        [10.0, 0.0],
        [0.0, 10.0],
        [0.0, 0.0],
    ];
    let city = load_rings("bow", &[("bow", bow)]);
    assert_eq!(city.buildings.len(), 1, "{:?}", city.report.rejected);
}

fn generated(buildings: usize, seed: u64) -> ScenePackage {
    let city = generate_city(&GenerateParams {
        buildings,
        seed,
        ..GenerateParams::default()
    })
    .expect("generate");
    run(city).0
}

/// How `pkg`, re-encoded with its checksums recomputed, opens: from bytes and from a file
/// decoded whole (`inspect`, `export`), and mapped for drawing (`render`, `bench`: the GPU scene
/// and no occluder set; `view`: with the buildings' parts).
struct Reopened {
    whole: Vec<Result<ScenePackage, PackageError>>,
    drawn: Vec<Result<ScenePackage, PackageError>>,
}

fn reopen(pkg: &ScenePackage, name: &str) -> Reopened {
    let bytes = pkg.to_bytes(WriteOptions::default()).expect("encode");
    let path =
        std::env::temp_dir().join(format!("citywalk-mixed-{}-{name}.cwk", std::process::id()));
    std::fs::write(&path, &bytes).unwrap();
    let whole = vec![ScenePackage::from_bytes(&bytes), ScenePackage::read(&path)];
    let drawn = [Decode::Runtime, Decode::RuntimeWithParts]
        .into_iter()
        .map(|what| PackageFile::open(&path).and_then(|file| file.decode_as(what)))
        .collect();
    let _ = std::fs::remove_file(&path);
    Reopened { whole, drawn }
}

fn errors(results: &[Result<ScenePackage, PackageError>]) -> Vec<&PackageError> {
    results.iter().filter_map(|r| r.as_ref().err()).collect()
}

#[test]
fn issue14_case11_a_section_from_another_package_is_refused_on_open_naming_the_sections() {
    // Two cities of the same size and layout rules (counts may agree); each section of one
    // taken into the other must be refused when the package is opened, not only by --check,
    // and on the paths that draw it as on those that read it whole.
    let (a, b) = (generated(120, 1), generated(120, 2));
    let intact = reopen(&a, "intact");
    let opened = errors(&intact.whole).is_empty() && errors(&intact.drawn).is_empty();
    assert!(
        opened,
        "{:?} {:?}",
        errors(&intact.whole),
        errors(&intact.drawn)
    );
    let mut cases: Vec<(&str, ScenePackage)> = Vec::new();
    let mut mixed = a.clone();
    mixed.buildings = b.buildings.clone();
    cases.push(("buildings", mixed));
    let mut mixed = a.clone();
    mixed.blocks = b.blocks.clone();
    cases.push(("blocks", mixed));
    let mut mixed = a.clone();
    mixed.quadtree = b.quadtree.clone();
    cases.push(("quadtree", mixed));
    let mut mixed = a.clone();
    mixed.occluders = b.occluders.clone();
    cases.push(("occluders", mixed));
    let mut mixed = a.clone();
    mixed.cluster_tree = b.cluster_tree.clone();
    cases.push(("cluster tree", mixed));
    let mut mixed = a.clone();
    mixed.gpu_scene = b.gpu_scene.clone();
    cases.push(("gpu scene", mixed));
    let names_the_section = |section: &str, e: &PackageError| {
        matches!(e, PackageError::Inconsistent { sections, .. } if sections.contains(section))
            || matches!(e, PackageError::Decode { section: s, .. } if s.contains("gpu"))
    };
    for (section, pkg) in &cases {
        let reopened = reopen(pkg, &section.replace(' ', "-"));
        let whole = errors(&reopened.whole);
        assert_eq!(whole.len(), 2, "{section}: opened whole");
        let drawn = errors(&reopened.drawn);
        if *section == "occluders" {
            // Drawing reads no occluder set: the occluders it draws are the GPU scene's,
            // which are the package's own and checked with it.
            assert!(drawn.is_empty(), "{section}: {drawn:?}");
            for opened in reopened.drawn.iter().flatten() {
                assert!(opened.occluders.is_none());
                assert!(
                    opened.gpu_scene == a.gpu_scene,
                    "{section}: another GPU scene"
                );
            }
        } else {
            assert_eq!(drawn.len(), 2, "{section}: opened for drawing");
        }
        for e in whole.into_iter().chain(drawn) {
            assert!(names_the_section(section, e), "{section}: {e}");
            eprintln!("{section}: {e}");
        }
    }
}

#[test]
fn issue14_small_the_unknown_extension_message_names_every_extension_read() {
    let path = std::env::temp_dir().join("citywalk-issue14-unknown.xyz");
    std::fs::write(&path, b"not a city").unwrap();
    let message = citywalk_scenes::load::detect_format(&path)
        .unwrap_err()
        .to_string();
    std::fs::remove_file(&path).ok();
    for ext in [
        ".osm.pbf",
        ".geojson",
        ".city.json",
        ".glb",
        ".gltf",
        ".b3dm",
        ".obj",
    ] {
        assert!(message.contains(ext), "{ext} missing from: {message}");
    }
    assert!(
        message.contains("citywalk-issue14-unknown.xyz"),
        "{message}"
    );
}

/// What [`load_and_preprocess_within`] gives back.
struct Preprocessed {
    pkg: ScenePackage,
    /// Buildings found, and loaded plus rejected.
    found: usize,
    counted: usize,
}

/// Loads `input` and preprocesses it on a thread of its own, so that a hang fails the test at
/// `limit` instead of running on; prints the load's and the stages' times.
fn load_and_preprocess_within(input: PathBuf, limit: Duration) -> Preprocessed {
    let (send, receive) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        let start = Instant::now();
        let city = load_cities(&[input], &LoadOptions::default()).expect("load");
        let loaded = start.elapsed();
        let found = city.report.buildings_found;
        let counted = city.report.buildings_loaded + city.report.rejected.len();
        let (pkg, _) = run(city);
        let _ = send.send((pkg, found, counted, loaded, start.elapsed()));
    });
    let (pkg, found, counted, loaded, elapsed) = receive
        .recv_timeout(limit)
        .unwrap_or_else(|_| panic!("loading and preprocessing did not finish within {limit:?}"));
    eprintln!(
        "loaded in {loaded:?}, {elapsed:?} in all; stages {:?}",
        pkg.timings
    );
    Preprocessed {
        pkg,
        found,
        counted,
    }
}

/// Every building of `pkg` has an occluder or the reason why not, never both.
fn assert_occluder_or_reason(pkg: &ScenePackage) {
    let occ = pkg.occluders.as_ref().expect("occluders");
    assert_eq!(occ.per_building.len(), pkg.buildings.len());
    for (building, outcome) in pkg.buildings.iter().zip(&occ.per_building) {
        let has = !occ.occluders_of(building.id).is_empty();
        let reason = outcome.reason_if_none.as_deref().unwrap_or_default();
        assert!(
            has == reason.is_empty(),
            "{}: {} occluders, reason {reason:?}",
            building.source_id,
            occ.occluders_of(building.id).len()
        );
    }
}

const AMSTERDAM_GLB: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/gltf_amsterdam_pg2b3dm/glb"
);

/// Issue 14 case 5 itself: the Amsterdam sample's `glb/2.glb` copied without its
/// `2.batch.json` loaded 48 of 50 features and then ran past 60 s in the occluder stage (8 s
/// with the sidecar). Both now load the same 25 buildings and preprocess in well under a
/// second in release (0.34 s each, 5 December 2026); the guard is for hangs only.
#[test]
fn issue14_case5_the_sample_tile_without_its_sidecar_preprocesses_in_seconds() {
    let dir = tempfile::tempdir().unwrap();
    let lone = dir.path().join("2.glb");
    std::fs::copy(format!("{AMSTERDAM_GLB}/2.glb"), &lone).unwrap();
    let beside_sidecar = PathBuf::from(format!("{AMSTERDAM_GLB}/2.glb"));
    let mut building_counts = Vec::new();
    for input in [lone, beside_sidecar] {
        let Preprocessed {
            pkg,
            found,
            counted,
        } = load_and_preprocess_within(input.clone(), Duration::from_secs(60));
        assert_eq!(found, counted, "{}: unbalanced report", input.display());
        assert!(!pkg.buildings.is_empty(), "{}", input.display());
        assert_occluder_or_reason(&pkg);
        assert!(
            pkg.occluders
                .as_ref()
                .is_some_and(|o| o.per_building.iter().any(|b| b.reason_if_none.is_none())),
            "{}: no building got an occluder",
            input.display()
        );
        pkg.check_invariants().expect("package invariants");
        building_counts.push(pkg.buildings.len());
    }
    assert_eq!(
        building_counts[0], building_counts[1],
        "the lone tile loads the buildings its sidecar names"
    );
}

/// OBJ text of prisms side by side, one per `(teeth, radius_m)` of `gears`: a gear footprint
/// (radii `radius_m` and 1.5 m less alternating: every vertex a real corner the simplification
/// keeps), 15 m high, then tilted by `tilt_deg` about the east axis, as a glTF tile in its
/// Earth-centred axes is when read without its placement (Amsterdam lies at 52° N).
fn tilted_gears_obj(gears: &[(usize, f64)], tilt_deg: f64) -> String {
    let (sin, cos) = tilt_deg.to_radians().sin_cos();
    let tilt = |x: f64, y: f64, z: f64| (x, y * cos - z * sin, y * sin + z * cos);
    let mut obj = String::new();
    let (mut first, mut cx) = (1, 0.0);
    for (b, &(teeth, radius_m)) in gears.iter().enumerate() {
        obj += &format!("o Building_{b}\n");
        let n = 2 * teeth;
        cx += radius_m;
        for z in [0.0, 15.0] {
            for i in 0..n {
                let t = std::f64::consts::TAU * i as f64 / n as f64;
                let r = if i % 2 == 0 { radius_m } else { radius_m - 1.5 };
                let (x, y, z) = tilt(cx + r * t.cos(), r * t.sin(), z);
                obj += &format!("v {x} {y} {z}\n");
            }
        }
        for z in [0.0, 15.0] {
            let (x, y, z) = tilt(cx, 0.0, z);
            obj += &format!("v {x} {y} {z}\n");
        }
        let (bottom, top) = (first, first + n);
        let (bottom_centre, top_centre) = (first + 2 * n, first + 2 * n + 1);
        for i in 0..n {
            let j = (i + 1) % n;
            obj += &format!("f {} {} {} {}\n", bottom + i, bottom + j, top + j, top + i);
            obj += &format!("f {} {} {}\n", bottom_centre, bottom + j, bottom + i);
            obj += &format!("f {} {} {}\n", top_centre, top + i, top + j);
        }
        first += 2 * n + 2;
        cx += radius_m + 10.0;
    }
    obj
}

#[test]
fn issue14_case5_tilted_mesh_buildings_of_thousands_of_vertices_get_occluders_in_seconds() {
    // Amsterdam's glb/2.glb without its sidecar: mesh buildings tilted by the tile's
    // Earth-centred axes, every face sloped, so many candidate levels; the wall-height test
    // (geo's relate, O(n) per footprint edge and level) made the occluder stage quadratic in a
    // building's vertices and ran past 60 s.
    let path = std::env::temp_dir().join(format!(
        "citywalk-hostile-{}-tilted.obj",
        std::process::id()
    ));
    std::fs::write(&path, tilted_gears_obj(&[(4000, 640.0), (60, 20.0)], 38.0)).unwrap();
    // A hang guard only: the fixed release build needs about a second; the wall-height test
    // through geo's relate ran past this guard on the same input.
    let Preprocessed {
        pkg,
        found,
        counted,
    } = load_and_preprocess_within(path.clone(), Duration::from_secs(60));
    let _ = std::fs::remove_file(&path);
    assert_eq!((found, counted), (2, 2));
    assert!(
        !pkg.buildings.is_empty(),
        "{:?}",
        pkg.provenance.load_report.rejected
    );
    assert_occluder_or_reason(&pkg);
    let occ = pkg.occluders.as_ref().expect("occluders");
    // The small gear is an ordinary building, tilted: it keeps a facade.
    let small = pkg
        .buildings
        .iter()
        .find(|b| b.source_id == "Building_1")
        .expect("the small gear loads");
    assert!(
        !occ.occluders_of(small.id).is_empty(),
        "{:?}",
        occ.per_building
    );
    pkg.check_invariants().expect("package invariants");
}
