//! What one frame culls: its candidates (every building of a scene, or the buildings and
//! cluster meshes of a LOD cut), which of them the early pass draws, and how the cull's status of
//! each candidate becomes the frame's statistics and the next frame's visible buildings.
//!
//! **Visibility across LOD cuts.** Visibility is kept per building, never per candidate, so it
//! survives any change of the cut: a candidate kept by the cull marks every building it covers
//! (a building itself; a cluster, every building under it) visible for the next frame. A
//! *building* candidate is drawn early when it was visible last frame, whether it was drawn
//! itself then or through a cluster. A *cluster* candidate is never drawn early: the pyramid must
//! be built from depth that the full-detail scene would hide at least as much as (the ground,
//! buildings, occluders contained in buildings), and a cluster mesh is not contained in its
//! buildings (it fills the negative space between them). Clusters therefore always go through
//! the cull, which tests the box of everything they stand for
//! ([`crate::lod::scene::LodScene::cull_records`]).

use std::borrow::Cow;

use citywalk_scenes::frustum::{Containment, Frustum};
use citywalk_shaders::BuildingRecord;
use glam::Vec3;

use crate::frame::{FrameOutput, FrameStats, Visibility};
use crate::hzb::cull::{CULL_FRUSTUM_OUTSIDE, CULL_OCCLUDED, CULL_VISIBLE};
use citywalk_scenes::cluster_tree::ClusterTree;

use crate::lod::scene::{LodScene, covered_by};
use crate::scene_gpu::SceneGpu;

/// What the candidates of a LOD cut need of its scene ([`LodScene`]).
#[derive(Debug, Clone, Copy)]
pub(super) struct LodSource<'a> {
    /// Buildings of the scene; draw id `building_count + n` is cluster node `n`.
    pub building_count: u32,
    /// Per draw id, the record the cull tests ([`LodScene::cull_records`]).
    pub cull_records: &'a [BuildingRecord],
    pub tree: &'a ClusterTree,
}

impl<'a> LodSource<'a> {
    pub fn of(lod: &'a LodScene) -> LodSource<'a> {
        LodSource {
            building_count: lod.building_count,
            cull_records: &lod.cull_records,
            tree: &lod.tree.tree,
        }
    }
}

/// The candidates of one frame.
#[derive(Debug, Default)]
pub(super) struct Candidates<'a> {
    /// Cull record of each candidate: its draw (geometry in the scene) and the box it is tested
    /// with.
    /// Borrowed from the scene when the candidates are its buildings (no per-frame copy).
    pub records: Cow<'a, [BuildingRecord]>,
    /// Per candidate: drawn by the early pass.
    pub early: Vec<bool>,
    /// Per building of the scene: drawn as itself by the early pass (occluder selection).
    pub early_buildings: Vec<bool>,
    /// Draws issued by the early pass, the ground included.
    pub early_draw_count: u32,
    /// The early candidates go through the occluder gate ([`Candidates::gate_records`]): their
    /// cull records keep their index counts (the cull skips those the gate drew) and `early`
    /// holds what the gate kept once [`Candidates::apply_gate`] has run.
    pub gated: bool,
    /// The LOD scene and the draw id of each candidate, for a LOD cut; `None`: candidate `i` is
    /// building `i`.
    lod: Option<(LodSource<'a>, Cow<'a, [u32]>)>,
    building_count: usize,
}

fn in_frustum(frustum: &Frustum, r: &BuildingRecord) -> bool {
    frustum.classify_aabb(
        Vec3::from_array(r.bounds_min_m),
        Vec3::from_array(r.bounds_max_m),
    ) != Containment::Outside
}

