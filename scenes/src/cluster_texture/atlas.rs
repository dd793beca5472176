//! Where each textured cluster lies in the texture pages: the one layout the baker renders
//! into, the package stores and the runtime samples.
//!
//! Chang et al. 2008 §7: every bin has one texture budget per view (the side view and the five
//! roof views), shared equally by its clusters ([`super::bins`]). Here the textures are cut
//! into *pages* of `page_px²` texels (the bin budget's side, Chang's 1024 by default), the
//! unit the runtime uploads and evicts: each bin's clusters get square cells of the bin's size
//! in a grid on the bin's own pages, a cluster's cell at the same place in the page's six
//! views. A bin of fewer texels than a page takes one page; a bin of many clusters at the
//! least cell size ([`super::bins::MIN_CELL_PX`]) takes several. In its side cell a cluster's
//! walls lie as [`super::side_layout`] places them; in a roof cell the view's image of the
//! cluster's box fills the cell inside a border of [`side_layout::BORDER_PX`] texels, filled
//! from the image's edge, so that filtering never reads a neighbouring cell.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use super::bins::texture_bins;
use super::roof_views::RoofView;
use super::side_layout::{self, FaceRect, SideLayout, layout_sides};

/// The largest page side: the largest 2D texture every GPU must offer (WebGPU's
/// `maxTextureDimension2D` default).
pub const MAX_PAGE_PX: u32 = 8192;

/// The six views of every page.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
pub enum AtlasView {
    /// The walls, each face an orthographic view of the cluster's buildings.
    Side,
    /// One of the roof views.
    Roof(RoofView),
}

impl AtlasView {
    /// The six, in the order of a page's views.
    pub const ALL: [AtlasView; 6] = [
        AtlasView::Side,
        AtlasView::Roof(RoofView::Top),
        AtlasView::Roof(RoofView::North),
        AtlasView::Roof(RoofView::East),
        AtlasView::Roof(RoofView::South),
        AtlasView::Roof(RoofView::West),
    ];

    /// The position in [`Self::ALL`].
    pub fn index(self) -> usize {
        Self::ALL
            .iter()
            .position(|v| *v == self)
            .expect("ALL lists every view")
    }

    pub fn name(self) -> &'static str {
        match self {
            AtlasView::Side => "side",
            AtlasView::Roof(RoofView::Top) => "top",
            AtlasView::Roof(RoofView::North) => "north",
            AtlasView::Roof(RoofView::East) => "east",
            AtlasView::Roof(RoofView::South) => "south",
            AtlasView::Roof(RoofView::West) => "west",
        }
    }
}

// The runtime's tables index a page's views by this order (`TEXTURE_PAGE_VIEWS` per page).
const _: () =
    assert!(AtlasView::ALL.len() == citywalk_shaders::constants::TEXTURE_PAGE_VIEWS as usize);

/// What the atlas needs of one cluster mesh: its walls and its box.
#[derive(Debug, Clone, PartialEq)]
pub struct ClusterWalls {
    /// The cluster's tree node.
    pub node: u32,
    /// Chang's sort key: the negative-space area of the cluster (m²).
    pub negative_space_m2: f64,
    /// The hull ring the walls stand on, counter-clockwise, not closed: wall `i` runs from
    /// vertex `i` to vertex `i + 1` (the last back to the first).
    pub ring: Vec<[f32; 2]>,
    /// The walls' foot and the roof's height (metres).
    pub base_m: f32,
    pub top_m: f32,
}

impl ClusterWalls {
    /// The length of each wall, in ring order.
    pub fn wall_lengths_m(&self) -> Vec<f64> {
        let n = self.ring.len();
        (0..n)
            .map(|i| {
                let (a, b) = (self.ring[i], self.ring[(i + 1) % n]);
                f64::from(b[0] - a[0]).hypot(f64::from(b[1] - a[1]))
            })
            .collect()
    }
}

/// One bin's cells on its pages.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct BinCells {
    /// The side of every cell, in texels.
    pub cell_px: u32,
    /// Cells per row (and rows) of a page.
    pub per_row: u32,
    /// The bin's pages are `first_page .. first_page + page_count`.
    pub first_page: u32,
    pub page_count: u32,
}

