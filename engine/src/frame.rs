//! The two-phase occlusion-culled frame (hierarchical Z with last frame's visible set, and
//! optionally the virtual-occluder pre-pass), as a script:
//!
//! ```text
//! early_pass    → colour + depth: the ground and last frame's visible buildings (in the frustum)
//! occluder_pass → (occluders on) copy of that depth + nearby virtual occluders, depth only
//! build_pyramid → HiZ pyramid from that depth
//! cull          → every building's box against the pyramid (status, indirect commands, count)
//! late_pass     → colour + depth: the buildings the cull kept that the early pass did not draw
//! read_status   → status to the CPU: statistics and next frame's visible set
//! ```
//!
//! Greene, Kass & Miller, *Hierarchical Z-buffer visibility* (SIGGRAPH 1993) for the pyramid;
//! the two-phase use of last frame's visible set follows the "early draw → pyramid → late cull →
//! late draw" frame of zeux/niagara. Virtual occluders after Germs & Jansen (2001), built
//! offline by the preprocessor.
//!
//! **Why it is conservative.** The pyramid is built from depth that holds only real geometry
//! (the ground and buildings drawn in full) and, with occluders on, virtual occluders, each of
//! which lies inside its building, so anything they hide the building hides as well. A building
//! visible in the final image is therefore not behind that depth, the cull keeps it and the late
//! pass draws it in the same frame, even right after a fast turn (disocclusion). Occluders are
//! drawn into a *copy* of the depth used only for the pyramid: the final image's depth never
//! holds them, so a building wall that coincides with its own occluder still passes the depth
//! test and the image equals brute force.
//!
//! **Late draws.** The cull reads a copy of the building records whose index count is zero for
//! every building the early pass drew, so the late pass issues an empty command for those and
//! draws each building at most once per frame. [`FrameStats::draw_calls`] counts non-empty
//! draws only; [`FrameStats::late_commands`] is every command the late pass walked.
//!
//! **Visibility.** The next frame's early set is this frame's cull status `CULL_VISIBLE`, read
//! back with the (small) status buffer, kept per building id in [`Visibility`]. A visibility of
//! another building count (a new scene) is reset to empty, which is still correct: the early pass
//! then draws only the ground and the late pass everything the cull keeps.

use std::time::Instant;

use citywalk_scenes::frustum::{Containment, Frustum};
use citywalk_scenes::occluder::OccluderSet;
use citywalk_shaders::{
    BuildingRecord, DEPTH_COPY_WGSL, DrawIndexedIndirectArgs, SCENE_WGSL, SceneVertex,
};
use glam::{Mat4, Vec3};
use wgpu::util::DeviceExt;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::hzb::cull::{CULL_FRUSTUM_OUTSIDE, CULL_OCCLUDED, CULL_VISIBLE, CullError};
use crate::hzb::{HzbCull, HzbPyramid};
use crate::render::targets::{DepthTarget, ReadbackError, check_size};
use crate::render::view::{SceneStyle, view_uniforms};
use crate::scene_gpu::SceneGpu;

/// Default projected-size threshold of the occluder selection: an occluder is drawn when its
/// bounding sphere's projected diameter exceeds this many pixels (a "near" occluder: Germs &
/// Jansen §4 select occluders by their screen size; the value is ours, chosen so that a
/// street-level view draws the street's facades and not the whole city).
pub const DEFAULT_OCCLUDER_MIN_PX: f32 = 48.0;

