//! The screen-space level-of-detail cut of the legibility cluster tree (CPU reference).
//!
//! This work is based on:
//! - Chang, Butkiewicz, Ziemkiewicz, Wartell, Pollard, Ribarsky: *Hierarchical simplification
//!   of city models to maintain urban legibility* (2008), §8: a cluster is not drawn (its
//!   children are examined instead) while the camera-facing faces of its negative-space box
//!   cover more than ε pixels; a landmark tolerance τ in pixels, projected to a world height
//!   τ_height at the cluster, draws buildings that rise more than τ_height above their cluster
//!   beside the cluster mesh.
//! - Yang, Zhang, Ma, Wang: *Interactive visualization of multi-resolution urban building
//!   models considering spatial cognition* (2011), §4: a node is refined while Δh > δh or
//!   Δa > δa, δh and δa being the screen tolerances δh_screen = 20 px and δa_screen = 200 px
//!   (the paper's experiments, §5) projected to world units at the node.
//!
//! **Projection** (both criteria): the distance `d` from the eye to the nearest point of the
//! node's bounds (0 inside them), and the camera's pixels per metre at that distance,
//! `height_px / (2·tan(fov_y/2)·d)`. Nearer means more pixels per metre, a larger projected
//! error and more refinement, so the cut is conservative for every point of the node and never
//! coarser for a closer camera. The tree's errors are monotone (a node's errors are at least its
//! children's), so every refined node's ancestors are refined too and the cut is consistent.
//!
//! **Culling**: nodes whose bounds lie outside the view frustum are dropped with everything
//! below them (hierarchical frustum culling on the tree), and optionally so are nodes whose
//! urban block the B-Quadtree culled (the tree records a node's block below the block level).
//!
//! The GPU side (cluster meshes next to the buildings in one scene) is [`scene`]; the cut
//! computed on the GPU, with hierarchical occlusion culling, is [`crate::hzb::tree_cull`], over
//! the flat arrays of [`gpu_tree`].

pub mod gpu_tree;
pub mod scene;

use citywalk_scenes::cluster_tree::{ClusterNode, ClusterTree};
use citywalk_scenes::frustum::{Containment, Frustum};
use glam::{Mat4, Vec3};

use crate::camera::Camera;

/// Which error measure decides refinement: citywalk's geometric error (the default) or one of
/// the two papers'.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum LodCriterion {
    /// citywalk's criterion (design, "Screen-space LOD"): refine while the node's error
    /// ([`ClusterNode::lod_error_m`]: how far the cluster mesh departs from its buildings in
    /// shape, `geometric_error_m`, and in colour, `colour_error_m`), projected at the nearest
    /// point of its bounds, exceeds `tolerance_px`. A drawn cluster then differs from the full
    /// scene only within about `tolerance_px` of an edge of the full frame (the bench measures
    /// this as `bound_violations`). No landmarks: the error already counts taller buildings.
    Geometric { tolerance_px: f32 },
    /// Chang et al. 2008 §8: negative-space box area in pixels against `epsilon_px`, landmark
    /// tolerance `tau_px`.
    Chang { epsilon_px: f32, tau_px: f32 },
    /// Yang et al. 2011 §4: Δh against `delta_h_px`, Δa against `delta_a_px` (a pixel area).
    Yang { delta_h_px: f32, delta_a_px: f32 },
}

impl LodCriterion {
    /// The geometric criterion's tolerance at street level (px): the brief's walkthrough error.
    pub const STREET_TOLERANCE_PX: f32 = 1.0;
    /// The geometric criterion's tolerance above the roofs (px): nothing can come close to the
    /// eye there.
    pub const ROOFS_TOLERANCE_PX: f32 = 2.0;
    /// The geometric criterion at street level.
    pub const GEOMETRIC_STREET: LodCriterion = LodCriterion::Geometric {
        tolerance_px: Self::STREET_TOLERANCE_PX,
    };
    /// The geometric criterion above the roofs.
    pub const GEOMETRIC_ROOFS: LodCriterion = LodCriterion::Geometric {
        tolerance_px: Self::ROOFS_TOLERANCE_PX,
    };
    /// Chang et al. §8 for a walkthrough: ε = 1 px (a cluster is drawn only where its
    /// negative-space box covers at most one pixel) and τ = 1 px (a building rising more than
    /// one pixel above its cluster is drawn as a landmark). citywalk's choice: the brief asks
    /// walkthroughs to stay within about 1 px of error.
    pub const CHANG_WALKTHROUGH: LodCriterion = LodCriterion::Chang {
        epsilon_px: 1.0,
        tau_px: 1.0,
    };
    /// Chang et al. §8 for a flyover: ε = 2 px, τ = 2 px (about 2 px of error).
    pub const CHANG_FLYOVER: LodCriterion = LodCriterion::Chang {
        epsilon_px: 2.0,
        tau_px: 2.0,
    };
    /// Chang et al. 2008 Fig. 13(b): ε = 100 px, τ = 2 px (the paper's simplified skyline,
    /// 243,381 → 15,826 polygons).
    pub const CHANG_PAPER: LodCriterion = LodCriterion::Chang {
        epsilon_px: 100.0,
        tau_px: 2.0,
    };
    /// Yang et al. 2011 §5: δh_screen = 20 px, δa_screen = 200 px.
    pub const YANG_PAPER: LodCriterion = LodCriterion::Yang {
        delta_h_px: 20.0,
        delta_a_px: 200.0,
    };

