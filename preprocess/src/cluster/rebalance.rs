//! Re-pairing the long chains of single-link clustering into weight-balanced binary trees,
//! before the hulls are merged.
//!
//! This work is based on Yang et al. 2011 §3.3.2, which reduces the merge tree to
//! n' = log(n)/λ levels by distance thresholds and balances it to at most δp = 2p children
//! (p = ⌈n^(1/n')⌉) by inserting further thresholds. Thresholds cannot cut what single-link
//! *chaining* builds: a cluster that absorbs its neighbours one at a time (a row of houses at
//! nearly equal spacing; a district absorbing block after block across streets of similar
//! width) is a caterpillar, its spine as long as the number of absorbed clusters, and a level
//! condensed from it either has more than δp children or, once the cap restores the spine,
//! is as deep as the chain is long (Porto's centre: 45 levels). Equal distances (blocks whose
//! distances all inherit the same monotone maximum) leave no threshold at all.
//!
//! citywalk therefore rewrites every long *heavy path* of the binary tree (from a node down
//! through the child with more buildings; [`MIN_SPINE`] nodes or more): the subtrees hanging
//! off it are laid out along a Hilbert curve through their mean building centres (so
//! neighbours on the curve are neighbours in the city) and re-paired into a binary tree split
//! by building count (halves of equal weight), so each absorbed cluster ends up at depth
//! about log₂(W / w) below the top of the path. Only the pairing changes: the leaves and the
//! top node's set of buildings stay. A new node is given the largest merge distance at which
//! the chain absorbed one of its clusters, so distances stay monotone up the tree, and a
//! distance threshold cuts the chain into pieces no coarser than single-link's clusters (a
//! few balanced pieces instead of one: the LOD cut is never coarser). Paths never mix the
//! levels below and above the urban blocks, so no node below the block level spans two
//! blocks. The merges are emitted by distance, as single-link made them (between blocks Yang's
//! δa = a_ave/divisor follows the city's running mean cluster area), and their number is unchanged
//! (n − 1).

use super::linkage::Merge;

/// Heavy paths with fewer nodes than this are kept as they are: a balanced tree over their
/// absorbed clusters would hardly be shallower.
pub const MIN_SPINE: usize = 8;

/// A node of the rewritten tree: a leaf (building) or a new merge.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Ref {
    Leaf(u32),
    New(u32),
    /// An original inner node, to be replaced by the top of its own rewritten heavy path.
    Orig(u32),
}

