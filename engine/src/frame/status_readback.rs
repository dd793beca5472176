//! The cull status on its way to the CPU (one `u32` per candidate).

use crate::frame::grow_buffer::GrowBuffer;
use crate::gpu::GpuContext;
use crate::render::targets::{ReadbackError, map_read_prefix};

/// A mappable copy of the cull status, grown to the largest candidate count seen.
#[derive(Debug)]
pub(super) struct StatusReadback {
    buffer: GrowBuffer,
}

impl StatusReadback {
    pub fn new(device: &wgpu::Device) -> StatusReadback {
        StatusReadback {
            buffer: GrowBuffer::new(
                device,
                "cull status readback",
                wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
            ),
        }
    }

    /// Makes room for `slots` statuses of `n` entries each (call before recording the copies).
    pub fn reserve(&mut self, gpu: &GpuContext, n: usize, slots: usize) {
        self.buffer
            .reserve(&gpu.device, (n.max(1) * slots.max(1) * 4) as u64);
    }

    /// Records the copy of the first `count` entries of `status` into slot `slot` of slots of
    /// `stride` entries (entries `slot·stride ..`; `count` ≤ `stride`), so that several culls of
    /// one encoder can be read in one map.
    pub fn copy_from(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        status: &wgpu::Buffer,
        count: usize,
        stride: usize,
        slot: usize,
    ) {
        debug_assert!(count <= stride, "{count} entries in a slot of {stride}");
        if count > 0 {
            encoder.copy_buffer_to_buffer(
                status,
                0,
                &self.buffer.buffer,
                (slot * stride * 4) as u64,
                (count * 4) as u64,
            );
        }
    }

    /// Waits for the GPU and reads the first `n` entries (all slots copied by the submitted
    /// frame, one after the other).
    pub fn read(&self, gpu: &GpuContext, n: usize) -> Result<Vec<u32>, ReadbackError> {
        if n == 0 {
            gpu.wait_idle();
            return Ok(Vec::new());
        }
        let bytes = map_read_prefix(gpu, &self.buffer.buffer, (n * 4) as u64)?;
        Ok(bytemuck::pod_collect_to_vec(&bytes))
    }
}
