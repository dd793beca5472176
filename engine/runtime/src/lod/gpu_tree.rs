//! The cluster tree as the GPU's LOD cut reads it ([`crate::hzb::tree_cull`]): one flat record
//! per node ([`TreeNode`]: bounds, children range, parent, errors), the children and landmark
//! lists, and each building's leaf. Built once when a LOD scene is uploaded.
//!
//! The refinement test here, [`refines`], is the one the CPU reference of the tree cull
//! ([`crate::hzb::reference::tree_cull`]) and the shader (`tree_refines` in
//! `shaders/wgsl/hzb_cull.wgsl`) compute, with the same operations in the same order as
//! [`crate::lod::LodTree::cut`]'s, so the three agree up to the GPU's rounding.

use citywalk_shaders::constants::{
    NO_PARENT, TREE_CRITERION_CHANG, TREE_CRITERION_GEOMETRIC, TREE_CRITERION_YANG,
};
use citywalk_shaders::{TreeCullParams, TreeLandmark, TreeNode};
use glam::Vec3;

use crate::lod::{LodCriterion, LodTree, LodView, chang_area_m2, distance_to_box, has_error};

/// The flat arrays of a cluster tree.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct TreeArrays {
    pub nodes: Vec<TreeNode>,
    pub children: Vec<u32>,
    pub landmarks: Vec<TreeLandmark>,
    /// Per building, its leaf node ([`NO_PARENT`] for none).
    pub leaf_of: Vec<u32>,
    pub root: u32,
    /// Levels of the tree (its depth plus one; 0 when empty).
    pub levels: u32,
}

impl TreeArrays {
    /// The arrays of `tree` over `building_count` buildings.
    pub fn build(tree: &LodTree, building_count: u32) -> TreeArrays {
        let t = &tree.tree;
        let mut parent = vec![NO_PARENT; t.nodes.len()];
        for (n, node) in t.nodes.iter().enumerate() {
            for &c in &node.children {
                if let Some(p) = parent.get_mut(c as usize) {
                    *p = n as u32;
                }
            }
        }
        let mut out = TreeArrays {
            leaf_of: vec![NO_PARENT; building_count as usize],
            root: t.root,
            ..TreeArrays::default()
        };
        for (n, node) in t.nodes.iter().enumerate() {
            let building = if node.is_leaf() {
                t.building_order
                    .get(node.buildings.0 as usize)
                    .map_or(NO_PARENT, |b| b.0)
            } else {
                NO_PARENT
            };
            if let Some(slot) = out.leaf_of.get_mut(building as usize) {
                *slot = n as u32;
            }
            let first_landmark = out.landmarks.len() as u32;
            out.landmarks.extend(node.landmarks.iter().filter_map(|b| {
                Some(TreeLandmark {
                    building: b.0,
                    top_m: tree.building_top_m(b.0)?,
                })
            }));
            let first_child = out.children.len() as u32;
            out.children.extend_from_slice(&node.children);
            out.levels = out.levels.max(node.depth + 1);
            out.nodes.push(TreeNode {
                bounds_min_m: node.bounds_min,
                first_child,
                bounds_max_m: node.bounds_max,
                child_count: node.children.len() as u32,
                parent: parent[n],
                building,
                building_count: node.buildings.1.saturating_sub(node.buildings.0),
                first_landmark,
                landmark_count: out.landmarks.len() as u32 - first_landmark,
                height_m: node.height_m,
                chang_area_m2: chang_area_m2(node),
                delta_h_m: node.delta_h_m,
                delta_a_m2: node.delta_a_m2 as f32,
                has_error: u32::from(has_error(node)),
                lod_error_m: node.lod_error_m(),
                _pad: 0,
            });
        }
        out
    }
}

/// The view and criterion part of the tree cull's uniforms (the caller fills in the lists,
/// queue and frame fields).
pub fn tree_params(view: &LodView, criterion: LodCriterion, building_count: u32) -> TreeCullParams {
    let (kind, a, b) = match criterion {
        LodCriterion::Geometric { tolerance_px } => (TREE_CRITERION_GEOMETRIC, tolerance_px, 0.0),
        LodCriterion::Chang { epsilon_px, tau_px } => (TREE_CRITERION_CHANG, epsilon_px, tau_px),
        LodCriterion::Yang {
            delta_h_px,
            delta_a_px,
        } => (TREE_CRITERION_YANG, delta_h_px, delta_a_px),
    };
    TreeCullParams {
        eye_m: view.eye_m.to_array(),
        px_per_m_at_1m: view.px_per_m_at_1m(),
        criterion: kind,
        tolerance_a: a,
        tolerance_b: b,
        building_count,
        ..bytemuck::Zeroable::zeroed()
    }
}

/// Pixels per metre at the nearest point of `node`'s bounds; 0 with the eye inside them.
pub fn px_per_m(node: &TreeNode, params: &TreeCullParams) -> f32 {
    let d = distance_to_box(
        Vec3::from_array(params.eye_m),
        Vec3::from_array(node.bounds_min_m),
        Vec3::from_array(node.bounds_max_m),
    );
    if d <= 0.0 {
        0.0
    } else {
        params.px_per_m_at_1m / d
    }
}

