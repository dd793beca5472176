//! `citywalk generate`: a procedural city written as GeoJSON in local metres.
//!
//! `citywalk generate --buildings 100000 --seed 7 -o city.geojson` streams exactly that many
//! buildings (with their Z-level parts) and the streets around them; the same seed always
//! gives the same file. See `citywalk_scenes::generate` for the file contract.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::Context;
use citywalk_scenes::generate::{GenerateParams, write_geojson_file};
use indicatif::{ProgressBar, ProgressDrawTarget, ProgressStyle};

/// Arguments of `citywalk generate`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Exact number of buildings (1 to 20,000,000).
    #[arg(long, default_value_t = 10_000)]
    buildings: usize,
    /// Seed of every random choice; the same seed gives the same file.
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Output GeoJSON file.
    #[arg(short, long)]
    output: PathBuf,
    /// Mean distance between neighbouring street centre lines across the columns (metres,
    /// 60 to 400); rows are 1.2–1.9× further apart.
    #[arg(long, default_value_t = 100.0)]
    block_size_m: f64,
    /// One landmark per this many buildings (at least one); 0 for none.
    #[arg(long, default_value_t = 2_000)]
    landmark_every: usize,
    /// Leave out the diagonal avenues.
    #[arg(long)]
    no_diagonals: bool,
}

/// The bar appears only once the work has taken this long.
const SHOW_PROGRESS_AFTER: Duration = Duration::from_secs(1);

pub fn run(args: Args) -> anyhow::Result<()> {
    let params = GenerateParams {
        buildings: args.buildings,
        seed: args.seed,
        block_size_m: args.block_size_m,
        landmark_every: args.landmark_every,
        diagonals: !args.no_diagonals,
    };
    params.validate()?;
    let start = Instant::now();
    let bar =
        ProgressBar::with_draw_target(Some(args.buildings as u64), ProgressDrawTarget::hidden());
    bar.set_style(
        ProgressStyle::with_template("{spinner} generating {pos}/{len} buildings {wide_bar} {eta}")
            .context("progress bar template")?,
    );
    let mut progress = |done: usize| {
        if bar.is_hidden() && start.elapsed() > SHOW_PROGRESS_AFTER {
            bar.set_draw_target(ProgressDrawTarget::stderr());
        }
        bar.set_position(done as u64);
    };
    let summary =
        write_geojson_file(&params, &args.output, &mut progress).context("generating the city")?;
    bar.finish_and_clear();
    let [w, d] = summary.extent_m();
    eprintln!(
        "generated {}: {} buildings, {} parts, {} streets, {} landmarks, extent {:.1} × {:.1} km, tallest {:.0} m, in {:.2} s",
        args.output.display(),
        summary.buildings,
        summary.parts,
        summary.streets,
        summary.landmarks,
        w / 1000.0,
        d / 1000.0,
        summary.max_height_m,
        start.elapsed().as_secs_f64()
    );
    Ok(())
}
