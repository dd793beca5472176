//! The tree cull: the screen-space LOD cut of the cluster tree computed on the GPU, with
//! hierarchical occlusion culling of the tree's nodes against the pyramid, so that a LOD frame
//! costs the CPU a constant amount whatever the city's size (`shaders/wgsl/hzb_cull.wgsl`,
//! entry points `tree_begin`, `tree_early`, `tree_advance`, `tree_level`; CPU reference
//! [`super::reference::tree_cull`]).
//!
//! The cut is Chang et al. 2008 §8 / Yang et al. 2011 §4 as in [`crate::lod`]; the walk is the
//! hierarchical culling of Greene, Kass & Miller (1993) applied to the cluster tree instead of an
//! octree: a node whose box (its cull record, holding every building under it) the pyramid
//! hides is dropped with its subtree. The walk is one dispatch per tree level, of a fixed
//! number of workgroups striding over the level's queue entries (the last workgroup to finish
//! moves the walk to the next level); the CPU records a fixed number of dispatches and uploads
//! two parameter blocks. (A walk of the whole tree in one workgroup, with barriers between the
//! levels, saved lavapipe a dispatch per level but dropped nodes on wide cuts: on the generated
//! 1M city it kept 12k of the 42k clusters the per-level walk keeps and lost a visible
//! building; it was removed.)
//!
//! **Why it is conservative.** A building visible in the full-detail frame is not hidden by the
//! pyramid (which holds only real geometry and occluders inside their buildings), so neither is
//! any box containing it: every ancestor's box passes, the walk reaches the cut node covering the
//! building, and that node passes too. The pyramid test is the cull's own (`test_hull`,
//! widened for rounding), so the GPU keeps a superset of what the CPU reference keeps.
//!
//! **Early draws.** This frame's kept draw ids go to one half of a two-half list held by the
//! [`crate::frame::Visibility`]; the next frame's `tree_early` draws those that are buildings
//! still in its cut and inside the frustum, marks them in a per-draw-id buffer with the frame's number (no clear)
//! and lists them for the report; the walk appends no second draw for a marked id.

use citywalk_shaders::constants::{TREE_C_WORDS, TREE_LIST_HEADER};
use citywalk_shaders::{
    DrawIndexedIndirectArgs, HZB_CULL_WGSL, HzbCullParams, TreeCullParams, TreeLandmark, TreeNode,
};
use glam::Mat4;

use super::build::HzbPyramid;
use crate::gpu::GpuContext;
use crate::lod::gpu_tree::TreeArrays;
use crate::upload::{UploadError, array_buffer};

/// The tree's arrays on the GPU (made once per LOD scene).
#[derive(Debug)]
pub struct TreeBuffers {
    pub nodes: wgpu::Buffer,
    pub children: wgpu::Buffer,
    pub landmarks: wgpu::Buffer,
    pub leaf_of: wgpu::Buffer,
    pub node_count: u32,
    pub root: u32,
    /// Levels of the tree: the walk's dispatches.
    pub levels: u32,
}

impl TreeBuffers {
    pub fn upload(gpu: &GpuContext, arrays: &TreeArrays) -> Result<TreeBuffers, UploadError> {
        fn storage<T: bytemuck::Pod>(
            gpu: &GpuContext,
            label: &str,
            items: &[T],
        ) -> Result<wgpu::Buffer, UploadError> {
            array_buffer(gpu, label, items, wgpu::BufferUsages::STORAGE, &|_| {})
        }
        Ok(TreeBuffers {
            nodes: storage::<TreeNode>(gpu, "tree nodes", &arrays.nodes)?,
            children: storage(gpu, "tree children", &arrays.children)?,
            landmarks: storage::<TreeLandmark>(gpu, "tree landmarks", &arrays.landmarks)?,
            leaf_of: storage(gpu, "tree leaf of building", &arrays.leaf_of)?,
            node_count: arrays.nodes.len() as u32,
            root: arrays.root,
            levels: arrays.levels,
        })
    }
}

/// What one tree cull reads: the tree, the records by draw id (a LOD scene's cull records), the
/// parts they name, and the two-half kept lists of the frame stream.
#[derive(Debug, Clone, Copy)]
pub struct TreeInputs<'a> {
    pub tree: &'a TreeBuffers,
    pub records: &'a wgpu::Buffer,
    pub parts: &'a wgpu::Buffer,
    /// [`TREE_LIST_HEADER`] count words, then two halves of `list_capacity` draw ids.
    pub lists: &'a wgpu::Buffer,
    pub draw_id_count: u32,
}

/// Tree cull: workgroups of each early and level dispatch on a hardware adapter, which stride
/// over their entries ([`TreeCullParams::walk_workgroups`]). A fixed count rather than an indirect
/// dispatch sized by the previous level: on lavapipe the dispatch that writes the arguments and
/// the barrier before the indirect read cost about 8 ms per tree level, the fixed dispatches
/// 0.05 ms.
const TREE_WALK_WORKGROUPS: u32 = 64;

