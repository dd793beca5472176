//! Tile jobs and their merge (issue 17): the package merged from independent tile jobs,
//! each written to and read back from its tile file, is byte for byte the one run's; damaged,
//! missing, repeated and foreign tile files are refused naming the file.

use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_preprocess::tile_jobs::{
    TileJobError, TilePlan, TileResult, TileShard, merge, plan_and_shard, run_tile,
};
use citywalk_scenes::City;
use citywalk_scenes::package::{SceneStore, WriteOptions};
use std::path::Path;

fn generated(buildings: usize, seed: u64) -> City {
    citywalk_scenes::generate::generate_city(&citywalk_scenes::generate::GenerateParams::new(
        buildings, seed,
    ))
    .expect("generated city")
}

#[test]
fn tile_jobs_merge_to_the_one_runs_package_and_bad_tile_files_are_refused() {
    let city = generated(4_000, 3);
    let params = PreprocessParams {
        tile_buildings: 600,
        ..PreprocessParams::default()
    };
    let one_run = preprocess(city.clone(), &params, &NoProgress)
        .expect("one run")
        .to_bytes(WriteOptions::default())
        .expect("encode");

    let dir = tempfile::tempdir().expect("temp dir");
    let plan = plan_of(&city, &params, dir.path());
    assert!(plan.tiles.len() >= 6, "{} tiles", plan.tiles.len());
    assert_eq!(
        plan.tiles.iter().sum::<u32>() as usize,
        city.buildings.len()
    );
    let mut files = Vec::new();
    // Jobs in reverse order: the merge takes them in any.
    for t in (0..plan.tiles.len()).rev() {
        let path = dir.path().join(format!("city.tile-{t}"));
        job(dir.path(), &plan, t)
            .write(&path)
            .expect("write the tile file");
        files.push(path);
    }
    let read = |paths: &[std::path::PathBuf]| -> Vec<(String, TileResult)> {
        paths
            .iter()
            .map(|p| {
                (
                    p.display().to_string(),
                    TileResult::read(p).expect("tile file"),
                )
            })
            .collect()
    };
    // The merge lays its GPU scene out in a scratch file, as the command line's does; in
    // memory, the tiles' occluders are put together whole rather than spilled.
    for store in [SceneStore::ScratchFileIn(dir.path()), SceneStore::Memory] {
        let merged = merge(city.clone(), &plan, given(read(&files)), &NoProgress, store)
            .expect("merge")
            .to_bytes(WriteOptions::default())
            .expect("encode");
        assert!(
            merged == one_run,
            "the package merged with {store:?} differs from the one run's"
        );
    }

    // A missing tile and a tile given twice.
    let mut short = read(&files[1..]);
    let err = merge(
        city.clone(),
        &plan,
        given(short.clone()),
        &NoProgress,
        SceneStore::Memory,
    )
    .expect_err("missing");
    assert!(
        matches!(err, TileJobError::Mismatch(ref m) if m.contains("no tile file")),
        "{err}"
    );
    short.push(short[0].clone());
    let err = merge(
        city.clone(),
        &plan,
        given(short),
        &NoProgress,
        SceneStore::Memory,
    )
    .expect_err("repeated");
    assert!(err.to_string().contains("given twice"), "{err}");

    // A tile of another plan.
    let other = PreprocessParams {
        tile_buildings: 700,
        ..params.clone()
    };
    let other_dir = tempfile::tempdir().expect("temp dir");
    let other_plan = plan_of(&city, &other, other_dir.path());
    let foreign = job(other_dir.path(), &other_plan, 0);
    // Its shard is refused by this plan's job too.
    let shard = TileShard::read(&other_dir.path().join("city.shard-0")).expect("shard");
    let err = run_tile(shard, &plan).expect_err("a shard of another plan");
    assert!(err.to_string().contains("another plan"), "{err}");
    let mut mixed = read(&files);
    mixed[0] = ("foreign".into(), foreign);
    let err = merge(
        city.clone(),
        &plan,
        given(mixed),
        &NoProgress,
        SceneStore::Memory,
    )
    .expect_err("foreign");
    assert!(
        err.to_string().contains("foreign: made for another plan"),
        "{err}"
    );

    // A tile whose occluders claim a building of another tile, and one without occluders.
    let mut stolen = read(&files);
    let theirs = stolen[1].1.buildings[0];
    let outcomes = &mut stolen[0]
        .1
        .occluders
        .as_mut()
        .expect("occluders")
        .per_building;
    outcomes[0].building = citywalk_scenes::BuildingId(theirs);
    let path = stolen[0].0.clone();
    let err = merge(
        city.clone(),
        &plan,
        given(stolen),
        &NoProgress,
        SceneStore::Memory,
    )
    .expect_err("a building's occluders in another tile");
    assert!(
        err.to_string().starts_with(&path)
            && err.to_string().contains("occluders are not its buildings'"),
        "{err}"
    );
    let mut without = read(&files);
    without[3].1.occluders = None;
    let err = merge(
        city.clone(),
        &plan,
        given(without),
        &NoProgress,
        SceneStore::Memory,
    )
    .expect_err("a tile without occluders");
    assert!(err.to_string().contains("has no occluders"), "{err}");

    // A damaged file (one byte flipped in the payload) and a truncated one.
    let bytes = std::fs::read(&files[0]).expect("read");
    let mut flipped = bytes.clone();
    flipped[bytes.len() / 2] ^= 0x40;
    let damaged = dir.path().join("damaged.tile");
    std::fs::write(&damaged, &flipped).expect("write");
    let err = TileResult::read(&damaged).expect_err("damaged");
    assert!(
        matches!(err, TileJobError::Damaged { ref path, ref reason }
            if path.ends_with("damaged.tile") && reason.contains("checksum")),
        "{err}"
    );
    std::fs::write(&damaged, &bytes[..bytes.len() - 9]).expect("write");
    let err = TileResult::read(&damaged).expect_err("truncated");
    assert!(matches!(err, TileJobError::Damaged { .. }), "{err}");
    // The merge stops at a tile file that cannot be read, naming it.
    let mut reads: Vec<Result<(String, TileResult), TileJobError>> =
        read(&files).into_iter().map(Ok).collect();
    reads[2] = TileResult::read(&damaged).map(|r| ("damaged.tile".into(), r));
    let err = merge(city.clone(), &plan, reads, &NoProgress, SceneStore::Memory)
        .expect_err("a damaged tile file");
    assert!(
        matches!(err, TileJobError::Damaged { ref path, .. } if path.ends_with("damaged.tile")),
        "{err}"
    );
}

