//! The 3D Tiles export in a real client: Chelsea's tileset opened in CesiumJS in headless
//! Chromium (`.ci/cesium-check/view.mjs`), seen from citywalk's own cameras, covers the pixels
//! citywalk's buildings cover, with no tileset, page or console error and nothing fetched from
//! outside; the same script plays a citywalk camera path and times CesiumJS's frames.
//!
//! citywalk's side is its visibility oracle's id image (building or not, exact), Cesium's a
//! frame over a flat magenta background with the globe hidden (anything else is a building).

use std::path::{Path, PathBuf};
use std::process::Command;

use citywalk_preprocess::pipeline::{NoProgress, PreprocessParams, preprocess};
use citywalk_runtime::camera::Camera;
use citywalk_runtime::camera_path_io::camera_from_pose;
use citywalk_runtime::oracle::{IdImage, Oracle};
use citywalk_runtime::scene_gpu::SceneGpu;
use citywalk_scenes::camera_path::GeneratedPath;
use citywalk_scenes::export::{ExportOptions, write_3d_tiles};
use citywalk_scenes::{LoadOptions, load_cities};
use citywalk_shaders::ID_BACKGROUND;
use citywalk_tests::gpu::gpu_or_skip;
use serde_json::Value;

const CHELSEA: &str = concat!(
    env!("CARGO_MANIFEST_DIR"),
    "/../scenes/data/chelsea.osm.pbf"
);
const CHECK: &str = concat!(env!("CARGO_MANIFEST_DIR"), "/../.ci/cesium-check");
const CHROMIUM: &str = "/usr/bin/chromium";
/// Frame size of both renders.
const SIZE: (u32, u32) = (640, 360);
/// Least intersection-over-union of the two building masks. Set on lavapipe (citywalk) against
/// SwiftShader in Chromium 156 (CesiumJS 1.145), which measured 0.996 (overview) and 0.9998
/// (walk): the tolerance leaves room for rasterisation and LOD differences of other drivers.
const MIN_IOU: f64 = 0.98;
/// Channel distance (sum of |difference|) from the magenta background below which a Cesium
/// pixel is background.
const BACKGROUND_TOLERANCE: u32 = 24;

/// Whether node, the npm packages and Chromium are there: without them the test fails under CI
/// (`.ci/setup.sh` installs them) and is skipped elsewhere.
fn cesium_ready() -> bool {
    let node = Command::new("node").arg("--version").output().is_ok();
    let installed = Path::new(CHECK).join("node_modules/cesium").is_dir()
        && Path::new(CHECK)
            .join("node_modules/playwright-core")
            .is_dir();
    let chromium = Path::new(CHROMIUM).exists();
    if node && installed && chromium {
        return true;
    }
    assert!(
        std::env::var_os("CI").is_none(),
        "node ({node}), {CHECK}/node_modules ({installed}) or {CHROMIUM} ({chromium}) missing: \
         run .ci/setup.sh"
    );
    eprintln!("skipping the CesiumJS check: node, the npm packages or chromium are missing");
    false
}

/// Runs view.mjs on the tileset in `dir` and returns its JSON summary, having checked that it
/// saw no error and asked for nothing outside.
fn view(dir: &Path, extra: &[String]) -> Value {
    let out = Command::new("node")
        .arg(Path::new(CHECK).join("view.mjs"))
        .arg(dir)
        .arg("--size")
        .arg(format!("{}x{}", SIZE.0, SIZE.1))
        .args(extra)
        .output()
        .expect("node runs");
    let stdout = String::from_utf8_lossy(&out.stdout);
    let summary: Value = serde_json::from_str(stdout.trim()).unwrap_or_else(|e| {
        panic!(
            "view.mjs printed no JSON ({e}): {stdout}{}",
            String::from_utf8_lossy(&out.stderr)
        )
    });
    assert_eq!(summary["errors"], Value::Array(vec![]), "{summary}");
    assert_eq!(
        summary["external_requests"],
        Value::Array(vec![]),
        "{summary}"
    );
    assert!(out.status.success(), "{summary}");
    summary
}

/// Building masks: citywalk's from the id image, Cesium's from its frame.
fn citywalk_mask(ids: &IdImage) -> Vec<bool> {
    ids.pixels.iter().map(|&v| v != ID_BACKGROUND).collect()
}

