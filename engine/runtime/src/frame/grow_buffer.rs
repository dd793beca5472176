//! A GPU buffer grown on demand to the largest size asked for.

/// A buffer grown to the largest size asked for.
#[derive(Debug)]
pub(super) struct GrowBuffer {
    pub(super) buffer: wgpu::Buffer,
    label: &'static str,
    usage: wgpu::BufferUsages,
}

impl GrowBuffer {
    pub(super) fn new(
        device: &wgpu::Device,
        label: &'static str,
        usage: wgpu::BufferUsages,
    ) -> GrowBuffer {
        GrowBuffer {
            buffer: Self::make(device, label, usage, 256),
            label,
            usage,
        }
    }

    fn make(
        device: &wgpu::Device,
        label: &str,
        usage: wgpu::BufferUsages,
        size: u64,
    ) -> wgpu::Buffer {
        device.create_buffer(&wgpu::BufferDescriptor {
            label: Some(label),
            size,
            usage,
            mapped_at_creation: false,
        })
    }

    /// Ensures room for `bytes` (contents are lost when it grows).
    pub(super) fn reserve(&mut self, device: &wgpu::Device, bytes: u64) -> bool {
        if bytes <= self.buffer.size() {
            return false;
        }
        let size = bytes.next_power_of_two().max(256);
        self.buffer = Self::make(device, self.label, self.usage, size);
        tracing::debug!(label = self.label, bytes = size, "buffer grown");
        true
    }
}
