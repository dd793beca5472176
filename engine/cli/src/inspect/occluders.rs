//! `citywalk inspect occluders SCENE [--json] [--views N] [--per-building] [--gltf out.glb]`:
//! builds the virtual occluders of an input (Germs & Jansen) and reports polygon counts
//! (planar faces, as the paper's Table 1 counts them) and triangle counts before and after,
//! the reductions, average polygon area gain and the occlusion-preserving quality of §4.1
//! (per building and in total: mean, min, p5/p25/p50, histogram), plus throughput and the
//! walls the buildings' outlines alone need (single level, per building and merged into
//! blocks). `--sloped-roof-step`, `--benefit-threshold`, `--merge-dz`, `--min-gain` and
//! `--select-walls` override the level parameters, so the quality / polygon trade-off can be
//! swept. `--gltf` writes the occluders
//! as a GLB for inspection in any glTF viewer.

use std::path::PathBuf;
use std::time::Instant;

use anyhow::Context;
use citywalk_preprocess::occluders::gltf_out::occluders_to_glb;
use citywalk_preprocess::occluders::quality::{
    BuildingQuality, OutlineWalls, QualityParams, QualitySummary, measure_city, outline_walls,
    summarise,
};
use citywalk_preprocess::occluders::{OccluderParams, build_occluders};
use citywalk_scenes::occluder::FacadeKind;
use serde::Serialize;

/// Arguments of this inspection.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A scene package (.cwk) or any input citywalk loads (OSM PBF, GeoJSON, CityJSON, glTF/GLB,
    /// OBJ).
    scene: PathBuf,
    #[command(flatten)]
    input: crate::input_args::InputArgs,
    /// Print the report as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Viewpoints on the circle for the quality measure (§4.1).
    #[arg(long, default_value_t = 16)]
    views: u32,
    /// Width and height of each quality image (pixels).
    #[arg(long, default_value_t = 128)]
    resolution: u32,
    /// Print one line per building.
    #[arg(long)]
    per_building: bool,
    /// Facade type: open, closed or wall-oriented.
    #[arg(long, default_value = "wall-oriented")]
    facade: String,
    /// Write the occluders to this GLB file.
    #[arg(long)]
    gltf: Option<PathBuf>,
    /// Sample sloped roofs every this many metres (0 = off, the paper's plain clustering).
    #[arg(long)]
    sloped_roof_step: Option<f64>,
    /// T_B of §3.2 (a huge value keeps only the lowest level of each building).
    #[arg(long)]
    benefit_threshold: Option<f64>,
    /// ΔZ of §3.2 in metres.
    #[arg(long)]
    merge_dz: Option<f64>,
    /// Level selection by silhouette gain: minimum share of the building's silhouette a level
    /// must add per polygon (0 = the paper's benefit rule alone).
    #[arg(long)]
    min_gain: Option<f64>,
    /// Choose single walls by silhouette gain instead of whole levels (beyond the paper; the
    /// facades no longer close their footprints).
    #[arg(long)]
    select_walls: bool,
}

#[derive(Debug, Serialize)]
struct Report<'a> {
    scene: String,
    facade: &'static str,
    parameters: &'a OccluderParams,
    quality_parameters: QualityParams,
    build_seconds: f64,
    buildings_per_second: f64,
    summary: QualitySummary,
    outline_walls: OutlineWalls,
    #[serde(skip_serializing_if = "Option::is_none")]
    per_building: Option<&'a [BuildingQuality]>,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let facade = FacadeKind::from_name(&args.facade).with_context(|| {
        format!(
            "unknown facade `{}` (open, closed, wall-oriented)",
            args.facade
        )
    })?;
    let load = args.input.load_options(std::slice::from_ref(&args.scene))?;
    let city = crate::scene_input::load_city(&args.scene, &load)?;
    let defaults = OccluderParams::default();
    let non_negative = |name: &str, v: Option<f64>, default: f64| match v {
        None => Ok(default),
        Some(v) if v.is_finite() && v >= 0.0 => Ok(v),
        Some(v) => Err(anyhow::anyhow!("--{name} must be finite and ≥ 0, got {v}")),
    };
    let params = OccluderParams {
        facade,
        sloped_roof_step_m: non_negative(
            "sloped-roof-step",
            args.sloped_roof_step,
            defaults.sloped_roof_step_m,
        )?,
        benefit_threshold: non_negative(
            "benefit-threshold",
            args.benefit_threshold,
            defaults.benefit_threshold,
        )?,
        merge_delta_z_m: non_negative("merge-dz", args.merge_dz, defaults.merge_delta_z_m)?,
        min_silhouette_gain_per_polygon: non_negative(
            "min-gain",
            args.min_gain,
            defaults.min_silhouette_gain_per_polygon,
        )?,
        select_walls: args.select_walls,
        ..defaults
    };
    let start = Instant::now();
    let set = build_occluders(&city, &params);
    let build_seconds = start.elapsed().as_secs_f64();
    if let Err(e) = set.check_invariants() {
        anyhow::bail!("occluder invariants violated: {e}");
    }
    let quality_params = QualityParams {
        views: args.views.max(1),
        resolution_px: args.resolution.clamp(8, 1024),
        ..QualityParams::default()
    };
    let rows = measure_city(&city, &set, &quality_params);
    let summary = summarise(&rows);
    let outline = outline_walls(&city, &params);
    if let Some(path) = &args.gltf {
        let bytes = occluders_to_glb(&set)?;
        std::fs::write(path, bytes).with_context(|| format!("cannot write {}", path.display()))?;
    }
    let report = Report {
        scene: args.scene.display().to_string(),
        facade: facade.name(),
        parameters: &params,
        quality_parameters: quality_params,
        build_seconds,
        buildings_per_second: city.buildings.len() as f64 / build_seconds.max(1e-9),
        summary,
        outline_walls: outline,
        per_building: args.per_building.then_some(&rows[..]),
    };
    if args.json {
        println!("{}", serde_json::to_string_pretty(&report)?);
    } else {
        print_text(&report, &rows, args.per_building);
        if let Some(path) = &args.gltf {
            println!("wrote {}", path.display());
        }
    }
    Ok(())
}

