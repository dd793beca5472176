//! A package's baked cluster textures: the atlas layout and, per bin and view, the texture
//! compressed as a PNG (8-bit sRGB RGB). The baked images are areas of flat colour (one per
//! building face, and the ground between buildings), which deflate to a few percent of their
//! texels; PNG keeps them exact and every GPU-less tool can read them.

use std::io::Cursor;

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder, ImageFormat, ImageReader, Limits};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::atlas::{AtlasLayout, AtlasView, BinGrid};
use crate::cluster_tree::ClusterTree;

/// The cluster textures of a package.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterTextures {
    pub layout: AtlasLayout,
    /// Per bin, its six textures in [`AtlasView::ALL`]'s order, each a PNG as wide and high
    /// as the bin's grid.
    pub images: Vec<Vec<Vec<u8>>>,
}

/// One texture, decoded: RGBA8 (sRGB), rows top to bottom, alpha 255.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct TextureImage {
    pub width: u32,
    pub height: u32,
    pub rgba: Vec<u8>,
}

impl ClusterTextures {
    /// Compresses baked textures: `rgba[bin][view]` is the bin's texture of that view, RGBA8
    /// (alpha dropped), as large as the bin's grid.
    pub fn compress(layout: AtlasLayout, rgba: &[Vec<Vec<u8>>]) -> Result<Self, String> {
        if rgba.len() != layout.bins.len() {
            return Err(format!(
                "{} bins of pixels for {} bins",
                rgba.len(),
                layout.bins.len()
            ));
        }
        for (bin, views) in rgba.iter().enumerate() {
            if views.len() != AtlasView::ALL.len() {
                return Err(format!("bin {bin}: {} views, not 6", views.len()));
            }
        }
        // Every texture on its own thread (rayon's pool: `preprocess --threads`).
        let images = layout
            .bins
            .par_iter()
            .zip(rgba)
            .enumerate()
            .map(|(bin, (grid, views))| {
                AtlasView::ALL
                    .par_iter()
                    .zip(views)
                    .map(|(view, pixels)| {
                        encode_png(grid, pixels)
                            .map_err(|e| format!("bin {bin}, {} view: {e}", view.name()))
                    })
                    .collect::<Result<Vec<_>, _>>()
            })
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ClusterTextures { layout, images })
    }

    /// Decodes the texture of `view` in `bin`. A PNG that is not as large as the bin's grid is
    /// an error, found from its header before anything is allocated.
    pub fn decode(&self, bin: usize, view: AtlasView) -> Result<TextureImage, String> {
        let grid = self
            .layout
            .bins
            .get(bin)
            .ok_or_else(|| format!("no bin {bin}"))?;
        let png = self
            .images
            .get(bin)
            .and_then(|views| views.get(view.index()))
            .ok_or_else(|| format!("bin {bin} has no {} texture", view.name()))?;
        decode_png(grid, png).map_err(|e| format!("bin {bin}, {} texture: {e}", view.name()))
    }

    /// Compressed bytes of all textures.
    pub fn compressed_bytes(&self) -> u64 {
        self.images.iter().flatten().map(|p| p.len() as u64).sum()
    }

    /// Texels of all textures (six per bin).
    pub fn texels(&self) -> u64 {
        self.layout
            .bins
            .iter()
            .map(|g| u64::from(g.width_px()) * u64::from(g.height_px()) * 6)
            .sum()
    }

    /// Checks the layout against the tree (each placement an inner node with a mesh, its bin
    /// and cell in range, no cell taken twice, every wall of the mesh laid out) and the images
    /// against the layout (six per bin, each PNG's header as large as its bin's grid).
    pub fn check(&self, tree: &ClusterTree) -> Result<(), String> {
        let layout = &self.layout;
        if self.images.len() != layout.bins.len() {
            return Err(format!(
                "{} bins of textures for {} bins",
                self.images.len(),
                layout.bins.len()
            ));
        }
        let mut taken = std::collections::HashSet::new();
        for (i, p) in layout.clusters.iter().enumerate() {
            if i > 0 && layout.clusters[i - 1].node >= p.node {
                return Err(format!("placements not sorted by node at node {}", p.node));
            }
            let node = tree
                .nodes
                .get(p.node as usize)
                .ok_or_else(|| format!("placement of node {}, which the tree lacks", p.node))?;
            if node.is_leaf() {
                return Err(format!("node {} is a leaf, drawn untextured", p.node));
            }
            let grid = layout
                .bins
                .get(p.bin as usize)
                .ok_or_else(|| format!("node {}: no bin {}", p.node, p.bin))?;
            if p.cell >= grid.columns.saturating_mul(grid.rows) || !taken.insert((p.bin, p.cell)) {
                return Err(format!("node {}: cell {} of bin {}", p.node, p.cell, p.bin));
            }
            if p.sides.side_px != grid.cell_px {
                return Err(format!("node {}: side layout not of its cell", p.node));
            }
            let walls = node.mesh.positions.len() / 2;
            if !node.mesh.positions.is_empty() && p.sides.faces.len() != walls {
                return Err(format!(
                    "node {}: {} walls laid out, its mesh has {walls}",
                    p.node,
                    p.sides.faces.len()
                ));
            }
        }
        for (bin, (grid, views)) in layout.bins.iter().zip(&self.images).enumerate() {
            if views.len() != AtlasView::ALL.len() {
                return Err(format!("bin {bin}: {} textures, not 6", views.len()));
            }
            for (view, png) in AtlasView::ALL.iter().zip(views) {
                let (w, h) = png_size(png)
                    .map_err(|e| format!("bin {bin}, {} texture: {e}", view.name()))?;
                if (w, h) != (grid.width_px(), grid.height_px()) {
                    return Err(format!(
                        "bin {bin}, {} texture: {w}×{h}, its grid is {}×{}",
                        view.name(),
                        grid.width_px(),
                        grid.height_px()
                    ));
                }
            }
        }
        Ok(())
    }
}

