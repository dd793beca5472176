//! The benchmark's files: `frames.csv` (one row per scene × path × mode × frame), `bench.json`
//! (one entry per scene × path × mode, plus the adapter and size) and `summary.md`.

use std::collections::BTreeMap;
use std::fmt::Write as _;
use std::path::Path;

use serde::Serialize;

use crate::bound::BoundCheck;
use crate::far::FarShare;
use crate::mode::Mode;
use crate::run::{BenchError, DRAW_PHASES, FrameRecord};

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
    "frame_ms_p95",
    "frame_ms_p99",
    "frame_ms_max",
    "cpu_ms_median",
    "cpu_ms_p99",
    "cpu_ms_max",
    "speedup_vs_brute",
    "oracle_ratio",
    "pixel_error_mean",
    "bound_violations",
    "bound_violations_max",
    "far_triangle_share",
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
    /// buildings with no triangles left, see [`crate::baseline`]).
    pub false_culls: usize,
    pub visible_mean: f64,
    pub drawn_mean: f64,
    /// Mean cluster meshes of the LOD cut drawn per frame (`lod`, `all`; 0 otherwise).
    pub clusters_mean: f64,
    pub culled_fraction_mean: f64,
    pub triangles_mean: f64,
    pub draw_calls_mean: f64,
    pub frame_ms_median: f64,
    /// The tail of the frame times ([`percentile`], nearest rank): hitches a median hides.
    pub frame_ms_p95: f64,
    pub frame_ms_p99: f64,
    pub frame_ms_max: f64,
    /// The engine's own CPU time per frame ([`FrameRecord::cpu_ms`]): median, p99 (nearest
    /// rank) and max.
    pub cpu_ms_median: f64,
    pub cpu_ms_p99: f64,
    pub cpu_ms_max: f64,
    /// Median over the frames with GPU timestamps of the frame's GPU time (ms): the sum of its
    /// timed phases ([`citywalk_runtime::gpu_timer::GpuTimes::total_ms`]). `null` when the adapter has no
    /// timestamp queries (or the mode is not timed, as the `decimated` baseline).
    pub gpu_ms_median: Option<f64>,
    /// Per phase, the median over the frames where that phase was timed of its GPU time (ms):
    /// `draw` for `brute`, `frustum`, `quadtree` and `lod`; `early`, `occluders`, `pyramid`,
    /// `cull` and `late` for the two-phase HiZ modes ([`citywalk_runtime::frame`]). Empty without
    /// timestamps. Wall time is still `frame_ms_median`.
    pub gpu_phase_ms_median: BTreeMap<String, f64>,
    /// Brute force's median frame time ÷ this mode's, same scene and path, same run.
    pub speedup_vs_brute: Option<f64>,
    /// This mode's median frame time ÷ the `oracle` mode's, same scene and path, same run: how
    /// far from the fastest any culling could be (1.0 is the floor). `null` when `oracle` was
    /// not run.
    pub oracle_ratio: Option<f64>,
    /// Mean share of pixels whose grey level differs from brute force (Chang et al. §9).
    pub pixel_error_mean: f64,
    /// Mean share of pixels differing by more than 40 in a channel (Chang et al. §9).
    pub pixel_error_colour_mean: f64,
    /// Of all the pixels of the path's frames whose grey level differs from brute force, the
    /// share farther from every edge of the brute-force frame than the LOD tolerance + 1 px
    /// ([`crate::bound`]); 0 when none differ.
    pub bound_violations: f64,
    /// The largest share of one frame.
    pub bound_violations_max: f64,
    /// The far views ([`crate::far`]): frames farther than the city's diameter from its centre,
    /// the share of the full-detail triangles drawn there and the LOD bound; `null` when the
    /// path has none.
    pub far_triangle_share: Option<FarShare>,
}

/// The adapter a run used.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct AdapterSummary {
    pub name: String,
    pub backend: String,
    pub device_type: String,
}

/// How long a scene took to open, and the process's memory once it was ready.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct SceneLoad {
    pub scene: String,
    pub buildings: usize,
    pub triangles: usize,
    /// From the start of reading the scene to everything uploaded and ready for the first
    /// frame (seconds, wall clock).
    pub ready_s: f64,
    /// Resident memory of the process when the scene was ready (MiB; `None` where the
    /// platform does not say). With a software adapter the GPU's buffers are in it too.
    pub resident_mib: Option<f64>,
    /// GPU memory the device's allocator held when the scene was ready (MiB; `None` where the
    /// backend keeps no report): the scene's buffers and the frames' targets.
    pub gpu_allocated_mib: Option<f64>,
    /// The cluster textures' residency after the scene's last frame (`None`: none drawn).
    pub cluster_textures: Option<TextureUse>,
}

