//! `citywalk inspect textures PACKAGE -o DIR [--json]`: the package's baked cluster textures
//! (Chang et al. 2008 §7), one PNG per bin and view written to `DIR` as they are stored
//! (`bin03_side.png`, `bin03_top.png`, ...), and a table of the bins: clusters, cell size,
//! texture size and compressed bytes.

use std::path::PathBuf;

use anyhow::Context;
use citywalk_scenes::cluster_texture::atlas::AtlasView;
use citywalk_scenes::package::{Decode, ScenePackage};
use serde::Serialize;

/// Arguments of this inspection.
#[derive(Debug, clap::Args)]
pub struct Args {
    /// A scene package (.cwk) made with `preprocess --cluster-textures`.
    package: PathBuf,
    /// The folder to write the textures to (created if missing).
    #[arg(short, long)]
    output: PathBuf,
    /// Print the table as JSON on stdout.
    #[arg(long)]
    json: bool,
}

#[derive(Debug, Serialize)]
struct BinRow {
    bin: usize,
    clusters: usize,
    cell_px: u32,
    width_px: u32,
    height_px: u32,
    compressed_bytes: u64,
}

pub fn run(args: Args) -> anyhow::Result<()> {
    let package = ScenePackage::read_as(&args.package, Decode::Runtime)
        .with_context(|| format!("cannot open {}", args.package.display()))?;
    let textures = package.cluster_textures.with_context(|| {
        format!(
            "{} has no cluster textures (preprocess it with --cluster-textures)",
            args.package.display()
        )
    })?;
    std::fs::create_dir_all(&args.output)
        .with_context(|| format!("cannot create {}", args.output.display()))?;
    let mut rows = Vec::new();
    for (bin, (grid, pngs)) in textures
        .layout
        .bins
        .iter()
        .zip(&textures.images)
        .enumerate()
    {
        for (view, png) in AtlasView::ALL.iter().zip(pngs) {
            let path = args.output.join(format!("bin{bin:02}_{}.png", view.name()));
            std::fs::write(&path, png)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
        rows.push(BinRow {
            bin,
            clusters: textures
                .layout
                .clusters
                .iter()
                .filter(|p| p.bin as usize == bin)
                .count(),
            cell_px: grid.cell_px,
            width_px: grid.width_px(),
            height_px: grid.height_px(),
            compressed_bytes: pngs.iter().map(|p| p.len() as u64).sum(),
        });
    }
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    println!(
        "{} textured clusters in {} bins ({} texels per bin and view): {} PNGs in {}",
        textures.layout.clusters.len(),
        rows.len(),
        textures.layout.bin_side_px,
        rows.len() * AtlasView::ALL.len(),
        args.output.display()
    );
    println!("bin  clusters  cell px  texture px   compressed");
    for r in &rows {
        println!(
            "{:>3}  {:>8}  {:>7}  {:>10}  {:>8.1} KiB",
            r.bin,
            r.clusters,
            r.cell_px,
            format!("{}×{}", r.width_px, r.height_px),
            r.compressed_bytes as f64 / 1024.0
        );
    }
    Ok(())
}
