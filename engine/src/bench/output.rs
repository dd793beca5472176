//! The benchmark's files: `frames.csv` (one row per scene × path × mode × frame), `bench.json`
//! (one entry per scene × path × mode, plus the adapter and size) and `summary.md`.

use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use crate::bench::run::{BenchError, FrameRecord};

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
    pub culled_fraction_mean: f64,
    pub triangles_mean: f64,
    pub draw_calls_mean: f64,
    pub frame_ms_median: f64,
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
                culled_fraction_mean: mean(rows.iter().map(|r| r.culled_fraction)),
                triangles_mean: mean(rows.iter().map(|r| r.triangles as f64)),
                draw_calls_mean: mean(rows.iter().map(|r| f64::from(r.draw_calls))),
                frame_ms_median: median(rows.iter().map(|r| r.frame_ms).collect()),
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

/// `frames.csv`: a header and one row per record.
pub fn frames_csv(records: &[FrameRecord]) -> String {
    let mut out = String::from(
        "scene,path,mode,frame,visible,drawn,false_culls,culled_fraction,triangles,draw_calls,\
         select_ms,frame_ms,pixel_error_grey,pixel_error_colour\n",
    );
    for r in records {
        let _ = writeln!(
            out,
            "{},{},{},{},{},{},{},{:.6},{},{},{:.4},{:.4},{:.6},{:.6}",
            csv_field(&r.scene),
            csv_field(&r.path),
            csv_field(&r.mode),
            r.frame,
            r.visible,
            r.drawn,
            r.false_culls,
            r.culled_fraction,
            r.triangles,
            r.draw_calls,
            r.select_ms,
            r.frame_ms,
            r.pixel_error_grey,
            r.pixel_error_colour
        );
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
        "| scene | path | mode | frames | false culls | visible | drawn | culled | triangles | \
         draw calls | frame ms (median) | speed-up vs brute | pixel error (grey / colour) |\n",
    );
    out.push_str("|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n");
    for e in &report.entries {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1} | {:.1} | {:.1} % | {:.0} | {:.1} | {:.2} | {} | {:.2} % / {:.2} % |",
            e.scene,
            e.path,
            e.mode,
            e.frames,
            e.false_culls,
            e.visible_mean,
            e.drawn_mean,
            100.0 * e.culled_fraction_mean,
            e.triangles_mean,
            e.draw_calls_mean,
            e.frame_ms_median,
            e.speedup_vs_brute
                .map_or("–".to_string(), |s| format!("{s:.2}×")),
            100.0 * e.pixel_error_mean,
            100.0 * e.pixel_error_colour_mean,
        );
    }
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

    fn record(mode: &str, frame: usize, ms: f64, false_culls: usize) -> FrameRecord {
        FrameRecord {
            scene: "s".into(),
            path: "street".into(),
            mode: mode.into(),
            frame,
            visible: 10,
            drawn: 20,
            false_culls,
            culled_fraction: 0.5,
            triangles: 100,
            draw_calls: 21,
            select_ms: 0.1,
            frame_ms: ms,
            pixel_error_grey: 0.0,
            pixel_error_colour: 0.0,
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
        let report = BenchReport {
            adapter: AdapterSummary {
                name: "a".into(),
                backend: "b".into(),
                device_type: "c".into(),
            },
            size: [64, 48],
            entries: summarise(&records),
        };
        let v: serde_json::Value = serde_json::to_value(&report).unwrap();
        for key in ["adapter", "size", "entries"] {
            assert!(v.get(key).is_some(), "{key}");
        }
        let e = &v["entries"][0];
        for key in [
            "scene",
            "path",
            "mode",
            "frames",
            "false_culls",
            "visible_mean",
            "drawn_mean",
            "culled_fraction_mean",
            "triangles_mean",
            "draw_calls_mean",
            "frame_ms_median",
            "speedup_vs_brute",
            "pixel_error_mean",
        ] {
            assert!(e.get(key).is_some(), "missing {key}");
        }
        let csv = frames_csv(&records);
        assert_eq!(csv.lines().count(), 2);
        assert!(summary_markdown(&report).contains("| s | street | brute |"));
    }
}
