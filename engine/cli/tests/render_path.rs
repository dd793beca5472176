//! `citywalk render SCENE --path ... -o DIR`: every pose of a camera path rendered headless to
//! `DIR/frame_0000.png` ...; a path file of five poses, and a generated `flyover` of five.
//!
//! Without a GPU adapter (software ones count: lavapipe, llvmpipe) the rendering test is skipped
//! with a message, except under CI (env `CI` set), where it fails.

use std::path::Path;
use std::process::Command;

use citywalk_scenes::camera_path::{CameraPath, CameraPose};
use glam::Vec3;

#[path = "support/gpu.rs"]
mod gpu;
#[path = "support/scratch.rs"]
mod scratch;
use gpu::gpu_available;
use scratch::temp_dir;

const WIDTH: u32 = 96;
const HEIGHT: u32 = 64;

/// A row of three buildings (20 m squares, 12 to 30 m tall) along a street, in local metres.
fn write_scene(path: &Path) {
    let mut features = Vec::new();
    for i in 0..3 {
        let x = i as f64 * 40.0;
        let ring = [
            [x, 0.0],
            [x + 20.0, 0.0],
            [x + 20.0, 20.0],
            [x, 20.0],
            [x, 0.0],
        ];
        features.push(serde_json::json!({
            "type": "Feature",
            "id": format!("b{i}"),
            "properties": { "building": "yes", "height": 12.0 + 9.0 * i as f64 },
            "geometry": { "type": "Polygon", "coordinates": [ring] }
        }));
    }
    features.push(serde_json::json!({
        "type": "Feature",
        "properties": { "highway": "residential" },
        "geometry": { "type": "LineString", "coordinates": [[-20.0, -10.0], [120.0, -10.0]] }
    }));
    let scene = serde_json::json!({
        "type": "FeatureCollection",
        "crs": { "type": "name", "properties": { "name": "citywalk:local" } },
        "features": features
    });
    std::fs::write(path, scene.to_string()).expect("write the test scene");
}

fn citywalk(args: &[&std::ffi::OsStr]) -> std::process::Output {
    Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .args(args)
        .output()
        .expect("run citywalk")
}

/// The frames written to `dir`, in order, checked for count and size.
fn frames(dir: &Path, count: usize) -> Vec<image::RgbaImage> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .expect("list the output directory")
        .map(|e| {
            e.expect("directory entry")
                .file_name()
                .to_string_lossy()
                .into_owned()
        })
        .filter(|n| n.ends_with(".png"))
        .collect();
    names.sort();
    let want: Vec<String> = (0..count).map(|i| format!("frame_{i:04}.png")).collect();
    assert_eq!(names, want);
    names
        .iter()
        .map(|n| {
            let image = image::open(dir.join(n)).expect("read a frame").to_rgba8();
            assert_eq!(image.dimensions(), (WIDTH, HEIGHT), "{n}");
            image
        })
        .collect()
}

#[test]
fn render_writes_one_png_per_pose_of_a_path() {
    if !gpu_available("render_path") {
        return;
    }
    let dir = temp_dir("render-path");
    let scene = dir.join("row.geojson");
    write_scene(&scene);
    // Five poses walking east along the street, looking north at the buildings.
    let walk = CameraPath {
        name: "test walk".into(),
        fov_y_deg: 60.0,
        poses: (0..5)
            .map(|i| CameraPose {
                position: Vec3::new(-10.0 + 30.0 * i as f32, -25.0, 1.7),
                yaw_deg: 90.0,
                pitch_deg: 10.0,
            })
            .collect(),
    };
    let path_file = dir.join("walk.path");
    walk.write(&path_file).expect("write the path");
    let out = dir.join("walk");
    let size = format!("{WIDTH}x{HEIGHT}");
    let run = citywalk(&[
        "render".as_ref(),
        scene.as_os_str(),
        "--path".as_ref(),
        path_file.as_os_str(),
        "--size".as_ref(),
        size.as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    let images = frames(&out, 5);
    assert_ne!(images[0], images[4], "the camera moved: the frames differ");
    assert!(!out.join("path.path").exists(), "a path file is not copied");

    // A generated flyover of five poses, written next to its frames.
    let out = dir.join("flyover");
    let run = citywalk(&[
        "render".as_ref(),
        scene.as_os_str(),
        "--path".as_ref(),
        "flyover".as_ref(),
        "--frames".as_ref(),
        "5".as_ref(),
        "--size".as_ref(),
        size.as_ref(),
        "-o".as_ref(),
        out.as_os_str(),
    ]);
    assert!(
        run.status.success(),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );
    frames(&out, 5);
    let written = CameraPath::read(&out.join("path.path")).expect("the generated path parses");
    assert_eq!(written.poses.len(), 5);
    // Best effort: a leftover temporary directory is harmless.
    let _ = std::fs::remove_dir_all(&dir);
}

/// `--mode` runs the frame through the culling stages of the benchmark's modes (the raw input is
/// preprocessed first): the occlusion-culled frames of a path are the brute-force images, texel
/// for texel but for at most 0.5 % of pixels (depth ties on coplanar faces drawn in another
/// order), and the tool says which stages ran. `oracle` is refused.
#[test]
fn culled_modes_render_the_brute_force_frames() {
    if !gpu_available("render_path modes") {
        return;
    }
    let dir = temp_dir("render-modes");
    let scene = dir.join("row.geojson");
    write_scene(&scene);
    let size = format!("{WIDTH}x{HEIGHT}");
    let render = |mode: &str| {
        let out = dir.join(mode);
        let run = citywalk(&[
            "render".as_ref(),
            scene.as_os_str(),
            "--path".as_ref(),
            "street".as_ref(),
            "--frames".as_ref(),
            "4".as_ref(),
            "--mode".as_ref(),
            mode.as_ref(),
            "--size".as_ref(),
            size.as_ref(),
            "-o".as_ref(),
            out.as_os_str(),
        ]);
        assert!(
            run.status.success(),
            "{mode}: {}",
            String::from_utf8_lossy(&run.stderr)
        );
        let stdout = String::from_utf8_lossy(&run.stdout).into_owned();
        assert!(stdout.contains(&format!("mode {mode}")), "{stdout}");
        frames(&out, 4)
    };
    let brute = render("brute");
    for mode in ["hzb", "occluders"] {
        for (i, (culled, full)) in render(mode).iter().zip(&brute).enumerate() {
            let differing = culled
                .pixels()
                .zip(full.pixels())
                .filter(|(a, b)| a != b)
                .count();
            assert!(
                differing * 200 <= (WIDTH * HEIGHT) as usize,
                "{mode} frame {i}: {differing} pixels differ from brute force"
            );
        }
    }
    let run = citywalk(&[
        "render".as_ref(),
        scene.as_os_str(),
        "--mode".as_ref(),
        "oracle".as_ref(),
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("benchmark pseudo-mode"), "{stderr}");
    // Best effort: a leftover temporary directory is harmless.
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn path_and_camera_are_mutually_exclusive() {
    let run = citywalk(&[
        "render".as_ref(),
        "scene.geojson".as_ref(),
        "--path".as_ref(),
        "street".as_ref(),
        "--camera".as_ref(),
        "0,0,2,0,0".as_ref(),
    ]);
    assert!(!run.status.success());
    let stderr = String::from_utf8_lossy(&run.stderr);
    assert!(stderr.contains("cannot be used with"), "{stderr}");
}
