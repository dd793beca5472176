//! The cluster tree built tile by tile (issue 17's tiled preprocessing, DESIGN.md step 3 at
//! scale): each tile — whole urban blocks along the B-Quadtree ([`crate::tiles`]) — gets the
//! tree of its own buildings ([`build_cluster_tree`], Chang et al. 2008 and Yang et al. 2011
//! unchanged inside it), and the tiles' roots are then clustered as the buildings of a small
//! city of their own, whose tree is the top of the city's: its leaves are replaced by the
//! tiles' trees. A tile needs nothing of the others, so tiles are built on every thread, and
//! each holds its own working data (vertex store, R-trees, heaps) only while it is built.
//!
//! The nodes above the tiles get their heights and bounds from their children and their
//! geometric error from the triangle inequality ([`error::errors_above_tiles`]): the plan
//! distance from their hull to the tiles' hulls plus the tiles' own error, so they need no
//! footprint of a building.

use std::sync::{Mutex, PoisonError};

use citywalk_scenes::city::{Building, BuildingPart, HeightSource};
use citywalk_scenes::cluster_tree::{ClusterNode, ClusterParams, ClusterStats, ClusterTree};
use citywalk_scenes::{BuildingId, City};
use geo::{Area, Coord, LineString, MultiPolygon, Polygon};
use rayon::prelude::*;

use crate::memory_budget::{MemoryBudget, tile_job_bytes};

use super::{
    ClusterError, NodeSums, build_cluster_tree, cluster_mesh, error, fill_inner_node, simplify,
};

/// Builds the cluster tree of `city` tile by tile: `tiles` lists each tile's buildings (by
/// index, every building in exactly one tile), `blocks` is as for [`build_cluster_tree`],
/// which one tile (or none) amounts to. Every tile's root is a node of the tree, and no node
/// below it holds buildings of two tiles. The tiles are built on every thread as `budget`
/// admits them; `settle` is called once the tiles' trees are built and as they are joined
/// ([`tree_above_tiles`]).
pub fn build_cluster_tree_tiled(
    city: &City,
    blocks: &[u32],
    tiles: &[Vec<u32>],
    params: &ClusterParams,
    budget: &MemoryBudget,
    settle: &dyn Fn(),
) -> Result<ClusterTree, ClusterError> {
    if tiles.len() <= 1 {
        return build_cluster_tree(city, blocks, params);
    }
    let subtrees = tile_trees(city, blocks, tiles, params, budget)?;
    settle();
    tree_above_tiles(city, subtrees, params, settle)
}

/// Each tile's tree ([`tile_tree`]), in tile order, built on every thread as `budget` admits
/// them ([`TileJobs`]).
fn tile_trees(
    city: &City,
    blocks: &[u32],
    tiles: &[Vec<u32>],
    params: &ClusterParams,
    budget: &MemoryBudget,
) -> Result<Vec<ClusterTree>, ClusterError> {
    let n = city.buildings.len();
    if blocks.len() != n {
        return Err(ClusterError::BlockCount {
            expected: n,
            got: blocks.len(),
        });
    }
    let start = std::time::Instant::now();
    let jobs = TileJobs {
        city,
        blocks,
        tiles,
        params,
        budget,
        workers: rayon::current_num_threads(),
        next: Mutex::new(0),
        trees: Mutex::new((0..tiles.len()).map(|_| None).collect()),
    };
    rayon::scope(|scope| jobs.start_next(scope));
    let trees = jobs
        .trees
        .into_inner()
        .unwrap_or_else(PoisonError::into_inner);
    let subtrees = trees
        .into_iter()
        .map(|tree| tree.expect("every tile's job ran"))
        .collect::<Result<Vec<_>, _>>()?;
    tracing::debug!(
        seconds = start.elapsed().as_secs_f64(),
        tiles = tiles.len(),
        "cluster tree: the tiles' trees"
    );
    Ok(subtrees)
}

