//! `citywalk render SCENE`: render one frame of a scene headless (brute force, every building)
//! and write it as PNG.

use std::path::{Path, PathBuf};
use std::time::Instant;

use anyhow::Context;
use citywalk_engine::camera::Camera;
use citywalk_engine::gpu::GpuContext;
use citywalk_engine::render::BruteRenderer;
use citywalk_engine::scene_gpu::SceneGpu;
use citywalk_scenes::City;

/// Arguments of `citywalk render`.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// The scene: OSM PBF, GeoJSON, CityJSON or glTF/GLB.
    pub scene: PathBuf,
    /// Camera as X,Y,Z,YAW,PITCH (metres in the scene's local frame; degrees, yaw 0 = east,
    /// pitch positive up). Default: the overview from the south-west.
    #[arg(long, allow_hyphen_values = true)]
    pub camera: Option<String>,
    /// Image size in pixels, WIDTHxHEIGHT.
    #[arg(long, default_value = "1280x720", value_parser = parse_size)]
    pub size: (u32, u32),
    /// Also render this many warm frames after the first and print their median and best CPU
    /// wall time (submit to readback done; on a software adapter this is the GPU time).
    #[arg(long, default_value_t = 0)]
    pub repeat: u32,
    /// Output PNG.
    #[arg(short, long, default_value = "frame.png")]
    pub output: PathBuf,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let started = Instant::now();
    let city = load_scene(&args.scene)?;
    let loaded_s = started.elapsed().as_secs_f64();
    let gpu = GpuContext::headless()?;
    println!("adapter: {}", gpu.adapter_summary());
    let scene = SceneGpu::upload_city(&gpu, &city);
    let (width, height) = args.size;
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
        .save(&args.output)
        .with_context(|| format!("writing {}", args.output.display()))?;
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
    println!("wrote {}", args.output.display());
    Ok(())
}

/// Loads any input citywalk reads. (Scene packages, `.cwk`, branch off here once they exist.)
fn load_scene(path: &Path) -> anyhow::Result<City> {
    citywalk_scenes::load_city(path, &citywalk_scenes::LoadOptions::default())
        .with_context(|| format!("loading {}", path.display()))
}

pub(crate) fn parse_size(s: &str) -> Result<(u32, u32), String> {
    let (w, h) = s
        .split_once(['x', 'X'])
        .ok_or_else(|| format!("size {s:?}: expected WIDTHxHEIGHT"))?;
    let w: u32 = w.trim().parse().map_err(|e| format!("width {w:?}: {e}"))?;
    let h: u32 = h.trim().parse().map_err(|e| format!("height {h:?}: {e}"))?;
    if w == 0 || h == 0 || w > 16384 || h > 16384 {
        return Err(format!("size {s:?}: each side must be 1..=16384"));
    }
    Ok((w, h))
}
