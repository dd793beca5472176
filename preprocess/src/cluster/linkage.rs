//! Single-link clustering of building footprints into a binary merge tree.
//!
//! This work is based on:
//! - Chang et al. 2008 §4 eq. 1: `d(C1,C2) = min size(C1)·size(C2)/avgClusterSize² · d(x,y)`
//!   over building centres x ∈ C1, y ∈ C2 (avgClusterSize: mean size of the current non-leaf
//!   clusters).
//! - Yang et al. 2011 §3.1 eq. 1–2: adjacent distance `d = d_min·(1 − N·λ)`, λ = 0.6,
//!   `N = (l1'/l1 + l2'/l2)/2` from the adjacent sides of the two footprints.
//!
//! Not the papers' O(n²)–O(n³): candidate pairs are the edges of a Delaunay triangulation
//! (spade) of the building centres (Chang) or footprint vertices (Yang). For plain single-link
//! on centre distances this is exact (the minimum spanning tree, which single-link follows, is
//! a subgraph of the Delaunay triangulation). With Chang's size weights it is an approximation
//! we chose: two clusters are candidates only when a Delaunay edge joins them (neighbours), so
//! a weighted pair with no Delaunay edge between them never merges directly. Merges come from a binary heap with version stamps (lazy deletion);
//! only the merged cluster's pairs are re-keyed. Chang's factor `1/avgClusterSize²` is common
//! to all pairs at any moment, so the heap orders by `size·size·d` (exact, no stale keys) and
//! the factor is applied to the recorded merge distance.
//!
//! Ties: single-link clustering leaves the order of merges at equal distances open (the
//! clusters at any distance threshold are the same whatever the order). Rows of houses that
//! share walls are all at adjacent distance 0; merged oldest-first they form a caterpillar
//! (the cluster grows by one house per merge, a tree as deep as the row is long) that no
//! distance threshold of the depth reduction can cut. Among equal distances the pair with the
//! fewest buildings therefore merges first, which pairs houses, then pairs of pairs: a
//! balanced binary tree for each run of equal distances.
//!
//! Lynch's paths: clustering runs inside each urban block first (one triangulation per block),
//! then between blocks, so no cluster below the block level holds buildings of two blocks.

use std::cmp::Ordering;
use std::collections::{BinaryHeap, HashMap};

use citywalk_scenes::cluster_tree::ClusterDistance;
use rayon::prelude::*;
use spade::{DelaunayTriangulation, HasPosition, Point2, Triangulation};

use super::ClusterError;
use super::geom::{Pt, Side, locate, point_segment_distance, rings_touch};
use super::leaves::Leaf;

/// One step of the agglomeration: nodes `a` and `b` (leaves are `0..n`, the k-th merge creates
/// node `n + k`) become one cluster at `distance`.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Merge {
    pub a: u32,
    pub b: u32,
    pub distance: f64,
    /// Whether both sides are in the same urban block.
    pub within_block: bool,
}

#[derive(Debug, Clone, Copy)]
struct Site {
    pos: Point2<f64>,
    owner: u32,
}

impl HasPosition for Site {
    type Scalar = f64;
    fn position(&self) -> Point2<f64> {
        self.pos
    }
}

/// Building pairs that are neighbours in a Delaunay triangulation of their sites.
fn delaunay_pairs(sites: Vec<Site>, out: &mut Vec<(u32, u32)>) -> Result<(), ClusterError> {
    if sites.len() < 2 {
        return Ok(());
    }
    let dt = DelaunayTriangulation::<Site>::bulk_load(sites)
        .map_err(|e| ClusterError::Triangulation(format!("{e:?}")))?;
    for e in dt.undirected_edges() {
        let [u, v] = e.vertices();
        let (a, b) = (u.data().owner, v.data().owner);
        if a != b {
            out.push((a.min(b), a.max(b)));
        }
    }
    Ok(())
}

