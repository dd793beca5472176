//! The legibility cluster tree (Chang et al. 2008; Yang et al. 2011): single-link clustering of
//! the buildings, merged and simplified cluster hulls, depth reduction and balancing, per-node
//! errors, landmarks and cluster meshes. The output types live in
//! [`citywalk_scenes::cluster_tree`] so the runtime reads them without linking this crate.
//!
//! Pipeline ([`build_cluster_tree`]):
//! 1. leaves: one ring per building in one shared vertex array ([`leaves`]);
//! 2. single-link clustering inside blocks, then between blocks ([`linkage`]); long chains
//!    re-paired by weight ([`rebalance`]);
//! 3. hulls merged bottom-up along the merge order ([`merge`]) and simplified ([`simplify`]);
//! 4. depth reduction and balancing ([`depth`]);
//! 5. node data: heights, errors (made monotone; the geometric and colour errors in [`error`]),
//!    bounds, landmarks, meshes.
//!
//! A large city's tree is built tile by tile ([`tiled`]): this pipeline on each tile, then
//! once more on the tiles' roots for the tree above them.

pub mod depth;
pub mod error;
pub mod geom;
pub mod hulls;
pub mod leaves;
pub mod linkage;
pub mod merge;
pub mod rebalance;
pub mod simplify;
pub mod tiled;

use citywalk_scenes::City;
use citywalk_scenes::city::TriangleMesh;
pub use citywalk_scenes::cluster_tree::{ClusterDistance, ClusterParams};
use citywalk_scenes::cluster_tree::{ClusterNode, ClusterStats, ClusterTree, HullSimplify};
use citywalk_scenes::extrude::extrude_polygon;
use rayon::prelude::*;

use geom::{convex_hull, ring_bounds};
pub use hulls::{Hulls, merge_hulls};
use leaves::{LeafKind, VertexStore};
pub use tiled::build_cluster_tree_tiled;

/// Why a cluster tree could not be built.
#[derive(Debug, thiserror::Error)]
pub enum ClusterError {
    #[error("the city has no buildings")]
    NoBuildings,
    #[error("{got} block ids for {expected} buildings")]
    BlockCount { expected: usize, got: usize },
    #[error("invalid cluster parameter: {0}")]
    InvalidParams(String),
    #[error("Delaunay triangulation of the footprints failed: {0}")]
    Triangulation(String),
}

fn check_params(p: &ClusterParams) -> Result<(), ClusterError> {
    let bad = |what: &str| Err(ClusterError::InvalidParams(what.to_string()));
    if !(0.0..=1.0).contains(&p.adjacency_lambda) {
        return bad("adjacency_lambda must be in [0, 1] (Yang §3.1)");
    }
    if !(p.concave_area_divisor.is_finite() && p.concave_area_divisor > 0.0) {
        return bad("concave_area_divisor must be positive");
    }
    if !(p.straight_angle_deg.is_finite() && p.straight_angle_deg <= 180.0) {
        return bad("straight_angle_deg must be at most 180");
    }
    if !(0.0..=1.0).contains(&p.chang_keep_fraction)
        || !(0.0..=1.0).contains(&p.chang_min_input_fraction)
    {
        return bad("Chang's fractions must be in [0, 1]");
    }
    if p.depth_lambda.is_some_and(|l| !(l.is_finite() && l > 0.0)) {
        return bad("depth_lambda must be positive");
    }
    if !(p.landmark_height_ratio.is_finite() && p.landmark_height_ratio >= 1.0) {
        return bad("landmark_height_ratio must be at least 1");
    }
    Ok(())
}