impl<'a> Candidates<'a> {
    /// Every building of `scene`; early: visible last frame and in the frustum.
    pub fn all_buildings(
        scene: &'a SceneGpu,
        visibility: &Visibility,
        frustum: &Frustum,
    ) -> Candidates<'a> {
        let early: Vec<bool> = scene
            .records
            .iter()
            .enumerate()
            .map(|(i, r)| visibility.is_visible(i as u32) && in_frustum(frustum, r))
            .collect();
        Candidates {
            records: Cow::Borrowed(&scene.records),
            early_buildings: early.clone(),
            early_draw_count: 1 + early.iter().filter(|&&e| e).count() as u32,
            gated: false,
            early,
            lod: None,
            building_count: scene.building_count(),
        }
    }

    /// The buildings and clusters of a LOD cut, `draw_ids` ([`crate::lod::scene::LodFrame::draw_ids`]); early: a
    /// building visible last frame, in the frustum (see the module documentation for why
    /// clusters are never early).
    pub fn lod(
        lod: LodSource<'a>,
        draw_ids: &'a [u32],
        visibility: &Visibility,
        frustum: &Frustum,
    ) -> Candidates<'a> {
        let building_count = lod.building_count as usize;
        let mut early_buildings = vec![false; building_count];
        let mut records = Vec::with_capacity(draw_ids.len());
        let mut early = Vec::with_capacity(draw_ids.len());
        let mut ids = Vec::with_capacity(draw_ids.len());
        for &id in draw_ids {
            let Some(record) = lod.cull_records.get(id as usize) else {
                continue;
            };
            let is_early = (id as usize) < building_count
                && visibility.is_visible(id)
                && in_frustum(frustum, record);
            if is_early {
                early_buildings[id as usize] = true;
            }
            records.push(*record);
            early.push(is_early);
            ids.push(id);
        }
        // `ids` equals `cut.draw_ids` unless the cut named an id out of range (the common case
        // borrows).
        let lod_ids = if ids.len() == draw_ids.len() {
            Cow::Borrowed(draw_ids)
        } else {
            Cow::Owned(ids)
        };
        Candidates {
            records: Cow::Owned(records),
            early_draw_count: 1 + early.iter().filter(|&&e| e).count() as u32,
            gated: false,
            early,
            early_buildings,
            lod: Some((lod, lod_ids)),
            building_count,
        }
    }

    pub fn len(&self) -> usize {
        self.records.len()
    }

    /// The early candidates for the occluder gate: their records (real index counts) and the
    /// candidate index each stands for, in candidate order.
    pub fn gate_records(&self) -> (Vec<BuildingRecord>, Vec<u32>) {
        self.early
            .iter()
            .enumerate()
            .filter(|&(_, &e)| e)
            .map(|(i, _)| (self.records[i], i as u32))
            .unzip()
    }

    /// Takes the gate's `status` (one per entry of [`Candidates::gate_records`], in its order):
    /// an early candidate stays early (drawn by the early pass) only when the gate kept it;
    /// the others go to the cull like any candidate. Returns how many the gate kept out.
    pub fn apply_gate(&mut self, status: &[u32]) -> u32 {
        let mut kept_out = 0;
        let mut next = status.iter();
        for i in 0..self.early.len() {
            if self.early[i] && next.next() != Some(&CULL_VISIBLE) {
                self.early[i] = false;
                kept_out += 1;
                if let Some(b) = self.building_of(i) {
                    self.early_buildings[b] = false;
                }
            }
        }
        self.early_draw_count -= kept_out;
        kept_out
    }

    /// The building candidate `i` is, when it is one (not a cluster).
    fn building_of(&self, i: usize) -> Option<usize> {
        match &self.lod {
            None => Some(i),
            Some((lod, ids)) => ids
                .get(i)
                .filter(|&&id| id < lod.building_count)
                .map(|&id| id as usize),
        }
    }

    /// Calls `f` with every building candidate `i` covers.
    fn for_each_covered(&self, i: usize, mut f: impl FnMut(u32)) {
        match &self.lod {
            None => f(i as u32),
            Some((lod, ids)) => {
                if let Some(&id) = ids.get(i) {
                    covered_by(lod.tree, lod.building_count, id).for_each(f);
                }
            }
        }
    }

    /// The cluster node of candidate `i` when it is a cluster mesh (a LOD cut's inner node).
    fn cluster_node(&self, i: usize) -> Option<u32> {
        let (lod, ids) = self.lod.as_ref()?;
        let id = *ids.get(i)?;
        id.checked_sub(lod.building_count)
    }

    /// Next frame's visible buildings from this frame's cull `status` (one per candidate).
    /// Whether the cull `status` kept a cluster mesh (so the late pass drew one): such a
    /// frame's final depth holds geometry that is not contained in its buildings.
    pub fn cluster_kept(&self, status: &[u32]) -> bool {
        status
            .iter()
            .enumerate()
            .any(|(i, &s)| s == CULL_VISIBLE && self.cluster_node(i).is_some())
    }

    pub fn update_visibility(&self, visibility: &mut Visibility, status: &[u32]) {
        if self.lod.is_none() {
            visibility.update(status);
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
        visibility.set(visible);
    }

    /// The frame's counts and drawn buildings from the cull `status` (one per candidate);
    /// `late_commands_all`: the late pass walks every candidate's command (no draw count).
    pub fn statistics(&self, status: Vec<u32>, late_commands_all: bool) -> FrameOutput {
        let mut stats = FrameStats {
            building_count: self.building_count as u32,
            candidates: self.len() as u32,
            draw_calls: self.early_draw_count,
            ..FrameStats::default()
        };
        // Per building: drawn itself, drawn through a cluster, best cull status seen.
        let mut itself = vec![false; self.building_count];
        let mut through_cluster = vec![false; self.building_count];
        let mut building_status = vec![CULL_FRUSTUM_OUTSIDE; self.building_count];
        let mut clusters = Vec::new();
        for (i, (&s, r)) in status.iter().zip(self.records.iter()).enumerate() {
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
            self.for_each_covered(i, |b| {
                let b = b as usize;
                let Some(st) = building_status.get_mut(b) else {
                    return;
                };
                // Visible beats occluded beats outside.
                if s == CULL_VISIBLE || (s == CULL_OCCLUDED && *st == CULL_FRUSTUM_OUTSIDE) {
                    *st = s;
                }
                if drawn {
                    if cluster.is_some() {
                        through_cluster[b] = true;
                    } else {
                        itself[b] = true;
                    }
                }
            });
        }
        stats.early_drawn = self.early.iter().filter(|&&d| d).count() as u32;
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
        FrameOutput {
            drawn,
            occluders: Vec::new(),
            status: if self.lod.is_none() {
                status
            } else {
                building_status
            },
            clusters,
            stats,
        }
    }

    /// The cull record of candidate `i` as the cull reads it: a zero index count when the
    /// candidate is early and not gated (the cull then emits an empty command for it and the
    /// late pass draws each candidate at most once; with the gate, the cull skips the drawn
    /// ones by the gate's flags instead).
    fn late_record(&self, i: usize) -> BuildingRecord {
        let mut r = self.records[i];
        if self.early[i] && !self.gated {
            r.index_count = 0;
        }
        r
    }

    /// The cull records with a zero index count for every early candidate
    /// ([`Candidates::late_record`]).
    #[cfg(test)]
    pub fn late_records(&self) -> Vec<BuildingRecord> {
        (0..self.len()).map(|i| self.late_record(i)).collect()
    }

    /// Brings `late` (last frame's late records) to this frame's
    /// ([`Candidates::late_record`] of every candidate) in place, and returns the runs of
    /// changed entries as `(first, end)` index ranges, ascending and disjoint: what must be
    /// uploaded when the GPU copy held `late`. Runs closer than `merge_gap` entries are merged
    /// (one upload of a few unchanged entries is cheaper than two uploads).
    pub fn update_late_records(
        &self,
        late: &mut Vec<BuildingRecord>,
        merge_gap: usize,
    ) -> Vec<(usize, usize)> {
        let n = self.len();
        let kept = late.len().min(n);
        late.truncate(n);
        let mut runs: Vec<(usize, usize)> = Vec::new();
        let push = |i: usize, runs: &mut Vec<(usize, usize)>| match runs.last_mut() {
            Some(last) if i <= last.1 + merge_gap => last.1 = i + 1,
            _ => runs.push((i, i + 1)),
        };
        for (i, slot) in late.iter_mut().enumerate().take(kept) {
            let r = self.late_record(i);
            if *slot != r {
                *slot = r;
                push(i, &mut runs);
            }
        }
        if n > kept {
            late.extend((kept..n).map(|i| self.late_record(i)));
            match runs.last_mut() {
                Some(last) if kept <= last.1 + merge_gap => last.1 = n,
                _ => runs.push((kept, n)),
            }
        }
        runs
    }
}

