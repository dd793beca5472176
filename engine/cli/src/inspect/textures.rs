//! `citywalk inspect textures PACKAGE -o DIR [--json]`: the package's baked cluster textures
//! (Chang et al. 2008 §7), one PNG per page and view written to `DIR` as they are stored
//! (`page003_side.png`, `page003_top.png`, ...), and a table of the bins: clusters, cell
//! size, pages and compressed bytes.

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
    first_page: u32,
    pages: u32,
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
    for (page, pngs) in textures.images.iter().enumerate() {
        for (view, png) in AtlasView::ALL.iter().zip(pngs) {
            let path = args
                .output
                .join(format!("page{page:03}_{}.png", view.name()));
            std::fs::write(&path, png)
                .with_context(|| format!("cannot write {}", path.display()))?;
        }
    }
    let layout = &textures.layout;
    let rows: Vec<BinRow> = layout
        .bins
        .iter()
        .enumerate()
        .map(|(bin, cells)| {
            // `check` (on opening) has bounded the bins' pages by the images.
            let first = cells.first_page as usize;
            let pages = first..first + cells.page_count as usize;
            BinRow {
                bin,
                clusters: layout
                    .clusters
                    .iter()
                    .filter(|p| p.bin as usize == bin)
                    .count(),
                cell_px: cells.cell_px,
                first_page: cells.first_page,
                pages: cells.page_count,
                compressed_bytes: textures.images[pages]
                    .iter()
                    .flatten()
                    .map(|p| p.len() as u64)
                    .sum(),
            }
        })
        .collect();
    if args.json {
        println!("{}", serde_json::to_string_pretty(&rows)?);
        return Ok(());
    }
    println!(
        "{} textured clusters in {} bins on {} pages of {px}×{px} texels: {} PNGs in {}",
        layout.clusters.len(),
        rows.len(),
        layout.page_count,
        layout.page_count as usize * AtlasView::ALL.len(),
        args.output.display(),
        px = layout.page_px,
    );
    println!("bin  clusters  cell px  pages   compressed");
    for r in &rows {
        println!(
            "{:>3}  {:>8}  {:>7}  {:>5}  {:>8.1} KiB",
            r.bin,
            r.clusters,
            r.cell_px,
            r.pages,
            r.compressed_bytes as f64 / 1024.0
        );
    }
    Ok(())
}
