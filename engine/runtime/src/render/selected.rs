//! Draws the ground and a chosen set of buildings — the output of a CPU culling stage — with the
//! brute-force renderer's pipeline and pass, one indirect draw per building.

use citywalk_shaders::DrawIndexedIndirectArgs;

use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::render::brute::BruteRenderer;
use crate::render::draws::IndirectDraws;
use crate::render::targets::DepthTarget;
use crate::scene_gpu::SceneGpu;

/// The scene pass restricted to a list of buildings.
#[derive(Debug)]
pub struct SelectedRenderer {
    /// Pipeline, view uniforms and style, shared with the brute-force pass.
    pub scene_pass: BruteRenderer,
    draws: IndirectDraws,
}

impl SelectedRenderer {
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> SelectedRenderer {
        SelectedRenderer {
            scene_pass: BruteRenderer::new(gpu, colour_format),
            draws: IndirectDraws::new(&gpu.device, "selected draws"),
        }
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
        self.encode_timed(
            gpu,
            encoder,
            scene,
            camera,
            buildings,
            (colour, depth),
            None,
        )
    }

    /// As [`SelectedRenderer::encode`], with the pass timed by `timestamp_writes`
    /// ([`crate::gpu_timer::GpuTimer::render_pass_writes`]).
    #[expect(clippy::too_many_arguments, reason = "one pass, all inputs explicit")]
    pub fn encode_timed(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        camera: &Camera,
        buildings: &[u32],
        (colour, depth): (&wgpu::TextureView, &DepthTarget),
        timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
    ) -> u32 {
        let mut draws: Vec<DrawIndexedIndirectArgs> = buildings
            .iter()
            .filter_map(|&b| scene.records.get(b as usize))
            .map(|r| r.draw_args())
            .collect();
        draws.push(scene.ground);
        let count = self.draws.write(gpu, &draws);
        let buffer = self.draws.buffer();
        self.scene_pass.encode_with(
            gpu,
            encoder,
            scene,
            camera,
            (colour, depth),
            "selected scene",
            timestamp_writes,
            |pass| pass.multi_draw_indexed_indirect(buffer, 0, count),
        );
        count
    }
}
