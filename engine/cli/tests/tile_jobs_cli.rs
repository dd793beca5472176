//! `citywalk preprocess --plan-tiles`, `--tiles-of PLAN --tile I` and `--merge PLAN` end to
//! end (issue 17): a generated city's tile jobs, run as separate processes in reverse order
//! from their shards alone (the input moved away) and with their files in another folder,
//! merge to the same package bytes as one run; a damaged tile file, a missing one and an input
//! that is not the plan's are refused, naming the file.
//! CPU only.

use std::ffi::OsStr;
use std::path::Path;
use std::process::{Command, Output};

#[path = "support/scratch.rs"]
mod scratch;
use scratch::temp_dir;

fn run<S: AsRef<OsStr>>(dir: &Path, args: &[S]) -> Output {
    Command::new(env!("CARGO_BIN_EXE_citywalk"))
        .current_dir(dir)
        .args(args)
        .output()
        .expect("run citywalk")
}

/// Runs the binary in `dir`; panics with its output unless it succeeds; returns its stdout.
fn citywalk<S: AsRef<OsStr>>(dir: &Path, args: &[S]) -> String {
    let out = run(dir, args);
    let stdout = String::from_utf8_lossy(&out.stdout).into_owned();
    assert!(
        out.status.success(),
        "citywalk {:?} failed:\n{stdout}\n{}",
        args.iter().map(|a| a.as_ref()).collect::<Vec<_>>(),
        String::from_utf8_lossy(&out.stderr)
    );
    stdout
}

/// Runs the binary in `dir`, expecting it to fail; returns its stderr.
fn refused<S: AsRef<OsStr>>(dir: &Path, args: &[S]) -> String {
    let out = run(dir, args);
    assert!(
        !out.status.success(),
        "citywalk {:?} succeeded",
        args.iter().map(|a| a.as_ref()).collect::<Vec<_>>()
    );
    String::from_utf8_lossy(&out.stderr).into_owned()
}

/// The merge of the test's plan and tile files (an output to follow).
const MERGE: [&str; 5] = ["preprocess", "--merge", "city.plan", "--tile-dir", "jobs"];

#[test]
fn tile_jobs_merge_to_the_one_runs_package() {
    let dir = temp_dir("tile-jobs-cli");
    let dir = dir.as_path();
    citywalk(
        dir,
        &[
            "generate",
            "--buildings",
            "3000",
            "--seed",
            "4",
            "-o",
            "city.geojson",
        ],
    );
    citywalk(
        dir,
        &[
            "preprocess",
            "city.geojson",
            "-o",
            "one.cwk",
            "--tile-buildings",
            "500",
        ],
    );
    let planned = citywalk(
        dir,
        &[
            "preprocess",
            "city.geojson",
            "--plan-tiles",
            "-o",
            "city.plan",
            "--tile-buildings",
            "500",
        ],
    );
    let plan: serde_json::Value =
        serde_json::from_slice(&std::fs::read(dir.join("city.plan")).expect("plan")).expect("json");
    let tiles = plan["tiles"].as_array().expect("tiles").len();
    assert!(tiles >= 4, "{tiles} tiles: {planned}");
    assert!(
        planned.starts_with(&format!("{tiles} tiles of 3000 buildings")),
        "{planned}"
    );
    std::fs::create_dir_all(dir.join("jobs")).expect("jobs folder");
    // The jobs read their shards, not the input.
    std::fs::rename(dir.join("city.geojson"), dir.join("away.geojson")).expect("move");
    for t in (0..tiles).rev() {
        let out = format!("jobs/city.plan.tile-{t}");
        let said = citywalk(
            dir,
            &[
                "preprocess",
                "--tiles-of",
                "city.plan",
                "--tile",
                &t.to_string(),
                "-o",
                &out,
            ],
        );
        assert!(said.starts_with(&format!("tile {t}: ")), "{said}");
    }
    // The merge reads the input again.
    std::fs::rename(dir.join("away.geojson"), dir.join("city.geojson")).expect("move back");
    citywalk(dir, &[&MERGE[..], &["-o", "merged.cwk"]].concat());
    let (one, merged) = (
        std::fs::read(dir.join("one.cwk")).expect("one run"),
        std::fs::read(dir.join("merged.cwk")).expect("merged"),
    );
    assert!(
        one == merged,
        "the merged package differs from the one run's"
    );
    // A merge under a memory budget the load alone exceeds: one thread, the budget reported
    // as not kept from the load on, the same package.
    let budgeted = [
        "-o",
        "budgeted.cwk",
        "--memory-budget-gib",
        "0.001",
        "--json",
    ];
    let summary = citywalk(dir, &[&MERGE[..], &budgeted].concat());
    let summary: serde_json::Value = serde_json::from_str(&summary).expect("json summary");
    assert_eq!(summary["threads"], 1, "{summary}");
    let report = &summary["memory_budget"];
    assert_eq!(report["kept"], false, "{report}");
    assert_eq!(report["first_step_over"], "load", "{report}");
    assert!(
        std::fs::read(dir.join("budgeted.cwk")).expect("budgeted merge") == one,
        "the budget changed the merged package"
    );

    // A tile file with a flipped byte, then none at all.
    let tile = dir.join("jobs/city.plan.tile-1");
    let mut bytes = std::fs::read(&tile).expect("tile");
    let middle = bytes.len() / 2;
    bytes[middle] ^= 1;
    std::fs::write(&tile, &bytes).expect("write");
    let merge = [&MERGE[..], &["-o", "bad.cwk"]].concat();
    let err = refused(dir, &merge);
    assert!(
        err.contains("city.plan.tile-1 is damaged: checksum mismatch"),
        "{err}"
    );
    std::fs::remove_file(&tile).expect("remove");
    let err = refused(dir, &merge);
    assert!(err.contains("city.plan.tile-1"), "{err}");
    assert!(!dir.join("bad.cwk").exists());

    // Another city in the plan's input's place.
    citywalk(
        dir,
        &[
            "generate",
            "--buildings",
            "3000",
            "--seed",
            "5",
            "-o",
            "other.geojson",
        ],
    );
    let err = refused(
        dir,
        &[
            "preprocess",
            "other.geojson",
            "--merge",
            "city.plan",
            "--tile-dir",
            "jobs",
            "-o",
            "x.cwk",
        ],
    );
    assert!(
        err.contains("other.geojson is not the plan's input city.geojson"),
        "{err}"
    );
    // A job takes no inputs: it reads its shard.
    let err = refused(
        dir,
        &[
            "preprocess",
            "other.geojson",
            "--tiles-of",
            "city.plan",
            "--tile",
            "0",
            "-o",
            "x",
        ],
    );
    assert!(err.contains("not input files"), "{err}");
}
