//! The LOD's pixel bound, checked: a frame drawn through a cut keeps the geometric criterion's
//! bound when every pixel it gets wrong lies within `tolerance + 1` px of an edge of the
//! full-detail frame (a cluster mesh within `tolerance` px of its buildings moves their edges by
//! at most that much; the extra pixel is rasterisation). `bound_violations` is the share of the
//! differing pixels farther than that.
//!
//! Edges are where the full-detail frame changes from one pixel to its right or lower
//! neighbour: a different id in the oracle's id image (another building, or building against
//! background), or a colour step above [`EDGE_COLOUR_STEP`]. Distances to them are exact
//! Euclidean distances between pixel centres, after Felzenszwalb and Huttenlocher, *Distance
//! transforms of sampled functions* (Theory of Computing 8, 2012), §2–3: the lower envelope of
//! parabolas in one dimension, once down the columns and once along the rows.

use crate::pixel_error::luma;

/// A colour step (8-bit, any channel) between neighbours that makes an edge. Shading is flat
/// per face and fog changes by a level or two between neighbours, so smooth gradients stay
/// below it while a face, material or ground-tile boundary exceeds it.
pub const EDGE_COLOUR_STEP: u8 = 8;

/// Per pixel of the full-detail frame, the distance (px) to its nearest edge pixel.
#[derive(Debug, Clone, PartialEq)]
pub struct EdgeDistance {
    width: usize,
    /// Squared distances, row-major; `f32::INFINITY` when the frame has no edge at all.
    dist2: Vec<f32>,
}

/// Differing pixels of one frame and how many of them break the bound.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default, serde::Serialize)]
pub struct BoundCheck {
    /// Pixels whose grey level differs from the full-detail frame.
    pub differing: u64,
    /// Of them, those farther than the bound from every edge of the full-detail frame.
    pub beyond: u64,
}

/// The pixels of several frames together.
impl std::iter::Sum for BoundCheck {
    fn sum<I: Iterator<Item = BoundCheck>>(frames: I) -> BoundCheck {
        frames.fold(BoundCheck::default(), |a, b| BoundCheck {
            differing: a.differing + b.differing,
            beyond: a.beyond + b.beyond,
        })
    }
}

impl BoundCheck {
    /// `beyond / differing`, 0 when nothing differs.
    pub fn share(self) -> f64 {
        if self.differing == 0 {
            0.0
        } else {
            self.beyond as f64 / self.differing as f64
        }
    }
}

impl EdgeDistance {
    /// The edges of the full-detail frame `rgba` (RGBA8) with its id image `ids`, both
    /// `width × height`, row-major.
    ///
    /// # Panics
    /// If the buffers do not match the size (both come from the same run at one size).
    pub fn of_frame(rgba: &[u8], ids: &[u32], width: u32, height: u32) -> EdgeDistance {
        let (w, h) = (width as usize, height as usize);
        assert_eq!(rgba.len(), w * h * 4, "colour image size");
        assert_eq!(ids.len(), w * h, "id image size");
        let differs = |a: usize, b: usize| {
            ids[a] != ids[b]
                || (0..3).any(|c| rgba[4 * a + c].abs_diff(rgba[4 * b + c]) > EDGE_COLOUR_STEP)
        };
        let mut edge = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let i = y * w + x;
                for j in [(x + 1 < w).then_some(i + 1), (y + 1 < h).then_some(i + w)]
                    .into_iter()
                    .flatten()
                {
                    if differs(i, j) {
                        edge[i] = true;
                        edge[j] = true;
                    }
                }
            }
        }
        let mut dist2: Vec<f32> = edge
            .iter()
            .map(|&e| if e { 0.0 } else { f32::INFINITY })
            .collect();
        let mut column = vec![0.0f32; h];
        let mut out = vec![0.0f32; w.max(h)];
        for x in 0..w {
            for y in 0..h {
                column[y] = dist2[y * w + x];
            }
            squared_distance_1d(&column, &mut out[..h]);
            for y in 0..h {
                dist2[y * w + x] = out[y];
            }
        }
        for row in dist2.chunks_exact_mut(w.max(1)) {
            squared_distance_1d(row, &mut out[..w]);
            row.copy_from_slice(&out[..w]);
        }
        EdgeDistance { width: w, dist2 }
    }

    /// Distance (px) from pixel `(x, y)` to the nearest edge.
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.dist2[y * self.width + x].sqrt()
    }

    /// Compares `frame` with the full-detail `reference` (RGBA8, the size of this map): every
    /// pixel whose grey level differs, and those of them farther than `bound_px` from an edge.
    pub fn check(&self, reference: &[u8], frame: &[u8], bound_px: f32) -> BoundCheck {
        assert_eq!(reference.len(), frame.len(), "images differ in size");
        assert_eq!(
            reference.len(),
            self.dist2.len() * 4,
            "not this frame's size"
        );
        let bound2 = bound_px * bound_px;
        let mut out = BoundCheck::default();
        for ((a, b), d2) in reference
            .chunks_exact(4)
            .zip(frame.chunks_exact(4))
            .zip(&self.dist2)
        {
            if luma(a) != luma(b) {
                out.differing += 1;
                if *d2 > bound2 {
                    out.beyond += 1;
                }
            }
        }
        out
    }
}

