//! CPU reference of the hierarchical-Z pyramid build and of the occlusion test against it,
//! shaped like the GPU passes so tests can compare them texel for texel.
//!
//! Depth is reversed-Z (1 at the near plane, 0 at infinity; cleared to 0). Each pyramid texel
//! keeps the *minimum* depth — the farthest surface — of the pixels it covers, so an object whose
//! nearest depth is smaller than every texel it overlaps lies behind everything drawn there.
//!
//! Non-power-of-two sizes: level `l + 1` has `ceil(w_l / 2) × ceil(h_l / 2)` texels and texel
//! `(x, y)` reduces texels `2x, 2x + 1` (the latter only where it exists) of level `l`. By
//! induction, texel `(x, y)` of level `l` is exactly the minimum over the pixels
//! `[x·2^l, (x+1)·2^l) × [y·2^l, (y+1)·2^l)` clipped to the viewport, so pixel `p` maps to texel
//! `p >> l` at every level and no pixel is ever left out (the classic odd-size bug).
//!
//! The occlusion test reads the pyramid twice: first the coarse level at which the box's screen
//! rectangle touches at most 2×2 texels (the classic test of Kubisch & Tavenrath's GPU-driven
//! rendering and zeux's niagara, level chosen by *ceil*), which culls most hidden boxes in four
//! reads; then, for a box that test keeps, the finest level at which the rectangle spans at most
//! [`HZB_FINE_SPAN`] texels each way. Texels are nested, so the fine test culls everything the
//! coarse one does and more (the coarse texels also cover pixels outside the rectangle, often
//! sky); at street level it keeps about half as many boxes. Its answer alone defines the
//! result; the coarse read is only a shortcut.
//!
//! Records: a building's record is tested by its axis-aligned box first; when that may be
//! visible, by the oriented prisms of its [`CullPart`]s, which hug rotated footprints and
//! separate a tower from its podium ([`crate::scene_gpu::cull_parts`]): the building is
//! visible when a part is ([`DepthPyramid::cull_record`]).
//!
//! Frustum: a box is outside when all eight corners lie beyond one plane of the frustum (the four
//! sides, or the near plane) in clip space. Corners behind the eye are fine for these half-space
//! tests, so a box that crosses the near plane (a building beside and behind a pedestrian) is
//! still culled when it is outside the view, instead of being kept as "unbounded".

use citywalk_shaders::constants::{HZB_BEHIND_W, HZB_FINE_SPAN};
use citywalk_shaders::{BuildingRecord, CullPart};
use glam::{Mat4, Vec3, Vec4};

/// One level of the pyramid.
#[derive(Debug, Clone, PartialEq)]
pub struct PyramidLevel {
    pub width: u32,
    pub height: u32,
    /// Row-major minimum depths.
    pub depth: Vec<f32>,
}

impl PyramidLevel {
    fn at(&self, x: u32, y: u32) -> f32 {
        self.depth[(y * self.width + x) as usize]
    }
}

/// A min-depth pyramid over a reversed-Z depth buffer; level 0 is the depth buffer itself.
#[derive(Debug, Clone, PartialEq)]
pub struct DepthPyramid {
    pub levels: Vec<PyramidLevel>,
}

/// Number of levels of the pyramid for a `width × height` viewport: down to 1×1.
pub fn level_count(width: u32, height: u32) -> u32 {
    let mut n = 1;
    let (mut w, mut h) = (width.max(1), height.max(1));
    while w > 1 || h > 1 {
        w = w.div_ceil(2);
        h = h.div_ceil(2);
        n += 1;
    }
    n
}

impl DepthPyramid {
    /// Builds the pyramid from a row-major depth buffer of `width × height` texels.
    pub fn build(width: u32, height: u32, depth: &[f32]) -> DepthPyramid {
        assert_eq!(depth.len(), (width * height) as usize, "depth buffer size");
        let mut levels = vec![PyramidLevel {
            width,
            height,
            depth: depth.to_vec(),
        }];
        for _ in 1..level_count(width, height) {
            let prev = levels.last().expect("level 0 exists");
            let (w, h) = (prev.width.div_ceil(2), prev.height.div_ceil(2));
            let mut next = Vec::with_capacity((w * h) as usize);
            for y in 0..h {
                for x in 0..w {
                    next.push(reduce_texel(prev, x, y));
                }
            }
            levels.push(PyramidLevel {
                width: w,
                height: h,
                depth: next,
            });
        }
        DepthPyramid { levels }
    }

