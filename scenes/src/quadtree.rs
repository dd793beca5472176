//! The B-Quadtree over urban blocks, and hierarchical frustum culling over it.
//!
//! This work is based on Pina, Serón, Cerezo, *Accelerating urban scenes visualization using a
//! quadtree decomposition of urban blocks* (§3): the smallest rectangle bounding the city is
//! split into four equal quadrants, recursively, while a quadrant holds two or more blocks; a
//! block crossing a split goes whole to one quadrant (here: the quadrant holding the centre of
//! its box); empty quadrants are not stored (an adaptive quadtree); leaves keep the bounding box
//! of their block, inner nodes the bounding sphere of their descendants' boxes; "a linear
//! codification based on a numeric key is used to identify all the elements of the tree".
//! Culling (§5) goes top-down, children in order (left to right).
//!
//! **Keys** (the path key of a linear quadtree): the root is `1`; the child in quadrant `q` of
//! a node with key `k` has key `4k + q`, with `q = east + 2·north` (0 south-west, 1
//! south-east, 2 north-west, 3 north-east). The depth is `(⌊log2 k⌋) / 2`, and the key alone
//! gives the quadrant's rectangle ([`BQuadtree::quadrant_of_key`]). Keys fit in a `u64` up to
//! [`MAX_DEPTH`] levels; blocks whose centres no split at that depth separates (or that are
//! equal) share one leaf.
//!
//! The tree is built by `citywalk_preprocess::quadtree::build_quadtree`.

use glam::Vec3;
use serde::{Deserialize, Serialize};

use crate::frustum::{Containment, Frustum};

/// Deepest level of the tree (keys use 2 bits per level plus a leading 1 in a `u64`).
pub const MAX_DEPTH: u32 = 30;

/// An axis-aligned box (local frame, metres).
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct Aabb {
    pub min: [f32; 3],
    pub max: [f32; 3],
}

impl Aabb {
    pub fn centre(&self) -> [f32; 3] {
        [
            0.5 * (self.min[0] + self.max[0]),
            0.5 * (self.min[1] + self.max[1]),
            0.5 * (self.min[2] + self.max[2]),
        ]
    }

    /// The eight corners.
    pub fn corners(&self) -> [Vec3; 8] {
        let (lo, hi) = (self.min, self.max);
        std::array::from_fn(|i| {
            Vec3::new(
                if i & 1 == 0 { lo[0] } else { hi[0] },
                if i & 2 == 0 { lo[1] } else { hi[1] },
                if i & 4 == 0 { lo[2] } else { hi[2] },
            )
        })
    }

    /// The smallest box holding both.
    pub fn union(&self, other: &Aabb) -> Aabb {
        Aabb {
            min: std::array::from_fn(|k| self.min[k].min(other.min[k])),
            max: std::array::from_fn(|k| self.max[k].max(other.max[k])),
        }
    }

    fn is_valid(&self) -> bool {
        (0..3).all(|k| {
            self.min[k].is_finite() && self.max[k].is_finite() && self.min[k] <= self.max[k]
        })
    }
}

/// What a node holds.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub enum QuadNodeKind {
    /// A subdivided quadrant: its non-empty children (indices into [`BQuadtree::nodes`], in
    /// quadrant order) and the bounding sphere of all boxes below it.
    Inner {
        children: Vec<u32>,
        sphere_centre: [f32; 3],
        sphere_radius: f32,
    },
    /// A quadrant holding one block (several only when no split can separate them): the
    /// block indices and the bounding box of their boxes.
    Leaf { blocks: Vec<u32>, bounds: Aabb },
}

/// One node or leaf.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct QuadNode {
    /// The linear path key (module documentation).
    pub key: u64,
    pub kind: QuadNodeKind,
}

impl QuadNode {
    /// Depth of a key (root 0).
    pub fn depth_of_key(key: u64) -> u32 {
        (63 - key.max(1).leading_zeros()) / 2
    }

    pub fn depth(&self) -> u32 {
        Self::depth_of_key(self.key)
    }
}

/// The B-Quadtree.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct BQuadtree {
    /// The root quadrant: the smallest rectangle bounding the blocks' boxes (x, y metres).
    pub root_min: [f64; 2],
    pub root_max: [f64; 2],
    /// Nodes in depth-first pre-order (children in quadrant order); node 0 is the root. Empty
    /// exactly when there are no blocks.
    pub nodes: Vec<QuadNode>,
    /// The bounding box of every block, by block index.
    pub block_bounds: Vec<Aabb>,
}

