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
/// the dependency's; not fixed here.
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
