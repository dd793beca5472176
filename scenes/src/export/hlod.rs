//! The cluster tree cut into tiles of a 3D Tiles HLOD hierarchy (`refine: "REPLACE"`).
//!
//! A tile holds a *frontier* of tree nodes: a set of nodes none of which is below another,
//! together standing for the buildings under the tile. The root tile starts from the tree's
//! root; a child tile starts from the children of some of its parent's frontier clusters and
//! some of its parent's buildings. Each tile
//! refines its frontier greedily, the node of largest error first (as the runtime's LOD cut
//! does, Chang et al. 2008 §8), while its triangles stay within a budget, so a tile is one
//! content of sensible size rather than one node. Nodes whose cluster mesh is empty are always
//! refined: they show none of their buildings.
//!
//! Refinement replaces a tile by all its children, so everything of its frontier must be
//! covered by them: the children start from the children of its clusters and from its
//! buildings (leaves), grouped in leaf order into tiles near the budget. A tile's geometric
//! error is the largest error of its frontier's clusters (0 when it holds buildings only); the
//! tree's errors are monotone, so a child's is never above its parent's, as 3D Tiles requires.

use std::cmp::Ordering;
use std::collections::BinaryHeap;

use crate::cluster_tree::ClusterTree;

/// One tile: the draws of its content (ids of the GPU scene: a building id, or
/// `building_count + node` for a cluster mesh) and its children.
#[derive(Debug, Clone, PartialEq)]
pub struct HlodTile {
    pub draws: Vec<u32>,
    /// The content's error in metres: how far it departs from the full-detail city.
    pub geometric_error_m: f32,
    pub children: Vec<HlodTile>,
}

impl HlodTile {
    /// Tiles in this subtree, this one included.
    pub fn count(&self) -> usize {
        1 + self.children.iter().map(HlodTile::count).sum::<usize>()
    }
}

/// What the tiling reads of the scene: the tree, the number of buildings, and the triangles of
/// each draw id.
pub struct HlodInput<'a> {
    pub tree: &'a ClusterTree,
    pub building_count: u32,
    pub triangles: &'a dyn Fn(u32) -> u64,
    /// The error a node's cluster mesh departs from its buildings (metres).
    pub error_m: &'a dyn Fn(u32) -> f32,
}

impl std::fmt::Debug for HlodInput<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("HlodInput")
            .field("nodes", &self.tree.nodes.len())
            .field("building_count", &self.building_count)
            .finish_non_exhaustive()
    }
}

impl HlodInput<'_> {
    /// The draw id of tree node `node`: its building for a leaf, its cluster mesh otherwise.
    fn draw(&self, node: u32) -> u32 {
        let n = &self.tree.nodes[node as usize];
        if n.is_leaf() {
            self.tree.building_order[n.buildings.0 as usize].0
        } else {
            self.building_count + node
        }
    }

    fn is_leaf(&self, node: u32) -> bool {
        self.tree.nodes[node as usize].is_leaf()
    }
}

/// The HLOD tiles of `input.tree` with at most `max_triangles` triangles a tile where the tree
/// allows (a single cluster mesh or a tile of buildings may exceed it).
pub fn tile_tree(input: &HlodInput<'_>, max_triangles: u64) -> HlodTile {
    tile_from(input, vec![input.tree.root], max_triangles)
}

/// A node of the frontier waiting to be refined, largest error first.
struct Refinable {
    error_m: f32,
    node: u32,
}

impl PartialEq for Refinable {
    fn eq(&self, other: &Self) -> bool {
        self.cmp(other) == Ordering::Equal
    }
}

impl Eq for Refinable {}

impl PartialOrd for Refinable {
    fn partial_cmp(&self, other: &Self) -> Option<Ordering> {
        Some(self.cmp(other))
    }
}

impl Ord for Refinable {
    fn cmp(&self, other: &Self) -> Ordering {
        self.error_m
            .total_cmp(&other.error_m)
            .then(other.node.cmp(&self.node))
    }
}

/// The frontier being refined: its nodes (leaves and clusters with a mesh) and triangles.
struct Frontier<'a, 'b> {
    input: &'a HlodInput<'b>,
    leaves: Vec<u32>,
    clusters: BinaryHeap<Refinable>,
    triangles: u64,
}

impl Frontier<'_, '_> {
    /// Adds `node`, or its descendants in its place when its cluster mesh is empty.
    fn add(&mut self, node: u32) {
        let mut stack = vec![node];
        while let Some(node) = stack.pop() {
            if self.input.is_leaf(node) {
                self.triangles += (self.input.triangles)(self.input.draw(node));
                self.leaves.push(node);
                continue;
            }
            let triangles = (self.input.triangles)(self.input.draw(node));
            if triangles == 0 {
                stack.extend(self.input.tree.nodes[node as usize].children.iter().rev());
                continue;
            }
            self.triangles += triangles;
            self.clusters.push(Refinable {
                error_m: (self.input.error_m)(node),
                node,
            });
        }
    }
}

