//! Rendering passes. Each pass is a module that owns its pipeline, bind-group layout and
//! resources; [`targets`] holds the render targets and GPU-to-CPU readback they share.

pub mod brute;
pub mod debug;
pub(crate) mod draws;
pub mod ground_surfaces;
pub mod outline;
pub mod selected;
pub mod targets;
pub mod view;

pub use brute::BruteRenderer;
pub use ground_surfaces::{GroundSurfacePass, SurfaceMeshes, SurfaceStats};
pub use outline::OutlineRenderer;
pub use targets::{DepthTarget, OffscreenTarget, ReadbackError};
pub use view::{SceneStyle, view_uniforms};

use crate::camera::Camera;
use crate::scene_gpu::{SCENE_VERTEX_LAYOUT, SceneGpu};
use citywalk_shaders::{SCENE_WGSL, ViewUniforms};

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

/// A pipeline drawing [`citywalk_shaders::SceneVertex`] triangles with no face culling into one
/// colour target, reversed-Z depth test and write. Without a colour format the pipeline writes
/// depth only (no fragment stage), as the occluder pre-pass does.
pub(crate) fn scene_pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layout: &wgpu::BindGroupLayout,
    colour_format: Option<wgpu::TextureFormat>,
) -> wgpu::RenderPipeline {
    let colour = colour_format.map(|format| wgpu::ColorTargetState {
        format,
        blend: None,
        write_mask: wgpu::ColorWrites::ALL,
    });
    scene_pipeline_with(
        device,
        label,
        source,
        layout,
        (Camera::DEPTH_COMPARE, true),
        colour,
    )
}

/// The scene pass's two pipelines over one view layout: flat-shaded (`fs_main`), and with the
/// cluster meshes' baked textures (`fs_textured`, group 1 of
/// [`crate::cluster_textures::bind_group_layout`]), for a scene that carries them.
#[derive(Debug)]
pub(crate) struct ScenePipelines {
    flat: wgpu::RenderPipeline,
    textured: wgpu::RenderPipeline,
}

impl ScenePipelines {
    pub(crate) fn new(
        device: &wgpu::Device,
        label: &str,
        view_layout: &wgpu::BindGroupLayout,
        colour_format: wgpu::TextureFormat,
    ) -> ScenePipelines {
        let colour = Some(wgpu::ColorTargetState {
            format: colour_format,
            blend: None,
            write_mask: wgpu::ColorWrites::ALL,
        });
        let depth = (Camera::DEPTH_COMPARE, true);
        let textures = crate::cluster_textures::bind_group_layout(device);
        ScenePipelines {
            flat: scene_pipeline_with(
                device,
                label,
                SCENE_WGSL,
                view_layout,
                depth,
                colour.clone(),
            ),
            textured: scene_pipeline_entry(
                device,
                &format!("{label} (textured clusters)"),
                SCENE_WGSL,
                &[view_layout, &textures],
                depth,
                colour.map(|c| ("fs_textured", c)),
            ),
        }
    }

    /// Sets the pipeline `scene` is drawn with, and its cluster textures as group 1 where it
    /// has them (group 0, the view, is the caller's).
    pub(crate) fn set(&self, pass: &mut wgpu::RenderPass<'_>, scene: &SceneGpu) {
        match &scene.texturing {
            Some(texturing) => {
                pass.set_pipeline(&self.textured);
                pass.set_bind_group(1, texturing.bind_group(), &[]);
            }
            None => pass.set_pipeline(&self.flat),
        }
    }
}

/// [`scene_pipeline`] with the depth test `depth_compare`, depth writes when `depth_write`, and
/// the colour target `colour` (`None`: depth only, no fragment stage).
pub(crate) fn scene_pipeline_with(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layout: &wgpu::BindGroupLayout,
    depth: (wgpu::CompareFunction, bool),
    colour: Option<wgpu::ColorTargetState>,
) -> wgpu::RenderPipeline {
    let colour = colour.map(|c| ("fs_main", c));
    scene_pipeline_entry(device, label, source, &[layout], depth, colour)
}

/// [`scene_pipeline_with`] over the bind groups `layouts`, its colour target drawn by the
/// fragment entry point named with it.
fn scene_pipeline_entry(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layouts: &[&wgpu::BindGroupLayout],
    (depth_compare, depth_write): (wgpu::CompareFunction, bool),
    colour: Option<(&str, wgpu::ColorTargetState)>,
) -> wgpu::RenderPipeline {
    let entry_point = colour.as_ref().map(|(entry, _)| *entry);
    let colour_targets = colour.map(|(_, target)| [Some(target)]);
    let (module, pipeline_layout) = module_and_layouts(device, label, source, layouts);
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
            depth_write_enabled: Some(depth_write),
            depth_compare: Some(depth_compare),
            stencil: wgpu::StencilState::default(),
            bias: wgpu::DepthBiasState::default(),
        }),
        multisample: wgpu::MultisampleState::default(),
        fragment: colour_targets.as_ref().map(|targets| wgpu::FragmentState {
            module: &module,
            entry_point,
            compilation_options: Default::default(),
            targets,
        }),
        multiview_mask: None,
        cache: None,
    })
}

