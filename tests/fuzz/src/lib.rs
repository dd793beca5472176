//! Coverage-guided fuzz targets for citywalk's loaders and the scene-package reader.
//!
//! Each target is a plain function from bytes to nothing that panics only on a bug: it feeds
//! the bytes to the real loader entry point of [`citywalk_scenes`] and, when the input loads,
//! runs the cheap consistency checks ([`check`]). An `Err` is the right answer to bad input and
//! is not a failure. The same functions are called by the AFL binaries (`src/bin/`, built with
//! the `afl` feature by `cargo afl build`) and by the replay test (`tests/replay.rs`), which
//! runs every seed of `corpus/<target>/` and every reproducer of `regressions/<target>/`, so a
//! crash found once stays fixed without AFL installed.

pub mod check;
pub mod loaders;
pub mod package;

use std::path::PathBuf;

/// One fuzz target: its name (the folder of its corpus and regressions, and `fuzz_<name>`, its
/// AFL binary) and the function under test.
#[derive(Debug, Clone, Copy)]
pub struct Target {
    pub name: &'static str,
    pub run: fn(&[u8]),
}

/// Every target, in the order of the README's table.
pub const TARGETS: [Target; 9] = [
    Target {
        name: "osm_pbf",
        run: loaders::osm_pbf,
    },
    Target {
        name: "geojson",
        run: loaders::geojson,
    },
    Target {
        name: "cityjson",
        run: loaders::cityjson,
    },
    Target {
        name: "gltf",
        run: loaders::gltf,
    },
    Target {
        name: "glb",
        run: loaders::glb,
    },
    Target {
        name: "b3dm",
        run: loaders::b3dm,
    },
    Target {
        name: "tileset",
        run: loaders::tileset,
    },
    Target {
        name: "obj",
        run: loaders::obj,
    },
    Target {
        name: "package",
        run: package::package,
    },
];

/// This crate's folder (corpora, regressions and assets live in it).
pub fn crate_dir() -> PathBuf {
    PathBuf::from(env!("CARGO_MANIFEST_DIR"))
}

/// The fixed files that glTF and tileset inputs may name by a relative `uri` (buffers
/// `4.bin`, `6.bin`; tile contents `tiles/4.b3dm`, `tiles/6.b3dm`): a mutated `.gltf` or
/// `tileset.json` is resolved against this folder, so its references reach real data.
pub fn assets_dir() -> PathBuf {
    crate_dir().join("assets")
}