/// Why a frame could not be rendered.
#[derive(Debug, thiserror::Error)]
pub enum FrameError {
    #[error(transparent)]
    Readback(#[from] ReadbackError),
    #[error(transparent)]
    Cull(#[from] CullError),
}

/// What the frame does besides the two HiZ phases.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct CullingOptions {
    /// Draw the selected virtual occluders into the depth the pyramid is built from.
    pub occluders: bool,
    /// Occluders whose bounding sphere projects to more than this many pixels are drawn.
    pub occluder_min_px: f32,
}

impl Default for CullingOptions {
    fn default() -> Self {
        CullingOptions {
            occluders: false,
            occluder_min_px: DEFAULT_OCCLUDER_MIN_PX,
        }
    }
}

/// Per-building "visible last frame" flags, carried from frame to frame.
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct Visibility {
    visible: Vec<bool>,
}

impl Visibility {
    /// Nothing visible (the state at the start of a camera path).
    pub fn reset(&mut self) {
        self.visible.clear();
    }

    /// Whether building `id` was visible in the last frame.
    pub fn is_visible(&self, id: u32) -> bool {
        self.visible.get(id as usize).copied().unwrap_or(false)
    }

    /// The visible buildings, in id order.
    pub fn visible_ids(&self) -> Vec<u32> {
        (0..self.visible.len() as u32)
            .filter(|&b| self.visible[b as usize])
            .collect()
    }

    /// Sets the flags from a cull status (`CULL_VISIBLE` = visible).
    fn update(&mut self, status: &[u32]) {
        self.visible.clear();
        self.visible
            .extend(status.iter().map(|&s| s == CULL_VISIBLE));
    }

    /// Adjusts to a scene of `building_count` buildings: a visibility of another size belongs
    /// to another scene and is dropped.
    fn fit(&mut self, building_count: usize) {
        if self.visible.len() != building_count {
            self.visible.clear();
        }
    }
}

/// One occluder on the GPU: its draw and its bounds for the CPU selection.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct OccluderDraw {
    pub building: u32,
    pub draw: DrawIndexedIndirectArgs,
    pub bounds_min_m: Vec3,
    pub bounds_max_m: Vec3,
    pub triangles: u32,
}

/// Every occluder mesh of a scene in one vertex and one index buffer, with per-occluder ranges.
#[derive(Debug)]
pub struct OccluderMeshes {
    vertex_buffer: wgpu::Buffer,
    index_buffer: wgpu::Buffer,
    /// One entry per occluder with a non-empty mesh.
    pub occluders: Vec<OccluderDraw>,
}

impl OccluderMeshes {
    /// Uploads every occluder of `set` (vertices carry the occluder's building id). Triangles
    /// with an index outside their mesh and non-finite meshes are left out.
    pub fn upload(gpu: &GpuContext, set: &OccluderSet) -> OccluderMeshes {
        let mut vertices: Vec<SceneVertex> = Vec::new();
        let mut indices: Vec<u32> = Vec::new();
        let mut occluders = Vec::new();
        for o in &set.occluders {
            let Some((lo, hi)) = o.mesh.bounds() else {
                continue;
            };
            if !(lo.is_finite() && hi.is_finite()) {
                continue;
            }
            let n = o.mesh.positions.len() as u32;
            let first_index = indices.len() as u32;
            for t in o.mesh.indices.chunks_exact(3) {
                if t.iter().all(|&v| v < n) {
                    indices.extend_from_slice(t);
                }
            }
            let index_count = indices.len() as u32 - first_index;
            if index_count == 0 {
                continue;
            }
            let base_vertex = vertices.len() as i32;
            vertices.extend(o.mesh.positions.iter().map(|p| SceneVertex {
                position_m: p.to_array(),
                building_id: o.building.0,
            }));
            occluders.push(OccluderDraw {
                building: o.building.0,
                draw: DrawIndexedIndirectArgs {
                    index_count,
                    instance_count: 1,
                    first_index,
                    base_vertex,
                    first_instance: 0,
                },
                bounds_min_m: lo,
                bounds_max_m: hi,
                triangles: index_count / 3,
            });
        }
        // Buffers are never empty, so they can always be bound.
        if vertices.is_empty() {
            vertices.push(SceneVertex {
                position_m: [0.0; 3],
                building_id: 0,
            });
        }
        if indices.is_empty() {
            indices.extend_from_slice(&[0, 0, 0]);
        }
        let device = &gpu.device;
        OccluderMeshes {
            vertex_buffer: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("occluder vertices"),
                contents: bytemuck::cast_slice(&vertices),
                usage: wgpu::BufferUsages::VERTEX,
            }),
            index_buffer: device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                label: Some("occluder indices"),
                contents: bytemuck::cast_slice(&indices),
                usage: wgpu::BufferUsages::INDEX,
            }),
            occluders,
        }
    }

    /// The occluders to draw for `camera` on a viewport `height_px` tall: in the frustum, of a
    /// building not drawn by the early pass (its own geometry hides at least as much), and whose
    /// bounding sphere projects to more than `min_px` pixels (or contains the eye).
    pub fn select(
        &self,
        camera: &Camera,
        frustum: &Frustum,
        height_px: u32,
        min_px: f32,
        drawn_early: &[bool],
    ) -> Vec<usize> {
        let px_per_rad = height_px as f32 / (camera.fov_y_rad * 0.5).tan();
        self.occluders
            .iter()
            .enumerate()
            .filter(|(_, o)| {
                !drawn_early
                    .get(o.building as usize)
                    .copied()
                    .unwrap_or(false)
            })
            .filter(|(_, o)| occluder_wanted(o, camera.position, frustum, px_per_rad, min_px))
            .map(|(i, _)| i)
            .collect()
    }
}