fn sites_of(leaves: &[Leaf], verts: &[Pt], members: &[u32], mode: ClusterDistance) -> Vec<Site> {
    let mut sites = Vec::new();
    for &m in members {
        let leaf = &leaves[m as usize];
        match mode {
            ClusterDistance::ChangSizeWeighted => sites.push(Site {
                pos: Point2::new(leaf.centre[0], leaf.centre[1]),
                owner: m,
            }),
            ClusterDistance::YangAdjacent => {
                sites.extend(leaf.ring.iter().map(|&i| {
                    let p = verts[i as usize];
                    Site {
                        pos: Point2::new(p[0], p[1]),
                        owner: m,
                    }
                }));
                sites.push(Site {
                    pos: Point2::new(leaf.centre[0], leaf.centre[1]),
                    owner: m,
                });
            }
        }
    }
    sites
}

/// Smaller (undirected) angle between the lines of two segments, radians in [0, π/2].
fn line_angle(a: (Pt, Pt), b: (Pt, Pt)) -> f64 {
    let u = [a.1[0] - a.0[0], a.1[1] - a.0[1]];
    let v = [b.1[0] - b.0[0], b.1[1] - b.0[1]];
    let cross = u[0] * v[1] - u[1] * v[0];
    let dot = u[0] * v[0] + u[1] * v[1];
    let ang = cross.abs().atan2(dot.abs());
    if ang.is_finite() { ang } else { 0.0 }
}

fn seg_len(s: (Pt, Pt)) -> f64 {
    ((s.1[0] - s.0[0]).powi(2) + (s.1[1] - s.0[1]).powi(2)).sqrt()
}

/// Length of the part of `onto` covered by the orthogonal projection of `s`.
fn projected_overlap(s: (Pt, Pt), onto: (Pt, Pt)) -> f64 {
    let d = [onto.1[0] - onto.0[0], onto.1[1] - onto.0[1]];
    let len = (d[0] * d[0] + d[1] * d[1]).sqrt();
    if len == 0.0 {
        return 0.0;
    }
    let t = |p: Pt| ((p[0] - onto.0[0]) * d[0] + (p[1] - onto.0[1]) * d[1]) / len;
    let (t0, t1) = (t(s.0), t(s.1));
    let (lo, hi) = (t0.min(t1).max(0.0), t0.max(t1).min(len));
    (hi - lo).max(0.0)
}

/// Yang et al. 2011 §3.1 eq. 1–2: the adjacent distance between two rings. 0 when they touch,
/// overlap or one contains the other. λ = 0.6 by default (§3.1).
pub fn adjacent_distance(verts: &[Pt], r1: &[u32], r2: &[u32], lambda: f64) -> f64 {
    if r1.len() < 2 || r2.len() < 2 || rings_touch(verts, r1, r2) {
        return 0.0;
    }
    if locate(verts, r2, verts[r1[0] as usize]) != Side::Outside
        || locate(verts, r1, verts[r2[0] as usize]) != Side::Outside
    {
        return 0.0;
    }
    let seg = |r: &[u32], i: usize| -> (Pt, Pt) {
        (
            verts[r[i % r.len()] as usize],
            verts[r[(i + 1) % r.len()] as usize],
        )
    };
    // Closest vertex–edge configuration, both ways.
    let mut best = (f64::INFINITY, 0usize, 0usize, false);
    for (flip, (p, q)) in [(false, (r1, r2)), (true, (r2, r1))] {
        for i in 0..p.len() {
            let v = verts[p[i] as usize];
            for j in 0..q.len() {
                let s = seg(q, j);
                let d = point_segment_distance(v, s.0, s.1);
                if d < best.0 {
                    best = (d, i, j, flip);
                }
            }
        }
    }
    let (d_min, i, j, flip) = best;
    let (p, q) = if flip { (r2, r1) } else { (r1, r2) };
    let n = p.len();
    // Adjacent sides (§3.1.1.1): the side at vertex i forming the smaller angle with the
    // opposite side; at a vertex–vertex contact the opposite side is chosen the same way.
    let v = verts[p[i] as usize];
    let s = seg(q, j);
    let m = q.len();
    let tol = d_min * 1e-12 + 1e-15;
    let s2_options: Vec<(Pt, Pt)> = if seg_len((v, s.0)) <= d_min + tol {
        vec![s, seg(q, j + m - 1)]
    } else if seg_len((v, s.1)) <= d_min + tol {
        vec![s, seg(q, j + 1)]
    } else {
        vec![s]
    };
    let s1_options = [seg(p, i), seg(p, i + n - 1)];
    let mut pair = (s1_options[0], s2_options[0], f64::INFINITY);
    for s1 in s1_options {
        for &s2 in &s2_options {
            let a = line_angle(s1, s2);
            if a < pair.2 {
                pair = (s1, s2, a);
            }
        }
    }
    let (s1, s2, _) = pair;
    let (l1, l2) = (seg_len(s1), seg_len(s2));
    if l1 == 0.0 || l2 == 0.0 {
        return d_min;
    }
    let n_ratio = 0.5 * (projected_overlap(s2, s1) / l1 + projected_overlap(s1, s2) / l2);
    d_min * (1.0 - n_ratio.clamp(0.0, 1.0) * lambda)
}

