//! Replays every seed of `corpus/<target>/` and every crash or hang reproducer of
//! `regressions/<target>/` through its target: what CI runs of the fuzzers. A panic in any
//! file fails the target's test, naming the file.

use std::panic::{AssertUnwindSafe, catch_unwind};
use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use citywalk_fuzz::{TARGETS, Target};

/// Files directly in `dir`, sorted; none when it does not exist.
fn files(dir: &Path) -> Vec<PathBuf> {
    let Ok(entries) = std::fs::read_dir(dir) else {
        return Vec::new();
    };
    let mut files: Vec<PathBuf> = entries
        .map(|e| e.expect("readable folder entry").path())
        .filter(|p| p.is_file() && p.file_name().is_some_and(|n| n != "README.md"))
        .collect();
    files.sort();
    files
}

fn target(name: &str) -> Target {
    *TARGETS
        .iter()
        .find(|t| t.name == name)
        .unwrap_or_else(|| panic!("no target {name}"))
}

/// Runs `name` on its corpus and regressions; panics listing every file that panicked.
fn replay(name: &str) {
    let target = target(name);
    let root = citywalk_fuzz::crate_dir();
    let corpus = files(&root.join("corpus").join(name));
    assert!(!corpus.is_empty(), "target {name} has no seed corpus");
    let regressions = files(&root.join("regressions").join(name));
    let mut failed = Vec::new();
    let mut slowest = (Duration::ZERO, PathBuf::new());
    for path in corpus.iter().chain(&regressions) {
        let data = std::fs::read(path).expect("readable corpus file");
        let start = Instant::now();
        if catch_unwind(AssertUnwindSafe(|| (target.run)(&data))).is_err() {
            failed.push(path.display().to_string());
        }
        slowest = slowest.max((start.elapsed(), path.clone()));
    }
    println!(
        "{name}: {} seeds, {} regressions; slowest {:?} ({})",
        corpus.len(),
        regressions.len(),
        slowest.0,
        slowest.1.display()
    );
    assert!(failed.is_empty(), "{name}: panicked on {failed:#?}");
}

#[test]
fn replay_osm_pbf() {
    replay("osm_pbf");
}

#[test]
fn replay_geojson() {
    replay("geojson");
}

#[test]
fn replay_cityjson() {
    replay("cityjson");
}

#[test]
fn replay_gltf() {
    replay("gltf");
}

#[test]
fn replay_glb() {
    replay("glb");
}

#[test]
fn replay_b3dm() {
    replay("b3dm");
}

#[test]
fn replay_tileset() {
    replay("tileset");
}

#[test]
fn replay_obj() {
    replay("obj");
}

#[test]
fn replay_package() {
    replay("package");
}

#[test]
fn every_target_is_replayed_and_has_a_binary() {
    let root = citywalk_fuzz::crate_dir();
    let tests = std::fs::read_to_string(root.join("tests/replay.rs")).expect("this file");
    for t in TARGETS {
        assert!(
            tests.contains(&format!("replay(\"{}\")", t.name)),
            "target {} has no replay test",
            t.name
        );
        assert!(
            root.join(format!("src/bin/fuzz_{}.rs", t.name)).is_file(),
            "target {} has no AFL binary",
            t.name
        );
    }
}