    /// Parses a criterion name of the command line: `auto` (`None`: the geometric preset by
    /// altitude, [`LodCriterion::for_altitude`]), `geometric-street`, `geometric-roofs`,
    /// `chang-walkthrough`, `chang-flyover`, `chang-paper`, `yang-paper`.
    pub fn parse(name: &str) -> Result<Option<LodCriterion>, String> {
        Ok(Some(match name.trim() {
            "auto" => return Ok(None),
            "geometric-street" => Self::GEOMETRIC_STREET,
            "geometric-roofs" => Self::GEOMETRIC_ROOFS,
            "chang-walkthrough" => Self::CHANG_WALKTHROUGH,
            "chang-flyover" => Self::CHANG_FLYOVER,
            "chang-paper" => Self::CHANG_PAPER,
            "yang-paper" => Self::YANG_PAPER,
            other => {
                return Err(format!(
                    "unknown LOD criterion '{other}' (auto, geometric-street, geometric-roofs, \
                     chang-walkthrough, chang-flyover, chang-paper, yang-paper)"
                ));
            }
        }))
    }

    /// The default criterion for a camera at `eye_z_m`: the geometric criterion at 2 px once the
    /// eye is above the tallest building top `scene_top_m` (nothing can come close to the eye),
    /// else at 1 px.
    pub fn for_altitude(eye_z_m: f32, scene_top_m: f32) -> LodCriterion {
        LodCriterion::Geometric {
            tolerance_px: Self::tolerance_for_altitude(eye_z_m, scene_top_m),
        }
    }

    /// The tolerance (px) of [`LodCriterion::for_altitude`]: 2 px above the roofs, else 1 px.
    pub fn tolerance_for_altitude(eye_z_m: f32, scene_top_m: f32) -> f32 {
        if eye_z_m > scene_top_m {
            Self::ROOFS_TOLERANCE_PX
        } else {
            Self::STREET_TOLERANCE_PX
        }
    }

    /// The pixel bound the criterion keeps: the geometric criterion's tolerance; `None` for
    /// Chang's and Yang's, which bound no distance on screen.
    pub fn bound_px(self) -> Option<f32> {
        match self {
            LodCriterion::Geometric { tolerance_px } => Some(tolerance_px),
            LodCriterion::Chang { .. } | LodCriterion::Yang { .. } => None,
        }
    }
}

/// The camera as the cut sees it.
#[derive(Debug, Clone, Copy)]
pub struct LodView {
    pub eye_m: Vec3,
    /// Vertical field of view (radians).
    pub fov_y_rad: f32,
    /// Viewport height in pixels.
    pub height_px: u32,
    /// Frustum to cull nodes with; `None` keeps every node (the cut then covers every building).
    pub frustum: Option<Frustum>,
}

impl LodView {
    /// The view of `camera` on a `width_px`×`height_px` viewport, with frustum culling.
    pub fn new(camera: &Camera, width_px: u32, height_px: u32) -> LodView {
        let aspect = width_px.max(1) as f32 / height_px.max(1) as f32;
        LodView {
            eye_m: camera.position,
            fov_y_rad: camera.fov_y_rad,
            height_px,
            frustum: Some(Frustum::from_view_proj(camera.view_proj(aspect))),
        }
    }

    /// The same view without frustum culling.
    pub fn without_culling(mut self) -> LodView {
        self.frustum = None;
        self
    }

    /// The frustum of `view_proj` replaces the current one.
    pub fn with_view_proj(mut self, view_proj: Mat4) -> LodView {
        self.frustum = Some(Frustum::from_view_proj(view_proj));
        self
    }

