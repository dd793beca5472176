//! A growable GPU list of indexed indirect draws, written from the CPU each frame.

use citywalk_shaders::DrawIndexedIndirectArgs;

use crate::gpu::GpuContext;

/// Draws in capacity the buffer starts with.
const INITIAL_CAPACITY: usize = 1024;

/// An `INDIRECT | COPY_DST` buffer of [`DrawIndexedIndirectArgs`], regrown to the next power
/// of two when a frame's list no longer fits.
#[derive(Debug)]
pub(crate) struct IndirectDraws {
    label: &'static str,
    buffer: wgpu::Buffer,
    capacity: usize,
}

impl IndirectDraws {
    pub(crate) fn new(device: &wgpu::Device, label: &'static str) -> IndirectDraws {
        IndirectDraws {
            label,
            buffer: Self::buffer_of(device, label, INITIAL_CAPACITY),
            capacity: INITIAL_CAPACITY,
        }
    }

    fn buffer_of(device: &wgpu::Device, label: &str, capacity: usize) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size: (capacity * size_of::<DrawIndexedIndirectArgs>()) as u64,
            usage: wgpu::BufferUsages::INDIRECT | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        })
    }

    /// Writes `draws` through the queue (growing the buffer first if needed) and returns their
    /// count.
    pub(crate) fn write(&mut self, gpu: &GpuContext, draws: &[DrawIndexedIndirectArgs]) -> u32 {
        if draws.len() > self.capacity {
            self.capacity = draws.len().next_power_of_two();
            self.buffer = Self::buffer_of(&gpu.device, self.label, self.capacity);
        }
        gpu.queue
            .write_buffer(&self.buffer, 0, bytemuck::cast_slice(draws));
        draws.len() as u32
    }

    /// The buffer the last [`IndirectDraws::write`] filled.
    pub(crate) fn buffer(&self) -> &wgpu::Buffer {
        &self.buffer
    }
}
