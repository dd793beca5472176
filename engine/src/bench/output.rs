//! The benchmark's files: `frames.csv` (one row per scene × path × mode × frame), `bench.json`
//! (one entry per scene × path × mode, plus the adapter and size) and `summary.md`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use crate::bench::run::{BenchError, DRAW_PHASES, FrameRecord};

/// The keys every `bench.json` entry holds (issue 7's documented set and ours), each a field of
/// [`ModeSummary`]: what a consumer of the file may rely on.
pub const ENTRY_KEYS: &[&str] = &[
    "scene",
    "path",
    "mode",
    "frames",
    "false_culls",
    "visible_mean",
    "drawn_mean",
    "clusters_mean",
    "culled_fraction_mean",
    "triangles_mean",
    "draw_calls_mean",
    "frame_ms_median",
    "speedup_vs_brute",
    "pixel_error_mean",
    "gpu_ms_median",
    "gpu_phase_ms_median",
];

/// The aggregate of one scene × path × mode.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ModeSummary {
    pub scene: String,
    pub path: String,
    pub mode: String,
    pub frames: usize,
    /// Total over all frames; anything but zero is a bug (for the `decimated` baseline: visible
    /// buildings with no triangles left, see [`crate::bench::baseline`]).
    pub false_culls: usize,
    pub visible_mean: f64,
    pub drawn_mean: f64,
    /// Mean cluster meshes of the LOD cut drawn per frame (`lod`, `all`; 0 otherwise).
    pub clusters_mean: f64,
    pub culled_fraction_mean: f64,
    pub triangles_mean: f64,
    pub draw_calls_mean: f64,
    pub frame_ms_median: f64,
    /// Median over the frames with GPU timestamps of the frame's GPU time (ms): the sum of its
    /// timed phases ([`crate::gpu_timer::GpuTimes::total_ms`]). `null` when the adapter has no
    /// timestamp queries (or the mode is not timed, as the `decimated` baseline).
    pub gpu_ms_median: Option<f64>,
    /// Per phase, the median over the frames where that phase was timed of its GPU time (ms):
    /// `draw` for `brute`, `frustum`, `quadtree` and `lod`; `early`, `occluders`, `pyramid`,
    /// `cull` and `late` for the two-phase HiZ modes ([`crate::frame`]). Empty without
    /// timestamps. Wall time is still `frame_ms_median`.
    pub gpu_phase_ms_median: BTreeMap<String, f64>,
    /// Brute force's median frame time ÷ this mode's, same scene and path, same run.
    pub speedup_vs_brute: Option<f64>,
    /// Mean share of pixels whose grey level differs from brute force (Chang et al. §9).
    pub pixel_error_mean: f64,
    /// Mean share of pixels differing by more than 40 in a channel (Chang et al. §9).
    pub pixel_error_colour_mean: f64,
}

/// The adapter a run used.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
}

/// Everything `bench.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BenchReport {
    pub adapter: AdapterSummary,
    pub size: [u32; 2],
    pub entries: Vec<ModeSummary>,
}

impl BenchReport {
    /// Total false culls over every culling mode's entry. The `decimated` baseline's entries
    /// are left out: theirs count visible buildings decimated away, not culling bugs
    /// ([`crate::bench::baseline`]).
    pub fn false_culls(&self) -> usize {
        self.entries
            .iter()
            .filter(|e| e.mode != crate::bench::baseline::DECIMATED_MODE)
            .map(|e| e.false_culls)
            .sum()
    }
}

fn mean(values: impl Iterator<Item = f64>) -> f64 {
    let (sum, n) = values.fold((0.0, 0usize), |(s, n), v| (s + v, n + 1));
    if n == 0 { 0.0 } else { sum / n as f64 }
}

fn median(mut values: Vec<f64>) -> f64 {
    if values.is_empty() {
        return 0.0;
    }
    values.sort_by(f64::total_cmp);
    let n = values.len();
    if n % 2 == 1 {
        values[n / 2]
    } else {
        0.5 * (values[n / 2 - 1] + values[n / 2])
    }
}