#[cfg(test)]
mod tests {
    use citywalk_scenes::BuildingId;
    use citywalk_scenes::cluster_tree::{ClusterNode, ClusterParams, ClusterStats};

    use super::*;
    use crate::camera::Camera;

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

    /// Three buildings ahead of a camera looking along +x; buildings 2 and 0 (in that leaf
    /// order) under cluster node 2, building 1 alone under the root.
    fn scene() -> (ClusterTree, Vec<BuildingRecord>, Frustum) {
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
        let camera = Camera::new(Vec3::ZERO, 0.0, 0.0);
        (
            tree,
            records,
            Frustum::from_view_proj(camera.view_proj(1.0)),
        )
    }

    /// The LOD source of [`scene`]'s tree and records, and a visibility of its three buildings
    /// with nothing visible.
    fn source<'a>(
        tree: &'a ClusterTree,
        records: &'a [BuildingRecord],
    ) -> (LodSource<'a>, Visibility) {
        let mut visibility = Visibility::default();
        visibility.fit(3);
        let lod = LodSource {
            building_count: 3,
            cull_records: records,
            tree,
        };
        (lod, visibility)
    }

    #[test]
    fn visibility_is_kept_per_building_across_cuts() {
        let (tree, records, frustum) = scene();
        let (lod, mut visibility) = source(&tree, &records);

        // Coarse cut: cluster 2 (buildings 2 and 0) and building 1. Nothing seen yet: nothing
        // early.
        let coarse = [1, 3 + 2];
        let c = Candidates::lod(lod, &coarse, &visibility, &frustum);
        assert_eq!(c.len(), 2);
        assert_eq!(c.early, vec![false, false]);
        assert_eq!(c.early_draw_count, 1);
        let status = vec![CULL_OCCLUDED, CULL_VISIBLE];
        c.update_visibility(&mut visibility, &status);
        assert_eq!(visibility.visible_ids(), vec![0, 2]);
        let out = c.statistics(status, false);
        assert_eq!(out.drawn, vec![0, 2]);
        assert_eq!(out.clusters, vec![2]);
        assert_eq!(out.status, vec![CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE]);
        let s = &out.stats;
        assert_eq!((s.candidates, s.cull_kept, s.occlusion_culled), (2, 1, 1));
        assert_eq!((s.clusters_drawn, s.buildings_through_clusters), (1, 2));
        assert_eq!((s.late_drawn, s.draw_calls, s.late_commands), (1, 2, 1));

        // The cut refines the cluster: its buildings were seen through it, so they are drawn
        // early as themselves; building 1 was not seen and is not.
        let fine = [0, 1, 2];
        let c = Candidates::lod(lod, &fine, &visibility, &frustum);
        assert_eq!(c.early, vec![true, false, true]);
        assert_eq!(c.early_buildings, vec![true, false, true]);
        assert_eq!(c.early_draw_count, 3);
        let late: Vec<u32> = c.late_records().iter().map(|r| r.index_count).collect();
        assert_eq!(
            late,
            vec![0, 36, 0],
            "early candidates are not drawn again late"
        );
        // Building 2 turned out hidden: drawn (early) this frame, not early next frame.
        let status = vec![CULL_VISIBLE, CULL_VISIBLE, CULL_OCCLUDED];
        c.update_visibility(&mut visibility, &status);
        assert_eq!(visibility.visible_ids(), vec![0, 1]);
        let out = c.statistics(status, true);
        assert_eq!(out.drawn, vec![0, 1, 2]);
        assert!(out.clusters.is_empty());
        let s = &out.stats;
        assert_eq!((s.early_drawn, s.late_drawn, s.drawn), (2, 1, 3));
        assert_eq!((s.clusters_drawn, s.buildings_through_clusters), (0, 0));
        assert_eq!(s.late_commands, 3);
        assert_eq!(s.triangles, 3 * 12);

        // Coarser again: the cluster is not early even though its buildings were visible
        // (cluster meshes never reach the pyramid's depth).
        let c = Candidates::lod(lod, &coarse, &visibility, &frustum);
        assert_eq!(c.early, vec![true, false]);
        assert_eq!(c.early_buildings, vec![false, true, false]);
    }

    /// The occluder gate's bookkeeping over a LOD cut: the gate's records are the early
    /// candidates in order, with the candidate each stands for; gated late records keep their
    /// index counts (the cull skips by the gate's flags); the gate's status leaves early only
    /// those it kept, and the statistics count the kept-out ones as late draws when the cull
    /// keeps them.
    #[test]
    fn the_gate_keeps_early_only_what_it_kept() {
        let (tree, records, frustum) = scene();
        let (lod, mut visibility) = source(&tree, &records);
        visibility.set(vec![true, true, true]);
        // Cut: building 2, cluster 2 (never early), building 0, building 1.
        let cut = [2, 3 + 2, 0, 1];
        let mut c = Candidates::lod(lod, &cut, &visibility, &frustum);
        assert_eq!(c.early, vec![true, false, true, true]);
        let (gate, targets) = c.gate_records();
        assert_eq!(targets, vec![0, 2, 3]);
        assert_eq!(gate, vec![records[2], records[0], records[1]]);
        c.gated = true;
        let late: Vec<u32> = c.late_records().iter().map(|r| r.index_count).collect();
        assert_eq!(
            late,
            vec![36, 36, 36, 36],
            "gated late records keep their draws"
        );
        // The gate keeps building 2 and building 1, keeps building 0 out.
        let kept_out = c.apply_gate(&[CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE]);
        assert_eq!(kept_out, 1);
        assert_eq!(c.early, vec![true, false, false, true]);
        assert_eq!(c.early_buildings, vec![false, true, true]);
        assert_eq!(c.early_draw_count, 3);
        // The cull keeps building 0 (drawn late) and hides the cluster and building 1 (drawn
        // early all the same).
        let out = c.statistics(
            vec![CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE, CULL_OCCLUDED],
            false,
        );
        let s = &out.stats;
        assert_eq!((s.early_drawn, s.late_drawn, s.drawn), (2, 1, 3));
        assert_eq!(out.drawn, vec![0, 1, 2]);
        assert_eq!(s.draw_calls, 3 + 1, "ground, two early, one late");
    }

    #[test]
    fn late_records_are_updated_in_place_with_the_changed_runs() {
        let (tree, records, frustum) = scene();
        let (lod, mut visibility) = source(&tree, &records);
        let fine = [0, 1, 2];
        let mut late = Vec::new();
        // First frame: everything is new.
        let c = Candidates::lod(lod, &fine, &visibility, &frustum);
        assert_eq!(c.update_late_records(&mut late, 0), vec![(0, 3)]);
        assert_eq!(late, c.late_records());
        // Same candidates, nothing early: nothing changes.
        assert!(c.update_late_records(&mut late, 0).is_empty());
        // Buildings 0 and 2 become early: two runs, one when merged across the gap.
        c.update_visibility(
            &mut visibility,
            &[CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE],
        );
        let c = Candidates::lod(lod, &fine, &visibility, &frustum);
        let mut merged = late.clone();
        assert_eq!(c.update_late_records(&mut late, 0), vec![(0, 1), (2, 3)]);
        assert_eq!(c.update_late_records(&mut merged, 1), vec![(0, 3)]);
        assert_eq!(late, c.late_records());
        assert_eq!(merged, late);
        // A shorter cut truncates; its changed entries are reported.
        let coarse = [1, 3 + 2];
        let c = Candidates::lod(lod, &coarse, &visibility, &frustum);
        let runs = c.update_late_records(&mut late, 0);
        assert_eq!(late, c.late_records());
        assert_eq!(runs, vec![(0, 2)]);
    }

    #[test]
    fn every_building_is_a_candidate_without_a_cut() {
        let (_, records, frustum) = scene();
        let scene_records = records[..3].to_vec();
        let mut visibility = Visibility::default();
        visibility.fit(3);
        visibility.update(&[CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE]);
        let early: Vec<bool> = scene_records
            .iter()
            .enumerate()
            .map(|(i, r)| visibility.is_visible(i as u32) && in_frustum(&frustum, r))
            .collect();
        assert_eq!(early, vec![true, false, true]);
        // The same rule as the LOD path, through the identity cover.
        let c = Candidates {
            records: Cow::Owned(scene_records),
            early_buildings: early.clone(),
            early_draw_count: 3,
            gated: false,
            early,
            lod: None,
            building_count: 3,
        };
        let status = vec![CULL_VISIBLE, CULL_FRUSTUM_OUTSIDE, CULL_OCCLUDED];
        c.update_visibility(&mut visibility, &status);
        assert_eq!(visibility.visible_ids(), vec![0]);
        let out = c.statistics(status.clone(), false);
        assert_eq!(out.drawn, vec![0, 2]);
        assert_eq!(out.status, status);
        assert_eq!(out.stats.frustum_culled, 1);
        assert_eq!(out.stats.buildings_through_clusters, 0);
    }
}
