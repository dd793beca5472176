//! `citywalk preprocess INPUT... -o city.cwk [--json]`: loads the inputs into one city, runs
//! the preprocessing pipeline (blocks, occluders, cluster tree, B-Quadtree) with a progress
//! line per stage, writes the scene package and prints a summary.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use anyhow::Context;
use citywalk_bench::output::resident_mib;
use citywalk_preprocess::memory_budget::{BudgetReport, MemoryBudget};
use citywalk_preprocess::pipeline::{
    DEFAULT_TILE_BUILDINGS, PreprocessParams, ProgressSink, Stage, preprocess_with,
};
use citywalk_preprocess::tile_jobs::merge;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::texture_bake::{BakeStats, bake_cluster_textures};
use citywalk_scenes::cluster_texture::bins::CHANG_BIN_SIDE_PX;
use citywalk_scenes::package::{
    ScenePackage, SceneStore, StageTiming, WriteOptions, check_output_path,
};
use citywalk_scenes::{City, LoadOptions, load_cities};
use indicatif::{MultiProgress, ProgressBar, ProgressStyle};
use serde::Serialize;

use crate::input_args::InputArgs;
use crate::report_items::{self, ReportItem};

/// Arguments of `citywalk preprocess`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Input files (OSM PBF, GeoJSON, CityJSON, glTF/GLB, OBJ), merged into one city. With
    /// `--merge`: the plan's inputs by default; given, they must be the same files (size and
    /// SHA-256) wherever they lie. A `--tiles-of` job reads none: its tile's shard holds its
    /// buildings.
    #[arg(required_unless_present_any = ["tiles_of", "merge"])]
    pub(crate) inputs: Vec<PathBuf>,
    #[command(flatten)]
    pub(crate) input: InputArgs,
    /// The scene package to write (with `--plan-tiles`: the plan; with `--tiles-of`: the tile
    /// file, by default `PLAN.tile-I` beside the plan).
    #[arg(short, long)]
    pub(crate) output: Option<PathBuf>,
    /// Plan tile jobs instead of preprocessing: write the city's tiles, inputs and parameters
    /// to the plan file `-o PLAN` and each tile's buildings to `PLAN.shard-I` beside it, for
    /// `--tiles-of PLAN --tile I` jobs and a `--merge PLAN`.
    #[arg(long, conflicts_with_all = ["tiles_of", "merge", "cluster_textures"])]
    pub(crate) plan_tiles: bool,
    /// Run tile job `--tile I` of the plan PLAN: that tile's occluders and cluster tree, from
    /// its shard `PLAN.shard-I` beside the plan, to a checksummed tile file. Jobs are
    /// independent and may run anywhere, each holding one tile.
    #[arg(long, value_name = "PLAN", requires = "tile", conflicts_with_all = ["merge", "cluster_textures"])]
    pub(crate) tiles_of: Option<PathBuf>,
    /// The tile of `--tiles-of` (0 to the plan's tile count - 1).
    #[arg(long, value_name = "I", requires = "tiles_of")]
    pub(crate) tile: Option<usize>,
    /// Merge the tile files of the plan PLAN (`PLAN.tile-0`, ... beside it, or in
    /// `--tile-dir`) into the package `-o`: the same package as one run with the plan's
    /// parameters.
    #[arg(long, value_name = "PLAN")]
    pub(crate) merge: Option<PathBuf>,
    /// With `--merge`: the folder holding the tile files (default: the plan's).
    #[arg(long, value_name = "DIR", requires = "merge")]
    pub(crate) tile_dir: Option<PathBuf>,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Leave out the virtual occluders.
    #[arg(long)]
    no_occluders: bool,
    /// Leave out the cluster tree.
    #[arg(long)]
    no_cluster_tree: bool,
    /// Also store the stage timings in the package (then the file is no longer byte-for-byte
    /// reproducible).
    #[arg(long)]
    store_timings: bool,
    /// Bake the cluster meshes' textures (Chang et al. 2008 §7: a side texture of every
    /// cluster's walls and five roof views) on the GPU, headless (a software adapter such as
    /// lavapipe will do), and store them in the package.
    #[arg(long)]
    cluster_textures: bool,
    /// With `--cluster-textures`: the side of each texture bin's budget, in texels per view
    /// (Chang: 1024).
    #[arg(long, default_value_t = CHANG_BIN_SIDE_PX, value_parser = clap::value_parser!(u32).range(16..=8192))]
    texture_bin_px: u32,
    /// Threads for the work that runs in parallel (occluders; the cluster tree's clustering,
    /// hulls, errors and meshes block by block or node by node; 0: one per core); fewer under
    /// `--memory-budget-gib`. The package is the same for every count.
    #[arg(long, default_value_t = 0)]
    threads: usize,
    /// The most buildings of a tile: the cluster tree is built tile by tile (whole blocks
    /// along the B-Quadtree, each on a thread of its own), the tiles' roots clustered above
    /// them. A city of no more buildings, or without streets that bound blocks, is one tile.
    #[arg(long, default_value_t = DEFAULT_TILE_BUILDINGS as u64, value_parser = clap::value_parser!(u64).range(1..))]
    tile_buildings: u64,
    /// The folder of the scratch files (default: the package's): the occluder set, encoded as
    /// its section once made, the occluders' drawable arrays, and the GPU scene, laid out
    /// through a memory map whose written pages leave the process's memory; the package is
    /// written from them; with `--merge`, also the tiles' occluders, put aside as each tile file
    /// is read. The files have no name and go when the run ends. They need about 2.1 GB free
    /// at a million buildings (a merge's and its package together took 3.9 GB).
    #[arg(long, value_name = "DIR")]
    scratch_dir: Option<PathBuf>,
    /// A ceiling on the run's resident memory, in GiB: the load runs on one thread, the
    /// stages on as many of `--threads` as fit beside the loaded city, and the cluster tree's
    /// tiles are started only while what is resident and their estimated working memory fit
    /// it, down to one thread and one tile at a time (the package is the same). The largest
    /// sets are spilled to the scratch files whatever the budget. The summary says whether
    /// the peak kept to it and, if not, after which step it went over (the load alone may).
    /// A merge (`--merge`) takes it as a run does. A tile job's memory is bounded by
    /// `--tile-buildings` instead (jobs of 65,536 buildings peaked under 320 MiB at 10M).
    #[arg(long, value_name = "GIB", value_parser = positive_gib, conflicts_with_all = ["plan_tiles", "tiles_of"])]
    memory_budget_gib: Option<f64>,
}

