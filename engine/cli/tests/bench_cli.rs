//! `citywalk bench` end to end on a tiny GeoJSON city: its files (frames.csv, bench.json,
//! summary.md, plots), the `oracle` pseudo-mode, the decimated baseline, `--json` on standard
//! output, and the refusal of modes it does not know.
//!
//! Without a GPU adapter (software ones count) the run is skipped with a message, except under
//! CI (env `CI` set), where it fails — the rule of `citywalk_tests::gpu::gpu_or_skip`.

use std::path::Path;
use std::process::{Command, Output};

use citywalk_bench::Mode;
use citywalk_bench::plots::PLOT_SIZE;

#[path = "support/gpu.rs"]
mod gpu;
#[path = "support/grid_scene.rs"]
mod grid_scene;
#[path = "support/scratch.rs"]
mod scratch;
use gpu::gpu_available;
use grid_scene::write_scene;
use scratch::temp_dir;

fn bench(scene: &Path, out: &Path, extra: &[&str]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .arg("bench")
        .arg(scene)
        .arg("--out")
        .arg(out)
        .args(["--paths", "street", "--frames", "4", "--size", "96x64"])
        .args(extra)
        .output()
        .expect("run citywalk bench")
}

#[test]
fn bench_writes_its_files_and_plots() {
    if !gpu_available("bench_cli") {
        return;
    }
    let dir = temp_dir("bench-cli-run");
    let scene = dir.join("tiny.geojson");
    write_scene(&scene);
    let out = dir.join("out");
    let run = bench(
        &scene,
        &out,
        &[
            "--modes",
            "brute,frustum,oracle",
            "--baseline",
            "decimate:25%",
            "--json",
        ],
    );
    let log = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "citywalk bench failed:\n{log}");
    // With --json, standard output is the report alone, the same as bench.json.
    let printed: serde_json::Value = serde_json::from_slice(&run.stdout).unwrap_or_else(|e| {
        panic!(
            "stdout is not JSON ({e}):\n{}",
            String::from_utf8_lossy(&run.stdout)
        )
    });
    let csv = std::fs::read_to_string(out.join("frames.csv")).expect("frames.csv");
    // Header + 4 frames × (3 modes + the decimated baseline).
    assert_eq!(csv.lines().count(), 1 + 4 * 4, "{csv}");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let mut oracle_rows = 0;
    for row in lines.map(|l| l.split(',').collect::<Vec<&str>>()) {
        let cpu_ms: f64 = row[column("cpu_ms")].parse().expect("cpu_ms");
        assert!(cpu_ms.is_finite() && cpu_ms >= 0.0, "{row:?}");
        if row[column("mode")] == "oracle" {
            oracle_rows += 1;
            assert_eq!(row[column("false_culls")], "0", "{row:?}");
            assert_eq!(row[column("drawn")], row[column("visible")], "{row:?}");
        }
    }
    assert_eq!(oracle_rows, 4);
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bench.json")).expect("json"))
            .expect("bench.json parses");
    let modes: Vec<&str> = json["entries"]
        .as_array()
        .expect("entries")
        .iter()
        .filter_map(|e| e["mode"].as_str())
        .collect();
    assert_eq!(modes, ["brute", "frustum", "oracle", "decimated"]);
    for e in json["entries"].as_array().expect("entries") {
        let ratio = e["oracle_ratio"].as_f64().unwrap_or_else(|| panic!("{e}"));
        let (median, oracle_median) = (
            e["frame_ms_median"].as_f64().expect("median"),
            json["entries"][2]["frame_ms_median"]
                .as_f64()
                .expect("oracle median"),
        );
        assert!(
            (ratio - median / oracle_median).abs() <= 1e-9 * ratio,
            "{e}"
        );
        for key in ["frame_ms_p95", "frame_ms_p99", "frame_ms_max"] {
            assert!(e[key].as_f64().expect(key) >= median, "{key}: {e}");
        }
        let cpu = |key: &str| e[key].as_f64().unwrap_or_else(|| panic!("{key}: {e}"));
        assert!(
            cpu("cpu_ms_max") >= cpu("cpu_ms_p99") && cpu("cpu_ms_p99") >= cpu("cpu_ms_median")
        );
    }
    assert_eq!(json["entries"][2]["false_culls"], 0);
    assert_eq!(json["size"], serde_json::json!([96, 64]));
    // The scene's load: its buildings, a time and the process's memory then and at its peak.
    let scenes = json["scenes"].as_array().expect("scenes");
    assert_eq!(scenes.len(), 1, "{scenes:?}");
    assert_eq!(scenes[0]["scene"], "tiny");
    assert!(scenes[0]["buildings"].as_u64().expect("buildings") > 0);
    assert!(scenes[0]["ready_s"].as_f64().expect("ready_s") > 0.0);
    let resident = scenes[0]["resident_mib"].as_f64().expect("resident_mib");
    let peak = json["peak_resident_mib"]
        .as_f64()
        .expect("peak_resident_mib");
    assert!(resident > 1.0 && peak >= resident, "{resident} {peak}");
    // Vulkan's allocator reports what the scene's buffers hold (lavapipe's are process memory).
    let on_gpu = scenes[0]["gpu_allocated_mib"]
        .as_f64()
        .expect("gpu_allocated_mib");
    assert!(on_gpu > 0.0 && on_gpu < resident, "{on_gpu} {resident}");
    assert_eq!(printed, json);
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(
        summary.contains("| tiny | street | decimated |"),
        "{summary}"
    );
    assert!(
        summary.contains("| tiny | street | oracle |") && summary.contains("÷ oracle"),
        "{summary}"
    );
    for kind in ["frame-ms", "triangles", "pixel-error", "culled"] {
        let file = out.join(format!("plot-tiny-street-{kind}.png"));
        let image = image::open(&file)
            .unwrap_or_else(|e| panic!("{}: {e}\n{log}", file.display()))
            .to_rgb8();
        assert_eq!(image.dimensions(), PLOT_SIZE);
        let first = *image.get_pixel(0, 0);
        assert!(image.pixels().any(|p| *p != first), "{kind} plot is blank");
    }
    std::fs::remove_dir_all(&dir).expect("clean up");
}