/// Whether inner node `node` is refined under `params` (the shader's `tree_refines`).
pub fn refines(node: &TreeNode, params: &TreeCullParams) -> bool {
    let ppm = px_per_m(node, params);
    if ppm <= 0.0 {
        return node.has_error != 0;
    }
    if params.criterion == TREE_CRITERION_GEOMETRIC {
        return node.lod_error_m * ppm > params.tolerance_a;
    }
    if params.criterion == TREE_CRITERION_CHANG {
        return node.chang_area_m2 * ppm * ppm > params.tolerance_a;
    }
    node.delta_h_m > params.tolerance_a / ppm || node.delta_a_m2 > params.tolerance_b / (ppm * ppm)
}

#[cfg(test)]
mod tests {
    use citywalk_scenes::BuildingId;
    use citywalk_scenes::cluster_tree::{ClusterNode, ClusterParams, ClusterStats, ClusterTree};

    use super::*;

    fn node(children: Vec<u32>, buildings: (u32, u32), depth: u32, x: f32) -> ClusterNode {
        ClusterNode {
            footprint: vec![],
            area_m2: 100.0,
            height_m: 10.0,
            h_min_m: 10.0,
            h_max_m: if children.is_empty() { 10.0 + x } else { 40.0 },
            delta_h_m: if children.is_empty() { 0.0 } else { 30.0 },
            delta_a_m2: if children.is_empty() { 0.0 } else { 50.0 },
            neg_space_box_m: if children.is_empty() {
                [0.0; 3]
            } else {
                [5.0, 5.0, 10.0]
            },
            geometric_error_m: if children.is_empty() { 0.0 } else { 12.0 },
            colour_error_m: if children.is_empty() { 0.0 } else { 5.0 },
            bounds_min: [x, 0.0, 0.0],
            bounds_max: [x + 10.0, 10.0, 40.0],
            children,
            buildings,
            depth,
            merge_distance: 0.0,
            landmarks: vec![],
            mesh: Default::default(),
            block: None,
        }
    }

    #[test]
    fn arrays_hold_parents_children_leaves_and_levels() {
        let mut root = node(vec![1, 2], (0, 2), 0, 0.0);
        root.landmarks = vec![BuildingId(1)];
        let tree = ClusterTree {
            nodes: vec![
                root,
                node(vec![], (0, 1), 1, 0.0),
                node(vec![], (1, 2), 1, 20.0),
            ],
            root: 0,
            building_order: vec![BuildingId(1), BuildingId(0)],
            vertices: vec![],
            params: ClusterParams::default(),
            stats: ClusterStats::default(),
        };
        let arrays = TreeArrays::build(&LodTree::new(tree), 2);
        assert_eq!(arrays.levels, 2);
        assert_eq!(arrays.children, vec![1, 2]);
        assert_eq!(arrays.nodes[0].parent, NO_PARENT);
        assert_eq!((arrays.nodes[1].parent, arrays.nodes[2].parent), (0, 0));
        assert_eq!((arrays.nodes[1].building, arrays.nodes[2].building), (1, 0));
        assert_eq!(arrays.leaf_of, vec![2, 1]);
        assert_eq!(arrays.nodes[0].building, NO_PARENT);
        assert_eq!(arrays.nodes[0].building_count, 2);
        // Building 1's top comes from its leaf (node 1: 10 + 0 m).
        assert_eq!(
            arrays.landmarks,
            vec![TreeLandmark {
                building: 1,
                top_m: 10.0
            }]
        );
        assert_eq!(arrays.nodes[0].has_error, 1);
        assert_eq!(arrays.nodes[1].has_error, 0);
        assert_eq!(
            (arrays.nodes[0].lod_error_m, arrays.nodes[1].lod_error_m),
            (12.0, 0.0)
        );
    }

    #[test]
    fn geometric_refinement_matches_the_cpu_cut() {
        // The root's 12 m error, seen from 100 m to 20 km away at 1 px: the flat test and the
        // CPU cut refine alike (refine while 12 m · px/m > 1 px, up to about 5.3 km here).
        let tree = LodTree::new(ClusterTree {
            nodes: vec![
                node(vec![1, 2], (0, 2), 0, 0.0),
                node(vec![], (0, 1), 1, 0.0),
                node(vec![], (1, 2), 1, 20.0),
            ],
            root: 0,
            building_order: vec![BuildingId(0), BuildingId(1)],
            vertices: vec![],
            params: ClusterParams::default(),
            stats: ClusterStats::default(),
        });
        let arrays = TreeArrays::build(&tree, 2);
        let mut refined = [false; 2];
        for d in [100.0, 1000.0, 5000.0, 20_000.0] {
            let view = LodView {
                eye_m: Vec3::new(5.0, -d, 20.0),
                fov_y_rad: 1.0,
                height_px: 481,
                frustum: None,
            };
            let params = tree_params(&view, LodCriterion::GEOMETRIC_STREET, 2);
            let gpu = refines(&arrays.nodes[0], &params);
            let cpu = tree
                .cut(&view, LodCriterion::GEOMETRIC_STREET, None)
                .clusters
                .is_empty();
            assert_eq!(gpu, cpu, "at {d} m");
            refined[usize::from(gpu)] = true;
        }
        assert_eq!(refined, [true, true], "both outcomes occur");
    }
}