/// Whether an occluder is near enough to draw: its bounding sphere contains the eye or projects
/// to more than `min_px` pixels (`px_per_rad`: viewport height over `tan(fov_y / 2)`), and its
/// box is not outside the frustum.
fn occluder_wanted(
    o: &OccluderDraw,
    eye: Vec3,
    frustum: &Frustum,
    px_per_rad: f32,
    min_px: f32,
) -> bool {
    let centre = (o.bounds_min_m + o.bounds_max_m) * 0.5;
    let radius_m = (o.bounds_max_m - o.bounds_min_m).length() * 0.5;
    let distance_m = centre.distance(eye);
    (distance_m <= radius_m || radius_m / distance_m * px_per_rad > min_px)
        && frustum.classify_aabb(o.bounds_min_m, o.bounds_max_m) != Containment::Outside
}

/// Counts and timing of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameStats {
    pub building_count: u32,
    /// Buildings drawn by the early pass (last frame's visible set, in the frustum).
    pub early_drawn: u32,
    /// Virtual occluders drawn into the pyramid's depth.
    pub occluders_drawn: u32,
    pub occluder_triangles: u64,
    /// Buildings the cull found outside the frustum.
    pub frustum_culled: u32,
    /// Buildings the cull found hidden behind the pyramid.
    pub occlusion_culled: u32,
    /// Buildings the cull kept.
    pub cull_kept: u32,
    /// Buildings drawn by the late pass (kept, not drawn early).
    pub late_drawn: u32,
    /// Buildings drawn in all: early ∪ kept.
    pub drawn: u32,
    /// Triangles of the drawn buildings (ground and occluders excluded).
    pub triangles: u64,
    /// Non-empty draws: ground, early buildings, occluders, late buildings.
    pub draw_calls: u32,
    /// Commands the late pass walked (including the empty ones of early buildings).
    pub late_commands: u32,
    /// CPU wall time from the start of recording to the GPU's completion, status read (ms).
    pub cpu_ms: f64,
}

/// The result of one frame.
#[derive(Debug, Clone, Default, PartialEq)]
pub struct FrameOutput {
    /// Buildings drawn (early ∪ kept), in id order.
    pub drawn: Vec<u32>,
    /// Per building: `CULL_VISIBLE`, `CULL_FRUSTUM_OUTSIDE` or `CULL_OCCLUDED`.
    pub status: Vec<u32>,
    pub stats: FrameStats,
}

