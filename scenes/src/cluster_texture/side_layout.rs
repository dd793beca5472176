//! Where each wall of a cluster mesh lies in the cluster's side texture.
//!
//! Chang et al. 2008 §7: an image per face of the cluster mesh, "set to fit into a single
//! texture, with the resolution of each image proportional to the length of each face". Each
//! face is a rectangle as wide as the face is long and as tall as the cluster, at one density
//! (texels per metre) for the whole cluster, so that texels are square and neighbouring faces
//! meet at the same scale. The rectangles follow the hull's order along rows (a face that
//! does not fit the rest of a row starts the next), each inside a border of [`BORDER_PX`]
//! that the baker fills from the rectangle's edge, so that filtering never reads a
//! neighbour; the density is the largest at which the rows fit the square.

use serde::{Deserialize, Serialize};

/// Texels around each face's rectangle, filled from its edge.
pub const BORDER_PX: u32 = 1;

/// A face's texels in the side texture, its border excluded. Row 0 is the top of the texture;
/// the top row of the rectangle is the top of the wall.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct FaceRect {
    pub x_px: u32,
    pub y_px: u32,
    pub width_px: u32,
    pub height_px: u32,
}

/// The side texture of one cluster mesh: a square of `side_px` texels holding one rectangle
/// per wall, in the hull's order.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct SideLayout {
    pub side_px: u32,
    /// The density every face shares.
    pub texels_per_m: f64,
    pub faces: Vec<FaceRect>,
}

impl SideLayout {
    /// The texture coordinate (0..1, v down) of the point of `face` at `along` (0 at the
    /// face's first hull vertex, 1 at its second) and `up` (0 at the wall's foot, 1 at its
    /// top).
    pub fn uv(&self, face: usize, along: f32, up: f32) -> [f32; 2] {
        let r = &self.faces[face];
        let side = self.side_px as f32;
        [
            (r.x_px as f32 + along * r.width_px as f32) / side,
            (r.y_px as f32 + (1.0 - up) * r.height_px as f32) / side,
        ]
    }
}

/// Lays out the walls of a cluster mesh of `height_m` whose faces are `face_lengths_m` long
/// (in the hull's order) in a square side texture of `side_px` texels. `None` when even one
/// texel per face does not fit, or the height is not a positive length: such a cluster keeps
/// its untextured colour (at a few texels the texture would be that colour anyway). A face
/// length that is not a positive finite number gets one texel's width.
pub fn layout_sides(face_lengths_m: &[f64], height_m: f64, side_px: u32) -> Option<SideLayout> {
    if !walls_fit(face_lengths_m, height_m, side_px) {
        return None;
    }
    let lengths = usable_lengths(face_lengths_m);
    let longest = lengths.iter().copied().fold(height_m, f64::max);
    let inner = f64::from(side_px.checked_sub(2 * BORDER_PX)?);
    // The densest layout conceivable puts the longest face across the whole texture.
    let (mut fits, mut too_dense) = (f64::MIN_POSITIVE, inner / longest * (1.0 + 1e-9));
    let mut best = place(&lengths, height_m, f64::MIN_POSITIVE, side_px)?;
    // The fit is monotone but for rounding; bisection keeps the densest layout that fitted.
    for _ in 0..48 {
        let density = 0.5 * (fits + too_dense);
        match place(&lengths, height_m, density, side_px) {
            Some(faces) => {
                fits = density;
                best = faces;
            }
            None => too_dense = density,
        }
    }
    Some(SideLayout {
        side_px,
        texels_per_m: fits,
        faces: best,
    })
}

/// Whether [`layout_sides`] can lay these walls out in `side_px` texels: one texel a face
/// and its border fit, and the height is a positive length.
pub fn walls_fit(face_lengths_m: &[f64], height_m: f64, side_px: u32) -> bool {
    !face_lengths_m.is_empty()
        && height_m.is_finite()
        && height_m > 0.0
        && place(
            &usable_lengths(face_lengths_m),
            height_m,
            f64::MIN_POSITIVE,
            side_px,
        )
        .is_some()
}

/// A length that is not a positive finite number counts as 0 (one texel's width).
fn usable_lengths(face_lengths_m: &[f64]) -> Vec<f64> {
    face_lengths_m
        .iter()
        .map(|&l| if l.is_finite() && l > 0.0 { l } else { 0.0 })
        .collect()
}

/// The faces at `density` texels per metre, row after row, or `None` when they overflow.
fn place(lengths: &[f64], height_m: f64, density: f64, side_px: u32) -> Option<Vec<FaceRect>> {
    let texels = |metres: f64| ((metres * density).round() as u32).max(1);
    let height_px = texels(height_m);
    let row_px = height_px.checked_add(2 * BORDER_PX)?;
    let mut faces = Vec::with_capacity(lengths.len());
    let (mut x, mut y) = (0u32, 0u32);
    for &length in lengths {
        let width_px = texels(length);
        let cell = width_px.checked_add(2 * BORDER_PX)?;
        if cell > side_px {
            return None;
        }
        if x + cell > side_px {
            (x, y) = (0, y + row_px);
        }
        faces.push(FaceRect {
            x_px: x + BORDER_PX,
            y_px: y + BORDER_PX,
            width_px,
            height_px,
        });
        x += cell;
    }
    (y.checked_add(row_px)? <= side_px).then_some(faces)
}

