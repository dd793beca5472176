//! `citywalk inspect SCENE [--json] [--check]`: what a scene package (or an input, preprocessed
//! on the fly) holds, and with `--check` every structure's invariant checker: city, blocks,
//! B-Quadtree, occluders and cluster tree. Exits non-zero on a violation.

use std::collections::BTreeMap;
use std::path::PathBuf;

use anyhow::Context;
use citywalk_scenes::GroundClass;
use citywalk_scenes::package::{PackageFile, ScenePackage, SectionKind};
use serde::Serialize;

use crate::report_items::{self, ReportItem};
use crate::scene_input::{is_package, load_scene};

/// Arguments of this inspection.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A scene package (.cwk) or any input citywalk loads.
    scene: Option<PathBuf>,
    /// Print the summary as JSON on stdout.
    #[arg(long)]
    json: bool,
    /// Run every structure's invariant checker; exit non-zero on a violation.
    #[arg(long)]
    check: bool,
    #[command(flatten)]
    input: crate::input_args::InputArgs,
}

#[derive(Debug, Serialize)]
struct SectionSummary {
    kind: &'static str,
    offset: u64,
    bytes: u64,
    crc32: String,
}

#[derive(Debug, Serialize)]
struct Summary {
    scene: String,
    is_package: bool,
    frame: String,
    tool_version: String,
    inputs: Vec<(String, u64, Option<String>)>,
    buildings_found: usize,
    buildings_loaded: usize,
    buildings_rejected: usize,
    rejections_by_reason: BTreeMap<String, usize>,
    /// Every rejected building: file, source id, reason.
    rejected: Vec<ReportItem>,
    load_warnings: usize,
    /// Every load warning: file, source id (empty for the file as a whole), message.
    load_warning_list: Vec<ReportItem>,
    buildings: usize,
    buildings_with_mesh: usize,
    streets: usize,
    streets_rejected: usize,
    ground_areas: usize,
    ground_areas_rejected: usize,
    /// Ground areas per class name ([`citywalk_scenes::GroundClass::name`]), every class listed.
    ground_areas_by_class: BTreeMap<&'static str, usize>,
    blocks: usize,
    blocks_with_street_outline: usize,
    buildings_per_block_min_median_max: Option<(usize, usize, usize)>,
    quadtree_nodes: usize,
    quadtree_leaves: usize,
    quadtree_depth: u32,
    occluders: Option<usize>,
    occluder_triangles: Option<usize>,
    cluster_tree_nodes: Option<usize>,
    cluster_tree_depth: Option<u32>,
    cluster_tree_vertices: Option<usize>,
    /// Footprint repairs and fallbacks of the cluster tree (`ClusterStats`): nothing is
    /// dropped, but a person should see what was repaired.
    cluster_tree_repairs: Option<ClusterRepairs>,
    /// The baked cluster textures (`preprocess --cluster-textures`), if any.
    cluster_textures: Option<TextureSummary>,
    counts: BTreeMap<String, u64>,
    parameters_json: String,
    warnings: Vec<String>,
    skipped_stages: Vec<String>,
    stage_seconds: Vec<(String, f64)>,
    sections: Vec<SectionSummary>,
    check: Option<Vec<String>>,
}

/// A package's baked cluster textures.
#[derive(Debug, Serialize)]
struct TextureSummary {
    clusters: usize,
    bins: usize,
    pages: u32,
    page_px: u32,
    compressed_bytes: u64,
}

