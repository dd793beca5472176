//! What one frame culled, as its report reads it: the candidates (every building of a scene,
//! or the buildings and cluster meshes of a LOD cut), the lists the GPU wrote of them (those the
//! early entry point drew, those the cull kept) with its counts of the rest, and how they become
//! the frame's statistics and the CPU copy of the visible buildings. Everything here is
//! O(what was drawn): a frame of a million candidates that draws thirty reads and walks thirty.
//!
//! **Visibility across LOD cuts.** A candidate kept by the cull makes every building it covers
//! (a building itself; a cluster, every building under it) visible for the next frame: on the
//! GPU through the stamps and the draw-id parents ([`crate::frame::Visibility`]), here in the CPU
//! copy the same way. A *building* candidate is drawn early when it was visible last frame,
//! whether it was drawn itself then or through a cluster. A *cluster* candidate is never drawn
//! early: the pyramid must be built from depth that the full-detail scene would hide at least as
//! much as (the ground, buildings, occluders contained in buildings), and a cluster mesh is not
//! contained in its buildings (it fills the negative space between them). Clusters therefore
//! always go through the cull, which tests the box of everything they stand for
//! ([`crate::lod::scene::LodScene::cull_records_buffer`]).

use citywalk_scenes::cluster_tree::ClusterTree;
use citywalk_shaders::BuildingRecord;

use crate::frame::{FrameOutput, FrameStats, Visibility};
use crate::lod::scene::{LodScene, covered_by};

/// What a LOD cut's candidates need of its scene ([`LodScene`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct LodSource<'a> {
    /// Buildings of the scene; draw id `building_count + n` is cluster node `n`.
    pub building_count: u32,
    /// Per draw id, its draw record (the cull tests [`LodScene::cull_records_buffer`]'s, whose
    /// index ranges are the same; the CPU reads only those).
    pub records: &'a [BuildingRecord],
    pub tree: &'a ClusterTree,
}

impl<'a> LodSource<'a> {
    pub fn of(lod: &'a LodScene) -> LodSource<'a> {
        LodSource {
            building_count: lod.building_count,
            records: &lod.gpu_scene.records,
            tree: &lod.tree.tree,
        }
    }
}

/// The cull's report of one frame ([`crate::hzb::HzbCull::report_buffer`]): candidate indices
/// the early entry point drew and the cull kept, and the counts of those it hid.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub(super) struct CullLists {
    /// Candidates the early pass drew, ascending.
    pub early: Vec<u32>,
    /// Candidates the cull found visible, ascending.
    pub kept: Vec<u32>,
    /// Candidates the cull found occluded (the others it did not keep lie outside the frustum).
    pub occluded: u32,
    /// Candidates visible last frame that the occluder gate kept out of the early pass (0
    /// without the gate: the frustum-only entry draws all it takes).
    pub gate_culled: u32,
}

impl CullLists {
    /// The lists as the GPU appended them (in any order): sorted, each index once.
    pub fn new(mut early: Vec<u32>, mut kept: Vec<u32>, occluded: u32, gate_culled: u32) -> Self {
        for list in [&mut early, &mut kept] {
            list.sort_unstable();
            list.dedup();
        }
        CullLists {
            early,
            kept,
            occluded,
            gate_culled,
        }
    }
}

/// The candidates of one frame, with what the GPU's report says of them.
#[derive(Debug)]
pub(super) struct Candidates<'a> {
    /// Records by draw id: the scene's buildings, or a LOD scene's cull records.
    records: &'a [BuildingRecord],
    lists: CullLists,
    /// The LOD scene and the draw id of each candidate, for a LOD cut; `None`: candidate `i` is
    /// building `i`.
    lod: Option<(LodSource<'a>, &'a [u32])>,
    building_count: usize,
}

