//! The fullscreen depth copy the occluder pre-pass starts from.

use citywalk_shaders::DEPTH_COPY_WGSL;

use crate::render::targets::DepthTarget;
use crate::render::{fragment_float_texture_entry, fullscreen_pipeline};

/// The fullscreen depth copy (`wgsl/depth_copy.wgsl`), no colour: with depth compare `Always`
/// a copy, with `Greater` (reversed Z) a merge that keeps the nearer of source and destination.
/// The source depth is bound as an unfilterable float texture and read through `.r` (GL trap 2).
pub(super) fn depth_copy_pipeline(
    device: &wgpu::Device,
    compare: wgpu::CompareFunction,
) -> (wgpu::RenderPipeline, wgpu::BindGroupLayout) {
    let layout = device.create_bind_group_layout(&wgpu::BindGroupLayoutDescriptor {
        label: Some("depth copy"),
        entries: &[fragment_float_texture_entry(0)],
    });
    let depth = wgpu::DepthStencilState {
        format: DepthTarget::FORMAT,
        depth_write_enabled: Some(true),
        depth_compare: Some(compare),
        stencil: wgpu::StencilState::default(),
        bias: wgpu::DepthBiasState::default(),
    };
    let pipeline = fullscreen_pipeline(
        device,
        "depth copy",
        DEPTH_COPY_WGSL,
        &layout,
        Some(depth),
        &[],
    );
    (pipeline, layout)
}
