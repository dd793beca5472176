//! The depth pyramid the pyramid debug view shows when the frame did not go through the
//! culling renderer (whose own pyramid, [`crate::frame::CullingRenderer::pyramid`], is shown
//! otherwise): a depth-only draw of the frame's drawn geometry (the ground and a draw list of
//! a scene) and an [`HzbPyramid`] built from it with the same GPU build as the culling frame's.

use citywalk_shaders::{DrawIndexedIndirectArgs, SCENE_WGSL};

use super::DebugDepth;
use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::hzb::HzbPyramid;
use crate::render::targets::ReadbackError;
use crate::render::view::{SceneStyle, view_uniforms};
use crate::scene_gpu::SceneGpu;

/// Depth-only scene pass, its depth target and the pyramid built from it.
#[derive(Debug)]
pub struct DepthPyramid {
    pipeline: wgpu::RenderPipeline,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    draws: wgpu::Buffer,
    draws_capacity: usize,
    depth: DebugDepth,
    pyramid: Option<HzbPyramid>,
}

impl DepthPyramid {
    pub fn new(gpu: &GpuContext) -> DepthPyramid {
        let device = &gpu.device;
        let layout = crate::render::view_bind_group_layout(device, "debug depth view");
        let (view_buffer, view_group) =
            crate::render::view_buffer_and_group(device, &layout, "debug depth view");
        let pipeline =
            crate::render::scene_pipeline(device, "debug depth", SCENE_WGSL, &layout, None);
        let draws_capacity = 1024;
        DepthPyramid {
            pipeline,
            view_buffer,
            view_group,
            draws: Self::draw_buffer(device, draws_capacity),
            draws_capacity,
            depth: DebugDepth::default(),
            pyramid: None,
        }
    }

    fn draw_buffer(device: &wgpu::Device, capacity: usize) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("debug depth draws"),
            size: (capacity * size_of::<DrawIndexedIndirectArgs>()) as u64,
            usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Records the depth of the ground and `draw_ids` of `scene` seen from `camera` on a
    /// `width × height` viewport, and the pyramid build from it; returns the pyramid (valid
    /// once the encoder is submitted).
    pub fn encode(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        camera: &Camera,
        draw_ids: &[u32],
        (width, height): (u32, u32),
    ) -> Result<&HzbPyramid, ReadbackError> {
        if self
            .pyramid
            .as_ref()
            .is_none_or(|p| p.size() != (width, height))
        {
            self.pyramid = Some(HzbPyramid::new(gpu, width, height)?);
        }
        let mut draws: Vec<DrawIndexedIndirectArgs> = draw_ids
            .iter()
            .filter_map(|&i| scene.records.get(i as usize))
            .filter(|r| r.index_count > 0)
            .map(|r| r.draw_args())
            .collect();
        draws.push(scene.ground);
        if draws.len() > self.draws_capacity {
            self.draws_capacity = draws.len().next_power_of_two();
            self.draws = Self::draw_buffer(&gpu.device, self.draws_capacity);
        }
        gpu.queue
            .write_buffer(&self.draws, 0, bytemuck::cast_slice(&draws));
        let uniforms = view_uniforms(camera, width, height, &SceneStyle::default());
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let depth = self.depth.fit(gpu, width, height);
        {
            let mut pass = encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
                label: Some("debug depth"),
                color_attachments: &[],
                depth_stencil_attachment: Some(depth.attachment()),
                timestamp_writes: None,
                occlusion_query_set: None,
                multiview_mask: None,
            });
            pass.set_pipeline(&self.pipeline);
            pass.set_bind_group(0, &self.view_group, &[]);
            scene.bind(&mut pass);
            pass.multi_draw_indexed_indirect(&self.draws, 0, draws.len() as u32);
        }
        let pyramid = self.pyramid.as_ref().expect("made above");
        pyramid.build(encoder, &depth.view);
        Ok(pyramid)
    }
}