/// Tree cull: workgroups of each dispatch on a software adapter, whose few threads run the
/// workgroups one after another: on the generated 1M city (lavapipe, 640×360) the walk took
/// 23.7 ms a walk frame and 32.8 ms a street frame with 64 workgroups, 2.9 ms and 8.9 ms with 4.
const TREE_WALK_WORKGROUPS_SOFTWARE: u32 = 4;

/// The bytes of a kept-lists buffer of `capacity` entries per half.
pub fn lists_bytes(capacity: u32) -> u64 {
    (u64::from(TREE_LIST_HEADER) + 2 * u64::from(capacity)) * 4
}

/// The tree cull's pipelines and per-frame buffers (queue, counters, commands, early marks),
/// sized to the scene.
#[derive(Debug)]
pub struct TreeCull {
    device: wgpu::Device,
    layout: wgpu::BindGroupLayout,
    begin: wgpu::ComputePipeline,
    early: wgpu::ComputePipeline,
    level: wgpu::ComputePipeline,
    /// Workgroups of each early and level dispatch: fewer on a software adapter, whose threads
    /// run them one after another.
    walk_workgroups: u32,
    params: wgpu::Buffer,
    tree_params: wgpu::Buffer,
    counters: wgpu::Buffer,
    sized: Option<Sized>,
}

/// The buffers whose size follows the scene.
#[derive(Debug)]
struct Sized {
    node_count: u32,
    draw_id_count: u32,
    queue: wgpu::Buffer,
    early_ids: wgpu::Buffer,
    early_commands: wgpu::Buffer,
    late_commands: wgpu::Buffer,
    early_marks: wgpu::Buffer,
}

/// Read-only storage bindings: records, parts, nodes, children, landmarks, leaf of building.
const BINDINGS_READ: [u32; 6] = [1, 6, 12, 13, 14, 15];