/// What the cluster tree repaired or fell back on ([`citywalk_scenes::cluster_tree::ClusterStats`]).
#[derive(Debug, Serialize)]
struct ClusterRepairs {
    degenerate_buildings: usize,
    multi_part_buildings: u32,
    merge_fallbacks: u32,
    simplify_fallbacks: u32,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let path = args
        .scene
        .context("give a scene: `citywalk inspect SCENE [--json] [--check]`")?;
    let load = args.input.load_options(std::slice::from_ref(&path))?;
    let package_file = is_package(&path)?;
    let sections = if package_file {
        let file = PackageFile::open(&path)
            .with_context(|| format!("cannot read the scene package {}", path.display()))?;
        file.sections()
            .iter()
            .map(|e| SectionSummary {
                kind: SectionKind::from_u32(e.kind).map_or("?", SectionKind::name),
                offset: e.offset,
                bytes: e.length,
                crc32: format!("{:08x}", e.crc32),
            })
            .collect()
    } else {
        Vec::new()
    };
    let pkg = load_scene(&path, &load)?;
    let check = args.check.then(|| match pkg.check_invariants() {
        Ok(()) => Vec::new(),
        Err(errors) => errors,
    });
    let summary = summarise(&pkg, &path, package_file, sections, check);
    if args.json {
        println!("{}", serde_json::to_string_pretty(&summary)?);
    } else {
        print_summary(&summary);
    }
    if let Some(errors) = &summary.check
        && !errors.is_empty()
    {
        anyhow::bail!(
            "{} invariant violation(s) in {}",
            errors.len(),
            path.display()
        );
    }
    Ok(())
}

fn summarise(
    pkg: &ScenePackage,
    path: &std::path::Path,
    is_package: bool,
    sections: Vec<SectionSummary>,
    check: Option<Vec<String>>,
) -> Summary {
    let report = &pkg.provenance.load_report;
    let mut rejections_by_reason = BTreeMap::new();
    for r in &report.rejected {
        *rejections_by_reason
            .entry(r.reason.to_string())
            .or_insert(0) += 1;
    }
    let (rejected, load_warning_list) = report_items::items(report);
    let mut ground_areas_by_class: BTreeMap<&'static str, usize> =
        GroundClass::ALL.iter().map(|c| (c.name(), 0)).collect();
    for g in &pkg.ground_areas {
        *ground_areas_by_class.entry(g.class.name()).or_insert(0) += 1;
    }
    Summary {
        scene: path.display().to_string(),
        is_package,
        frame: format!("{:?} origin {:?}", pkg.frame.crs, pkg.frame.origin),
        tool_version: pkg.provenance.tool_version.clone(),
        inputs: pkg
            .provenance
            .inputs
            .iter()
            .map(|i| (i.path.clone(), i.size_bytes, i.sha256.clone()))
            .collect(),
        buildings_found: report.buildings_found,
        buildings_loaded: report.buildings_loaded,
        buildings_rejected: report.rejected.len(),
        rejections_by_reason,
        rejected,
        load_warnings: report.warnings.len(),
        load_warning_list,
        buildings: pkg.buildings.len(),
        buildings_with_mesh: pkg.buildings.iter().filter(|b| b.mesh.is_some()).count(),
        streets: pkg.streets.len(),
        streets_rejected: report.streets_rejected.len(),
        ground_areas: pkg.ground_areas.len(),
        ground_areas_rejected: report.ground_areas_rejected.len(),
        ground_areas_by_class,
        blocks: pkg.blocks.blocks.len(),
        blocks_with_street_outline: pkg
            .blocks
            .blocks
            .iter()
            .filter(|b| b.outline.is_some())
            .count(),
        buildings_per_block_min_median_max: pkg.blocks.size_stats(),
        quadtree_nodes: pkg.quadtree.nodes.len(),
        quadtree_leaves: pkg.quadtree.leaf_count(),
        quadtree_depth: pkg.quadtree.max_depth(),
        occluders: pkg.occluders.as_ref().map(|o| o.occluders.len()),
        occluder_triangles: pkg.occluders.as_ref().map(|o| o.triangle_count()),
        cluster_tree_nodes: pkg.cluster_tree.as_ref().map(|t| t.nodes.len()),
        cluster_tree_depth: pkg.cluster_tree.as_ref().map(|t| t.max_depth()),
        cluster_tree_vertices: pkg.cluster_tree.as_ref().map(|t| t.vertices.len()),
        cluster_tree_repairs: pkg.cluster_tree.as_ref().map(|t| ClusterRepairs {
            degenerate_buildings: t.stats.degenerate_buildings.len(),
            multi_part_buildings: t.stats.multi_part_buildings,
            merge_fallbacks: t.stats.merge_fallbacks,
            simplify_fallbacks: t.stats.simplify_fallbacks,
        }),
        cluster_textures: pkg.cluster_textures.as_ref().map(|t| TextureSummary {
            clusters: t.layout.clusters.len(),
            bins: t.layout.bins.len(),
            pages: t.layout.page_count,
            page_px: t.layout.page_px,
            compressed_bytes: t.compressed_bytes(),
        }),
        counts: pkg.provenance.counts.clone(),
        parameters_json: pkg.provenance.parameters_json.clone(),
        warnings: pkg.provenance.warnings.clone(),
        skipped_stages: pkg.provenance.skipped_stages.clone(),
        stage_seconds: pkg
            .timings
            .iter()
            .map(|t| (t.stage.clone(), t.seconds))
            .collect(),
        sections,
        check,
    }
}

