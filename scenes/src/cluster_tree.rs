//! The legibility cluster tree: the data the preprocessing writes and the runtime LOD cut reads.
//!
//! This work is based on:
//! - Chang, Butkiewicz, Ziemkiewicz, Wartell, Pollard, Ribarsky: *Hierarchical simplification
//!   of city models to maintain urban legibility* (2008) — single-link clustering, hull
//!   merging and simplification, cluster height (eq. 5; citywalk puts the roof where its
//!   vertical error is least), negative-space error box (§8) and landmark tolerance τ.
//! - Yang, Zhang, Ma, Wang: *Interactive visualization of multi-resolution urban building
//!   models considering spatial cognition* (2011) — adjacent distance, one shared vertex
//!   array (§3.3.1), depth reduction and balancing (§3.3.2), Δh / Δa errors (§4).
//!
//! The tree is built by `citywalk_preprocess::cluster::build_cluster_tree` and stored in the
//! scene package. A leaf is one building; an inner node is a cluster whose footprint (the
//! merged, simplified hull) contains the footprints of everything below it.
//!
//! **Errors are monotone**: for every node, each error measure (`delta_h_m`, `delta_a_m2`,
//! each side of `neg_space_box_m`, `geometric_error_m`, `colour_error_m`) is at least the same measure of each child,
//! so a cut that refines a node whenever its error exceeds a tolerance is consistent. The
//! builder enforces this by taking the maximum with the children where the raw value is lower
//! (this only ever overstates an error, so the cut stays conservative).

pub mod ring;

use serde::{Deserialize, Serialize};

use crate::city::{BuildingId, City, TriangleMesh};

/// Distance used by the single-link clustering.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum ClusterDistance {
    /// Chang et al. 2008 eq. 1: size-weighted minimum distance,
    /// `size(C1)·size(C2)/avgClusterSize² · min d(x, y)`.
    ChangSizeWeighted,
    /// Yang et al. 2011 §3.1: adjacent distance `d_min·(1 − N·λ)`.
    YangAdjacent,
}

/// How two cluster hulls are merged.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum HullMerge {
    /// Yang et al. 2011 §3.2: connection pairs from a constrained Delaunay triangulation.
    YangDelaunay,
    /// Chang et al. 2008 §5: disjoint / bisecting / intersecting / contained cases.
    ChangCases,
}

/// How a merged hull is simplified.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum HullSimplify {
    /// Chang et al. 2008 §5: remove the vertex adding the smallest area, down to
    /// max(2/3 of the children's edges, 1 % of the input edges, the convex hull's count).
    ChangSmallestArea,
    /// Yang et al. 2011 §3.2: remove concave triangles under δa = a_ave /
    /// [`ClusterParams::concave_area_divisor`], then vertices between edges at more than 175°.
    YangConcaveTriangles,
}

/// Parameters of the cluster tree; stored with the tree so a package records how it was built.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterParams {
    pub distance: ClusterDistance,
    pub merge: HullMerge,
    pub simplify: HullSimplify,
    /// Yang et al. 2011 §3.1, λ = 0.6: weight of the adjacency ratio N in the adjacent distance.
    pub adjacency_lambda: f64,
    /// Yang et al. 2011 §3.2, δa = a_ave / 50: divisor of the mean cluster area. citywalk's
    /// default is 20: hulls with fewer small concave notches draw the far views with 15–20 %
    /// fewer triangles at the same pixel error and geometric bound (generated 100k, seeds 1
    /// and 5: BENCHMARKS.md "Far views under 5 %"); 10 and 30 did about as well, 5 and 2
    /// worse, their larger plan errors refining the cut further.
    pub concave_area_divisor: f64,
    /// Yang et al. 2011 §3.2: vertices between edges at more than this angle are removed (175°).
    pub straight_angle_deg: f64,
    /// Chang et al. 2008 §5: a merged hull keeps at least this fraction of its children's
    /// edges (2/3).
    pub chang_keep_fraction: f64,
    /// Chang et al. 2008 §5: ... and at least this fraction of the input's edges (1 %).
    pub chang_min_input_fraction: f64,
    /// Yang et al. 2011 §3.3.2: reduce the binary merge tree to about `log2(n)/λ` levels
    /// (λ = 1.5 in the paper's experiments) and balance it. `None` keeps the binary tree.
    pub depth_lambda: Option<f64>,
    /// Chang et al. 2008 §8 landmarks: a building is a landmark candidate of a cluster when its
    /// top is at least this factor times the cluster's height above ground (citywalk default
    /// 1.5; the runtime then applies the pixel tolerance τ).
    pub landmark_height_ratio: f64,
}