/// The median of the values present; `None` when none is.
fn median_of_some(values: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let present: Vec<f64> = values.flatten().collect();
    (!present.is_empty()).then(|| median(present))
}

/// The GPU phase names of `records`: the bench's phases in frame order ([`DRAW_PHASES`], then
/// [`crate::gpu_timer::FRAME_PHASES`]), then any other phase a record has, in first-seen order.
pub fn gpu_phase_names<'a>(
    records: impl IntoIterator<Item = &'a FrameRecord>,
) -> Vec<&'static str> {
    let mut names: Vec<&'static str> = DRAW_PHASES.to_vec();
    names.extend(crate::gpu_timer::FRAME_PHASES.iter().copied());
    for r in records {
        for p in &r.gpu.phases {
            if !names.contains(&p.name) {
                names.push(p.name);
            }
        }
    }
    names
}

/// Aggregates frame records by scene × path × mode, in first-seen order.
pub fn summarise(records: &[FrameRecord]) -> Vec<ModeSummary> {
    let mut keys: Vec<(String, String, String)> = Vec::new();
    for r in records {
        let key = (r.scene.clone(), r.path.clone(), r.mode.clone());
        if !keys.contains(&key) {
            keys.push(key);
        }
    }
    let mut out: Vec<ModeSummary> = keys
        .into_iter()
        .map(|(scene, path, mode)| {
            let rows: Vec<&FrameRecord> = records
                .iter()
                .filter(|r| r.scene == scene && r.path == path && r.mode == mode)
                .collect();
            ModeSummary {
                frames: rows.len(),
                false_culls: rows.iter().map(|r| r.false_culls).sum(),
                visible_mean: mean(rows.iter().map(|r| r.visible as f64)),
                drawn_mean: mean(rows.iter().map(|r| r.drawn as f64)),
                clusters_mean: mean(rows.iter().map(|r| r.clusters as f64)),
                culled_fraction_mean: mean(rows.iter().map(|r| r.culled_fraction)),
                triangles_mean: mean(rows.iter().map(|r| r.triangles as f64)),
                draw_calls_mean: mean(rows.iter().map(|r| f64::from(r.draw_calls))),
                frame_ms_median: median(rows.iter().map(|r| r.frame_ms).collect()),
                gpu_ms_median: median_of_some(rows.iter().map(|r| r.gpu.total_ms())),
                gpu_phase_ms_median: gpu_phase_names(rows.iter().copied())
                    .into_iter()
                    .filter_map(|phase| {
                        let ms = median_of_some(rows.iter().map(|r| r.gpu.phase_ms(phase)))?;
                        Some((phase.to_string(), ms))
                    })
                    .collect(),
                speedup_vs_brute: None,
                pixel_error_mean: mean(rows.iter().map(|r| r.pixel_error_grey)),
                pixel_error_colour_mean: mean(rows.iter().map(|r| r.pixel_error_colour)),
                scene,
                path,
                mode,
            }
        })
        .collect();
    let brute: Vec<(String, String, f64)> = out
        .iter()
        .filter(|s| s.mode == "brute")
        .map(|s| (s.scene.clone(), s.path.clone(), s.frame_ms_median))
        .collect();
    for s in &mut out {
        s.speedup_vs_brute = brute
            .iter()
            .find(|(scene, path, _)| *scene == s.scene && *path == s.path)
            .filter(|_| s.frame_ms_median > 0.0)
            .map(|(_, _, b)| b / s.frame_ms_median);
    }
    out
}