impl<'a> Candidates<'a> {
    /// Every building of a scene (`records`), with the frame's `lists`.
    pub fn all_buildings(records: &'a [BuildingRecord], lists: CullLists) -> Candidates<'a> {
        Candidates {
            records,
            lists,
            lod: None,
            building_count: records.len(),
        }
        .within_range()
    }

    /// The buildings and clusters of a LOD cut, `draw_ids`
    /// ([`crate::lod::scene::LodFrame::draw_ids`]), with the frame's `lists`.
    pub fn lod(lod: LodSource<'a>, draw_ids: &'a [u32], lists: CullLists) -> Candidates<'a> {
        Candidates {
            records: lod.records,
            lists,
            lod: Some((lod, draw_ids)),
            building_count: lod.building_count as usize,
        }
        .within_range()
    }

    /// Drops listed indices past the candidates (the GPU lists none; a report of another frame
    /// shape must not index out of range).
    fn within_range(mut self) -> Self {
        let n = self.len() as u32;
        self.lists.early.retain(|&i| i < n);
        self.lists.kept.retain(|&i| i < n);
        self
    }

    pub fn len(&self) -> usize {
        match &self.lod {
            None => self.records.len(),
            Some((_, ids)) => ids.len(),
        }
    }

    /// The draw id of candidate `i`.
    fn draw_id(&self, i: u32) -> u32 {
        match &self.lod {
            None => i,
            Some((_, ids)) => ids[i as usize],
        }
    }

    /// The record the cull tested for candidate `i` (zeroed for a draw id out of range: the
    /// shader clamps such an id, and it draws nothing the report should count).
    fn record(&self, i: u32) -> BuildingRecord {
        self.records
            .get(self.draw_id(i) as usize)
            .copied()
            .unwrap_or_else(bytemuck::Zeroable::zeroed)
    }

    /// Appends to `out` every building candidate `i` covers.
    fn push_covered(&self, i: u32, out: &mut Vec<u32>) {
        match &self.lod {
            None => out.push(i),
            Some((lod, ids)) => {
                out.extend(covered_by(lod.tree, lod.building_count, ids[i as usize]))
            }
        }
    }

    /// The cluster node of candidate `i` when it is a cluster mesh (a LOD cut's inner node).
    fn cluster_node(&self, i: u32) -> Option<u32> {
        let (lod, ids) = self.lod.as_ref()?;
        ids[i as usize].checked_sub(lod.building_count)
    }

    /// Buildings that are real (below the building count), ascending, each once.
    fn buildings(&self, mut ids: Vec<u32>) -> Vec<u32> {
        ids.retain(|&b| (b as usize) < self.building_count);
        ids.sort_unstable();
        ids.dedup();
        ids
    }

    /// The CPU copy of the buildings visible for the next frame: those the kept candidates
    /// cover, as the GPU's stamps say.
    pub fn update_visibility(&self, visibility: &mut Visibility) {
        let mut visible = Vec::with_capacity(self.lists.kept.len());
        for &i in &self.lists.kept {
            self.push_covered(i, &mut visible);
        }
        visibility.mirror_ids(self.buildings(visible));
    }