/// Felzenszwalb and Huttenlocher 2012, Algorithm 1 (`DT(f)`): `out[q] = min_p (q − p)² + f[p]`,
/// by the lower envelope of the parabolas rooted at the finite samples of `f`.
fn squared_distance_1d(f: &[f32], out: &mut [f32]) {
    // Roots of the envelope's parabolas and where each takes over.
    let mut roots: Vec<usize> = Vec::with_capacity(f.len());
    let mut starts: Vec<f32> = Vec::with_capacity(f.len());
    for (q, &fq) in f.iter().enumerate() {
        if !fq.is_finite() {
            continue;
        }
        let mut s = f32::NEG_INFINITY;
        while let Some(&p) = roots.last() {
            // Intersection of the parabolas of p and q.
            let (pf, qf) = (p as f32, q as f32);
            s = ((fq + qf * qf) - (f[p] + pf * pf)) / (2.0 * (qf - pf));
            if s <= *starts.last().unwrap_or(&f32::NEG_INFINITY) {
                roots.pop();
                starts.pop();
                s = f32::NEG_INFINITY;
            } else {
                break;
            }
        }
        roots.push(q);
        starts.push(s);
    }
    let mut k = 0;
    for (q, slot) in out.iter_mut().enumerate() {
        if roots.is_empty() {
            *slot = f32::INFINITY;
            continue;
        }
        while k + 1 < roots.len() && starts[k + 1] < q as f32 {
            k += 1;
        }
        let p = roots[k];
        let d = q as f32 - p as f32;
        *slot = d * d + f[p];
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Brute-force squared distance to the nearest zero of `f`.
    fn brute(f: &[f32]) -> Vec<f32> {
        (0..f.len())
            .map(|q| {
                (0..f.len())
                    .filter(|&p| f[p].is_finite())
                    .map(|p| (q as f32 - p as f32).powi(2) + f[p])
                    .fold(f32::INFINITY, f32::min)
            })
            .collect()
    }

    #[test]
    fn one_dimensional_transform_matches_brute_force() {
        let inf = f32::INFINITY;
        for f in [
            vec![inf, 0.0, inf, inf, inf, 0.0, inf],
            vec![0.0, inf, inf, inf, inf, inf, inf, inf],
            vec![inf, inf, 4.0, inf, 1.0, inf, 9.0, inf, inf],
            vec![inf, inf, inf],
            vec![0.0],
        ] {
            let mut out = vec![0.0; f.len()];
            squared_distance_1d(&f, &mut out);
            assert_eq!(out, brute(&f), "{f:?}");
        }
    }

    /// A `w × h` frame: grey background, one id, with a 4 × 3 block of another id and colour
    /// at `(bx, by)`.
    fn frame_with_block(w: usize, h: usize, bx: usize, by: usize) -> (Vec<u8>, Vec<u32>) {
        let mut rgba = vec![100u8; w * h * 4];
        let mut ids = vec![0u32; w * h];
        for y in by..by + 3 {
            for x in bx..bx + 4 {
                ids[y * w + x] = 7;
                rgba[4 * (y * w + x)..4 * (y * w + x) + 3].copy_from_slice(&[200, 50, 50]);
            }
        }
        (rgba, ids)
    }

    #[test]
    fn distances_are_euclidean_to_the_block_outline() {
        let (w, h) = (23, 17);
        let (rgba, ids) = frame_with_block(w, h, 10, 6);
        let map = EdgeDistance::of_frame(&rgba, &ids, w as u32, h as u32);
        // Edge pixels: both sides of the block's outline.
        assert_eq!(map.at(10, 6), 0.0);
        assert_eq!(map.at(9, 7), 0.0);
        // Brute force against the edge set, at every pixel.
        let edge = |x: usize, y: usize| {
            let i = y * w + x;
            let n = [(x + 1 < w).then_some(i + 1), (y + 1 < h).then_some(i + w)];
            let p = [(x > 0).then(|| i - 1), (y > 0).then(|| i - w)];
            n.into_iter().chain(p).flatten().any(|j| ids[j] != ids[i])
        };
        for y in 0..h {
            for x in 0..w {
                let want = (0..h)
                    .flat_map(|v| (0..w).map(move |u| (u, v)))
                    .filter(|&(u, v)| edge(u, v))
                    .map(|(u, v)| (x as f32 - u as f32).powi(2) + (y as f32 - v as f32).powi(2))
                    .fold(f32::INFINITY, f32::min)
                    .sqrt();
                assert!((map.at(x, y) - want).abs() < 1e-4, "({x}, {y})");
            }
        }
    }

    #[test]
    fn differing_pixels_far_from_edges_break_the_bound() {
        let (w, h) = (31, 21);
        let (reference, ids) = frame_with_block(w, h, 12, 8);
        let map = EdgeDistance::of_frame(&reference, &ids, w as u32, h as u32);
        // The block moved one pixel right: every differing pixel is on or next to an edge.
        let (moved, _) = frame_with_block(w, h, 13, 8);
        let near = map.check(&reference, &moved, 2.0);
        assert_eq!((near.differing, near.beyond), (6, 0));
        // A block drawn far from every edge of the reference breaks the bound with all of its
        // twelve pixels.
        let (far, _) = frame_with_block(w, h, 1, 15);
        let mut far_only = reference.clone();
        for (i, px) in far.chunks_exact(4).enumerate() {
            if px[0] == 200 {
                far_only[4 * i..4 * i + 4].copy_from_slice(px);
            }
        }
        let broken = map.check(&reference, &far_only, 2.0);
        assert_eq!((broken.differing, broken.beyond), (12, 12));
        assert_eq!(broken.share(), 1.0);
        assert_eq!(map.check(&reference, &reference, 2.0).share(), 0.0);
    }
}
