//! Render targets (reversed-Z depth, offscreen colour) and texture readback with the 256-byte
//! row alignment wgpu requires.

use crate::gpu::GpuContext;

/// Why a frame could not be read back to the CPU.
#[derive(Debug, thiserror::Error)]
pub enum ReadbackError {
    #[error("viewport {width}x{height} is outside 1..={max} pixels per side")]
    Size { width: u32, height: u32, max: u32 },
    #[error("mapping the readback buffer failed: {0}")]
    Map(#[from] wgpu::BufferAsyncError),
    #[error("reading the mapped readback buffer failed: {0}")]
    MappedRange(String),
    #[error("the device failed while waiting for the readback: {0}")]
    Poll(#[from] wgpu::PollError),
    #[error(transparent)]
    DeviceLost(#[from] crate::gpu::DeviceLost),
}

/// Checks a viewport size against the device's texture limit.
pub fn check_size(gpu: &GpuContext, width: u32, height: u32) -> Result<(), ReadbackError> {
    let max = gpu.device.limits().max_texture_dimension_2d;
    if width == 0 || height == 0 || width > max || height > max {
        return Err(ReadbackError::Size { width, height, max });
    }
    Ok(())
}

/// A `Depth32Float` target for reversed-Z passes (clear to 0, compare `Greater`).
#[derive(Debug)]
pub struct DepthTarget {
    pub texture: wgpu::Texture,
    pub view: wgpu::TextureView,
    pub width: u32,
    pub height: u32,
}

impl DepthTarget {
    pub const FORMAT: wgpu::TextureFormat = wgpu::TextureFormat::Depth32Float;

    /// A depth target of the given size; also bindable as a texture (for a later HiZ build).
    pub fn new(gpu: &GpuContext, width: u32, height: u32) -> DepthTarget {
        let texture = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("depth (reversed Z)"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format: Self::FORMAT,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::TEXTURE_BINDING,
            view_formats: &[],
        });
        let view = texture.create_view(&wgpu::TextureViewDescriptor::default());
        DepthTarget {
            texture,
            view,
            width,
            height,
        }
    }

    /// The attachment that clears to reversed-Z infinity and stores.
    pub fn attachment(&self) -> wgpu::RenderPassDepthStencilAttachment<'_> {
        wgpu::RenderPassDepthStencilAttachment {
            view: &self.view,
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Clear(crate::camera::Camera::DEPTH_CLEAR),
                store: wgpu::StoreOp::Store,
            }),
            stencil_ops: None,
        }
    }

    /// The attachment that keeps the depth drawn so far (a pass over a frame already drawn).
    pub fn loaded_attachment(&self) -> wgpu::RenderPassDepthStencilAttachment<'_> {
        wgpu::RenderPassDepthStencilAttachment {
            depth_ops: Some(wgpu::Operations {
                load: wgpu::LoadOp::Load,
                store: wgpu::StoreOp::Store,
            }),
            ..self.attachment()
        }
    }
}

/// An offscreen colour + depth target that can be read back (PNG frames, the oracle, tests).
#[derive(Debug)]
pub struct OffscreenTarget {
    pub colour: wgpu::Texture,
    pub colour_view: wgpu::TextureView,
    pub depth: DepthTarget,
    pub format: wgpu::TextureFormat,
    pub width: u32,
    pub height: u32,
}

impl OffscreenTarget {
    /// A target of `format` (e.g. `Rgba8UnormSrgb`, `R32Uint`) with a reversed-Z depth buffer.
    pub fn new(
        gpu: &GpuContext,
        width: u32,
        height: u32,
        format: wgpu::TextureFormat,
    ) -> Result<OffscreenTarget, ReadbackError> {
        check_size(gpu, width, height)?;
        let colour = gpu.device.create_texture(&wgpu::TextureDescriptor {
            label: Some("offscreen colour"),
            size: wgpu::Extent3d {
                width,
                height,
                depth_or_array_layers: 1,
            },
            mip_level_count: 1,
            sample_count: 1,
            dimension: wgpu::TextureDimension::D2,
            format,
            usage: wgpu::TextureUsages::RENDER_ATTACHMENT | wgpu::TextureUsages::COPY_SRC,
            view_formats: &[],
        });
        let colour_view = colour.create_view(&wgpu::TextureViewDescriptor::default());
        Ok(OffscreenTarget {
            colour,
            colour_view,
            depth: DepthTarget::new(gpu, width, height),
            format,
            width,
            height,
        })
    }

