//! The frame's size-dependent resources: depth, its copy for the occluders, the pyramid.

use crate::frame::FrameError;
use crate::gpu::GpuContext;
use crate::hzb::HzbPyramid;
use crate::render::targets::{DepthTarget, check_size};

/// Size-dependent resources: depth, its copy for the occluders, the pyramid.
#[derive(Debug)]
pub(super) struct Targets {
    pub depth: DepthTarget,
    pub cull_depth_view: wgpu::TextureView,
    /// Binds `depth` as the depth copy's source.
    pub copy_group: wgpu::BindGroup,
    pub pyramid: HzbPyramid,
}

impl Targets {
    /// Targets for a `width × height` viewport; `copy_layout` is the depth copy's bind-group
    /// layout.
    pub fn new(
        gpu: &GpuContext,
        copy_layout: &wgpu::BindGroupLayout,
        width: u32,
        height: u32,
    ) -> Result<Targets, FrameError> {
        check_size(gpu, width, height)?;
        let depth = DepthTarget::new(gpu, width, height);
        // The culling depth (early pass + occluders) is a second target of the same kind.
        let cull_depth_view = DepthTarget::new(gpu, width, height).view;
        let copy_group = gpu.device.create_bind_group(&wgpu::BindGroupDescriptor {
            label: Some("depth copy"),
            layout: copy_layout,
            entries: &[wgpu::BindGroupEntry {
                binding: 0,
                resource: wgpu::BindingResource::TextureView(&depth.view),
            }],
        });
        Ok(Targets {
            depth,
            cull_depth_view,
            copy_group,
            pyramid: HzbPyramid::new(gpu, width, height)?,
        })
    }
}
