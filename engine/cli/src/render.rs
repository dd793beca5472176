//! `citywalk render SCENE`: render one frame of a scene headless and write it as PNG, or every
//! pose of a camera path (`--path`) as numbered PNGs. Frames go through the frame runner with
//! the plan of `--mode` (the benchmark's modes; brute force, every building at full detail, by
//! default), as `view` and `bench` draw theirs.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use citywalk_bench::Mode;
use citywalk_runtime::auto::AutoPlanner;
use citywalk_runtime::camera::Camera;
use citywalk_runtime::camera_path_io::camera_from_pose;
use citywalk_runtime::drawable::DrawableScene;
use citywalk_runtime::frame::Visibility;
use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::plan::FramePlan;
use citywalk_runtime::render::BruteRenderer;
use citywalk_runtime::render::targets::OffscreenTarget;
use citywalk_runtime::runner::{Completion, FrameReport, FrameRunner, FrameTarget};
use citywalk_scenes::City;
use citywalk_scenes::camera_path::GeneratedPath;

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
    #[command(flatten)]
    pub textures: crate::texture_args::TextureArgs,
    /// Camera as X,Y,Z,YAW,PITCH (metres in the scene's local frame; degrees, yaw 0 = east,
    /// pitch positive up). Default: the overview from the south-west.
    #[arg(long, allow_hyphen_values = true, conflicts_with = "path")]
    pub camera: Option<String>,
    /// Render every pose of a camera path to OUTPUT/frame_0000.png, ...: a `.path` file, or
    /// `street`, `walk`, `flyover`, `dive` or `overview` (generated for the scene with `--frames`
    /// poses and written to OUTPUT/path.path).
    #[arg(long)]
    pub path: Option<PathBuf>,
    /// Poses of a generated `--path` (default 60).
    #[arg(long, requires = "path", value_parser = clap::value_parser!(u32).range(1..=100_000))]
    pub frames: Option<u32>,
    /// The frame's culling stages, as the benchmark's modes: brute (everything at full detail),
    /// frustum, quadtree, hzb, occluders, lod, all, or auto (chosen frame by frame from their
    /// cost). Stages the scene lacks are skipped (a raw input other than with brute is
    /// preprocessed first, as `bench` does).
    #[arg(long, default_value = "brute", value_parser = parse_mode)]
    pub mode: Mode,
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
    let gpu = GpuContext::headless()?;
    let (city, scene) = load_drawable(&gpu, &args.scene, &load, args.mode, &args.textures)?;
    let loaded_s = started.elapsed().as_secs_f64();
    println!("adapter: {}", gpu.adapter_summary());
    let mut frames = Frames::new(&gpu, &scene, args.mode, args.size)?;
    if let Some(path_arg) = &args.path {
        let dir = args.output.unwrap_or_else(|| PathBuf::from("frames"));
        return frames.render_path(&city, path_arg, args.frames, &dir);
    }
    let output = args.output.unwrap_or_else(|| PathBuf::from("frame.png"));
    let bounds = scene.buildings.bounds;
    let camera = match &args.camera {
        Some(s) => Camera::parse(s)?,
        None => Camera::overview(bounds.0, bounds.1),
    };
    let frame_started = Instant::now();
    let (image, report) = frames.draw(&camera)?;
    let frame_s = frame_started.elapsed().as_secs_f64();
    image
        .save(&output)
        .with_context(|| format!("writing {}", output.display()))?;
    println!(
        "{} buildings, {} triangles, bounds {:.0} .. {:.0} m; camera {}; load {:.2} s, first frame {:.1} ms (incl. \
         shader compilation and readback)",
        scene.buildings.building_count(),
        scene.buildings.triangle_count,
        bounds.0,
        bounds.1,
        camera.to_arg_string(),
        loaded_s,
        frame_s * 1e3
    );
    println!("mode {}: {}", args.mode.name(), describe(&report));
    if args.repeat > 0 {
        let mut times_ms = Vec::with_capacity(args.repeat as usize);
        for _ in 0..args.repeat {
            let t = Instant::now();
            frames.draw(&camera)?;
            times_ms.push(t.elapsed().as_secs_f64() * 1e3);
        }
        times_ms.sort_by(f64::total_cmp);
        println!(
            "{} warm frames at {}x{} (render + readback): median {:.1} ms, best {:.1} ms",
            times_ms.len(),
            args.size.0,
            args.size.1,
            times_ms[times_ms.len() / 2],
            times_ms[0]
        );
    }
    println!("wrote {}", output.display());
    Ok(())
}

/// `--mode`: a benchmark mode that has a plan (`oracle` needs the benchmark's oracle).
fn parse_mode(word: &str) -> Result<Mode, String> {
    match Mode::parse_list(word)?.as_slice() {
        [Mode::Oracle] => Err(
            "oracle draws the oracle's visible set and is a benchmark pseudo-mode (citywalk bench)"
                .into(),
        ),
        [mode] => Ok(*mode),
        _ => Err("one mode, not a list".into()),
    }
}

