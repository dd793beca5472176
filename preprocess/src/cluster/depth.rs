//! Depth reduction and balancing of the binary merge tree.
//!
//! This work is based on Yang et al. 2011 §3.3.2: the target depth is n' = log(n)/λ (λ > 1;
//! the paper uses λ = 1.5 and reports int(log(35 138)/1.5) ≈ 9, so citywalk takes log₂ and
//! rounds up); the n' − 1 thresholds sit in the largest jumps r_i = (d_{i+1} − d_i)/d_i of
//! the sorted merge distances, at (d_i + d_{i+1})/2; a node has at most δp = 2p children,
//! p = ⌈n^(1/n')⌉ (eq. 7).
//!
//! Balancing differs in form from the paper's inserted thresholds but not in effect: when a
//! condensed node would get more than δp children, its removed binary descendants are
//! restored largest merge distance first (the next largest jump inside that level; among
//! equal distances the one with the most buildings, which splits the level evenly) until
//! the node has at most δp children. Thresholds cannot shorten the caterpillars that
//! single-link chaining builds; those are re-paired before the hulls are merged
//! ([`super::rebalance`]), so the restored nodes form a balanced tree.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, VecDeque};

/// Children of every kept node of the reduced tree (indexed by binary node id; empty for
/// leaves and for binary nodes that were condensed away).
#[derive(Debug, Clone)]
pub struct Reduced {
    pub children: Vec<Vec<u32>>,
    pub kept: Vec<bool>,
    pub target_depth: u32,
}

