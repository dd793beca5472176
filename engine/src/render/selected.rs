//! Draws the ground and a chosen set of buildings — the output of a CPU culling stage — with the
//! same flat-shaded pipeline as the brute-force renderer, one indirect draw per building.

use citywalk_shaders::{DrawIndexedIndirectArgs, SCENE_WGSL};

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::render::targets::DepthTarget;
use crate::render::view::{SceneStyle, view_uniforms};
use crate::scene_gpu::SceneGpu;

/// The scene pass restricted to a list of buildings.
#[derive(Debug)]
pub struct SelectedRenderer {
    pipeline: wgpu::RenderPipeline,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    draws: wgpu::Buffer,
    draws_capacity: usize,
    pub style: SceneStyle,
}

impl SelectedRenderer {
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> SelectedRenderer {
        let device = &gpu.device;
        let layout = super::view_bind_group_layout(device, "selected view");
        let (view_buffer, view_group) =
            super::view_buffer_and_group(device, &layout, "selected view");
        let pipeline = super::scene_pipeline(
            device,
            "selected scene",
            SCENE_WGSL,
            &layout,
            Some(colour_format),
        );
        let draws_capacity = 1024;
        SelectedRenderer {
            pipeline,
            view_buffer,
            view_group,
            draws: Self::draw_buffer(device, draws_capacity),
            draws_capacity,
            style: SceneStyle::default(),
        }
    }

    fn draw_buffer(device: &wgpu::Device, capacity: usize) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("selected draws"),
            size: (capacity * size_of::<DrawIndexedIndirectArgs>()) as u64,
            usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Records the pass drawing the ground and `buildings` (ids into `scene`; ids out of range
    /// are ignored). Returns the number of draw calls recorded.
    ///
    /// The view uniforms and draw list are written through the queue: submit this encoder
    /// before recording another frame with this renderer.
    #[expect(clippy::too_many_arguments, reason = "one pass, all inputs explicit")]
    pub fn encode(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        camera: &Camera,
        buildings: &[u32],
        colour: &wgpu::TextureView,
        depth: &DepthTarget,
    ) -> u32 {
        let mut draws: Vec<DrawIndexedIndirectArgs> = buildings
            .iter()
            .filter_map(|&b| scene.records.get(b as usize))
            .map(|r| r.draw_args())
            .collect();
        draws.push(scene.ground);
        if draws.len() > self.draws_capacity {
            self.draws_capacity = draws.len().next_power_of_two();
            self.draws = Self::draw_buffer(&gpu.device, self.draws_capacity);
        }
        gpu.queue
            .write_buffer(&self.draws, 0, bytemuck::cast_slice(&draws));
        let uniforms = view_uniforms(camera, depth.width, depth.height, &self.style);
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let mut pass = super::begin_scene_pass(
            encoder,
            "selected scene",
            colour,
            depth,
            self.style.clear_colour(),
        );
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        pass.multi_draw_indexed_indirect(&self.draws, 0, draws.len() as u32);
        draws.len() as u32
    }
}