/// Returns `merges` (leaves `0..n`, merge k creating node `n + k`) with every heavy path of
/// at least [`MIN_SPINE`] nodes re-paired by weight; still `n − 1` merges in an order where
/// children come before parents. `blocks[i]` is the urban block of building `i`.
pub fn rebalance(n: usize, merges: &[Merge], blocks: &[u32], centres: &[[f64; 2]]) -> Vec<Merge> {
    if merges.len() + 1 != n || n < 3 {
        return merges.to_vec();
    }
    let total = n + merges.len();
    let kids =
        |x: usize| -> Option<[u32; 2]> { x.checked_sub(n).map(|k| [merges[k].a, merges[k].b]) };
    let mut size = vec![1u32; total];
    let mut block: Vec<Option<u32>> = blocks.iter().map(|&b| Some(b)).collect();
    let mut dist = vec![0.0f64; total];
    // Sum of the building centres below each node (their mean places the node).
    let mut centre_sum: Vec<[f64; 2]> = (0..n)
        .map(|i| centres.get(i).copied().unwrap_or([0.0, 0.0]))
        .collect();
    for (k, m) in merges.iter().enumerate() {
        let (a, b) = (m.a as usize, m.b as usize);
        size[n + k] = size[a] + size[b];
        centre_sum.push([
            centre_sum[a][0] + centre_sum[b][0],
            centre_sum[a][1] + centre_sum[b][1],
        ]);
        block.push(match (block[a], block[b]) {
            (Some(x), Some(y)) if x == y => Some(x),
            _ => None,
        });
        dist[n + k] = m.distance.max(dist[a]).max(dist[b]);
    }
    // New merges: (left, right, distance).
    let mut new: Vec<(Ref, Ref, f64)> = Vec::with_capacity(merges.len());
    // The rewritten top of every original inner node that tops a heavy path.
    let mut top: Vec<Option<Ref>> = vec![None; total];
    let mut work = vec![total - 1];
    while let Some(x) = work.pop() {
        // The heavy path from x: p_0 = x, p_{i+1} = the heavier child of p_i, while it is an
        // inner node on the same side of the block level.
        let mut items_rev: Vec<(usize, f64)> = Vec::new(); // (light child, absorbing distance)
        let mut p = x;
        let bottom = loop {
            let Some([a, b]) = kids(p) else { break p };
            let (a, b) = (a as usize, b as usize);
            let (heavy, light) = if (size[a], a) >= (size[b], b) {
                (a, b)
            } else {
                (b, a)
            };
            items_rev.push((light, dist[p]));
            if kids(heavy).is_some() && block[heavy].is_some() == block[p].is_some() {
                p = heavy;
            } else {
                break heavy;
            }
        };
        // Absorption order: the bottom first, then the light children from the deepest up.
        let mut items: Vec<(Ref, u32)> = Vec::with_capacity(items_rev.len() + 1);
        let mut absorb: Vec<f64> = Vec::with_capacity(items_rev.len() + 1);
        let as_ref = |y: usize| {
            if y < n {
                Ref::Leaf(y as u32)
            } else {
                Ref::Orig(y as u32)
            }
        };
        for &(y, d) in std::iter::once(&(bottom, 0.0)).chain(items_rev.iter().rev()) {
            items.push((as_ref(y), size[y]));
            absorb.push(d);
            if y >= n {
                work.push(y);
            }
        }
        let root = if items.len() - 1 < MIN_SPINE {
            // Keep the chain.
            let mut cur = items[0].0;
            for (r, &(it, _)) in items.iter().enumerate().skip(1) {
                new.push((cur, it, absorb[r]));
                cur = Ref::New(new.len() as u32 - 1);
            }
            cur
        } else {
            // Spatial order (a Hilbert curve over the items' mean centres), so that the
            // pieces of the balanced tree are compact and their hulls merge across short gaps.
            let place = |r: &Ref| {
                let y = match *r {
                    Ref::Leaf(y) | Ref::Orig(y) => y as usize,
                    Ref::New(_) => return [0.0, 0.0],
                };
                let w = f64::from(size[y]);
                [centre_sum[y][0] / w, centre_sum[y][1] / w]
            };
            let (mut lo, mut hi) = ([f64::INFINITY; 2], [f64::NEG_INFINITY; 2]);
            for (r, _) in &items {
                let c = place(r);
                lo = [lo[0].min(c[0]), lo[1].min(c[1])];
                hi = [hi[0].max(c[0]), hi[1].max(c[1])];
            }
            let span = (hi[0] - lo[0]).max(hi[1] - lo[1]).max(1e-9);
            let mut order: Vec<(u64, usize)> = items
                .iter()
                .enumerate()
                .map(|(k, (r, _))| {
                    let c = place(r);
                    let q = |v: f64| (v * 65_535.0).clamp(0.0, 65_535.0) as u32;
                    (
                        hilbert_index(q((c[0] - lo[0]) / span), q((c[1] - lo[1]) / span)),
                        k,
                    )
                })
                .collect();
            order.sort_unstable();
            let items: Vec<(Ref, u32)> = order.iter().map(|&(_, k)| items[k]).collect();
            let absorb: Vec<f64> = order.iter().map(|&(_, k)| absorb[k]).collect();
            let mut prefix = vec![0u64; items.len() + 1];
            for (r, &(_, w)) in items.iter().enumerate() {
                prefix[r + 1] = prefix[r] + u64::from(w);
            }
            build_balanced(&items, &absorb, &prefix, 0, items.len() - 1, &mut new).0
        };
        top[x] = Some(root);
    }
    // Post-order (children first), each new node with its distance made monotone.
    let resolve = |r: Ref| -> Ref {
        match r {
            Ref::Orig(y) => top[y as usize].unwrap_or(Ref::Leaf(y)),
            other => other,
        }
    };
    let Some(root) = top[total - 1] else {
        return unbalanced(merges, "the last merge is not the root");
    };
    let mut eff = vec![0.0f64; new.len()];
    let mut post: Vec<u32> = Vec::with_capacity(new.len());
    let mut stack: Vec<(Ref, bool)> = vec![(root, false)];
    while let Some((r, expanded)) = stack.pop() {
        let Ref::New(k) = r else { continue };
        let (a, b, d) = new[k as usize];
        let (a, b) = (resolve(a), resolve(b));
        if !expanded {
            stack.push((r, true));
            stack.push((b, false));
            stack.push((a, false));
            continue;
        }
        let of = |c: Ref| match c {
            Ref::New(j) => eff[j as usize],
            _ => 0.0,
        };
        eff[k as usize] = d.max(of(a)).max(of(b));
        post.push(k);
    }
    // Merge order by distance (stable: children stay before parents), as single-link merged:
    // the hull stage's running mean cluster areas (Yang's a_ave) depend on it.
    post.sort_by(|&x, &y| eff[x as usize].total_cmp(&eff[y as usize]));
    let mut id_of_new: Vec<u32> = vec![u32::MAX; new.len()];
    let mut node_block: Vec<Option<u32>> = vec![None; new.len()];
    let mut out: Vec<Merge> = Vec::with_capacity(merges.len());
    for &k in &post {
        let (a, b, _) = new[k as usize];
        let (a, b) = (resolve(a), resolve(b));
        let id = |c: Ref| match c {
            Ref::Leaf(y) | Ref::Orig(y) => y,
            Ref::New(j) => id_of_new[j as usize],
        };
        let block_of = |c: Ref| match c {
            Ref::Leaf(y) => Some(blocks[y as usize]),
            Ref::New(j) => node_block[j as usize],
            Ref::Orig(_) => None,
        };
        let (ia, ib) = (id(a), id(b));
        if ia == u32::MAX || ib == u32::MAX {
            return unbalanced(merges, "a node is used before it is made");
        }
        let (ba, bb) = (block_of(a), block_of(b));
        node_block[k as usize] = match (ba, bb) {
            (Some(x), Some(y)) if x == y => Some(x),
            _ => None,
        };
        id_of_new[k as usize] = (n + out.len()) as u32;
        out.push(Merge {
            a: ia,
            b: ib,
            distance: eff[k as usize],
            within_block: ba.is_some() && ba == bb,
        });
    }
    if out.len() == merges.len() {
        out
    } else {
        unbalanced(merges, "the re-paired tree lost or gained merges")
    }
}