fn positive_gib(text: &str) -> Result<f64, String> {
    match text.parse::<f64>() {
        Ok(gib) if gib.is_finite() && gib > 0.0 && gib < 1e6 => Ok(gib),
        _ => Err(format!("{text} is not a positive number of GiB")),
    }
}

/// One spinner per stage; the process's memory at the end of each; the memory budget.
struct Bars {
    multi: MultiProgress,
    bars: std::cell::RefCell<Vec<(Stage, ProgressBar)>>,
    memory: std::cell::RefCell<Vec<StepMemory>>,
    budget: Option<MemoryBudget>,
}

/// The process's resident memory at the end of a step of the run, and its peak so far (MiB;
/// `None` off Linux): where the memory of a large city goes.
#[derive(Debug, Serialize)]
struct StepMemory {
    step: String,
    resident_mib: Option<f64>,
    peak_mib: Option<f64>,
}

impl StepMemory {
    fn now(step: &str) -> StepMemory {
        let (resident_mib, peak_mib) = resident_mib();
        StepMemory {
            step: step.into(),
            resident_mib,
            peak_mib,
        }
    }
}

impl std::fmt::Debug for Bars {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("Bars")
    }
}

impl ProgressSink for Bars {
    fn settle(&self) {
        crate::allocator::give_back_freed_memory();
    }

    fn memory_budget(&self) -> Option<&MemoryBudget> {
        self.budget.as_ref()
    }

    fn stage_started(&self, stage: Stage) {
        let bar = self.multi.add(ProgressBar::new_spinner());
        if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} {elapsed}") {
            bar.set_style(style);
        }
        bar.set_message(stage.name().to_string());
        bar.enable_steady_tick(Duration::from_millis(120));
        self.bars.borrow_mut().push((stage, bar));
    }

    fn stage_finished(&self, stage: Stage, seconds: f64, summary: &str) {
        self.memory.borrow_mut().push(StepMemory::now(stage.name()));
        if let Some((_, bar)) = self.bars.borrow().iter().find(|(s, _)| *s == stage) {
            bar.finish_with_message(format!("{}: {summary} ({seconds:.2} s)", stage.name()));
        }
    }
}

