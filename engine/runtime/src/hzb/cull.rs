//! The GPU hierarchical-Z occlusion cull: one invocation per box (a [`BuildingRecord`]) projects
//! its 8 corners (frustum planes by corner outcodes, so a box crossing the near plane outside the
//! view is culled too), reads 2×2 texels at the coarse level ([`super::reference::select_level`])
//! and, when they do not hide the box, at most [`HZB_FINE_SPAN`]² texels at the fine level
//! ([`super::reference::select_fine_level`]), as [`super::reference::project_box`] and
//! [`super::reference::DepthPyramid::is_occluded`] do. Each box gets a status
//! ([`CULL_VISIBLE`], [`CULL_FRUSTUM_OUTSIDE`], [`CULL_OCCLUDED`]) and each visible box appends
//! its [`DrawIndexedIndirectArgs`] behind an atomic counter (`shaders/wgsl/hzb_cull.wgsl`).
//!
//! Conservative rounding: every comparison is widened towards "visible" by a bound on the
//! difference between the GPU's and the CPU's float rounding ([`HZB_ROUNDING_REL`]), so the GPU
//! never culls a box the CPU reference keeps; it may keep a few more.
//!
//! **Early draws and visibility.** The same pass serves the early pass of [`crate::frame`]
//! ([`CullEntry`]): entry point `early` (or, against the occluders' pyramid, `gate`) draws last
//! frame's visible candidates and marks them in a per-candidate flag buffer; the main cull
//! (`cull`) appends no draw for a marked candidate, still writes its status, and stamps every
//! visible candidate's draw id in the visibility buffer that the next frame's early entry reads
//! ([`CullVisibility`]). Nothing of it passes through the CPU.
//!
//! **The report.** What the CPU needs of a frame is O(what was drawn): the entry points list the
//! candidates the early pass drew and those the cull kept, and count the occluded and the
//! gate-culled ones, in [`HzbCull::report_buffer`] (`CULL_R_*` words, then the two lists). The
//! per-candidate status stays on the GPU ([`HzbCull::read_back`] for tests).
//!
//! The command buffer is cleared before each cull, so it can be drawn either with
//! `multi_draw_indexed_indirect_count` (count from [`HzbCull::count_buffer`], when
//! `MULTI_DRAW_INDIRECT_COUNT` is available) or with `multi_draw_indexed_indirect` of
//! `box_count` commands, where the unused tail is zero draws.
//!
//! **Parameters in a storage buffer.** The per-frame [`HzbCullParams`] (and the tree cull's) are
//! bound as read-only storage, not as a uniform buffer: lavapipe inlines uniform values that
//! steer control flow and recompiles the shader whenever they change, which made frames of a
//! software adapter take 0.4–2.5 s each on a cold shader cache.

use citywalk_shaders::constants::HZB_CULL_WORKGROUP;
use citywalk_shaders::constants::{CULL_FLAG_DRAW_IDS, CULL_FLAG_VISIBILITY, CULL_R_WORDS};
pub use citywalk_shaders::constants::{
    CULL_FRUSTUM_OUTSIDE, CULL_NOT_EARLY, CULL_OCCLUDED, CULL_VISIBLE, HZB_FINE_SPAN,
    HZB_ROUNDING_REL, NO_PARENT,
};
use citywalk_shaders::{
    BuildingRecord, CullPart, DrawIndexedIndirectArgs, HZB_CULL_WGSL, HzbCullParams,
};
use glam::Mat4;
use wgpu::util::DeviceExt;

use super::build::HzbPyramid;
use crate::gpu::GpuContext;
use crate::render::targets::{ReadbackError, map_read};

/// Why a cull could not be recorded.
#[derive(Debug, thiserror::Error)]
pub enum CullError {
    #[error("{box_count} boxes exceed the {max} one dispatch of the cull pass can test")]
    TooManyBoxes { box_count: u32, max: u32 },
    #[error("the records buffer holds {records} records, fewer than the {box_count} boxes to cull")]
    RecordsTooSmall { records: u64, box_count: u32 },
    #[error("the draw-id buffer holds {ids} entries, fewer than the {box_count} boxes to cull")]
    DrawIdsTooSmall { ids: u64, box_count: u32 },
}