/// `frames.csv`: a header and one row per record. After the pixel errors come the GPU times
/// (ms): `gpu_ms` (the sum of the frame's timed phases), then `gpu_<phase>_ms` for every phase
/// of [`gpu_phase_names`]; a cell is empty where the phase was not timed (no timestamp queries
/// on the adapter, or a phase the mode does not have).
pub fn frames_csv(records: &[FrameRecord]) -> String {
    let phases = gpu_phase_names(records);
    let mut out = String::from(
        "scene,path,mode,frame,visible,drawn,clusters,false_culls,culled_fraction,triangles,draw_calls,\
         select_ms,frame_ms,pixel_error_grey,pixel_error_colour,gpu_ms",
    );
    for phase in &phases {
        let _ = write!(out, ",gpu_{phase}_ms");
    }
    out.push('\n');
    let cell = |ms: Option<f64>| ms.map_or(String::new(), |ms| format!("{ms:.4}"));
    for r in records {
        let _ = write!(
            out,
            "{},{},{},{},{},{},{},{},{:.6},{},{},{:.4},{:.4},{:.6},{:.6},{}",
            csv_field(&r.scene),
            csv_field(&r.path),
            csv_field(&r.mode),
            r.frame,
            r.visible,
            r.drawn,
            r.clusters,
            r.false_culls,
            r.culled_fraction,
            r.triangles,
            r.draw_calls,
            r.select_ms,
            r.frame_ms,
            r.pixel_error_grey,
            r.pixel_error_colour,
            cell(r.gpu.total_ms()),
        );
        for phase in &phases {
            let _ = write!(out, ",{}", cell(r.gpu.phase_ms(phase)));
        }
        out.push('\n');
    }
    out
}

fn csv_field(s: &str) -> String {
    if s.contains([',', '"', '\n']) {
        format!("\"{}\"", s.replace('"', "\"\""))
    } else {
        s.to_string()
    }
}

/// `summary.md`: one table a person can read.
pub fn summary_markdown(report: &BenchReport) -> String {
    let mut out = String::new();
    let _ = writeln!(
        out,
        "Adapter: {} ({}, {}); {}×{} pixels.\n",
        report.adapter.name,
        report.adapter.backend,
        report.adapter.device_type,
        report.size[0],
        report.size[1]
    );
    out.push_str(
        "| scene | path | mode | frames | false culls | visible | drawn | clusters | culled | triangles | \
         draw calls | frame ms (median) | GPU ms (median) | speed-up vs brute | pixel error (grey / \
         colour) |\n",
    );
    out.push_str("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for e in &report.entries {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} % | {:.0} | {:.1} | {:.2} | {} | {} | {:.2} % / {:.2} % |",
            e.scene,
            e.path,
            e.mode,
            e.frames,
            e.false_culls,
            e.visible_mean,
            e.drawn_mean,
            e.clusters_mean,
            100.0 * e.culled_fraction_mean,
            e.triangles_mean,
            e.draw_calls_mean,
            e.frame_ms_median,
            e.gpu_ms_median
                .map_or("n/a".to_string(), |ms| format!("{ms:.2}")),
            e.speedup_vs_brute
                .map_or("–".to_string(), |s| format!("{s:.2}×")),
            100.0 * e.pixel_error_mean,
            100.0 * e.pixel_error_colour_mean,
        );
    }
    gpu_phase_table(&mut out, report);
    if report
        .entries
        .iter()
        .any(|e| e.mode == crate::bench::baseline::DECIMATED_MODE)
    {
        out.push_str(
            "\n`decimated`: the whole city decimated with meshoptimizer to a triangle budget and \
             drawn unculled (the baseline a user would pick instead); its false culls are \
             visible buildings with no triangles left and do not fail the benchmark.\n",
        );
    }
    out
}

