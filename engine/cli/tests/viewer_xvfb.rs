//! The viewer through a real window: `citywalk view --screenshot` under Xvfb (`xvfb-run -a`),
//! in walk and fly mode, on a small GeoJSON city written here. The screenshot must exist, have
//! the requested size and not be (nearly) one flat colour. Then a five-pose path is played
//! (`--play`) twice, with and without the overlay panel: the two screenshots of its last pose
//! must differ (the panel is drawn) and the one without the panel must show the scene. The
//! panel-less playback runs with occlusion culling (the default) and again with
//! `--no-culling` (brute force): the same camera must give the same image (under 1 % of the
//! pixels may differ).
//!
//! A second test preprocesses the same city into a scene package (occluders, cluster tree,
//! B-Quadtree) and plays an aerial path through every culling stage and debug view: all stages,
//! brute force and the LOD cut at the walkthrough tolerance give the same image; a coarse LOD
//! tolerance changes it, the same with and without HZB culling; the cluster view repaints the
//! frame and changes with the cut; the pyramid view is grey and, at level 3, uniform in 8 × 8
//! blocks; the occluder view tints part of the frame blue and leaves the rest.
//!
//! Without Xvfb or a GPU adapter (software ones count: lavapipe, llvmpipe) the test is skipped
//! with a message, except under CI (env `CI` set), where it fails.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

#[path = "support/grid_scene.rs"]
mod grid_scene;
use grid_scene::write_scene;

const WIDTH: u32 = 320;
const HEIGHT: u32 = 200;
/// A generous bound on one viewer run on a software adapter (start-up is about a second).
const RUN_LIMIT: Duration = Duration::from_secs(120);

/// Five poses walking north along the street at x = 40 m, the last one the screenshot's.
fn write_path(path: &Path) {
    let mut text = String::from("citywalk-path 1\nname test walk\nfov_y_deg 60\n");
    for i in 0..5 {
        text.push_str(&format!("pose 40 {} 1.7 90 5\n", -15 + 10 * i));
    }
    std::fs::write(path, text).expect("write the test path");
}

fn has_program(name: &str) -> bool {
    std::env::var_os("PATH")
        .is_some_and(|paths| std::env::split_paths(&paths).any(|dir| dir.join(name).is_file()))
}

/// Skips (prints why) outside CI; fails under CI.
fn unavailable(why: &str) {
    if std::env::var_os("CI").is_some() {
        panic!("CI is set but the viewer test cannot run: {why}");
    }
    eprintln!("skipping the Xvfb viewer test: {why}");
}

/// What one viewer run gave.
enum Outcome {
    Screenshot(image::RgbaImage),
    /// No GPU adapter could present (the message says so).
    NoAdapter(String),
}

fn run_viewer(scene: &Path, out: &Path, extra: &[&str]) -> Outcome {
    run_viewer_sized(scene, out, (WIDTH, HEIGHT), extra)
}

/// [`run_viewer`] with a window of `width × height` pixels.
fn run_viewer_sized(
    scene: &Path,
    out: &Path,
    (width, height): (u32, u32),
    extra: &[&str],
) -> Outcome {
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x1024x24"])
        .arg(env!("CARGO_BIN_EXE_citywalk"))
        .arg("view")
        .arg(scene)
        .args(["--size", &format!("{width}x{height}")])
        .arg("--screenshot")
        .arg(out)
        .args(["--frames", "5"])
        .args(extra)
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .expect("start xvfb-run");
    let mut stderr = child.stderr.take().expect("piped stderr");
    let reader = std::thread::spawn(move || {
        let mut text = String::new();
        // A read error only shortens the message shown on failure.
        let _ = stderr.read_to_string(&mut text);
        text
    });
    let started = Instant::now();
    let status = loop {
        if let Some(status) = child.try_wait().expect("wait for the viewer") {
            break status;
        }
        if started.elapsed() > RUN_LIMIT {
            // Best effort: the panic below is what matters.
            let _ = child.kill();
            panic!("the viewer ran longer than {RUN_LIMIT:?}");
        }
        std::thread::sleep(Duration::from_millis(50));
    };
    let log = reader.join().unwrap_or_default();
    if !status.success() {
        if log.contains("no GPU adapter") {
            return Outcome::NoAdapter(log);
        }
        panic!("citywalk view {extra:?} failed ({status}):\n{log}");
    }
    let image = image::open(out)
        .unwrap_or_else(|e| panic!("reading {}: {e}\n{log}", out.display()))
        .to_rgba8();
    Outcome::Screenshot(image)
}

