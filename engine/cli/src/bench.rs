//! `citywalk bench SCENE... --out DIR`: the occlusion benchmark. Every frame of every path and
//! mode is checked against the exact visibility oracle; the process exits non-zero if any
//! visible building was culled, after writing all outputs.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use citywalk_bench::baseline::{BaselineTarget, DecimatedBaseline};
use citywalk_bench::decimate::decimate_city;
use citywalk_bench::plots::write_plots;
use citywalk_bench::{
    AdapterSummary, BenchConfig, BenchRenderers, BenchReport, BenchScene, FrameRecord, Mode,
    SceneLoad, TextureUse, resident_mib, run_path, summarise, write_outputs,
};
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::lod::LodCriterion;
use citywalk_runtime::scene_gpu::{SceneGeometry, SceneGpu};
use citywalk_scenes::LoadOptions;
use citywalk_scenes::camera_path::{CameraPath, GeneratedPath};
use citywalk_scenes::city_sphere::CitySphere;
use citywalk_scenes::package::PackageParts;

use crate::scene_input::{SceneInputs, load_scene, load_scene_to_draw};

/// Arguments of `citywalk bench`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// Scenes: packages (.cwk) or any loadable input (preprocessed on the fly).
    #[arg(required_unless_present = "list_modes")]
    pub scenes: Vec<PathBuf>,
    #[command(flatten)]
    pub input: crate::input_args::InputArgs,
    #[command(flatten)]
    pub textures: crate::texture_args::TextureArgs,
    /// Output folder for frames.csv, bench.json, summary.md, path files and PNG frames.
    #[arg(long, required_unless_present = "list_modes")]
    pub out: Option<PathBuf>,
    /// Print the modes this build implements, comma-separated, and exit.
    #[arg(long)]
    pub list_modes: bool,
    /// Camera paths generated per scene: street (the whole street route, frames spread over
    /// it), walk (an interactive walkthrough: 3 m per frame from the route's middle), flyover,
    /// dive, overview (from three city diameters away in, once round the city, and away: its
    /// far views are reported apart).
    #[arg(long, default_value = "street,walk,flyover,dive")]
    pub paths: String,
    /// Path files to replay in addition to (or, with --paths "", instead of) generated ones.
    #[arg(long = "path-file")]
    pub path_files: Vec<PathBuf>,
    /// Culling modes: brute, frustum, quadtree, hzb, occluders, lod, all (quadtree + LOD + HZB +
    /// occluders), oracle (exactly the oracle's visible set: the fastest any culling could be).
    #[arg(long, default_value = "brute,frustum,quadtree")]
    pub modes: String,
    /// LOD criterion of the `lod` mode: auto (the geometric criterion at 1 px at street level,
    /// 2 px above the roofs), geometric-street (1 px), geometric-roofs (2 px),
    /// chang-walkthrough (ε = τ = 1 px), chang-flyover (ε = τ = 2 px), chang-paper (ε = 100,
    /// τ = 2 px), yang-paper (δh = 20 px, δa = 200 px²).
    #[arg(long, default_value = "auto")]
    pub lod_criterion: String,
    /// Frames per generated path (at least 1).
    #[arg(long, default_value_t = 60, value_parser = clap::builder::RangedU64ValueParser::<usize>::new().range(1..))]
    pub frames: usize,
    /// Viewport in pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = crate::cli_args::parse_size)]
    pub size: (u32, u32),
    /// Write a PNG of every N-th frame of each path and mode (0: none).
    #[arg(long, default_value_t = 0)]
    pub png_every: usize,
    /// Print bench.json to standard output (alone: the summary table then goes to standard
    /// error).
    #[arg(long)]
    pub json: bool,
    /// Also measure the baseline a user would pick instead: the whole city decimated with
    /// meshoptimizer and drawn unculled, as the pseudo-mode `decimated`. `decimate:N` (N
    /// triangles), `decimate:P%` (P % of the city's triangles) or `decimate:MODE` (the mean
    /// triangles per frame MODE drew on the scene; MODE must be among --modes).
    #[arg(long, value_parser = BaselineTarget::parse)]
    pub baseline: Option<BaselineTarget>,
}