#[derive(Debug, Clone, Copy)]
struct Entry {
    key: f64,
    /// Buildings in both clusters: among equal keys the smallest pair merges first.
    size: u32,
    a: u32,
    b: u32,
    va: u32,
    vb: u32,
}

impl PartialEq for Entry {
    fn eq(&self, o: &Self) -> bool {
        self.cmp(o) == Ordering::Equal
    }
}
impl Eq for Entry {}
impl PartialOrd for Entry {
    fn partial_cmp(&self, o: &Self) -> Option<Ordering> {
        Some(self.cmp(o))
    }
}
impl Ord for Entry {
    fn cmp(&self, o: &Self) -> Ordering {
        // Reversed: the heap pops the smallest key; ties by size, then ids (determinism).
        o.key
            .total_cmp(&self.key)
            .then(o.size.cmp(&self.size))
            .then(o.a.cmp(&self.a))
            .then(o.b.cmp(&self.b))
    }
}

/// Chang's avgClusterSize: the sum of sizes and the count of the current non-leaf clusters.
#[derive(Debug, Clone, Copy, Default)]
struct InnerSizes {
    sum: f64,
    count: f64,
}

impl InnerSizes {
    /// The distance a merge of clusters of `sizes` at `base` records (Chang eq. 1 with the
    /// average taken before the merge; `base` itself for Yang's distance).
    fn recorded(&self, mode: ClusterDistance, sizes: [u32; 2], base: f64) -> f64 {
        match mode {
            ClusterDistance::ChangSizeWeighted => {
                let avg = if self.count > 0.0 {
                    self.sum / self.count
                } else {
                    1.0
                };
                f64::from(sizes[0]) * f64::from(sizes[1]) * base / (avg * avg)
            }
            ClusterDistance::YangAdjacent => base,
        }
    }

    /// The two clusters of `sizes` are now one.
    fn merged(&mut self, sizes: [u32; 2]) {
        for s in sizes {
            if s > 1 {
                self.sum -= f64::from(s);
                self.count -= 1.0;
            }
        }
        self.sum += f64::from(sizes[0] + sizes[1]);
        self.count += 1.0;
    }
}

/// A merge as the agglomeration took it: its place in the heap's order (the key, then the
/// pair's buildings, then its cluster roots' ids) and the inputs of its recorded distance.
#[derive(Debug, Clone, Copy)]
struct Taken {
    key: f64,
    size: u32,
    roots: [u32; 2],
    sizes: [u32; 2],
    base: f64,
}

/// The agglomeration state: union-find over buildings, neighbour maps on cluster roots. It
/// runs on local indices: `global[i]` is the building of index `i` (the identity for the whole
/// city; one block's buildings, ascending, for a block), so ties break as on global ids.
struct Agglomeration<'a> {
    parent: Vec<u32>,
    size: Vec<u32>,
    node: Vec<u32>,
    version: Vec<u32>,
    nbrs: Vec<HashMap<u32, f64>>,
    heap: BinaryHeap<Entry>,
    merges: Vec<Merge>,
    /// Per merge this agglomeration made, how it was taken: a block's are put in the city's
    /// order by them ([`after_blocks`]).
    taken: Vec<Taken>,
    /// Leaves of this agglomeration's node numbering (merge k creates node `n + k`).
    n: u32,
    mode: ClusterDistance,
    inner: InnerSizes,
    blocks: &'a [u32],
    global: Vec<u32>,
}