/// Size-dependent resources: depth, its copy for the occluders, the pyramid.
#[derive(Debug)]
struct Targets {
    depth: DepthTarget,
    cull_depth_view: wgpu::TextureView,
    /// Binds `depth` as the depth copy's source.
    copy_group: wgpu::BindGroup,
    pyramid: HzbPyramid,
}

/// The two-phase culling renderer: pipelines, the cull pass, draw lists and targets.
#[derive(Debug)]
pub struct CullingRenderer {
    scene_pipeline: wgpu::RenderPipeline,
    depth_pipeline: wgpu::RenderPipeline,
    copy_pipeline: wgpu::RenderPipeline,
    copy_layout: wgpu::BindGroupLayout,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    cull: HzbCull,
    early_draws: GrowBuffer,
    occluder_draws: GrowBuffer,
    late_records: GrowBuffer,
    status_readback: GrowBuffer,
    targets: Option<Targets>,
    /// The records the cull read last, with zero index counts for early buildings.
    late_records_cpu: Vec<BuildingRecord>,
    multi_draw_count: bool,
    /// Sky, sun and fog.
    pub style: SceneStyle,
}

/// A buffer grown to the largest size asked for.
#[derive(Debug)]
struct GrowBuffer {
    buffer: wgpu::Buffer,
    label: &'static str,
    usage: wgpu::BufferUsages,
}

impl GrowBuffer {
    fn new(device: &wgpu::Device, label: &'static str, usage: wgpu::BufferUsages) -> GrowBuffer {
        GrowBuffer {
            buffer: Self::make(device, label, usage, 256),
            label,
            usage,
        }
    }

    fn make(
        device: &wgpu::Device,
        label: &str,
        usage: wgpu::BufferUsages,
        size: u64,
    ) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        })
    }

    /// Ensures room for `bytes` (contents are lost when it grows).
    fn reserve(&mut self, device: &wgpu::Device, bytes: u64) -> bool {
        if bytes <= self.buffer.size() {
            return false;
        }
        let size = bytes.next_power_of_two().max(256);
        self.buffer = Self::make(device, self.label, self.usage, size);
        true
    }
}

impl CullingRenderer {
    /// A renderer drawing into colour targets of `colour_format` (as
    /// [`crate::render::BruteRenderer::new`]).
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> CullingRenderer {
        let device = &gpu.device;
        let layout = crate::render::view_bind_group_layout(device, "frame view");
        let (view_buffer, view_group) =
            crate::render::view_buffer_and_group(device, &layout, "frame view");
        let scene_pipeline = crate::render::scene_pipeline(
            device,
            "frame scene",
            SCENE_WGSL,
            &layout,
            Some(colour_format),
        );
        let depth_pipeline =
            crate::render::scene_pipeline(device, "occluder depth", SCENE_WGSL, &layout, None);
        let (copy_pipeline, copy_layout) = depth_copy_pipeline(device);
        let indirect = wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST;
        CullingRenderer {
            scene_pipeline,
            depth_pipeline,
            copy_pipeline,
            copy_layout,
            view_buffer,
            view_group,
            cull: HzbCull::new(gpu, 1024),
            early_draws: GrowBuffer::new(device, "early draws", indirect),
            occluder_draws: GrowBuffer::new(device, "occluder draws", indirect),
            late_records: GrowBuffer::new(
                device,
                "late cull records",
                wgpu::BufferUsages::STORAGE | wgpu::BufferUsages::COPY_DST,
            ),
            status_readback: GrowBuffer::new(
                device,
                "cull status readback",
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            ),
            targets: None,
            late_records_cpu: Vec::new(),
            multi_draw_count: gpu.has(wgpu::Features::MULTI_DRAW_INDIRECT_COUNT),
            style: SceneStyle::default(),
        }
    }