impl Default for ClusterParams {
    fn default() -> Self {
        ClusterParams {
            distance: ClusterDistance::YangAdjacent,
            merge: HullMerge::YangDelaunay,
            simplify: HullSimplify::YangConcaveTriangles,
            adjacency_lambda: 0.6,
            concave_area_divisor: 20.0,
            straight_angle_deg: 175.0,
            chang_keep_fraction: 2.0 / 3.0,
            chang_min_input_fraction: 0.01,
            depth_lambda: Some(1.5),
            landmark_height_ratio: 1.5,
        }
    }
}

/// Why a hull merge could not use the construction its method and case call for.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub enum MergeFailure {
    /// Disjoint hulls: no connection-edge pair gave a simple ring containing both.
    NoValidBridge,
    /// Touching or overlapping hulls: the trace of the union's outer outline did not close.
    UnionTraceFailed,
    /// The union's outer outline is not a simple ring (the hulls touch at isolated points,
    /// so the outline passes a vertex twice).
    UnionNotSimple,
    /// The union's outline does not contain both hulls (rounding of an intersection point).
    UnionMissesChild,
    /// Chang's candidate-list heuristic (lists with n×m ≤ 12) found no valid pair of
    /// connection edges; larger lists go to the full hull search without a failure.
    HeuristicFailed,
    /// Chang's full hull search (convex hull, then inverse simplification) could not carve a
    /// valid ring: the result is the plain convex hull.
    CarvingFailed,
}

/// One merge whose first construction failed, and what it fell back to.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Serialize, Deserialize)]
pub struct MergeFallback {
    /// Index of the merge in the binary merge order (the merge created binary node n + k); in a
    /// tree built tile by tile, the tiles' merges are numbered in tile order, then those of the
    /// tree above the tiles.
    pub merge: u32,
    /// Why the first construction failed.
    pub reason: MergeFailure,
    /// Whether the final ring is the plain convex hull of both hulls (counted in
    /// [`ClusterStats::merge_fallbacks`]); otherwise Chang's full hull search carved it.
    pub convex_hull: bool,
}

/// Counters of the build (how often a fallback was needed, what was reported).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct ClusterStats {
    /// Merges whose result is the plain convex hull of the union (every construction,
    /// including Chang's full hull search, failed); each is listed in `merge_fallback_log`.
    pub merge_fallbacks: u32,
    /// Every merge whose first construction failed, with its reason (Chang's full hull search
    /// is then used, and the convex hull only if that fails too).
    pub merge_fallback_log: Vec<MergeFallback>,
    /// Simplifications abandoned (the merged ring kept) because the result was not a simple
    /// ring; growth-only simplification should never need this.
    pub simplify_fallbacks: u32,
    /// Buildings whose leaf is the convex hull of their footprint: footprints of several
    /// polygons, and rings that are not simple (self-intersecting, such as a bow-tie). A
    /// polygon with holes keeps its exterior ring and is not counted.
    pub multi_part_buildings: u32,
    /// Buildings whose footprint was degenerate (no area) and whose leaf uses the footprint's
    /// bounding box grown by 0.25 m instead; listed by id.
    pub degenerate_buildings: Vec<BuildingId>,
    /// Number of inner nodes before depth reduction.
    pub binary_inner_nodes: u32,
}

