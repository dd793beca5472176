//! `citywalk view SCENE`: open a window and walk (or fly) through a scene, record the camera
//! path (R) or play one back (`--play`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use citywalk_runtime::camera_path_io::PlayEnd;
use citywalk_runtime::controller::Mode;
use citywalk_scenes::package::{Decode, PackageFile};
use citywalk_viewer::{
    CriterionKind, DebugView, FramePlan, PlayRequest, RenderSettings, ScreenshotRequest,
    ViewerOptions, ViewerScene,
};

use crate::path_arg::PathSource;

/// Poses of a path generated for `--play` (10 s at 60 fps).
const GENERATED_PLAY_POSES: usize = 600;

/// Arguments of `citywalk view`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene: a package (.cwk) or any input (OSM PBF, GeoJSON, CityJSON, glTF/GLB, OBJ).
    pub scene: PathBuf,
    #[command(flatten)]
    pub input: crate::input_args::InputArgs,
    #[command(flatten)]
    pub textures: crate::texture_args::TextureArgs,
    /// Start in fly mode at the overview camera (default: walk mode on a street near the centre).
    #[arg(long)]
    pub fly: bool,
    /// Window size in pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = crate::cli_args::parse_size)]
    pub size: (u32, u32),
    /// Render `--frames` frames, write the last one to this PNG and exit.
    #[arg(long, requires = "frames")]
    pub screenshot: Option<PathBuf>,
    /// Number of frames to render before the screenshot.
    #[arg(long, requires = "screenshot", value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,
    /// Play a camera path, one pose per frame: a `.path` file, or `street`, `walk`, `flyover`,
    /// `dive` or `overview` (generated for the scene, 600 poses). At its end the camera switches
    /// to fly mode there.
    #[arg(long)]
    pub play: Option<PathBuf>,
    /// Loop the path given with `--play` instead of stopping at its end.
    #[arg(long = "loop", requires = "play")]
    pub looping: bool,
    /// Where R (start / stop recording the camera, one pose per frame) writes the path.
    #[arg(long, default_value = "recorded.path")]
    pub record: PathBuf,
    /// Start with the overlay panel hidden (H shows it).
    #[arg(long)]
    pub no_overlay: bool,
    /// Start drawing brute force, every culling stage off (B, C, V, L switch them on).
    #[arg(long)]
    pub no_culling: bool,
    /// Start with the stages as the flags set them instead of the `auto` plan, which picks
    /// them by their measured cost (P toggles).
    #[arg(long)]
    pub no_auto: bool,
    /// Start with the occluder gate off: last frame's visible set drawn early unculled (N
    /// toggles).
    #[arg(long)]
    pub no_occluder_gate: bool,
    /// Start with the screen-space LOD cut on (scene packages with a cluster tree; L toggles).
    #[arg(long)]
    pub lod: bool,
    /// The LOD criterion at start: `geometric` (the cluster's geometric and colour error against
    /// `--tolerance-px`), `chang` (ε, τ) or `yang` (δh, δa); K cycles.
    #[arg(long, default_value = "geometric", value_parser = parse_criterion)]
    pub criterion: CriterionKind,
    /// The geometric criterion's tolerance at start (pixels; default 1, street level).
    #[arg(long, value_parser = parse_tolerance)]
    pub tolerance_px: Option<f32>,
    /// Chang's ε at start (pixels; default 1, the walkthrough tolerance).
    #[arg(long, value_parser = parse_tolerance)]
    pub epsilon_px: Option<f32>,
    /// Chang's landmark tolerance τ at start (pixels; default 1).
    #[arg(long, value_parser = parse_tolerance)]
    pub tau_px: Option<f32>,
    /// Yang's δh at start (pixels; default 20).
    #[arg(long, value_parser = parse_tolerance)]
    pub delta_h_px: Option<f32>,
    /// Yang's δa at start (square pixels; default 200).
    #[arg(long, value_parser = parse_tolerance)]
    pub delta_a_px2: Option<f32>,
    /// The debug view at start: `off`, `pyramid`, `clusters` or `occluders`; G cycles.
    #[arg(long, default_value = "off", value_parser = parse_debug_view)]
    pub debug_view: DebugView,
    /// The pyramid level the `pyramid` debug view shows (the `[` and `]` keys change it).
    #[arg(long, default_value_t = 0)]
    pub mip: u32,
}

fn parse_criterion(s: &str) -> Result<CriterionKind, String> {
    CriterionKind::parse(s)
        .ok_or_else(|| format!("unknown LOD criterion '{s}' (geometric, chang, yang)"))
}