/// The merges as they were, when re-pairing met an inconsistency it cannot repair (a bug, not
/// an input problem): logged, never silent.
fn unbalanced(merges: &[Merge], why: &str) -> Vec<Merge> {
    tracing::warn!(why, "cluster tree rebalancing skipped");
    merges.to_vec()
}

/// A binary tree over `items[lo..=hi]` split where the building counts balance; returns its
/// root and the largest distance at which one of its items was absorbed (`absorb`, 0 for the
/// path's bottom).
fn build_balanced(
    items: &[(Ref, u32)],
    absorb: &[f64],
    prefix: &[u64],
    lo: usize,
    hi: usize,
    new: &mut Vec<(Ref, Ref, f64)>,
) -> (Ref, f64) {
    if lo == hi {
        return (items[lo].0, absorb[lo]);
    }
    // Split after m (lo ≤ m < hi) so that both halves weigh about half.
    let half = (prefix[lo] + prefix[hi + 1]) / 2;
    let m = (prefix[lo + 1..=hi].partition_point(|&p| p <= half) + lo).clamp(lo, hi - 1);
    let (l, dl) = build_balanced(items, absorb, prefix, lo, m, new);
    let (r, dr) = build_balanced(items, absorb, prefix, m + 1, hi, new);
    let d = dl.max(dr);
    new.push((l, r, d));
    (Ref::New(new.len() as u32 - 1), d)
}