fn print_summary(s: &Summary) {
    let opt = |v: Option<usize>| v.map_or("none".to_string(), |v| v.to_string());
    println!(
        "{} ({})",
        s.scene,
        if s.is_package {
            "scene package"
        } else {
            "input, preprocessed on the fly"
        }
    );
    println!("frame: {}; made by {}", s.frame, s.tool_version);
    for (path, size, hash) in &s.inputs {
        println!(
            "input: {path} ({size} bytes, sha256 {})",
            hash.as_deref().unwrap_or("unavailable")
        );
    }
    println!(
        "buildings: {} found, {} loaded, {} rejected, {} load warnings; {} with meshes; {} streets \
         ({} rejected)",
        s.buildings_found,
        s.buildings_loaded,
        s.buildings_rejected,
        s.load_warnings,
        s.buildings_with_mesh,
        s.streets,
        s.streets_rejected
    );
    for (reason, n) in &s.rejections_by_reason {
        println!("  rejected {n}: {reason}");
    }
    let by_class: Vec<String> = s
        .ground_areas_by_class
        .iter()
        .map(|(class, n)| format!("{n} {class}"))
        .collect();
    println!(
        "ground areas: {} ({} rejected): {}",
        s.ground_areas,
        s.ground_areas_rejected,
        by_class.join(", ")
    );
    report_items::print(&s.rejected, &s.load_warning_list);
    print!(
        "blocks: {} ({} street faces)",
        s.blocks, s.blocks_with_street_outline
    );
    match s.buildings_per_block_min_median_max {
        Some((lo, med, hi)) => println!("; buildings per block min {lo}, median {med}, max {hi}"),
        None => println!(),
    }
    println!(
        "quadtree: {} nodes, {} leaves, depth {}",
        s.quadtree_nodes, s.quadtree_leaves, s.quadtree_depth
    );
    println!(
        "occluders: {} ({} triangles)",
        opt(s.occluders),
        opt(s.occluder_triangles)
    );
    println!(
        "cluster tree: {} nodes, depth {}, {} shared vertices",
        opt(s.cluster_tree_nodes),
        s.cluster_tree_depth.map_or("-".into(), |d| d.to_string()),
        opt(s.cluster_tree_vertices)
    );
    if let Some(r) = &s.cluster_tree_repairs {
        println!(
            "cluster tree repairs: {} degenerate footprints (grown to a box), {} multi-part or \
             self-crossing footprints (their hull), {} merge fallbacks, {} simplification \
             fallbacks",
            r.degenerate_buildings, r.multi_part_buildings, r.merge_fallbacks, r.simplify_fallbacks
        );
    }
    if let Some(t) = &s.cluster_textures {
        println!(
            "cluster textures: {} clusters in {} bins on {} pages of {px}×{px} texels, {:.1} MiB",
            t.clusters,
            t.bins,
            t.pages,
            t.compressed_bytes as f64 / 1048576.0,
            px = t.page_px
        );
    }
    for sec in &s.sections {
        println!(
            "section {:<12} at {:>10}: {:>10} bytes, crc32 {}",
            sec.kind, sec.offset, sec.bytes, sec.crc32
        );
    }
    for w in &s.warnings {
        println!("warning: {w}");
    }
    for k in &s.skipped_stages {
        println!("skipped: {k}");
    }
    if let Some(check) = &s.check {
        if check.is_empty() {
            println!(
                "check: all invariants hold (city, blocks, quadtree, occluders, cluster tree, gpu scene)"
            );
        } else {
            for e in check {
                println!("check FAILED: {e}");
            }
        }
    }
}