/// The city (for the overview and generated paths) and the scene on the GPU: a package from
/// its mapping; a raw input meshed as it is for brute force, else preprocessed on the fly, so
/// that the culling stages have their structures.
fn load_drawable(
    gpu: &GpuContext,
    path: &Path,
    load: &citywalk_scenes::LoadOptions,
    mode: Mode,
    textures: &crate::texture_args::TextureArgs,
) -> anyhow::Result<(City, DrawableScene)> {
    if mode == Mode::Brute && !crate::scene_input::is_package(path)? {
        let city = crate::scene_input::load_city(path, load)?;
        let scene = DrawableScene::upload_city(gpu, &city, None, None)
            .with_context(|| format!("cannot draw {}", path.display()))?;
        return Ok((city, scene));
    }
    let parts = crate::scene_input::load_scene_to_draw(path, load)?.into_parts();
    let scene = DrawableScene::upload_package(
        gpu,
        &parts.gpu_scene,
        parts.cluster_tree,
        Some((parts.blocks, parts.quadtree)),
    )
    .and_then(|d| d.with_surfaces(gpu, &parts.ground_surfaces))
    .with_context(|| format!("cannot draw {}", path.display()))?;
    let scene = textures.apply(gpu, scene, &parts.gpu_scene, parts.cluster_textures)?;
    Ok((parts.city, scene))
}

/// What a frame drew, in one line.
fn describe(report: &FrameReport) -> String {
    let clusters = report
        .clusters_drawn
        .map_or(String::new(), |c| format!(", {c} cluster meshes"));
    format!(
        "{}; {} buildings drawn{clusters}, {} triangles, {} draw calls",
        report.plan.describe(),
        report.buildings_drawn,
        report.triangles,
        report.draw_calls
    )
}

/// Frames of one scene and mode into one offscreen target, read back as images.
struct Frames<'a> {
    gpu: &'a GpuContext,
    scene: &'a DrawableScene,
    runner: FrameRunner,
    target: OffscreenTarget,
    mode: Mode,
    /// The `auto` mode's planner, learning along the frames.
    planner: Option<AutoPlanner>,
    /// Last frame's visible set, carried along a path.
    visibility: Visibility,
}

impl<'a> Frames<'a> {
    fn new(
        gpu: &'a GpuContext,
        scene: &'a DrawableScene,
        mode: Mode,
        (width, height): (u32, u32),
    ) -> anyhow::Result<Frames<'a>> {
        let format = BruteRenderer::PNG_FORMAT;
        Ok(Frames {
            gpu,
            scene,
            runner: FrameRunner::new(gpu, format),
            target: OffscreenTarget::new(gpu, width, height, format)?,
            mode,
            planner: (mode == Mode::Auto)
                .then(|| AutoPlanner::new(scene.features(), scene.lod.is_some())),
            visibility: Visibility::default(),
        })
    }

    /// One frame from `camera`, waited for, and its image: drawn again, as the same frame,
    /// when the cluster textures it drew were still loading, so that an image shows them.
    fn draw(&mut self, camera: &Camera) -> anyhow::Result<(image::RgbaImage, FrameReport)> {
        let mut frame = self.draw_once(camera)?;
        if let Some(texturing) = self.scene.texturing()
            && texturing.loading() > 0
        {
            texturing.settle(self.gpu);
            frame = self.draw_once(camera)?;
        }
        if let Some(planner) = &mut self.planner {
            planner.record(&frame.1);
        }
        Ok(frame)
    }

    fn draw_once(&mut self, camera: &Camera) -> anyhow::Result<(image::RgbaImage, FrameReport)> {
        let plan = match (&mut self.planner, self.mode.plan()) {
            (Some(planner), _) => planner.plan_for(camera),
            (None, Some(plan)) => plan,
            (None, None) => FramePlan::NONE,
        };
        let target = &self.target;
        let report = self
            .runner
            .run(
                self.gpu,
                self.scene.refs(),
                plan,
                None,
                &mut self.visibility,
                camera,
                FrameTarget::offscreen(target),
                (Completion::Wait, false),
            )?
            .context("a waited frame has its report")?;
        let rgba = target.read_colour(self.gpu)?;
        let image = image::RgbaImage::from_raw(target.width, target.height, rgba)
            .context("readback size does not match the image size")?;
        Ok((image, report))
    }

    /// Renders the poses of a camera path to numbered PNGs in `dir`.
    fn render_path(
        &mut self,
        city: &City,
        path_arg: &Path,
        frames: Option<u32>,
        dir: &Path,
    ) -> anyhow::Result<()> {
        let source = PathSource::of(path_arg);
        if let (PathSource::File(file), Some(_)) = (&source, frames) {
            anyhow::bail!(
                "--frames sets the length of a generated path ({}), not of the path file {}",
                GeneratedPath::list(&GeneratedPath::ALL),
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
        let started = Instant::now();
        let mut drawn = 0u64;
        for (i, pose) in path.poses.iter().enumerate() {
            let camera = camera_from_pose(pose, path.fov_y_deg);
            let (image, report) = self.draw(&camera)?;
            drawn += u64::from(report.buildings_drawn);
            let file = dir.join(format!("frame_{i:04}.png"));
            image
                .save(&file)
                .with_context(|| format!("writing {}", file.display()))?;
        }
        let total_s = started.elapsed().as_secs_f64();
        let count = path.poses.len().max(1);
        println!(
            "path {:?}: {} frames at {}x{} to {}/frame_0000.png ...; mode {}, {:.1} buildings drawn \
             a frame; {:.1} ms a frame (render, readback and PNG encoding)",
            path.name,
            path.poses.len(),
            self.target.width,
            self.target.height,
            dir.display(),
            self.mode.name(),
            drawn as f64 / count as f64,
            total_s * 1e3 / count as f64
        );
        Ok(())
    }
}