/// Merge distance, buildings below, node id: the heap pops the largest distance, then the
/// largest subtree (equal distances: the split that keeps the children balanced).
#[derive(Debug, Clone, Copy)]
struct ByDist(f64, u32, u32);
impl PartialEq for ByDist {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for ByDist {}
impl PartialOrd for ByDist {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for ByDist {
    fn cmp(&self, o: &Self) -> Ordering {
        self.0
            .total_cmp(&o.0)
            .then(self.1.cmp(&o.1))
            .then(self.2.cmp(&o.2))
    }
}

/// Reduces a binary tree of `n` leaves (`bin_children[n + k]` are the two children of merge
/// k, `dist` the monotone merge distance per node, 0 for leaves). `force_keep` marks nodes
/// that must stay (the block roots). `lambda = None` keeps the binary tree.
pub fn reduce(
    n: usize,
    bin_children: &[[u32; 2]],
    dist: &[f64],
    force_keep: &[bool],
    lambda: Option<f64>,
) -> Reduced {
    let total = n + bin_children.len();
    let root = total - 1;
    let child = |x: usize| -> Option<[u32; 2]> { x.checked_sub(n).map(|k| bin_children[k]) };
    let Some(lambda) = lambda.filter(|l| l.is_finite() && *l > 0.0) else {
        let mut children = vec![Vec::new(); total];
        for (x, c) in children.iter_mut().enumerate().skip(n) {
            if let Some(cc) = child(x) {
                *c = cc.to_vec();
            }
        }
        return Reduced {
            children,
            kept: vec![true; total],
            target_depth: 0,
        };
    };
    let target = ((n.max(2) as f64).log2() / lambda).ceil().max(1.0);
    let mut sorted: Vec<f64> = dist[n..].to_vec();
    sorted.sort_by(f64::total_cmp);
    let eps = 1e-3;
    let mut jumps: Vec<(f64, usize)> = sorted
        .windows(2)
        .enumerate()
        .filter(|(_, w)| w[1] > w[0])
        .map(|(i, w)| ((w[1] - w[0]) / w[0].max(eps), i))
        .collect();
    jumps.sort_by(|x, y| y.0.total_cmp(&x.0).then(x.1.cmp(&y.1)));
    let mut thresholds: Vec<f64> = jumps
        .iter()
        .take((target as usize).saturating_sub(1))
        .map(|&(_, i)| 0.5 * (sorted[i] + sorted[i + 1]))
        .collect();
    thresholds.sort_by(f64::total_cmp);
    let class = |x: usize| thresholds.partition_point(|&t| t < dist[x]);
    let mut parent = vec![u32::MAX; total];
    for (k, c) in bin_children.iter().enumerate() {
        for &x in c {
            parent[x as usize] = (n + k) as u32;
        }
    }
    let mut kept: Vec<bool> = (0..total)
        .map(|x| {
            x < n
                || x == root
                || force_keep.get(x).copied().unwrap_or(false)
                || parent
                    .get(x)
                    .is_some_and(|&p| p != u32::MAX && class(x) < class(p as usize))
        })
        .collect();
    let p = (n.max(2) as f64).powf(1.0 / target).ceil() as usize;
    let cap = (2 * p).max(2);
    let mut size = vec![1u32; total];
    for (k, c) in bin_children.iter().enumerate() {
        size[n + k] = size[c[0] as usize] + size[c[1] as usize];
    }
    let mut children = vec![Vec::new(); total];
    let mut queue = VecDeque::from([root]);
    while let Some(x) = queue.pop_front() {
        let Some(cc) = child(x) else { continue };
        let mut heap: BinaryHeap<ByDist> = cc
            .iter()
            .map(|&c| ByDist(dist[c as usize], size[c as usize], c))
            .collect();
        let mut out = Vec::new();
        while let Some(ByDist(_, _, y)) = heap.pop() {
            let y = y as usize;
            if kept[y] {
                out.push(y as u32);
                continue;
            }
            let count = out.len() + heap.len() + 1;
            match child(y) {
                Some(yc) if count < cap => {
                    for c in yc {
                        heap.push(ByDist(dist[c as usize], size[c as usize], c));
                    }
                }
                _ => {
                    kept[y] = true;
                    out.push(y as u32);
                }
            }
        }
        out.sort_unstable();
        for &c in &out {
            queue.push_back(c as usize);
        }
        children[x] = out;
    }
    Reduced {
        children,
        kept,
        target_depth: target as u32,
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A caterpillar of `n` leaves merged one by one at distances 1, 2, ..., with a big jump.
    #[test]
    fn condenses_at_the_largest_jump_and_caps_children() {
        let n = 64;
        let mut bin = Vec::new();
        let mut dist = vec![0.0; n];
        let mut cur = 0u32;
        for k in 1..n {
            bin.push([cur, k as u32]);
            dist.push(if k < 32 {
                1.0 + k as f64 * 0.01
            } else {
                10.0 + k as f64 * 0.01
            });
            cur = (n + k - 1) as u32;
        }
        let r = reduce(n, &bin, &dist, &vec![false; 2 * n - 1], Some(1.5));
        let root = 2 * n - 2;
        // Every node's children are within the cap.
        let target = ((n as f64).log2() / 1.5).ceil();
        let cap = 2 * (n as f64).powf(1.0 / target).ceil() as usize;
        for c in &r.children {
            assert!(c.len() <= cap, "{} > {cap}", c.len());
        }
        // All leaves reachable exactly once.
        let mut seen = vec![0; 2 * n - 1];
        let mut stack = vec![root];
        while let Some(x) = stack.pop() {
            seen[x] += 1;
            stack.extend(r.children[x].iter().map(|&c| c as usize));
        }
        assert!(seen[..n].iter().all(|&s| s == 1));
        // Much shallower than the binary caterpillar (depth 63).
        let depth = |mut x: usize| {
            let mut parent = vec![usize::MAX; 2 * n - 1];
            for (p, c) in r.children.iter().enumerate() {
                for &cc in c {
                    parent[cc as usize] = p;
                }
            }
            let mut d = 0;
            while parent[x] != usize::MAX {
                x = parent[x];
                d += 1;
            }
            d
        };
        let max_depth = (0..n).map(depth).max().unwrap_or(0);
        assert!(max_depth < 40, "depth {max_depth}");
    }
}
