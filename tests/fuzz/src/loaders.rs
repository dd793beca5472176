//! One target per input kind, each calling the loader entry point the command line reaches
//! for that kind (`citywalk_scenes::load`), then [`crate::check::loaded`].
//!
//! Loaders that read bytes or a reader (CityJSON, glTF, OBJ) get the input directly; the two
//! that read a path (OSM PBF in several passes, GeoJSON streamed) get it through a temporary
//! file. glTF and tileset inputs are named as files of [`crate::assets_dir`], so a relative
//! buffer or content `uri` reaches the fixed assets there and the reads behind it are fuzzed
//! too.

use std::io::Write;
use std::path::Path;

use citywalk_scenes::LoadOptions;
use citywalk_scenes::load::{cityjson, geojson, gltf, obj, osm};

use crate::check;

/// `data` as an `.osm.pbf` file, through [`osm::load`] with the default options (streets on).
pub fn osm_pbf(data: &[u8]) {
    with_file(data, ".osm.pbf", |path| {
        check::loaded(path, osm::load(path, &LoadOptions::default()))
    });
}

/// `data` as a `.geojson` file, through [`geojson::load`] with the default options.
pub fn geojson(data: &[u8]) {
    with_file(data, ".geojson", |path| {
        check::loaded(path, geojson::load(path, &LoadOptions::default()))
    });
}

/// `data` as CityJSON bytes, through [`cityjson::load_bytes`].
pub fn cityjson(data: &[u8]) {
    let path = Path::new("fuzz/input.city.json");
    check::loaded(path, cityjson::load_bytes(path, data));
}

/// `data` as a `.gltf` (JSON) beside the assets, through [`gltf::load_bytes`]: its buffers
/// may name `4.bin` or `6.bin`.
pub fn gltf(data: &[u8]) {
    let path = crate::assets_dir().join("input.gltf");
    check::loaded(&path, gltf::load_bytes(&path, data));
}

/// `data` as a `.glb`, through [`gltf::load_bytes`].
pub fn glb(data: &[u8]) {
    let path = crate::assets_dir().join("input.glb");
    check::loaded(&path, gltf::load_bytes(&path, data));
}

/// `data` as a `.b3dm` tile, through [`gltf::load_bytes`].
pub fn b3dm(data: &[u8]) {
    let path = crate::assets_dir().join("input.b3dm");
    check::loaded(&path, gltf::load_bytes(&path, data));
}

/// `data` as a `tileset.json` beside the assets, through [`gltf::load_bytes`]: its contents
/// may name `tiles/4.b3dm` and `tiles/6.b3dm`.
pub fn tileset(data: &[u8]) {
    let path = crate::assets_dir().join("tileset.json");
    check::loaded(&path, gltf::load_bytes(&path, data));
}

/// `data` as OBJ text, through [`obj::load_reader`] with the default options (z up, local
/// frame, `building` marker).
pub fn obj(data: &[u8]) {
    let path = Path::new("fuzz/input.obj");
    check::loaded(path, obj::load_reader(path, data, &LoadOptions::default()));
}

/// Writes `data` to a fresh temporary file named `*<suffix>` and runs `f` on its path. A file
/// of its own per call: the replay test runs targets on several threads at once.
fn with_file(data: &[u8], suffix: &str, f: impl FnOnce(&Path)) {
    let mut file = tempfile::Builder::new()
        .prefix("citywalk-fuzz-")
        .suffix(suffix)
        .tempfile()
        .expect("cannot create a temporary file for the fuzz input");
    file.write_all(data)
        .and_then(|()| file.flush())
        .expect("cannot write the fuzz input to its temporary file");
    f(file.path());
}
