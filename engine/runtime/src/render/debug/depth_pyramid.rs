//! The depth pyramid the pyramid debug view shows when the frame did not go through the
//! culling renderer (whose own pyramid, [`crate::frame::CullingRenderer::pyramid`], is shown
//! otherwise): a depth-only draw of the frame's drawn geometry (the ground and a draw list of
//! a scene) and an [`HzbPyramid`] built from it with the same GPU build as the culling frame's.

use citywalk_shaders::SCENE_WGSL;

use super::DebugCamera;
use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::hzb::HzbPyramid;
use crate::render::draws::IndirectDraws;
use crate::render::targets::ReadbackError;
use crate::scene_gpu::SceneGpu;

/// Depth-only scene pass, its depth target and the pyramid built from it.
#[derive(Debug)]
pub struct DepthPyramid {
    pipeline: wgpu::RenderPipeline,
    camera: DebugCamera,
    draws: IndirectDraws,
    pyramid: Option<HzbPyramid>,
}

impl DepthPyramid {
    pub fn new(gpu: &GpuContext) -> DepthPyramid {
        let device = &gpu.device;
        let (camera, layout) = DebugCamera::new(device, "debug depth view");
        let pipeline =
            crate::render::scene_pipeline(device, "debug depth", SCENE_WGSL, &layout, None);
        DepthPyramid {
            pipeline,
            camera,
            draws: IndirectDraws::new(device, "debug depth draws"),
            pyramid: None,
        }
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
        let count = self.draws.write(gpu, &super::scene_draws(scene, draw_ids));
        let (depth, view_group) = self.camera.prepare(gpu, camera, (width, height));
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
            pass.set_bind_group(0, view_group, &[]);
            scene.bind(&mut pass);
            pass.multi_draw_indexed_indirect(self.draws.buffer(), 0, count);
        }
        let pyramid = self.pyramid.as_ref().expect("made above");
        pyramid.build(encoder, &depth.view);
        Ok(pyramid)
    }
}
