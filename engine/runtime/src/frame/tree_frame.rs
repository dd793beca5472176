//! The LOD frame whose cut the GPU computes ([`crate::hzb::tree_cull`]), as a script:
//!
//! ```text
//! tree_early    → counters reset; last frame's kept buildings still in the cut and in the
//!                 frustum drawn early (no occluder gate: see `submit_tree`)
//! early_pass    → colour + depth: the ground and those buildings
//! occluder_pass → (occluders on) as in the candidate frame
//! build_pyramid → HiZ pyramid
//! tree_walk     → the cut, level by level, culling whole subtrees against the pyramid; the
//!                 kept draw ids listed for the next frame, the late draws appended
//! late_pass     → what the walk kept that the early pass did not draw
//! report        → counters, kept and early ids into a ring slot, read a frame or more late
//! ```
//!
//! The CPU's work is the same for any city: two uniform blocks, the occluder selection, and a
//! fixed number of dispatches (the tree's levels plus two). Its report is O(what was drawn): the
//! kept and early lists, up to [`CullingRenderer::report_entries`] each (grown when a frame
//! keeps more). A frame waited for is read whole; a polled report whose lists outgrew it is
//! dropped, never read in part.

use std::time::Instant;

use citywalk_scenes::frustum::Frustum;
use citywalk_shaders::constants::{
    TREE_C_EARLY_DRAWS, TREE_C_EARLY_LISTED, TREE_C_FRUSTUM_CULLED, TREE_C_LATE_DRAWS,
    TREE_C_OCCLUSION_CULLED, TREE_C_OVERFLOW, TREE_C_VISITED, TREE_C_WORDS, TREE_EARLY_FRUSTUM,
    TREE_EARLY_NONE, TREE_LIST_HEADER, TREE_MAX_LEVELS,
};

use super::report_ring::{ListSources, ReadSlot, SlotLayout, read_lists};
use super::{
    CullingOptions, CullingRenderer, FrameError, FrameOutput, FrameStats, FrameTicket,
    IndirectDraws, OccluderMeshes, PendingFrame, Visibility, occluder_triangles, select_occluders,
};
use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::hzb::tree_cull::TreeInputs;
use crate::lod::gpu_tree::tree_params;
use crate::lod::scene::LodScene;
use crate::lod::{LodCriterion, LodView};
use crate::render::view::view_uniforms;

/// What a submitted tree frame keeps until its report is read.
#[derive(Debug)]
pub(super) struct TreePending {
    lists: wgpu::Buffer,
    /// The half this frame wrote.
    half: u32,
    capacity: u32,
    early_ids: wgpu::Buffer,
}

impl CullingRenderer {
    /// Whether [`CullingRenderer::submit_tree`] can run `lod` on this adapter: it draws through
    /// indirect counts (`MULTI_DRAW_INDIRECT_COUNT`) and walks at most [`TREE_MAX_LEVELS`]
    /// levels.
    pub fn runs_tree(&self, lod: &LodScene) -> bool {
        self.multi_draw_count && lod.tree_gpu.levels <= TREE_MAX_LEVELS
    }