/// The tiles' tree jobs, handed out in tile order. No thread waits for memory: the tiles
/// that fit are started, and each job, once done and its memory released, starts the next
/// that fit, so the last job to finish always starts one (a job is admitted when none runs).
struct TileJobs<'a> {
    city: &'a City,
    blocks: &'a [u32],
    tiles: &'a [Vec<u32>],
    params: &'a ClusterParams,
    budget: &'a MemoryBudget,
    workers: usize,
    /// The next tile to start.
    next: Mutex<usize>,
    trees: Mutex<Vec<Option<Result<ClusterTree, ClusterError>>>>,
}

impl<'a> TileJobs<'a> {
    /// Starts the next tiles on `scope` while the budget admits them.
    fn start_next(&'a self, scope: &rayon::Scope<'a>) {
        loop {
            let mut next = self.next.lock().unwrap_or_else(PoisonError::into_inner);
            let i = *next;
            let Some(members) = self.tiles.get(i) else {
                return;
            };
            let bytes = tile_job_bytes(members.len());
            let Some(admission) = self.budget.try_admit(i, bytes, self.workers) else {
                return;
            };
            *next += 1;
            drop(next);
            scope.spawn(move |scope| {
                let tree = tile_tree(self.city, self.blocks, members, self.params);
                drop(admission);
                self.trees.lock().unwrap_or_else(PoisonError::into_inner)[i] = Some(tree);
                self.start_next(scope);
            });
        }
    }
}

/// The city's tree from its tiles' trees ([`tile_tree`], in tile order): the tiles' roots
/// clustered as a city of their own, whose leaves are replaced by the tiles' trees. `settle`
/// is called after each tile's nodes are moved into the city's
/// ([`crate::pipeline::ProgressSink::settle`]: the tiles' buffers, freed here, were allocated
/// on the worker threads).
pub fn tree_above_tiles(
    city: &City,
    subtrees: Vec<ClusterTree>,
    params: &ClusterParams,
    settle: &dyn Fn(),
) -> Result<ClusterTree, ClusterError> {
    let roots = city_of_tile_roots(city, &subtrees);
    let top = build_cluster_tree(&roots, &vec![0; subtrees.len()], params)?;
    Ok(graft(city, top, subtrees, params, settle))
}

/// The tree of one tile's buildings (`members`, ascending), its building ids those of `city`:
/// the same whichever job builds it.
pub fn tile_tree(
    city: &City,
    blocks: &[u32],
    members: &[u32],
    params: &ClusterParams,
) -> Result<ClusterTree, ClusterError> {
    let tile_blocks: Vec<u32> = members.iter().map(|&i| blocks[i as usize]).collect();
    tree_of_tile(&tile_city(city, members), &tile_blocks, members, params)
}

/// One tile's buildings (`members`, ascending) as a city of their own, their ids their
/// positions in it; tags are left out (the tree reads none).
pub fn tile_city(city: &City, members: &[u32]) -> City {
    City {
        frame: city.frame.clone(),
        buildings: members
            .iter()
            .enumerate()
            .map(|(local, &i)| {
                let b = &city.buildings[i as usize];
                Building {
                    id: BuildingId(local as u32),
                    source_id: b.source_id.clone(),
                    footprint: b.footprint.clone(),
                    parts: b.parts.clone(),
                    base_m: b.base_m,
                    top_m: b.top_m,
                    height_source: b.height_source,
                    mesh: b.mesh.clone(),
                    tags: Default::default(),
                }
            })
            .collect(),
        streets: Vec::new(),
        ground_areas: Vec::new(),
        report: Default::default(),
    }
}

/// The tree of a tile's city ([`tile_city`]; `tile_blocks` its buildings' blocks), its
/// building ids mapped back to the city's through `members`.
pub fn tree_of_tile(
    tile: &City,
    tile_blocks: &[u32],
    members: &[u32],
    params: &ClusterParams,
) -> Result<ClusterTree, ClusterError> {
    let mut tree = build_cluster_tree(tile, tile_blocks, params)?;
    let global = |b: &mut BuildingId| *b = BuildingId(members[b.index()]);
    tree.building_order.iter_mut().for_each(global);
    for node in &mut tree.nodes {
        node.landmarks.iter_mut().for_each(global);
    }
    tree.stats.degenerate_buildings.iter_mut().for_each(global);
    Ok(tree)
}