impl<'a> Agglomeration<'a> {
    /// Every building of `global` its own cluster.
    fn new(global: Vec<u32>, blocks: &'a [u32], mode: ClusterDistance) -> Self {
        let n = global.len() as u32;
        Agglomeration {
            parent: (0..n).collect(),
            size: vec![1; n as usize],
            node: (0..n).collect(),
            version: vec![0; n as usize],
            nbrs: vec![HashMap::new(); n as usize],
            heap: BinaryHeap::new(),
            merges: Vec::with_capacity(n.saturating_sub(1) as usize),
            taken: Vec::new(),
            n,
            mode,
            inner: InnerSizes::default(),
            blocks,
            global,
        }
    }

    fn find(&mut self, mut x: u32) -> u32 {
        while self.parent[x as usize] != x {
            let p = self.parent[x as usize];
            self.parent[x as usize] = self.parent[p as usize];
            x = p;
        }
        x
    }

    fn key(&self, a: u32, b: u32, base: f64) -> f64 {
        match self.mode {
            ClusterDistance::ChangSizeWeighted => {
                f64::from(self.size[a as usize]) * f64::from(self.size[b as usize]) * base
            }
            ClusterDistance::YangAdjacent => base,
        }
    }

    fn push(&mut self, a: u32, b: u32, base: f64) {
        let key = self.key(a, b, base);
        let (a, b) = (a.min(b), a.max(b));
        self.heap.push(Entry {
            key,
            size: self.size[a as usize] + self.size[b as usize],
            a,
            b,
            va: self.version[a as usize],
            vb: self.version[b as usize],
        });
    }

    /// Adds a candidate pair of buildings (local indices) with its base distance.
    fn add_pair(&mut self, x: u32, y: u32, base: f64) {
        let (a, b) = (self.find(x), self.find(y));
        if a == b {
            return;
        }
        let cur = self.nbrs[a as usize].get(&b).copied();
        if cur.is_none_or(|c| base < c) {
            self.nbrs[a as usize].insert(b, base);
            self.nbrs[b as usize].insert(a, base);
            self.push(a, b, base);
        }
    }

    fn merge(&mut self, a: u32, b: u32, base: f64) {
        let sizes = [self.size[a as usize], self.size[b as usize]];
        let (lo, hi) = (a.min(b), a.max(b));
        self.taken.push(Taken {
            key: self.key(a, b, base),
            size: sizes[0] + sizes[1],
            roots: [self.global[lo as usize], self.global[hi as usize]],
            sizes,
            base,
        });
        let recorded = self.inner.recorded(self.mode, sizes, base);
        self.inner.merged(sizes);
        let within_block = self.blocks[self.global[a as usize] as usize]
            == self.blocks[self.global[b as usize] as usize];
        self.merges.push(Merge {
            a: self.node[a as usize],
            b: self.node[b as usize],
            distance: recorded,
            within_block,
        });
        let (big, small) = if self.nbrs[a as usize].len() >= self.nbrs[b as usize].len() {
            (a, b)
        } else {
            (b, a)
        };
        self.parent[small as usize] = big;
        self.size[big as usize] += self.size[small as usize];
        self.node[big as usize] = self.n + self.merges.len() as u32 - 1;
        self.version[big as usize] += 1;
        self.version[small as usize] += 1;
        let small_map = std::mem::take(&mut self.nbrs[small as usize]);
        self.nbrs[big as usize].remove(&small);
        for (k, d) in small_map {
            if k == big {
                continue;
            }
            let e = self.nbrs[big as usize].entry(k).or_insert(d);
            if d < *e {
                *e = d;
            }
        }
        let entries: Vec<(u32, f64)> = self.nbrs[big as usize]
            .iter()
            .map(|(&k, &d)| (k, d))
            .collect();
        for (k, d) in entries {
            let m = &mut self.nbrs[k as usize];
            m.remove(&small);
            m.insert(big, d);
            self.push(big, k, d);
        }
    }