impl BinCells {
    /// Cells on one page.
    pub fn per_page(&self) -> u32 {
        self.per_row.saturating_mul(self.per_row)
    }

    /// The top-left texel of cell `cell` of a page, row by row.
    pub fn cell_origin_px(&self, cell: u32) -> [u32; 2] {
        let per_row = self.per_row.max(1);
        [
            (cell % per_row) * self.cell_px,
            (cell / per_row) * self.cell_px,
        ]
    }
}

/// Where one cluster's textures lie.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterPlacement {
    pub node: u32,
    pub bin: u32,
    /// The page (of all pages) holding the cluster's cells, and the cell on it, the same in
    /// the page's six views.
    pub page: u32,
    pub cell: u32,
    /// Its walls in the side cell (cell-local texels).
    pub sides: SideLayout,
    /// The box the roof views see: the ring's bounds, from the walls' foot to the roof.
    pub box_lo_m: [f32; 3],
    pub box_hi_m: [f32; 3],
}

impl ClusterPlacement {
    /// Wall `face`'s texels in its page's side view.
    pub fn face_rect_px(&self, bin: &BinCells, face: usize) -> Option<FaceRect> {
        let r = *self.sides.faces.get(face)?;
        let [x, y] = bin.cell_origin_px(self.cell);
        Some(FaceRect {
            x_px: x + r.x_px,
            y_px: y + r.y_px,
            ..r
        })
    }

    /// The texels a roof view's image fills in its page's roof views: the cell inside its
    /// border.
    pub fn roof_rect_px(&self, bin: &BinCells) -> FaceRect {
        let [x, y] = bin.cell_origin_px(self.cell);
        let b = side_layout::BORDER_PX;
        let inner = bin.cell_px.saturating_sub(2 * b).max(1);
        FaceRect {
            x_px: x + b,
            y_px: y + b,
            width_px: inner,
            height_px: inner,
        }
    }

    /// The texture coordinate (0..1 across the page of `page_px` texels, v down) where `view`
    /// sees the roof point `point`.
    pub fn roof_uv(&self, bin: &BinCells, page_px: u32, view: RoofView, point: Vec3) -> [f32; 2] {
        let [u, v] = view.uv(point, Vec3::from(self.box_lo_m), Vec3::from(self.box_hi_m));
        let r = self.roof_rect_px(bin);
        let page = page_px as f32;
        [
            (r.x_px as f32 + u * r.width_px as f32) / page,
            (r.y_px as f32 + v * r.height_px as f32) / page,
        ]
    }
}

/// The bins, their pages and the placement of every textured cluster.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct AtlasLayout {
    /// The side of every page (and Chang's texel budget of each bin and view, its square).
    pub page_px: u32,
    pub bins: Vec<BinCells>,
    pub page_count: u32,
    /// Sorted by node; a cluster whose walls fit no bin's cell at one texel each is left out
    /// (drawn untextured).
    pub clusters: Vec<ClusterPlacement>,
}

impl AtlasLayout {
    /// The placement of `node`'s cluster, if it is textured.
    pub fn placement(&self, node: u32) -> Option<&ClusterPlacement> {
        self.clusters
            .binary_search_by_key(&node, |p| p.node)
            .ok()
            .map(|i| &self.clusters[i])
    }
}

