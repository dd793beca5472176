//! Rendering passes. Each pass is a module that owns its pipeline, bind-group layout and
//! resources; [`targets`] holds the render targets and GPU-to-CPU readback they share.

pub mod brute;
pub mod debug;
pub mod selected;
pub mod targets;
pub mod view;

pub use brute::BruteRenderer;
pub use targets::{DepthTarget, OffscreenTarget, ReadbackError};
pub use view::{SceneStyle, view_uniforms};

use crate::camera::Camera;
use crate::scene_gpu::SCENE_VERTEX_LAYOUT;
use citywalk_shaders::ViewUniforms;

/// Bind-group layout of group 0 in the scene-drawing shaders: the [`ViewUniforms`] uniform.
pub(crate) fn view_bind_group_layout(device: &wgpu::Device, label: &str) -> wgpu::BindGroupLayout {
    device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some(label),
        entries: &[wgpu::BindGroupLayoutEntry {
            binding: 0,
            visibility: wgpu::ShaderStages::VERTEX_FRAGMENT,
            ty: wgpu::BindingType::Buffer {
                ty: wgpu::BufferBindingType::Uniform,
                has_dynamic_offset: false,
                min_binding_size: wgpu::BufferSize::new(size_of::<ViewUniforms>() as u64),
            },
            count: None,
        }],
    })
}

/// A uniform buffer for [`ViewUniforms`] and its bind group.
pub(crate) fn view_buffer_and_group(
    device: &wgpu::Device,
    layout: &wgpu::BindGroupLayout,
    label: &str,
) -> (wgpu::Buffer, wgpu::BindGroup) {
    let buffer = device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size_of::<ViewUniforms>() as u64,
        usage: wgpu::BufferUsages::UNIFORM | wgpu::BufferUsages::COPY_DST,
        mapped_at_creation: false,
    });
    let group = device.create_bind_group(&wgpu::BindGroupDescriptor {
        label: Some(label),
        layout,
        entries: &[wgpu::BindGroupEntry {
            binding: 0,
            resource: buffer.as_entire_binding(),
        }],
    });
    (buffer, group)
}

/// A pipeline drawing [`crate::scene_gpu::SceneVertex`] triangles with no face culling into one
/// colour target, reversed-Z depth test and write. Without a colour format the pipeline writes
/// depth only (no fragment stage), as the occluder pre-pass does.
pub(crate) fn scene_pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layout: &wgpu::BindGroupLayout,
    colour_format: Option<wgpu::TextureFormat>,
) -> wgpu::RenderPipeline {
    let colour_targets = colour_format.map(|format| {
        [Some(wgpu::ColorTargetState {
            format,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        })]
    });
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
            buffers: &[Some(SCENE_VERTEX_LAYOUT)],
        },
        primitive: wgpu::PrimitiveState {
            topology: wgpu::PrimitiveTopology::TriangleList,
            cull_mode: None,
            ..Default::default()
        },
        depth_stencil: Some(wgpu::DepthStencilState {
            format: DepthTarget::FORMAT,
            depth_write_enabled: Some(true),
            depth_compare: Some(Camera::DEPTH_COMPARE),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: colour_targets.as_ref().map(|targets| wgpu::FragmentState {
            module: &module,
            entry_point: Some("fs_main"),
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// Begins a render pass into `colour` and `depth` that clears colour to `clear` and depth to
/// reversed-Z infinity, storing both: the start of every scene-drawing pass. `timestamp_writes`
/// times the pass ([`crate::gpu_timer::GpuTimer::render_pass_writes`]).
pub(crate) fn begin_scene_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colour: &wgpu::TextureView,
    depth: &DepthTarget,
    clear: wgpu::Color,
    timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: colour,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load: wgpu::LoadOp::Clear(clear),
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: Some(depth.attachment()),
        timestamp_writes,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