    /// Whether an object covering the pixel rectangle `rect` (inclusive, clamped to the
    /// viewport) whose nearest point has depth `nearest_depth` is hidden behind the depth
    /// buffer everywhere in that rectangle.
    ///
    /// Decided at [`select_fine_level`] (the GPU reads [`select_level`] first as a shortcut: same
    /// answer, see the module documentation).
    pub fn is_occluded(&self, rect: PixelRect, nearest_depth: f32) -> bool {
        nearest_depth < self.farthest_in(rect, select_fine_level(rect))
    }

    /// The farthest (minimum) depth of the texels of `level` (clamped to the coarsest) that
    /// cover `rect`: the farthest depth of the depth buffer over the rectangle, or a smaller
    /// value as the level gets coarser.
    pub fn farthest_in(&self, rect: PixelRect, level: u32) -> f32 {
        let level = level.min(self.levels.len() as u32 - 1);
        let l = &self.levels[level as usize];
        let (x0, x1) = (rect.x0 >> level, rect.x1 >> level);
        let (y0, y1) = (rect.y0 >> level, rect.y1 >> level);
        let mut farthest = f32::INFINITY;
        for y in y0..=y1.min(l.height - 1) {
            for x in x0..=x1.min(l.width - 1) {
                farthest = farthest.min(l.at(x, y));
            }
        }
        farthest
    }
}

/// What the cull decides for one record ([`DepthPyramid::cull_record`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum RecordCull {
    /// The box, or every part, is outside the view frustum.
    Outside,
    /// Hidden behind the pyramid: the box, or every part not outside.
    Occluded,
    /// May be visible.
    Visible,
}

/// What the test of one convex hull (a box or a part) finds.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum HullTest {
    Outside,
    Occluded,
    /// Its rectangle is not hidden.
    Kept,
    /// It reaches the near plane: no safe rectangle, visible.
    CrossesNear,
}

impl DepthPyramid {
    /// The convex hull of `corners` seen through the reversed-Z `view_proj` against this
    /// pyramid (level 0 is the viewport), by [`project_corners`] and
    /// [`DepthPyramid::is_occluded`].
    pub fn test_hull(&self, view_proj: Mat4, corners: &[Vec3; 8]) -> HullTest {
        let (width, height) = (self.levels[0].width, self.levels[0].height);
        match project_corners(view_proj, corners, width, height) {
            BoxProjection::Outside => HullTest::Outside,
            BoxProjection::CrossesNear => HullTest::CrossesNear,
            BoxProjection::Rect {
                rect,
                nearest_depth,
            } if self.is_occluded(rect, nearest_depth) => HullTest::Occluded,
            BoxProjection::Rect { .. } => HullTest::Kept,
        }
    }

    /// The record's box, then, when the box may be visible, its parts `parts[first_part..]`
    /// (a range past `parts` is ignored: the box decides): outside when every part is, hidden
    /// when no part is visible. What the GPU cull computes (`shaders/wgsl/hzb_cull.wgsl`).
    pub fn cull_record(
        &self,
        view_proj: Mat4,
        record: &BuildingRecord,
        parts: &[CullPart],
    ) -> RecordCull {
        let lo = Vec3::from_array(record.bounds_min_m);
        let hi = Vec3::from_array(record.bounds_max_m);
        match self.test_hull(view_proj, &box_corners(lo, hi)) {
            HullTest::Outside => return RecordCull::Outside,
            HullTest::Occluded => return RecordCull::Occluded,
            HullTest::Kept | HullTest::CrossesNear => {}
        }
        let first = record.first_part as usize;
        let Some(parts) = parts.get(first..first + record.part_count as usize) else {
            return RecordCull::Visible;
        };
        if parts.is_empty() {
            return RecordCull::Visible;
        }
        let mut all_outside = true;
        for part in parts {
            match self.test_hull(view_proj, &part.corners().map(Vec3::from_array)) {
                HullTest::Kept | HullTest::CrossesNear => return RecordCull::Visible,
                HullTest::Occluded => all_outside = false,
                HullTest::Outside => {}
            }
        }
        if all_outside {
            RecordCull::Outside
        } else {
            RecordCull::Occluded
        }
    }
}

