//! Stage 3 of the cluster tree: the hulls merged bottom-up along the merge order
//! ([`merge::merge_rings`]) and simplified ([`simplify_hull`]).
//!
//! The merges inside an urban block depend only on that block's hulls, so each block's are
//! made on rayon's threads, in a vertex array of the block's own; their new vertices join the
//! city's array block by block afterwards, so the package is the same for every thread count.
//! The merges between blocks follow, in merge order.
//!
//! Yang et al. 2011 §3.2 sets the concave-triangle threshold δa = a_ave / 50 (citywalk's
//! default divisor is 20: [`ClusterParams::concave_area_divisor`]), a_ave "the
//! average area of all the footprints at the level" of the merged children. Below the block
//! level the tree is the block's own (clustering runs inside each block first, Lynch's paths),
//! so a merge inside a block takes a_ave over the block's current clusters; a merge between
//! blocks takes it over the city's current clusters.

use citywalk_scenes::cluster_tree::{ClusterParams, ClusterStats, MergeFailure, MergeFallback};
use rayon::prelude::*;

use super::geom::{self, Pt, signed_area};
use super::leaves::{Leaf, VertexStore};
use super::linkage::Merge;
use super::{merge, simplify_hull};

/// The binary merge tree with its hulls (stage 3).
#[derive(Debug, Clone, Default)]
pub struct Hulls {
    /// Hull ring per binary node (leaves `0..n`, merge k is node `n + k`).
    pub rings: Vec<Vec<u32>>,
    /// Hull area per binary node (m²).
    pub areas: Vec<f64>,
    /// Monotone merge distance per binary node (0 for leaves).
    pub dist: Vec<f64>,
    /// The two children of every merge.
    pub bin_children: Vec<[u32; 2]>,
    /// With `record`: per merge, the merged ring before simplification and the
    /// simplification target inputs `(children's edges, a_ave)`, for the per-stage bench.
    pub merged: Vec<(Vec<u32>, usize, f64)>,
}

/// One merge's hull, in the vertex array it was made in.
struct Merged {
    ring: Vec<u32>,
    area: f64,
    /// Why the first construction failed, and whether the hull fell back to the convex hull.
    failure: Option<(MergeFailure, bool)>,
    /// The simplified ring was not simple: the unsimplified one was kept.
    simplify_fallback: bool,
    /// With `record`: the ring before simplification and the simplification's inputs.
    recorded: Option<(Vec<u32>, usize, f64)>,
}

/// What the hull merges have in common: the parameters and the input's edge count (Chang's
/// 1 % floor).
struct MergeSettings<'a> {
    params: &'a ClusterParams,
    input_edges: usize,
    record: bool,
}

impl MergeSettings<'_> {
    /// Merges rings `a` and `b` (of `store`) and simplifies the result with Yang's `a_ave`.
    fn merge(&self, store: &mut VertexStore, a: &[u32], b: &[u32], a_ave: f64) -> Merged {
        let params = self.params;
        let merged = merge::merge_rings(store, a, b, params.merge, params.adjacency_lambda);
        let child_edges = a.len() + b.len();
        let ring = simplify_hull(
            &store.verts,
            &merged.ring,
            child_edges,
            self.input_edges,
            a_ave,
            params,
        );
        // Growth-only removals keep the ring simple by construction; verify, and keep the
        // unsimplified ring (counted) should that ever fail.
        let simple = geom::ring_is_simple_ccw(&store.verts, &ring);
        let ring = if simple { ring } else { merged.ring.clone() };
        Merged {
            area: signed_area(&store.verts, &ring),
            ring,
            failure: merged.failure.map(|f| (f, merged.convex_hull)),
            simplify_fallback: !simple,
            recorded: self.record.then_some((merged.ring, child_edges, a_ave)),
        }
    }
}

/// Running mean area of the current clusters (Yang's a_ave) of a block or of the city.
struct LevelArea {
    sum: f64,
    count: f64,
}

impl LevelArea {
    fn mean(&self) -> f64 {
        self.sum / self.count.max(1.0)
    }

    /// Two clusters of areas `a` and `b` became one of area `merged`.
    fn merged(&mut self, a: f64, b: f64, merged: f64) {
        self.sum += merged - a - b;
        self.count -= 1.0;
    }
}

/// One block's merges (`ks`, ascending) made in a vertex array of its own; returns that
/// array's vertices and each merge's hull in it.
fn merge_block(
    verts: &[Pt],
    leaves: &[Leaf],
    merges: &[Merge],
    ks: &[u32],
    settings: &MergeSettings<'_>,
) -> (Vec<Pt>, Vec<Merged>) {
    let n = leaves.len();
    let mut store = VertexStore::default();
    let mut local: std::collections::HashMap<u32, (Vec<u32>, f64)> =
        std::collections::HashMap::new();
    let mut level = LevelArea {
        sum: 0.0,
        count: 0.0,
    };
    // The block's buildings are the leaves of its merges.
    for &k in ks {
        let m = merges[k as usize];
        for c in [m.a, m.b] {
            if (c as usize) < n {
                let ring: Vec<u32> = leaves[c as usize]
                    .ring
                    .iter()
                    .map(|&v| store.intern(verts[v as usize]))
                    .collect();
                let area = signed_area(&store.verts, &ring);
                level.sum += area;
                level.count += 1.0;
                local.insert(c, (ring, area));
            }
        }
    }
    let mut out = Vec::with_capacity(ks.len());
    for &k in ks {
        let m = merges[k as usize];
        let (ring_a, area_a) = local.remove(&m.a).expect("a child made before its parent");
        let (ring_b, area_b) = local.remove(&m.b).expect("a child made before its parent");
        let merged = settings.merge(&mut store, &ring_a, &ring_b, level.mean());
        level.merged(area_a, area_b, merged.area);
        local.insert(n as u32 + k, (merged.ring.clone(), merged.area));
        out.push(merged);
    }
    (store.verts, out)
}