/// The summary printed at the end (and as JSON with `--json`).
#[derive(Debug, Serialize)]
struct Summary {
    output: String,
    package_bytes: u64,
    buildings_found: usize,
    buildings_loaded: usize,
    buildings_rejected: usize,
    streets_found: usize,
    streets_rejected: usize,
    /// Every rejected building and street: kind, file, source id, reason.
    rejected: Vec<ReportItem>,
    /// Every load warning: file, source id (empty for the file as a whole), message.
    load_warnings: Vec<ReportItem>,
    streets: usize,
    occluders: Option<usize>,
    occluder_triangles: Option<usize>,
    cluster_tree_nodes: Option<usize>,
    cluster_tree_depth: Option<u32>,
    blocks: usize,
    buildings_per_block_min_median_max: Option<(usize, usize, usize)>,
    quadtree_nodes: usize,
    quadtree_leaves: usize,
    quadtree_depth: u32,
    /// Threads the parallel stages ran on.
    threads: usize,
    load_seconds: f64,
    stage_seconds: Vec<(String, f64)>,
    write_seconds: f64,
    total_seconds: f64,
    peak_memory_bytes: Option<u64>,
    /// After the load, each stage and the write: resident memory and the peak so far.
    step_memory: Vec<StepMemory>,
    warnings: Vec<String>,
    skipped_stages: Vec<String>,
    /// `None` without `--cluster-textures`.
    cluster_textures: Option<TextureSummary>,
    /// `None` without `--memory-budget-gib`.
    memory_budget: Option<BudgetSummary>,
}

/// What `--memory-budget-gib` did.
#[derive(Debug, Serialize)]
struct BudgetSummary {
    budget_mib: f64,
    /// Whether the run's resident peak kept to the budget.
    kept: bool,
    /// The first step after which the peak was over the budget (`load`: the input alone).
    first_step_over: Option<String>,
    /// The cluster tree's tile jobs under the budget.
    tile_jobs: BudgetReport,
}

impl BudgetSummary {
    fn of(budget: &MemoryBudget, steps: &[StepMemory]) -> Option<BudgetSummary> {
        let limit = budget.limit_bytes()?;
        let budget_mib = limit as f64 / 1_048_576.0;
        let over = |m: &&StepMemory| m.peak_mib.is_some_and(|peak| peak > budget_mib);
        let first_step_over = steps.iter().find(over).map(|m| m.step.clone());
        Some(BudgetSummary {
            budget_mib,
            kept: first_step_over.is_none(),
            first_step_over,
            tile_jobs: budget.report(),
        })
    }
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let start = Instant::now();
    if args.plan_tiles || args.tiles_of.is_some() {
        start_threads(args.threads)?;
        return if args.plan_tiles {
            crate::tile_jobs::plan(&args, tile_buildings(&args))
        } else {
            crate::tile_jobs::job(&args)
        };
    }
    let Some(output) = args.output.clone() else {
        anyhow::bail!("-o/--output: the scene package to write is missing");
    };
    // Refuse a device, a folder or a read-only file before minutes of work, not after.
    check_output_path(&output).context("cannot write the package")?;
    if args.cluster_textures && args.no_cluster_tree {
        anyhow::bail!(
            "--cluster-textures needs the cluster tree (drop --no-cluster-tree): the textures are the cluster meshes'"
        );
    }
    let scratch_dir = scratch_dir(&args, &output);
    // A scratch file the folder cannot take fails here, not after minutes of work.
    tempfile::tempfile_in(&scratch_dir)
        .with_context(|| format!("cannot use {} for scratch files", scratch_dir.display()))?;
    let store = SceneStore::ScratchFileIn(&scratch_dir);
    // A merge loads the plan's inputs (checked against it) with the plan's options.
    let merging = match &args.merge {
        Some(plan_path) => Some((plan_path, crate::tile_jobs::read_plan(plan_path)?)),
        None => None,
    };
    let load_options = match &merging {
        Some((_, plan)) => plan.params.load.clone(),
        None => args.input.load_options(&args.inputs)?,
    };
    // The load on threads of its own, so that the stages' threads can be as many as the
    // memory budget leaves room for beside the city. Under a budget the load runs on one:
    // its parallel part (projecting and cleaning the polygons) has every thread hold the
    // cleaned copies while the raw ones, freed into the parsing thread's heap, wait for
    // that thread to reuse them (at 100k, 8 threads peaked 60 MiB above one).
    let load_threads = if args.memory_budget_gib.is_some() {
        1
    } else {
        args.threads
    };
    let (city, load_seconds) = rayon::ThreadPoolBuilder::new()
        .num_threads(load_threads)
        .build()
        .context("cannot start the load's threads")?
        .install(|| {
            let loaded = match &merging {
                Some((_, plan)) => crate::tile_jobs::load_plan_inputs(&args, plan, start),
                None => load_with_spinner(&args.inputs, &load_options, start),
            };
            // The raw areas freed on these threads, given back before they end.
            crate::allocator::give_back_freed_memory();
            loaded
        })?;
    let bars = Bars::after_load(budget_of(&args));
    if let Some(warning) = bars.load_over_budget() {
        eprintln!("warning: {warning}");
    }
    start_threads(bars.threads_within(&args, city.buildings.len()))?;
    let mut package = match merging {
        Some((plan_path, plan)) => {
            let results = crate::tile_jobs::read_tiles(&args, plan_path, &plan);
            merge(city, &plan, results, &bars, store).context("cannot merge the tiles")?
        }
        None => {
            let params = PreprocessParams {
                load: load_options,
                ..preprocess_params(&args)
            };
            preprocess_with(city, &params, &bars, None, store).context("preprocessing failed")?
        }
    };
    let textures = if args.cluster_textures {
        let baked = bake_textures(&mut package, args.texture_bin_px)?;
        bars.memory
            .borrow_mut()
            .push(StepMemory::now("cluster textures"));
        Some(baked)
    } else {
        None
    };
    let write_start = Instant::now();
    let bytes = package
        .write(
            &output,
            WriteOptions {
                include_timings: args.store_timings,
            },
        )
        .context("cannot write the package")?;
    let write_seconds = write_start.elapsed().as_secs_f64();
    bars.memory.borrow_mut().push(StepMemory::now("write"));