/// Lays out `clusters` (any order, each node once) in bins of `page_px²` texels per view, on
/// pages of that size (at most [`MAX_PAGE_PX`]: a larger `page_px` is taken as that).
///
/// A cluster whose walls do not fit its bin's cell at one texel each (a ragged hull of many
/// walls in a first bin of small cells) joins the first later bin whose cell holds them,
/// rather than staying untextured: that bin then takes more than Chang's equal share, as the
/// first bins do when [`super::bins::MIN_CELL_PX`] floors their cells. Only a cluster that no
/// bin's cell holds (or a wall-less or flat one) is left out.
pub fn layout_atlas(clusters: &[ClusterWalls], page_px: u32) -> AtlasLayout {
    let page_px = page_px.clamp(1, MAX_PAGE_PX);
    let areas: Vec<f64> = clusters.iter().map(|c| c.negative_space_m2).collect();
    let texels = texture_bins(&areas, page_px);
    let bin_count = texels.iter().map(|t| t.bin + 1).max().unwrap_or(0) as usize;
    // A cell is never larger than a page: bins give at most the page's texels. Cells grow
    // from bin to bin.
    let mut cell_px = vec![0u32; bin_count];
    for t in &texels {
        cell_px[t.bin as usize] = t.side_px.min(page_px);
    }
    let mut members: Vec<Vec<(usize, SideLayout)>> = vec![Vec::new(); bin_count];
    for (i, (c, t)) in clusters.iter().zip(&texels).enumerate() {
        let lengths = c.wall_lengths_m();
        let height = f64::from(c.top_m) - f64::from(c.base_m);
        let bin = (t.bin as usize..bin_count)
            .find(|&b| side_layout::walls_fit(&lengths, height, cell_px[b]));
        if let Some(bin) = bin
            && let Some(sides) = layout_sides(&lengths, height, cell_px[bin])
        {
            members[bin].push((i, sides));
        }
    }
    let mut bins = Vec::with_capacity(bin_count);
    let mut placements = Vec::with_capacity(clusters.len());
    let mut page_count = 0u32;
    // Bins every cluster left for a later one are dropped, so every bin has a page.
    for (cell_px, mut members) in cell_px.into_iter().zip(members) {
        if members.is_empty() {
            continue;
        }
        let bin = bins.len() as u32;
        let count = members.len() as u32;
        let per_row = (page_px / cell_px.max(1)).max(1);
        let cells = BinCells {
            cell_px,
            per_row,
            first_page: page_count,
            page_count: count.div_ceil(per_row * per_row),
        };
        page_count += cells.page_count;
        bins.push(cells);
        // Cells in the order of the nodes, so that a bin's texture reads like the tree.
        members.sort_by_key(|(i, _)| clusters[*i].node);
        for (k, (i, sides)) in members.into_iter().enumerate() {
            let c = &clusters[i];
            let k = k as u32;
            let (mut lo, mut hi) = ([f32::MAX; 2], [f32::MIN; 2]);
            for p in &c.ring {
                for axis in 0..2 {
                    lo[axis] = lo[axis].min(p[axis]);
                    hi[axis] = hi[axis].max(p[axis]);
                }
            }
            placements.push(ClusterPlacement {
                node: c.node,
                bin,
                page: cells.first_page + k / cells.per_page(),
                cell: k % cells.per_page(),
                sides,
                box_lo_m: [lo[0], lo[1], c.base_m],
                box_hi_m: [hi[0], hi[1], c.top_m],
            });
        }
    }
    placements.sort_by_key(|p| p.node);
    AtlasLayout {
        page_px,
        bins,
        page_count,
        clusters: placements,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn square(node: u32, size: f32, area: f64) -> ClusterWalls {
        ClusterWalls {
            node,
            negative_space_m2: area,
            ring: vec![[0.0, 0.0], [size, 0.0], [size, size], [0.0, size]],
            base_m: 0.0,
            top_m: 12.0,
        }
    }

    /// (x0, y0, x1, y1) of a rectangle with its border, end exclusive.
    fn with_border(r: FaceRect) -> (u32, u32, u32, u32) {
        let b = side_layout::BORDER_PX;
        (
            r.x_px - b,
            r.y_px - b,
            r.x_px + r.width_px + b,
            r.y_px + r.height_px + b,
        )
    }

    fn apart(a: (u32, u32, u32, u32), b: (u32, u32, u32, u32)) -> bool {
        a.2 <= b.0 || b.2 <= a.0 || a.3 <= b.1 || b.3 <= a.1
    }

    /// No two rectangles of one page overlap, borders included, and every one lies inside its
    /// page and its cluster's cell; every cluster is on one of its bin's pages.
    fn assert_packed(layout: &AtlasLayout) {
        let mut pages_seen = 0;
        for (b, bin) in layout.bins.iter().enumerate() {
            assert_eq!(bin.first_page, pages_seen, "bin {b}'s pages follow");
            pages_seen += bin.page_count;
            assert!(bin.cell_px * bin.per_row <= layout.page_px);
        }
        assert_eq!(pages_seen, layout.page_count);
        for page in 0..layout.page_count {
            let placed: Vec<&ClusterPlacement> =
                layout.clusters.iter().filter(|p| p.page == page).collect();
            let mut sides = Vec::new();
            let mut roofs = Vec::new();
            for p in &placed {
                let bin = &layout.bins[p.bin as usize];
                assert!((bin.first_page..bin.first_page + bin.page_count).contains(&p.page));
                assert!(p.cell < bin.per_page());
                let [cx, cy] = bin.cell_origin_px(p.cell);
                let cell = (cx, cy, cx + bin.cell_px, cy + bin.cell_px);
                assert!(cell.2 <= layout.page_px && cell.3 <= layout.page_px);
                for face in 0..p.sides.faces.len() {
                    let r = with_border(p.face_rect_px(bin, face).unwrap());
                    assert!(r.0 >= cell.0 && r.1 >= cell.1 && r.2 <= cell.2 && r.3 <= cell.3);
                    sides.push(r);
                }
                let r = with_border(p.roof_rect_px(bin));
                assert!(r.0 >= cell.0 && r.1 >= cell.1 && r.2 <= cell.2 && r.3 <= cell.3);
                roofs.push(r);
            }
            for rects in [&sides, &roofs] {
                for (i, a) in rects.iter().enumerate() {
                    for b in &rects[i + 1..] {
                        assert!(apart(*a, *b), "page {page}: {a:?} overlaps {b:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn every_cluster_gets_its_own_cell_on_its_bins_pages() {
        let clusters: Vec<ClusterWalls> = (0..13)
            .map(|i| square(100 - i, 10.0 + i as f32, f64::from(i)))
            .collect();
        let layout = layout_atlas(&clusters, 256);
        assert_eq!(layout.clusters.len(), 13);
        assert!(layout.clusters.windows(2).all(|w| w[0].node < w[1].node));
        // Bins of 7, 3, 2, 1 clusters: cells of 96, 144, 180 and 256 texels, one page each.
        let cells: Vec<(u32, u32)> = layout.bins.iter().map(|b| (b.cell_px, b.per_row)).collect();
        assert_eq!(cells, [(96, 2), (144, 1), (180, 1), (256, 1)]);
        // 7 cells of 4 per page: two pages; 3 and 2 cells of one per page: three and two.
        let pages: Vec<u32> = layout.bins.iter().map(|b| b.page_count).collect();
        assert_eq!(pages, [2, 3, 2, 1]);
        assert_eq!(layout.page_count, 8);
        // The last bin holds the cluster of most negative space, alone, with the budget.
        let last = layout.placement(88).unwrap();
        assert_eq!((last.bin, last.page, last.cell), (3, 7, 0));
        assert_eq!(last.box_lo_m, [0.0, 0.0, 0.0]);
        assert_eq!(last.box_hi_m, [22.0, 22.0, 12.0]);
        assert_packed(&layout);
        assert!(layout.placement(5).is_none());
    }

    /// A cluster of `walls` walls on a circle of 50 m, 12 m tall.
    fn ragged(node: u32, walls: usize, area: f64) -> ClusterWalls {
        let ring = (0..walls)
            .map(|i| {
                let a = i as f32 / walls as f32 * std::f32::consts::TAU;
                [50.0 * a.cos(), 50.0 * a.sin()]
            })
            .collect();
        ClusterWalls {
            ring,
            ..square(node, 1.0, area)
        }
    }

    #[test]
    fn a_cluster_of_more_walls_than_its_cell_holds_moves_to_a_later_bin() {
        // Pages of 32²: bins of 4, 2, 1 and 1 clusters, cells of 16 (the least: 25 walls of
        // one texel with their borders), 20 (36 walls) and 32 texels (100 walls).
        let clusters = [
            ragged(0, 30, 0.0),
            ragged(1, 40, 1.0),
            ragged(2, 4, 2.0),
            ragged(3, 150, 3.0),
            ragged(4, 4, 4.0),
            ragged(5, 4, 5.0),
            ragged(6, 4, 6.0),
            ragged(7, 4, 7.0),
        ];
        let layout = layout_atlas(&clusters, 32);
        let cells: Vec<u32> = layout.bins.iter().map(|b| b.cell_px).collect();
        assert_eq!(cells, [16, 20, 32, 32]);
        let bin_of = |node| layout.placement(node).map(|p| p.bin);
        // 30 walls: one bin on; 40: two bins on; 4 walls: where Chang's order puts them.
        assert_eq!(bin_of(0), Some(1));
        assert_eq!(bin_of(1), Some(2));
        assert_eq!(bin_of(2), Some(0));
        // No cell holds 150 walls: untextured.
        assert_eq!(bin_of(3), None);
        assert_eq!(bin_of(4), Some(1));
        assert_eq!(bin_of(7), Some(3));
        assert_eq!(layout.clusters.len(), 7);
        assert_packed(&layout);
    }

    #[test]
    fn a_bin_every_cluster_leaves_is_dropped() {
        // Both clusters of the first bin (cells of 20 texels: 36 walls) have 40 walls; the
        // second bin's 32 texels hold them.
        let clusters = [ragged(0, 40, 0.0), ragged(1, 40, 1.0), ragged(2, 4, 2.0)];
        let layout = layout_atlas(&clusters, 32);
        assert_eq!(layout.bins.len(), 1);
        assert_eq!((layout.bins[0].cell_px, layout.bins[0].page_count), (32, 3));
        assert_eq!(layout.clusters.len(), 3);
        assert!(layout.clusters.iter().all(|p| p.bin == 0));
        assert_packed(&layout);
    }

    #[test]
    fn roof_coordinates_stay_inside_the_clusters_cell() {
        let clusters = [
            square(0, 30.0, 5.0),
            square(1, 8.0, 1.0),
            square(2, 50.0, 0.0),
        ];
        let layout = layout_atlas(&clusters, 64);
        let page = layout.page_px as f32;
        for p in &layout.clusters {
            let bin = &layout.bins[p.bin as usize];
            let [cx, cy] = bin.cell_origin_px(p.cell);
            for view in RoofView::ALL {
                for corner in [[0.0, 0.0], [1.0, 1.0], [0.5, 0.25]] {
                    let lo = Vec3::from(p.box_lo_m);
                    let hi = Vec3::from(p.box_hi_m);
                    let point = lo + (hi - lo) * Vec3::new(corner[0], corner[1], 1.0);
                    let [u, v] = p.roof_uv(bin, layout.page_px, view, point);
                    let (x, y) = (u * page, v * page);
                    assert!(x >= cx as f32 + 0.999 && x <= (cx + bin.cell_px) as f32 - 0.999);
                    assert!(y >= cy as f32 + 0.999 && y <= (cy + bin.cell_px) as f32 - 0.999);
                }
            }
        }
    }

    proptest! {
        #[test]
        fn cells_and_walls_never_overlap(
            shapes in prop::collection::vec(
                (prop::collection::vec((-200.0f32..200.0, -200.0f32..200.0), 3..12), 0.0f64..5e4, 1.0f32..80.0),
                1..40,
            ),
            page in prop::sample::select(vec![32u32, 128, 1024]),
        ) {
            let clusters: Vec<ClusterWalls> = shapes
                .into_iter()
                .enumerate()
                .map(|(i, (ring, area, top))| ClusterWalls {
                    node: i as u32 * 3,
                    negative_space_m2: area,
                    ring: ring.into_iter().map(|(x, y)| [x, y]).collect(),
                    base_m: 0.0,
                    top_m: top,
                })
                .collect();
            let layout = layout_atlas(&clusters, page);
            assert_packed(&layout);
            // Cells are never larger than a page, so one page per bin at least holds them.
            prop_assert!(layout.page_count as usize >= layout.bins.len());
        }
    }
}