/// The virtual occluders' depth as the pyramid takes it: each texel the farthest (smallest,
/// reversed Z) of itself and its four edge neighbours in `depth` (`width × height`, row-major),
/// texels outside the viewport counting as cleared (0).
///
/// Why: an occluder lies inside its building (Germs & Jansen 2001), but where its edge meets the
/// building's silhouette the two are rasterised by different draws, and the occluder can cover
/// a pixel centre that the building leaves to what lies behind it: on a street path of the
/// generated 1M city (640×360) an occluder whose corner projects 0.011 px left of a pixel
/// centre covered it, hiding the one building seen there, with vertices identical to its
/// building's. Such a pixel is within a fraction of a pixel of the occluder's edge, so its
/// neighbour across the edge along the normal's larger axis (at least 0.7 px across) is
/// uncovered or farther, and the eroded texel no nearer than what the image shows. The price is
/// a pixel of each occluder's outline: on that city's street path `all` drew about 2.7× the
/// buildings it drew before.
pub fn erode(width: u32, height: u32, depth: &[f32]) -> Vec<f32> {
    assert_eq!(depth.len(), (width * height) as usize, "depth buffer size");
    let at = |x: i64, y: i64| {
        if x < 0 || y < 0 || x >= i64::from(width) || y >= i64::from(height) {
            0.0
        } else {
            depth[(y * i64::from(width) + x) as usize]
        }
    };
    let mut out = Vec::with_capacity(depth.len());
    for y in 0..i64::from(height) {
        for x in 0..i64::from(width) {
            let m = at(x, y)
                .min(at(x - 1, y))
                .min(at(x + 1, y))
                .min(at(x, y - 1))
                .min(at(x, y + 1));
            out.push(m);
        }
    }
    out
}

/// Minimum of the up to 2×2 texels of `prev` under texel `(x, y)` of the next level.
pub fn reduce_texel(prev: &PyramidLevel, x: u32, y: u32) -> f32 {
    let mut m = f32::INFINITY;
    for dy in 0..2 {
        for dx in 0..2 {
            let (sx, sy) = (2 * x + dx, 2 * y + dy);
            if sx < prev.width && sy < prev.height {
                m = m.min(prev.at(sx, sy));
            }
        }
    }
    m
}

/// The coarse level: the finest at which `rect` spans at most two texels in each direction
/// (ceil, never floor: the test reads every texel the rectangle touches at that level, so
/// whatever level is chosen no pixel is left out; this one bounds the reads to 2×2).
pub fn select_level(rect: PixelRect) -> u32 {
    level_spanning(rect, 2)
}

/// The fine level: the finest at which `rect` spans at most [`HZB_FINE_SPAN`] texels in each
/// direction (level 0, the depth buffer itself, for rectangles up to that many pixels).
pub fn select_fine_level(rect: PixelRect) -> u32 {
    level_spanning(rect, HZB_FINE_SPAN)
}

/// The finest level at which `rect` touches at most `span` (≥ 1) texels in each direction.
fn level_spanning(rect: PixelRect, span: u32) -> u32 {
    let mut level = 0;
    while level < 31
        && ((rect.x1 >> level) - (rect.x0 >> level) >= span
            || (rect.y1 >> level) - (rect.y0 >> level) >= span)
    {
        level += 1;
    }
    level
}

/// An inclusive rectangle of pixels, `x0 <= x1`, `y0 <= y1`, y down.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct PixelRect {
    pub x0: u32,
    pub y0: u32,
    pub x1: u32,
    pub y1: u32,
}