    let mut summary = summarise(&package, &output, bytes, load_seconds, write_seconds, start);
    summary.cluster_textures = textures.map(TextureSummary::from);
    summary.step_memory = bars.memory.take();
    if let Some(budget) = &bars.budget {
        summary.memory_budget = BudgetSummary::of(budget, &summary.step_memory);
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary);
    }
    Ok(())
}

/// `--scratch-dir`, or the folder `output` is written to.
fn scratch_dir(args: &Args, output: &Path) -> PathBuf {
    match (&args.scratch_dir, output.parent()) {
        (Some(dir), _) => dir.clone(),
        (None, Some(parent)) if !parent.as_os_str().is_empty() => parent.to_path_buf(),
        (None, _) => PathBuf::from("."),
    }
}

/// The rayon pool of `--threads` (0: one thread per core).
fn start_threads(threads: usize) -> anyhow::Result<()> {
    rayon::ThreadPoolBuilder::new()
        .num_threads(threads)
        .build_global()
        .context("cannot start the worker threads")
}

fn tile_buildings(args: &Args) -> usize {
    usize::try_from(args.tile_buildings).unwrap_or(usize::MAX)
}

/// The parameters the command line sets (the load options apart).
pub(crate) fn preprocess_params(args: &Args) -> PreprocessParams {
    PreprocessParams {
        build_occluders: !args.no_occluders,
        build_cluster_tree: !args.no_cluster_tree,
        tile_buildings: tile_buildings(args),
        ..PreprocessParams::default()
    }
}

/// Loads `inputs` behind a spinner; the seconds since `start` when done.
pub(crate) fn load_with_spinner(
    inputs: &[PathBuf],
    load_options: &LoadOptions,
    start: Instant,
) -> anyhow::Result<(City, f64)> {
    let load = ProgressBar::new_spinner();
    if let Ok(style) = ProgressStyle::with_template("{spinner} {msg} {elapsed}") {
        load.set_style(style);
    }
    load.set_message(format!("loading {} input(s)", inputs.len()));
    load.enable_steady_tick(Duration::from_millis(120));
    let city = load_cities(inputs, load_options).context("cannot load the inputs")?;
    let load_seconds = start.elapsed().as_secs_f64();
    load.finish_with_message(format!("load: {} ({load_seconds:.2} s)", city.report));
    Ok((city, load_seconds))
}

impl Bars {
    /// The stages' spinners, the memory after the load recorded first.
    fn after_load(budget: Option<MemoryBudget>) -> Bars {
        Bars {
            multi: MultiProgress::new(),
            bars: Default::default(),
            memory: std::cell::RefCell::new(vec![StepMemory::now("load")]),
            budget,
        }
    }