/// Which entry point a cull runs (see the module documentation).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum CullEntry {
    /// Last frame's visible candidates inside the frustum: drawn early and marked.
    Early,
    /// Last frame's visible candidates against the pyramid (the occluders'): those it keeps
    /// drawn early and marked.
    Gate,
    /// Every candidate against the pyramid: status, draws of the unmarked visible ones, stamps.
    Cull,
}

impl CullEntry {
    fn name(self) -> &'static str {
        match self {
            CullEntry::Early => "early",
            CullEntry::Gate => "gate",
            CullEntry::Cull => "cull",
        }
    }
}

/// The GPU-resident visibility a frame's culls read and mark: per draw id the stamp of the last
/// frame that kept it, and the draw id of the cluster above it.
#[derive(Debug, Clone, Copy)]
pub struct CullVisibility<'a> {
    /// `u32` per draw id.
    pub stamps: &'a wgpu::Buffer,
    /// `u32` per draw id: the parent cluster's draw id, or [`NO_PARENT`].
    pub parents: &'a wgpu::Buffer,
    /// This frame's stamp; last frame's is one less.
    pub frame_stamp: u32,
    /// Draw ids below this are buildings.
    pub building_count: u32,
}

/// What a cull reads and writes besides its records: the candidates' draw ids (`None`: box `i`
/// is draw id `i`), the drawn-early flags (one `u32` per box; written by the early entry
/// points, read by the cull) and the visibility.
#[derive(Debug, Clone, Copy, Default)]
pub struct CullLinks<'a> {
    pub draw_ids: Option<&'a wgpu::Buffer>,
    pub drawn_early: Option<&'a wgpu::Buffer>,
    pub visibility: Option<CullVisibility<'a>>,
}

/// What one cull wrote, read back to the CPU (tests, statistics).
#[derive(Debug, Clone, PartialEq)]
pub struct CullResults {
    /// Per box: [`CULL_VISIBLE`], [`CULL_FRUSTUM_OUTSIDE`] or [`CULL_OCCLUDED`].
    pub status: Vec<u32>,
    /// The appended draws of the visible boxes (in no particular order).
    pub commands: Vec<DrawIndexedIndirectArgs>,
}

/// The cull pass: pipeline, uniforms and output buffers (status, commands, count), grown to the
/// largest box count seen.
#[derive(Debug)]
pub struct HzbCull {
    device: wgpu::Device,
    module: wgpu::ShaderModule,
    pipeline_layout: wgpu::PipelineLayout,
    /// The `early`, `gate` and `cull` pipelines, made when first used.
    pipelines: [Option<wgpu::ComputePipeline>; 3],
    layout: wgpu::BindGroupLayout,
    params: wgpu::Buffer,
    status: wgpu::Buffer,
    commands: wgpu::Buffer,
    count: wgpu::Buffer,
    /// The frame's report: `CULL_R_WORDS` header words, then the kept and the early list of
    /// `capacity` candidate indices each.
    report: wgpu::Buffer,
    /// One zeroed part, bound when the records name none.
    no_parts: wgpu::Buffer,
    /// One word each, bound when the frame gives none: the drawn-early flags, the draw ids, the
    /// stamps and the parents (separate buffers: some bindings are written, others read).
    no_flags: wgpu::Buffer,
    no_ids: wgpu::Buffer,
    no_stamps: wgpu::Buffer,
    no_parents: wgpu::Buffer,
    capacity: u32,
}

const STATUS_BYTES: u64 = 4;
const COMMAND_BYTES: u64 = size_of::<DrawIndexedIndirectArgs>() as u64;

