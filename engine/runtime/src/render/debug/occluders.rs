//! Debug view of the virtual occluders (Germs & Jansen 2001, built by the preprocessor): every
//! occluder mesh blended over the frame in [`DEBUG_OCCLUDER_RGB`], the occluders the frame's
//! pre-pass selected drawn again on top in [`DEBUG_OCCLUDER_SELECTED_RGB`]
//! (`wgsl/debug_occluders.wgsl`). Occluders hide each other (a depth target of their own, filled
//! by a depth-only draw first, so each pixel blends its nearest occluder surface once) but not
//! the scene, which they lie inside.

use citywalk_shaders::DEBUG_OCCLUDERS_WGSL;
#[cfg(doc)]
use citywalk_shaders::constants::{DEBUG_OCCLUDER_RGB, DEBUG_OCCLUDER_SELECTED_RGB};

use super::{DebugCamera, DebugPipelineMode};
use crate::camera::Camera;
use crate::frame::OccluderMeshes;
use crate::gpu::GpuContext;

/// One occluder's triangles in [`OccluderOverlayMeshes`].
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct OccluderRange {
    /// The building the occluder stands for.
    pub building: u32,
    /// Its indices (absolute vertex numbers) in the index buffer.
    pub first_index: u32,
    pub index_count: u32,
}

/// Every occluder mesh of a scene in one vertex and one index buffer with absolute indices
/// (the frame's own, [`OccluderMeshes`]), so the whole set is one draw.
#[derive(Debug)]
pub struct OccluderOverlayMeshes {
    vertex_buffer: wgpu::Buffer,
    index_buffer: wgpu::Buffer,
    /// Every occluder with a non-empty mesh of finite bounds, in the set's order: the same
    /// occluders, in the same order, as [`crate::frame::OccluderMeshes::occluders`], so an
    /// index of the frame's occluder selection is an index here.
    pub ranges: Vec<OccluderRange>,
}

impl OccluderOverlayMeshes {
    /// The overlay of the frame's occluders over their own vertex and index buffers (absolute
    /// indices, [`OccluderMeshes::buffers`]): no second upload of every occluder mesh (at a
    /// million buildings, hundreds of megabytes that a software adapter holds in process memory).
    pub fn of(meshes: &OccluderMeshes) -> OccluderOverlayMeshes {
        let (vertex_buffer, index_buffer) = meshes.buffers();
        OccluderOverlayMeshes {
            vertex_buffer: vertex_buffer.clone(),
            index_buffer: index_buffer.clone(),
            ranges: meshes
                .occluders
                .iter()
                .map(|o| OccluderRange {
                    building: o.building,
                    first_index: o.draw.first_index,
                    index_count: o.draw.index_count,
                })
                .collect(),
        }
    }

    /// Indices from the first up to the end of the last occluder: all of them in one draw
    /// (indices between ranges, if any, are zero: degenerate triangles).
    fn index_count(&self) -> u32 {
        self.ranges
            .iter()
            .map(|r| r.first_index.saturating_add(r.index_count))
            .max()
            .unwrap_or(0)
    }
}

/// The occluder view's pipeline, uniforms and depth.
#[derive(Debug)]
pub struct OccluderOverlay {
    /// Nearest occluder surfaces into the overlay's depth.
    depth_pipeline: wgpu::RenderPipeline,
    /// Blends the colour on those surfaces only.
    pipeline: wgpu::RenderPipeline,
    camera: DebugCamera,
}

impl OccluderOverlay {
    /// An overlay drawing into colour targets of `colour_format`.
    pub fn new(gpu: &GpuContext, colour_format: wgpu::TextureFormat) -> OccluderOverlay {
        let device = &gpu.device;
        let (camera, layout) = DebugCamera::new(device, "debug occluders view");
        let pipeline = |label, mode| {
            super::debug_scene_pipeline(
                device,
                label,
                DEBUG_OCCLUDERS_WGSL,
                &layout,
                colour_format,
                mode,
            )
        };
        OccluderOverlay {
            depth_pipeline: pipeline("debug occluders depth", DebugPipelineMode::DepthOnly),
            pipeline: pipeline("debug occluders", DebugPipelineMode::BlendOnNearest),
            camera,
        }
    }

    /// Records a pass blending every occluder of `meshes` over `target` (`width × height`,
    /// loaded, not cleared) from `camera`, and the occluders `selected` (indices into
    /// [`OccluderOverlayMeshes::ranges`]; others are ignored) again in the highlight colour.
    /// Returns the number of occluders highlighted. The uniforms are written through the queue:
    /// submit before recording another view.
    #[expect(clippy::too_many_arguments, reason = "one pass, all inputs explicit")]
    pub fn encode(
        &mut self,
        gpu: &GpuContext,
        encoder: &mut wgpu::CommandEncoder,
        meshes: &OccluderOverlayMeshes,
        camera: &Camera,
        selected: &[usize],
        target: &wgpu::TextureView,
        (width, height): (u32, u32),
    ) -> u32 {
        let (depth, view_group) = self.camera.prepare(gpu, camera, (width, height));
        let mut pass = crate::render::begin_colour_pass(
            encoder,
            "debug occluders",
            target,
            wgpu::LoadOp::Load,
            Some(depth),
        );
        let total = meshes.index_count();
        if total == 0 {
            return 0;
        }
        pass.set_bind_group(0, view_group, &[]);
        pass.set_vertex_buffer(0, meshes.vertex_buffer.slice(..));
        pass.set_index_buffer(meshes.index_buffer.slice(..), wgpu::IndexFormat::Uint32);
        // Depth first, so each pixel blends its nearest occluder surface only.
        pass.set_pipeline(&self.depth_pipeline);
        pass.draw_indexed(0..total, 0, 0..1);
        pass.set_pipeline(&self.pipeline);
        // Instance 0: every occluder in the plain colour.
        pass.draw_indexed(0..total, 0, 0..1);
        // Instance 1: the selected ones again, highlighted.
        let mut highlighted = 0;
        for r in selected.iter().filter_map(|&i| meshes.ranges.get(i)) {
            pass.draw_indexed(r.first_index..r.first_index + r.index_count, 0, 1..2);
            highlighted += 1;
        }
        highlighted
    }
}
