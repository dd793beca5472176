//! The viewer through a real window: `citywalk view --screenshot` under Xvfb (`xvfb-run -a`),
//! in walk and fly mode, on a small GeoJSON city written here. The screenshot must exist, have
//! the requested size and not be (nearly) one flat colour. Then a five-pose path is played
//! (`--play`) twice, with and without the overlay panel: the two screenshots of its last pose
//! must differ (the panel is drawn) and the one without the panel must show the scene. The
//! panel-less playback runs with occlusion culling (the default) and again with
//! `--no-culling` (brute force): the same camera must give the same image (under 1 % of the
//! pixels may differ).
//!
//! Without Xvfb or a GPU adapter (software ones count: lavapipe, llvmpipe) the test is skipped
//! with a message, except under CI (env `CI` set), where it fails.

use std::io::Read;
use std::path::{Path, PathBuf};
use std::process::{Command, Stdio};
use std::time::{Duration, Instant};

const WIDTH: u32 = 320;
const HEIGHT: u32 = 200;
/// A generous bound on one viewer run on a software adapter (start-up is about a second).
const RUN_LIMIT: Duration = Duration::from_secs(120);

/// A 3 × 3 grid of buildings (30 m squares, 9 to 33 m tall) separated by 20 m streets, with the
/// street centre lines, in local metres.
fn write_scene(path: &Path) {
    let mut features = Vec::new();
    for i in 0..3 {
        for j in 0..3 {
            let (x, y) = (i as f64 * 50.0, j as f64 * 50.0);
            let ring = [
                [x, y],
                [x + 30.0, y],
                [x + 30.0, y + 30.0],
                [x, y + 30.0],
                [x, y],
            ];
            features.push(serde_json::json!({
                "type": "Feature",
                "id": format!("b{i}{j}"),
                "properties": { "building": "yes", "height": 9.0 + 3.0 * (i * 3 + j) as f64 },
                "geometry": { "type": "Polygon", "coordinates": [ring] }
            }));
        }
    }
    for k in 0..4 {
        let c = k as f64 * 50.0 - 10.0;
        for line in [[[-20.0, c], [150.0, c]], [[c, -20.0], [c, 150.0]]] {
            features.push(serde_json::json!({
                "type": "Feature",
                "properties": { "highway": "residential" },
                "geometry": { "type": "LineString", "coordinates": line }
            }));
        }
    }
    let scene = serde_json::json!({
        "type": "FeatureCollection",
        "crs": { "type": "name", "properties": { "name": "citywalk:local" } },
        "features": features
    });
    std::fs::write(path, scene.to_string()).expect("write the test scene");
}

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
    let mut child = Command::new("xvfb-run")
        .args(["-a", "-s", "-screen 0 1280x1024x24"])
        .arg(env!("CARGO_BIN_EXE_citywalk"))
        .arg("view")
        .arg(scene)
        .args(["--size", &format!("{WIDTH}x{HEIGHT}")])
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

#[test]
fn viewer_writes_a_screenshot_through_a_real_window() {
    if !has_program("xvfb-run") {
        unavailable("xvfb-run is not installed (apt-get install xvfb)");
        return;
    }
    let dir: PathBuf =
        std::env::temp_dir().join(format!("citywalk-viewer-xvfb-{}", std::process::id()));
    std::fs::create_dir_all(&dir).expect("create a temporary directory");
    let scene = dir.join("grid.geojson");
    write_scene(&scene);
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
        let out = dir.join(format!("{name}.png"));
        match run_viewer(&scene, &out, extra) {
            Outcome::NoAdapter(log) => {
                unavailable(&format!("no GPU adapter can present to a window:\n{log}"));
                return;
            }
            Outcome::Screenshot(image) => {
                assert_eq!(
                    image.dimensions(),
                    (WIDTH, HEIGHT),
                    "{name} screenshot size"
                );
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
        }
    }
    let [plain, with_panel] = &played[..] else {
        panic!("two playback screenshots expected, got {}", played.len());
    };
    let differing = plain
        .pixels()
        .zip(with_panel.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        differing > (WIDTH * HEIGHT / 50) as usize,
        "the overlay panel changed only {differing} pixels of the same pose"
    );
    let brute = brute.expect("the brute-force playback ran");
    let changed = plain
        .pixels()
        .zip(brute.pixels())
        .filter(|(a, b)| a != b)
        .count();
    assert!(
        changed * 100 < (WIDTH * HEIGHT) as usize,
        "culling changed {changed} of {} pixels of the same pose",
        WIDTH * HEIGHT
    );
    // Best effort: a leftover temporary directory is harmless.
    let _ = std::fs::remove_dir_all(&dir);
}