/// The per-phase GPU medians of every timed entry, as a second table (nothing when no entry
/// has timestamps).
fn gpu_phase_table(out: &mut String, report: &BenchReport) {
    let timed: Vec<&ModeSummary> = report
        .entries
        .iter()
        .filter(|e| !e.gpu_phase_ms_median.is_empty())
        .collect();
    if timed.is_empty() {
        out.push_str(
            "\nGPU ms: n/a, the adapter has no timestamp queries; frame ms is CPU wall time from \
             recording to the GPU's completion.\n",
        );
        return;
    }
    let mut phases: Vec<&str> = DRAW_PHASES
        .iter()
        .chain(crate::gpu_timer::FRAME_PHASES)
        .copied()
        .collect();
    for e in &timed {
        for name in e.gpu_phase_ms_median.keys() {
            if !phases.contains(&name.as_str()) {
                phases.push(name);
            }
        }
    }
    phases.retain(|p| timed.iter().any(|e| e.gpu_phase_ms_median.contains_key(*p)));
    out.push_str(
        "\nGPU time per phase from timestamp queries (median ms; frame ms above is CPU wall \
         time):\n\n| scene | path | mode |",
    );
    for p in &phases {
        let _ = write!(out, " {p} |");
    }
    out.push_str("\n|---|---|---|");
    for _ in &phases {
        out.push_str("---:|");
    }
    out.push('\n');
    for e in timed {
        let _ = write!(out, "| {} | {} | {} |", e.scene, e.path, e.mode);
        for p in &phases {
            match e.gpu_phase_ms_median.get(*p) {
                Some(ms) => {
                    let _ = write!(out, " {ms:.3} |");
                }
                None => out.push_str(" – |"),
            }
        }
        out.push('\n');
    }
}