/// Stage 3: hulls merged bottom-up along the merge order and simplified, the merges inside
/// each block (`blocks[i]` is building i's) on rayon's threads.
pub fn merge_hulls(
    store: &mut VertexStore,
    leaves: &[Leaf],
    merges: &[Merge],
    blocks: &[u32],
    params: &ClusterParams,
    stats: &mut ClusterStats,
    record: bool,
) -> Hulls {
    merge_hulls_with(store, leaves, merges, Some(blocks), params, stats, record)
}

/// [`merge_hulls`]; without `blocks` every merge is made in merge order in the city's vertex
/// array with the city's running mean area (the reference its tests compare with).
pub(super) fn merge_hulls_with(
    store: &mut VertexStore,
    leaves: &[Leaf],
    merges: &[Merge],
    blocks: Option<&[u32]>,
    params: &ClusterParams,
    stats: &mut ClusterStats,
    record: bool,
) -> Hulls {
    let n = leaves.len();
    let settings = MergeSettings {
        params,
        input_edges: leaves.iter().map(|l| l.ring.len()).sum(),
        record,
    };
    let total = n + merges.len();
    let mut rings: Vec<Vec<u32>> = leaves.iter().map(|l| l.ring.clone()).collect();
    rings.resize(total, Vec::new());
    let mut areas: Vec<f64> = leaves
        .iter()
        .map(|l| signed_area(&store.verts, &l.ring))
        .collect();
    areas.resize(total, 0.0);
    let mut dist = vec![0.0f64; total];
    // Each node's block, where all its buildings are in one (and the blocks are made apart).
    let mut block_of: Vec<Option<u32>> = match blocks {
        Some(blocks) => blocks.iter().map(|&b| Some(b)).collect(),
        None => vec![None; n],
    };
    block_of.resize(total, None);
    for (k, m) in merges.iter().enumerate() {
        let (a, b) = (m.a as usize, m.b as usize);
        dist[n + k] = m.distance.max(dist[a]).max(dist[b]);
        if m.within_block && block_of[a] == block_of[b] {
            block_of[n + k] = block_of[a];
        }
    }
    let mut outcomes: Vec<Option<Merged>> = (0..merges.len()).map(|_| None).collect();
    // Inside the blocks, block by block on rayon's threads.
    let mut within: Vec<(u32, u32)> = (0..merges.len() as u32)
        .filter_map(|k| block_of[n + k as usize].map(|b| (b, k)))
        .collect();
    within.sort_unstable();
    let groups: Vec<&[(u32, u32)]> = within.chunk_by(|x, y| x.0 == y.0).collect();
    let made: Vec<(Vec<Pt>, Vec<Merged>)> = groups
        .par_iter()
        .map(|g| {
            let ks: Vec<u32> = g.iter().map(|&(_, k)| k).collect();
            merge_block(&store.verts, leaves, merges, &ks, &settings)
        })
        .collect();
    for (g, (local_verts, merged)) in groups.iter().zip(made) {
        let to_city: Vec<u32> = local_verts.iter().map(|&p| store.intern(p)).collect();
        for (&(_, k), mut m) in g.iter().zip(merged) {
            for v in &mut m.ring {
                *v = to_city[*v as usize];
            }
            if let Some((ring, _, _)) = &mut m.recorded {
                for v in ring {
                    *v = to_city[*v as usize];
                }
            }
            outcomes[k as usize] = Some(m);
        }
    }
    // Between the blocks, in merge order, with the city's running mean area.
    let mut level = LevelArea {
        sum: areas[..n].iter().sum(),
        count: n as f64,
    };
    let mut recorded = Vec::new();
    for (k, m) in merges.iter().enumerate() {
        let (a, b) = (m.a as usize, m.b as usize);
        let merged = match outcomes[k].take() {
            Some(made) => made,
            None => settings.merge(store, &rings[a], &rings[b], level.mean()),
        };
        level.merged(areas[a], areas[b], merged.area);
        note_fallbacks(stats, k, &merged);
        areas[n + k] = merged.area;
        rings[n + k] = merged.ring;
        recorded.extend(merged.recorded);
    }
    Hulls {
        rings,
        areas,
        dist,
        bin_children: merges.iter().map(|m| [m.a, m.b]).collect(),
        merged: recorded,
    }
}

/// Counts merge `k`'s fallbacks in `stats` (and warns of a convex hull).
fn note_fallbacks(stats: &mut ClusterStats, k: usize, merged: &Merged) {
    if let Some((reason, convex_hull)) = merged.failure {
        stats.merge_fallback_log.push(MergeFallback {
            merge: k as u32,
            reason,
            convex_hull,
        });
        if convex_hull {
            stats.merge_fallbacks += 1;
            tracing::warn!(
                merge = k,
                ?reason,
                "merged hull fell back to the convex hull"
            );
        }
    }
    if merged.simplify_fallback {
        stats.simplify_fallbacks += 1;
    }
}