/// A child tile starts from at most this fraction of the budget ([`child_groups`]).
const GROUP_FRACTION: u64 = 4;

/// What the children of a tile with frontier `clusters` and `leaves` start from: the children of
/// the clusters and the leaves themselves, in leaf order (neighbours in the tree are
/// neighbours in the city), cut into groups of at most a [`GROUP_FRACTION`] of `max_triangles`
/// where one node's children allow. A child then has room to refine within the budget, as a
/// quadtree's child covers a quarter of its parent; one child per cluster instead would make
/// the deepest tiles a few hundred triangles each, and groups as large as the budget would make
/// every level nearly the whole city again.
fn child_groups(
    input: &HlodInput<'_>,
    clusters: &[Refinable],
    leaves: &[u32],
    max_triangles: u64,
) -> Vec<Vec<u32>> {
    let nodes = &input.tree.nodes;
    // (first building in leaf order, the nodes to start from, their triangles).
    let mut items: Vec<(u32, Vec<u32>, u64)> = clusters
        .iter()
        .map(|c| {
            let node = &nodes[c.node as usize];
            let triangles = node
                .children
                .iter()
                .map(|&k| (input.triangles)(input.draw(k)))
                .sum();
            (node.buildings.0, node.children.clone(), triangles)
        })
        .collect();
    items.extend(leaves.iter().map(|&leaf| {
        let triangles = (input.triangles)(input.draw(leaf));
        (nodes[leaf as usize].buildings.0, vec![leaf], triangles)
    }));
    items.sort_by_key(|(first, ..)| *first);
    let mut groups: Vec<Vec<u32>> = Vec::new();
    let mut current: Vec<u32> = Vec::new();
    let mut current_triangles = 0;
    for (_, start, triangles) in items {
        if !current.is_empty() && current_triangles + triangles > max_triangles / GROUP_FRACTION {
            groups.push(std::mem::take(&mut current));
            current_triangles = 0;
        }
        current.extend(start);
        current_triangles += triangles;
    }
    if !current.is_empty() {
        groups.push(current);
    }
    groups
}

