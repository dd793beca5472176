//! Debug views of the frame, each a pass that owns its pipeline and resources:
//!
//! - [`pyramid`]: one level of the hierarchical-Z pyramid as a greyscale full-screen image
//!   (of the pyramid [`depth_pyramid`] builds from the frame's drawn geometry);
//! - [`clusters`]: every drawn building or cluster mesh in its own colour (Chang et al. 2008,
//!   Fig. 1(c));
//! - [`occluders`]: the virtual occluder meshes blended over the frame, the ones the frame's
//!   pre-pass selected highlighted.
//!
//! Each module has the CPU twin of its shader's colour function, which the GPU tests
//! (`tests/tests/debug_views.rs`) compare the rendered pixels with.

pub mod clusters;
pub mod depth_pyramid;
pub mod occluders;
pub mod pyramid;

pub use clusters::ClusterView;
pub use depth_pyramid::DepthPyramid;
pub use occluders::{OccluderOverlay, OccluderOverlayMeshes};
pub use pyramid::PyramidView;

/// How a debug pipeline treats depth and colour.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum DebugPipelineMode {
    /// Reversed-Z depth test and write, colour written.
    Opaque,
    /// Reversed-Z depth test and write, no colour: the first pass of a translucent overlay.
    DepthOnly,
    /// Depth equal to what the depth-only pass left, no depth write, alpha-blended: only the
    /// nearest surface of a translucent overlay is blended, once per draw.
    BlendOnNearest,
}

/// A render pipeline drawing [`crate::scene_gpu::SceneVertex`] triangles (no face culling)
/// into one colour target, with depth and colour as `mode` says: the scene pipeline of
/// [`crate::render`] for a debug shader.
pub(crate) fn debug_scene_pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layout: &wgpu::BindGroupLayout,
    colour_format: wgpu::TextureFormat,
    mode: DebugPipelineMode,
) -> wgpu::RenderPipeline {
    let (depth_compare, depth_write, blend, write_mask) = match mode {
        DebugPipelineMode::Opaque => (
            crate::camera::Camera::DEPTH_COMPARE,
            true,
            None,
            wgpu::ColorWrites::ALL,
        ),
        DebugPipelineMode::DepthOnly => (
            crate::camera::Camera::DEPTH_COMPARE,
            true,
            None,
            wgpu::ColorWrites::empty(),
        ),
        DebugPipelineMode::BlendOnNearest => (
            wgpu::CompareFunction::Equal,
            false,
            Some(wgpu::BlendState::ALPHA_BLENDING),
            wgpu::ColorWrites::ALL,
        ),
    };
    crate::render::scene_pipeline_with(
        device,
        label,
        source,
        layout,
        (depth_compare, depth_write),
        Some(wgpu::ColorTargetState {
            format: colour_format,
            blend,
            write_mask,
        }),
    )
}

/// The indirect draws of the entries `draw_ids` of `scene` that have triangles (ids out of
/// range are ignored), then the ground.
pub(crate) fn scene_draws(
    scene: &crate::scene_gpu::SceneGpu,
    draw_ids: &[u32],
) -> Vec<citywalk_shaders::DrawIndexedIndirectArgs> {
    let mut draws: Vec<_> = draw_ids
        .iter()
        .filter_map(|&i| scene.records.get(i as usize))
        .filter(|r| r.index_count > 0)
        .map(|r| r.draw_args())
        .collect();
    draws.push(scene.ground);
    draws
}

/// What every scene-drawing debug pass has of the camera: the view uniforms (group 0), their
/// bind group and the pass's depth target.
#[derive(Debug)]
pub(crate) struct DebugCamera {
    view_buffer: wgpu::Buffer,
    view_group: wgpu::BindGroup,
    depth: DebugDepth,
}

impl DebugCamera {
    /// The camera side of a pass, with the group-0 layout its pipelines are built with.
    pub(crate) fn new(device: &wgpu::Device, label: &str) -> (DebugCamera, wgpu::BindGroupLayout) {
        let layout = crate::render::view_bind_group_layout(device, label);
        let (view_buffer, view_group) =
            crate::render::view_buffer_and_group(device, &layout, label);
        let camera = DebugCamera {
            view_buffer,
            view_group,
            depth: DebugDepth::default(),
        };
        (camera, layout)
    }

    /// Writes the view uniforms of `camera` on a `width × height` viewport through the queue;
    /// returns the depth target of that size and the bind group to set at group 0.
    pub(crate) fn prepare(
        &mut self,
        gpu: &crate::gpu::GpuContext,
        camera: &crate::camera::Camera,
        (width, height): (u32, u32),
    ) -> (&crate::render::DepthTarget, &wgpu::BindGroup) {
        let uniforms = crate::render::view_uniforms(
            camera,
            width,
            height,
            &crate::render::SceneStyle::default(),
        );
        gpu.queue
            .write_buffer(&self.view_buffer, 0, bytemuck::bytes_of(&uniforms));
        (self.depth.fit(gpu, width, height), &self.view_group)
    }
}

/// The depth target a debug pass draws with, remade when the viewport size changes.
#[derive(Debug, Default)]
pub(crate) struct DebugDepth {
    target: Option<crate::render::DepthTarget>,
}

impl DebugDepth {
    /// The depth target of `width × height`.
    pub(crate) fn fit(
        &mut self,
        gpu: &crate::gpu::GpuContext,
        width: u32,
        height: u32,
    ) -> &crate::render::DepthTarget {
        let fits = self
            .target
            .as_ref()
            .is_some_and(|t| (t.width, t.height) == (width, height));
        if !fits {
            self.target = None;
        }
        self.target
            .get_or_insert_with(|| crate::render::DepthTarget::new(gpu, width, height))
    }
}