    /// The frame's counts and drawn buildings; `late_commands_all`: the late pass walks every
    /// candidate's command (no draw count).
    pub fn statistics(&self, late_commands_all: bool) -> FrameOutput {
        let CullLists {
            early,
            kept,
            occluded,
            gate_culled,
        } = &self.lists;
        let candidates = self.len() as u32;
        let cull_kept = kept.len() as u32;
        let occlusion_culled = (*occluded).min(candidates - cull_kept);
        let early_drawn = early.len() as u32;
        let mut stats = FrameStats {
            building_count: self.building_count as u32,
            candidates,
            early_drawn,
            gate_culled: *gate_culled,
            cull_kept,
            occlusion_culled,
            frustum_culled: candidates - cull_kept - occlusion_culled,
            // The ground and the early draws.
            draw_calls: 1 + early_drawn,
            ..FrameStats::default()
        };
        // The drawn candidates: early, then kept ones the early pass did not draw (late).
        let late = kept
            .iter()
            .copied()
            .filter(|i| early.binary_search(i).is_err());
        let drawn_candidates: Vec<(u32, bool)> = early
            .iter()
            .map(|&i| (i, true))
            .chain(late.map(|i| (i, false)))
            .collect();
        // Per building: drawn itself, drawn through a cluster.
        let mut itself = Vec::new();
        let mut through_cluster = Vec::new();
        let mut clusters = Vec::new();
        let mut drawn_early = Vec::new();
        for &(i, was_early) in &drawn_candidates {
            let r = self.record(i);
            let cluster = self.cluster_node(i);
            if !was_early {
                stats.late_drawn += 1;
                if r.index_count > 0 {
                    stats.draw_calls += 1;
                }
            }
            // A cluster with an empty mesh shows none of its buildings: counting them as drawn
            // would hide a false cull from the benchmark.
            if cluster.is_some() && r.index_count == 0 {
                continue;
            }
            stats.triangles += u64::from(r.index_count / 3);
            match cluster {
                Some(node) => {
                    clusters.push(node);
                    self.push_covered(i, &mut through_cluster);
                }
                None => {
                    self.push_covered(i, &mut itself);
                    if was_early {
                        drawn_early.push(self.draw_id(i));
                    }
                }
            }
        }
        let itself = self.buildings(itself);
        let through_cluster = self.buildings(through_cluster);
        let mut drawn = itself.clone();
        drawn.extend_from_slice(&through_cluster);
        let drawn = self.buildings(drawn);
        stats.drawn = drawn.len() as u32;
        stats.clusters_drawn = clusters.len() as u32;
        stats.buildings_through_clusters = (drawn.len() - itself.len()) as u32;
        stats.late_commands = if late_commands_all {
            stats.candidates
        } else {
            stats.cull_kept
        };
        clusters.sort_unstable();
        drawn_early.sort_unstable();
        FrameOutput {
            drawn,
            drawn_early,
            drawn_themselves: itself,
            lod_cut: self.lod.is_some(),
            occluders: Vec::new(),
            clusters,
            stats,
        }
    }
}

#[cfg(test)]
mod tests {
    use citywalk_scenes::BuildingId;
    use citywalk_scenes::cluster_tree::{ClusterNode, ClusterParams, ClusterStats};

    use super::*;
    use crate::hzb::cull::{CULL_FRUSTUM_OUTSIDE, CULL_NOT_EARLY, CULL_OCCLUDED, CULL_VISIBLE};

    /// The report the GPU writes for a frame whose early entry gave `early_status` and whose
    /// cull gave `status` (one per candidate), listed in reverse as atomics may append them.
    fn report(early_status: &[u32], status: &[u32]) -> CullLists {
        let listed = |statuses: &[u32]| -> Vec<u32> {
            (0..statuses.len() as u32)
                .rev()
                .filter(|&i| statuses[i as usize] == CULL_VISIBLE)
                .collect()
        };
        let count = |statuses: &[u32], f: fn(u32) -> bool| -> u32 {
            statuses.iter().filter(|&&s| f(s)).count() as u32
        };
        CullLists::new(
            listed(early_status),
            listed(status),
            count(status, |s| s == CULL_OCCLUDED),
            count(early_status, |s| s != CULL_VISIBLE && s != CULL_NOT_EARLY),
        )
    }

    /// A 10 m cube record at `x` metres along the view axis.
    fn record(x: f32) -> BuildingRecord {
        BuildingRecord {
            bounds_min_m: [x, -5.0, 0.0],
            first_index: 0,
            bounds_max_m: [x + 10.0, 5.0, 10.0],
            index_count: 36,
            base_vertex: 0,
            vertex_count: 8,
            first_part: 0,
            part_count: 0,
        }
    }