/// Where an axis-aligned box lands on screen.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum BoxProjection {
    /// Entirely beyond one plane of the frustum (a side, or the near plane: behind the camera).
    Outside,
    /// Some corner is at or behind the near plane and the box is not beyond any frustum plane:
    /// no safe screen rectangle, treat as visible.
    CrossesNear,
    /// The pixels the box can cover and the depth of its nearest point.
    Rect { rect: PixelRect, nearest_depth: f32 },
}

/// Frustum planes a clip-space point lies beyond, one bit each: right `x > w`, left `x < -w`,
/// top `y > w`, bottom `y < -w`, near `z > w` (reversed Z: between the eye and the near plane,
/// or behind the eye). Each is a half-space of world space, so a box whose eight corners share a
/// bit lies wholly beyond that plane.
pub fn outcode(clip: Vec4) -> u32 {
    u32::from(clip.x > clip.w)
        | u32::from(clip.x < -clip.w) << 1
        | u32::from(clip.y > clip.w) << 2
        | u32::from(clip.y < -clip.w) << 3
        | u32::from(clip.z > clip.w) << 4
}

/// Projects the box `[lo, hi]` with a reversed-Z `view_proj` onto a `width × height` viewport.
/// The rectangle is conservative: it contains every pixel whose centre the box's rasterisation
/// could cover.
pub fn project_box(view_proj: Mat4, lo: Vec3, hi: Vec3, width: u32, height: u32) -> BoxProjection {
    project_corners(view_proj, &box_corners(lo, hi), width, height)
}

/// The eight corners of the box `[lo, hi]` (bit 0 of the index: x at `hi`, bit 1: y, bit 2: z).
pub fn box_corners(lo: Vec3, hi: Vec3) -> [Vec3; 8] {
    std::array::from_fn(|i| {
        Vec3::new(
            if i & 1 == 0 { lo.x } else { hi.x },
            if i & 2 == 0 { lo.y } else { hi.y },
            if i & 4 == 0 { lo.z } else { hi.z },
        )
    })
}

/// As [`project_box`], for the convex hull of eight `corners` (a box, or a [`CullPart`]'s
/// prism).
pub fn project_corners(
    view_proj: Mat4,
    corners: &[Vec3; 8],
    width: u32,
    height: u32,
) -> BoxProjection {
    let mut ndc_min = glam::Vec2::splat(f32::INFINITY);
    let mut ndc_max = glam::Vec2::splat(f32::NEG_INFINITY);
    let mut nearest_depth = 0.0f32;
    let (mut behind, mut inside_near) = (0, 0);
    // Planes every corner so far lies beyond.
    let mut beyond_all = 0b1_1111;
    for corner in corners {
        let clip: Vec4 = view_proj * corner.extend(1.0);
        beyond_all &= outcode(clip);
        // The same threshold as the GPU cull (`shaders/wgsl/hzb_cull.wgsl`).
        if clip.w <= HZB_BEHIND_W {
            behind += 1;
            continue;
        }
        if clip.z > clip.w {
            // Between the eye and the near plane.
            inside_near += 1;
            continue;
        }
        let ndc = clip.truncate() / clip.w;
        ndc_min = ndc_min.min(ndc.truncate());
        ndc_max = ndc_max.max(ndc.truncate());
        nearest_depth = nearest_depth.max(ndc.z);
    }
    if behind == 8 || beyond_all != 0 {
        return BoxProjection::Outside;
    }
    if behind > 0 || inside_near > 0 {
        // Part of the box is at or behind the eye: its projection is unbounded.
        return BoxProjection::CrossesNear;
    }
    if ndc_max.x < -1.0 || ndc_min.x > 1.0 || ndc_max.y < -1.0 || ndc_min.y > 1.0 {
        return BoxProjection::Outside;
    }
    let (w, h) = (width as f32, height as f32);
    let to_px = |x: f32| ((x * 0.5 + 0.5) * w).clamp(0.0, w - 1.0);
    let to_py = |y: f32| ((0.5 - y * 0.5) * h).clamp(0.0, h - 1.0);
    let rect = PixelRect {
        x0: to_px(ndc_min.x).floor() as u32,
        x1: to_px(ndc_max.x).floor() as u32,
        y0: to_py(ndc_max.y).floor() as u32,
        y1: to_py(ndc_min.y).floor() as u32,
    };
    BoxProjection::Rect {
        rect,
        nearest_depth,
    }
}

