//! The brute-force renderer: draws every building and the ground, flat-shaded, with no culling.
//! The reference image for every culling scheme, and the viewer's renderer until culling lands.

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::render::targets::{DepthTarget, OffscreenTarget, ReadbackError};
use crate::render::view::{SceneStyle, view_uniforms};
use crate::scene_gpu::SceneGpu;

/// Flat-shaded scene pass into a colour target of one format, with a reversed-Z
/// `Depth32Float` depth target.
#[derive(Debug)]
pub struct BruteRenderer {
    pipelines: super::ScenePipelines,
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    /// The colour format the pipeline was built for.
    pub colour_format: wgpu::TextureFormat,
    /// Sky, sun and fog.
    pub style: SceneStyle,
}

impl BruteRenderer {
    /// The colour format of offscreen frames written as PNG.
    pub const PNG_FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Rgba8UnormSrgb;

    /// A renderer for colour targets of `colour_format` (`Rgba8UnormSrgb` for PNG frames, the
    /// surface's format in the viewer; use an sRGB format so the shader's linear colours are
    /// encoded).
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> BruteRenderer {
        let device = &gpu.device;
        let layout = super::view_bind_group_layout(device, "brute view");
        let (view_buffer, view_group) = super::view_buffer_and_group(device, &layout, "brute view");
        let pipelines = super::ScenePipelines::new(device, "brute scene", &layout, colour_format);
        BruteRenderer {
            pipelines,
            view_buffer,
            view_group,
            colour_format,
            style: SceneStyle::default(),
        }
    }

    /// Records the pass: clears colour to the sky and depth to reversed-Z infinity, then draws
    /// the ground and every building. `colour` and `depth` must be `width × height`.
    ///
    /// The view uniforms are written through the queue, so submit this encoder before
    /// recording another frame with this renderer.
    pub fn encode(
        &self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        camera: &Camera,
        colour: &wgpu::TextureView,
        depth: &DepthTarget,
    ) {
        self.encode_timed(gpu, encoder, scene, camera, colour, depth, None);
    }

    /// As [`BruteRenderer::encode`], with the pass timed by `timestamp_writes`
    /// ([`crate::gpu_timer::GpuTimer::render_pass_writes`]).
    #[expect(clippy::too_many_arguments, reason = "one pass, all inputs explicit")]
    pub fn encode_timed(
        &self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        camera: &Camera,
        colour: &wgpu::TextureView,
        depth: &DepthTarget,
        timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) {
        self.encode_with(
            gpu,
            encoder,
            scene,
            camera,
            (colour, depth),
            "brute scene",
            timestamp_writes,
            |pass| scene.draw_all(pass),
        );
    }

    /// Records the scene pass — view uniforms, clears, pipeline, scene buffers bound — and lets
    /// `draw` issue the draws: every building here, a culled list in
    /// [`crate::render::selected::SelectedRenderer`]. The pass is timed by `timestamp_writes`.
    #[expect(clippy::too_many_arguments, reason = "one pass, all inputs explicit")]
    pub(crate) fn encode_with(
        &self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        camera: &Camera,
        (colour, depth): (&wgpu::TextureView, &DepthTarget),
        label: &str,
        timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
        draw: impl FnOnce(&mut wgpu::RenderPass<'_>),
    ) {
        let uniforms = view_uniforms(camera, depth.width, depth.height, &self.style);
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        let mut pass = super::begin_scene_pass(
            encoder,
            label,
            colour,
            depth,
            self.style.clear_colour(),
            timestamp_writes,
        );
        self.pipelines.set(&mut pass, scene);
        pass.set_bind_group(0, &self.view_group, &[]);
        scene.bind(&mut pass);
        draw(&mut pass);
    }

    /// Renders one frame offscreen and reads it back as tightly packed RGBA8 (sRGB) rows.
    /// The renderer must have been made for `Rgba8UnormSrgb`.
    pub fn render_rgba(
        &self,
        gpu: &GpuContext,
        scene: &SceneGpu,
        camera: &Camera,
        width: u32,
        height: u32,
    ) -> Result<Vec<u8>, ReadbackError> {
        let target = OffscreenTarget::new(gpu, width, height, self.colour_format)?;
        let mut encoder = gpu
            .device
            .create_command_encoder(&wgpu::CommandEncoderDescriptor {
                label: Some("brute frame"),
            });
        self.encode(
            gpu,
            &mut encoder,
            scene,
            camera,
            &target.colour_view,
            &target.depth,
        );
        gpu.queue.submit([encoder.finish()]);
        target.read_colour(gpu)
    }
}