/// Position of cell (x, y) along a Hilbert curve over a 2¹⁶ × 2¹⁶ grid.
fn hilbert_index(x: u32, y: u32) -> u64 {
    let (mut x, mut y) = (x & 0xffff, y & 0xffff);
    let mut d = 0u64;
    let mut s = 1u32 << 15;
    while s > 0 {
        let rx = u32::from(x & s > 0);
        let ry = u32::from(y & s > 0);
        d += u64::from(s) * u64::from(s) * u64::from((3 * rx) ^ ry);
        if ry == 0 {
            if rx == 1 {
                x = 0xffff - x;
                y = 0xffff - y;
            }
            std::mem::swap(&mut x, &mut y);
        }
        s >>= 1;
    }
    d
}

#[cfg(test)]
mod tests {
    use super::*;

    fn depth_of(n: usize, merges: &[Merge]) -> usize {
        let total = n + merges.len();
        let mut depth = vec![0usize; total];
        for k in (0..merges.len()).rev() {
            let m = merges[k];
            depth[m.a as usize] = depth[n + k] + 1;
            depth[m.b as usize] = depth[n + k] + 1;
        }
        depth.into_iter().max().unwrap_or(0)
    }

    fn leaves_of(n: usize, merges: &[Merge], x: usize) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![x];
        while let Some(y) = stack.pop() {
            if y < n {
                out.push(y as u32);
            } else {
                let m = merges[y - n];
                stack.extend([m.a as usize, m.b as usize]);
            }
        }
        out.sort_unstable();
        out
    }

    #[test]
    fn a_caterpillar_becomes_balanced_and_keeps_monotone_distances() {
        let n = 256;
        let mut merges = Vec::new();
        let mut cur = 0u32;
        for k in 1..n {
            merges.push(Merge {
                a: cur,
                b: k as u32,
                distance: 1.0 + (k % 5) as f64 * 0.1,
                within_block: true,
            });
            cur = (n + k - 1) as u32;
        }
        assert_eq!(depth_of(n, &merges), n - 1);
        let centres: Vec<[f64; 2]> = (0..n).map(|i| [i as f64, 0.0]).collect();
        let r = rebalance(n, &merges, &vec![0; n], &centres);
        assert_eq!(r.len(), n - 1);
        assert!(depth_of(n, &r) <= 10, "depth {}", depth_of(n, &r));
        // Children before parents, every leaf once, distances monotone.
        let mut dist = vec![0.0f64; n + r.len()];
        let mut seen = vec![0u32; n + r.len()];
        for (k, m) in r.iter().enumerate() {
            assert!((m.a as usize) < n + k && (m.b as usize) < n + k);
            seen[m.a as usize] += 1;
            seen[m.b as usize] += 1;
            assert!(m.distance >= dist[m.a as usize] && m.distance >= dist[m.b as usize]);
            dist[n + k] = m.distance;
        }
        assert!(seen[..n + r.len() - 1].iter().all(|&s| s == 1));
        assert_eq!(leaves_of(n, &r, n + r.len() - 1).len(), n);
    }

    #[test]
    fn paths_do_not_mix_the_levels_below_and_above_blocks() {
        // Two blocks of 20 caterpillar-merged buildings, joined at the top.
        let n = 40;
        let blocks: Vec<u32> = (0..n as u32).map(|i| i / 20).collect();
        let mut merges = Vec::new();
        for half in 0..2u32 {
            let base = half * 20;
            let mut cur = base;
            for k in 1..20u32 {
                merges.push(Merge {
                    a: cur,
                    b: base + k,
                    distance: f64::from(k),
                    within_block: true,
                });
                cur = (n + merges.len() - 1) as u32;
            }
        }
        let (ra, rb) = ((n + 18) as u32, (n + 37) as u32);
        merges.push(Merge {
            a: ra,
            b: rb,
            distance: 50.0,
            within_block: false,
        });
        let centres: Vec<[f64; 2]> = (0..n).map(|i| [(i % 20) as f64, (i / 20) as f64]).collect();
        let r = rebalance(n, &merges, &blocks, &centres);
        for (k, m) in r.iter().enumerate() {
            let ls = leaves_of(n, &r, n + k);
            let mixed = ls
                .iter()
                .any(|&l| blocks[l as usize] != blocks[ls[0] as usize]);
            assert_eq!(mixed, !m.within_block, "merge {k}");
            if mixed {
                assert_eq!(k, r.len() - 1, "only the root spans both blocks");
            }
        }
        assert!(depth_of(n, &r) < 19);
    }
}