/// A city with one building per tile: the tile root's hull as its footprint, from the
/// tile's lowest base to its highest top. Its tree is the top of the city's.
fn city_of_tile_roots(city: &City, subtrees: &[ClusterTree]) -> City {
    let buildings = subtrees
        .iter()
        .enumerate()
        .map(|(t, tree)| {
            let root = &tree.nodes[tree.root as usize];
            let ring: Vec<Coord<f64>> = root.footprint[0]
                .iter()
                .map(|&v| {
                    let [x, y] = tree.vertices[v as usize];
                    Coord { x, y }
                })
                .collect();
            let footprint = MultiPolygon(vec![Polygon::new(LineString::from(ring), Vec::new())]);
            let (base_m, top_m) = (root.bounds_min[2], root.bounds_max[2]);
            let source_id = format!("tile {t}");
            Building {
                id: BuildingId(t as u32),
                parts: vec![BuildingPart {
                    source_id: source_id.clone(),
                    footprint: footprint.clone(),
                    base_m,
                    top_m,
                }],
                source_id,
                footprint,
                base_m,
                top_m,
                height_source: HeightSource::Geometry,
                mesh: None,
                tags: Default::default(),
            }
        })
        .collect();
    City {
        frame: city.frame.clone(),
        buildings,
        streets: Vec::new(),
        ground_areas: Vec::new(),
        report: Default::default(),
    }
}