/// One node of the cluster tree.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterNode {
    /// Footprint rings as indices into [`ClusterTree::vertices`]; the outer ring first,
    /// counter-clockwise, not closed (the last index is not a repeat of the first). Cluster
    /// hulls have one ring.
    ///
    /// **Holes are filled**: a hull is only the outer ring of its region. Courtyards and the
    /// enclosed gaps between buildings that a merge closes off (and the holes of a building's
    /// own footprint, in its leaf ring) are part of the hull. That is conservative for a hull —
    /// it contains everything below it, and the filled area counts in the negative-space
    /// errors `delta_a_m2` / `neg_space_box_m`, so the LOD cut refines it when it shows — and
    /// the cluster mesh is a closed extrusion without inner walls.
    pub footprint: Vec<Vec<u32>>,
    /// Footprint (hull) area in m².
    pub area_m2: f64,
    /// The cluster mesh's roof height (metres): midway between its buildings' lowest roof
    /// point and highest top, within their tops (citywalk's choice, the least vertical error;
    /// Chang et al. 2008 eq. 5 uses the area-weighted mean). A leaf's is its building's top.
    pub height_m: f32,
    /// Lowest building top in the node (metres).
    pub h_min_m: f32,
    /// Highest building top in the node (metres).
    pub h_max_m: f32,
    /// Yang et al. 2011 §4: Δh = h_max − h_min (metres), made monotone.
    pub delta_h_m: f32,
    /// Yang et al. 2011 §4: Δa = hull area − Σ building footprint areas (m²), made monotone.
    pub delta_a_m2: f64,
    /// Chang et al. 2008 §8: the negative-space box `[width_m, depth_m, height_m]`: the
    /// negative-space area laid out with the aspect of the hull's bounding box, as tall as the
    /// cluster; the runtime projects it and refines while it covers more than ε pixels.
    pub neg_space_box_m: [f32; 3],
    /// citywalk's geometric error (metres), the quantity 3D Tiles calls `geometricError`: how far
    /// the cluster mesh departs from the buildings it replaces, `√(vertical² + plan²)` of the
    /// largest vertical departure (its roof above or below a building's top, its walls below a
    /// building's base) and the largest plan distance from a point of the hull to the
    /// buildings' footprints; made monotone. 0 for leaves (drawn as the building itself).
    pub geometric_error_m: f32,
    /// How far a point of the untextured cluster mesh, drawn in one colour, can be from an edge
    /// of the buildings it replaces (metres): the largest inradius of a face of a building's
    /// bounding box, half its second-smallest side. Textured clusters will lower it. 0 for
    /// leaves.
    pub colour_error_m: f32,
    /// Axis-aligned bounds of everything below the node (buildings' full heights).
    pub bounds_min: [f32; 3],
    pub bounds_max: [f32; 3],
    /// Child node indices; empty for a leaf (one building).
    pub children: Vec<u32>,
    /// `building_order[buildings.0 .. buildings.1]` are the buildings below this node.
    pub buildings: (u32, u32),
    /// Depth below the root (root = 0).
    pub depth: u32,
    /// Clustering distance at which this node was formed (0 for leaves).
    pub merge_distance: f64,
    /// Buildings below this node that are much taller than the cluster (landmark candidates,
    /// Chang et al. 2008 §8); drawn beside the cluster mesh when their projected excess
    /// height exceeds τ. Empty for leaves.
    pub landmarks: Vec<BuildingId>,
    /// The hull extruded to `height_m` (walls and a constrained-Delaunay roof); empty for
    /// leaves, which are drawn with the building's own geometry.
    ///
    /// Not serialized: a package stores the cluster meshes once, in its GPU scene, and a full
    /// decode restores them from there ([`crate::package::format`]).
    #[serde(skip)]
    pub mesh: TriangleMesh,
    /// The urban block of the node's buildings, or `None` above the block level.
    pub block: Option<u32>,
}

impl ClusterNode {
    pub fn is_leaf(&self) -> bool {
        self.children.is_empty()
    }

    /// Number of buildings below the node.
    pub fn building_count(&self) -> usize {
        (self.buildings.1 - self.buildings.0) as usize
    }

    /// The error the default LOD criterion projects (metres): the larger of the geometric and
    /// the colour error, so a drawn cluster stays within the tolerance in shape and in colour.
    pub fn lod_error_m(&self) -> f32 {
        self.geometric_error_m.max(self.colour_error_m)
    }