#[test]
fn unknown_and_unbuilt_modes_are_refused() {
    let dir = temp_dir("bench-cli-refuse");
    let scene = dir.join("tiny.geojson");
    write_scene(&scene);
    let out = dir.join("out");
    let run = bench(&scene, &out, &["--modes", "brute,warp-speed"]);
    let log = String::from_utf8_lossy(&run.stderr);
    assert!(!run.status.success());
    assert!(log.contains("unknown mode 'warp-speed'"), "{log}");
    assert!(!out.join("bench.json").exists());

    let run = bench(&scene, &out, &["--baseline", "decimate:nothing"]);
    assert!(!run.status.success());
    assert!(
        String::from_utf8_lossy(&run.stderr).contains("unknown mode 'nothing'"),
        "{}",
        String::from_utf8_lossy(&run.stderr)
    );

    // `--list-modes` lists every mode the command line takes, in order.
    let list = Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .args(["bench", "--list-modes"])
        .output()
        .expect("run citywalk bench --list-modes");
    assert!(list.status.success());
    assert_eq!(
        String::from_utf8_lossy(&list.stdout).trim(),
        Mode::NAMED.map(Mode::name).join(",")
    );
    std::fs::remove_dir_all(&dir).expect("clean up");
}

/// Issue 14: `bench --frames 1` measured 2 frames (every generated path was raised to two
/// poses). One frame per generated path and mode now, in frames.csv and the path file.
#[test]
fn issue14_small_bench_frames_1_measures_one_frame() {
    if !gpu_available("bench_cli frames 1") {
        return;
    }
    let dir = temp_dir("bench-cli-one-frame");
    let scene = dir.join("tiny.geojson");
    write_scene(&scene);
    let out = dir.join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .arg("bench")
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--paths", "street,dive", "--frames", "1", "--size", "96x64"])
        .args(["--modes", "brute,frustum"])
        .output()
        .expect("run citywalk bench");
    let log = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "citywalk bench failed:\n{log}");
    let csv = std::fs::read_to_string(out.join("frames.csv")).expect("frames.csv");
    // Header + 1 frame × 2 paths × 2 modes.
    assert_eq!(csv.lines().count(), 1 + 2 * 2, "{csv}");
    for path in ["street", "dive"] {
        let file = std::fs::read_to_string(out.join(format!("tiny-{path}.path"))).unwrap();
        let poses = file.lines().filter(|l| l.starts_with("pose ")).count();
        assert_eq!(poses, 1, "{file}");
    }
}

/// Issue 15: `--paths overview` flies in from three city diameters, circles and flies away; the
/// far frames' share of the full-detail triangles reaches bench.json and summary.md, brute force
/// drawing all of them.
#[test]
fn issue15_overview_reports_its_far_views() {
    if !gpu_available("bench_cli overview") {
        return;
    }
    let dir = temp_dir("bench-cli-overview");
    let scene = dir.join("tiny.geojson");
    write_scene(&scene);
    let out = dir.join("out");
    let run = Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .arg("bench")
        .arg(&scene)
        .arg("--out")
        .arg(&out)
        .args(["--paths", "overview", "--frames", "8", "--size", "96x64"])
        .args(["--modes", "brute,lod"])
        .output()
        .expect("run citywalk bench");
    let log = String::from_utf8_lossy(&run.stderr);
    assert!(run.status.success(), "citywalk bench failed:\n{log}");
    let csv = std::fs::read_to_string(out.join("frames.csv")).expect("frames.csv");
    let mut lines = csv.lines();
    let header: Vec<&str> = lines.next().expect("header").split(',').collect();
    let column = |name: &str| header.iter().position(|h| *h == name).expect(name);
    let distances: Vec<f64> = lines
        .map(|l| l.split(',').collect::<Vec<&str>>())
        .filter(|row| row[column("mode")] == "brute")
        .map(|row| row[column("distance_diameters")].parse().expect("distance"))
        .collect();
    assert_eq!(distances.len(), 8, "{csv}");
    assert!(distances[0] > 2.9 && distances[7] > 2.9, "{distances:?}");
    assert!(distances[3] < 1.0, "the circle is near: {distances:?}");
    let json: serde_json::Value =
        serde_json::from_str(&std::fs::read_to_string(out.join("bench.json")).expect("json"))
            .expect("bench.json parses");
    let entries = json["entries"].as_array().expect("entries");
    let far = |mode: &str| {
        let e = entries.iter().find(|e| e["mode"] == mode).expect(mode);
        e["far_triangle_share"].clone()
    };
    let far_frames = distances.iter().filter(|&&d| d > 1.0).count() as u64;
    assert_eq!(far("brute")["frames"], far_frames, "{json}");
    assert_eq!(far("brute")["mean"], 1.0, "{json}");
    let lod = far("lod");
    let (mean, max) = (lod["mean"].as_f64().unwrap(), lod["max"].as_f64().unwrap());
    assert!(0.0 < mean && mean <= max && max <= 1.0, "{lod}");
    let summary = std::fs::read_to_string(out.join("summary.md")).expect("summary.md");
    assert!(summary.contains("Far views"), "{summary}");
    assert!(out.join("tiny-overview.path").exists());
    std::fs::remove_dir_all(&dir).expect("clean up");
}