    /// Records and submits one LOD frame of `lod` whose cut the GPU computes under `criterion`
    /// (see the module documentation); returns without waiting, as
    /// [`CullingRenderer::submit`]. Requires [`CullingRenderer::runs_tree`].
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn submit_tree(
        &mut self,
        gpu: &GpuContext,
        lod: &LodScene,
        criterion: LodCriterion,
        occluders: Option<&OccluderMeshes>,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        colour: &wgpu::TextureView,
        (width, height): (u32, u32),
    ) -> Result<FrameTicket, FrameError> {
        let started = Instant::now();
        let clock = crate::cpu_clock::CpuClock::start();
        self.fit_targets(gpu, width, height)?;
        self.frames += 1;
        let number = self.frames;
        let draw_id_count = lod.gpu_scene.records.len() as u32;
        let (_, frame_stamp) = visibility.begin_frame(gpu, draw_id_count);
        let capacity = draw_id_count.max(1);
        let (lists, last_half, early_valid) = visibility.tree_lists(gpu, capacity, frame_stamp);
        let view_proj = Self::view_proj(camera, (width, height));
        let frustum = Frustum::from_view_proj(view_proj);
        let (meshes, selected) = select_occluders(occluders, options, camera, &frustum, height);
        // No occluder gate in a tree frame (`options.occluder_gate` is not read): its early set
        // is only last frame's kept buildings still in the cut, and the gate costs a second
        // occluder pass and pyramid. It was first left out because gated street frames took
        // 2.5–4 s on lavapipe: the driver recompiling the cull shader for each new value of its
        // uniform parameters, since read from storage buffers. Restored without that stall
        // (generated 1M city, 640×360, 8 frames, lavapipe, two runs each), it drew fewer
        // buildings (458 instead of 867 a walk frame, 5,371 instead of 6,161 a street frame)
        // but did not pay: `all` 18.1–19.5× brute force on the walk against 17.7–20.4× without,
        // 16.2–16.9× on the street path against 20.9–21.9×.

        let uniforms = view_uniforms(camera, width, height, &self.style);
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));

        let mut params = tree_params(
            &LodView::new(camera, width, height),
            criterion,
            lod.building_count,
        );
        params.list_capacity = capacity;
        params.last_half = last_half;
        params.early = if early_valid {
            TREE_EARLY_FRUSTUM
        } else {
            TREE_EARLY_NONE
        };
        // Frame numbers start at 1; the marks buffer starts zeroed.
        params.early_mark = number as u32;
        let inputs = TreeInputs {
            tree: &lod.tree_gpu,
            records: &lod.cull_records_buffer,
            parts: &lod.gpu_scene.parts_buffer,
            lists: &lists,
            draw_id_count,
        };
        {
            let targets = self.targets.as_ref().expect("fit_targets ran");
            self.tree_cull
                .prepare(gpu, &inputs, params, (&targets.pyramid, view_proj));
        }
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("tree frame"),
            });
        self.timer.begin_frame();
        let max_draws = self.tree_cull.max_draws();
        {
            let targets = self.targets.as_ref().expect("fit_targets ran");
            self.tree_cull.encode_early(
                &mut encoder,
                &inputs,
                &targets.pyramid,
                self.timer.compute_pass_writes("early_cull"),
            );
        }
        let early_draws = self.tree_draws(self.tree_cull.early_commands(), TREE_C_EARLY_DRAWS);
        self.early_pass(
            &mut encoder,
            &lod.gpu_scene,
            (early_draws, max_draws),
            colour,
        );
        let occluders =
            meshes.map(|meshes| (meshes, self.upload_occluder_draws(gpu, meshes, &selected)));
        if let Some(occluders) = occluders {
            self.occluder_pass(&mut encoder, occluders);
        }
        self.build_pyramid(&mut encoder, meshes.is_some());
        {
            let targets = self.targets.as_ref().expect("fit_targets ran");
            self.tree_cull.encode_walk(
                &mut encoder,
                &inputs,
                &targets.pyramid,
                self.timer.compute_pass_writes("cull"),
            );
        }
        let late_draws = self.tree_draws(self.tree_cull.late_commands(), TREE_C_LATE_DRAWS);
        self.late_pass(
            &mut encoder,
            &lod.gpu_scene,
            (late_draws, max_draws),
            colour,
        );
        let half = 1 - last_half;
        let report = self.record_tree_report(gpu, &mut encoder, &lists, (half, capacity));
        gpu.queue.submit([encoder.finish()]);
        visibility.tree_written(frame_stamp);
        let reported = report.is_some();
        if let Some((ticket, layout, timed)) = report {
            let occluder_triangles = occluder_triangles(meshes, &selected);
            let pending = PendingFrame {
                number,
                buildings: lod.building_count as usize,
                lod_ids: None,
                timed,
                occluders: selected,
                occluder_triangles,
                occluder_draws: occluders.map_or(0, |(_, draws)| draws),
                cpu_ms: clock.elapsed_ms(),
                started,
                tree: Some(TreePending {
                    lists,
                    half,
                    capacity,
                    early_ids: self.tree_cull.early_ids().clone(),
                }),
                lists: None,
            };
            self.reports.submitted(ticket, layout, pending);
        }
        Ok(FrameTicket { number, reported })
    }

    /// The tree cull's `commands`, counted by its counter word `count_word`.
    fn tree_draws<'a>(&'a self, commands: &'a wgpu::Buffer, count_word: u32) -> IndirectDraws<'a> {
        IndirectDraws {
            commands,
            count: self.tree_cull.counters(),
            count_offset: u64::from(count_word) * 4,
        }
    }

    /// Renders one LOD frame whose cut the GPU computes ([`CullingRenderer::submit_tree`]) and
    /// waits for its report, as [`CullingRenderer::render_lod`] does for a CPU cut.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn render_tree(
        &mut self,
        gpu: &GpuContext,
        lod: &LodScene,
        criterion: LodCriterion,
        occluders: Option<&OccluderMeshes>,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        colour: &wgpu::TextureView,
        size: (u32, u32),
    ) -> Result<FrameOutput, FrameError> {
        let ticket = self.submit_tree(
            gpu, lod, criterion, occluders, options, visibility, camera, colour, size,
        )?;
        self.wait_report(gpu, ticket, (&lod.gpu_scene, Some(lod)), visibility)
    }

    /// Copies the timestamps, the counters, the lists' header and the first
    /// [`CullingRenderer::report_entries`] kept and early ids into a free report slot.
    fn record_tree_report(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        lists: &wgpu::Buffer,
        (half, capacity): (u32, u32),
    ) -> Option<(
        super::report_ring::SlotTicket,
        SlotLayout,
        crate::gpu_timer::TimedPhases,
    )> {
        let entries = self.report_entries.min(capacity);
        let layout = SlotLayout {
            timestamps_bytes: self.timer.resolved_bytes(),
            header_words: u64::from(TREE_C_WORDS + TREE_LIST_HEADER),
            candidates: u64::from(entries),
        };
        let (ticket, buffer) = self.reports.reserve(gpu, layout)?;
        let timed = self.timer.resolve_to(encoder, buffer, 0);
        let at = layout.header_at();
        let counters_bytes = u64::from(TREE_C_WORDS) * 4;
        encoder.copy_buffer_to_buffer(self.tree_cull.counters(), 0, buffer, at, counters_bytes);
        let header_bytes = u64::from(TREE_LIST_HEADER) * 4;
        encoder.copy_buffer_to_buffer(lists, 0, buffer, at + counters_bytes, header_bytes);
        let bytes = u64::from(entries) * 4;
        if bytes > 0 {
            let half_at = header_bytes + u64::from(half) * u64::from(capacity) * 4;
            encoder.copy_buffer_to_buffer(lists, half_at, buffer, layout.status_at(), bytes);
            encoder.copy_buffer_to_buffer(
                self.tree_cull.early_ids(),
                0,
                buffer,
                layout.early_at(),
                bytes,
            );
        }
        Some((ticket, layout, timed))
    }

    /// A tree frame's output from its report slot. Lists longer than the slot holds are read
    /// whole from the GPU when `gpu` is given (a frame waited for: nothing has overwritten them
    /// since); without it (a polled report, whose lists a later frame may have overwritten)
    /// the output is `None`: a part of the lists would undercount what was drawn. Either way
    /// later reports copy more.
    pub(super) fn read_tree_report(
        &mut self,
        gpu: Option<&GpuContext>,
        slot: ReadSlot<PendingFrame>,
        lod: &LodScene,
        visibility: Option<&mut Visibility>,
    ) -> Result<Option<FrameOutput>, FrameError> {
        let ReadSlot {
            bytes,
            layout,
            pending,
        } = slot;
        let frame_ms = pending.started.elapsed().as_secs_f64() * 1e3;
        let tree = pending.tree.as_ref().expect("a tree frame");
        let words = |at: u64, n: usize| -> Vec<u32> {
            let at = at as usize;
            bytemuck::pod_collect_to_vec(&bytes[at..at + n * 4])
        };
        let counters = words(layout.header_at(), TREE_C_WORDS as usize);
        let header = words(
            layout.header_at() + u64::from(TREE_C_WORDS) * 4,
            TREE_LIST_HEADER as usize,
        );
        let kept_count = (header[tree.half as usize] as usize).min(tree.capacity as usize);
        let early_count =
            (counters[TREE_C_EARLY_LISTED as usize] as usize).min(tree.capacity as usize);
        let header_bytes = u64::from(TREE_LIST_HEADER) * 4;
        let sources = ListSources {
            kept: (
                tree.lists.clone(),
                header_bytes + u64::from(tree.half) * u64::from(tree.capacity) * 4,
            ),
            early: (tree.early_ids.clone(), 0),
        };
        let Some((kept, early)) = read_lists(
            (&bytes, layout),
            (kept_count, early_count),
            &sources,
            gpu,
            &mut self.report_entries,
        )?
        else {
            tracing::debug!(
                frame = pending.number,
                kept_count,
                early_count,
                "tree report dropped: its lists outgrew the report"
            );
            return Ok(None);
        };
        if counters[TREE_C_OVERFLOW as usize] != 0 {
            tracing::error!(
                "tree cull overflowed its queue or lists (frame {}): the frame is incomplete",
                pending.number
            );
        }
        tracing::debug!(
            frame = pending.number,
            visited = counters[TREE_C_VISITED as usize],
            kept = kept.len(),
            early = early.len(),
            late = counters[TREE_C_LATE_DRAWS as usize],
            "tree cull"
        );
        let mut output = tree_output(lod, &kept, early, &counters);
        if let Some(visibility) = visibility {
            visibility.mirror_ids(output.drawn.clone());
        }
        let stats = &mut output.stats;
        stats.occluders_drawn = pending.occluders.len() as u32;
        stats.occluder_triangles = pending.occluder_triangles;
        stats.draw_calls += pending.occluder_draws;
        stats.cpu_ms = pending.cpu_ms;
        stats.frame_ms = frame_ms;
        stats.gpu = self
            .timer
            .times_from(&pending.timed, &bytes[..layout.timestamps_bytes as usize]);
        output.occluders = pending.occluders;
        output.lod_cut = true;
        Ok(Some(output))
    }
}