impl BQuadtree {
    /// The rectangle `(min, max)` of the quadrant with `key`.
    pub fn quadrant_of_key(&self, key: u64) -> ([f64; 2], [f64; 2]) {
        let depth = QuadNode::depth_of_key(key);
        let (mut lo, mut hi) = (self.root_min, self.root_max);
        for level in (0..depth).rev() {
            let q = (key >> (2 * level)) & 3;
            let mid = [0.5 * (lo[0] + hi[0]), 0.5 * (lo[1] + hi[1])];
            if q & 1 == 0 {
                hi[0] = mid[0];
            } else {
                lo[0] = mid[0];
            }
            if q & 2 == 0 {
                hi[1] = mid[1];
            } else {
                lo[1] = mid[1];
            }
        }
        (lo, hi)
    }

    /// Depth of the deepest node (0 for a single leaf or an empty tree).
    pub fn max_depth(&self) -> u32 {
        self.nodes.iter().map(QuadNode::depth).max().unwrap_or(0)
    }

    /// Number of leaves.
    pub fn leaf_count(&self) -> usize {
        self.nodes
            .iter()
            .filter(|n| matches!(n.kind, QuadNodeKind::Leaf { .. }))
            .count()
    }

    /// Hierarchical frustum culling (Pina et al. §5): top-down from the root, children in
    /// order; an inner node is tested by its sphere, a leaf's blocks by their boxes; a subtree
    /// whose sphere is fully inside is accepted without further tests. Returns the blocks not
    /// outside the frustum, in tree order. The result equals testing every block's box.
    pub fn cull(&self, frustum: &Frustum) -> Vec<u32> {
        let mut out = Vec::new();
        if !self.nodes.is_empty() {
            self.cull_node(0, frustum, &mut out);
        }
        out
    }

    fn cull_node(&self, index: u32, frustum: &Frustum, out: &mut Vec<u32>) {
        let Some(node) = self.nodes.get(index as usize) else {
            return;
        };
        match &node.kind {
            QuadNodeKind::Inner {
                children,
                sphere_centre,
                sphere_radius,
            } => match frustum.classify_sphere(Vec3::from_array(*sphere_centre), *sphere_radius) {
                Containment::Outside => {}
                Containment::Inside => self.collect_blocks(index, out),
                Containment::Intersecting => {
                    for &c in children {
                        self.cull_node(c, frustum, out);
                    }
                }
            },
            QuadNodeKind::Leaf { blocks, bounds } => {
                if blocks.len() == 1 {
                    if frustum
                        .classify_aabb(Vec3::from_array(bounds.min), Vec3::from_array(bounds.max))
                        != Containment::Outside
                    {
                        out.extend_from_slice(blocks);
                    }
                    return;
                }
                for &b in blocks {
                    if let Some(bb) = self.block_bounds.get(b as usize)
                        && frustum.classify_aabb(Vec3::from_array(bb.min), Vec3::from_array(bb.max))
                            != Containment::Outside
                    {
                        out.push(b);
                    }
                }
            }
        }
    }

    /// All blocks below node `index`, in tree order.
    pub fn collect_blocks(&self, index: u32, out: &mut Vec<u32>) {
        let Some(node) = self.nodes.get(index as usize) else {
            return;
        };
        match &node.kind {
            QuadNodeKind::Inner { children, .. } => {
                for &c in children {
                    self.collect_blocks(c, out);
                }
            }
            QuadNodeKind::Leaf { blocks, .. } => out.extend_from_slice(blocks),
        }
    }

    /// Brute force: every block whose box is not outside the frustum, ascending.
    pub fn cull_brute_force(&self, frustum: &Frustum) -> Vec<u32> {
        (0..self.block_bounds.len() as u32)
            .filter(|&b| {
                let bb = &self.block_bounds[b as usize];
                frustum.classify_aabb(Vec3::from_array(bb.min), Vec3::from_array(bb.max))
                    != Containment::Outside
            })
            .collect()
    }