#[cfg(test)]
mod tests {
    use super::*;
    use proptest::prelude::*;

    /// Each face's rectangle with its border, as (x0, y0, x1, y1), end exclusive.
    fn cells(layout: &SideLayout) -> Vec<(u32, u32, u32, u32)> {
        let b = BORDER_PX;
        layout
            .faces
            .iter()
            .map(|r| {
                (
                    r.x_px - b,
                    r.y_px - b,
                    r.x_px + r.width_px + b,
                    r.y_px + r.height_px + b,
                )
            })
            .collect()
    }

    fn assert_valid(layout: &SideLayout, lengths: &[f64], height_m: f64) {
        let cells = cells(layout);
        assert_eq!(cells.len(), lengths.len());
        for (i, a) in cells.iter().enumerate() {
            assert!(
                a.2 <= layout.side_px && a.3 <= layout.side_px,
                "face {i} outside"
            );
            for b in &cells[i + 1..] {
                let apart = a.2 <= b.0 || b.2 <= a.0 || a.3 <= b.1 || b.3 <= a.1;
                assert!(apart, "{a:?} overlaps {b:?}");
            }
        }
        let d = layout.texels_per_m;
        for (r, &l) in layout.faces.iter().zip(lengths) {
            // Proportional to the face's length, to the nearest texel (one at least).
            assert_eq!(
                r.width_px,
                ((l * d).round() as u32).max(1),
                "{l} m at {d}/m"
            );
            assert_eq!(r.height_px, ((height_m * d).round() as u32).max(1));
        }
        // In the hull's order: along a row, then the next row.
        for pair in layout.faces.windows(2) {
            let (a, b) = (pair[0], pair[1]);
            assert!(
                (b.y_px == a.y_px && b.x_px > a.x_px) || b.y_px > a.y_px,
                "{a:?} then {b:?}"
            );
        }
    }

    #[test]
    fn a_square_hull_fills_its_texture_in_two_rows() {
        // Four 10 m walls, 10 m tall, in 64 texels: two rows of two 30-texel squares (with
        // their borders, 32 each) are the densest layout.
        let lengths = [10.0; 4];
        let layout = layout_sides(&lengths, 10.0, 64).unwrap();
        assert_valid(&layout, &lengths, 10.0);
        let sizes: Vec<_> = layout
            .faces
            .iter()
            .map(|r| (r.width_px, r.height_px))
            .collect();
        assert_eq!(sizes, [(30, 30); 4]);
        assert_eq!(
            layout.faces[2],
            FaceRect {
                x_px: 1,
                y_px: 33,
                width_px: 30,
                height_px: 30
            }
        );
    }

    #[test]
    fn texture_coordinates_span_each_faces_rectangle() {
        let layout = layout_sides(&[10.0, 25.0, 4.0], 12.0, 128).unwrap();
        for (i, r) in layout.faces.iter().enumerate() {
            let s = 128.0;
            assert_eq!(
                layout.uv(i, 0.0, 1.0),
                [r.x_px as f32 / s, r.y_px as f32 / s]
            );
            let (x1, y1) = (r.x_px + r.width_px, r.y_px + r.height_px);
            assert_eq!(layout.uv(i, 1.0, 0.0), [x1 as f32 / s, y1 as f32 / s]);
        }
    }

    #[test]
    fn too_many_faces_for_the_texture_keep_the_cluster_untextured() {
        // One texel and its border per face: 100 faces need more than 8 × 8 texels.
        assert_eq!(layout_sides(&[1.0; 100], 10.0, 8), None);
        assert!(!walls_fit(&[1.0; 100], 10.0, 8));
        assert!(walls_fit(&[1.0; 100], 10.0, 32));
        assert!(layout_sides(&[1.0; 4], 10.0, 8).is_some());
        assert_eq!(layout_sides(&[], 10.0, 64), None);
        assert_eq!(layout_sides(&[5.0], 0.0, 64), None);
        assert_eq!(layout_sides(&[5.0], f64::NAN, 64), None);
        assert_eq!(layout_sides(&[5.0], 3.0, 2), None);
    }

    #[test]
    fn degenerate_face_lengths_get_one_texel() {
        let lengths = [10.0, f64::NAN, -3.0, 0.0, f64::INFINITY, 10.0];
        let layout = layout_sides(&lengths, 5.0, 64).unwrap();
        for i in 1..5 {
            assert_eq!(layout.faces[i].width_px, 1);
        }
        assert!(layout.faces[0].width_px > 1);
    }

    proptest! {
        #![proptest_config(ProptestConfig { cases: 256, ..ProptestConfig::default() })]
        #[test]
        fn layouts_never_overlap_and_stay_proportional(
            lengths in prop::collection::vec(0.05f64..400.0, 1..60),
            height_m in 1.0f64..300.0,
            side_blocks in 1u32..128,
        ) {
            let side_px = side_blocks * 4;
            if let Some(layout) = layout_sides(&lengths, height_m, side_px) {
                assert_valid(&layout, &lengths, height_m);
            } else {
                // Only when one texel per face does not fit.
                prop_assert!(place(&lengths, height_m, f64::MIN_POSITIVE, side_px).is_none());
                prop_assert!(!walls_fit(&lengths, height_m, side_px));
            }
        }
    }
}