/// The frame's output from its kept draw ids, early building ids and counters: O(what was
/// drawn), never O(buildings).
pub(super) fn tree_output(
    lod: &LodScene,
    kept: &[u32],
    mut early: Vec<u32>,
    counters: &[u32],
) -> FrameOutput {
    let n = lod.building_count;
    let index_count = |id: u32| {
        lod.gpu_scene
            .records
            .get(id as usize)
            .map_or(0, |r| r.index_count)
    };
    early.sort_unstable();
    early.dedup();
    let mut themselves: Vec<u32> = kept.iter().copied().filter(|&id| id < n).collect();
    themselves.extend_from_slice(&early);
    themselves.sort_unstable();
    themselves.dedup();
    // A cluster with an empty mesh shows none of its buildings: not counted as drawn (that
    // would hide a false cull from the benchmark).
    let mut clusters: Vec<u32> = kept
        .iter()
        .copied()
        .filter(|&id| id >= n && index_count(id) > 0)
        .map(|id| id - n)
        .collect();
    clusters.sort_unstable();
    clusters.dedup();
    let mut drawn = themselves.clone();
    for &c in &clusters {
        drawn.extend(lod.covered_by(n + c));
    }
    drawn.sort_unstable();
    drawn.dedup();
    let triangles: u64 = themselves
        .iter()
        .copied()
        .chain(clusters.iter().map(|&c| n + c))
        .map(|id| u64::from(index_count(id) / 3))
        .sum();
    let late = counters[TREE_C_LATE_DRAWS as usize];
    let early_drawn = counters[TREE_C_EARLY_DRAWS as usize];
    let stats = FrameStats {
        building_count: n,
        candidates: counters[TREE_C_VISITED as usize],
        early_drawn,
        frustum_culled: counters[TREE_C_FRUSTUM_CULLED as usize],
        occlusion_culled: counters[TREE_C_OCCLUSION_CULLED as usize],
        cull_kept: kept.len() as u32,
        late_drawn: late,
        drawn: drawn.len() as u32,
        clusters_drawn: clusters.len() as u32,
        buildings_through_clusters: (drawn.len() - themselves.len()) as u32,
        triangles,
        // The ground, the early and the late draws.
        draw_calls: 1 + early_drawn + late,
        late_commands: late,
        ..FrameStats::default()
    };
    FrameOutput {
        drawn,
        clusters,
        drawn_early: early,
        drawn_themselves: themselves,
        lod_cut: true,
        occluders: Vec::new(),
        stats,
    }
}