/// Builds the cluster tree of `city`. `blocks[i]` is the urban block of building `i`
/// (`UrbanBlocks::block_of_building`; all zeros for one block). No node below the block level
/// holds buildings of two blocks.
pub fn build_cluster_tree(
    city: &City,
    blocks: &[u32],
    params: &ClusterParams,
) -> Result<ClusterTree, ClusterError> {
    check_params(params)?;
    let n = city.buildings.len();
    if n == 0 {
        return Err(ClusterError::NoBuildings);
    }
    if blocks.len() != n {
        return Err(ClusterError::BlockCount {
            expected: n,
            got: blocks.len(),
        });
    }
    let mut stats = ClusterStats::default();
    let mut lap = Lap::start();
    let mut store = VertexStore::default();
    let leaves = leaves::build_leaves(&mut store, &city.buildings);
    for (i, l) in leaves.iter().enumerate() {
        match l.kind {
            LeafKind::Exterior => {}
            LeafKind::Hull => stats.multi_part_buildings += 1,
            LeafKind::Degenerate => stats.degenerate_buildings.push(city.buildings[i].id),
        }
    }
    if !stats.degenerate_buildings.is_empty() {
        tracing::warn!(
            count = stats.degenerate_buildings.len(),
            "degenerate footprints replaced by their bounding boxes grown by 0.25 m"
        );
    }
    lap.step("leaves");
    let merges = linkage::single_link(
        &leaves,
        &store.verts,
        blocks,
        params.distance,
        params.adjacency_lambda,
    )?;
    let centres: Vec<[f64; 2]> = leaves.iter().map(|l| l.centre).collect();
    lap.step("single-link clustering");
    let merges = rebalance::rebalance(n, &merges, blocks, &centres);
    lap.step("rebalancing");
    let hulls = merge_hulls(
        &mut store, &leaves, &merges, blocks, params, &mut stats, false,
    );
    lap.step("hull merging");
    stats.binary_inner_nodes = merges.len() as u32;
    let Assembled {
        mut nodes,
        building_order,
        plan_slack_m,
    } = assemble_nodes(city, blocks, &store.verts, &leaves, &merges, hulls, params);
    lap.step("depth reduction, node data and errors");
    build_meshes(
        city,
        &store.verts,
        &building_order,
        &plan_slack_m,
        &mut nodes,
    );
    lap.step("meshes");

    Ok(ClusterTree {
        vertices: store.verts,
        nodes,
        root: 0,
        building_order,
        params: params.clone(),
        stats,
    })
}

/// Times the steps of the tree stage for the debug log (`RUST_LOG=citywalk_preprocess=debug`).
struct Lap(std::time::Instant);

impl Lap {
    fn start() -> Self {
        Lap(std::time::Instant::now())
    }

    fn step(&mut self, name: &str) {
        tracing::debug!(
            seconds = self.0.elapsed().as_secs_f64(),
            "cluster tree: {name}"
        );
        self.0 = std::time::Instant::now();
    }
}

/// The final nodes with their data, before their meshes.
#[derive(Debug, Clone)]
pub struct Assembled {
    /// In depth-first preorder.
    pub nodes: Vec<ClusterNode>,
    /// Leaf order: every node's buildings are a contiguous range of it.
    pub building_order: Vec<citywalk_scenes::BuildingId>,
    /// Per node, the plan departure its geometric error allows its mesh
    /// ([`error::fill_errors`]).
    pub plan_slack_m: Vec<f32>,
}