    /// Renders one frame of `scene` from `camera` into `colour` (`width × height`, the format
    /// given to [`CullingRenderer::new`]), with `occluders` when `options.occluders` is set and
    /// some are given. Reads `visibility` (last frame) and writes it for the next frame. Waits
    /// for the GPU.
    #[expect(clippy::too_many_arguments, reason = "one frame, all inputs explicit")]
    pub fn render(
        &mut self,
        gpu: &GpuContext,
        scene: &SceneGpu,
        occluders: Option<&OccluderMeshes>,
        options: &CullingOptions,
        visibility: &mut Visibility,
        camera: &Camera,
        colour: &wgpu::TextureView,
        (width, height): (u32, u32),
    ) -> Result<FrameOutput, FrameError> {
        let start = Instant::now();
        self.fit_targets(gpu, width, height)?;
        let n = scene.building_count();
        self.reserve_readback(gpu, n);
        visibility.fit(n);
        let view_proj = camera.view_proj(width as f32 / height as f32);
        let frustum = Frustum::from_view_proj(view_proj);
        let uniforms = view_uniforms(camera, width, height, &self.style);
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("culled frame"),
            });

        let early = self.early_pass(gpu, &mut encoder, scene, visibility, &frustum, colour);
        let occluders_drawn = match occluders.filter(|_| options.occluders) {
            Some(meshes) => self.occluder_pass(
                gpu,
                &mut encoder,
                meshes,
                camera,
                &frustum,
                height,
                options.occluder_min_px,
                &early.drawn,
            ),
            None => Vec::new(),
        };
        self.build_pyramid(&mut encoder, !occluders_drawn.is_empty());
        self.cull(gpu, &mut encoder, scene, &early.drawn, view_proj)?;
        self.late_pass(&mut encoder, scene, colour);
        self.read_status(&mut encoder, n);

        gpu.queue.submit([encoder.finish()]);
        let status = self.status_to_cpu(gpu, n)?;
        visibility.update(&status);
        let mut output = self.statistics(scene, &early, status);
        if let Some(meshes) = occluders {
            output.stats.occluders_drawn = occluders_drawn.len() as u32;
            output.stats.occluder_triangles = occluders_drawn
                .iter()
                .map(|&i| u64::from(meshes.occluders[i].triangles))
                .sum();
            output.stats.draw_calls += occluders_drawn.len() as u32;
        }
        output.stats.cpu_ms = start.elapsed().as_secs_f64() * 1e3;
        Ok(output)
    }

    /// Clears colour and depth, draws the ground and last frame's visible buildings that lie in
    /// the frustum.
    fn early_pass(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        visibility: &Visibility,
        frustum: &Frustum,
        colour: &wgpu::TextureView,
    ) -> EarlySet {
        let mut drawn = vec![false; scene.building_count()];
        let mut draws = vec![scene.ground];
        for (i, r) in scene.records.iter().enumerate() {
            if visibility.is_visible(i as u32)
                && frustum.classify_aabb(
                    Vec3::from_array(r.bounds_min_m),
                    Vec3::from_array(r.bounds_max_m),
                ) != Containment::Outside
            {
                drawn[i] = true;
                draws.push(r.draw_args());
            }
        }
        let bytes: &[u8] = bytemuck::cast_slice(&draws);
        self.early_draws.reserve(&gpu.device, bytes.len() as u64);
        gpu.queue.write_buffer(&self.early_draws.buffer, 0, bytes);
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("early_pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: colour,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Clear(self.style.clear_colour()),
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(targets.depth.attachment()),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.scene_pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        pass.multi_draw_indexed_indirect(&self.early_draws.buffer, 0, draws.len() as u32);
        EarlySet {
            drawn,
            draw_count: draws.len() as u32,
        }
    }

    /// Copies the early depth into the pyramid's depth and draws the selected occluders into
    /// it, depth only. Returns the indices of the occluders drawn.
    #[expect(clippy::too_many_arguments, reason = "one pass, all inputs explicit")]
    fn occluder_pass(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        meshes: &OccluderMeshes,
        camera: &Camera,
        frustum: &Frustum,
        height: u32,
        min_px: f32,
        drawn_early: &[bool],
    ) -> Vec<usize> {
        let selected = meshes.select(camera, frustum, height, min_px, drawn_early);
        if selected.is_empty() {
            return selected;
        }
        let draws: Vec<DrawIndexedIndirectArgs> =
            selected.iter().map(|&i| meshes.occluders[i].draw).collect();
        let bytes: &[u8] = bytemuck::cast_slice(&draws);
        self.occluder_draws.reserve(&gpu.device, bytes.len() as u64);
        gpu.queue
            .write_buffer(&self.occluder_draws.buffer, 0, bytes);
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("occluder_pass"),
            color_attachments: &[],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.cull_depth_view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Clear(Camera::DEPTH_CLEAR),
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        // The early depth, texel for texel (a shader copy: see `wgsl/depth_copy.wgsl`).
        pass.set_pipeline(&self.copy_pipeline);
        pass.set_bind_group(0, &targets.copy_group, &[]);
        pass.draw(0..3, 0..1);
        pass.set_pipeline(&self.depth_pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        pass.set_vertex_buffer(0, meshes.vertex_buffer.slice(..));
        pass.set_index_buffer(meshes.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        pass.multi_draw_indexed_indirect(&self.occluder_draws.buffer, 0, draws.len() as u32);
        selected
    }

    /// Builds the pyramid from the early depth, or from its copy holding the occluders.
    fn build_pyramid(&self, encoder: &mut wgpu::CommandEncoder, with_occluders: bool) {
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let depth = if with_occluders {
            &targets.cull_depth_view
        } else {
            &targets.depth.view
        };
        targets.pyramid.build(encoder, depth);
    }

    /// Culls every building against the pyramid; early buildings get empty commands.
    fn cull(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        drawn_early: &[bool],
        view_proj: Mat4,
    ) -> Result<(), FrameError> {
        let n = scene.building_count();
        let changed = self.late_records_cpu.len() != n
            || self
                .late_records_cpu
                .iter()
                .zip(&scene.records)
                .zip(drawn_early)
                .any(|((late, r), &early)| {
                    late.index_count != if early { 0 } else { r.index_count }
                        || late.first_index != r.first_index
                });
        let bytes = (n.max(1) * size_of::<BuildingRecord>()) as u64;
        let grown = self.late_records.reserve(&gpu.device, bytes);
        if changed || grown {
            self.late_records_cpu.clear();
            self.late_records_cpu
                .extend(scene.records.iter().zip(drawn_early).map(|(r, &early)| {
                    let mut r = *r;
                    if early {
                        r.index_count = 0;
                    }
                    r
                }));
            if !self.late_records_cpu.is_empty() {
                gpu.queue.write_buffer(
                    &self.late_records.buffer,
                    0,
                    bytemuck::cast_slice(&self.late_records_cpu),
                );
            }
        }
        let targets = self.targets.as_ref().expect("fit_targets ran");
        self.cull.encode(
            gpu,
            encoder,
            &self.late_records.buffer,
            n as u32,
            &targets.pyramid,
            view_proj,
        )?;
        Ok(())
    }

    /// Draws the cull's commands (colour and depth loaded).
    fn late_pass(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        colour: &wgpu::TextureView,
    ) {
        let n = scene.building_count() as u32;
        if n == 0 {
            return;
        }
        let targets = self.targets.as_ref().expect("fit_targets ran");
        let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
            label: Some("late_pass"),
            color_attachments: &[Some(wgpu::RenderPassColorAttachment {
                view: colour,
                depth_slice: None,
                resolve_target: None,
                ops: wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                },
            })],
            depth_stencil_attachment: Some(wgpu::RenderPassDepthStencilAttachment {
                view: &targets.depth.view,
                depth_ops: Some(wgpu::Operations {
                    load: wgpu::LoadOp::Load,
                    store: wgpu::StoreOp::Store,
                }),
                stencil_ops: None,
            }),
            timestamp_writes: None,
            occlusion_query_set: None,
            multiview_mask: None,
        });
        pass.set_pipeline(&self.scene_pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        if self.multi_draw_count {
            pass.multi_draw_indexed_indirect_count(
                self.cull.commands_buffer(),
                0,
                self.cull.count_buffer(),
                0,
                n,
            );
        } else {
            // The commands past the count are zero (cleared by the cull): empty draws.
            pass.multi_draw_indexed_indirect(self.cull.commands_buffer(), 0, n);
        }
    }

    /// Copies the cull status into the readback buffer.
    fn read_status(&mut self, encoder: &mut wgpu::CommandEncoder, n: usize) {
        if n == 0 {
            return;
        }
        let bytes = (n * 4) as u64;
        encoder.copy_buffer_to_buffer(
            self.cull.status_buffer(),
            0,
            &self.status_readback.buffer,
            0,
            bytes,
        );
    }

    fn status_to_cpu(&mut self, gpu: &GpuContext, n: usize) -> Result<Vec<u32>, FrameError> {
        if n == 0 {
            gpu.wait_idle();
            return Ok(Vec::new());
        }
        let slice = self.status_readback.buffer.slice(..(n * 4) as u64);
        let (tx, rx) = std::sync::mpsc::channel();
        slice.map_async(wgpu::MapMode::Read, move |r| {
            let _ = tx.send(r);
        });
        gpu.device
            .poll(wgpu::PollType::wait_indefinitely())
            .map_err(ReadbackError::from)?;
        rx.recv()
            .map_err(|e| ReadbackError::MappedRange(e.to_string()))?
            .map_err(ReadbackError::from)?;
        let mapped = slice
            .get_mapped_range()
            .map_err(|e| ReadbackError::MappedRange(e.to_string()))?;
        let status: Vec<u32> = bytemuck::pod_collect_to_vec(&mapped);
        drop(mapped);
        self.status_readback.buffer.unmap();
        Ok(status)
    }

    fn statistics(&self, scene: &SceneGpu, early: &EarlySet, status: Vec<u32>) -> FrameOutput {
        let mut stats = FrameStats {
            building_count: scene.building_count() as u32,
            draw_calls: early.draw_count,
            late_commands: 0,
            ..FrameStats::default()
        };
        let mut drawn = Vec::new();
        for (i, (&s, r)) in status.iter().zip(&scene.records).enumerate() {
            let was_early = early.drawn[i];
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
            if was_early || s == CULL_VISIBLE {
                drawn.push(i as u32);
                stats.triangles += u64::from(r.index_count / 3);
            }
        }
        stats.early_drawn = early.drawn.iter().filter(|&&d| d).count() as u32;
        stats.drawn = drawn.len() as u32;
        stats.late_commands = if self.multi_draw_count {
            stats.cull_kept
        } else {
            stats.building_count
        };
        FrameOutput {
            drawn,
            status,
            stats,
        }
    }

    /// (Re)makes the depth targets and the pyramid for a new viewport size.
    fn fit_targets(&mut self, gpu: &GpuContext, width: u32, height: u32) -> Result<(), FrameError> {
        if self
            .targets
            .as_ref()
            .is_some_and(|t| (t.depth.width, t.depth.height) == (width, height))
        {
            return Ok(());
        }
        check_size(gpu, width, height)?;
        let depth = DepthTarget::new(gpu, width, height);
        // The culling depth (early pass + occluders) is a second target of the same kind.
        let cull_depth_view = DepthTarget::new(gpu, width, height).view;
        let copy_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("depth copy"),
            layout: &self.copy_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&depth.view),
            }],
        });
        self.targets = Some(Targets {
            depth,
            cull_depth_view,
            copy_group,
            pyramid: HzbPyramid::new(gpu, width, height)?,
        });
        Ok(())
    }

    /// Makes sure the status readback can hold `n` entries (called before recording).
    fn reserve_readback(&mut self, gpu: &GpuContext, n: usize) {
        self.status_readback
            .reserve(&gpu.device, (n.max(1) * 4) as u64);
    }
}