    /// Volume of the negative-space box (m³), Chang's error measure.
    pub fn neg_space_volume_m3(&self) -> f64 {
        self.neg_space_box_m.iter().map(|v| f64::from(*v)).product()
    }
}

#[cfg(test)]
impl ClusterNode {
    /// A node for tests: `children` over `buildings` (a range of the building order), error
    /// `error_m`, everything else zero or empty.
    pub(crate) fn bare(children: Vec<u32>, buildings: (u32, u32), error_m: f32) -> ClusterNode {
        ClusterNode {
            footprint: Vec::new(),
            area_m2: 0.0,
            height_m: 0.0,
            h_min_m: 0.0,
            h_max_m: 0.0,
            delta_h_m: 0.0,
            delta_a_m2: 0.0,
            neg_space_box_m: [0.0; 3],
            geometric_error_m: error_m,
            colour_error_m: 0.0,
            bounds_min: [0.0; 3],
            bounds_max: [0.0; 3],
            children,
            buildings,
            depth: 0,
            merge_distance: 0.0,
            landmarks: Vec::new(),
            mesh: Default::default(),
            block: None,
        }
    }
}

/// The legibility cluster tree of a city.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct ClusterTree {
    /// One shared vertex array for all footprints (Yang et al. 2011 §3.3.1), local metres.
    pub vertices: Vec<[f64; 2]>,
    pub nodes: Vec<ClusterNode>,
    pub root: u32,
    /// Leaf order: every node's buildings are a contiguous range of this array.
    pub building_order: Vec<BuildingId>,
    pub params: ClusterParams,
    pub stats: ClusterStats,
}

impl ClusterTree {
    /// Frees the footprints and their shared vertex array. Drawing never reads them (the cut
    /// reads bounds and errors, the cluster meshes are in the GPU scene); at a million
    /// buildings they are a quarter of a gigabyte. A tree without footprints no longer passes
    /// [`ClusterTree::check_invariants`]: this is for a package decoded to draw
    /// ([`crate::package::Decode::Runtime`]).
    pub fn drop_footprints(&mut self) {
        self.vertices = Vec::new();
        for node in &mut self.nodes {
            node.footprint = Vec::new();
        }
    }

    /// The nodes at depth `level` plus the leaves shallower than it: a complete cut.
    pub fn cut_at_level(&self, level: u32) -> Vec<u32> {
        let mut out = Vec::new();
        let mut stack = vec![self.root];
        while let Some(n) = stack.pop() {
            let Some(node) = self.nodes.get(n as usize) else {
                continue;
            };
            if node.depth >= level || node.is_leaf() {
                out.push(n);
            } else {
                stack.extend(node.children.iter().rev());
            }
        }
        out
    }

    /// Depth of the deepest node.
    pub fn max_depth(&self) -> u32 {
        self.nodes.iter().map(|n| n.depth).max().unwrap_or(0)
    }

    /// A node's ring as coordinates.
    pub fn ring_coords(&self, ring: &[u32]) -> Vec<[f64; 2]> {
        ring.iter()
            .filter_map(|&i| self.vertices.get(i as usize).copied())
            .collect()
    }
}