    /// The threads of the stages: `--threads` (0: rayon's default, one per core), fewer if
    /// the memory budget has no room for them beside a city of `buildings`.
    fn threads_within(&self, args: &Args, buildings: usize) -> usize {
        let Some(budget) = &self.budget else {
            return args.threads;
        };
        let requested = match args.threads {
            0 => std::thread::available_parallelism().map_or(1, |n| n.get()),
            n => n,
        };
        budget.threads_within(requested, buildings, tile_buildings(args))
    }

    /// Why the budget cannot be kept, when the load alone went over it.
    fn load_over_budget(&self) -> Option<String> {
        let budget_mib = self.budget.as_ref()?.limit_bytes()? as f64 / 1_048_576.0;
        let peak_mib = self.memory.borrow().first()?.peak_mib?;
        (peak_mib > budget_mib).then(|| {
            format!(
                "the load alone peaked at {peak_mib:.0} MiB, over the memory budget of {budget_mib:.0} MiB: the run's peak is over it whatever the stages do (the budget does not bound the load's parse)"
            )
        })
    }
}

/// The budget of `--memory-budget-gib`.
fn budget_of(args: &Args) -> Option<MemoryBudget> {
    let gib = args.memory_budget_gib?;
    Some(MemoryBudget::new((gib * 1_073_741_824.0) as u64))
}

/// Bakes the cluster textures of `package` on a headless GPU and stores them in it.
fn bake_textures(package: &mut ScenePackage, bin_side_px: u32) -> anyhow::Result<BakeStats> {
    let Some(tree) = package.cluster_tree.as_ref() else {
        anyhow::bail!(
            "no cluster tree was built ({}), so there are no cluster meshes to texture",
            package.provenance.skipped_stages.join("; ")
        );
    };
    let spinner = ProgressBar::new_spinner();
    spinner.set_message("cluster textures");
    spinner.enable_steady_tick(Duration::from_millis(120));
    let gpu = GpuContext::headless().context("cannot bake the cluster textures")?;
    let (textures, stats) =
        bake_cluster_textures(&gpu, &package.gpu_scene.view(), tree, bin_side_px)
            .context("cannot bake the cluster textures")?;
    spinner.finish_with_message(format!(
        "cluster textures: {} clusters in {} bins on {} ({:.2} s)",
        stats.clusters,
        stats.bins,
        gpu.adapter_summary(),
        stats.seconds
    ));
    package.cluster_textures = Some(textures);
    package
        .provenance
        .counts
        .insert("textured clusters".into(), stats.clusters as u64);
    package.timings.push(StageTiming {
        stage: "cluster textures".into(),
        seconds: stats.seconds,
    });
    Ok(stats)
}

/// What the texture bake did, for the summary.
#[derive(Debug, Serialize)]
struct TextureSummary {
    clusters: usize,
    /// Cluster meshes with walls; those not among `clusters` have more walls than their cell
    /// holds.
    candidates: usize,
    bins: usize,
    pages: usize,
    texels: u64,
    compressed_bytes: u64,
    seconds: f64,
    /// Of `seconds`, the PNG compression on the CPU.
    compress_seconds: f64,
    clusters_per_second: f64,
}

impl From<BakeStats> for TextureSummary {
    fn from(s: BakeStats) -> Self {
        TextureSummary {
            clusters: s.clusters,
            candidates: s.candidates,
            bins: s.bins,
            pages: s.pages,
            texels: s.texels,
            compressed_bytes: s.compressed_bytes,
            seconds: s.seconds,
            compress_seconds: s.compress_seconds,
            clusters_per_second: s.clusters as f64 / s.seconds.max(1e-9),
        }
    }
}

