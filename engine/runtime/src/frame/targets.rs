//! The frame's size-dependent resources: depth, the occluders' depth, the pyramid.

use crate::frame::FrameError;
use crate::gpu::GpuContext;
use crate::hzb::HzbPyramid;
use crate::render::targets::{DepthTarget, check_size};

/// Size-dependent resources: depth, the occluders' depth, the pyramid.
#[derive(Debug)]
pub(super) struct Targets {
    pub depth: DepthTarget,
    /// The culling depth: the virtual occluders (with the gate, the ground too), merged with
    /// `depth` when the pyramid is built.
    pub cull_depth_view: wgpu::TextureView,
    pub pyramid: HzbPyramid,
}

impl Targets {
    /// Targets for a `width × height` viewport.
    pub fn new(gpu: &GpuContext, width: u32, height: u32) -> Result<Targets, FrameError> {
        check_size(gpu, width, height)?;
        let depth = DepthTarget::new(gpu, width, height);
        let cull_depth_view = DepthTarget::new(gpu, width, height).view;
        Ok(Targets {
            depth,
            cull_depth_view,
            pyramid: HzbPyramid::new(gpu, width, height)?,
        })
    }
}