impl ClusterTree {
    /// Checks the tree's invariants against the city it was built from; returns the first
    /// violation found:
    /// - `building_order` is a permutation of the city's buildings; every leaf holds exactly
    ///   one building; every inner node's range is the concatenation of its children's;
    /// - child depths are parent depth + 1; every node but the root has exactly one parent;
    /// - every footprint ring is a simple counter-clockwise polygon on `vertices`;
    /// - every node's footprint contains its children's footprints, and every leaf's footprint
    ///   contains its building's footprint (so, transitively, each node contains its buildings);
    ///   containment is exact up to [`ring::CONTAIN_TOL_M`] (1 µm), the rounding of inserted
    ///   intersection points;
    /// - errors are monotone: Δh, Δa, each side of the negative-space box, the geometric and
    ///   the colour error are at least the children's (Yang's, Chang's and citywalk's measures);
    /// - height is within [h_min, h_max]; bounds contain the children's bounds.
    pub fn check_invariants(&self, city: &City) -> Result<(), String> {
        use ring::{Side, locate, ring_contains_ring, ring_is_simple_ccw};
        let n = city.buildings.len();
        if self.building_order.len() != n {
            return Err(format!(
                "building_order has {} of {n} buildings",
                self.building_order.len()
            ));
        }
        let mut seen = vec![false; n];
        for b in &self.building_order {
            match seen.get_mut(b.index()) {
                Some(s) if !*s => *s = true,
                _ => {
                    return Err(format!(
                        "building {b:?} missing or repeated in building_order"
                    ));
                }
            }
        }
        let root = self
            .nodes
            .get(self.root as usize)
            .ok_or("root out of range")?;
        if root.depth != 0 || root.buildings != (0, n as u32) {
            return Err(format!(
                "root has depth {} and range {:?}",
                root.depth, root.buildings
            ));
        }
        let mut parents = vec![0u32; self.nodes.len()];
        for (i, node) in self.nodes.iter().enumerate() {
            let fail = |what: String| Err(format!("node {i}: {what}"));
            let Some(outer) = node.footprint.first() else {
                return fail("no footprint".into());
            };
            if node
                .footprint
                .iter()
                .flatten()
                .any(|&v| v as usize >= self.vertices.len())
            {
                return fail("vertex index out of range".into());
            }
            if !ring_is_simple_ccw(&self.vertices, outer) {
                return fail(format!(
                    "footprint {outer:?} is not a simple counter-clockwise ring"
                ));
            }
            if !(node.h_min_m <= node.height_m + 1e-3 && node.height_m <= node.h_max_m + 1e-3) {
                return fail(format!(
                    "height {} outside [{}, {}]",
                    node.height_m, node.h_min_m, node.h_max_m
                ));
            }
            if node.children.is_empty() {
                if node.buildings.1 != node.buildings.0 + 1 {
                    return fail(format!("leaf with range {:?}", node.buildings));
                }
                let b = self.building_order[node.buildings.0 as usize];
                let building = &city.buildings[b.index()];
                for poly in &building.footprint.0 {
                    for c in &poly.exterior().0 {
                        if locate(&self.vertices, outer, [c.x, c.y]) == Side::Outside {
                            return fail(format!(
                                "building {b:?} corner ({}, {}) outside its leaf",
                                c.x, c.y
                            ));
                        }
                    }
                }
                continue;
            }
            let mut next = node.buildings.0;
            for &c in &node.children {
                let child = self
                    .nodes
                    .get(c as usize)
                    .ok_or(format!("node {i}: child {c} out of range"))?;
                parents[c as usize] += 1;
                if child.depth != node.depth + 1 {
                    return fail(format!("child {c} at depth {}", child.depth));
                }
                if child.buildings.0 != next || child.buildings.1 <= child.buildings.0 {
                    return fail(format!(
                        "child {c} range {:?} not contiguous",
                        child.buildings
                    ));
                }
                next = child.buildings.1;
                let Some(cring) = child.footprint.first() else {
                    return fail(format!("child {c} has no footprint"));
                };
                if !ring_contains_ring(&self.vertices, outer, cring) {
                    return fail(format!("footprint does not contain child {c}"));
                }
                if child.delta_h_m > node.delta_h_m
                    || child.delta_a_m2 > node.delta_a_m2
                    || (0..3).any(|k| child.neg_space_box_m[k] > node.neg_space_box_m[k])
                    || child.geometric_error_m > node.geometric_error_m
                    || child.colour_error_m > node.colour_error_m
                {
                    return fail(format!("error smaller than child {c}'s"));
                }
                if (0..3).any(|k| {
                    child.bounds_min[k] < node.bounds_min[k]
                        || child.bounds_max[k] > node.bounds_max[k]
                }) {
                    return fail(format!("bounds do not contain child {c}'s"));
                }
            }
            if next != node.buildings.1 {
                return fail(format!(
                    "children cover up to {next}, range {:?}",
                    node.buildings
                ));
            }
        }
        for (i, &p) in parents.iter().enumerate() {
            let want = u32::from(i as u32 != self.root);
            if p != want {
                return Err(format!("node {i} has {p} parents"));
            }
        }
        Ok(())
    }
}