    /// Checks the structure (Pina et al. §3 properties): keys are path keys in pre-order with
    /// children in quadrant order (so sibling quadrants are the distinct, disjoint quarters of
    /// their parent), every block is in exactly one leaf whose quadrant holds its centre, a
    /// leaf holds several blocks only when they cannot be split apart, inner nodes hold at
    /// least two blocks, leaf boxes hold their blocks' boxes and every inner sphere holds all
    /// boxes below it. Returns the first violation found.
    pub fn check_invariants(&self) -> Result<(), String> {
        let n_blocks = self.block_bounds.len();
        if self.nodes.is_empty() {
            return if n_blocks == 0 {
                Ok(())
            } else {
                Err(format!("{n_blocks} blocks but no nodes"))
            };
        }
        let ordered = self.root_min[0] <= self.root_max[0] && self.root_min[1] <= self.root_max[1];
        if !ordered
            || !self
                .root_min
                .iter()
                .chain(&self.root_max)
                .all(|v| v.is_finite())
        {
            return Err("root rectangle is not ordered and finite".into());
        }
        for (b, bb) in self.block_bounds.iter().enumerate() {
            if !bb.is_valid() {
                return Err(format!("block {b}: box not ordered and finite"));
            }
        }
        if self.nodes[0].key != 1 {
            return Err(format!("root key is {}", self.nodes[0].key));
        }
        let mut parent_of: Vec<Option<u32>> = vec![None; self.nodes.len()];
        let mut leaf_of_block: Vec<Option<u32>> = vec![None; n_blocks];
        for (i, node) in self.nodes.iter().enumerate() {
            match &node.kind {
                QuadNodeKind::Inner {
                    children,
                    sphere_centre,
                    sphere_radius,
                } => {
                    if children.is_empty() {
                        return Err(format!("inner node {i} has no children"));
                    }
                    if QuadNode::depth_of_key(node.key) >= MAX_DEPTH {
                        return Err(format!("inner node {i} at the maximum depth"));
                    }
                    let mut last_q: Option<u64> = None;
                    for &c in children {
                        let child = self
                            .nodes
                            .get(c as usize)
                            .ok_or_else(|| format!("node {i}: child {c} out of range"))?;
                        if c as usize <= i {
                            return Err(format!("node {i}: child {c} not after it (pre-order)"));
                        }
                        if child.key >> 2 != node.key {
                            return Err(format!(
                                "node {i} (key {}): child {c} has key {}",
                                node.key, child.key
                            ));
                        }
                        let q = child.key & 3;
                        if last_q.is_some_and(|l| l >= q) {
                            return Err(format!("node {i}: children not in quadrant order"));
                        }
                        last_q = Some(q);
                        if parent_of[c as usize].replace(i as u32).is_some() {
                            return Err(format!("node {c} has two parents"));
                        }
                    }
                    let centre = Vec3::from_array(*sphere_centre);
                    if !centre.is_finite() || !sphere_radius.is_finite() || *sphere_radius < 0.0 {
                        return Err(format!("node {i}: sphere not finite"));
                    }
                    let mut below = Vec::new();
                    self.collect_blocks(i as u32, &mut below);
                    if below.len() < 2 {
                        return Err(format!("inner node {i} holds {} blocks", below.len()));
                    }
                    for b in below {
                        let bb = self
                            .block_bounds
                            .get(b as usize)
                            .ok_or_else(|| format!("node {i}: block {b} out of range"))?;
                        for corner in bb.corners() {
                            let d = corner.distance(centre);
                            if d > *sphere_radius * (1.0 + 1e-6) + 1e-4 {
                                return Err(format!(
                                    "node {i}: sphere (r {sphere_radius}) misses block {b} by {}",
                                    d - sphere_radius
                                ));
                            }
                        }
                    }
                }
                QuadNodeKind::Leaf { blocks, bounds } => {
                    if blocks.is_empty() {
                        return Err(format!("leaf {i} is empty"));
                    }
                    let (lo, hi) = self.quadrant_of_key(node.key);
                    let mut centres = Vec::new();
                    for &b in blocks {
                        let slot = leaf_of_block
                            .get_mut(b as usize)
                            .ok_or_else(|| format!("leaf {i}: block {b} out of range"))?;
                        if slot.replace(i as u32).is_some() {
                            return Err(format!("block {b} is in two leaves"));
                        }
                        let bb = &self.block_bounds[b as usize];
                        for k in 0..3 {
                            if bb.min[k] < bounds.min[k] || bb.max[k] > bounds.max[k] {
                                return Err(format!("leaf {i}: box does not hold block {b}"));
                            }
                        }
                        let c = bb.centre();
                        let (cx, cy) = (f64::from(c[0]), f64::from(c[1]));
                        // f32 box centres: allow their rounding at the quadrant edges.
                        let slack = 1e-6 * (1.0 + cx.abs().max(cy.abs()));
                        if cx < lo[0] - slack
                            || cx > hi[0] + slack
                            || cy < lo[1] - slack
                            || cy > hi[1] + slack
                        {
                            return Err(format!(
                                "block {b}: centre ({cx}, {cy}) outside its leaf {i}'s quadrant"
                            ));
                        }
                        centres.push(c);
                    }
                    if blocks.len() > 1
                        && node.depth() < MAX_DEPTH
                        && centres.iter().any(|c| c[..2] != centres[0][..2])
                    {
                        return Err(format!("leaf {i} holds {} separable blocks", blocks.len()));
                    }
                }
            }
        }
        for (i, p) in parent_of.iter().enumerate().skip(1) {
            if p.is_none() {
                return Err(format!("node {i} has no parent"));
            }
        }
        if let Some(b) = leaf_of_block.iter().position(Option::is_none) {
            return Err(format!("block {b} is in no leaf"));
        }
        Ok(())
    }
}
