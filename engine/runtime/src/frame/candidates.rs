//! What one frame culled, as its report reads it: the candidates (every building of a scene,
//! or the buildings and cluster meshes of a LOD cut), which of them the early pass drew (the
//! early entry point's status, from the GPU), and how the cull's status of each candidate becomes
//! the frame's statistics and the CPU copy of the visible buildings.
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
use crate::hzb::cull::{CULL_FRUSTUM_OUTSIDE, CULL_NOT_EARLY, CULL_OCCLUDED, CULL_VISIBLE};
use crate::lod::scene::{LodScene, covered_by};

/// What the candidates of a LOD cut need of its scene ([`LodScene`]).
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

/// The candidates of one frame, with what the early entry point did with each.
#[derive(Debug)]
pub(super) struct Candidates<'a> {
    /// Records by draw id: the scene's buildings, or a LOD scene's cull records.
    records: &'a [BuildingRecord],
    /// Per candidate: drawn by the early pass.
    pub early: Vec<bool>,
    /// Candidates visible last frame that the early entry did not draw: the occluder gate kept
    /// them out (0 without the gate: the frustum-only entry draws all it takes).
    pub gate_culled: u32,
    /// The LOD scene and the draw id of each candidate, for a LOD cut; `None`: candidate `i` is
    /// building `i`.
    lod: Option<(LodSource<'a>, &'a [u32])>,
    building_count: usize,
}

impl<'a> Candidates<'a> {
    /// Every building of a scene (`records`), with the early entry's `early_status` (one per
    /// building).
    pub fn all_buildings(records: &'a [BuildingRecord], early_status: &[u32]) -> Candidates<'a> {
        let mut c = Candidates {
            records,
            early: Vec::new(),
            gate_culled: 0,
            lod: None,
            building_count: records.len(),
        };
        c.take_early(early_status);
        c
    }

    /// The buildings and clusters of a LOD cut, `draw_ids`
    /// ([`crate::lod::scene::LodFrame::draw_ids`]), with the early entry's `early_status`.
    pub fn lod(lod: LodSource<'a>, draw_ids: &'a [u32], early_status: &[u32]) -> Candidates<'a> {
        let mut c = Candidates {
            records: lod.records,
            early: Vec::new(),
            gate_culled: 0,
            lod: Some((lod, draw_ids)),
            building_count: lod.building_count as usize,
        };
        c.take_early(early_status);
        c
    }

    /// Early: the early entry drew the candidate (`CULL_VISIBLE`); a candidate it took but did
    /// not draw was kept out by the gate.
    fn take_early(&mut self, early_status: &[u32]) {
        let n = self.len();
        self.early = (0..n)
            .map(|i| early_status.get(i) == Some(&CULL_VISIBLE))
            .collect();
        self.gate_culled = early_status
            .iter()
            .take(n)
            .filter(|&&s| s != CULL_VISIBLE && s != CULL_NOT_EARLY)
            .count() as u32;
    }

    pub fn len(&self) -> usize {
        match &self.lod {
            None => self.records.len(),
            Some((_, ids)) => ids.len(),
        }
    }

    /// The draw id of candidate `i`.
    fn draw_id(&self, i: usize) -> u32 {
        match &self.lod {
            None => i as u32,
            Some((_, ids)) => ids[i],
        }
    }

    /// The record the cull tested for candidate `i` (zeroed for a draw id out of range: the
    /// shader clamps such an id, and it draws nothing the report should count).
    fn record(&self, i: usize) -> BuildingRecord {
        self.records
            .get(self.draw_id(i) as usize)
            .copied()
            .unwrap_or_else(bytemuck::Zeroable::zeroed)
    }

    /// Calls `f` with every building candidate `i` covers.
    fn for_each_covered(&self, i: usize, f: impl FnMut(u32)) {
        match &self.lod {
            None => std::iter::once(i as u32).for_each(f),
            Some((lod, ids)) => covered_by(lod.tree, lod.building_count, ids[i]).for_each(f),
        }
    }

    /// The cluster node of candidate `i` when it is a cluster mesh (a LOD cut's inner node).
    fn cluster_node(&self, i: usize) -> Option<u32> {
        let (lod, ids) = self.lod.as_ref()?;
        ids[i].checked_sub(lod.building_count)
    }

    /// The CPU copy of the buildings visible for the next frame, from this frame's cull
    /// `status` (one per candidate): what the GPU's stamps say, per building.
    pub fn update_visibility(&self, visibility: &mut Visibility, status: &[u32]) {
        if self.lod.is_none() {
            visibility.mirror_status(status);
            return;
        }
        let mut visible = vec![false; self.building_count];
        for (i, _) in status
            .iter()
            .enumerate()
            .filter(|&(_, &s)| s == CULL_VISIBLE)
        {
            self.for_each_covered(i, |b| {
                if let Some(v) = visible.get_mut(b as usize) {
                    *v = true;
                }
            });
        }
        visibility.mirror_set(visible);
    }