    fn run(&mut self) {
        while let Some(e) = self.heap.pop() {
            if self.parent[e.a as usize] != e.a
                || self.parent[e.b as usize] != e.b
                || self.version[e.a as usize] != e.va
                || self.version[e.b as usize] != e.vb
            {
                continue;
            }
            let Some(&base) = self.nbrs[e.a as usize].get(&e.b) else {
                continue;
            };
            self.merge(e.a, e.b, base);
        }
    }

    /// Joins what is still apart in `members` (local indices; a disconnected candidate graph,
    /// e.g. all sites on one point): chains the clusters by centre x, at their centre distance.
    fn join_rest(&mut self, members: &[u32], leaves: &[Leaf]) {
        let centre = |ag: &Self, x: u32| leaves[ag.global[x as usize] as usize].centre;
        let mut roots: Vec<u32> = members.iter().map(|&m| self.find(m)).collect();
        roots.sort_unstable();
        roots.dedup();
        roots.sort_by(|&x, &y| centre(self, x)[0].total_cmp(&centre(self, y)[0]));
        for w in 1..roots.len() {
            let (a, b) = (self.find(roots[w - 1]), self.find(roots[w]));
            if a != b {
                let (ca, cb) = (centre(self, a), centre(self, b));
                let d = ((ca[0] - cb[0]).powi(2) + (ca[1] - cb[1]).powi(2)).sqrt();
                self.nbrs[a as usize].insert(b, d);
                self.nbrs[b as usize].insert(a, d);
                self.merge(a, b, d);
            }
        }
    }
}

/// One block clustered on its own (phase 1): its merges on the block's local numbering
/// (leaves `0..m` for `members`, merge k is node `m + k`), the first `popped` taken from the
/// heap, the rest joining what the candidate pairs left apart.
struct BlockRun {
    members: Vec<u32>,
    merges: Vec<Merge>,
    taken: Vec<Taken>,
    popped: usize,
    /// The local index of the block's one cluster root.
    root: u32,
}

/// Clusters one block's buildings (`members`, ascending) among themselves.
fn cluster_block(
    members: &[u32],
    leaves: &[Leaf],
    verts: &[Pt],
    blocks: &[u32],
    mode: ClusterDistance,
    base: &(dyn Fn(u32, u32) -> f64 + Sync),
) -> Result<BlockRun, ClusterError> {
    let mut pairs = Vec::new();
    delaunay_pairs(sites_of(leaves, verts, members, mode), &mut pairs)?;
    pairs.sort_unstable();
    pairs.dedup();
    let local = |x: u32| members.binary_search(&x).expect("a block's own building") as u32;
    let mut ag = Agglomeration::new(members.to_vec(), blocks, mode);
    for &(x, y) in &pairs {
        ag.add_pair(local(x), local(y), base(x, y));
    }
    ag.run();
    let popped = ag.merges.len();
    let all: Vec<u32> = (0..members.len() as u32).collect();
    ag.join_rest(&all, leaves);
    let root = ag.find(0);
    Ok(BlockRun {
        members: members.to_vec(),
        merges: ag.merges,
        taken: ag.taken,
        popped,
        root,
    })
}