/// Stages 4–5: depth reduction and balancing of the binary tree ([`depth`]), the final nodes
/// in depth-first preorder, and their data (heights, errors, bounds, landmarks; no meshes).
pub fn assemble_nodes(
    city: &City,
    blocks: &[u32],
    verts: &[geom::Pt],
    leaves: &[leaves::Leaf],
    merges: &[linkage::Merge],
    hulls: Hulls,
    params: &ClusterParams,
) -> Assembled {
    let n = leaves.len();
    let Hulls {
        mut rings,
        areas,
        dist,
        bin_children,
        ..
    } = hulls;
    // Block roots stay in the reduced tree: the block level is a level of its own.
    let total = rings.len();
    let mut force_keep = vec![false; total];
    let mut within = vec![true; total];
    for (k, m) in merges.iter().enumerate() {
        within[n + k] = m.within_block && within[m.a as usize] && within[m.b as usize];
    }
    for (k, m) in merges.iter().enumerate() {
        if !within[n + k] {
            for c in [m.a, m.b] {
                if within[c as usize] {
                    force_keep[c as usize] = true;
                }
            }
        }
    }
    let reduced = depth::reduce(n, &bin_children, &dist, &force_keep, params.depth_lambda);

    // Final nodes in depth-first preorder, so every node's buildings are a contiguous range.
    let mut order: Vec<(u32, u32, u32)> = Vec::new(); // (binary id, parent final id, depth)
    let mut stack = vec![(total as u32 - 1, u32::MAX, 0u32)];
    while let Some((x, parent, d)) = stack.pop() {
        let id = order.len() as u32;
        order.push((x, parent, d));
        for &c in reduced.children[x as usize].iter().rev() {
            stack.push((c, id, d + 1));
        }
    }
    let mut children: Vec<Vec<u32>> = vec![Vec::new(); order.len()];
    for (id, &(_, parent, _)) in order.iter().enumerate() {
        if parent != u32::MAX {
            children[parent as usize].push(id as u32);
        }
    }
    let mut building_order = Vec::with_capacity(n);
    let mut range = vec![(0u32, 0u32); order.len()];
    for (id, &(x, _, _)) in order.iter().enumerate() {
        if (x as usize) < n {
            range[id] = (building_order.len() as u32, building_order.len() as u32 + 1);
            building_order.push(city.buildings[x as usize].id);
        }
    }
    // Ranges of inner nodes, bottom-up (children come after parents in preorder).
    for id in (0..order.len()).rev() {
        if let (Some(&f), Some(&l)) = (children[id].first(), children[id].last()) {
            range[id] = (range[f as usize].0, range[l as usize].1);
        }
    }

    let mut nodes: Vec<ClusterNode> = Vec::with_capacity(order.len());
    for (id, &(x, _, d)) in order.iter().enumerate() {
        nodes.push(ClusterNode {
            // Each binary node is at most one final node: move its ring, do not copy it.
            footprint: vec![std::mem::take(&mut rings[x as usize])],
            area_m2: areas[x as usize],
            height_m: 0.0,
            h_min_m: 0.0,
            h_max_m: 0.0,
            delta_h_m: 0.0,
            delta_a_m2: 0.0,
            neg_space_box_m: [0.0; 3],
            geometric_error_m: 0.0,
            colour_error_m: 0.0,
            bounds_min: [0.0; 3],
            bounds_max: [0.0; 3],
            children: std::mem::take(&mut children[id]),
            buildings: range[id],
            depth: d,
            merge_distance: dist[x as usize],
            landmarks: Vec::new(),
            mesh: TriangleMesh::default(),
            block: None,
        });
    }
    let heights = error::building_heights(city, &building_order);
    fill_node_data(
        city,
        blocks,
        verts,
        leaves,
        &building_order,
        &heights,
        &mut nodes,
        params,
    );
    let plan_slack_m = error::fill_errors(city, verts, &building_order, &heights, &mut nodes);

    Assembled {
        nodes,
        building_order,
        plan_slack_m,
    }
}