fn cesium_mask(png: &Path) -> Vec<bool> {
    let image = image::open(png).expect("Cesium's frame").to_rgba8();
    assert_eq!(image.dimensions(), SIZE);
    image
        .pixels()
        .map(|p| {
            let [r, g, b, _] = p.0;
            (255 - u32::from(r)) + u32::from(g) + (255 - u32::from(b)) > BACKGROUND_TOLERANCE
        })
        .collect()
}

/// Intersection over union, and each mask's share of the frame.
fn iou(a: &[bool], b: &[bool]) -> (f64, f64, f64) {
    let both = a.iter().zip(b).filter(|(x, y)| **x && **y).count();
    let either = a.iter().zip(b).filter(|(x, y)| **x || **y).count();
    let share = |m: &[bool]| m.iter().filter(|x| **x).count() as f64 / m.len() as f64;
    (both as f64 / either.max(1) as f64, share(a), share(b))
}

#[test]
fn cesium_draws_chelsea_where_citywalk_does_and_plays_its_walk() {
    let Some(gpu) = gpu_or_skip("export_cesium") else {
        return;
    };
    if !cesium_ready() {
        return;
    }
    let city = load_cities(&[PathBuf::from(CHELSEA)], &LoadOptions::default()).expect("load");
    let package = preprocess(city, &PreprocessParams::default(), &NoProgress).expect("preprocess");
    let dir = tempfile::tempdir().unwrap();
    let tiles = dir.path().join("chelsea");
    write_3d_tiles(&package, &tiles, &ExportOptions::default()).expect("export");

    let city = package.city();
    let scene = SceneGpu::upload_city(&gpu, &city).expect("the scene fits the GPU");
    let oracle = Oracle::new(&gpu);
    let (lo, hi) = city.bounds().expect("buildings");
    let walk = GeneratedPath::Walk.generate(&city, 9);
    // citywalk's default render (the overview from the south-west) and a pedestrian's view.
    let cameras = [
        ("overview", Camera::overview(lo, hi)),
        ("walk", camera_from_pose(&walk.poses[4], walk.fov_y_deg)),
    ];
    let keep = std::env::var_os("CITYWALK_CESIUM_OUT").map(PathBuf::from);
    for (name, camera) in cameras {
        let ids = oracle
            .id_image(&gpu, &scene, &camera, SIZE.0, SIZE.1)
            .expect("oracle");
        let shot = dir.path().join(format!("{name}.png"));
        let summary = view(
            &tiles,
            &[
                "--camera".into(),
                camera.to_arg_string(),
                "--fov-y".into(),
                camera.fov_y_rad.to_degrees().to_string(),
                "--shot".into(),
                shot.display().to_string(),
            ],
        );
        let (ours, theirs) = (citywalk_mask(&ids), cesium_mask(&shot));
        let (iou, our_share, their_share) = iou(&ours, &theirs);
        eprintln!(
            "{name}: IoU {iou:.4}, buildings on {:.1} % of citywalk's frame, {:.1} % of Cesium's; {summary}",
            our_share * 100.0,
            their_share * 100.0
        );
        if let Some(keep) = &keep {
            std::fs::create_dir_all(keep).unwrap();
            std::fs::copy(&shot, keep.join(format!("{name}-cesium.png"))).unwrap();
            let mask = image::GrayImage::from_fn(SIZE.0, SIZE.1, |x, y| {
                let i = (y * SIZE.0 + x) as usize;
                image::Luma([u8::from(ours[i]) * 127 + u8::from(theirs[i]) * 128])
            });
            mask.save(keep.join(format!("{name}-masks.png"))).unwrap();
        }
        assert!(
            our_share > 0.05,
            "{name}: buildings fill a fair share of the frame"
        );
        assert!(iou >= MIN_IOU, "{name}: IoU {iou} < {MIN_IOU}");
    }

    // The walk played in Cesium, timed (a few frames: the benchmark plays 30).
    let path = dir.path().join("walk.path");
    walk.write(&path).unwrap();
    let times = dir.path().join("walk.json");
    let summary = view(
        &tiles,
        &[
            "--path".into(),
            path.display().to_string(),
            "--times".into(),
            times.display().to_string(),
            "--repeat".into(),
            "1".into(),
        ],
    );
    assert_eq!(summary["frames"]["count"], walk.poses.len(), "{summary}");
    assert!(summary["frames"]["median_ms"].as_f64().unwrap() > 0.0);
}
