//! The GPU hierarchical-Z pyramid build: an `R32Float` texture with every level down to 1×1,
//! level 0 copied from the reversed-Z `Depth32Float` depth buffer and each further level the
//! minimum (farthest depth) of up to 2×2 texels of the one before, exactly as
//! [`super::reference::DepthPyramid::build`] (which the tests compare with texel for texel).
//!
//! One compute dispatch per level (`shaders/wgsl/hzb_build.wgsl`), the first writing levels 0
//! and 1 together; [`HzbPyramid::build_merged_timed`] builds from two depth buffers at once (the
//! nearer depth of each texel kept), so the virtual occluders are drawn into a cleared depth of
//! their own instead of into a full-screen copy of the frame's. The occluders' depth is eroded
//! by one texel as it is read ([`super::reference::erode`]). Every level has its own
//! single-level views, the source level is a read-only storage texture and no level index is a
//! shader value, which avoids the llvmpipe and GL traps of `/work/shared/GPU-NOTES.md`.
//!
//! Texture mips halve with floor (1001 → 500) but the pyramid halves with ceil (1001 → 501, and
//! 1280 needs 12 levels where its mip chain has 11), so the texture is allocated at the next
//! powers of two of the viewport; level `l` of the pyramid is the top-left
//! [`HzbPyramid::level_size`] region of mip `l`, and nothing outside it is written or read.

use citywalk_shaders::HZB_BUILD_WGSL;
use citywalk_shaders::constants::HZB_BUILD_WORKGROUP;

use wgpu::util::DeviceExt;

use super::reference::{DepthPyramid, PyramidLevel, level_count};
use crate::gpu::GpuContext;
use crate::render::targets::{ReadbackError, check_size, map_read};

/// The pyramid's texel format.
pub const HZB_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::R32Float;

/// The pyramid texture of one viewport size and the pipelines that build it.
#[derive(Debug)]
pub struct HzbPyramid {
    device: wgpu::Device,
    copy_pipeline: wgpu::ComputePipeline,
    eroded_pipeline: wgpu::ComputePipeline,
    merge_pipeline: wgpu::ComputePipeline,
    copy_layout: wgpu::BindGroupLayout,
    /// Mip 1 of the texture: pyramid level 1, or (a one-level pyramid) an unread spare.
    level1_view: wgpu::TextureView,
    reduce_pipeline: wgpu::ComputePipeline,
    /// `reduce_groups[l]` reads level `l + 1` and writes level `l + 2`.
    reduce_groups: Vec<wgpu::BindGroup>,
    /// Single-level views, one per level.
    level_views: Vec<wgpu::TextureView>,
    texture: wgpu::Texture,
    /// A view of all levels, for the cull pass.
    all_levels_view: wgpu::TextureView,
    width: u32,
    height: u32,
}