    /// The frame's counts and drawn buildings from the cull `status` (one per candidate);
    /// `late_commands_all`: the late pass walks every candidate's command (no draw count).
    pub fn statistics(&self, status: &[u32], late_commands_all: bool) -> FrameOutput {
        let early_drawn = self.early.iter().filter(|&&d| d).count() as u32;
        let mut stats = FrameStats {
            building_count: self.building_count as u32,
            candidates: self.len() as u32,
            early_drawn,
            gate_culled: self.gate_culled,
            // The ground and the early draws.
            draw_calls: 1 + early_drawn,
            ..FrameStats::default()
        };
        // Per building: drawn itself, drawn through a cluster.
        let mut itself = vec![false; self.building_count];
        let mut through_cluster = vec![false; self.building_count];
        let mut clusters = Vec::new();
        for (i, &s) in status.iter().enumerate().take(self.len()) {
            let r = self.record(i);
            let was_early = self.early[i];
            match s {
                CULL_FRUSTUM_OUTSIDE => stats.frustum_culled += 1,
                CULL_OCCLUDED => stats.occlusion_culled += 1,
                _ => {
                    stats.cull_kept += 1;
                    if !was_early {
                        stats.late_drawn += 1;
                        if r.index_count > 0 {
                            stats.draw_calls += 1;
                        }
                    }
                }
            }
            // A cluster with an empty mesh shows none of its buildings, kept or not: counting
            // them as drawn would hide a false cull from the benchmark.
            let cluster = self.cluster_node(i);
            let drawn =
                (was_early || s == CULL_VISIBLE) && (cluster.is_none() || r.index_count > 0);
            if drawn {
                stats.triangles += u64::from(r.index_count / 3);
            }
            if drawn && let Some(node) = cluster {
                clusters.push(node);
            }
            if drawn {
                let marks = if cluster.is_some() {
                    &mut through_cluster
                } else {
                    &mut itself
                };
                self.for_each_covered(i, |b| {
                    if let Some(mark) = marks.get_mut(b as usize) {
                        *mark = true;
                    }
                });
            }
        }
        let drawn: Vec<u32> = (0..self.building_count)
            .filter(|&b| itself[b] || through_cluster[b])
            .map(|b| b as u32)
            .collect();
        stats.drawn = drawn.len() as u32;
        stats.clusters_drawn = clusters.len() as u32;
        stats.buildings_through_clusters = (0..self.building_count)
            .filter(|&b| through_cluster[b] && !itself[b])
            .count() as u32;
        stats.late_commands = if late_commands_all {
            stats.candidates
        } else {
            stats.cull_kept
        };
        clusters.sort_unstable();
        let mut drawn_early: Vec<u32> = (0..self.len())
            .filter(|&i| self.early[i] && self.cluster_node(i).is_none())
            .map(|i| self.draw_id(i))
            .collect();
        drawn_early.sort_unstable();
        let drawn_themselves: Vec<u32> = (0..self.building_count)
            .filter(|&b| itself[b])
            .map(|b| b as u32)
            .collect();
        FrameOutput {
            drawn,
            drawn_early,
            drawn_themselves,
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
        let c = Candidates::lod(lod, &coarse, &[CULL_NOT_EARLY, CULL_NOT_EARLY]);
        assert_eq!(c.len(), 2);
        assert_eq!(c.early, vec![false, false]);
        let status = vec![CULL_OCCLUDED, CULL_VISIBLE];
        c.update_visibility(&mut visibility, &status);
        assert_eq!(visibility.visible_ids(), vec![0, 2]);
        let out = c.statistics(&status, false);
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
        let c = Candidates::lod(lod, &fine, &[CULL_VISIBLE, CULL_NOT_EARLY, CULL_VISIBLE]);
        assert_eq!(c.early, vec![true, false, true]);
        let status = vec![CULL_VISIBLE, CULL_VISIBLE, CULL_OCCLUDED];
        c.update_visibility(&mut visibility, &status);
        assert_eq!(visibility.visible_ids(), vec![0, 1]);
        let out = c.statistics(&status, true);
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
            &[CULL_VISIBLE, CULL_NOT_EARLY, CULL_OCCLUDED, CULL_VISIBLE],
        );
        assert_eq!(c.early, vec![true, false, false, true]);
        assert_eq!(c.gate_culled, 1);
        let out = c.statistics(
            &[CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE, CULL_OCCLUDED],
            false,
        );
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
        let c =
            Candidates::all_buildings(scene_records, &[CULL_VISIBLE, CULL_NOT_EARLY, CULL_VISIBLE]);
        let mut visibility = Visibility::default();
        let status = vec![CULL_VISIBLE, CULL_FRUSTUM_OUTSIDE, CULL_OCCLUDED];
        c.update_visibility(&mut visibility, &status);
        assert_eq!(visibility.visible_ids(), vec![0]);
        let out = c.statistics(&status, false);
        assert_eq!(out.drawn, vec![0, 2]);
        assert_eq!(out.drawn_early, vec![0, 2]);
        assert_eq!(out.stats.frustum_culled, 1);
        assert_eq!(out.stats.buildings_through_clusters, 0);
    }
}
