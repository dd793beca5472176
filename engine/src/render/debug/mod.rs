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
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &[Some(layout)],
        immediate_size: 0,
    });
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[Some(crate::scene_gpu::SCENE_VERTEX_LAYOUT)],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: crate::render::DepthTarget::FORMAT,
            depth_write_enabled: Some(depth_write),
            depth_compare: Some(depth_compare),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets: &[Some(wgpu::ColorTargetState {
                format: colour_format,
                blend,
                write_mask,
            })],
        }),
        multiview_mask: None,
        cache: None,
    })
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