/// Writes `frames.csv`, `bench.json` and `summary.md` into `dir`.
pub fn write_outputs(
    dir: &Path,
    records: &[FrameRecord],
    report: &BenchReport,
) -> Result<(), BenchError> {
    let write = |name: &str, text: String| {
        let path = dir.join(name);
        std::fs::write(&path, text).map_err(|e| BenchError::Write {
            path,
            reason: e.to_string(),
        })
    };
    write("frames.csv", frames_csv(records))?;
    let json = serde_json::to_string_pretty(report).map_err(|e| BenchError::Write {
        path: dir.join("bench.json"),
        reason: e.to_string(),
    })?;
    write("bench.json", json)?;
    write("summary.md", summary_markdown(report))?;
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A 64×48 report of `entries` on a made-up adapter.
    fn report_of(entries: Vec<ModeSummary>) -> BenchReport {
        BenchReport {
            adapter: AdapterSummary {
                name: "a".into(),
                backend: "b".into(),
                device_type: "c".into(),
            },
            size: [64, 48],
            entries,
        }
    }

    fn record(mode: &str, frame: usize, ms: f64, false_culls: usize) -> FrameRecord {
        FrameRecord {
            scene: "s".into(),
            path: "street".into(),
            mode: mode.into(),
            frame,
            visible: 10,
            drawn: 20,
            clusters: 0,
            false_culls,
            culled_fraction: 0.5,
            triangles: 100,
            draw_calls: 21,
            select_ms: 0.1,
            frame_ms: ms,
            pixel_error_grey: 0.0,
            pixel_error_colour: 0.0,
            gpu: crate::gpu_timer::GpuTimes::default(),
        }
    }

    #[test]
    fn speedup_and_medians() {
        let records = vec![
            record("brute", 0, 10.0, 0),
            record("frustum", 0, 2.0, 0),
            record("brute", 1, 30.0, 0),
            record("frustum", 1, 3.0, 1),
            record("brute", 2, 20.0, 0),
            record("frustum", 2, 4.0, 0),
        ];
        let s = summarise(&records);
        assert_eq!(s.len(), 2);
        assert_eq!(s[0].frame_ms_median, 20.0);
        assert_eq!(s[1].frame_ms_median, 3.0);
        assert_eq!(s[1].speedup_vs_brute, Some(20.0 / 3.0));
        assert_eq!(s[0].speedup_vs_brute, Some(1.0));
        assert_eq!(s[1].false_culls, 1);
    }

    #[test]
    fn json_has_the_documented_keys() {
        let records = vec![record("brute", 0, 10.0, 0)];
        let report = report_of(summarise(&records));
        let v: serde_json::Value = serde_json::to_value(&report).unwrap();
        for key in ["adapter", "size", "entries"] {
            assert!(v.get(key).is_some(), "{key}");
        }
        let e = &v["entries"][0];
        for key in ENTRY_KEYS {
            assert!(e.get(key).is_some(), "missing {key}");
        }
        let csv = frames_csv(&records);
        assert_eq!(csv.lines().count(), 2);
        assert!(summary_markdown(&report).contains("| s | street | brute |"));
    }

    fn timed(mode: &str, frame: usize, phases: &[(&'static str, Option<f64>)]) -> FrameRecord {
        use crate::gpu_timer::{GpuSpan, GpuTimes, PhaseTime};
        let mut r = record(mode, frame, 1.0, 0);
        let mut at_ms = 0.0;
        r.gpu = GpuTimes {
            phases: phases
                .iter()
                .map(|&(name, ms)| PhaseTime {
                    name,
                    span: ms.map(|ms| {
                        let span = GpuSpan {
                            begin_ms: at_ms,
                            end_ms: at_ms + ms,
                        };
                        at_ms += ms;
                        span
                    }),
                })
                .collect(),
        };
        r
    }

    #[test]
    fn gpu_times_reach_the_csv_the_json_and_the_summary() {
        let records = vec![
            timed("brute", 0, &[("draw", Some(4.0))]),
            timed("brute", 1, &[("draw", Some(2.0))]),
            timed("brute", 2, &[("draw", Some(3.0))]),
            timed(
                "hzb",
                0,
                &[
                    ("early", Some(0.5)),
                    ("occluders", None),
                    ("pyramid", Some(0.25)),
                    ("cull", Some(0.125)),
                    ("late", Some(1.0)),
                ],
            ),
            timed(
                "hzb",
                1,
                &[
                    ("early", Some(1.5)),
                    ("occluders", Some(0.5)),
                    ("pyramid", Some(0.25)),
                    ("cull", Some(0.125)),
                    ("late", None),
                ],
            ),
            // An untimed mode (as the adapter without timestamps reports every mode).
            timed("frustum", 0, &[("draw", None)]),
        ];
        let entries = summarise(&records);
        let brute = &entries[0];
        assert_eq!(brute.gpu_ms_median, Some(3.0));
        assert_eq!(brute.gpu_phase_ms_median.get("draw"), Some(&3.0));
        let hzb = &entries[1];
        // Totals 1.875 and 2.375: the median of two is their mean.
        assert_eq!(hzb.gpu_ms_median, Some(2.125));
        assert_eq!(hzb.gpu_phase_ms_median.get("early"), Some(&1.0));
        // Medians over the frames where the phase ran.
        assert_eq!(hzb.gpu_phase_ms_median.get("occluders"), Some(&0.5));
        assert_eq!(hzb.gpu_phase_ms_median.get("late"), Some(&1.0));
        assert!(!hzb.gpu_phase_ms_median.contains_key("draw"));
        let frustum = &entries[2];
        assert_eq!(frustum.gpu_ms_median, None);
        assert!(frustum.gpu_phase_ms_median.is_empty());

        let csv = frames_csv(&records);
        let mut lines = csv.lines();
        let header: Vec<&str> = lines.next().expect("header").split(',').collect();
        let column = |name: &str| header.iter().position(|h| *h == name).expect(name);
        let rows: Vec<Vec<&str>> = lines.map(|l| l.split(',').collect()).collect();
        assert!(rows.iter().all(|r| r.len() == header.len()));
        assert_eq!(rows[0][column("gpu_ms")], "4.0000");
        assert_eq!(rows[0][column("gpu_draw_ms")], "4.0000");
        assert_eq!(rows[0][column("gpu_early_ms")], "");
        assert_eq!(rows[3][column("gpu_occluders_ms")], "");
        assert_eq!(rows[3][column("gpu_late_ms")], "1.0000");
        assert_eq!(rows[5][column("gpu_ms")], "");

        let report = report_of(entries);
        let json: serde_json::Value = serde_json::to_value(&report).unwrap();
        assert_eq!(json["entries"][1]["gpu_phase_ms_median"]["cull"], 0.125);
        assert!(json["entries"][2]["gpu_ms_median"].is_null());
        let md = summary_markdown(&report);
        assert!(md.contains("GPU ms (median)"), "{md}");
        assert!(md.contains("| 3.00 |") && md.contains("| n/a |"), "{md}");
        assert!(md.contains("GPU time per phase"), "{md}");
    }
}