impl HzbCull {
    /// A cull pass with room for `capacity` boxes (grown on demand).
    pub fn new(gpu: &GpuContext, capacity: u32) -> HzbCull {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("hzb cull"),
            source: wgpu::ShaderSource::Wgsl(HZB_CULL_WGSL.into()),
        });
        let buffer_entry = |binding, ty, min: u64| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(min),
            },
            count: None,
        };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("hzb cull"),
            entries: &[
                buffer_entry(
                    0,
                    wgpu::BufferBindingType::Storage { read_only: true },
                    size_of::<HzbCullParams>() as u64,
                ),
                buffer_entry(
                    1,
                    wgpu::BufferBindingType::Storage { read_only: true },
                    size_of::<BuildingRecord>() as u64,
                ),
                crate::render::float_texture_entry(2, wgpu::ShaderStages::COMPUTE),
                buffer_entry(3, rw, STATUS_BYTES),
                buffer_entry(4, rw, COMMAND_BYTES),
                buffer_entry(5, rw, 4),
                buffer_entry(
                    6,
                    wgpu::BufferBindingType::Storage { read_only: true },
                    size_of::<CullPart>() as u64,
                ),
                buffer_entry(7, rw, 4),
                buffer_entry(8, wgpu::BufferBindingType::Storage { read_only: true }, 4),
                buffer_entry(9, rw, 4),
                buffer_entry(10, wgpu::BufferBindingType::Storage { read_only: true }, 4),
                buffer_entry(23, rw, report_bytes(1)),
            ],
        });
        let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("hzb cull"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let params = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hzb cull params"),
            size: size_of::<HzbCullParams>() as u64,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let count = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hzb cull draw count"),
            size: 4,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let no_parts = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
            label: Some("hzb cull: no parts"),
            contents: bytemuck::bytes_of(&<CullPart as bytemuck::Zeroable>::zeroed()),
            usage: wgpu::BufferUsages::STORAGE,
        });
        let zero_word = |label| {
            device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some(label),
                contents: &[0; 4],
                usage: wgpu::BufferUsages::STORAGE,
            })
        };
        let no_flags = zero_word("hzb cull: no early draws");
        let no_ids = zero_word("hzb cull: no draw ids");
        let no_stamps = zero_word("hzb cull: no stamps");
        let no_parents = zero_word("hzb cull: no parents");
        let capacity = capacity.max(1);
        let (status, commands, report) = Self::outputs(device, capacity);
        HzbCull {
            device: device.clone(),
            module,
            pipeline_layout,
            pipelines: [None, None, None],
            layout,
            params,
            status,
            commands,
            count,
            report,
            no_parts,
            no_flags,
            no_ids,
            no_stamps,
            no_parents,
            capacity,
        }
    }

    /// The pipeline of `entry`, made on first use.
    fn pipeline(&mut self, entry: CullEntry) -> &wgpu::ComputePipeline {
        let slot = entry as usize;
        self.pipelines[slot].get_or_insert_with(|| {
            self.device
                .create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                    label: Some(entry.name()),
                    layout: Some(&self.pipeline_layout),
                    module: &self.module,
                    entry_point: Some(entry.name()),
                    compilation_options: Default::default(),
                    cache: None,
                })
        })
    }

    fn outputs(device: &wgpu::Device, capacity: u32) -> (wgpu::Buffer, wgpu::Buffer, wgpu::Buffer) {
        let status = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hzb cull status"),
            size: u64::from(capacity) * STATUS_BYTES,
            usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_SRC,
            mapped_at_creation: false,
        });
        let commands = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hzb cull commands"),
            size: u64::from(capacity) * COMMAND_BYTES,
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::INDIRECT
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let report = device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hzb cull report"),
            size: report_bytes(capacity),
            usage: wgpu::BufferUsages::STORAGE
                | wgpu::BufferUsages::COPY_SRC
                | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        (status, commands, report)
    }

    /// The most boxes one cull can test (one-dimensional dispatch).
    pub fn max_boxes(gpu: &GpuContext) -> u32 {
        gpu.device
            .limits()
            .max_compute_workgroups_per_dimension
            .saturating_mul(HZB_CULL_WORKGROUP)
    }

    /// Records the cull of the first `box_count` records of `records` (a storage buffer of
    /// [`BuildingRecord`], e.g. [`crate::scene_gpu::AllDraws::records_buffer`], whose part ranges
    /// index `parts`, e.g. [`crate::scene_gpu::SceneGpu::parts_buffer`]; `None` when no record
    /// names parts) against
    /// `pyramid` (built from this frame's depth, seen with `view_proj`). Clears the commands and
    /// the count first. The uniforms are written through the queue: submit this encoder before
    /// recording another cull with this pass.
    pub fn encode(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        (records, parts): (&wgpu::Buffer, Option<&wgpu::Buffer>),
        box_count: u32,
        pyramid: &HzbPyramid,
        view_proj: Mat4,
    ) -> Result<(), CullError> {
        self.encode_timed(
            gpu,
            encoder,
            (records, parts),
            box_count,
            (pyramid, view_proj),
            None,
        )
    }

    /// As [`HzbCull::encode`], with the compute pass timed by `timestamp_writes`
    /// ([`crate::gpu_timer::GpuTimer::compute_pass_writes`]). With no boxes an empty pass
    /// still writes the timestamps, so a timed cull always resolves.
    pub fn encode_timed(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        (records, parts): (&wgpu::Buffer, Option<&wgpu::Buffer>),
        box_count: u32,
        (pyramid, view_proj): (&HzbPyramid, Mat4),
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), CullError> {
        self.clear_report(encoder);
        self.encode_entry(
            gpu,
            encoder,
            (CullEntry::Cull, records, parts, CullLinks::default()),
            box_count,
            (pyramid, view_proj),
            timestamp_writes,
        )
    }

    /// As [`HzbCull::encode_timed`], running `entry` with the frame's `links` (draw ids,
    /// drawn-early flags, visibility; see the module documentation). The flags buffer is the
    /// caller's to clear before an early entry point runs.
    pub fn encode_entry(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        (entry, records, parts, links): (
            CullEntry,
            &wgpu::Buffer,
            Option<&wgpu::Buffer>,
            CullLinks<'_>,
        ),
        box_count: u32,
        (pyramid, view_proj): (&HzbPyramid, Mat4),
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) -> Result<(), CullError> {
        let max = Self::max_boxes(gpu);
        if box_count > max {
            return Err(CullError::TooManyBoxes { box_count, max });
        }
        let record_capacity = records.size() / size_of::<BuildingRecord>() as u64;
        // With draw ids the records are indexed by id (the shader clamps an id past them).
        if links.draw_ids.is_none() && record_capacity < u64::from(box_count) {
            return Err(CullError::RecordsTooSmall {
                records: record_capacity,
                box_count,
            });
        }
        if let Some(ids) = links.draw_ids
            && ids.size() / 4 < u64::from(box_count)
        {
            return Err(CullError::DrawIdsTooSmall {
                ids: ids.size() / 4,
                box_count,
            });
        }
        let mut flags = 0;
        if links.draw_ids.is_some() {
            flags |= CULL_FLAG_DRAW_IDS;
        }
        if links.visibility.is_some() {
            flags |= CULL_FLAG_VISIBILITY;
        }
        if box_count > self.capacity {
            self.capacity = box_count.next_power_of_two().min(max).max(box_count);
            (self.status, self.commands, self.report) = Self::outputs(&self.device, self.capacity);
        }
        let (width, height) = pyramid.size();
        let params = HzbCullParams {
            view_proj: view_proj.to_cols_array_2d(),
            viewport_px: [width, height],
            box_count,
            level_count: pyramid.level_count(),
            frame_stamp: links.visibility.map_or(1, |v| v.frame_stamp),
            building_count: links.visibility.map_or(0, |v| v.building_count),
            flags,
            _pad: 0,
        };
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&params));
        encoder.clear_buffer(&self.count, 0, None);
        encoder.clear_buffer(
            &self.commands,
            0,
            Some(u64::from(box_count.max(1)) * COMMAND_BYTES),
        );
        if box_count == 0 {
            if timestamp_writes.is_some() {
                encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
                    label: Some("hzb cull (no boxes)"),
                    timestamp_writes,
                });
            }
            return Ok(());
        }
        let group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("hzb cull"),
            layout: &self.layout,
            entries: &[
                wgpu::BindGroupEntry {
                    binding: 0,
                    resource: self.params.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 1,
                    resource: records.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(pyramid.view()),
                },
                wgpu::BindGroupEntry {
                    binding: 3,
                    resource: self.status.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 4,
                    resource: self.commands.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 5,
                    resource: self.count.as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 6,
                    resource: parts.unwrap_or(&self.no_parts).as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 7,
                    resource: links
                        .drawn_early
                        .unwrap_or(&self.no_flags)
                        .as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 8,
                    resource: links.draw_ids.unwrap_or(&self.no_ids).as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 9,
                    resource: links
                        .visibility
                        .map_or(&self.no_stamps, |v| v.stamps)
                        .as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 10,
                    resource: links
                        .visibility
                        .map_or(&self.no_parents, |v| v.parents)
                        .as_entire_binding(),
                },
                wgpu::BindGroupEntry {
                    binding: 23,
                    resource: self.report.as_entire_binding(),
                },
            ],
        });
        let pipeline = self.pipeline(entry).clone();
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some(entry.name()),
            timestamp_writes,
        });
        pass.set_pipeline(&pipeline);
        pass.set_bind_group(0, &group, &[]);
        pass.dispatch_workgroups(box_count.div_ceil(HZB_CULL_WORKGROUP), 1, 1);
        Ok(())
    }

    /// Per-box status (`u32`), valid for the boxes of the last cull.
    pub fn status_buffer(&self) -> &wgpu::Buffer {
        &self.status
    }

    /// The frame's report: `CULL_R_*` header words, then the kept list at word
    /// `CULL_R_WORDS` and the early list at `CULL_R_WORDS +` [`HzbCull::list_capacity`]
    /// (candidate indices in no particular order). Zeroed by [`HzbCull::clear_report`], then
    /// added to by the entry points run with this pass; a cull that grows the pass replaces it
    /// by a new one, which wgpu zeroes.
    pub fn report_buffer(&self) -> &wgpu::Buffer {
        &self.report
    }

    /// Room in each list of [`HzbCull::report_buffer`].
    pub fn list_capacity(&self) -> u32 {
        self.capacity
    }

    /// Zeroes the report's header (the lists are read up to their lengths).
    pub fn clear_report(&self, encoder: &mut wgpu::CommandEncoder) {
        encoder.clear_buffer(&self.report, 0, Some(u64::from(CULL_R_WORDS) * 4));
    }

    /// The visible boxes' [`DrawIndexedIndirectArgs`], packed from the start; the rest of the
    /// last cull's `box_count` slots are zero (no-op draws).
    pub fn commands_buffer(&self) -> &wgpu::Buffer {
        &self.commands
    }

    /// The number of commands written (`u32`), for `multi_draw_indexed_indirect_count`.
    pub fn count_buffer(&self) -> &wgpu::Buffer {
        &self.count
    }

    /// Reads back the status of the last cull's `box_count` boxes and its commands (after the
    /// cull was submitted).
    pub fn read_back(
        &self,
        gpu: &GpuContext,
        box_count: u32,
    ) -> Result<CullResults, ReadbackError> {
        let n = u64::from(box_count.min(self.capacity));
        let status_bytes = n * STATUS_BYTES;
        let commands_bytes = n * COMMAND_BYTES;
        // Status, then the count at a 4-aligned offset, then the commands.
        let count_at = status_bytes;
        let commands_at = count_at + 4;
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hzb cull readback"),
            size: (commands_at + commands_bytes).max(4),
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("hzb cull readback"),
            });
        if n > 0 {
            encoder.copy_buffer_to_buffer(&self.status, 0, &buffer, 0, status_bytes);
            encoder.copy_buffer_to_buffer(&self.commands, 0, &buffer, commands_at, commands_bytes);
        }
        encoder.copy_buffer_to_buffer(&self.count, 0, &buffer, count_at, 4);
        gpu.queue.submit([encoder.finish()]);
        let bytes = map_read(gpu, &buffer)?;
        let words: Vec<u32> = bytes
            .chunks_exact(4)
            .map(|b| u32::from_le_bytes([b[0], b[1], b[2], b[3]]))
            .collect();
        let status = words[..n as usize].to_vec();
        let count = (words[n as usize] as usize).min(n as usize);
        let commands = words[n as usize + 1..]
            .chunks_exact(5)
            .take(count)
            .map(|c| DrawIndexedIndirectArgs {
                index_count: c[0],
                instance_count: c[1],
                first_index: c[2],
                base_vertex: c[3] as i32,
                first_instance: c[4],
            })
            .collect();
        Ok(CullResults { status, commands })
    }
}

/// Bytes of a report with room for `capacity` candidates in each list.
fn report_bytes(capacity: u32) -> u64 {
    (u64::from(CULL_R_WORDS) + 2 * u64::from(capacity)) * 4
}