    fn node(children: Vec<u32>, buildings: (u32, u32)) -> ClusterNode {
        ClusterNode {
            footprint: vec![],
            area_m2: 0.0,
            height_m: 10.0,
            h_min_m: 10.0,
            h_max_m: 10.0,
            delta_h_m: 0.0,
            delta_a_m2: 0.0,
            neg_space_box_m: [0.0; 3],
            geometric_error_m: 0.0,
            colour_error_m: 0.0,
            bounds_min: [0.0; 3],
            bounds_max: [0.0; 3],
            children,
            buildings,
            depth: 0,
            merge_distance: 0.0,
            landmarks: vec![],
            mesh: Default::default(),
            block: None,
        }
    }

    /// Three buildings; buildings 2 and 0 (in that leaf order) under cluster node 2, building 1
    /// alone under the root.
    fn scene() -> (ClusterTree, Vec<BuildingRecord>) {
        let tree = ClusterTree {
            vertices: vec![],
            nodes: vec![
                node(vec![], (0, 1)),
                node(vec![], (1, 2)),
                node(vec![0, 1], (0, 2)),
                node(vec![], (2, 3)),
                node(vec![2, 3], (0, 3)),
            ],
            root: 4,
            building_order: vec![BuildingId(2), BuildingId(0), BuildingId(1)],
            params: ClusterParams::default(),
            stats: ClusterStats::default(),
        };
        // Records: the three buildings, then one per node (cluster 2's covers 20..60 m).
        let mut records = vec![record(20.0), record(40.0), record(50.0)];
        records.extend((0..5).map(|_| record(20.0)));
        records[3 + 2].bounds_max_m[0] = 60.0;
        (tree, records)
    }

    /// The LOD source of [`scene`]'s tree and records.
    fn source<'a>(tree: &'a ClusterTree, records: &'a [BuildingRecord]) -> LodSource<'a> {
        LodSource {
            building_count: 3,
            records,
            tree,
        }
    }

    #[test]
    fn visibility_and_statistics_are_kept_per_building_across_cuts() {
        let (tree, records) = scene();
        let lod = source(&tree, &records);
        let mut visibility = Visibility::default();

        // Coarse cut: cluster 2 (buildings 2 and 0) and building 1. Nothing seen yet: nothing
        // early.
        let coarse = [1, 3 + 2];
        let status = [CULL_OCCLUDED, CULL_VISIBLE];
        let c = Candidates::lod(
            lod,
            &coarse,
            report(&[CULL_NOT_EARLY, CULL_NOT_EARLY], &status),
        );
        assert_eq!(c.len(), 2);
        assert!(c.lists.early.is_empty());
        c.update_visibility(&mut visibility);
        assert_eq!(visibility.visible_ids(), vec![0, 2]);
        let out = c.statistics(false);
        assert_eq!(out.drawn, vec![0, 2]);
        assert_eq!(out.clusters, vec![2]);
        assert!(out.drawn_early.is_empty());
        let s = &out.stats;
        assert_eq!((s.candidates, s.cull_kept, s.occlusion_culled), (2, 1, 1));
        assert_eq!((s.clusters_drawn, s.buildings_through_clusters), (1, 2));
        assert_eq!((s.late_drawn, s.draw_calls, s.late_commands), (1, 2, 1));

        // The cut refines the cluster; the GPU drew buildings 0 and 2 early (seen through the
        // cluster). Building 2 turned out hidden: drawn (early) this frame, not visible next.
        let fine = [0, 1, 2];
        let status = [CULL_VISIBLE, CULL_VISIBLE, CULL_OCCLUDED];
        let c = Candidates::lod(
            lod,
            &fine,
            report(&[CULL_VISIBLE, CULL_NOT_EARLY, CULL_VISIBLE], &status),
        );
        assert_eq!(c.lists.early, vec![0, 2]);
        c.update_visibility(&mut visibility);
        assert_eq!(visibility.visible_ids(), vec![0, 1]);
        let out = c.statistics(true);
        assert_eq!(out.drawn, vec![0, 1, 2]);
        assert_eq!(out.drawn_early, vec![0, 2]);
        assert!(out.clusters.is_empty());
        let s = &out.stats;
        assert_eq!((s.early_drawn, s.late_drawn, s.drawn), (2, 1, 3));
        assert_eq!((s.clusters_drawn, s.buildings_through_clusters), (0, 0));
        assert_eq!(s.late_commands, 3);
        assert_eq!(s.triangles, 3 * 12);
        assert_eq!(s.draw_calls, 1 + 2 + 1, "ground, two early, one late");
    }