/// Five poses of an aerial view from the west, 80 m up, looking east and down at the grid
/// (outside the cluster tree's bounds, so the LOD cut can choose clusters).
fn write_aerial_path(path: &Path) {
    let mut text = String::from("citywalk-path 1\nname test aerial\nfov_y_deg 60\n");
    for i in 0..5 {
        text.push_str(&format!("pose {} 65 80 0 -25\n", -150 + 5 * i));
    }
    std::fs::write(path, text).expect("write the test path");
}

/// A fresh temporary directory `citywalk-{name}-{pid}` with the grid scene written into it:
/// `(directory, scene file)`; `None` (skipped, or failed under CI) without `xvfb-run`.
fn scratch_scene(name: &str) -> Option<(PathBuf, PathBuf)> {
    if !has_program("xvfb-run") {
        unavailable("xvfb-run is not installed (apt-get install xvfb)");
        return None;
    }
    let dir: PathBuf = std::env::temp_dir().join(format!("citywalk-{name}-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create a temporary directory");
    let scene = dir.join("grid.geojson");
    write_scene(&scene);
    Some((dir, scene))
}

/// The viewer's screenshot of `scene` with `extra` arguments, written to `dir/{name}.png` and
/// asserted to be `WIDTH × HEIGHT`; `None` (skipped, or failed under CI) when no adapter can
/// present to a window.
fn screenshot(scene: &Path, dir: &Path, name: &str, extra: &[&str]) -> Option<image::RgbaImage> {
    let out = dir.join(format!("{name}.png"));
    match run_viewer(scene, &out, extra) {
        Outcome::NoAdapter(log) => {
            unavailable(&format!("no GPU adapter can present to a window:\n{log}"));
            None
        }
        Outcome::Screenshot(image) => {
            assert_eq!(
                image.dimensions(),
                (WIDTH, HEIGHT),
                "{name} screenshot size"
            );
            Some(image)
        }
    }
}

/// Pixels that differ between two images of equal size.
fn differing(a: &image::RgbaImage, b: &image::RgbaImage) -> usize {
    assert_eq!(a.dimensions(), b.dimensions());
    a.pixels().zip(b.pixels()).filter(|(p, q)| p != q).count()
}

/// The share of pixels (0..=1) that have the image's most common colour.
fn commonest_colour_share(image: &image::RgbaImage) -> f64 {
    let mut colours: Vec<[u8; 4]> = image.pixels().map(|p| p.0).collect();
    colours.sort_unstable();
    let commonest = colours
        .chunk_by(|a, b| a == b)
        .map(<[[u8; 4]]>::len)
        .max()
        .unwrap_or(0);
    commonest as f64 / colours.len().max(1) as f64
}

/// Issue 14 (GPU faults, tiny viewports): windows of 1×1, 3×1 and 1×5 pixels draw through every
/// stage (the pyramid's levels, the cull's tiles and the overlay all shrink to nothing) and give
/// a screenshot of their size, without a panic or a validation error.
#[test]
fn viewer_draws_windows_of_one_pixel() {
    let Some((dir, scene)) = scratch_scene("viewer-tiny") else {
        return;
    };
    for (w, h) in [(1, 1), (3, 1), (1, 5)] {
        let out = dir.join(format!("tiny-{w}x{h}.png"));
        match run_viewer_sized(&scene, &out, (w, h), &["--fly"]) {
            Outcome::NoAdapter(log) => {
                unavailable(&format!("no GPU adapter can present to a window:\n{log}"));
                return;
            }
            Outcome::Screenshot(image) => assert_eq!(image.dimensions(), (w, h)),
        }
    }
    // Best effort: a leftover temporary directory is harmless.
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn viewer_writes_a_screenshot_through_a_real_window() {
    let Some((dir, scene)) = scratch_scene("viewer-xvfb") else {
        return;
    };
    let path_file = dir.join("walk.path");
    write_path(&path_file);
    let path_arg = path_file.to_str().expect("a UTF-8 temporary path");
    let mut played = Vec::new();
    let mut brute = None;
    for (name, extra) in [
        ("walk", &[][..]),
        ("fly", &["--fly"][..]),
        ("play", &["--play", path_arg, "--no-overlay"][..]),
        ("play-overlay", &["--play", path_arg][..]),
        (
            "play-brute",
            &["--play", path_arg, "--no-overlay", "--no-culling"][..],
        ),
    ] {
        let Some(image) = screenshot(&scene, &dir, name, extra) else {
            return;
        };
        // Sky, ground and facades: no colour may cover (nearly) the whole frame.
        let share = commonest_colour_share(&image);
        assert!(
            share < 0.95,
            "{name} screenshot is {:.1} % one colour",
            share * 100.0
        );
        if name == "play-brute" {
            brute = Some(image);
        } else if name.starts_with("play") {
            played.push(image);
        }
    }
    let [plain, with_panel] = &played[..] else {
        panic!("two playback screenshots expected, got {}", played.len());
    };
    let differing_px = differing(plain, with_panel);
    assert!(
        differing_px > (WIDTH * HEIGHT / 50) as usize,
        "the overlay panel changed only {differing_px} pixels of the same pose"
    );
    let brute = brute.expect("the brute-force playback ran");
    let changed = differing(plain, &brute);
    assert!(
        changed * 100 < (WIDTH * HEIGHT) as usize,
        "culling changed {changed} of {} pixels of the same pose",
        WIDTH * HEIGHT
    );
    // Best effort: a leftover temporary directory is harmless.
    let _ = std::fs::remove_dir_all(&dir);
}

#[test]
fn viewer_switches_stages_lod_and_debug_views() {
    let Some((dir, geojson)) = scratch_scene("viewer-stages") else {
        return;
    };
    let package = dir.join("grid.cwk");
    let status = Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .arg("preprocess")
        .arg(&geojson)
        .arg("-o")
        .arg(&package)
        .stdout(Stdio::null())
        .stderr(Stdio::null())
        .status()
        .expect("run citywalk preprocess");
    assert!(status.success(), "citywalk preprocess failed: {status}");
    let path_file = dir.join("aerial.path");
    write_aerial_path(&path_file);
    let path_arg = path_file.to_str().expect("a UTF-8 temporary path");
    let coarse = [
        "--lod",
        "--criterion",
        "chang",
        "--epsilon-px",
        "100000",
        "--tau-px",
        "100",
    ];
    let runs: [(&str, Vec<&str>); 10] = [
        ("all", vec![]),
        ("brute", vec!["--no-culling"]),
        ("lod-fine", vec!["--lod"]),
        ("lod-coarse", coarse.to_vec()),
        (
            "lod-coarse-alone",
            [&coarse[..], &["--no-culling"]].concat(),
        ),
        ("clusters", vec!["--debug-view", "clusters"]),
        (
            "clusters-coarse",
            [&coarse[..], &["--debug-view", "clusters"]].concat(),
        ),
        // The frame's own pyramid and occluder selection: the stages as set, not the auto plan
        // (which may be running a plan without them at the captured frame).
        ("pyramid", vec!["--debug-view", "pyramid", "--no-auto"]),
        (
            "pyramid-3",
            vec!["--debug-view", "pyramid", "--mip", "3", "--no-auto"],
        ),
        ("occluders", vec!["--debug-view", "occluders", "--no-auto"]),
    ];
    let mut shots = std::collections::HashMap::new();
    for (name, flags) in runs {
        let mut extra = vec!["--play", path_arg, "--no-overlay"];
        extra.extend(flags);
        let Some(image) = screenshot(&package, &dir, name, &extra) else {
            return;
        };
        shots.insert(name, image);
    }
    let pixels = (WIDTH * HEIGHT) as usize;
    let shot = |name: &str| &shots[name];
    let same = |a: &str, b: &str| {
        let n = differing(shot(a), shot(b));
        assert!(
            n * 100 < pixels,
            "{a} and {b} differ in {n} of {pixels} pixels"
        );
    };
    let changed = |a: &str, b: &str, min_percent: usize| {
        let n = differing(shot(a), shot(b));
        assert!(
            n * 100 >= pixels * min_percent,
            "{a} and {b} differ in only {n} of {pixels} pixels"
        );
    };
    // Culling and the fine LOD cut do not change the image; a coarse cut does, with or without
    // HZB culling alike.
    same("all", "brute");
    same("all", "lod-fine");
    changed("all", "lod-coarse", 2);
    same("lod-coarse", "lod-coarse-alone");
    // The cluster view repaints everything and follows the cut.
    changed("all", "clusters", 90);
    changed("clusters", "clusters-coarse", 2);
    // The pyramid view is greyscale, not flat; level 3 is uniform over 8 × 8 blocks.
    for name in ["pyramid", "pyramid-3"] {
        let image = shot(name);
        assert!(
            image.pixels().all(|p| p[0] == p[1] && p[1] == p[2]),
            "{name} is not greyscale"
        );
        assert!(commonest_colour_share(image) < 0.95, "{name} is flat");
    }
    let level3 = shot("pyramid-3");
    for (x, y, p) in level3.enumerate_pixels() {
        assert_eq!(
            p,
            level3.get_pixel(x & !7, y & !7),
            "pyramid-3 at ({x}, {y})"
        );
    }
    changed("pyramid", "pyramid-3", 2);
    // The occluder view tints the occluders and leaves the rest of the frame.
    let (all, occluders) = (shot("all"), shot("occluders"));
    let tinted: Vec<_> = all
        .pixels()
        .zip(occluders.pixels())
        .filter(|(a, b)| a != b)
        .collect();
    assert!(
        tinted.len() * 100 >= pixels && tinted.len() * 100 <= pixels * 90,
        "the occluder view changed {} of {pixels} pixels",
        tinted.len()
    );
    // Every occluder is tinted blue, those the pre-pass selected this frame orange, blended
    // over the frame with alpha A in linear light: what a changed pixel gained over (1 - A)
    // times its old colour is the shaded tint, whose channels are ordered as the tint's (blue
    // above green above red, or the reverse for orange), within a rounding tolerance.
    let alpha = citywalk_shaders::constants::DEBUG_OCCLUDER_ALPHA;
    let linear = |p: &image::Rgba<u8>| {
        [0, 1, 2].map(|c| {
            let v = f32::from(p[c]) / 255.0;
            if v <= 0.04045 {
                v / 12.92
            } else {
                ((v + 0.055) / 1.055).powf(2.4)
            }
        })
    };
    let gained = |(a, b): &(&image::Rgba<u8>, &image::Rgba<u8>)| {
        let (a, b) = (linear(a), linear(b));
        [0, 1, 2].map(|c| b[c] - (1.0 - alpha) * a[c])
    };
    const ROUNDING: f32 = 0.01;
    // Channels ordered as the blue tint's (blue, green, red) or the orange tint's (red, green,
    // blue).
    let ordered = |g: [f32; 3], [hi, mid, lo]: [usize; 3]| {
        g[hi] + ROUNDING >= g[mid] && g[mid] + ROUNDING >= g[lo]
    };
    let bluer = tinted
        .iter()
        .filter(|pair| ordered(gained(pair), [2, 1, 0]))
        .count();
    let oranger = tinted
        .iter()
        .filter(|pair| ordered(gained(pair), [0, 1, 2]))
        .count();
    let either = tinted
        .iter()
        .filter(|pair| {
            let g = gained(pair);
            ordered(g, [2, 1, 0]) || ordered(g, [0, 1, 2])
        })
        .count();
    assert!(
        either * 10 >= tinted.len() * 9,
        "only {either} of {} changed pixels took an occluder tint ({bluer} blue, {oranger} orange)",
        tinted.len()
    );
    assert!(oranger > 0, "no selected occluder is shown");
    eprintln!(
        "occluder view: {either} of {} changed pixels tinted ({bluer} blue, {oranger} orange)",
        tinted.len()
    );
    // Best effort: a leftover temporary directory is harmless.
    let _ = std::fs::remove_dir_all(&dir);
}
