//! Which clusters share a texture budget, and how many texels each gets.
//!
//! Chang et al. 2008 §7: the clusters are sorted by the negative-space area of their meshes,
//! ascending, and cut into bins of n/2, n/4, … clusters (halves rounded up), the last holding
//! one; every bin gets the same texture resolution per view (Chang: 1024 × 1024), shared
//! equally by its clusters. The coarse clusters, few and large, which an overview draws, get
//! the most texels each; the fine ones, drawn only close by where the buildings themselves
//! soon replace them, the fewest. Each cluster's texture is a square whose side is a multiple
//! of [`TEXEL_BLOCK`] (block-compressed formats store 4 × 4 blocks; Chang's card needed sides
//! divisible by four for the same reason). No cluster gets less than [`MIN_CELL_PX`] on a
//! side: where a bin holds so many clusters that Chang's budget would give each fewer texels
//! (a large city's first bins), the bin grows past the budget instead,
//! since a cell of a few texels cannot hold one texel per wall with its border, and the
//! cluster would stay untextured.

/// Chang et al. 2008 §7's default resolution of every bin's texture, per view.
pub const CHANG_BIN_SIDE_PX: u32 = 1024;

/// Texture sides are multiples of this many texels.
pub const TEXEL_BLOCK: u32 = 4;

/// The least side of a cluster's texture per view, in texels: room for 25 walls of one texel
/// and their borders (five rows of five).
pub const MIN_CELL_PX: u32 = 16;

/// One cluster's share of its bin.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct ClusterTexels {
    /// The bin, 0 for the first (the half of the clusters with the least negative space).
    pub bin: u32,
    /// The side of the cluster's square texture per view, in texels: a multiple of
    /// [`TEXEL_BLOCK`], at least [`MIN_CELL_PX`].
    pub side_px: u32,
}

/// The bin and texture side of each cluster, given each one's negative-space area (m²) and
/// the side of a bin's texture (`bin_side_px`, [`CHANG_BIN_SIDE_PX`] by default). Equal areas
/// keep the clusters' order; a NaN area sorts last. The result is in the clusters' order.
pub fn texture_bins(negative_space_m2: &[f64], bin_side_px: u32) -> Vec<ClusterTexels> {
    let mut order: Vec<usize> = (0..negative_space_m2.len()).collect();
    order.sort_by(|&a, &b| {
        let (x, y) = (negative_space_m2[a], negative_space_m2[b]);
        // NaN last, whatever its sign bit.
        (x.is_nan(), x)
            .partial_cmp(&(y.is_nan(), y))
            .unwrap_or(std::cmp::Ordering::Equal)
    });
    let bin_texels = u64::from(bin_side_px) * u64::from(bin_side_px);
    let mut out = vec![
        ClusterTexels {
            bin: 0,
            side_px: TEXEL_BLOCK
        };
        order.len()
    ];
    let (mut start, mut bin) = (0usize, 0u32);
    while start < order.len() {
        let remaining = order.len() - start;
        let size = remaining.div_ceil(2);
        let side_px = block_side(bin_texels / size as u64);
        for &cluster in &order[start..start + size] {
            out[cluster] = ClusterTexels { bin, side_px };
        }
        start += size;
        bin += 1;
    }
    out
}

/// The largest square side, a multiple of [`TEXEL_BLOCK`], whose area is at most `texels`,
/// and never less than [`MIN_CELL_PX`].
fn block_side(texels: u64) -> u32 {
    let side = texels.isqrt();
    let blocks = side / u64::from(TEXEL_BLOCK);
    let side = u32::try_from(blocks * u64::from(TEXEL_BLOCK)).unwrap_or(u32::MAX - 3);
    side.max(MIN_CELL_PX)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn bins_halve_and_end_with_one_cluster() {
        // 8 clusters: bins of 4, 2, 1, 1.
        let areas: Vec<f64> = (0..8).map(|i| f64::from(7 - i) * 10.0).collect();
        let texels = texture_bins(&areas, 1024);
        let mut sizes = [0usize; 4];
        for t in &texels {
            sizes[t.bin as usize] += 1;
        }
        assert_eq!(sizes, [4, 2, 1, 1]);
        // Ascending negative space: the largest area (cluster 0) is alone in the last bin and
        // has the whole texture; the smallest four share the first.
        assert_eq!(
            texels[0],
            ClusterTexels {
                bin: 3,
                side_px: 1024
            }
        );
        assert_eq!(texels[1].bin, 2);
        assert!(texels[4..].iter().all(|t| t.bin == 0 && t.side_px == 512));
        assert_eq!(
            texels[2].side_px, 724,
            "1024²/2 texels: a side of 724.08, in blocks"
        );
    }

    #[test]
    fn every_bin_stays_within_its_budget_and_sides_are_whole_blocks() {
        for n in [1usize, 2, 3, 7, 100, 1001, 10_000] {
            let areas: Vec<f64> = (0..n).map(|i| ((i * 7919) % 97) as f64).collect();
            let texels = texture_bins(&areas, 1024);
            let bins = texels.iter().map(|t| t.bin).max().unwrap() as usize + 1;
            assert!(
                bins <= (n as f64).log2().floor() as usize + 1,
                "{n}: {bins} bins"
            );
            let mut used = vec![0u64; bins];
            for t in &texels {
                assert_eq!(t.side_px % TEXEL_BLOCK, 0);
                assert!(t.side_px >= MIN_CELL_PX);
                used[t.bin as usize] += u64::from(t.side_px).pow(2);
            }
            for (bin, texels_used) in used.iter().enumerate() {
                // The least cell each is the floor: a bin of more clusters than 1024²/256
                // exceeds the budget.
                let clusters = texels.iter().filter(|t| t.bin as usize == bin).count() as u64;
                let floor = clusters * u64::from(MIN_CELL_PX).pow(2);
                assert!(*texels_used <= (1024 * 1024).max(floor), "{n}: bin {bin}");
            }
            // A bin further on never gives a cluster less than an earlier one.
            for a in &texels {
                for b in texels.iter().filter(|b| b.bin > a.bin) {
                    assert!(b.side_px >= a.side_px);
                }
            }
        }
    }

    #[test]
    fn more_negative_space_never_means_fewer_texels() {
        let areas = [5.0, f64::NAN, 0.0, 120.0, 5.0, 3.5, 1e9, 42.0, 0.5];
        let texels = texture_bins(&areas, 256);
        for (i, a) in areas.iter().enumerate() {
            for (j, b) in areas.iter().enumerate() {
                if a < b {
                    assert!(texels[i].side_px <= texels[j].side_px, "{a} against {b}");
                }
            }
        }
        // The NaN sorts last: the whole texture.
        assert_eq!(
            texels[1],
            ClusterTexels {
                bin: 3,
                side_px: 256
            }
        );
    }

    #[test]
    fn no_clusters_no_bins() {
        assert!(texture_bins(&[], 1024).is_empty());
    }
}