/// The whole city's agglomeration after phase 1, from its blocks clustered apart: their
/// merges in the order one heap over all blocks takes them (a block's own merges come off
/// that heap in the block's order, and the keys never decrease, so the city's order is the
/// blocks' orders merged by key), then each block's joins in block order, as
/// [`Agglomeration::join_rest`] would add them block by block.
fn after_blocks<'a>(
    n: u32,
    runs: &[BlockRun],
    blocks: &'a [u32],
    mode: ClusterDistance,
) -> Agglomeration<'a> {
    let mut order: Vec<(usize, usize)> = runs
        .iter()
        .enumerate()
        .flat_map(|(r, run)| (0..run.popped).map(move |k| (r, k)))
        .collect();
    order.sort_unstable_by(|&(r, k), &(s, l)| {
        let (x, y) = (&runs[r].taken[k], &runs[s].taken[l]);
        x.key
            .total_cmp(&y.key)
            .then(x.size.cmp(&y.size))
            .then(x.roots.cmp(&y.roots))
    });
    order.extend(
        runs.iter()
            .enumerate()
            .flat_map(|(r, run)| (run.popped..run.merges.len()).map(move |k| (r, k))),
    );
    let mut ag = Agglomeration::new((0..n).collect(), blocks, mode);
    // Global node id of each block's local merge.
    let mut merge_node: Vec<Vec<u32>> = runs.iter().map(|r| vec![0; r.merges.len()]).collect();
    for (k, &(r, l)) in order.iter().enumerate() {
        merge_node[r][l] = n + k as u32;
    }
    for &(r, l) in &order {
        let (run, m, t) = (&runs[r], runs[r].merges[l], runs[r].taken[l]);
        let local_len = run.members.len() as u32;
        let node = |x: u32| {
            if x < local_len {
                run.members[x as usize]
            } else {
                merge_node[r][(x - local_len) as usize]
            }
        };
        ag.merges.push(Merge {
            a: node(m.a),
            b: node(m.b),
            distance: ag.inner.recorded(mode, t.sizes, t.base),
            within_block: true,
        });
        ag.inner.merged(t.sizes);
    }
    for (r, run) in runs.iter().enumerate() {
        let root = run.members[run.root as usize];
        for &x in &run.members {
            ag.parent[x as usize] = root;
        }
        ag.size[root as usize] = run.members.len() as u32;
        ag.node[root as usize] = match run.merges.len() {
            0 => root,
            len => merge_node[r][len - 1],
        };
    }
    ag
}

/// The distance of buildings `x` and `y` before any cluster weighting: their centres' (Chang)
/// or their footprints' adjacent distance (Yang).
fn base_distance(
    leaves: &[Leaf],
    verts: &[Pt],
    mode: ClusterDistance,
    lambda: f64,
    x: u32,
    y: u32,
) -> f64 {
    let (lx, ly) = (&leaves[x as usize], &leaves[y as usize]);
    match mode {
        ClusterDistance::ChangSizeWeighted => {
            ((lx.centre[0] - ly.centre[0]).powi(2) + (lx.centre[1] - ly.centre[1]).powi(2)).sqrt()
        }
        ClusterDistance::YangAdjacent => adjacent_distance(verts, &lx.ring, &ly.ring, lambda),
    }
}

/// Every building, ascending within its block.
fn group_by_block(blocks: &[u32]) -> Vec<u32> {
    let mut by_block: Vec<u32> = (0..blocks.len() as u32).collect();
    by_block.sort_by_key(|&i| (blocks[i as usize], i));
    by_block
}

/// The blocks' runs of `by_block` ([`group_by_block`]): each block's buildings.
fn block_runs<'b>(by_block: &'b [u32], blocks: &[u32]) -> Vec<&'b [u32]> {
    by_block
        .chunk_by(|&x, &y| blocks[x as usize] == blocks[y as usize])
        .collect()
}

/// Clusters `leaves` (one per building) into `n − 1` merges, blocks first.
pub fn single_link(
    leaves: &[Leaf],
    verts: &[Pt],
    blocks: &[u32],
    mode: ClusterDistance,
    lambda: f64,
) -> Result<Vec<Merge>, ClusterError> {
    let n = leaves.len() as u32;
    let base = |x: u32, y: u32| base_distance(leaves, verts, mode, lambda, x, y);
    // Phase 1: inside each block. The blocks are independent: each is clustered on rayon's
    // threads, and their merges are put in the order one heap over the city would take them.
    let by_block = group_by_block(blocks);
    let groups = block_runs(&by_block, blocks);
    // Phase 2's candidate pairs do not depend on phase 1: found beside it (the triangulation
    // of every site of the city is one sequential job, seconds at a million buildings).
    let (runs, cross) = rayon::join(
        || {
            groups
                .par_iter()
                .map(|g| cluster_block(g, leaves, verts, blocks, mode, &base))
                .collect::<Result<Vec<BlockRun>, _>>()
        },
        || cross_pairs(leaves, verts, blocks, &by_block, groups.len(), mode, &base),
    );
    let mut ag = after_blocks(n, &runs?, blocks, mode);
    join_blocks(&mut ag, &cross?, &by_block, leaves);
    Ok(ag.merges)
}

