//! A package's baked cluster textures: the atlas layout and, per page and view, the texture
//! compressed as a PNG (8-bit sRGB RGB). The baked images are areas of flat colour (one per
//! building face, and the ground between buildings), which deflate to a few percent of their
//! texels; PNG keeps them exact and every GPU-less tool can read them.

use std::io::Cursor;

use image::codecs::png::{CompressionType, FilterType, PngEncoder};
use image::{ExtendedColorType, ImageEncoder, ImageFormat, ImageReader, Limits};
use rayon::prelude::*;
use serde::{Deserialize, Serialize};

use super::atlas::{AtlasLayout, AtlasView, MAX_PAGE_PX};
use crate::cluster_tree::ClusterTree;

/// The cluster textures of a package.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterTextures {
    pub layout: AtlasLayout,
    /// Per page, its six views in [`AtlasView::ALL`]'s order, each a PNG of the layout's
    /// `page_px` on a side.
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
    /// Compresses baked textures: `rgba[page][view]` is the page's view, RGBA8 (alpha
    /// dropped), `page_px` on a side.
    #[cfg(test)]
    fn compress(layout: AtlasLayout, rgba: &[Vec<Vec<u8>>]) -> Result<Self, String> {
        if rgba.len() != layout.page_count as usize {
            return Err(format!(
                "{} pages of pixels for {} pages",
                rgba.len(),
                layout.page_count
            ));
        }
        let images = rgba
            .iter()
            .enumerate()
            .map(|(page, views)| compress_page(layout.page_px, page, views))
            .collect::<Result<Vec<_>, _>>()?;
        Ok(ClusterTextures { layout, images })
    }

    /// The textures of `layout` from pages compressed one at a time ([`compress_page`]), so
    /// that a bake holds one page of texels, not all.
    pub fn from_compressed(layout: AtlasLayout, images: Vec<Vec<Vec<u8>>>) -> Result<Self, String> {
        if images.len() != layout.page_count as usize {
            return Err(format!(
                "{} compressed pages for {} pages",
                images.len(),
                layout.page_count
            ));
        }
        Ok(ClusterTextures { layout, images })
    }

    /// Decodes `view` of page `page`. A PNG that is not a page's size is an error, found from
    /// its header before anything is allocated.
    pub fn decode(&self, page: usize, view: AtlasView) -> Result<TextureImage, String> {
        let png = self
            .images
            .get(page)
            .and_then(|views| views.get(view.index()))
            .ok_or_else(|| format!("page {page} has no {} view", view.name()))?;
        decode_png(self.layout.page_px, png)
            .map_err(|e| format!("page {page}, {} view: {e}", view.name()))
    }

    /// Compressed bytes of all textures.
    pub fn compressed_bytes(&self) -> u64 {
        self.images.iter().flatten().map(|p| p.len() as u64).sum()
    }

    /// Texels of all textures (six views per page).
    pub fn texels(&self) -> u64 {
        u64::from(self.layout.page_px).pow(2) * 6 * u64::from(self.layout.page_count)
    }

    /// Checks the layout against the tree (each placement an inner node, on a page of its bin,
    /// in a cell of it, no cell taken twice, its walls' rectangles inside its cell, its box
    /// finite and ordered; where the tree holds its meshes, a package decoded whole, every
    /// wall of the mesh laid out) and the images against the layout (six per page, each PNG's
    /// header a page's size). A package is untrusted input: every number read is bounded
    /// before it is used.
    pub fn check(&self, tree: &ClusterTree) -> Result<(), String> {
        let layout = &self.layout;
        if !(1..=MAX_PAGE_PX).contains(&layout.page_px) {
            return Err(format!(
                "pages of {} texels on a side, not 1 to {MAX_PAGE_PX}",
                layout.page_px
            ));
        }
        if self.images.len() != layout.page_count as usize {
            return Err(format!(
                "{} pages of textures for {} pages",
                self.images.len(),
                layout.page_count
            ));
        }
        let mut next_page = 0u32;
        for (b, bin) in layout.bins.iter().enumerate() {
            let fits = bin.cell_px.checked_mul(bin.per_row.max(1));
            if bin.first_page != next_page || fits.is_none_or(|w| w > layout.page_px) {
                return Err(format!("bin {b}: its pages or cells are out of place"));
            }
            next_page = next_page.saturating_add(bin.page_count);
        }
        if next_page != layout.page_count {
            return Err(format!(
                "the bins take {next_page} pages of {}",
                layout.page_count
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
            let bin = layout
                .bins
                .get(p.bin as usize)
                .ok_or_else(|| format!("node {}: no bin {}", p.node, p.bin))?;
            // The loop above bounded every bin's pages by `page_count`: no overflow.
            let on_its_pages = (bin.first_page..bin.first_page + bin.page_count).contains(&p.page);
            if !on_its_pages || p.cell >= bin.per_page() || !taken.insert((p.page, p.cell)) {
                return Err(format!(
                    "node {}: cell {} of page {}",
                    p.node, p.cell, p.page
                ));
            }
            if p.sides.side_px != bin.cell_px {
                return Err(format!("node {}: side layout not of its cell", p.node));
            }
            placement_in_bounds(p).map_err(|e| format!("node {}: {e}", p.node))?;
            let walls = node.mesh.positions.len() / 2;
            if !node.mesh.positions.is_empty() && p.sides.faces.len() != walls {
                return Err(format!(
                    "node {}: {} walls laid out, its mesh has {walls}",
                    p.node,
                    p.sides.faces.len()
                ));
            }
        }
        let side = layout.page_px;
        for (page, views) in self.images.iter().enumerate() {
            if views.len() != AtlasView::ALL.len() {
                return Err(format!("page {page}: {} views, not 6", views.len()));
            }
            for (view, png) in AtlasView::ALL.iter().zip(views) {
                let (w, h) =
                    png_size(png).map_err(|e| format!("page {page}, {} view: {e}", view.name()))?;
                if (w, h) != (side, side) {
                    return Err(format!(
                        "page {page}, {} view: {w}×{h}, a page is {side}×{side}",
                        view.name()
                    ));
                }
            }
        }
        Ok(())
    }
}

/// The parts of a placement that do not refer to others: its box finite and ordered, its
/// density positive, each wall's rectangle of at least a texel inside the cell with its border.
fn placement_in_bounds(p: &super::atlas::ClusterPlacement) -> Result<(), String> {
    let ordered = (0..3).all(|k| {
        let (lo, hi) = (p.box_lo_m[k], p.box_hi_m[k]);
        lo.is_finite() && hi.is_finite() && lo <= hi
    });
    if !ordered {
        return Err("its box is not finite and ordered".into());
    }
    if !(p.sides.texels_per_m.is_finite() && p.sides.texels_per_m > 0.0) {
        return Err("its walls' density is not a positive number".into());
    }
    let b = super::side_layout::BORDER_PX;
    let side = p.sides.side_px;
    for (i, r) in p.sides.faces.iter().enumerate() {
        let right = r
            .x_px
            .checked_add(r.width_px)
            .and_then(|x| x.checked_add(b));
        let bottom = r
            .y_px
            .checked_add(r.height_px)
            .and_then(|y| y.checked_add(b));
        let inside = r.width_px >= 1
            && r.height_px >= 1
            && r.x_px >= b
            && r.y_px >= b
            && right.is_some_and(|x| x <= side)
            && bottom.is_some_and(|y| y <= side);
        if !inside {
            return Err(format!("wall {i}'s rectangle lies outside its cell"));
        }
    }
    Ok(())
}

/// Compresses the six views of page `page`, each RGBA8 (alpha dropped) of `page_px` on a
/// side, on rayon's threads (`preprocess --threads`).
pub fn compress_page(page_px: u32, page: usize, views: &[Vec<u8>]) -> Result<Vec<Vec<u8>>, String> {
    if views.len() != AtlasView::ALL.len() {
        return Err(format!("page {page}: {} views, not 6", views.len()));
    }
    AtlasView::ALL
        .par_iter()
        .zip(views)
        .map(|(view, pixels)| {
            encode_png(page_px, pixels)
                .map_err(|e| format!("page {page}, {} view: {e}", view.name()))
        })
        .collect()
}

fn encode_png(side_px: u32, rgba: &[u8]) -> Result<Vec<u8>, String> {
    let (w, h) = (side_px, side_px);
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

fn decode_png(side_px: u32, png: &[u8]) -> Result<TextureImage, String> {
    if side_px > MAX_PAGE_PX {
        return Err(format!(
            "pages of {side_px} texels, more than {MAX_PAGE_PX}"
        ));
    }
    let (w, h) = (side_px, side_px);
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
            "{}×{}, a page is {w}×{h}",
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
        let n = (layout.page_px * layout.page_px) as usize;
        (0..layout.page_count)
            .map(|page| {
                (0..6)
                    .map(|view| {
                        (0..n)
                            .flat_map(|i| [(i % 251) as u8, page as u8, view as u8 * 40, 255])
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
        for (page, views) in rgba.iter().enumerate() {
            for (view, pixels) in AtlasView::ALL.iter().zip(views) {
                let image = textures.decode(page, *view).unwrap();
                assert_eq!(&image.rgba, pixels, "page {page} {}", view.name());
            }
        }
        assert!(textures.compressed_bytes() > 0);
        assert!(
            textures
                .decode(layout.page_count as usize, AtlasView::Side)
                .is_err()
        );
    }

    #[test]
    fn a_texture_of_the_wrong_size_is_refused_before_it_is_decoded() {
        let layout = layout();
        let mut textures = ClusterTextures::compress(layout.clone(), &pixels(&layout)).unwrap();
        // A page of another size in page 0's place: its header says so.
        let mut other = layout.clone();
        other.page_px = 16;
        let small = ClusterTextures::compress(other.clone(), &pixels(&other)).unwrap();
        textures.images[0][0] = small.images[0][0].clone();
        let err = textures.decode(0, AtlasView::Side).unwrap_err();
        assert!(err.contains("page 0, side view"), "{err}");
        // Damaged bytes are an error, not a panic.
        textures.images[0][1].truncate(40);
        assert!(textures.decode(0, AtlasView::ALL[1]).is_err());
    }

    #[test]
    fn pixels_not_of_the_page_are_refused() {
        let layout = layout();
        let mut rgba = pixels(&layout);
        rgba[0][2].pop();
        let err = ClusterTextures::compress(layout, &rgba).unwrap_err();
        assert!(err.contains("page 0, north view"), "{err}");
    }
}