fn encode_png(grid: &BinGrid, rgba: &[u8]) -> Result<Vec<u8>, String> {
    let (w, h) = (grid.width_px(), grid.height_px());
    if rgba.len() as u64 != u64::from(w) * u64::from(h) * 4 {
        return Err(format!("{} bytes for {w}×{h} RGBA texels", rgba.len()));
    }
    let rgb: Vec<u8> = rgba
        .chunks_exact(4)
        .flat_map(|p| [p[0], p[1], p[2]])
        .collect();
    let mut png = Vec::new();
    PngEncoder::new_with_quality(&mut png, CompressionType::Default, FilterType::Adaptive)
        .write_image(&rgb, w, h, ExtendedColorType::Rgb8)
        .map_err(|e| e.to_string())?;
    Ok(png)
}

fn png_size(png: &[u8]) -> Result<(u32, u32), String> {
    ImageReader::with_format(Cursor::new(png), ImageFormat::Png)
        .into_dimensions()
        .map_err(|e| e.to_string())
}

fn decode_png(grid: &BinGrid, png: &[u8]) -> Result<TextureImage, String> {
    let (w, h) = (grid.width_px(), grid.height_px());
    let mut reader = ImageReader::with_format(Cursor::new(png), ImageFormat::Png);
    let mut limits = Limits::default();
    limits.max_image_width = Some(w);
    limits.max_image_height = Some(h);
    // The decoded image and the decoder's rows: never more than the texture it must be.
    limits.max_alloc = Some(u64::from(w) * u64::from(h) * 8 + (1 << 20));
    reader.limits(limits);
    let image = reader.decode().map_err(|e| e.to_string())?;
    if (image.width(), image.height()) != (w, h) {
        return Err(format!(
            "{}×{}, its grid is {w}×{h}",
            image.width(),
            image.height()
        ));
    }
    Ok(TextureImage {
        width: w,
        height: h,
        rgba: image.into_rgba8().into_raw(),
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::cluster_texture::atlas::{ClusterWalls, layout_atlas};

    fn layout() -> AtlasLayout {
        let walls: Vec<ClusterWalls> = (0..3)
            .map(|i| ClusterWalls {
                node: i,
                negative_space_m2: f64::from(i),
                ring: vec![[0.0, 0.0], [10.0, 0.0], [10.0, 10.0], [0.0, 10.0]],
                base_m: 0.0,
                top_m: 10.0,
            })
            .collect();
        layout_atlas(&walls, 32)
    }

    fn pixels(layout: &AtlasLayout) -> Vec<Vec<Vec<u8>>> {
        layout
            .bins
            .iter()
            .enumerate()
            .map(|(bin, g)| {
                (0..6)
                    .map(|view| {
                        let n = (g.width_px() * g.height_px()) as usize;
                        (0..n)
                            .flat_map(|i| [(i % 251) as u8, bin as u8, view as u8 * 40, 255])
                            .collect()
                    })
                    .collect()
            })
            .collect()
    }

    #[test]
    fn textures_come_back_exactly() {
        let layout = layout();
        let rgba = pixels(&layout);
        let textures = ClusterTextures::compress(layout.clone(), &rgba).unwrap();
        for (bin, views) in rgba.iter().enumerate() {
            for (view, pixels) in AtlasView::ALL.iter().zip(views) {
                let image = textures.decode(bin, *view).unwrap();
                assert_eq!(&image.rgba, pixels, "bin {bin} {}", view.name());
            }
        }
        assert!(textures.compressed_bytes() > 0);
        assert!(textures.decode(layout.bins.len(), AtlasView::Side).is_err());
    }

    #[test]
    fn a_texture_of_the_wrong_size_is_refused_before_it_is_decoded() {
        let layout = layout();
        let mut textures = ClusterTextures::compress(layout.clone(), &pixels(&layout)).unwrap();
        // Bin 1's textures put in bin 0's place: their headers name another size.
        let other = textures.images[1][0].clone();
        textures.images[0][0] = other;
        let err = textures.decode(0, AtlasView::Side).unwrap_err();
        assert!(err.contains("bin 0, side texture"), "{err}");
        // Damaged bytes are an error, not a panic.
        textures.images[0][1].truncate(40);
        assert!(textures.decode(0, AtlasView::ALL[1]).is_err());
    }

    #[test]
    fn pixels_not_of_the_grid_are_refused() {
        let layout = layout();
        let mut rgba = pixels(&layout);
        rgba[0][2].pop();
        let err = ClusterTextures::compress(layout, &rgba).unwrap_err();
        assert!(err.contains("bin 0, north view"), "{err}");
    }
}