/// Stage 6: cluster meshes, the hull of every inner node with its corners cut within the
/// node's plan slack ([`simplify::cut_corners`]), extruded from its lowest base to its height
/// (walls and a constrained-Delaunay roof).
pub fn build_meshes(
    city: &City,
    verts: &[geom::Pt],
    building_order: &[citywalk_scenes::BuildingId],
    plan_slack_m: &[f32],
    nodes: &mut [ClusterNode],
) {
    // Lowest building base per node, bottom-up (children follow their parent in preorder).
    let mut base = vec![f32::INFINITY; nodes.len()];
    for id in (0..nodes.len()).rev() {
        let n = &nodes[id];
        base[id] = if n.is_leaf() {
            building_order
                .get(n.buildings.0 as usize)
                .and_then(|b| city.buildings.get(b.index()))
                .map_or(0.0, |b| b.base_m)
        } else {
            n.children
                .iter()
                .map(|&c| base[c as usize])
                .fold(f32::INFINITY, f32::min)
        };
    }
    // Each node's mesh is its own: made on rayon's threads, each into its node's slot.
    nodes.par_iter_mut().enumerate().for_each(|(id, n)| {
        if !n.is_leaf() {
            let ring = simplify::cut_corners(verts, &n.footprint[0], f64::from(plan_slack_m[id]));
            n.mesh = cluster_mesh(verts, &ring, base[id].min(n.height_m), n.height_m);
        }
    });
}

/// Simplifies one merged hull: Chang's smallest-area removal down to max(2/3 of the
/// children's edges, 1 % of the input edges, the convex hull's count), or Yang's concave
/// triangles under δa = `a_ave`/50 then vertices over 175°.
pub fn simplify_hull(
    verts: &[geom::Pt],
    merged: &[u32],
    child_edges: usize,
    input_edges: usize,
    a_ave: f64,
    params: &ClusterParams,
) -> Vec<u32> {
    match params.simplify {
        HullSimplify::ChangSmallestArea => {
            let hull_len = convex_hull(verts, merged.iter().copied()).len();
            let target = ((params.chang_keep_fraction * child_edges as f64).ceil() as usize)
                .max((params.chang_min_input_fraction * input_edges as f64).ceil() as usize)
                .max(hull_len);
            simplify::simplify_chang(verts, merged, target)
        }
        HullSimplify::YangConcaveTriangles => simplify::simplify_yang(
            verts,
            merged,
            a_ave / params.concave_area_divisor,
            params.straight_angle_deg,
        ),
    }
}

/// Heights ([`error::roof_height_m`]), errors (Yang §4, Chang §8, made monotone), bounds and
/// landmarks, bottom-up.
#[expect(
    clippy::too_many_arguments,
    reason = "one pass over the nodes, all inputs explicit"
)]
fn fill_node_data(
    city: &City,
    blocks: &[u32],
    verts: &[geom::Pt],
    leaves: &[leaves::Leaf],
    building_order: &[citywalk_scenes::BuildingId],
    heights: &[error::Heights],
    nodes: &mut [ClusterNode],
    params: &ClusterParams,
) {
    // Per node: lowest roof point, Σ footprint area, lowest base.
    let mut sums: Vec<NodeSums> = vec![(f32::INFINITY, 0.0f64, f32::INFINITY); nodes.len()];
    for id in (0..nodes.len()).rev() {
        let (s, e) = nodes[id].buildings;
        let node_blocks = || {
            building_order[s as usize..e as usize]
                .iter()
                .map(|b| blocks[b.index()])
        };
        let first_block = node_blocks().next();
        nodes[id].block = first_block.filter(|&f| node_blocks().all(|b| b == f));
        if nodes[id].children.is_empty() {
            let bi = building_order[s as usize].index();
            let b = &city.buildings[bi];
            let area_b = leaves[bi].area_m2;
            let (lo, hi) = b.bounds();
            let n = &mut nodes[id];
            n.height_m = b.top_m;
            n.h_min_m = b.top_m;
            n.h_max_m = b.top_m;
            n.delta_h_m = 0.0;
            n.delta_a_m2 = (n.area_m2 - area_b).max(0.0);
            n.bounds_min = lo.to_array();
            n.bounds_max = hi.to_array();
            sums[id] = (heights[s as usize].lowest_top_m, area_b, b.base_m);
        } else {
            sums[id] = fill_inner_node(city, verts, building_order, &sums, nodes, id, params);
        }
    }
}

/// Per node, what its roof height and negative space need of its buildings: the lowest roof
/// point, the sum of their footprint areas and the lowest base.
pub(crate) type NodeSums = (f32, f64, f32);

