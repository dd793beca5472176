//! `citywalk view SCENE`: open a window and walk (or fly) through a scene, record the camera
//! path (R) or play one back (`--play`).

use std::path::{Path, PathBuf};

use anyhow::Context;
use citywalk_engine::camera_path_io::PlayEnd;
use citywalk_engine::controller::Mode;
use citywalk_engine::viewer::{self, PlayRequest, ScreenshotRequest, ViewerOptions};
use citywalk_scenes::City;
use citywalk_scenes::occluder::OccluderSet;
use citywalk_scenes::package::ScenePackage;

use crate::path_arg::PathSource;

/// Poses of a default path generated for `--play street|flyover|dive` (10 s at 60 fps).
const GENERATED_PLAY_POSES: usize = 600;

/// Arguments of `citywalk view`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene: a package (.cwk) or any input (OSM PBF, GeoJSON, CityJSON, glTF/GLB).
    pub scene: PathBuf,
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
    /// Play a camera path, one pose per frame: a `.path` file, or `street`, `flyover` or `dive`
    /// (generated for the scene, 600 poses). At its end the camera switches to fly mode there.
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
    /// Start drawing brute force, without occlusion culling (C toggles it).
    #[arg(long)]
    pub no_culling: bool,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let (city, occluders) = load_scene(&args.scene)?;
    let play = match &args.play {
        Some(arg) => Some(PlayRequest {
            path: PathSource::of(arg).load(&city, GENERATED_PLAY_POSES)?,
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
        culling: !args.no_culling,
    };
    viewer::run(city, occluders, options).context("citywalk view")
}

/// The one place the viewer loads its scene: a package's city and virtual occluders, or any
/// other input's city as it is (no occluders: they come from preprocessing).
fn load_scene(path: &Path) -> anyhow::Result<(City, Option<OccluderSet>)> {
    let named_package = path
        .extension()
        .is_some_and(|e| e.eq_ignore_ascii_case("cwk"));
    let (city, occluders) = if crate::scene_input::is_package(path)? || named_package {
        let package = ScenePackage::read(path)
            .with_context(|| format!("cannot read the scene package {}", path.display()))?;
        (package.city(), package.occluders)
    } else {
        (crate::scene_input::load_city(path)?, None)
    };
    tracing::info!(
        buildings = city.buildings.len(),
        streets = city.streets.len(),
        rejected = city.report.rejected.len(),
        occluders = occluders.as_ref().map_or(0, |o| o.occluders.len()),
        "loaded {}",
        path.display()
    );
    Ok((city, occluders))
}