/// The city's tree: `top`'s inner nodes, each of its leaves replaced by its tile's tree, in
/// depth-first preorder; the inner nodes' data made from their children's.
fn graft(
    city: &City,
    top: ClusterTree,
    subtrees: Vec<ClusterTree>,
    params: &ClusterParams,
    settle: &dyn Fn(),
) -> ClusterTree {
    let ClusterTree {
        mut vertices,
        nodes: top_nodes,
        building_order: tile_order,
        stats: top_stats,
        ..
    } = top;
    let mut stats = ClusterStats::default();
    // Sized once: grown by doubling, the city's nodes (0.3 GB at a million buildings) would
    // be copied into a buffer of up to twice their size while the tiles' trees are still held.
    let mut nodes: Vec<ClusterNode> =
        Vec::with_capacity(top_nodes.len() + subtrees.iter().map(|t| t.nodes.len()).sum::<usize>());
    vertices.reserve_exact(subtrees.iter().map(|t| t.vertices.len()).sum());
    let mut building_order = Vec::with_capacity(city.buildings.len());
    let mut final_of_top = vec![0u32; top_nodes.len()];
    let mut tile_root = vec![0u32; subtrees.len()];
    // The nodes above the tiles (final ids).
    let mut above: Vec<usize> = Vec::new();
    let mut subtrees: Vec<Option<ClusterTree>> = subtrees.into_iter().map(Some).collect();
    for (u, node) in top_nodes.into_iter().enumerate() {
        let id = nodes.len() as u32;
        final_of_top[u] = id;
        if !node.is_leaf() {
            above.push(id as usize);
            nodes.push(node);
            continue;
        }
        let t = tile_order[node.buildings.0 as usize].index();
        let tree = subtrees[t]
            .take()
            .expect("every tile is one leaf of the top");
        tile_root[t] = id;
        let first_vertex = vertices.len() as u32;
        let first_building = building_order.len() as u32;
        vertices.extend_from_slice(&tree.vertices);
        for mut child in tree.nodes {
            child
                .footprint
                .iter_mut()
                .flatten()
                .for_each(|v| *v += first_vertex);
            child.children.iter_mut().for_each(|c| *c += id);
            child.buildings.0 += first_building;
            child.buildings.1 += first_building;
            child.depth += node.depth;
            nodes.push(child);
        }
        building_order.extend(tree.building_order);
        add_stats(&mut stats, tree.stats);
        settle();
    }
    add_stats(
        &mut stats,
        ClusterStats {
            multi_part_buildings: 0,
            degenerate_buildings: Vec::new(),
            ..top_stats
        },
    );
    stats.degenerate_buildings.sort_unstable();

    // Bottom-up over the nodes above the tiles (children follow their parent in preorder).
    let heights = error::building_heights(city, &building_order);
    let mut sums: Vec<NodeSums> = vec![(f32::INFINITY, 0.0, f32::INFINITY); nodes.len()];
    for &id in &tile_root {
        let (s, e) = nodes[id as usize].buildings;
        let (s, e) = (s as usize, e as usize);
        sums[id as usize] = range_sums(city, &building_order[s..e], &heights[s..e]);
    }
    for &id in above.iter().rev() {
        let node = &mut nodes[id];
        node.children
            .iter_mut()
            .for_each(|c| *c = final_of_top[*c as usize]);
        let children = node.children.clone();
        let child = |c: &u32| &nodes[*c as usize];
        let range = (
            child(&children[0]).buildings.0,
            child(children.last().expect("an inner node")).buildings.1,
        );
        let merge_distance = children
            .iter()
            .map(|c| child(c).merge_distance)
            .fold(nodes[id].merge_distance, f64::max);
        let block = child(&children[0]).block;
        let block = block.filter(|_| children.iter().all(|c| child(c).block == block));
        let node = &mut nodes[id];
        node.buildings = range;
        node.merge_distance = merge_distance;
        node.block = block;
        sums[id] = fill_inner_node(
            city,
            &vertices,
            &building_order,
            &sums,
            &mut nodes,
            id,
            params,
        );
    }

    // Their errors, measured on the buildings' footprints as in one tree ([`error::fill_errors`]),
    // bottom-up a depth at a time, then their meshes ([`super::build_meshes`]).
    let fp = error::Footprints::new(city, &building_order);
    let deepest = above.iter().map(|&id| nodes[id].depth).max().unwrap_or(0);
    let mut slack = vec![0.0f32; nodes.len()];
    for depth in (0..=deepest).rev() {
        let ids: Vec<usize> = above
            .iter()
            .copied()
            .filter(|&id| nodes[id].depth == depth)
            .collect();
        let errors: Vec<(f32, f32, f32)> = ids
            .par_iter()
            .map(|&id| error::node_errors(&fp, &vertices, &heights, &nodes, id))
            .collect();
        for (&id, (geometric, colour, node_slack)) in ids.iter().zip(errors) {
            nodes[id].geometric_error_m = geometric;
            nodes[id].colour_error_m = colour;
            slack[id] = node_slack;
        }
    }
    let meshes: Vec<_> = above
        .par_iter()
        .map(|&id| {
            let node = &nodes[id];
            let ring = simplify::cut_corners(&vertices, &node.footprint[0], f64::from(slack[id]));
            cluster_mesh(
                &vertices,
                &ring,
                sums[id].2.min(node.height_m),
                node.height_m,
            )
        })
        .collect();
    for (&id, mesh) in above.iter().zip(meshes) {
        nodes[id].mesh = mesh;
    }
    ClusterTree {
        vertices,
        nodes,
        root: 0,
        building_order,
        params: params.clone(),
        stats,
    }
}

/// The [`NodeSums`] of the buildings `order` (a tile root's), `heights` theirs.
fn range_sums(city: &City, order: &[BuildingId], heights: &[error::Heights]) -> NodeSums {
    let start = (f32::INFINITY, 0.0, f32::INFINITY);
    order.iter().zip(heights).fold(start, |acc, (b, h)| {
        let building = &city.buildings[b.index()];
        (
            acc.0.min(h.lowest_top_m),
            acc.1 + building.footprint.unsigned_area(),
            acc.2.min(building.base_m),
        )
    })
}

/// Adds a tile's (or the top's) counters to the city's; its merges are numbered after those
/// already counted.
fn add_stats(into: &mut ClusterStats, from: ClusterStats) {
    let first_merge = into.binary_inner_nodes;
    into.merge_fallbacks += from.merge_fallbacks;
    into.merge_fallback_log
        .extend(from.merge_fallback_log.into_iter().map(|mut f| {
            f.merge += first_merge;
            f
        }));
    into.simplify_fallbacks += from.simplify_fallbacks;
    into.multi_part_buildings += from.multi_part_buildings;
    into.degenerate_buildings.extend(from.degenerate_buildings);
    into.binary_inner_nodes += from.binary_inner_nodes;
}