/// An inner node's heights, monotone errors (Δh, Δa, the negative-space box), bounds and
/// landmarks from its children's (already filled, their [`NodeSums`] in `sums`); returns its
/// own sums.
pub(crate) fn fill_inner_node(
    city: &City,
    verts: &[geom::Pt],
    building_order: &[citywalk_scenes::BuildingId],
    sums: &[NodeSums],
    nodes: &mut [ClusterNode],
    id: usize,
    params: &ClusterParams,
) -> NodeSums {
    let ch = nodes[id].children.clone();
    let mut acc = (f32::INFINITY, 0.0, f32::INFINITY);
    let (mut hmin, mut hmax) = (f32::INFINITY, f32::NEG_INFINITY);
    let (mut lo, mut hi) = ([f32::INFINITY; 3], [f32::NEG_INFINITY; 3]);
    let (mut dh, mut da, mut bx) = (0.0f32, 0.0f64, [0.0f32; 3]);
    for &c in &ch {
        let (cs, cn) = (sums[c as usize], &nodes[c as usize]);
        acc = (acc.0.min(cs.0), acc.1 + cs.1, acc.2.min(cs.2));
        hmin = hmin.min(cn.h_min_m);
        hmax = hmax.max(cn.h_max_m);
        for k in 0..3 {
            lo[k] = lo[k].min(cn.bounds_min[k]);
            hi[k] = hi[k].max(cn.bounds_max[k]);
            bx[k] = bx[k].max(cn.neg_space_box_m[k]);
        }
        dh = dh.max(cn.delta_h_m);
        da = da.max(cn.delta_a_m2);
    }
    let n = &mut nodes[id];
    n.height_m = error::roof_height_m(acc.0, hmin, hmax);
    n.h_min_m = hmin;
    n.h_max_m = hmax;
    // Monotone errors: never below a child's (only ever overstates the error).
    n.delta_h_m = (hmax - hmin).max(dh);
    n.delta_a_m2 = (n.area_m2 - acc.1).max(0.0).max(da);
    n.bounds_min = lo;
    n.bounds_max = hi;
    // Chang et al. 2008 §8: the negative space as a box with the hull AABB's aspect.
    let (rlo, rhi) = ring_bounds(verts, &n.footprint[0]);
    let (w0, d0) = ((rhi[0] - rlo[0]).max(1e-6), (rhi[1] - rlo[1]).max(1e-6));
    let raw_da = (n.area_m2 - acc.1).max(0.0);
    let raw = [
        (raw_da * w0 / d0).sqrt() as f32,
        (raw_da * d0 / w0).sqrt() as f32,
        (n.height_m - acc.2).max(0.0),
    ];
    for k in 0..3 {
        n.neg_space_box_m[k] = raw[k].max(bx[k]);
    }
    // Chang et al. 2008 §8: landmark candidates, much taller than the cluster.
    let threshold = n.height_m.max(0.0) * params.landmark_height_ratio as f32;
    let (s, e) = n.buildings;
    n.landmarks = building_order[s as usize..e as usize]
        .iter()
        .copied()
        .filter(|b| {
            let t = city.buildings[b.index()].top_m;
            t > n.height_m && t >= threshold
        })
        .collect();
    acc
}

/// The hull extruded from `base_m` to `top_m` (walls and a constrained-Delaunay roof).
pub(crate) fn cluster_mesh(
    verts: &[geom::Pt],
    ring: &[u32],
    base_m: f32,
    top_m: f32,
) -> TriangleMesh {
    let coords: Vec<geo::Coord<f64>> = ring
        .iter()
        .map(|&i| {
            let p = verts[i as usize];
            geo::Coord { x: p[0], y: p[1] }
        })
        .collect();
    let polygon = geo::Polygon::new(geo::LineString::from(coords), Vec::new());
    extrude_polygon(&polygon, base_m, top_m)
}

#[cfg(test)]
mod tests;
