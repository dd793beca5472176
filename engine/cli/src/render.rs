//! `citywalk render SCENE`: render one frame of a scene headless (brute force, every building)
//! and write it as PNG, or every pose of a camera path (`--path`) as numbered PNGs.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use citywalk_runtime::camera::Camera;
use citywalk_runtime::camera_path_io::camera_from_pose;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::render::BruteRenderer;
use citywalk_runtime::scene_gpu::SceneGpu;

use crate::path_arg::PathSource;

/// Poses of a generated path when `--frames` is not given.
const DEFAULT_PATH_FRAMES: usize = 60;

/// Arguments of `citywalk render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene: a package (.cwk) or any input (OSM PBF, GeoJSON, CityJSON, glTF/GLB, OBJ).
    pub scene: PathBuf,
    #[command(flatten)]
    pub input: crate::input_args::InputArgs,
    /// Camera as X,Y,Z,YAW,PITCH (metres in the scene's local frame; degrees, yaw 0 = east,
    /// pitch positive up). Default: the overview from the south-west.
    #[arg(long, allow_hyphen_values = true, conflicts_with = "path")]
    pub camera: Option<String>,
    /// Render every pose of a camera path to OUTPUT/frame_0000.png, ...: a `.path` file, or
    /// `street`, `flyover` or `dive` (generated for the scene with `--frames` poses and written
    /// to OUTPUT/path.path).
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Poses of a generated `--path` (default 60).
    #[arg(long, requires = "path", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: Option<u32>,
    /// Image size in pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = crate::cli_args::parse_size)]
    pub size: (u32, u32),
    /// Also render this many warm frames after the first and print their median and best CPU
    /// wall time (submit to readback done; on a software adapter this is the GPU time).
    #[arg(long, default_value_t = 0, conflicts_with = "path")]
    pub repeat: u32,
    /// Output PNG (default frame.png), or with `--path` the output directory (default frames).
    #[arg(short, long)]
    pub output: Option<PathBuf>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let started = Instant::now();
    let load = args.input.load_options(std::slice::from_ref(&args.scene))?;
    let city = crate::scene_input::load_city(&args.scene, &load)?;
    let loaded_s = started.elapsed().as_secs_f64();
    let gpu = GpuContext::headless()?;
    println!("adapter: {}", gpu.adapter_summary());
    let scene = SceneGpu::upload_city(&gpu, &city);
    let (width, height) = args.size;
    if let Some(path_arg) = &args.path {
        let dir = args.output.unwrap_or_else(|| PathBuf::from("frames"));
        let renderer = BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
        let frames = PathFrames {
            gpu: &gpu,
            scene: &scene,
            renderer: &renderer,
            size: args.size,
        };
        return frames.render(&city, path_arg, args.frames, &dir);
    }
    let output = args.output.unwrap_or_else(|| PathBuf::from("frame.png"));
    let camera = match &args.camera {
        Some(s) => Camera::parse(s)?,
        None => Camera::overview(scene.bounds.0, scene.bounds.1),
    };
    let renderer = BruteRenderer::new(&gpu, BruteRenderer::PNG_FORMAT);
    let frame_started = Instant::now();
    let rgba = renderer.render_rgba(&gpu, &scene, &camera, width, height)?;
    let frame_s = frame_started.elapsed().as_secs_f64();
    let image = image::RgbaImage::from_raw(width, height, rgba)
        .context("readback size does not match the image size")?;
    image
        .save(&output)
        .with_context(|| format!("writing {}", output.display()))?;
    println!(
        "{} buildings, {} triangles, bounds {:.0} .. {:.0} m; camera {}; load {:.2} s, first frame {:.1} ms (incl. \
         shader compilation and readback)",
        scene.building_count(),
        scene.triangle_count,
        scene.bounds.0,
        scene.bounds.1,
        camera.to_arg_string(),
        loaded_s,
        frame_s * 1e3
    );
    if args.repeat > 0 {
        let mut times_ms = Vec::with_capacity(args.repeat as usize);
        for _ in 0..args.repeat {
            let t = Instant::now();
            renderer.render_rgba(&gpu, &scene, &camera, width, height)?;
            times_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        times_ms.sort_by(f64::total_cmp);
        println!(
            "{} warm frames at {width}x{height} (render + readback): median {:.1} ms, best {:.1} ms",
            times_ms.len(),
            times_ms[times_ms.len() / 2],
            times_ms[0]
        );
    }
    println!("wrote {}", output.display());
    Ok(())
}

/// Renders the poses of a camera path to numbered PNGs.
struct PathFrames<'a> {
    gpu: &'a GpuContext,
    scene: &'a SceneGpu,
    renderer: &'a BruteRenderer,
    size: (u32, u32),
}

impl PathFrames<'_> {
    fn render(
        &self,
        city: &citywalk_scenes::City,
        path_arg: &Path,
        frames: Option<u32>,
        dir: &Path,
    ) -> anyhow::Result<()> {
        let source = PathSource::of(path_arg);
        if let (PathSource::File(file), Some(_)) = (&source, frames) {
            anyhow::bail!(
                "--frames sets the length of a generated path (street, walk, flyover, dive), not of \
                 the path file {}",
                file.display()
            );
        }
        let frames = frames.map_or(DEFAULT_PATH_FRAMES, |n| n as usize);
        let path = source.load(city, frames)?;
        std::fs::create_dir_all(dir)
            .with_context(|| format!("cannot create the output directory {}", dir.display()))?;
        if let PathSource::Generated(_) = source {
            let file = dir.join("path.path");
            path.write(&file)
                .with_context(|| format!("writing {}", file.display()))?;
            println!("wrote the generated path to {}", file.display());
        }
        let (width, height) = self.size;
        let started = Instant::now();
        for (i, pose) in path.poses.iter().enumerate() {
            let camera = camera_from_pose(pose, path.fov_y_deg);
            let rgba = self
                .renderer
                .render_rgba(self.gpu, self.scene, &camera, width, height)?;
            let image = image::RgbaImage::from_raw(width, height, rgba)
                .context("readback size does not match the image size")?;
            let file = dir.join(format!("frame_{i:04}.png"));
            image
                .save(&file)
                .with_context(|| format!("writing {}", file.display()))?;
        }
        let total_s = started.elapsed().as_secs_f64();
        println!(
            "path {:?}: {} frames at {width}x{height} to {}/frame_0000.png ...; {:.1} ms a frame \
             (render, readback and PNG encoding)",
            path.name,
            path.poses.len(),
            dir.display(),
            total_s * 1e3 / path.poses.len().max(1) as f64
        );
        Ok(())
    }
}
