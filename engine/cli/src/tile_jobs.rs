//! `citywalk preprocess --plan-tiles`, `--tiles-of PLAN --tile I` and `--merge PLAN`: a
//! city's preprocessing as independent tile jobs and their merge
//! ([`citywalk_preprocess::tile_jobs`]). Beside the plan `PLAN` lie the tiles' shards
//! `PLAN.shard-I` (the plan writes them, a job reads its own) and tile files `PLAN.tile-I`
//! (a job writes its own, the merge reads them all).

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use citywalk_preprocess::pipeline::PreprocessParams;
use citywalk_preprocess::tile_jobs::{
    TileJobError, TilePlan, TileResult, TileShard, plan_and_shard, run_tile,
};
use citywalk_scenes::City;
use citywalk_scenes::package::{InputFile, sha256_file};

use crate::preprocess::{Args, load_with_spinner, preprocess_params};

/// `--plan-tiles`: loads the inputs, plans the tiles and writes the plan to `-o`.
pub fn plan(args: &Args, tile_buildings: usize) -> anyhow::Result<()> {
    let start = Instant::now();
    let Some(output) = &args.output else {
        anyhow::bail!("-o/--output: the plan file to write is missing");
    };
    let load_options = args.input.load_options(&args.inputs)?;
    let (city, _) = load_with_spinner(&args.inputs, &load_options, start)?;
    let params = PreprocessParams {
        load: load_options,
        tile_buildings,
        ..preprocess_params(args)
    };
    let inputs = args
        .inputs
        .iter()
        .map(|p| {
            let (size_bytes, sha256) =
                sha256_file(p).with_context(|| format!("cannot read {}", p.display()))?;
            Ok(InputFile {
                path: p.display().to_string(),
                size_bytes,
                sha256: Some(sha256),
            })
        })
        .collect::<anyhow::Result<Vec<_>>>()?;
    let shard_path = |t: usize| sibling(output, None, "shard", t);
    let plan = plan_and_shard(&city, &params, inputs, &shard_path)?;
    std::fs::write(output, plan.to_json())
        .with_context(|| format!("cannot write the plan {}", output.display()))?;
    let mut sizes = plan.tiles.clone();
    sizes.sort_unstable();
    println!(
        "{} tiles of {} buildings (smallest {}, median {}, largest {}) -> {}, shards {}",
        plan.tiles.len(),
        city.buildings.len(),
        sizes.first().unwrap_or(&0),
        sizes.get(sizes.len() / 2).unwrap_or(&0),
        sizes.last().unwrap_or(&0),
        output.display(),
        shard_path(0)
            .display()
            .to_string()
            .replace(".shard-0", ".shard-I")
    );
    println!(
        "next: citywalk preprocess --tiles-of {0} --tile I   (I = 0 to {1}, anywhere, in any order)\n      citywalk preprocess --merge {0} -o city.cwk",
        output.display(),
        plan.tiles.len().saturating_sub(1)
    );
    Ok(())
}

/// `--tiles-of PLAN --tile I`: one tile job, from the tile's shard beside the plan.
pub fn job(args: &Args) -> anyhow::Result<()> {
    let start = Instant::now();
    let (Some(plan_path), Some(tile)) = (&args.tiles_of, args.tile) else {
        anyhow::bail!("--tiles-of PLAN needs --tile I");
    };
    if !args.inputs.is_empty() {
        anyhow::bail!(
            "a tile job reads its tile's shard beside the plan, not input files: leave out {}",
            args.inputs[0].display()
        );
    }
    let plan = read_plan(plan_path)?;
    if tile >= plan.tiles.len() {
        anyhow::bail!(
            "--tile {tile}: the plan {} has tiles 0 to {}",
            plan_path.display(),
            plan.tiles.len().saturating_sub(1)
        );
    }
    let output = args
        .output
        .clone()
        .unwrap_or_else(|| sibling(plan_path, None, "tile", tile));
    let shard = TileShard::read(&sibling(plan_path, None, "shard", tile))?;
    let result = run_tile(shard, &plan)?;
    result.write(&output)?;
    println!(
        "tile {tile}: {} buildings, {} occluders, {} cluster tree nodes ({:.2} s) -> {}",
        result.buildings.len(),
        result.occluders.as_ref().map_or(0, |o| o.occluders.len()),
        result.tree.as_ref().map_or(0, |t| t.nodes.len()),
        start.elapsed().as_secs_f64(),
        output.display()
    );
    Ok(())
}

/// Reads a plan file.
pub fn read_plan(path: &Path) -> anyhow::Result<TilePlan> {
    Ok(TilePlan::read(path)?)
}

/// Tile `tile`'s `kind` file (`shard`, `tile`) of the plan `plan_path`: `PLAN.KIND-I`, in
/// `dir` or beside the plan.
fn sibling(plan_path: &Path, dir: Option<&Path>, kind: &str, tile: usize) -> PathBuf {
    let name = format!(
        "{}.{kind}-{tile}",
        plan_path.file_name().unwrap_or_default().to_string_lossy()
    );
    match dir {
        Some(dir) => dir.join(name),
        None => plan_path.with_file_name(name),
    }
}

/// Loads the plan's inputs (or the ones given in their place, checked to be the same files)
/// with the plan's load options; the seconds since `start` when loaded.
pub fn load_plan_inputs(
    args: &Args,
    plan: &TilePlan,
    start: Instant,
) -> anyhow::Result<(City, f64)> {
    let paths: Vec<PathBuf> = if args.inputs.is_empty() {
        plan.inputs.iter().map(|i| PathBuf::from(&i.path)).collect()
    } else {
        args.inputs.clone()
    };
    if paths.len() != plan.inputs.len() {
        anyhow::bail!(
            "{} inputs given, the plan was made from {}",
            paths.len(),
            plan.inputs.len()
        );
    }
    for (path, planned) in paths.iter().zip(&plan.inputs) {
        let (size, sha256) =
            sha256_file(path).with_context(|| format!("cannot read {}", path.display()))?;
        if size != planned.size_bytes || planned.sha256.as_deref() != Some(sha256.as_str()) {
            anyhow::bail!(
                "{} is not the plan's input {} ({size} bytes, SHA-256 {sha256}; the plan's: {} bytes, {})",
                path.display(),
                planned.path,
                planned.size_bytes,
                planned.sha256.as_deref().unwrap_or("unknown")
            );
        }
    }
    load_with_spinner(&paths, &plan.params.load, start)
}

/// Every tile file of the plan (`--tile-dir` or beside the plan), each read and checked as
/// the merge comes to it (so that one tile's occluders are held at a time).
pub fn read_tiles<'a>(
    args: &'a Args,
    plan_path: &'a Path,
    plan: &TilePlan,
) -> impl Iterator<Item = Result<(String, TileResult), TileJobError>> + 'a {
    (0..plan.tiles.len()).map(move |t| {
        let path = sibling(plan_path, args.tile_dir.as_deref(), "tile", t);
        let result = TileResult::read(&path)?;
        Ok((path.display().to_string(), result))
    })
}