/// Buildings without occluders listed in the plain-text report before `--per-building` is asked.
const WITHOUT_OCCLUDERS_LISTED: usize = 20;

/// Every building left without an occluder, by source id with its reason (the first
/// [`WITHOUT_OCCLUDERS_LISTED`], then a count): nothing is dropped without saying why.
fn print_without_occluders(rows: &[BuildingQuality]) {
    let without: Vec<&BuildingQuality> = rows.iter().filter(|r| r.occluders == 0).collect();
    for r in without.iter().take(WITHOUT_OCCLUDERS_LISTED) {
        println!(
            "  no occluder: {}: {}",
            r.source_id,
            r.reason_if_none.as_deref().unwrap_or("no reason recorded")
        );
    }
    if without.len() > WITHOUT_OCCLUDERS_LISTED {
        println!(
            "  ... and {} more without an occluder (--per-building lists them all)",
            without.len() - WITHOUT_OCCLUDERS_LISTED
        );
    }
}

fn print_text(report: &Report<'_>, rows: &[BuildingQuality], per_building: bool) {
    let s = &report.summary;
    if per_building {
        println!(
            "building  source_id  occluders  polygons(src→occ)  triangles(src→occ)  area_gain  quality  reason"
        );
        for r in rows {
            let gain = if r.source_mean_polygon_area_m2 > 0.0 {
                r.occluder_mean_polygon_area_m2 / r.source_mean_polygon_area_m2
            } else {
                0.0
            };
            println!(
                "{:>6}  {}  {}  {}→{}  {}→{}  {:.2}×  {}  {}",
                r.building,
                r.source_id,
                r.occluders,
                r.source_polygons,
                r.occluder_polygons,
                r.source_triangles,
                r.occluder_triangles,
                gain,
                r.quality
                    .map_or_else(|| "-".to_owned(), |q| format!("{:.1} %", q * 100.0)),
                r.reason_if_none.as_deref().unwrap_or("")
            );
        }
        println!();
    }
    println!("scene: {} ({} facades)", report.scene, report.facade);
    println!(
        "buildings: {} ({} with occluders), occluders: {}",
        s.buildings, s.buildings_with_occluders, s.occluders
    );
    if !per_building {
        print_without_occluders(rows);
    }
    println!(
        "polygons (planar faces): {} → {} ({:.2}× fewer), mean polygon area gain {:.2}×",
        s.source_polygons, s.occluder_polygons, s.polygon_reduction, s.mean_polygon_area_gain
    );
    println!(
        "triangles: {} → {} ({:.2}× fewer)",
        s.source_triangles, s.occluder_triangles, s.triangle_reduction
    );
    let o = &report.outline_walls;
    println!(
        "outline walls (one level): {} per building, {} merged into {} blocks",
        o.per_building, o.merged_blocks, o.blocks
    );
    println!(
        "quality: mean {:.1} %, min {:.1} %, p5 {:.1} %, p25 {:.1} %, p50 {:.1} % ({} views, {} px)",
        s.quality_mean * 100.0,
        s.quality_min * 100.0,
        s.quality_p5 * 100.0,
        s.quality_p25 * 100.0,
        s.quality_p50 * 100.0,
        report.quality_parameters.views,
        report.quality_parameters.resolution_px
    );
    println!("histogram (per 10 %):");
    let most = s
        .quality_histogram
        .iter()
        .copied()
        .max()
        .unwrap_or(0)
        .max(1);
    for (i, n) in s.quality_histogram.iter().enumerate() {
        let label = if i == 10 {
            " >100 %".to_owned()
        } else {
            format!("{:>3}–{:<3}%", i * 10, i * 10 + 10)
        };
        println!("  {label} {:>6} {}", n, "#".repeat(n * 50 / most));
    }
    println!(
        "leak (facade pixels outside the building): {:.4} %, in {} buildings",
        s.leak_fraction * 100.0,
        s.buildings_with_leaks
    );
    println!(
        "throughput: {:.0} buildings/s ({:.3} s)",
        report.buildings_per_second, report.build_seconds
    );
}
