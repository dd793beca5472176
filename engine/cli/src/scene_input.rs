//! One way for every command to open a scene: a scene package is read as it is; any other
//! input (OSM PBF, GeoJSON, CityJSON, glTF, OBJ) is loaded (with the options of
//! [`crate::input_args::InputArgs`]) and preprocessed on the fly.

use std::io::Read;
use std::path::{Path, PathBuf};

use anyhow::Context;
use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_scenes::package::{Decode, MAGIC, ScenePackage};
use citywalk_scenes::{LoadOptions, load_cities};

/// The scenes a command was given, and how the raw inputs among them are read.
#[derive(Debug, Clone, Copy)]
pub struct SceneInputs<'a> {
    pub paths: &'a [PathBuf],
    pub load: &'a LoadOptions,
}

/// Whether `path` is a scene package, judged by its first bytes (the magic), not its name.
pub fn is_package(path: &Path) -> anyhow::Result<bool> {
    let mut file =
        std::fs::File::open(path).with_context(|| format!("cannot open {}", path.display()))?;
    let mut head = [0u8; 4];
    let mut read = 0;
    while read < head.len() {
        let n = file
            .read(&mut head[read..])
            .with_context(|| format!("cannot read {}", path.display()))?;
        if n == 0 {
            break;
        }
        read += n;
    }
    Ok(read == head.len() && head == MAGIC)
}

/// The package at `path` when it is one (a file starting with the package magic, or named
/// `*.cwk`, which then must be a valid package); `None` for any other input.
pub fn open_package(path: &Path) -> anyhow::Result<Option<ScenePackage>> {
    open_package_as(path, Decode::All)
}

/// [`open_package`] decoding only what `what` names.
fn open_package_as(path: &Path, what: Decode) -> anyhow::Result<Option<ScenePackage>> {
    let named_package = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("cwk"));
    if !(is_package(path)? || named_package) {
        return Ok(None);
    }
    ScenePackage::read_as(path, what)
        .map(Some)
        .with_context(|| format!("cannot read the scene package {}", path.display()))
}

/// Opens a scene: the package at `path` (a file starting with the package magic, or named
/// `*.cwk`, which then must be a valid package), or the input at `path` loaded with `load` and
/// preprocessed with the default parameters (no progress bars; logs through `tracing`).
pub fn load_scene(path: &Path, load: &LoadOptions) -> anyhow::Result<ScenePackage> {
    load_scene_as(path, load, Decode::All)
}

/// [`load_scene`] for drawing it ([`Decode::Runtime`]): a package's occluder set, cluster
/// meshes and building parts and tags are not decoded; the GPU scene holds what is drawn.
pub fn load_scene_to_draw(path: &Path, load: &LoadOptions) -> anyhow::Result<ScenePackage> {
    load_scene_as(path, load, Decode::Runtime)
}

fn load_scene_as(path: &Path, load: &LoadOptions, what: Decode) -> anyhow::Result<ScenePackage> {
    if let Some(package) = open_package_as(path, what)? {
        return Ok(package);
    }
    tracing::info!(input = %path.display(), "not a scene package: loading and preprocessing it");
    let city = load_cities(&[PathBuf::from(path)], load)
        .with_context(|| format!("cannot load {}", path.display()))?;
    let params = PreprocessParams {
        load: load.clone(),
        ..PreprocessParams::default()
    };
    preprocess(city, &params, &NoProgress)
        .with_context(|| format!("cannot preprocess {}", path.display()))
}

/// Opens the city of a scene for drawing: a package's buildings and streets as stored, or any
/// other input loaded with `load` as it is (no preprocessing: rendering and viewing need only
/// the city).
pub fn load_city(path: &Path, load: &LoadOptions) -> anyhow::Result<citywalk_scenes::City> {
    if let Some(package) = open_package(path)? {
        return Ok(package.into_city());
    }
    citywalk_scenes::load_city(path, load)
        .with_context(|| format!("cannot load {}", path.display()))
}