fn summarise(
    package: &ScenePackage,
    output: &Path,
    package_bytes: u64,
    load_seconds: f64,
    write_seconds: f64,
    start: Instant,
) -> Summary {
    let report = &package.provenance.load_report;
    let (rejected, load_warnings) = report_items::items(report);
    // The provenance's counts: a set spilled to its section is not in memory to count.
    let count = |name: &str| {
        package
            .provenance
            .counts
            .get(name)
            .map(|&v| usize::try_from(v).unwrap_or(usize::MAX))
    };
    Summary {
        output: output.display().to_string(),
        package_bytes,
        buildings_found: report.buildings_found,
        buildings_loaded: report.buildings_loaded,
        buildings_rejected: report.rejected.len(),
        streets_found: report.streets_found,
        streets_rejected: report.streets_rejected.len(),
        rejected,
        load_warnings,
        streets: package.streets.len(),
        occluders: count("occluders"),
        occluder_triangles: count("occluder_triangles"),
        cluster_tree_nodes: package.cluster_tree.as_ref().map(|t| t.nodes.len()),
        cluster_tree_depth: package.cluster_tree.as_ref().map(|t| t.max_depth()),
        blocks: package.blocks.blocks.len(),
        buildings_per_block_min_median_max: package.blocks.size_stats(),
        quadtree_nodes: package.quadtree.nodes.len(),
        quadtree_leaves: package.quadtree.leaf_count(),
        quadtree_depth: package.quadtree.max_depth(),
        threads: rayon::current_num_threads(),
        load_seconds,
        stage_seconds: package
            .timings
            .iter()
            .map(|t| (t.stage.clone(), t.seconds))
            .collect(),
        write_seconds,
        total_seconds: start.elapsed().as_secs_f64(),
        peak_memory_bytes: resident_mib().1.map(|mib| (mib * 1048576.0) as u64),
        step_memory: Vec::new(),
        warnings: package.provenance.warnings.clone(),
        skipped_stages: package.provenance.skipped_stages.clone(),
        cluster_textures: None,
        memory_budget: None,
    }
}

fn print_summary(s: &Summary) {
    let opt = |v: Option<usize>| v.map_or("not built".to_string(), |v| v.to_string());
    println!(
        "wrote {} ({:.1} MiB)",
        s.output,
        s.package_bytes as f64 / 1048576.0
    );
    println!(
        "buildings: {} found, {} loaded, {} rejected; streets: {} found, {} loaded, {} rejected",
        s.buildings_found,
        s.buildings_loaded,
        s.buildings_rejected,
        s.streets_found,
        s.streets,
        s.streets_rejected
    );
    report_items::print(&s.rejected, &s.load_warnings);
    println!(
        "occluders: {} ({} triangles)",
        opt(s.occluders),
        opt(s.occluder_triangles)
    );
    println!(
        "cluster tree: {} nodes, depth {}",
        opt(s.cluster_tree_nodes),
        s.cluster_tree_depth.map_or("-".into(), |d| d.to_string())
    );
    match s.buildings_per_block_min_median_max {
        Some((lo, med, hi)) => println!(
            "blocks: {} (buildings per block: min {lo}, median {med}, max {hi})",
            s.blocks
        ),
        None => println!("blocks: {}", s.blocks),
    }
    println!(
        "quadtree: {} nodes, {} leaves, depth {}",
        s.quadtree_nodes, s.quadtree_leaves, s.quadtree_depth
    );
    print!("time: load {:.2} s", s.load_seconds);
    for (stage, seconds) in &s.stage_seconds {
        print!(", {stage} {seconds:.2} s");
    }
    println!(
        ", write {:.2} s; total {:.2} s",
        s.write_seconds, s.total_seconds
    );
    if let Some(t) = &s.cluster_textures {
        println!(
            "cluster textures: {} of {} cluster meshes in {} bins on {} pages, {:.1} Mtexels, {:.1} MiB compressed; {:.2} s, {:.2} s of it compressing ({:.0} clusters/s)",
            t.clusters,
            t.candidates,
            t.bins,
            t.pages,
            t.texels as f64 / 1e6,
            t.compressed_bytes as f64 / 1048576.0,
            t.seconds,
            t.compress_seconds,
            t.clusters_per_second
        );
    }
    if let Some(peak) = s.peak_memory_bytes {
        println!("peak memory: {:.0} MiB", peak as f64 / 1048576.0);
    }
    let mib = |v: Option<f64>| v.map_or("-".to_string(), |m| format!("{m:.0}"));
    let steps: Vec<String> = s
        .step_memory
        .iter()
        .map(|m| format!("{} {} / {}", m.step, mib(m.resident_mib), mib(m.peak_mib)))
        .collect();
    if !steps.is_empty() {
        println!(
            "memory (MiB resident / peak so far, after each step): {}",
            steps.join(", ")
        );
    }
    if let Some(b) = &s.memory_budget {
        let verdict = match &b.first_step_over {
            None => "kept".to_string(),
            Some(step) => format!("over it after {step}"),
        };
        println!(
            "memory budget: {:.0} MiB, {verdict}; tile jobs at most {} at once, {} held back",
            b.budget_mib, b.tile_jobs.most_jobs_at_once, b.tile_jobs.jobs_held_back
        );
    }
    for w in &s.warnings {
        println!("warning: {w}");
    }
    for k in &s.skipped_stages {
        println!("skipped: {k}");
    }
}
