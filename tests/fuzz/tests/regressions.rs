//! What each saved reproducer of `regressions/` must give, one named test per finding (the
//! replay test only asks that none panics). The loader-side test of each fix lives beside the
//! loader (`scenes/tests/`); these pin the exact bytes the fuzzer found.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use citywalk_scenes::load::gltf;

fn reproducer(target: &str, name: &str) -> Vec<u8> {
    let path: PathBuf = citywalk_fuzz::crate_dir()
        .join("regressions")
        .join(target)
        .join(name);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

fn expect_gltf_error(name: &str, bytes: &[u8], needle: &str) {
    match gltf::load_bytes(Path::new(name), bytes) {
        Ok(city) => panic!("{name} loaded: {}", city.report),
        Err(e) => {
            let message = e.to_string();
            assert!(message.contains(name), "{message}");
            assert!(message.contains(needle), "{message} lacks {needle:?}");
        }
    }
}

/// `glb` and `b3dm`, run 1: a GLB header declaring 4 bytes, under its own 12 (`gltf`
/// subtracted past zero). The AFL original of the b3dm one is a mutated Amsterdam tile 6.
#[test]
fn glb_length_under_header_is_an_error() {
    let needle = "less than the header's 12";
    expect_gltf_error(
        "length_under_header.glb",
        &reproducer("glb", "length_under_header"),
        needle,
    );
    expect_gltf_error(
        "glb_length_under_header.b3dm",
        &reproducer("b3dm", "glb_length_under_header"),
        needle,
    );
    // AFL's own file also damaged the container version, which the header check meets first.
    expect_gltf_error(
        "afl_glb_length_under_header.b3dm",
        &reproducer("b3dm", "afl_glb_length_under_header"),
        "GLB container version",
    );
}

/// `gltf`, run 2, reported as a hang: Amsterdam tile 6 with `byteStride` and `_BATCHID`
/// misspelt, so its interleaved attributes are read as tightly packed positions and one
/// feature's ~90 projected triangles cross each other everywhere. The footprint union is
/// output-sensitive (i_overlay), so this takes ~35 ms where the seed takes 0.2 ms, and about
/// 0.3 s in the instrumented AFL build, over AFL's 1 s limit only on a loaded machine. Not a
/// hang; kept so that it stays far from one. The bound is loose on purpose (a shared
/// 2-core machine).
#[test]
fn gltf_crossing_garbage_triangles_load_in_bounded_time() {
    let bytes = reproducer("gltf", "slow_footprint_union");
    let path = citywalk_fuzz::assets_dir().join("slow_footprint_union.gltf");
    let start = Instant::now();
    let result = gltf::load_bytes(&path, &bytes);
    let elapsed = start.elapsed();
    assert!(elapsed < Duration::from_secs(5), "took {elapsed:?}");
    let city = result.expect("the misread mesh still loads, its footprint is the union");
    assert!(city.report.is_balanced());
    assert_eq!(city.check_invariants(), Ok(()));
}

/// `cityjson`, run 4 (20 crashes, one cause): building `b1`'s faces, one vertex thrown 38 km
/// north, project to overlapping slivers whose union trips a `debug_assert!` inside i_overlay
/// (`extract_ogc.rs`: "overlay_rule.is_fill_top(link.fill)"), reached through geo's
/// `unary_union` in `mesh_footprint`. Only builds with debug assertions (the AFL build) panic;
/// a release build loads `b1` and rejects `f8` (zero area) with its id. Kept so that the
/// release behaviour stays: the city loads, balanced, naming the rejection. The assertion is
/// the dependency's; since run 5 a panic there is caught and made the building's rejection.
#[test]
fn cityjson_overlapping_slivers_load_balanced() {
    use citywalk_scenes::load::cityjson;
    let name = "i_overlay_fill_debug_assert.city.json";
    let city = cityjson::load_bytes(
        Path::new(name),
        &reproducer("cityjson", "i_overlay_fill_debug_assert"),
    )
    .expect("the file loads");
    let report = &city.report;
    assert!(report.is_balanced(), "{report}");
    assert_eq!(report.buildings_found, 2);
    assert_eq!(city.buildings.len(), 1);
    assert_eq!(city.buildings[0].source_id, "b1");
    assert_eq!(report.rejected.len(), 1);
    assert_eq!(report.rejected[0].source_id, "f8");
}

/// Loads a reproducer with the glTF loader within `limit`, balanced and valid; its report.
fn load_gltf_bounded(
    target: &str,
    name: &str,
    limit: Duration,
) -> citywalk_scenes::report::LoadReport {
    let path = citywalk_fuzz::assets_dir().join(format!("{name}.{target}"));
    let start = Instant::now();
    let result = gltf::load_bytes(&path, &reproducer(target, name));
    let elapsed = start.elapsed();
    assert!(elapsed < limit, "{name} took {elapsed:?}");
    let city = result.unwrap_or_else(|e| panic!("{name} should load: {e}"));
    assert!(city.report.is_balanced(), "{}", city.report);
    assert_eq!(city.check_invariants(), Ok(()));
    println!("{name}: {}", city.report);
    city.report
}

/// `glb`, run 5, 62 "hangs" from one source: a mutated Amsterdam tile whose misread vertices
/// project to faces 15 km long and 0.1 mm wide along one line. i_overlay split those 24 faces
/// into 68,974 pieces over 21 s (84 s in the AFL build), then panicked on an index out of
/// bounds. Needle faces (within `f32` precision of collinear) are now left out of footprints
/// and the union has a work budget (`mesh_footprint`); both buildings load in milliseconds.
#[test]
fn glb_kilometre_long_sliver_faces_load_in_bounded_time() {
    for name in ["sliver_faces", "sliver_faces_2"] {
        let report = load_gltf_bounded("glb", name, Duration::from_secs(5));
        assert_eq!(
            (report.buildings_found, report.buildings_loaded),
            (2, 2),
            "{report}"
        );
    }
}

/// `glb` and `b3dm`, run 5: i_overlay's `is_fill_top` debug assertion again (as `cityjson`'s),
/// through `footprint_from_mesh`. In a build with debug assertions the panic is caught and
/// the building rejected with the reason; in release the union succeeds. Either way the tile
/// loads, balanced, and the other buildings with it.
#[test]
fn glb_and_b3dm_overlay_assertion_inputs_load_balanced() {
    let glb = load_gltf_bounded("glb", "i_overlay_fill_debug_assert", Duration::from_secs(5));
    assert_eq!(glb.buildings_found, 1, "{glb}");
    let b3dm = load_gltf_bounded(
        "b3dm",
        "i_overlay_fill_debug_assert",
        Duration::from_secs(5),
    );
    assert_eq!(b3dm.buildings_found, 4, "{b3dm}");
    for report in [glb, b3dm] {
        for rejection in &report.rejected {
            assert!(
                rejection.to_string().contains("i_overlay"),
                "an unexpected rejection: {rejection}"
            );
        }
    }
}

/// `b3dm`, run 5: a part one unit in the last place tall (base 103.500244 m, top 103.500275 m)
/// passed the height check, and shifting the city onto the ground in `f32` made its top equal
/// its base, which `City::check_invariants` caught. A building or part is now at least
/// `MIN_HEIGHT_EXTENT_M` tall, or rejected with both heights named.
#[test]
fn b3dm_part_one_ulp_tall_is_rejected_naming_its_heights() {
    let report = load_gltf_bounded("b3dm", "part_one_ulp_tall", Duration::from_secs(5));
    let flat = report
        .rejected
        .iter()
        .find(|r| r.source_id == "part_one_ulp_tall#75")
        .expect("the one-ulp part is rejected");
    let message = flat.to_string();
    assert!(
        message.contains("not 0.01 m above base 103.500244 m"),
        "{message}"
    );
    assert!(report.buildings_loaded > 0, "{report}");
}

/// `gltf`, run 5, two AFL "hangs" (1.0 s and 3.1 s in the instrumented build on a loaded
/// machine): more crossing garbage triangles like `slow_footprint_union`, 0.2 s in release.
/// Kept so that they stay far from a hang.
#[test]
fn gltf_run_5_crossing_triangles_load_in_bounded_time() {
    for name in ["crossing_triangles_run5_a", "crossing_triangles_run5_b"] {
        let report = load_gltf_bounded("gltf", name, Duration::from_secs(5));
        assert_eq!(report.buildings_found, 1, "{report}");
    }
}

/// `obj`, run 6: i_overlay's `is_fill_top` debug assertion once more, this time in the repair
/// of a crossing footprint (`validate::clean_footprint`, re-noding by a union), which no guard
/// covered on the mesh loaders' path. Every footprint overlay now goes through one guard
/// (`overlay_guard`): in a build with debug assertions the building is rejected naming
/// i_overlay. In release the four mangled buildings are rejected for their own reasons
/// (non-finite coordinates first) and the load is an error naming the file. Either way the
/// target's checks hold, in bounded time.
#[test]
fn obj_overlay_assertion_in_the_footprint_repair_is_contained() {
    use citywalk_scenes::LoadOptions;
    use citywalk_scenes::load::obj;

    let bytes = reproducer("obj", "i_overlay_repair_assert");
    let start = Instant::now();
    citywalk_fuzz::loaders::obj(&bytes);
    assert!(
        start.elapsed() < Duration::from_secs(5),
        "{:?}",
        start.elapsed()
    );
    let name = "i_overlay_repair_assert.obj";
    match obj::load_reader(Path::new(name), &bytes[..], &LoadOptions::default()) {
        Ok(city) => {
            let report = &city.report;
            assert!(report.is_balanced(), "{report}");
            for rejection in &report.rejected {
                assert!(
                    !rejection.to_string().is_empty(),
                    "a rejection without its reason"
                );
            }
        }
        Err(e) => {
            let message = e.to_string();
            assert!(message.contains(name), "{message}");
            assert!(message.contains("4 found"), "{message}");
        }
    }
}

/// `package`, run 9: a package (checksums recomputed) whose building footprint has nearly
/// coincident edges; `check_invariants` asked geo's `Validation` about it and geo's relate
/// graph panicked inside `edge_end_bundle_star.rs` (a debug assertion). The check now says the
/// footprint's validity cannot be decided, naming geo's message, and goes on.
#[test]
fn package_footprint_geo_cannot_judge_is_reported_not_a_panic() {
    let data = reproducer("package", "geo_relate_panic_in_validity");
    let fixed = citywalk_fuzz::package::with_checksums(&data);
    let verdicts: Vec<String> = [Some(data), fixed]
        .into_iter()
        .flatten()
        .filter_map(|bytes| citywalk_scenes::package::ScenePackage::from_bytes(&bytes).ok())
        .map(|package| format!("{:?}", package.check_invariants()))
        .collect();
    // With debug assertions (the AFL build) geo panics and the check says its validity cannot
    // be decided; without, geo answers: either way the footprint is refused, not a crash.
    assert!(
        verdicts
            .iter()
            .any(|v| v.contains("part b2: footprint is invalid")),
        "{verdicts:#?}"
    );
}