/// The `--lod-criterion` of this run, set once by [`run`] (unset: auto), read where the scenes
/// are loaded; kept out of the shared `run_benchmark_with` signature.
static LOD_CRITERION: std::sync::OnceLock<Option<LodCriterion>> = std::sync::OnceLock::new();

/// The `--texture-budget-mib` of this run, set once by [`run`] (unset, as in `demo`: the
/// default budget), read where the scenes are loaded, as [`LOD_CRITERION`].
static TEXTURES: std::sync::OnceLock<crate::texture_args::TextureArgs> = std::sync::OnceLock::new();

pub fn run(args: Args) -> anyhow::Result<()> {
    let lod_criterion = LodCriterion::parse(&args.lod_criterion).map_err(anyhow::Error::msg)?;
    let _ = LOD_CRITERION.set(lod_criterion);
    let _ = TEXTURES.set(args.textures);
    if args.list_modes {
        println!("{}", Mode::NAMED.map(Mode::name).join(","));
        return Ok(());
    }
    let out = args.out.clone().context("--out is required")?;
    let modes = Mode::parse_list(&args.modes).map_err(anyhow::Error::msg)?;
    let config = BenchConfig {
        modes,
        width: args.size.0,
        height: args.size.1,
        frames_dir: (args.png_every > 0).then(|| out.clone()),
        png_every: args.png_every,
    };
    let path_kinds = parse_path_kinds(&args.paths)?;
    if path_kinds.is_empty() && args.path_files.is_empty() {
        anyhow::bail!(
            "no camera path to measure: --paths {:?} names none and no --path-file is given \
             (paths: {})",
            args.paths,
            GeneratedPath::list(&GeneratedPath::ALL)
        );
    }
    let replayed: Vec<CameraPath> = args
        .path_files
        .iter()
        .map(|p| CameraPath::read(p).with_context(|| format!("reading path {}", p.display())))
        .collect::<Result<_, _>>()?;
    if let Some(BaselineTarget::MeanOfMode(mode)) = args.baseline
        && !config.modes.contains(&mode)
    {
        anyhow::bail!("--baseline decimate:{mode} needs mode '{mode}' in --modes");
    }
    let load = args.input.load_options(&args.scenes)?;
    let report = run_benchmark_with(
        SceneInputs {
            paths: &args.scenes,
            load: &load,
        },
        &out,
        &path_kinds,
        &replayed,
        args.frames,
        &config,
        args.baseline,
    )?;
    let summary = citywalk_bench::output::summary_markdown(&report);
    if args.json {
        // Standard output holds the JSON alone (for pipes); the table goes to standard error.
        eprint!("{summary}");
        println!("{}", serde_json::to_string_pretty(&report)?);
        eprintln!("wrote {}", out.display());
    } else {
        print!("{summary}");
        println!("wrote {}", out.display());
    }
    let false_culls = report.false_culls();
    if false_culls > 0 {
        anyhow::bail!(
            "{false_culls} false culls: visible buildings were culled (see {}/frames.csv)",
            out.display()
        );
    }
    Ok(())
}

/// The generated path kinds, in order.
pub fn parse_path_kinds(list: &str) -> anyhow::Result<Vec<GeneratedPath>> {
    list.split(',')
        .map(str::trim)
        .filter(|w| !w.is_empty())
        .map(|word| {
            GeneratedPath::named(word).with_context(|| {
                format!(
                    "unknown path '{word}' (paths: {})",
                    GeneratedPath::list(&GeneratedPath::ALL)
                )
            })
        })
        .collect()
}