    /// Reads the colour texture back: `width × height` texels, rows tightly packed.
    pub fn read_colour(&self, gpu: &GpuContext) -> Result<Vec<u8>, ReadbackError> {
        read_texture(gpu, &self.colour, self.width, self.height)
    }
}

/// Copies a single-sample 2D texture (mip 0) of a non-compressed colour format to the CPU,
/// removing the 256-byte row padding of the copy.
pub fn read_texture(
    gpu: &GpuContext,
    texture: &wgpu::Texture,
    width: u32,
    height: u32,
) -> Result<Vec<u8>, ReadbackError> {
    let texel_bytes = texture.format().block_copy_size(None).unwrap_or(4);
    let row_bytes = width * texel_bytes;
    let padded_row_bytes =
        row_bytes.div_ceil(wgpu::COPY_BYTES_PER_ROW_ALIGNMENT) * wgpu::COPY_BYTES_PER_ROW_ALIGNMENT;
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("texture readback"),
        size: u64::from(padded_row_bytes) * u64::from(height),
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("readback"),
        });
    encoder.copy_texture_to_buffer(
        texture.as_image_copy(),
        wgpu::TexelCopyBufferInfo {
            buffer: &buffer,
            layout: wgpu::TexelCopyBufferLayout {
                offset: 0,
                bytes_per_row: Some(padded_row_bytes),
                rows_per_image: Some(height),
            },
        },
        wgpu::Extent3d {
            width,
            height,
            depth_or_array_layers: 1,
        },
    );
    gpu.queue.submit([encoder.finish()]);
    let mapped = map_read(gpu, &buffer)?;
    let mut out = Vec::with_capacity((row_bytes * height) as usize);
    for row in mapped.chunks_exact(padded_row_bytes as usize) {
        out.extend_from_slice(&row[..row_bytes as usize]);
    }
    Ok(out)
}

/// Maps a `MAP_READ` buffer whose copies were submitted, waits, and returns its bytes.
pub fn map_read(gpu: &GpuContext, buffer: &wgpu::Buffer) -> Result<Vec<u8>, ReadbackError> {
    map_read_prefix(gpu, buffer, buffer.size())
}

/// [`map_read`] of the first `len` bytes of `buffer` (a buffer grown past what one read needs).
pub fn map_read_prefix(
    gpu: &GpuContext,
    buffer: &wgpu::Buffer,
    len: u64,
) -> Result<Vec<u8>, ReadbackError> {
    gpu.alive()?;
    let slice = buffer.slice(..len);
    let (tx, rx) = std::sync::mpsc::channel();
    slice.map_async(wgpu::MapMode::Read, move |r| {
        let _ = tx.send(r);
    });
    let mapped = gpu
        .device
        .poll(wgpu::PollType::wait_indefinitely())
        .map_err(ReadbackError::from)
        .and_then(|_| {
            rx.recv()
                .map_err(|e| ReadbackError::MappedRange(e.to_string()))?
                .map_err(ReadbackError::from)
        });
    // A mapping that failed because the device went says so.
    if let Err(e) = mapped {
        return Err(gpu.lost().map_or(e, ReadbackError::from));
    }
    let mapped = slice
        .get_mapped_range()
        .map_err(|e| ReadbackError::MappedRange(e.to_string()))?;
    let bytes = mapped.to_vec();
    drop(mapped);
    buffer.unmap();
    Ok(bytes)
}