/// CPU reference of the tree cull ([`crate::hzb::tree_cull`], the GPU's LOD cut with
/// hierarchical occlusion): the draw ids its walk keeps over `tree` against this pyramid, under
/// the view and criterion of `params`, ascending. `records` are the LOD scene's cull records by
/// draw id (node `n`'s box is record `building_count + n`), `parts` the parts they name. A node
/// whose box is outside or hidden is dropped with its subtree; a leaf keeps its building when the
/// building's record may be visible; an inner node refines
/// ([`crate::lod::gpu_tree::refines`]) or keeps its cluster mesh and, under Chang's criterion,
/// each landmark rising more than τ above it whose record may be visible.
pub fn tree_cull(
    pyramid: &DepthPyramid,
    tree: &crate::lod::gpu_tree::TreeArrays,
    (records, parts): (&[BuildingRecord], &[CullPart]),
    view_proj: Mat4,
    params: &citywalk_shaders::TreeCullParams,
) -> Vec<u32> {
    use crate::lod::gpu_tree::{px_per_m, refines};
    use citywalk_shaders::constants::TREE_CRITERION_CHANG;

    let shows = |id: u32| {
        records
            .get(id as usize)
            .is_some_and(|r| pyramid.cull_record(view_proj, r, parts) == RecordCull::Visible)
    };
    let mut kept = Vec::new();
    let mut stack: Vec<u32> = Vec::new();
    if (tree.root as usize) < tree.nodes.len() {
        stack.push(tree.root);
    }
    while let Some(n) = stack.pop() {
        let (Some(node), Some(record)) = (
            tree.nodes.get(n as usize),
            records.get((params.building_count + n) as usize),
        ) else {
            continue;
        };
        let corners = box_corners(
            Vec3::from_array(record.bounds_min_m),
            Vec3::from_array(record.bounds_max_m),
        );
        if matches!(
            pyramid.test_hull(view_proj, &corners),
            HullTest::Outside | HullTest::Occluded
        ) {
            continue;
        }
        if node.child_count == 0 {
            if node.building < params.building_count && shows(node.building) {
                kept.push(node.building);
            }
            continue;
        }
        let first = node.first_child as usize;
        if refines(node, params) {
            stack.extend(
                tree.children
                    .get(first..first + node.child_count as usize)
                    .unwrap_or(&[]),
            );
            continue;
        }
        kept.push(params.building_count + n);
        if params.criterion == TREE_CRITERION_CHANG {
            let ppm = px_per_m(node, params);
            let tau_height_m = if ppm > 0.0 {
                params.tolerance_b / ppm
            } else {
                0.0
            };
            let first = node.first_landmark as usize;
            for landmark in tree
                .landmarks
                .get(first..first + node.landmark_count as usize)
                .unwrap_or(&[])
            {
                if landmark.top_m - node.height_m > tau_height_m
                    && landmark.building < params.building_count
                    && shows(landmark.building)
                {
                    kept.push(landmark.building);
                }
            }
        }
    }
    kept.sort_unstable();
    kept.dedup();
    kept
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    fn brute_min(w: u32, depth: &[f32], r: PixelRect) -> f32 {
        let mut m = f32::INFINITY;
        for y in r.y0..=r.y1 {
            for x in r.x0..=r.x1 {
                m = m.min(depth[(y * w + x) as usize]);
            }
        }
        m
    }

    #[test]
    fn erosion_keeps_only_texels_whose_edge_neighbours_are_covered() {
        // A 4×3 occluder block at depth 0.5 with one nearer texel, in a 6×5 viewport whose
        // right column the block touches.
        let (w, h) = (6u32, 5u32);
        let mut d = vec![0.0f32; (w * h) as usize];
        for y in 1..4 {
            for x in 2..6 {
                d[(y * w + x) as usize] = 0.5;
            }
        }
        d[(2 * w + 3) as usize] = 0.9;
        let e = erode(w, h, &d);
        // Only (3, 2) and (4, 2) have their four edge neighbours covered; (5, 2) lies at the
        // viewport's edge, whose outside counts as cleared.
        for y in 0..h {
            for x in 0..w {
                let want = if y == 2 && (x == 3 || x == 4) {
                    0.5
                } else {
                    0.0
                };
                assert_eq!(e[(y * w + x) as usize], want, "({x}, {y})");
            }
        }
        // Erosion never brings a texel nearer.
        assert!(e.iter().zip(&d).all(|(a, b)| a <= b));
    }

    #[test]
    fn level_counts() {
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(2, 1), 2);
        assert_eq!(level_count(1280, 720), 12);
        assert_eq!(level_count(1001, 777), 11);
    }

    #[test]
    fn odd_sizes_keep_the_last_row_and_column() {
        // 5x3 buffer, everything far (0.0 is infinitely far) except a near last column.
        let (w, h) = (5, 3);
        let mut d = vec![0.9; 15];
        d[14] = 0.1; // bottom-right pixel: far-ish
        let p = DepthPyramid::build(w, h, &d);
        assert_eq!(p.levels.last().unwrap().depth, vec![0.1]);
        assert_eq!(p.levels[1].width, 3);
        assert_eq!(p.levels[1].height, 2);
        assert_eq!(p.levels[1].at(2, 1), 0.1);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, rng_seed: proptest::test_runner::RngSeed::Fixed(7), ..ProptestConfig::default() })]
        /// Every texel is the minimum of exactly the pixels it covers, and the occlusion test
        /// equals the brute-force test over the whole rectangle for every rectangle.
        #[test]
        fn pyramid_is_exact_and_test_is_conservative(
            w in 1u32..70, h in 1u32..50, seed in 0u64..1000,
            rx in 0.0f32..1.0, ry in 0.0f32..1.0, rw in 0.0f32..1.0, rh in 0.0f32..1.0,
            depth in 0.0f32..1.0,
        ) {
            let mut state = seed.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
            let buffer: Vec<f32> = (0..w * h).map(|_| {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 40) as f32 / (1u64 << 24) as f32
            }).collect();
            let p = DepthPyramid::build(w, h, &buffer);
            for (l, level) in p.levels.iter().enumerate() {
                for y in 0..level.height {
                    for x in 0..level.width {
                        let r = PixelRect {
                            x0: x << l, y0: y << l,
                            x1: (((x + 1) << l) - 1).min(w - 1), y1: (((y + 1) << l) - 1).min(h - 1),
                        };
                        prop_assert_eq!(level.at(x, y), brute_min(w, &buffer, r));
                    }
                }
            }
            let x0 = (rx * (w - 1) as f32) as u32;
            let y0 = (ry * (h - 1) as f32) as u32;
            let x1 = (x0 + (rw * w as f32) as u32).min(w - 1);
            let y1 = (y0 + (rh * h as f32) as u32).min(h - 1);
            let rect = PixelRect { x0, y0, x1, y1 };
            let hidden = p.is_occluded(rect, depth);
            // Never claims hidden when some pixel of the rectangle is farther than the object.
            if hidden {
                prop_assert!(depth < brute_min(w, &buffer, rect));
            }
            // Rectangles up to HZB_FINE_SPAN pixels each way are tested exactly, at level 0.
            if rect.x1 - rect.x0 < HZB_FINE_SPAN && rect.y1 - rect.y0 < HZB_FINE_SPAN {
                prop_assert_eq!(select_fine_level(rect), 0);
                prop_assert_eq!(hidden, depth < brute_min(w, &buffer, rect));
            }
            // The GPU's coarse 2x2 shortcut never culls what the fine test keeps.
            let coarse = select_level(rect);
            prop_assert!(coarse >= select_fine_level(rect));
            if depth < p.farthest_in(rect, coarse) {
                prop_assert!(hidden);
            }
            // The fine level reads at most HZB_FINE_SPAN texels each way, and no coarser level
            // than needed: one level finer would exceed it (ceil, never floor).
            let fine = select_fine_level(rect);
            prop_assert!((rect.x1 >> fine) - (rect.x0 >> fine) < HZB_FINE_SPAN);
            prop_assert!((rect.y1 >> fine) - (rect.y0 >> fine) < HZB_FINE_SPAN);
            if fine > 0 {
                let finer = fine - 1;
                prop_assert!(
                    (rect.x1 >> finer) - (rect.x0 >> finer) >= HZB_FINE_SPAN
                        || (rect.y1 >> finer) - (rect.y0 >> finer) >= HZB_FINE_SPAN
                );
            }
        }

        /// The projection is conservative: a box called outside has no point inside the view
        /// frustum (points sampled over the box, corners and faces included), and every sampled
        /// point of a projected box inside the frustum lands in its rectangle, no nearer than
        /// its nearest depth. Cameras at street level and above, boxes around, beside and
        /// behind the eye as well as ahead; viewports of odd sizes.
        #[test]
        fn box_projection_is_conservative(
            yaw in 0.0f32..std::f32::consts::TAU, pitch in -1.2f32..0.6,
            eye_z in 1.0f32..60.0,
            cx in -80.0f32..80.0, cy in -80.0f32..80.0, cz in -10.0f32..60.0,
            sx in 0.1f32..40.0, sy in 0.1f32..40.0, sz in 0.1f32..60.0,
            w in 16u32..1400, h in 16u32..900, seed in 0u64..1000,
        ) {
            let cam = crate::camera::Camera::new(Vec3::new(0.0, 0.0, eye_z), yaw, pitch);
            let vp = cam.view_proj(w as f32 / h as f32);
            let lo = Vec3::new(cx, cy, cz);
            let hi = lo + Vec3::new(sx, sy, sz);
            let projection = project_box(vp, lo, hi, w, h);
            let mut state = seed.wrapping_add(1);
            let mut unit = || {
                state = state.wrapping_mul(6364136223846793005).wrapping_add(1442695040888963407);
                (state >> 40) as f32 / (1u64 << 24) as f32
            };
            for k in 0..400 {
                // Corners, then points on faces, then anywhere inside.
                let mut t = Vec3::new(unit(), unit(), unit());
                if k < 8 {
                    t = Vec3::new((k & 1) as f32, ((k >> 1) & 1) as f32, ((k >> 2) & 1) as f32);
                } else if k < 200 {
                    t[k % 3] = if k % 2 == 0 { 0.0 } else { 1.0 };
                }
                let point = lo + (hi - lo) * t;
                let clip = vp * point.extend(1.0);
                // Strictly inside the frustum, with a margin for this test's own rounding.
                let m = 1e-4 * clip.w.abs();
                let inside = clip.w > 1e-3
                    && clip.x.abs() < clip.w - m
                    && clip.y.abs() < clip.w - m
                    && clip.z < clip.w - m;
                if !inside {
                    continue;
                }
                match projection {
                    BoxProjection::Outside => {
                        prop_assert!(false, "point {point} of [{lo}, {hi}] is in view, box called outside");
                    }
                    BoxProjection::CrossesNear => {}
                    BoxProjection::Rect { rect, nearest_depth } => {
                        let ndc = clip.truncate() / clip.w;
                        let px = (ndc.x * 0.5 + 0.5) * w as f32;
                        let py = (0.5 - ndc.y * 0.5) * h as f32;
                        prop_assert!(px >= rect.x0 as f32 - 0.01 && px < rect.x1 as f32 + 1.01);
                        prop_assert!(py >= rect.y0 as f32 - 0.01 && py < rect.y1 as f32 + 1.01);
                        prop_assert!(ndc.z <= nearest_depth * (1.0 + 1e-5));
                    }
                }
            }
        }
    }

    /// The fine test culls a box the coarse 2x2 test keeps: a near wall covers the box's
    /// rectangle, but the coarse texels around it also cover sky.
    #[test]
    fn fine_level_culls_what_the_coarse_level_keeps() {
        let (w, h) = (97, 61);
        // Wall at depth 0.5 over x < 40, sky (0) beyond.
        let depth: Vec<f32> = (0..w * h)
            .map(|i| if i % w < 40 { 0.5 } else { 0.0 })
            .collect();
        let p = DepthPyramid::build(w, h, &depth);
        let rect = PixelRect {
            x0: 21,
            y0: 10,
            x1: 35,
            y1: 20,
        };
        // The coarse level reads texels reaching into the sky: it keeps the box.
        let coarse = select_level(rect);
        assert_eq!(coarse, 4);
        assert_eq!(p.farthest_in(rect, coarse), 0.0);
        // The fine one reads exactly the rectangle (15 x 11 pixels at level 0): culled.
        assert_eq!(select_fine_level(rect), 0);
        assert!(p.is_occluded(rect, 0.3));
        // ... and never a box in front of the wall or reaching the sky.
        assert!(!p.is_occluded(rect, 0.5));
        assert!(!p.is_occluded(PixelRect { x1: 40, ..rect }, 0.3));
        // A wide rectangle (60 pixels) is tested at level 2, still inside the wall's texels.
        let wide = PixelRect {
            x0: 0,
            y0: 0,
            x1: 35,
            y1: 60,
        };
        assert_eq!(select_fine_level(wide), 2);
        assert!(p.is_occluded(wide, 0.3));
    }

    #[test]
    fn box_projection_cases() {
        let cam = crate::camera::Camera {
            position: Vec3::new(0.0, 0.0, 1.7),
            yaw_rad: 0.0,
            pitch_rad: 0.0,
            fov_y_rad: 60f32.to_radians(),
            near_m: 0.1,
        };
        let vp = cam.view_proj(16.0 / 9.0);
        // A box straight ahead projects to a centred rectangle.
        match project_box(
            vp,
            Vec3::new(10.0, -1.0, 0.7),
            Vec3::new(12.0, 1.0, 2.7),
            1280,
            720,
        ) {
            BoxProjection::Rect {
                rect,
                nearest_depth,
            } => {
                assert!(rect.x0 < 640 && rect.x1 > 640 && rect.y0 < 360 && rect.y1 > 360);
                assert!((nearest_depth - 0.1 / 10.0).abs() < 1e-4, "{nearest_depth}");
            }
            other => panic!("{other:?}"),
        }
        // Behind the camera: outside. Around the camera: crosses the near plane.
        assert_eq!(
            project_box(
                vp,
                Vec3::new(-12.0, -1.0, 0.0),
                Vec3::new(-10.0, 1.0, 2.0),
                1280,
                720
            ),
            BoxProjection::Outside
        );
        assert_eq!(
            project_box(
                vp,
                Vec3::new(-1.0, -1.0, 0.0),
                Vec3::new(1.0, 1.0, 3.0),
                1280,
                720
            ),
            BoxProjection::CrossesNear
        );
        assert_eq!(
            project_box(
                vp,
                Vec3::new(10.0, 50.0, 0.0),
                Vec3::new(12.0, 52.0, 2.0),
                1280,
                720
            ),
            BoxProjection::Outside
        );
        // A building beside and behind the pedestrian: its box crosses the eye plane, but lies
        // wholly left of the view (at x = 5 m the view reaches y ≈ 5.1 m). Outside, where the
        // old test kept every box crossing the near plane.
        assert_eq!(
            project_box(
                vp,
                Vec3::new(-20.0, 30.0, 0.0),
                Vec3::new(5.0, 40.0, 10.0),
                1280,
                720
            ),
            BoxProjection::Outside
        );
        // The same building closer to the street is partly in view: kept.
        assert_eq!(
            project_box(
                vp,
                Vec3::new(-20.0, 3.0, 0.0),
                Vec3::new(5.0, 10.0, 10.0),
                1280,
                720
            ),
            BoxProjection::CrossesNear
        );
        // Between the eye and the near plane (0.1 m) only: clipped away entirely.
        assert_eq!(
            project_box(
                vp,
                Vec3::new(0.02, -0.01, 1.69),
                Vec3::new(0.08, 0.01, 1.71),
                1280,
                720
            ),
            BoxProjection::Outside
        );
    }
}
