//! Debug view of the level-of-detail cut: every drawn building or cluster mesh in its own
//! colour, a hash of its draw id, as in Chang et al. 2008 Fig. 1(c) (`wgsl/debug_clusters.wgsl`).
//! Roofs are drawn at full brightness, walls at [`DEBUG_WALL_SHADE`], the ground dark grey.
//!
//! In a [`crate::lod::scene::LodScene`] the draw ids are the buildings, then cluster node `n` at
//! `building_count + n`, so each entry of the cut gets its own colour; in a plain
//! [`SceneGpu`] each building does.

use citywalk_shaders::DEBUG_CLUSTERS_WGSL;
use citywalk_shaders::constants::DEBUG_WALL_SHADE;

use super::DebugCamera;
use crate::camera::Camera;
use crate::gpu::GpuContext;
use crate::render::draws::IndirectDraws;
use crate::scene_gpu::SceneGpu;

/// Background of the cluster view (linear RGB).
const BACKGROUND: wgpu::Color = wgpu::Color {
    r: 0.02,
    g: 0.02,
    b: 0.03,
    a: 1.0,
};

/// lowbias32 by Chris Wellons. CPU twin of `hash_u32` in `wgsl/shared/materials.wgsl`.
pub fn hash_u32(x: u32) -> u32 {
    let mut x = x;
    x ^= x >> 16;
    x = x.wrapping_mul(0x7feb_352d);
    x ^= x >> 15;
    x = x.wrapping_mul(0x846c_a68b);
    x ^= x >> 16;
    x
}

/// HSV (all in `[0, 1]`) to RGB. CPU twin of `hsv_to_rgb` in the shader.
pub fn hsv_to_rgb(h: f32, s: f32, v: f32) -> [f32; 3] {
    [5.0f32, 3.0, 1.0].map(|n| {
        let k = (n + h * 6.0) % 6.0;
        v - v * s * k.min(4.0 - k).clamp(0.0, 1.0)
    })
}

/// The colour of draw id `id` (linear RGB, roof brightness). CPU twin of `cluster_colour` in
/// the shader.
pub fn cluster_colour(id: u32) -> [f32; 3] {
    let h = hash_u32(id);
    let hue = (h & 0xffff) as f32 / 65536.0;
    let saturation = 0.55 + 0.45 * ((h >> 16) & 0xff) as f32 / 255.0;
    let value = 0.65 + 0.35 * (h >> 24) as f32 / 255.0;
    hsv_to_rgb(hue, saturation, value)
}

/// The wall colour of draw id `id`: [`cluster_colour`] times [`DEBUG_WALL_SHADE`].
pub fn cluster_wall_colour(id: u32) -> [f32; 3] {
    cluster_colour(id).map(|c| c * DEBUG_WALL_SHADE)
}

/// The cluster view's pipeline, uniforms, draw list and depth.
#[derive(Debug)]
pub struct ClusterView {
    pipeline: wgpu::RenderPipeline,
    camera: DebugCamera,
    draws: IndirectDraws,
}

impl ClusterView {
    /// A view drawing into colour targets of `colour_format`.
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> ClusterView {
        let device = &gpu.device;
        let (camera, layout) = DebugCamera::new(device, "debug clusters view");
        let pipeline = super::debug_scene_pipeline(
            device,
            "debug clusters",
            DEBUG_CLUSTERS_WGSL,
            &layout,
            colour_format,
            super::DebugPipelineMode::Opaque,
        );
        ClusterView {
            pipeline,
            camera,
            draws: IndirectDraws::new(device, "debug clusters draws"),
        }
    }

    /// Records a pass that clears `target` (`width × height`) and draws the ground and the
    /// entries `draw_ids` of `scene` (ids out of range are ignored) in their colours, from
    /// `camera`. Returns the number of draws. The uniforms and draw list are written through
    /// the queue: submit before recording another view.
    #[expect(clippy::too_many_arguments, reason = "one pass, all inputs explicit")]
    pub fn encode(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        scene: &SceneGpu,
        camera: &Camera,
        draw_ids: &[u32],
        target: &wgpu::TextureView,
        (width, height): (u32, u32),
    ) -> u32 {
        let count = self.draws.write(gpu, &super::scene_draws(scene, draw_ids));
        let (depth, view_group) = self.camera.prepare(gpu, camera, (width, height));
        let mut pass = crate::render::begin_scene_pass(
            encoder,
            "debug clusters",
            target,
            depth,
            BACKGROUND,
            None,
        );
        pass.set_pipeline(&self.pipeline);
        pass.set_bind_group(0, view_group, &[]);
        scene.bind(&mut pass);
        pass.multi_draw_indexed_indirect(self.draws.buffer(), 0, count);
        count
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn hsv_primaries_and_greys() {
        let close = |a: [f32; 3], b: [f32; 3]| a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5);
        assert!(close(hsv_to_rgb(0.0, 1.0, 1.0), [1.0, 0.0, 0.0]));
        assert!(close(hsv_to_rgb(1.0 / 3.0, 1.0, 1.0), [0.0, 1.0, 0.0]));
        assert!(close(hsv_to_rgb(2.0 / 3.0, 1.0, 1.0), [0.0, 0.0, 1.0]));
        assert!(close(hsv_to_rgb(0.4, 0.0, 0.5), [0.5, 0.5, 0.5]));
    }

    #[test]
    fn neighbouring_ids_get_clearly_different_colours() {
        // The shader hash: the values of the published lowbias32 constants.
        assert_eq!(hash_u32(0), 0);
        assert_ne!(hash_u32(1), hash_u32(2));
        for id in 0..2000u32 {
            let (a, b) = (cluster_colour(id), cluster_colour(id + 1));
            let d: f32 = a.iter().zip(b).map(|(x, y)| (x - y).abs()).sum();
            assert!(a.iter().all(|c| (0.0..=1.0).contains(c)), "{id}: {a:?}");
            assert!(d > 1.0 / 255.0, "ids {id} and {} share a colour", id + 1);
        }
    }
}