fn parse_tolerance(s: &str) -> Result<f32, String> {
    s.trim()
        .parse::<f32>()
        .ok()
        .filter(|v| v.is_finite() && *v > 0.0)
        .ok_or_else(|| format!("'{s}' is not a positive number of pixels"))
}

fn parse_debug_view(s: &str) -> Result<DebugView, String> {
    DebugView::parse(s)
        .ok_or_else(|| format!("unknown debug view '{s}' (off, pyramid, clusters, occluders)"))
}

/// The settings at start from the flags.
fn start_settings(args: &Args) -> RenderSettings {
    let mut settings = RenderSettings::default();
    if args.no_culling {
        settings.stages = FramePlan::NONE;
    }
    // Any flag that sets a culling stage asks for that stage, not for the auto plan.
    settings.auto = !(args.no_auto || args.no_culling || args.no_occluder_gate);
    settings.stages.lod = args.lod;
    settings.stages.occluder_gate &= !args.no_occluder_gate;
    settings.lod.kind = args.criterion;
    let lod = &mut settings.lod;
    for (value, slot) in [
        (args.tolerance_px, &mut lod.tolerance_px),
        (args.epsilon_px, &mut lod.epsilon_px),
        (args.tau_px, &mut lod.tau_px),
        (args.delta_h_px, &mut lod.delta_h_px),
        (args.delta_a_px2, &mut lod.delta_a_px2),
    ] {
        if let Some(v) = value {
            *slot = v;
        }
    }
    settings.debug_view = args.debug_view;
    settings.mip_level = args.mip;
    settings
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let started = std::time::Instant::now();
    let load = args.input.load_options(std::slice::from_ref(&args.scene))?;
    let scene = load_scene(&args.scene, &load, args.textures.texture_budget_mib)?;
    let city = &scene.city;
    let settings = start_settings(&args);
    let play = match &args.play {
        Some(arg) => Some(PlayRequest {
            path: PathSource::of(arg).load(city, GENERATED_PLAY_POSES)?,
            end: if args.looping {
                PlayEnd::Loop
            } else {
                PlayEnd::Stop
            },
        }),
        None => None,
    };
    let options = ViewerOptions {
        mode: if args.fly { Mode::Fly } else { Mode::Walk },
        size_px: args.size,
        screenshot: args.screenshot.map(|path| ScreenshotRequest {
            path,
            frames: args.frames.unwrap_or(1),
        }),
        title: args
            .scene
            .file_name()
            .map(|n| n.to_string_lossy().into_owned())
            .unwrap_or_default(),
        record_to: args.record,
        play,
        overlay: !args.no_overlay,
        settings,
        started,
    };
    citywalk_viewer::run(scene, options).context("citywalk view")
}

/// The one place the viewer loads its scene: a package's city, virtual occluders, cluster tree,
/// urban blocks and B-Quadtree, or any other input's city as it is (no occluders, tree or
/// quadtree: they come from preprocessing).
fn load_scene(
    path: &Path,
    load: &citywalk_scenes::LoadOptions,
    texture_budget_mib: u64,
) -> anyhow::Result<ViewerScene> {
    let named_package = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("cwk"));
    let scene = if crate::scene_input::is_package(path)? || named_package {
        // What drawing and walking need: the occluders and cluster meshes come from the GPU
        // scene; the buildings' parts are walked against.
        // The file stays mapped: a picked building's tags are read from it.
        let context = || format!("cannot read the scene package {}", path.display());
        let file = PackageFile::open(path).with_context(context)?;
        let package = file
            .decode_as(Decode::RuntimeWithParts)
            .with_context(context)?;
        let parts = package.into_parts();
        ViewerScene {
            city: parts.city,
            cluster_tree: parts.cluster_tree,
            blocks: Some((parts.blocks, parts.quadtree)),
            gpu_scene: Some(parts.gpu_scene),
            ground_surfaces: Some(parts.ground_surfaces),
            package: Some(file),
            cluster_textures: parts.cluster_textures.map(|t| (t, texture_budget_mib)),
        }
    } else {
        ViewerScene {
            city: crate::scene_input::load_city(path, load)?,
            cluster_tree: None,
            blocks: None,
            gpu_scene: None,
            ground_surfaces: None,
            package: None,
            cluster_textures: None,
        }
    };
    let city = &scene.city;
    tracing::info!(
        buildings = city.buildings.len(),
        streets = city.streets.len(),
        rejected = city.report.rejected.len(),
        occluders = scene
            .gpu_scene
            .as_ref()
            .map_or(0, |g| g.view().occluders.records.len()),
        cluster_tree = scene.cluster_tree.is_some(),
        "loaded {}",
        path.display()
    );
    Ok(scene)
}