/// What the early pass drew.
#[derive(Debug)]
struct EarlySet {
    /// Per building.
    drawn: Vec<bool>,
    /// Draws issued, ground included.
    draw_count: u32,
}

/// The fullscreen depth copy (`wgsl/depth_copy.wgsl`): depth compare Always, no colour.
fn depth_copy_pipeline(device: &wgpu::Device) -> (wgpu::RenderPipeline, wgpu::BindGroupLayout) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some("depth copy"),
        source: wgpu::ShaderSource::Wgsl(DEPTH_COPY_WGSL.into()),
    });
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("depth copy"),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::FRAGMENT,
            // Depth bound as unfilterable float and read through `.r` (GL trap 2).
            ty: wgpu::BindingType::Texture {
                sample_type: wgpu::TextureSampleType::Float { filterable: false },
                view_dimension: wgpu::TextureViewDimension::D2,
                multisampled: false,
            },
            count: None,
        }],
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some("depth copy"),
        bind_group_layouts: &[Some(&layout)],
        immediate_size: 0,
    });
    let pipeline = device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some("depth copy"),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DepthTarget::FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(wgpu::CompareFunction::Always),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[],
        }),
        multiview_mask: None,
        cache: None,
    });
    (pipeline, layout)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn visibility_follows_the_status_and_resets_for_another_scene() {
        let mut v = Visibility::default();
        assert!(!v.is_visible(0));
        v.fit(3);
        v.update(&[CULL_VISIBLE, CULL_OCCLUDED, CULL_VISIBLE]);
        assert_eq!(v.visible_ids(), vec![0, 2]);
        assert!(v.is_visible(2) && !v.is_visible(1) && !v.is_visible(7));
        v.fit(3);
        assert_eq!(v.visible_ids(), vec![0, 2]);
        // Another building count: another scene, nothing carried over.
        v.fit(4);
        assert!(v.visible_ids().is_empty());
        v.update(&[CULL_FRUSTUM_OUTSIDE, CULL_VISIBLE, 0, 0]);
        v.reset();
        assert!(!v.is_visible(1));
    }

    #[test]
    fn occluders_are_wanted_by_projected_size_and_frustum() {
        let camera = Camera::new(Vec3::ZERO, 0.0, 0.0);
        let height_px = 720;
        let px_per_rad = height_px as f32 / (camera.fov_y_rad * 0.5).tan();
        let frustum = Frustum::from_view_proj(camera.view_proj(16.0 / 9.0));
        // A 10 m cube (radius ≈ 8.66 m) straight ahead at distance d projects to
        // 8.66 / d · 1247 px: more than 48 px up to d ≈ 225 m.
        let cube = |centre: Vec3| OccluderDraw {
            building: 0,
            draw: DrawIndexedIndirectArgs {
                index_count: 3,
                instance_count: 1,
                first_index: 0,
                base_vertex: 0,
                first_instance: 0,
            },
            bounds_min_m: centre - Vec3::splat(5.0),
            bounds_max_m: centre + Vec3::splat(5.0),
            triangles: 1,
        };
        let wanted = |centre: Vec3| {
            occluder_wanted(
                &cube(centre),
                camera.position,
                &frustum,
                px_per_rad,
                DEFAULT_OCCLUDER_MIN_PX,
            )
        };
        assert!(wanted(Vec3::new(50.0, 0.0, 0.0)));
        assert!(wanted(Vec3::new(200.0, 0.0, 0.0)));
        assert!(!wanted(Vec3::new(260.0, 0.0, 0.0)));
        // Behind the eye: outside the frustum however large.
        assert!(!wanted(Vec3::new(-20.0, 0.0, 0.0)));
        // Around the eye: always.
        assert!(wanted(Vec3::new(1.0, 0.0, 0.0)));
    }
}