    /// Pixels per metre at distance `distance_m`, for something facing the camera. Infinite at
    /// distance 0 (the eye inside a node's bounds refines it whenever it has any error).
    pub fn px_per_m(&self, distance_m: f32) -> f32 {
        self.px_per_m_at_1m() / distance_m.max(0.0)
    }

    /// Pixels per metre at 1 m, `height_px / (2·tan(fov_y/2))`: [`LodView::px_per_m`] divides it
    /// by the distance (as the GPU's tree cull does, so both round alike).
    pub fn px_per_m_at_1m(&self) -> f32 {
        let half = (self.fov_y_rad * 0.5).tan().max(1e-6);
        self.height_px as f32 / (2.0 * half)
    }
}

/// The result of a cut: what to draw.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct LodCut {
    /// Inner nodes drawn with their cluster mesh, ascending.
    pub clusters: Vec<u32>,
    /// Buildings drawn with their own geometry (the leaves of the cut and the landmarks),
    /// ascending, without repeats.
    pub buildings: Vec<u32>,
    /// The buildings of `buildings` drawn as landmarks beside a drawn cluster that contains
    /// them (Chang et al. §8), ascending.
    pub landmarks: Vec<u32>,
}

impl LodCut {
    /// The number of buildings [`LodCut::covered_buildings`] lists, in the cut's size: the
    /// drawn clusters are disjoint, and the buildings of the cut under a drawn cluster are its
    /// landmarks.
    pub fn covered_count(&self, tree: &ClusterTree) -> usize {
        let in_clusters: usize = self
            .clusters
            .iter()
            .filter_map(|&c| tree.nodes.get(c as usize))
            .map(|n| n.buildings.1.saturating_sub(n.buildings.0) as usize)
            .sum();
        in_clusters + self.buildings.len() - self.landmarks.len()
    }