fn tile_from(input: &HlodInput<'_>, start: Vec<u32>, max_triangles: u64) -> HlodTile {
    let mut frontier = Frontier {
        input,
        leaves: Vec::new(),
        clusters: BinaryHeap::new(),
        triangles: 0,
    };
    for node in start {
        frontier.add(node);
    }
    // Refine the largest error while the children fit the budget.
    while let Some(top) = frontier.clusters.peek() {
        let node = top.node;
        let own = (input.triangles)(input.draw(node));
        let children = &input.tree.nodes[node as usize].children;
        let mut trial = Frontier {
            input,
            leaves: Vec::new(),
            clusters: BinaryHeap::new(),
            triangles: 0,
        };
        for &c in children {
            trial.add(c);
        }
        if frontier.triangles - own + trial.triangles > max_triangles {
            break;
        }
        frontier.clusters.pop();
        frontier.triangles = frontier.triangles - own + trial.triangles;
        frontier.leaves.extend(trial.leaves);
        frontier.clusters.extend(trial.clusters);
    }
    let mut clusters: Vec<Refinable> = frontier.clusters.into_vec();
    clusters.sort_by_key(|c| c.node);
    let mut leaves = frontier.leaves;
    leaves.sort_unstable();
    let geometric_error_m = clusters.iter().map(|c| c.error_m).fold(0.0, f32::max);
    let mut draws: Vec<u32> = leaves.iter().map(|&n| input.draw(n)).collect();
    draws.extend(clusters.iter().map(|c| input.draw(c.node)));
    let children = if clusters.is_empty() {
        Vec::new()
    } else {
        child_groups(input, &clusters, &leaves, max_triangles)
            .into_iter()
            .map(|start| tile_from(input, start, max_triangles))
            .collect()
    };
    HlodTile {
        draws,
        geometric_error_m,
        children,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::city::BuildingId;
    use crate::cluster_tree::{ClusterNode, ClusterParams, ClusterStats};

    /// A complete binary tree over `2^levels` buildings; a node of depth d has error
    /// `2^(levels - d)`; leaves in building order.
    fn binary_tree(levels: u32) -> ClusterTree {
        let mut nodes = Vec::new();
        fn build(nodes: &mut Vec<ClusterNode>, lo: u32, hi: u32, levels: u32, depth: u32) -> u32 {
            let index = nodes.len() as u32;
            nodes.push(ClusterNode::bare(Vec::new(), (lo, hi), 0.0));
            if hi - lo > 1 {
                let mid = (lo + hi) / 2;
                let a = build(nodes, lo, mid, levels, depth + 1);
                let b = build(nodes, mid, hi, levels, depth + 1);
                nodes[index as usize].children = vec![a, b];
                nodes[index as usize].geometric_error_m = (1 << (levels - depth)) as f32;
            }
            nodes[index as usize].depth = depth;
            index
        }
        let n = 1u32 << levels;
        let root = build(&mut nodes, 0, n, levels, 0);
        ClusterTree {
            vertices: Vec::new(),
            nodes,
            root,
            building_order: (0..n).map(BuildingId).collect(),
            params: ClusterParams::default(),
            stats: ClusterStats::default(),
        }
    }

    /// Every building is drawn, at the finest tiles, exactly once along each root-to-leaf
    /// refinement; errors never grow from parent to child.
    fn check(tile: &HlodTile, building_count: u32, parent_error: f32, shown: &mut Vec<u32>) {
        assert!(tile.geometric_error_m <= parent_error);
        if tile.children.is_empty() {
            assert_eq!(
                tile.geometric_error_m, 0.0,
                "a final tile holds buildings only"
            );
            shown.extend(tile.draws.iter().copied());
            assert!(tile.draws.iter().all(|&d| d < building_count));
        }
        for c in &tile.children {
            check(c, building_count, tile.geometric_error_m, shown);
        }
    }

    #[test]
    fn tiles_cover_every_building_once_with_monotone_errors_within_budget() {
        let tree = binary_tree(8);
        let n = 256;
        // Buildings 12 triangles, a cluster 12 per building below it (an extruded box each).
        let triangles = |draw: u32| -> u64 {
            if draw < n {
                12
            } else {
                let node = &tree.nodes[(draw - n) as usize];
                12 * node.building_count() as u64 / 4
            }
        };
        let error = |node: u32| tree.nodes[node as usize].geometric_error_m;
        let input = HlodInput {
            tree: &tree,
            building_count: n,
            triangles: &triangles,
            error_m: &error,
        };
        for budget in [50, 200, 1000, 100_000] {
            let root = tile_tree(&input, budget);
            let mut shown = Vec::new();
            check(&root, n, f32::INFINITY, &mut shown);
            shown.sort_unstable();
            assert_eq!(shown, (0..n).collect::<Vec<_>>(), "budget {budget}");
            // Within budget but for a tile that could not refine what it starts from: the
            // root, or the children of one node (siblings).
            let mut parent = vec![u32::MAX; tree.nodes.len()];
            for (i, nd) in tree.nodes.iter().enumerate() {
                for &c in &nd.children {
                    parent[c as usize] = i as u32;
                }
            }
            let mut stack = vec![&root];
            while let Some(t) = stack.pop() {
                let tris: u64 = t.draws.iter().map(|&d| triangles(d)).sum();
                let parents: std::collections::BTreeSet<u32> = t
                    .draws
                    .iter()
                    .filter(|&&d| d >= n)
                    .map(|&d| parent[(d - n) as usize])
                    .collect();
                assert!(tris <= budget || parents.len() <= 1, "{tris} > {budget}");
                stack.extend(&t.children);
            }
            if budget >= 100_000 {
                // Everything fits one tile: the city at full detail.
                assert_eq!(root.count(), 1);
                assert_eq!(root.geometric_error_m, 0.0);
            } else {
                assert!(root.geometric_error_m > 0.0 && root.count() > 2);
            }
        }
    }

    #[test]
    fn an_empty_cluster_mesh_is_always_refined() {
        let tree = binary_tree(3);
        let n = 8;
        let root_draw = n + tree.root;
        let triangles = |draw: u32| -> u64 { if draw == root_draw { 0 } else { 12 } };
        let error = |node: u32| tree.nodes[node as usize].geometric_error_m;
        let input = HlodInput {
            tree: &tree,
            building_count: n,
            triangles: &triangles,
            error_m: &error,
        };
        // A budget of one mesh: the root tile would hold the (empty) root cluster alone.
        let root = tile_tree(&input, 12);
        assert!(!root.draws.contains(&root_draw));
        assert_eq!(root.draws.len(), 2, "the root's two children");
        let mut shown = Vec::new();
        check(&root, n, f32::INFINITY, &mut shown);
        shown.sort_unstable();
        assert_eq!(shown, (0..n).collect::<Vec<_>>());
    }
}