/// Runs the benchmark over `scenes` (raw inputs read with the default options) and writes every
/// output into `out`; returns the report.
pub fn run_benchmark(
    scenes: &[PathBuf],
    out: &Path,
    path_kinds: &[GeneratedPath],
    replayed: &[CameraPath],
    frames: usize,
    config: &BenchConfig,
) -> anyhow::Result<BenchReport> {
    let load = LoadOptions::default();
    let scenes = SceneInputs {
        paths: scenes,
        load: &load,
    };
    run_benchmark_with(scenes, out, path_kinds, replayed, frames, config, None)
}

/// [`run_benchmark`], plus the decimated-city baseline of each scene when `baseline` is given.
pub fn run_benchmark_with(
    scenes: SceneInputs<'_>,
    out: &Path,
    path_kinds: &[GeneratedPath],
    replayed: &[CameraPath],
    frames: usize,
    config: &BenchConfig,
    baseline: Option<BaselineTarget>,
) -> anyhow::Result<BenchReport> {
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let gpu = GpuContext::headless()?;
    eprintln!("adapter: {}", gpu.adapter_summary());
    let mut renderers = BenchRenderers::new(&gpu);
    let mut records: Vec<FrameRecord> = Vec::new();
    let mut loads = Vec::new();
    for scene_path in scenes.paths {
        let started = Instant::now();
        // The decimated baseline meshes the buildings from their parts, which a package read
        // only to draw leaves out.
        let package = if baseline.is_some() {
            load_scene(scene_path, scenes.load)?
        } else {
            load_scene_to_draw(scene_path, scenes.load)?
        };
        let PackageParts {
            city,
            blocks,
            quadtree,
            occluders,
            cluster_tree,
            cluster_textures,
            gpu_scene,
            ground_surfaces,
        } = package.into_parts();
        let name = scene_name(scene_path);
        // The occluders are drawn from the GPU scene's arrays (a package read to draw has no
        // occluder set; a preprocessed input's set drew the same arrays).
        drop(occluders);
        // The camera paths are made from the city on a second thread while this one uploads
        // the scene: the upload is the driver's and the kernel's work on fresh pages, the
        // paths are the CPU's (1M buildings: about a second each).
        let (paths, drawable) = std::thread::scope(|s| {
            let paths = s.spawn(|| {
                let sphere = CitySphere::of(&city);
                let paths: Vec<CameraPath> = path_kinds
                    .iter()
                    .map(|kind| kind.generate(&city, frames))
                    .collect();
                (sphere, paths)
            });
            let drawable = DrawableScene::upload_package(
                &gpu,
                &gpu_scene,
                cluster_tree,
                Some((blocks, quadtree)),
            )
            .and_then(|d| d.with_surfaces(&gpu, &ground_surfaces));
            let paths = paths
                .join()
                .unwrap_or_else(|panic| std::panic::resume_unwind(panic));
            (paths, drawable)
        });
        let (sphere, mut paths) = paths;
        paths.extend(replayed.iter().cloned());
        // The frames draw from the GPU; only the decimated baseline meshes the city again (a
        // million buildings are a third of a gigabyte of heap).
        let city = baseline.is_some().then_some(city);
        let drawable = drawable.with_context(|| format!("cannot draw {}", scene_path.display()))?;
        let textures = TEXTURES.get().copied().unwrap_or_default();
        let mut drawable = textures.apply(&gpu, drawable, &gpu_scene, cluster_textures)?;
        if let Some(lod) = &mut drawable.lod {
            lod.criterion = LOD_CRITERION.get().copied().flatten();
        }
        // Uploaded: unmap the package.
        drop(gpu_scene);
        let scene = BenchScene {
            name: name.clone(),
            drawable,
            sphere,
        };
        let load = SceneLoad {
            scene: name.clone(),
            buildings: scene.drawable.buildings.building_count(),
            triangles: scene.drawable.buildings.triangle_count,
            ready_s: started.elapsed().as_secs_f64(),
            resident_mib: resident_mib().0,
            gpu_allocated_mib: gpu.allocated_mib(),
            cluster_textures: None,
        };
        let mib = |m: Option<f64>| m.map_or("?".into(), |m| format!("{m:.0}"));
        eprintln!(
            "{name}: {} buildings, {} triangles, ready in {:.1} s, {} MiB resident, {} MiB on the GPU",
            load.buildings,
            load.triangles,
            load.ready_s,
            mib(load.resident_mib),
            mib(load.gpu_allocated_mib)
        );
        loads.push(load);
        let budget_mib = TEXTURES
            .get()
            .copied()
            .unwrap_or_default()
            .texture_budget_mib;
        for path in &paths {
            let file = out.join(format!("{name}-{}.path", path.name));
            path.write(&file)
                .with_context(|| format!("writing {}", file.display()))?;
            let started = Instant::now();
            let rows = run_path(&gpu, &mut renderers, &scene, path, config)
                .with_context(|| format!("{name}, path {}", path.name))?;
            let false_culls: usize = rows.iter().map(|r| r.false_culls).sum();
            eprintln!(
                "{name} / {}: {} frames × {} modes in {:.1} s, {false_culls} false culls",
                path.name,
                path.poses.len(),
                config.modes.len(),
                started.elapsed().as_secs_f64()
            );
            records.extend(rows);
        }
        if let (Some(texturing), Some(load)) = (scene.drawable.texturing(), loads.last_mut()) {
            let r = texturing.residency();
            eprintln!(
                "{name}: cluster textures: {} of {} page views resident ({:.0} MiB of a {budget_mib} MiB budget), {} uploaded, {} evicted",
                r.resident, r.layers, r.resident_mib, r.uploaded, r.evictions
            );
            load.cluster_textures = Some(TextureUse {
                budget_mib,
                layers: r.layers,
                resident: r.resident,
                resident_mib: r.resident_mib,
                uploaded: r.uploaded,
                evictions: r.evictions,
            });
        }
        if let (Some(target), Some(city)) = (baseline, &city) {
            let started = Instant::now();
            let geometry = SceneGeometry::from_city(city);
            let budget = target
                .triangles(&name, geometry.building_triangle_count(), &records)
                .with_context(|| format!("{name}: no frames to size the baseline by"))?;
            let decimated = decimate_city(&geometry, budget);
            let decimated_gpu = SceneGpu::upload(&gpu, &decimated.geometry(&geometry))
                .with_context(|| format!("{name}: cannot draw the decimated baseline"))?;
            eprintln!(
                "{name}: decimated to {} triangles (budget {budget}, {:?}) in {:.1} s",
                decimated.triangles,
                decimated.method,
                started.elapsed().as_secs_f64()
            );
            let mut runner = DecimatedBaseline::new(&gpu);
            for path in &paths {
                let rows = runner
                    .run_path(&gpu, &scene, &decimated_gpu, path, config)
                    .with_context(|| format!("{name}, path {}, decimated", path.name))?;
                records.extend(rows);
            }
        }
    }
    let info = &gpu.adapter_info;
    let report = BenchReport {
        adapter: AdapterSummary {
            name: info.name.clone(),
            backend: format!("{:?}", info.backend),
            device_type: format!("{:?}", info.device_type),
        },
        size: [config.width, config.height],
        scenes: loads,
        peak_resident_mib: resident_mib().1,
        entries: summarise(&records),
    };
    write_outputs(out, &records, &report)?;
    let plots = write_plots(out, &records)?;
    eprintln!("{} plots", plots.len());
    Ok(report)
}

/// A short scene name from its file name: `chelsea.osm.pbf` → `chelsea`.
pub fn scene_name(path: &Path) -> String {
    let file = path
        .file_name()
        .map(|f| f.to_string_lossy().into_owned())
        .unwrap_or_else(|| "scene".into());
    file.split('.').next().unwrap_or("scene").to_string()
}