/// Phase 2's candidates: the Delaunay pairs of buildings of different blocks (`by_block`:
/// every building, grouped by block; `block_count` groups) with their base distances.
fn cross_pairs(
    leaves: &[Leaf],
    verts: &[Pt],
    blocks: &[u32],
    by_block: &[u32],
    block_count: usize,
    mode: ClusterDistance,
    base: &(dyn Fn(u32, u32) -> f64 + Sync),
) -> Result<Vec<(u32, u32, f64)>, ClusterError> {
    if block_count < 2 {
        return Ok(Vec::new());
    }
    let mut cross = Vec::new();
    delaunay_pairs(sites_of(leaves, verts, by_block, mode), &mut cross)?;
    cross.retain(|&(x, y)| blocks[x as usize] != blocks[y as usize]);
    cross.sort_unstable();
    cross.dedup();
    Ok(cross.par_iter().map(|&(x, y)| (x, y, base(x, y))).collect())
}

/// Phase 2: the blocks' clusters joined along the `cross` pairs, then whatever they left apart.
fn join_blocks(
    ag: &mut Agglomeration<'_>,
    cross: &[(u32, u32, f64)],
    by_block: &[u32],
    leaves: &[Leaf],
) {
    for &(x, y, d) in cross {
        ag.add_pair(x, y, d);
    }
    ag.run();
    ag.join_rest(by_block, leaves);
}

/// [`single_link`] with phase 1 as one heap over the whole city, the definition the blocks'
/// separate runs reproduce (for the tests).
#[cfg(test)]
pub(super) fn single_link_one_heap(
    leaves: &[Leaf],
    verts: &[Pt],
    blocks: &[u32],
    mode: ClusterDistance,
    lambda: f64,
) -> Result<Vec<Merge>, ClusterError> {
    let base = |x: u32, y: u32| base_distance(leaves, verts, mode, lambda, x, y);
    let by_block = group_by_block(blocks);
    let groups = block_runs(&by_block, blocks);
    let mut ag = Agglomeration::new((0..leaves.len() as u32).collect(), blocks, mode);
    let mut pairs = Vec::new();
    for g in &groups {
        delaunay_pairs(sites_of(leaves, verts, g, mode), &mut pairs)?;
    }
    pairs.sort_unstable();
    pairs.dedup();
    for &(x, y) in &pairs {
        ag.add_pair(x, y, base(x, y));
    }
    ag.run();
    for g in &groups {
        ag.join_rest(g, leaves);
    }
    let cross = cross_pairs(leaves, verts, blocks, &by_block, groups.len(), mode, &base)?;
    join_blocks(&mut ag, &cross, &by_block, leaves);
    Ok(ag.merges)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn adjacent_distance_prefers_parallel_facing_sides() {
        // Two unit squares facing each other across 1 m, and one offset diagonally at the
        // same d_min: the facing pair must be nearer (Yang Figure 1a vs 1e).
        let verts = vec![
            [0.0, 0.0],
            [1.0, 0.0],
            [1.0, 1.0],
            [0.0, 1.0],
            [2.0, 0.0],
            [3.0, 0.0],
            [3.0, 1.0],
            [2.0, 1.0],
            [2.0, 2.0],
            [3.0, 2.0],
            [3.0, 3.0],
            [2.0, 3.0],
        ];
        let a = [0, 1, 2, 3];
        let facing = [4, 5, 6, 7];
        let d_face = adjacent_distance(&verts, &a, &facing, 0.6);
        assert!((d_face - 1.0 * (1.0 - 0.6)).abs() < 1e-9, "{d_face}");
        let diag = [8, 9, 10, 11];
        let d_diag = adjacent_distance(&verts, &a, &diag, 0.6);
        let d_min = 2f64.sqrt();
        assert!(d_diag <= d_min + 1e-9 && d_diag > d_face, "{d_diag}");
        assert_eq!(adjacent_distance(&verts, &a, &a, 0.6), 0.0);
    }
}