    /// Every building the cut shows, itself or through a drawn cluster containing it, ascending
    /// without repeats: the set to check against the visibility oracle.
    pub fn covered_buildings(&self, tree: &ClusterTree) -> Vec<u32> {
        let mut out = self.buildings.clone();
        for &c in &self.clusters {
            if let Some(node) = tree.nodes.get(c as usize) {
                let (s, e) = node.buildings;
                if let Some(range) = tree.building_order.get(s as usize..e as usize) {
                    out.extend(range.iter().map(|b| b.0));
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }
}

/// Distance from `p` to the nearest point of the box `[min, max]` (0 inside).
pub fn distance_to_box(p: Vec3, min: Vec3, max: Vec3) -> f32 {
    (min - p).max(p - max).max(Vec3::ZERO).length()
}

/// Chang et al. 2008 §8: screen area (px²) of the camera-facing faces of the negative-space box
/// `[w, d, h]` at `px_per_m`. Seen along a unit direction `v` the box covers
/// Σ |v_i|·A_i (A_i its three face areas); citywalk takes the largest value over all
/// directions, `|(A_yz, A_xz, A_xy)|`, so the error does not depend on the direction and a
/// nearer camera never gives a coarser cut (the paper does not say which direction it uses).
fn neg_space_px(node: &ClusterNode, px_per_m: f32) -> f32 {
    chang_area_m2(node) * px_per_m * px_per_m
}

/// The largest area (m²) the negative-space box of `node` shows from any direction,
/// `|(A_yz, A_xz, A_xy)|` ([`neg_space_px`] projects it).
pub fn chang_area_m2(node: &ClusterNode) -> f32 {
    let [w, d, h] = node.neg_space_box_m.map(|v| v.max(0.0));
    Vec3::new(d * h, w * h, w * d).length()
}

/// Whether `node` has any error (refined whenever the eye is inside its bounds).
pub fn has_error(node: &ClusterNode) -> bool {
    node.delta_h_m > 0.0
        || node.delta_a_m2 > 0.0
        || node.neg_space_box_m.iter().any(|v| *v > 0.0)
        || node.lod_error_m() > 0.0
}

/// Whether `node` (an inner node) must be refined at `px_per_m`.
fn refine(criterion: LodCriterion, node: &ClusterNode, px_per_m: f32) -> bool {
    if !px_per_m.is_finite() {
        // The eye is inside the node's bounds: refine anything with an error.
        return has_error(node);
    }
    match criterion {
        LodCriterion::Geometric { tolerance_px } => node.lod_error_m() * px_per_m > tolerance_px,
        LodCriterion::Chang { epsilon_px, .. } => neg_space_px(node, px_per_m) > epsilon_px,
        LodCriterion::Yang {
            delta_h_px,
            delta_a_px,
        } => {
            // δh, δa: the screen tolerances projected to metres (m²) at the node.
            let delta_h_m = delta_h_px / px_per_m;
            let delta_a_m2 = f64::from(delta_a_px / (px_per_m * px_per_m));
            node.delta_h_m > delta_h_m || node.delta_a_m2 > delta_a_m2
        }
    }
}

/// The urban blocks a frame may show ([`crate::runner::visible_blocks`], the B-Quadtree's
/// frustum cull): their ids, ascending, so that a frame costs what it sees, not one flag per
/// block of the city. A block id from `block_count` on (which no valid package has) counts as
/// visible: a damaged id never culls.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct VisibleBlocks {
    pub ids: Vec<u32>,
    pub block_count: u32,
}

impl VisibleBlocks {
    /// Whether the cut may show block `block`.
    pub fn contains(&self, block: u32) -> bool {
        block >= self.block_count || self.ids.binary_search(&block).is_ok()
    }
}

/// A cluster tree prepared for cuts: the leaf of every building (for landmark heights).
#[derive(Debug, Clone)]
pub struct LodTree {
    pub tree: ClusterTree,
    /// `leaf_of[b]` is the leaf node of building `b` (`u32::MAX` if none).
    leaf_of: Vec<u32>,
}

impl LodTree {
    pub fn new(tree: ClusterTree) -> LodTree {
        let mut leaf_of = vec![u32::MAX; tree.building_order.len()];
        for (i, node) in tree.nodes.iter().enumerate() {
            if node.is_leaf()
                && let Some(b) = tree.building_order.get(node.buildings.0 as usize)
                && let Some(slot) = leaf_of.get_mut(b.index())
            {
                *slot = i as u32;
            }
        }
        LodTree { tree, leaf_of }
    }

    /// The highest building top of the tree (metres; 0 for an empty tree).
    pub fn top_m(&self) -> f32 {
        self.tree
            .nodes
            .get(self.tree.root as usize)
            .map_or(0.0, |n| n.bounds_max[2])
    }

    /// Top of building `b` (metres), from its leaf.
    pub fn building_top_m(&self, b: u32) -> Option<f32> {
        let leaf = *self.leaf_of.get(b as usize)?;
        self.tree.nodes.get(leaf as usize).map(|n| n.h_max_m)
    }

    /// The cut for `view` under `criterion`. `visible_blocks`, when given, culls every node of
    /// an urban block it does not hold (e.g. the B-Quadtree found it outside the frustum).
    pub fn cut(
        &self,
        view: &LodView,
        criterion: LodCriterion,
        visible_blocks: Option<&VisibleBlocks>,
    ) -> LodCut {
        let tree = &self.tree;
        let mut cut = LodCut::default();
        let mut stack = vec![tree.root];
        while let Some(n) = stack.pop() {
            let Some(node) = tree.nodes.get(n as usize) else {
                continue;
            };
            if let (Some(visible), Some(block)) = (visible_blocks, node.block)
                && !visible.contains(block)
            {
                continue;
            }
            let (min, max) = (
                Vec3::from_array(node.bounds_min),
                Vec3::from_array(node.bounds_max),
            );
            if let Some(frustum) = &view.frustum
                && frustum.classify_aabb(min, max) == Containment::Outside
            {
                continue;
            }
            if node.is_leaf() {
                if let Some(b) = tree.building_order.get(node.buildings.0 as usize) {
                    cut.buildings.push(b.0);
                }
                continue;
            }
            let distance_m = distance_to_box(view.eye_m, min, max);
            let px_per_m = view.px_per_m(distance_m);
            if refine(criterion, node, px_per_m) {
                stack.extend(node.children.iter().rev());
                continue;
            }
            cut.clusters.push(n);
            if let LodCriterion::Chang { tau_px, .. } = criterion {
                // Chang et al. §8: τ projected to τ_height at the cluster.
                let tau_height_m = tau_px / px_per_m;
                for b in &node.landmarks {
                    if self
                        .building_top_m(b.0)
                        .is_some_and(|top| top - node.height_m > tau_height_m)
                    {
                        cut.landmarks.push(b.0);
                    }
                }
            }
        }
        cut.clusters.sort_unstable();
        cut.landmarks.sort_unstable();
        cut.landmarks.dedup();
        cut.buildings.extend_from_slice(&cut.landmarks);
        cut.buildings.sort_unstable();
        cut.buildings.dedup();
        cut
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn visible_blocks_hold_their_ids_and_every_id_past_the_count() {
        let visible = VisibleBlocks {
            ids: vec![2, 5, 9],
            block_count: 10,
        };
        assert!(visible.contains(2) && visible.contains(5) && visible.contains(9));
        assert!(!visible.contains(0) && !visible.contains(6));
        // A block id no package has is never culled.
        assert!(visible.contains(10) && visible.contains(u32::MAX));
    }

    #[test]
    fn distance_to_box_is_zero_inside_and_euclidean_outside() {
        let (lo, hi) = (Vec3::ZERO, Vec3::splat(10.0));
        assert_eq!(distance_to_box(Vec3::splat(5.0), lo, hi), 0.0);
        assert_eq!(distance_to_box(Vec3::new(13.0, 5.0, 14.0), lo, hi), 5.0);
        assert_eq!(distance_to_box(Vec3::new(-2.0, 5.0, 5.0), lo, hi), 2.0);
    }

    #[test]
    fn pixels_per_metre_follows_the_field_of_view() {
        let view = LodView {
            eye_m: Vec3::ZERO,
            fov_y_rad: std::f32::consts::FRAC_PI_2,
            height_px: 800,
            frustum: None,
        };
        // tan(45°) = 1: 800 px span 2·d metres.
        assert!((view.px_per_m(100.0) - 4.0).abs() < 1e-4);
        assert!((view.px_per_m(200.0) - 2.0).abs() < 1e-4);
        assert!(view.px_per_m(0.0).is_infinite());
    }

    #[test]
    fn criteria_refine_by_projected_error() {
        let node = ClusterNode {
            footprint: vec![],
            area_m2: 0.0,
            height_m: 10.0,
            h_min_m: 5.0,
            h_max_m: 15.0,
            delta_h_m: 10.0,
            delta_a_m2: 100.0,
            neg_space_box_m: [10.0, 10.0, 10.0],
            geometric_error_m: 4.0,
            colour_error_m: 3.0,
            bounds_min: [0.0; 3],
            bounds_max: [1.0; 3],
            children: vec![1],
            buildings: (0, 1),
            depth: 0,
            merge_distance: 0.0,
            landmarks: vec![],
            mesh: Default::default(),
            block: None,
        };
        // Chang: the 10 m cube shows at most √3·100 m²: 1.73 px² at 0.1 px/m, 6.9 px² at
        // 0.2 px/m.
        let chang = LodCriterion::Chang {
            epsilon_px: 2.0,
            tau_px: 1.0,
        };
        assert!(!refine(chang, &node, 0.1));
        assert!(refine(chang, &node, 0.2));
        // Yang: Δh = 10 m against 20 px: refine above 2 px/m; Δa = 100 m² against 200 px²:
        // refine above √2 px/m.
        let yang = LodCriterion::YANG_PAPER;
        assert!(!refine(yang, &node, 1.0));
        assert!(refine(yang, &node, 1.5));
        assert!(refine(yang, &node, f32::INFINITY));
        // Geometric: the larger error, 4 m, against 1 px: refine above 0.25 px/m.
        let geometric = LodCriterion::GEOMETRIC_STREET;
        assert!(!refine(geometric, &node, 0.2));
        assert!(refine(geometric, &node, 0.3));
        // The colour error counts when it is the larger.
        let colourful = ClusterNode {
            colour_error_m: 8.0,
            ..node.clone()
        };
        assert!(refine(geometric, &colourful, 0.2));
    }

    #[test]
    fn default_criterion_is_geometric_by_altitude() {
        assert_eq!(
            LodCriterion::for_altitude(1.7, 30.0),
            LodCriterion::GEOMETRIC_STREET
        );
        assert_eq!(
            LodCriterion::for_altitude(31.0, 30.0),
            LodCriterion::GEOMETRIC_ROOFS
        );
        assert_eq!(LodCriterion::parse("auto"), Ok(None));
        assert_eq!(
            LodCriterion::parse("geometric-roofs"),
            Ok(Some(LodCriterion::GEOMETRIC_ROOFS))
        );
        assert_eq!(LodCriterion::GEOMETRIC_STREET.bound_px(), Some(1.0));
        assert_eq!(LodCriterion::YANG_PAPER.bound_px(), None);
        assert!(LodCriterion::parse("geometric").is_err());
    }
}