/// Tile results as the merge reads them, one at a time.
fn given(
    results: Vec<(String, TileResult)>,
) -> impl Iterator<Item = Result<(String, TileResult), TileJobError>> {
    results.into_iter().map(Ok)
}

/// The plan of `city`, its shards written to `dir`.
fn plan_of(city: &City, params: &PreprocessParams, dir: &Path) -> TilePlan {
    let shard = |t: usize| dir.join(format!("city.shard-{t}"));
    plan_and_shard(city, params, Vec::new(), &shard).expect("plan")
}

/// Tile `t`'s job, reading only its shard from `dir`.
fn job(dir: &Path, plan: &TilePlan, t: usize) -> TileResult {
    let shard = TileShard::read(&dir.join(format!("city.shard-{t}"))).expect("shard");
    run_tile(shard, plan).expect("tile job")
}

/// A city without streets bounding blocks has no tiles: the plan says so.
#[test]
fn a_city_without_street_blocks_cannot_be_tiled() {
    let mut city = generated(300, 5);
    city.streets.clear();
    let dir = tempfile::tempdir().expect("temp dir");
    let shard = |t: usize| dir.path().join(format!("city.shard-{t}"));
    let err = plan_and_shard(&city, &PreprocessParams::default(), Vec::new(), &shard)
        .expect_err("no tiles");
    assert!(matches!(err, TileJobError::NoStreetBlocks), "{err}");
}