/// The depth a pyramid is built from.
#[derive(Debug, Clone, Copy)]
enum PyramidSource<'a> {
    /// Real geometry, taken as it is.
    Depth(&'a wgpu::TextureView),
    /// Virtual occluders (and the ground), eroded by one texel.
    Occluders(&'a wgpu::TextureView),
    /// Real geometry and virtual occluders, these eroded, the nearer depth kept.
    Merged(&'a wgpu::TextureView, &'a wgpu::TextureView),
}

impl HzbPyramid {
    /// A pyramid for a `width × height` depth buffer, with [`level_count`] levels.
    pub fn new(gpu: &GpuContext, width: u32, height: u32) -> Result<HzbPyramid, ReadbackError> {
        check_size(gpu, width, height)?;
        let device = &gpu.device;
        let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
            label: Some("hzb build"),
            source: wgpu::ShaderSource::Wgsl(HZB_BUILD_WGSL.into()),
        });
        let storage = |binding, access| wgpu::BindGroupLayoutEntry {
            binding,
            visibility: wgpu::ShaderStages::COMPUTE,
            ty: wgpu::BindingType::StorageTexture {
                access,
                format: HZB_FORMAT,
                view_dimension: wgpu::TextureViewDimension::D2,
            },
            count: None,
        };
        // Depth bound as unfilterable float and read through `.r` (GL trap 2).
        let depth =
            |binding| crate::render::float_texture_entry(binding, wgpu::ShaderStages::COMPUTE);
        let copy_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("hzb copy depth"),
            entries: &[
                depth(0),
                depth(5),
                storage(1, wgpu::StorageTextureAccess::WriteOnly),
                storage(6, wgpu::StorageTextureAccess::WriteOnly),
            ],
        });
        let reduce_layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
            label: Some("hzb reduce"),
            entries: &[
                storage(2, wgpu::StorageTextureAccess::ReadOnly),
                storage(3, wgpu::StorageTextureAccess::WriteOnly),
                wgpu::BindGroupLayoutEntry {
                    binding: 4,
                    visibility: wgpu::ShaderStages::COMPUTE,
                    ty: wgpu::BindingType::Buffer {
                        ty: wgpu::BufferBindingType::Uniform,
                        has_dynamic_offset: false,
                        min_binding_size: wgpu::BufferSize::new(16),
                    },
                    count: None,
                },
            ],
        });
        let pipeline = |label, layout: &wgpu::BindGroupLayout, entry| {
            let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
                label: Some(label),
                bind_group_layouts: &[Some(layout)],
                immediate_size: 0,
            });
            device.create_compute_pipeline(&wgpu::ComputePipelineDescriptor {
                label: Some(label),
                layout: Some(&pipeline_layout),
                module: &module,
                entry_point: Some(entry),
                compilation_options: Default::default(),
                cache: None,
            })
        };
        let copy_pipeline = pipeline("hzb copy depth", &copy_layout, "copy_depth");
        let eroded_pipeline = pipeline("hzb copy eroded", &copy_layout, "copy_eroded");
        let merge_pipeline = pipeline("hzb merge depths", &copy_layout, "merge_depths");
        let reduce_pipeline = pipeline("hzb reduce", &reduce_layout, "reduce");

        let levels = level_count(width, height);
        // Powers of two, so that mip `l` (floor halving) holds pyramid level `l` (ceil halving),
        // and at least two mips, which the first dispatch writes.
        let (texture_width, texture_height) = (
            width.next_power_of_two().max(2),
            height.next_power_of_two().max(2),
        );
        check_size(gpu, texture_width, texture_height)?;
        let texture = device.create_texture(&wgpu::TextureDescriptor {
            label: Some("hzb pyramid"),
            size: wgpu::Extent3d {
                width: texture_width,
                height: texture_height,
                depth_or_array_layers: 1,
            },
            mip_level_count: levels.max(2),
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: HZB_FORMAT,
            usage: wgpu::TextureUsages::STORAGE_BINDING
                | wgpu::TextureUsages::TEXTURE_BINDING
                | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let level_views: Vec<wgpu::TextureView> = (0..levels)
            .map(|l| {
                texture.create_view(&wgpu::TextureViewDescriptor {
                    label: Some("hzb level"),
                    base_mip_level: l,
                    mip_level_count: Some(1),
                    ..Default::default()
                })
            })
            .collect();
        let level1_view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("hzb level 1"),
            base_mip_level: 1,
            mip_level_count: Some(1),
            ..Default::default()
        });
        let logical = |l: u32| (((width - 1) >> l) + 1, ((height - 1) >> l) + 1);
        // From level 1: the first dispatch writes levels 0 and 1.
        let reduce_groups = level_views
            .windows(2)
            .enumerate()
            .skip(1)
            .map(|(l, pair)| {
                let (src, dst) = (logical(l as u32), logical(l as u32 + 1));
                let sizes = device.create_buffer_init(&wgpu::util::BufferInitDescriptor {
                    label: Some("hzb level sizes"),
                    contents: bytemuck::cast_slice(&[src.0, src.1, dst.0, dst.1]),
                    usage: wgpu::BufferUsages::UNIFORM,
                });
                device.create_bind_group(&wgpu::BindGroupDescriptor {
                    label: Some("hzb reduce"),
                    layout: &reduce_layout,
                    entries: &[
                        wgpu::BindGroupEntry {
                            binding: 2,
                            resource: wgpu::BindingResource::TextureView(&pair[0]),
                        },
                        wgpu::BindGroupEntry {
                            binding: 3,
                            resource: wgpu::BindingResource::TextureView(&pair[1]),
                        },
                        wgpu::BindGroupEntry {
                            binding: 4,
                            resource: sizes.as_entire_binding(),
                        },
                    ],
                })
            })
            .collect();
        let all_levels_view = texture.create_view(&wgpu::TextureViewDescriptor {
            label: Some("hzb all levels"),
            mip_level_count: Some(levels),
            ..Default::default()
        });
        Ok(HzbPyramid {
            device: device.clone(),
            copy_pipeline,
            eroded_pipeline,
            merge_pipeline,
            copy_layout,
            level1_view,
            reduce_pipeline,
            reduce_groups,
            level_views,
            texture,
            all_levels_view,
            width,
            height,
        })
    }

    /// Records the build from `depth_view`, a single-level view of a `Depth32Float` texture of
    /// exactly this pyramid's size with `TEXTURE_BINDING` usage (e.g.
    /// [`crate::render::DepthTarget::view`]), after the pass that wrote it.
    pub fn build(&self, encoder: &mut wgpu::CommandEncoder, depth_view: &wgpu::TextureView) {
        self.build_timed(encoder, depth_view, None);
    }

    /// As [`HzbPyramid::build`], with the compute pass timed by `timestamp_writes`
    /// ([`crate::gpu_timer::GpuTimer::compute_pass_writes`]).
    pub fn build_timed(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        depth_view: &wgpu::TextureView,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        self.encode(encoder, PyramidSource::Depth(depth_view), timestamp_writes);
    }

    /// As [`HzbPyramid::build_timed`], from a depth holding virtual occluders (the occluder
    /// gate's: the ground and the occluders), eroded by one texel first
    /// ([`super::reference::erode`] says why).
    pub fn build_occluders_timed(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        occluder_view: &wgpu::TextureView,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        self.encode(
            encoder,
            PyramidSource::Occluders(occluder_view),
            timestamp_writes,
        );
    }

    /// As [`HzbPyramid::build_timed`], from the nearer (greater, reversed Z) depth of
    /// `depth_view` and `occluder_view`, eroded ([`HzbPyramid::build_occluders_timed`]), at each
    /// texel (both of this pyramid's size): the pyramid of one depth buffer holding both.
    pub fn build_merged_timed(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        depth_view: &wgpu::TextureView,
        occluder_view: &wgpu::TextureView,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        self.encode(
            encoder,
            PyramidSource::Merged(depth_view, occluder_view),
            timestamp_writes,
        );
    }

    fn encode(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        source: PyramidSource<'_>,
        timestamp_writes: Option<wgpu::ComputePassTimestampWrites<'_>>,
    ) {
        let view = |binding, view| wgpu::BindGroupEntry {
            binding,
            resource: wgpu::BindingResource::TextureView(view),
        };
        let (pipeline, depth_view, second_view) = match source {
            PyramidSource::Depth(depth) => (&self.copy_pipeline, depth, depth),
            PyramidSource::Occluders(occluders) => (&self.eroded_pipeline, occluders, occluders),
            PyramidSource::Merged(depth, occluders) => (&self.merge_pipeline, depth, occluders),
        };
        let copy_group = self.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("hzb copy depth"),
            layout: &self.copy_layout,
            entries: &[
                view(0, depth_view),
                view(5, second_view),
                view(1, &self.level_views[0]),
                view(6, &self.level1_view),
            ],
        });
        let mut pass = encoder.begin_compute_pass(&wgpu::ComputePassDescriptor {
            label: Some("hzb build"),
            timestamp_writes,
        });
        pass.set_pipeline(pipeline);
        pass.set_bind_group(0, &copy_group, &[]);
        // One invocation per texel of level 1 (the viewport halved, rounded up).
        let (w1, h1) = (self.width.div_ceil(2), self.height.div_ceil(2));
        pass.dispatch_workgroups(
            w1.div_ceil(HZB_BUILD_WORKGROUP),
            h1.div_ceil(HZB_BUILD_WORKGROUP),
            1,
        );
        pass.set_pipeline(&self.reduce_pipeline);
        for (l, group) in self.reduce_groups.iter().enumerate() {
            let (w, h) = self.level_size(l as u32 + 2);
            pass.set_bind_group(0, group, &[]);
            pass.dispatch_workgroups(
                w.div_ceil(HZB_BUILD_WORKGROUP),
                h.div_ceil(HZB_BUILD_WORKGROUP),
                1,
            );
        }
    }

    /// Width and height of level 0 (the viewport).
    pub fn size(&self) -> (u32, u32) {
        (self.width, self.height)
    }

    /// Number of levels, down to 1×1.
    pub fn level_count(&self) -> u32 {
        self.level_views.len() as u32
    }

    /// Size of pyramid `level`: `ceil` halving of the viewport, `level` times (the top-left
    /// region of the texture's mip `level`).
    pub fn level_size(&self, level: u32) -> (u32, u32) {
        (
            ((self.width - 1) >> level) + 1,
            ((self.height - 1) >> level) + 1,
        )
    }

    /// The pyramid texture (`R32Float`, all levels, padded to powers of two: see the module).
    pub fn texture(&self) -> &wgpu::Texture {
        &self.texture
    }

    /// A view of every level, bound as an unfilterable-float `texture_2d<f32>` by the cull pass.
    pub fn view(&self) -> &wgpu::TextureView {
        &self.all_levels_view
    }

    /// Reads every level back to the CPU (after the build was submitted), in the reference's
    /// layout.
    pub fn read_back(&self, gpu: &GpuContext) -> Result<DepthPyramid, ReadbackError> {
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("hzb readback"),
            });
        // Each level at a 256-byte aligned offset with 256-byte aligned rows.
        let mut layouts = Vec::new();
        let mut offset = 0u64;
        for l in 0..self.level_count() {
            let (w, h) = self.level_size(l);
            let row = (w * 4).div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT)
                * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
            layouts.push((offset, row, w, h));
            offset += u64::from(row) * u64::from(h);
        }
        let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("hzb readback"),
            size: offset,
            usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            mapped_at_creation: false,
        });
        for (l, &(offset, row, w, h)) in layouts.iter().enumerate() {
            encoder.copy_texture_to_buffer(
                wgpu::TexelCopyTextureInfo {
                    texture: &self.texture,
                    mip_level: l as u32,
                    origin: wgpu::Origin3d::ZERO,
                    aspect: wgpu::TextureAspect::All,
                },
                wgpu::TexelCopyBufferInfo {
                    buffer: &buffer,
                    layout: wgpu::TexelCopyBufferLayout {
                        offset,
                        bytes_per_row: Some(row),
                        rows_per_image: Some(h),
                    },
                },
                wgpu::Extent3d {
                    width: w,
                    height: h,
                    depth_or_array_layers: 1,
                },
            );
        }
        gpu.queue.submit([encoder.finish()]);
        let bytes = map_read(gpu, &buffer)?;
        let levels = layouts
            .iter()
            .map(|&(offset, row, w, h)| {
                let mut depth = Vec::with_capacity((w * h) as usize);
                for y in 0..h as usize {
                    let start = offset as usize + y * row as usize;
                    let texels: &[u8] = &bytes[start..start + 4 * w as usize];
                    depth.extend(
                        texels
                            .chunks_exact(4)
                            .map(|b| f32::from_le_bytes([b[0], b[1], b[2], b[3]])),
                    );
                }
                PyramidLevel {
                    width: w,
                    height: h,
                    depth,
                }
            })
            .collect();
        Ok(DepthPyramid { levels })
    }
}