/// How a scene's cluster textures were held over its frames.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct TextureUse {
    /// `--texture-budget-mib`, and the page views it holds (the texture array's layers,
    /// allocated at load: the GPU memory the textures take, whatever is resident).
    pub budget_mib: u64,
    pub layers: usize,
    /// Page views resident after the last frame (a layer once filled stays filled, so this
    /// is the most that was resident in any frame), their MiB, and how many were uploaded and
    /// evicted in all.
    pub resident: usize,
    pub resident_mib: f64,
    pub uploaded: u64,
    pub evictions: u64,
}

/// Everything `bench.json` holds.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BenchReport {
    pub adapter: AdapterSummary,
    pub size: [u32; 2],
    /// One per scene, in the order benchmarked.
    pub scenes: Vec<SceneLoad>,
    /// The process's peak resident memory at the end of the run (MiB; `None` where the
    /// platform does not say).
    pub peak_resident_mib: Option<f64>,
    pub entries: Vec<ModeSummary>,
}

/// The process's resident memory now and its peak so far (MiB;
/// [`citywalk_scenes::process_memory::resident_bytes`]); `None` off Linux.
pub fn resident_mib() -> (Option<f64>, Option<f64>) {
    let mib = |bytes: Option<u64>| bytes.map(|b| b as f64 / 1_048_576.0);
    let (now, peak) = citywalk_scenes::process_memory::resident_bytes();
    (mib(now), mib(peak))
}

