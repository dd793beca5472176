//! `citywalk view SCENE`: open a window and walk (or fly) through a scene.

use std::path::{Path, PathBuf};

use anyhow::Context;
use citywalk_engine::controller::Mode;
use citywalk_engine::viewer::{self, ScreenshotRequest, ViewerOptions};

/// Arguments of `citywalk view`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene: GeoJSON, CityJSON, glTF/GLB or OSM PBF.
    pub scene: PathBuf,
    /// Start in fly mode at the overview camera (default: walk mode on a street near the centre).
    #[arg(long)]
    pub fly: bool,
    /// Window size in pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Render `--frames` frames, write the last one to this PNG and exit.
    #[arg(long, requires = "frames")]
    pub screenshot: Option<PathBuf>,
    /// Number of frames to render before the screenshot.
    #[arg(long, requires = "screenshot", value_parser = clap::value_parser!(u32).range(1..))]
    pub frames: Option<u32>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let city = load_scene(&args.scene)?;
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
    };
    viewer::run(city, options).context("citywalk view")
}

/// The one place the viewer loads its scene.
fn load_scene(path: &Path) -> anyhow::Result<citywalk_scenes::City> {
    let city = citywalk_scenes::load_city(path, &citywalk_scenes::LoadOptions::default())
        .with_context(|| format!("loading {}", path.display()))?;
    tracing::info!(
        buildings = city.buildings.len(),
        streets = city.streets.len(),
        rejected = city.report.rejected.len(),
        "loaded {}",
        path.display()
    );
    Ok(city)
}

/// Parses `WIDTHxHEIGHT`.
fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("expected WIDTHxHEIGHT, got {s:?}"))?;
    let parse = |v: &str| {
        v.trim()
            .parse::<u32>()
            .ok()
            .filter(|n| (1..=16384).contains(n))
            .ok_or_else(|| format!("size {v:?} is not a whole number of pixels in 1..=16384"))
    };
    Ok((parse(w)?, parse(h)?))
}

#[cfg(test)]
mod tests {
    use super::parse_size;

    #[test]
    fn sizes_parse() {
        assert_eq!(parse_size("320x200"), Ok((320, 200)));
        assert_eq!(parse_size("64X48"), Ok((64, 48)));
        assert!(parse_size("320").is_err());
        assert!(parse_size("0x10").is_err());
        assert!(parse_size("axb").is_err());
    }
}