    /// The occluder gate's statuses: a candidate the early entry took but did not draw (the
    /// gate's cull status) was kept out, and the main cull's keeping it makes it a late draw.
    #[test]
    fn the_gate_keeps_early_only_what_it_kept() {
        let (tree, records) = scene();
        let lod = source(&tree, &records);
        // Cut: building 2, cluster 2 (never early), building 0, building 1. The gate drew
        // buildings 2 and 1 and kept building 0 out; the main cull then finds building 0
        // visible (a late draw) and hides the cluster and building 1 (drawn early all the same).
        let cut = [2, 3 + 2, 0, 1];
        let c = Candidates::lod(
            lod,
            &cut,
            report(
                &[CULL_VISIBLE, CULL_NOT_EARLY, CULL_OCCLUDED, CULL_VISIBLE],
                &[CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE, CULL_OCCLUDED],
            ),
        );
        assert_eq!(c.lists.early, vec![0, 3]);
        assert_eq!(c.lists.gate_culled, 1);
        let out = c.statistics(false);
        let s = &out.stats;
        assert_eq!((s.early_drawn, s.late_drawn, s.drawn), (2, 1, 3));
        assert_eq!(s.gate_culled, 1);
        assert_eq!(out.drawn, vec![0, 1, 2]);
        assert_eq!(out.drawn_early, vec![1, 2]);
        assert_eq!(s.draw_calls, 3 + 1, "ground, two early, one late");
    }

    #[test]
    fn every_building_is_a_candidate_without_a_cut() {
        let (_, records) = scene();
        let scene_records = &records[..3];
        let status = [CULL_VISIBLE, CULL_FRUSTUM_OUTSIDE, CULL_OCCLUDED];
        let c = Candidates::all_buildings(
            scene_records,
            report(&[CULL_VISIBLE, CULL_NOT_EARLY, CULL_VISIBLE], &status),
        );
        let mut visibility = Visibility::default();
        c.update_visibility(&mut visibility);
        assert_eq!(visibility.visible_ids(), vec![0]);
        let out = c.statistics(false);
        assert_eq!(out.drawn, vec![0, 2]);
        assert_eq!(out.drawn_early, vec![0, 2]);
        let s = &out.stats;
        assert_eq!(
            (s.frustum_culled, s.occlusion_culled, s.cull_kept),
            (1, 1, 1)
        );
        assert_eq!(s.buildings_through_clusters, 0);
    }

    /// A report naming candidates past the frame's (another frame's shape) counts none of them
    /// and never indexes out of range.
    #[test]
    fn listed_indices_past_the_candidates_are_ignored() {
        let (_, records) = scene();
        let lists = CullLists::new(vec![7, 0], vec![0, 9, u32::MAX], 1, 0);
        let c = Candidates::all_buildings(&records[..3], lists);
        let out = c.statistics(false);
        assert_eq!(out.drawn, vec![0]);
        let s = &out.stats;
        assert_eq!((s.candidates, s.cull_kept, s.occlusion_culled), (3, 1, 1));
        assert_eq!((s.frustum_culled, s.early_drawn, s.late_drawn), (1, 1, 0));
    }
}