impl TreeCull {
    pub fn new(gpu: &GpuContext) -> TreeCull {
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("tree cull"),
            source: wgpu::ShaderSource::Wgsl(HZB_CULL_WGSL.into()),
        });
        let buffer = |binding, ty| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::Buffer {
                ty,
                has_dynamic_offset: false,
                min_binding_size: None,
            },
            count: None,
        };
        let read = wgpu::BufferBindingType::Storage { read_only: true };
        let rw = wgpu::BufferBindingType::Storage { read_only: false };
        let mut entries = vec![
            buffer(0, read),
            crate::render::float_texture_entry(2, wgpu::ShaderStages::COMPUTE),
            buffer(11, read),
        ];
        entries.extend(BINDINGS_READ.iter().map(|&b| buffer(b, read)));
        entries.extend((16..=22).map(|b| buffer(b, rw)));
        let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("tree cull"),
            entries: &entries,
        });
        let walk_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
            label: Some("tree cull"),
            bind_group_layouts: &[Some(&layout)],
            immediate_size: 0,
        });
        let pipeline = |entry: &str, layout: &wgpu::PipelineLayout| {
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(entry),
                layout: Some(layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let uniform_buffer = |label, size| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size,
                usage: wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
                mapped_at_creation: false,
            })
        };
        TreeCull {
            begin: pipeline("tree_begin", &walk_layout),
            early: pipeline("tree_early", &walk_layout),
            level: pipeline("tree_level", &walk_layout),
            walk_workgroups: if gpu.is_software() {
                TREE_WALK_WORKGROUPS_SOFTWARE
            } else {
                TREE_WALK_WORKGROUPS
            },
            params: uniform_buffer("tree cull params", size_of::<HzbCullParams>() as u64),
            tree_params: uniform_buffer(
                "tree cull tree params",
                size_of::<TreeCullParams>() as u64,
            ),
            counters: device.create_buffer(&wgpu::BufferDescriptor {
                label: Some("tree cull counters"),
                size: u64::from(TREE_C_WORDS) * 4,
                usage: wgpu::BufferUsages::STORAGE
                    | wgpu::BufferUsages::INDIRECT
                    | wgpu::BufferUsages::COPY_SRC,
                mapped_at_creation: false,
            }),
            layout,
            device: device.clone(),
            sized: None,
        }
    }

    /// Sizes the buffers for `inputs`' scene and writes this frame's uniforms: the view
    /// (`view_proj`, the pyramid's size and levels) and `params` (the caller's view, criterion,
    /// lists and frame fields; the queue size and root are filled in here).
    pub fn prepare(
        &mut self,
        gpu: &GpuContext,
        inputs: &TreeInputs<'_>,
        mut params: TreeCullParams,
        (pyramid, view_proj): (&HzbPyramid, Mat4),
    ) {
        let fits = self.sized.as_ref().is_some_and(|s| {
            s.node_count == inputs.tree.node_count && s.draw_id_count == inputs.draw_id_count
        });
        if !fits {
            self.sized = Some(Sized::new(
                &self.device,
                inputs.tree.node_count,
                inputs.draw_id_count,
            ));
        }
        params.root = inputs.tree.root;
        params.node_count = inputs.tree.node_count;
        params.queue_capacity = inputs.tree.node_count;
        params.walk_workgroups = self.walk_workgroups;
        let (width, height) = pyramid.size();
        let view = HzbCullParams {
            view_proj: view_proj.to_cols_array_2d(),
            viewport_px: [width, height],
            box_count: 0,
            level_count: pyramid.level_count(),
            frame_stamp: 0,
            building_count: params.building_count,
            flags: 0,
            _pad: 0,
        };
        gpu.queue
            .write_buffer(&self.params, 0, bytemuck::bytes_of(&view));
        gpu.queue
            .write_buffer(&self.tree_params, 0, bytemuck::bytes_of(&params));
    }

    fn group(&self, inputs: &TreeInputs<'_>, pyramid: &HzbPyramid) -> wgpu::BindGroup {
        let s = self.sized.as_ref().expect("prepare ran");
        self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("tree cull"),
            layout: &self.layout,
            entries: &[
                entry(0, &self.params),
                entry(1, inputs.records),
                wgpu::BindGroupEntry {
                    binding: 2,
                    resource: wgpu::BindingResource::TextureView(pyramid.view()),
                },
                entry(6, inputs.parts),
                entry(11, &self.tree_params),
                entry(12, &inputs.tree.nodes),
                entry(13, &inputs.tree.children),
                entry(14, &inputs.tree.landmarks),
                entry(15, &inputs.tree.leaf_of),
                entry(16, &s.queue),
                entry(17, &self.counters),
                entry(18, inputs.lists),
                entry(19, &s.early_ids),
                entry(20, &s.early_commands),
                entry(21, &s.late_commands),
                entry(22, &s.early_marks),
            ],
        })
    }

    /// Resets the counters, then runs the early entry point over last frame's kept list
    /// (`pyramid` is bound but not read).
    pub fn encode_early(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &TreeInputs<'_>,
        pyramid: &HzbPyramid,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let group = self.group(inputs, pyramid);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("tree_early"),
            timestamp_writes,
        });
        pass.set_bind_group(0, &group, &[]);
        pass.set_pipeline(&self.begin);
        pass.dispatch_workgroups(1, 1, 1);
        pass.set_pipeline(&self.early);
        pass.dispatch_workgroups(self.walk_workgroups, 1, 1);
    }

    /// The walk over the tree's levels against `pyramid` (the main one).
    pub fn encode_walk(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        inputs: &TreeInputs<'_>,
        pyramid: &HzbPyramid,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let group = self.group(inputs, pyramid);
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("tree_walk"),
            timestamp_writes,
        });
        pass.set_bind_group(0, &group, &[]);
        pass.set_pipeline(&self.level);
        for _ in 0..inputs.tree.levels {
            pass.dispatch_workgroups(self.walk_workgroups, 1, 1);
        }
    }

    /// The counters (`TREE_C_*` words; the draw counts are the indirect draw counts).
    pub fn counters(&self) -> &wgpu::Buffer {
        &self.counters
    }

    /// The early entry point's draws and the ids it drew.
    pub fn early_commands(&self) -> &wgpu::Buffer {
        &self.sized.as_ref().expect("prepare ran").early_commands
    }

    pub fn early_ids(&self) -> &wgpu::Buffer {
        &self.sized.as_ref().expect("prepare ran").early_ids
    }

    /// The walk's draws.
    pub fn late_commands(&self) -> &wgpu::Buffer {
        &self.sized.as_ref().expect("prepare ran").late_commands
    }

    /// The most draws either command buffer holds (one per draw id).
    pub fn max_draws(&self) -> u32 {
        self.sized.as_ref().map_or(0, |s| s.draw_id_count.max(1))
    }
}

fn entry(binding: u32, buffer: &wgpu::Buffer) -> wgpu::BindGroupEntry<'_> {
    wgpu::BindGroupEntry {
        binding,
        resource: buffer.as_entire_binding(),
    }
}

impl Sized {
    fn new(device: &wgpu::Device, node_count: u32, draw_id_count: u32) -> Sized {
        let make = |label, bytes: u64, usage| {
            device.create_buffer(&wgpu::BufferDescriptor {
                label: Some(label),
                size: bytes.max(16),
                usage: wgpu::BufferUsages::STORAGE | usage,
                mapped_at_creation: false,
            })
        };
        let draws = u64::from(draw_id_count.max(1));
        let command = size_of::<DrawIndexedIndirectArgs>() as u64;
        let indirect = wgpu::BufferUsages::INDIRECT;
        Sized {
            node_count,
            draw_id_count,
            queue: make(
                "tree cull queue",
                u64::from(node_count) * 4,
                wgpu::BufferUsages::empty(),
            ),
            early_ids: make(
                "tree cull early ids",
                draws * 4,
                wgpu::BufferUsages::COPY_SRC,
            ),
            early_commands: make("tree cull early draws", draws * command, indirect),
            late_commands: make("tree cull late draws", draws * command, indirect),
            // Zeroed at creation; frame marks start at 1.
            early_marks: make(
                "tree cull early marks",
                draws * 4,
                wgpu::BufferUsages::empty(),
            ),
        }
    }
}
