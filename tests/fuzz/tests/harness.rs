//! The harness itself: its seeds reach the loaders' deep code (they load, with the buildings
//! the samples hold) and the package checksum repair leaves intact packages as they are.

use std::path::PathBuf;

use citywalk_fuzz::package::with_checksums;
use citywalk_scenes::load::gltf;
use citywalk_scenes::package::ScenePackage;

fn corpus(target: &str, file: &str) -> Vec<u8> {
    let path: PathBuf = citywalk_fuzz::crate_dir()
        .join("corpus")
        .join(target)
        .join(file);
    std::fs::read(&path).unwrap_or_else(|e| panic!("{}: {e}", path.display()))
}

#[test]
fn checksum_repair_keeps_intact_packages() {
    for file in [
        "hand_local.package",
        "hand_3857_streets.package",
        "hand_pitched.package",
    ] {
        let bytes = corpus("package", file);
        let package = ScenePackage::from_bytes(&bytes)
            .unwrap_or_else(|e| panic!("seed {file} is not a valid package: {e}"));
        assert_eq!(package.check_invariants(), Ok(()), "seed {file}");
        assert_eq!(
            with_checksums(&bytes).as_deref(),
            Some(&bytes[..]),
            "{file}"
        );
    }
}

#[test]
fn checksum_repair_lets_a_mutation_reach_the_decoders() {
    let mut bytes = corpus("package", "hand_local.package");
    // The last byte belongs to the last section's payload: flipping it fails that checksum,
    // and with the checksums recomputed the package passes verification again, so whatever
    // error remains comes from decoding the payload, not from a checksum.
    *bytes.last_mut().expect("non-empty") ^= 0x55;
    let raw = ScenePackage::from_bytes(&bytes).expect_err("a flipped byte");
    assert!(raw.to_string().contains("checksum"), "{raw}");
    let fixed = with_checksums(&bytes).expect("a package header");
    if let Err(e) = ScenePackage::from_bytes(&fixed) {
        assert!(!e.to_string().contains("checksum"), "{e}");
    }
}

#[test]
fn gltf_and_tileset_seeds_reach_the_assets() {
    let assets = citywalk_fuzz::assets_dir();
    let gltf_path = assets.join("input.gltf");
    let city = gltf::load_bytes(&gltf_path, &corpus("gltf", "amsterdam_4.gltf"))
        .expect("the .gltf seed loads its buffer 4.bin");
    // Tile 4's 4 batch features are its 2 buildings written twice (no batch table names them):
    // the copies with the same triangles are dropped, each with a warning. Without its
    // tileset, the content (in ECEF axes) is levelled by its walls, with a third warning.
    assert_eq!(city.buildings.len(), 2);
    assert_eq!(city.report.warnings.len(), 3, "{}", city.report);
    let levelled = (city.report.warnings.iter())
        .filter(|w| w.message.contains("not georeferenced") && w.message.contains("levelled"))
        .count();
    assert_eq!(levelled, 1, "{:?}", city.report.warnings);
    let tileset_path = assets.join("tileset.json");
    let city = gltf::load_bytes(&tileset_path, &corpus("tileset", "amsterdam_4_6.json"))
        .expect("the tileset seed loads tiles/4.b3dm and tiles/6.b3dm");
    // Tile 4 holds 2 buildings (BAG blockids), tile 6 holds 4.
    assert_eq!(city.buildings.len(), 6);
}