impl BenchReport {
    /// Total false culls over every culling mode's entry. The `decimated` baseline's entries
    /// are left out: theirs count visible buildings decimated away, not culling bugs
    /// ([`crate::baseline`]).
    pub fn false_culls(&self) -> usize {
        self.entries
            .iter()
            .filter(|e| e.mode != crate::baseline::DECIMATED_MODE)
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

/// The `pct`-th percentile (`pct` in 1..=100) by nearest rank: the smallest value with at least
/// `pct` % of the values at or below it, i.e. the `⌈pct·n/100⌉`-th smallest. It is always one of
/// the measured frames (no interpolation), and p100 is the max. The rank is computed in
/// integers, so p95 of 20 frames is the 19th exactly. 0 for no values, as [`median`].
pub fn percentile(values: &[f64], pct: u32) -> f64 {
    debug_assert!((1..=100).contains(&pct), "percentile {pct}");
    if values.is_empty() {
        return 0.0;
    }
    let mut sorted = values.to_vec();
    sorted.sort_by(f64::total_cmp);
    let n = sorted.len();
    let rank = (pct.clamp(1, 100) as usize * n).div_ceil(100);
    sorted[rank.clamp(1, n) - 1]
}

/// The median of the values present; `None` when none is.
fn median_of_some(values: impl Iterator<Item = Option<f64>>) -> Option<f64> {
    let present: Vec<f64> = values.flatten().collect();
    (!present.is_empty()).then(|| median(present))
}

/// The GPU phase names of `records`: the bench's phases in frame order ([`DRAW_PHASES`], then
/// [`citywalk_runtime::gpu_timer::FRAME_PHASES`]), then any other phase a record has, in first-seen order.
pub fn gpu_phase_names<'a>(
    records: impl IntoIterator<Item = &'a FrameRecord>,
) -> Vec<&'static str> {
    let mut names: Vec<&'static str> = DRAW_PHASES.to_vec();
    names.extend(citywalk_runtime::gpu_timer::FRAME_PHASES.iter().copied());
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
            let frame_ms: Vec<f64> = rows.iter().map(|r| r.frame_ms).collect();
            let cpu_ms: Vec<f64> = rows.iter().map(|r| r.cpu_ms).collect();
            ModeSummary {
                frames: rows.len(),
                false_culls: rows.iter().map(|r| r.false_culls).sum(),
                visible_mean: mean(rows.iter().map(|r| r.visible as f64)),
                drawn_mean: mean(rows.iter().map(|r| r.drawn as f64)),
                clusters_mean: mean(rows.iter().map(|r| r.clusters as f64)),
                culled_fraction_mean: mean(rows.iter().map(|r| r.culled_fraction)),
                triangles_mean: mean(rows.iter().map(|r| r.triangles as f64)),
                draw_calls_mean: mean(rows.iter().map(|r| f64::from(r.draw_calls))),
                frame_ms_median: median(frame_ms.clone()),
                frame_ms_p95: percentile(&frame_ms, 95),
                frame_ms_p99: percentile(&frame_ms, 99),
                frame_ms_max: percentile(&frame_ms, 100),
                cpu_ms_median: median(cpu_ms.clone()),
                cpu_ms_p99: percentile(&cpu_ms, 99),
                cpu_ms_max: percentile(&cpu_ms, 100),
                gpu_ms_median: median_of_some(rows.iter().map(|r| r.gpu.total_ms())),
                gpu_phase_ms_median: gpu_phase_names(rows.iter().copied())
                    .into_iter()
                    .filter_map(|phase| {
                        let ms = median_of_some(rows.iter().map(|r| r.gpu.phase_ms(phase)))?;
                        Some((phase.to_string(), ms))
                    })
                    .collect(),
                speedup_vs_brute: None,
                oracle_ratio: None,
                pixel_error_mean: mean(rows.iter().map(|r| r.pixel_error_grey)),
                pixel_error_colour_mean: mean(rows.iter().map(|r| r.pixel_error_colour)),
                bound_violations: rows
                    .iter()
                    .map(|r| r.bound_check())
                    .sum::<BoundCheck>()
                    .share(),
                bound_violations_max: rows
                    .iter()
                    .map(|r| r.bound_check().share())
                    .fold(0.0, f64::max),
                far_triangle_share: FarShare::of(rows.iter().copied()),
                scene,
                path,
                mode,
            }
        })
        .collect();
    let medians_of = |mode: &str| -> Vec<(String, String, f64)> {
        out.iter()
            .filter(|s| s.mode == mode)
            .map(|s| (s.scene.clone(), s.path.clone(), s.frame_ms_median))
            .collect()
    };
    let brute = medians_of(Mode::Brute.name());
    let oracle = medians_of(Mode::Oracle.name());
    let same_run = |of: &[(String, String, f64)], s: &ModeSummary| {
        of.iter()
            .find(|(scene, path, _)| *scene == s.scene && *path == s.path)
            .map(|&(_, _, ms)| ms)
    };
    for s in &mut out {
        s.speedup_vs_brute = same_run(&brute, s)
            .filter(|_| s.frame_ms_median > 0.0)
            .map(|b| b / s.frame_ms_median);
        s.oracle_ratio = same_run(&oracle, s)
            .filter(|&o| o > 0.0)
            .map(|o| s.frame_ms_median / o);
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
        "scene,path,mode,frame,visible,drawn,clusters,false_culls,culled_fraction,triangles,\
         triangle_share,distance_diameters,draw_calls,select_ms,frame_ms,cpu_ms,pixel_error_grey,\
         pixel_error_colour,bound_px,differing_px,beyond_bound_px,gpu_ms",
    );
    for phase in &phases {
        let _ = write!(out, ",gpu_{phase}_ms");
    }
    out.push('\n');
    let cell = |ms: Option<f64>| ms.map_or(String::new(), |ms| format!("{ms:.4}"));
    for r in records {
        let _ = write!(
            out,
            "{},{},{},{},{},{},{},{},{:.6},{},{:.6},{:.4},{},{:.4},{:.4},{:.4},{:.6},{:.6},{},{},{},{}",
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
            r.triangle_share,
            r.distance_diameters,
            r.draw_calls,
            r.select_ms,
            r.frame_ms,
            r.cpu_ms,
            r.pixel_error_grey,
            r.pixel_error_colour,
            r.bound_px,
            r.differing_px,
            r.beyond_bound_px,
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
    if !report.scenes.is_empty() {
        out.push_str(
            "| scene | buildings | triangles | ready (s) | resident (MiB) | GPU allocated (MiB) |\n",
        );
        out.push_str("|---|---:|---:|---:|---:|---:|\n");
        let mib = |m: Option<f64>| m.map_or("n/a".to_string(), |m| format!("{m:.0}"));
        for l in &report.scenes {
            let _ = writeln!(
                out,
                "| {} | {} | {} | {:.2} | {} | {} |",
                l.scene,
                l.buildings,
                l.triangles,
                l.ready_s,
                mib(l.resident_mib),
                mib(l.gpu_allocated_mib)
            );
        }
        let peak = report.peak_resident_mib;
        let _ = writeln!(
            out,
            "\nPeak resident memory of the run: {} MiB.\n",
            peak.map_or("n/a".to_string(), |m| format!("{m:.0}"))
        );
    }
    out.push_str(
        "| scene | path | mode | frames | false culls | visible | drawn | clusters | culled | triangles | \
         draw calls | frame ms (median) | p95 | p99 | max | CPU ms (median / p99 / max) | \
         GPU ms (median) | speed-up vs brute | ÷ oracle | pixel error (grey / colour) | \
         bound violations (path / worst frame) |\n",
    );
    out.push_str(
        "|---|---|---|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|---:|\n",
    );
    for e in &report.entries {
        let _ = writeln!(
            out,
            "| {} | {} | {} | {} | {} | {:.1} | {:.1} | {:.1} | {:.1} % | {:.0} | {:.1} | {:.2} | {:.2} | {:.2} | {:.2} | {:.2} / {:.2} / {:.2} | {} | {} | {} | {:.2} % / {:.2} % | {:.3} % / {:.3} % |",
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
            e.frame_ms_p95,
            e.frame_ms_p99,
            e.frame_ms_max,
            e.cpu_ms_median,
            e.cpu_ms_p99,
            e.cpu_ms_max,
            e.gpu_ms_median
                .map_or("n/a".to_string(), |ms| format!("{ms:.2}")),
            e.speedup_vs_brute
                .map_or("–".to_string(), |s| format!("{s:.2}×")),
            e.oracle_ratio
                .map_or("–".to_string(), |r| format!("{r:.2}×")),
            100.0 * e.pixel_error_mean,
            100.0 * e.pixel_error_colour_mean,
            100.0 * e.bound_violations,
            100.0 * e.bound_violations_max,
        );
    }
    out.push_str(
        "\nFrame ms is CPU wall time from recording to the GPU's completion; p95 and p99 are \
         nearest-rank percentiles over the path's frames. CPU ms is the engine's own thread CPU \
         time per frame (selection, recording, submission, reading its report; not the wait for \
         the GPU). Bound violations: of the pixels differing from brute force, the share farther \
         than the LOD tolerance + 1 px from every edge (colour or id step) of the brute-force \
         frame.\n",
    );
    if report.entries.iter().any(|e| e.mode == Mode::Oracle.name()) {
        out.push_str(
            "\n`oracle`: exactly the buildings the ID-buffer oracle sees, drawn in one plain pass \
             (finding them is not timed): the fastest any culling could be. ÷ oracle is a mode's \
             median frame time ÷ the oracle's, same scene and path.\n",
        );
    }
    crate::far::far_table(&mut out, report);
    gpu_phase_table(&mut out, report);
    if report
        .entries
        .iter()
        .any(|e| e.mode == crate::baseline::DECIMATED_MODE)
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
        .chain(citywalk_runtime::gpu_timer::FRAME_PHASES)
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
pub(crate) mod tests {
    use super::*;

    /// A 64×48 report of `entries` on a made-up adapter.
    pub(crate) fn report_of(entries: Vec<ModeSummary>) -> BenchReport {
        BenchReport {
            adapter: AdapterSummary {
                name: "a".into(),
                backend: "b".into(),
                device_type: "c".into(),
            },
            size: [64, 48],
            scenes: Vec::new(),
            peak_resident_mib: None,
            entries,
        }
    }

    pub(crate) fn record(mode: &str, frame: usize, ms: f64, false_culls: usize) -> FrameRecord {
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
            triangle_share: 0.5,
            distance_diameters: 0.5,
            draw_calls: 21,
            select_ms: 0.1,
            frame_ms: ms,
            cpu_ms: ms / 10.0,
            pixel_error_grey: 0.0,
            pixel_error_colour: 0.0,
            bound_px: 2.0,
            differing_px: 0,
            beyond_bound_px: 0,
            gpu: citywalk_runtime::gpu_timer::GpuTimes::default(),
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
    fn percentiles_are_nearest_rank() {
        // 1..=100 in a scrambled order: the p-th percentile of 100 values is the p-th smallest.
        let hundred: Vec<f64> = (0..100).map(|i| f64::from((i * 37) % 100 + 1)).collect();
        assert_eq!(percentile(&hundred, 95), 95.0);
        assert_eq!(percentile(&hundred, 99), 99.0);
        assert_eq!(percentile(&hundred, 100), 100.0);
        assert_eq!(percentile(&hundred, 1), 1.0);
        // Few frames: the rank rounds up, so one hitch in four is the p95 and the p99.
        let four = [30.0, 10.0, 400.0, 20.0];
        assert_eq!(percentile(&four, 50), 20.0);
        assert_eq!(percentile(&four, 75), 30.0);
        assert_eq!(percentile(&four, 76), 400.0);
        assert_eq!(percentile(&four, 95), 400.0);
        // 20 frames: p95 is the 19th smallest, not the max (the rank is exact, 95·20/100 = 19).
        let twenty: Vec<f64> = (1..=20).rev().map(f64::from).collect();
        assert_eq!(percentile(&twenty, 95), 19.0);
        assert_eq!(percentile(&twenty, 99), 20.0);
        assert_eq!(percentile(&[7.5], 99), 7.5);
        assert_eq!(percentile(&[], 95), 0.0);
    }

    #[test]
    fn tails_cpu_time_and_oracle_ratio() {
        let mut records = Vec::new();
        for (frame, ms) in [4.0, 5.0, 6.0, 50.0, 5.5].into_iter().enumerate() {
            records.push(record("brute", frame, 10.0 * ms, 0));
            records.push(record("frustum", frame, ms, 0));
            records.push(record("oracle", frame, 2.0 + 0.1 * frame as f64, 0));
        }
        let s = summarise(&records);
        let frustum = &s[1];
        assert_eq!(frustum.frame_ms_median, 5.5);
        assert_eq!(frustum.frame_ms_p95, 50.0);
        assert_eq!(frustum.frame_ms_p99, 50.0);
        assert_eq!(frustum.frame_ms_max, 50.0);
        // `record` gives every frame a tenth of its frame time as CPU time.
        assert_eq!(frustum.cpu_ms_median, 0.55);
        assert_eq!(frustum.cpu_ms_max, 5.0);
        assert_eq!(frustum.cpu_ms_p99, 5.0);
        let oracle = &s[2];
        assert_eq!(oracle.mode, "oracle");
        assert_eq!(oracle.frame_ms_median, 2.2);
        assert_eq!(oracle.oracle_ratio, Some(1.0));
        assert_eq!(frustum.oracle_ratio, Some(5.5 / 2.2));
        assert_eq!(s[0].oracle_ratio, Some(55.0 / 2.2));

        // Without an oracle run there is no ratio, in the JSON too (null, not absent).
        let no_oracle: Vec<FrameRecord> = records
            .iter()
            .filter(|r| r.mode != "oracle")
            .cloned()
            .collect();
        let s = summarise(&no_oracle);
        assert!(s.iter().all(|e| e.oracle_ratio.is_none()));
        let json = serde_json::to_value(report_of(s)).unwrap();
        assert!(json["entries"][1]["oracle_ratio"].is_null());

        // An oracle of another path does not count.
        let mut other_path = records.clone();
        for r in other_path.iter_mut().filter(|r| r.mode == "oracle") {
            r.path = "flyover".into();
        }
        let s = summarise(&other_path);
        assert!(
            s.iter()
                .filter(|e| e.path == "street")
                .all(|e| e.oracle_ratio.is_none())
        );

        let md = summary_markdown(&report_of(summarise(&records)));
        assert!(md.contains("÷ oracle") && md.contains("`oracle`:"), "{md}");
        assert!(md.contains("| 2.50× |"), "{md}");
        assert!(md.contains("| 0.55 / 5.00 / 5.00 |"), "{md}");
        let csv = frames_csv(&records);
        let header: Vec<&str> = csv.lines().next().unwrap().split(',').collect();
        let cpu = header
            .iter()
            .position(|h| *h == "cpu_ms")
            .expect("cpu_ms column");
        let row: Vec<&str> = csv.lines().nth(5).unwrap().split(',').collect();
        assert_eq!(row[2], "frustum");
        assert_eq!(row[cpu], "0.5000");
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
        use citywalk_runtime::gpu_timer::{GpuSpan, GpuTimes, PhaseTime};
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