/// The WGSL module `source` and a pipeline layout of the single bind group `layout`.
fn module_and_layout(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layout: &wgpu::BindGroupLayout,
) -> (wgpu::ShaderModule, wgpu::PipelineLayout) {
    module_and_layouts(device, label, source, &[layout])
}

/// The WGSL module `source` and a pipeline layout of the bind groups `layouts`, in order.
fn module_and_layouts(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layouts: &[&wgpu::BindGroupLayout],
) -> (wgpu::ShaderModule, wgpu::PipelineLayout) {
    let module = device.create_shader_module(wgpu::ShaderModuleDescriptor {
        label: Some(label),
        source: wgpu::ShaderSource::Wgsl(source.into()),
    });
    let groups: Vec<Option<&wgpu::BindGroupLayout>> = layouts.iter().map(|l| Some(*l)).collect();
    let pipeline_layout = device.create_pipeline_layout(&wgpu::PipelineLayoutDescriptor {
        label: Some(label),
        bind_group_layouts: &groups,
        immediate_size: 0,
    });
    (module, pipeline_layout)
}

/// Layout entry of an unfilterable float 2D texture at `binding`, seen by the `visibility`
/// stages: how depth (read through `.r`) and `R32Float` pyramid levels are bound (GL trap 2).
pub fn float_texture_entry(
    binding: u32,
    visibility: wgpu::ShaderStages,
) -> wgpu::BindGroupLayoutEntry {
    wgpu::BindGroupLayoutEntry {
        binding,
        visibility,
        ty: wgpu::BindingType::Texture {
            sample_type: wgpu::TextureSampleType::Float { filterable: false },
            view_dimension: wgpu::TextureViewDimension::D2,
            multisampled: false,
        },
        count: None,
    }
}

/// A pipeline drawing one full-screen triangle: `vs_main` makes it from the vertex index (no
/// vertex buffers), `fs_main` shades it with the single bind group of `layout`, under the depth
/// state `depth_stencil` (`None`: no depth attachment) into the colour `targets` (empty: depth
/// only).
pub fn fullscreen_pipeline(
    device: &wgpu::Device,
    label: &str,
    source: &str,
    layout: &wgpu::BindGroupLayout,
    depth_stencil: Option<wgpu::DepthStencilState>,
    targets: &[Option<wgpu::ColorTargetState>],
) -> wgpu::RenderPipeline {
    let (module, pipeline_layout) = module_and_layout(device, label, source, layout);
    device.create_render_pipeline(&wgpu::RenderPipelineDescriptor {
        label: Some(label),
        layout: Some(&pipeline_layout),
        vertex: wgpu::VertexState {
            module: &module,
            entry_point: Some("vs_main"),
            compilation_options: Default::default(),
            buffers: &[],
        },
        primitive: wgpu::PrimitiveState::default(),
        depth_stencil,
        multisample: wgpu::MultisampleState::default(),
        fragment: Some(wgpu::FragmentState {
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
    colour_pass(
        encoder,
        label,
        colour,
        wgpu::LoadOp::Clear(clear),
        Some(depth.attachment()),
        timestamp_writes,
    )
}

/// Begins a render pass that draws over a frame already drawn: `colour` and `depth` both loaded
/// and kept (the late pass, the ground surfaces, the picked building's outline).
pub(crate) fn overlay_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colour: &wgpu::TextureView,
    depth: &DepthTarget,
    timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    colour_pass(
        encoder,
        label,
        colour,
        wgpu::LoadOp::Load,
        Some(depth.loaded_attachment()),
        timestamp_writes,
    )
}

/// Begins an untimed render pass into `colour`, loaded or cleared as `load` and stored, with
/// `depth` (cleared to reversed-Z infinity) when given.
pub(crate) fn begin_colour_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colour: &wgpu::TextureView,
    load: wgpu::LoadOp<wgpu::Color>,
    depth: Option<&DepthTarget>,
) -> wgpu::RenderPass<'e> {
    colour_pass(
        encoder,
        label,
        colour,
        load,
        depth.map(DepthTarget::attachment),
        None,
    )
}

fn colour_pass<'e>(
    encoder: &'e mut wgpu::CommandEncoder,
    label: &str,
    colour: &wgpu::TextureView,
    load: wgpu::LoadOp<wgpu::Color>,
    depth: Option<wgpu::RenderPassDepthStencilAttachment<'_>>,
    timestamp_writes: Option<wgpu::RenderPassTimestampWrites<'_>>,
) -> wgpu::RenderPass<'e> {
    encoder.begin_render_pass(&wgpu::RenderPassDescriptor {
        label: Some(label),
        color_attachments: &[Some(wgpu::RenderPassColorAttachment {
            view: colour,
            depth_slice: None,
            resolve_target: None,
            ops: wgpu::Operations {
                load,
                store: wgpu::StoreOp::Store,
            },
        })],
        depth_stencil_attachment: depth,
        timestamp_writes,
        occlusion_query_set: None,
        multiview_mask: None,
    })
}
