//! Large arrays to the GPU at a bounded memory cost.
//!
//! `create_buffer_init` and `Queue::write_buffer` both copy through a staging buffer that lives
//! until the submission that consumes it has completed. Uploading a package's arrays (1.6 GB at
//! a million buildings) in one go therefore holds them twice at once, and on a software adapter,
//! whose GPU memory is process memory, a third time with the mapped file's pages: the 1M bench
//! peaked at 7.7 GB where the scene needs 3.7 GB. Here an array goes up in chunks of
//! [`UPLOAD_CHUNK_BYTES`], each chunk's submission is waited for before the next (which frees its
//! staging), and the source bytes of each chunk are handed to a `release` function (a package's
//! memory map gives those pages back: see `GpuSceneView::release_resident`).

use crate::gpu::GpuContext;

/// Why an array did not reach the GPU: the adapter's limits or its memory, named with the
/// array and its size, instead of wgpu's panic on an uncaptured error.
#[derive(Debug, thiserror::Error)]
pub enum UploadError {
    #[error(
        "the scene's {what} take {bytes} bytes ({}), over this GPU's {limit_name} of {limit} \
         bytes ({}): the city is too large for this adapter",
        binary_size(*bytes),
        binary_size(*limit)
    )]
    OverLimit {
        what: String,
        bytes: u64,
        /// `max_buffer_size`, or `max_storage_buffer_binding_size` for an array a pass binds
        /// whole as storage.
        limit_name: &'static str,
        limit: u64,
    },
    /// The GPU's memory ran out: the budget it reached is what was allocated on the adapter
    /// then (wgpu reports no heap size; a software adapter's heap is host memory).
    #[error(
        "out of GPU memory for the scene's {what} ({bytes} bytes, {}) on {adapter}, with {} \
         already allocated there: {message}",
        binary_size(*bytes),
        allocated.map_or_else(|| "an unknown amount".to_owned(), binary_size)
    )]
    OutOfMemory {
        what: String,
        bytes: u64,
        adapter: String,
        allocated: Option<u64>,
        message: String,
    },
    /// The buffer mapped at its creation could not be written (a wgpu error, not the data's).
    #[error("cannot write the scene's {what} into their mapped GPU buffer: {message}")]
    Map { what: String, message: String },
    /// Arrays that contradict each other (an index past the vertices, a range past the
    /// indices): uploading them would draw garbage or fault on the GPU.
    #[error("the scene's {what} are inconsistent: {message}")]
    Inconsistent { what: String, message: String },
}

/// `bytes` in the largest binary unit that keeps a whole number before the point:
/// `146.6 KiB`, `353.0 MiB`, `1.6 GiB`.
fn binary_size(bytes: u64) -> String {
    let mut value = bytes as f64;
    for unit in ["B", "KiB", "MiB"] {
        if value < 1024.0 {
            return format!("{value:.1} {unit}");
        }
        value /= 1024.0;
    }
    format!("{value:.1} GiB")
}

/// Bytes copied per submission: large enough that the waits cost little (about 50 at a
/// million buildings), small enough that the staging is a rounding error.
pub const UPLOAD_CHUNK_BYTES: usize = 32 << 20;

/// A buffer of `usage` holding `items`, or one zeroed item when there is none (so that it can
/// always be bound), uploaded chunk by chunk; the bytes of each chunk are given to `release`
/// once on the GPU.
pub fn array_buffer<T: bytemuck::Pod>(
    gpu: &GpuContext,
    label: &str,
    items: &[T],
    usage: wgpu::BufferUsages,
    release: &dyn Fn(&[u8]),
) -> Result<wgpu::Buffer, UploadError> {
    let contents: &[u8] = bytemuck::cast_slice(items);
    let len = contents.len().max(size_of::<T>());
    buffer_from_chunks(gpu, label, len, usage, |range, out| {
        // Past the items (the one padding item) `out` stays zero.
        let source = contents.get(range).unwrap_or(&[]);
        out[..source.len()].copy_from_slice(source);
        release(source);
    })
}

/// A buffer of `usage`, `len` bytes long (rounded up to a multiple of 4, at least 4), whose
/// bytes are produced chunk by chunk, in order: `fill(range, out)` writes bytes `range` into
/// `out` (zeroed, `range.len()` long, 4-byte aligned; ranges start at multiples of 4). Each
/// chunk is on the GPU before the next is produced. A size over the device's buffer size limit
/// or a failed allocation is an error naming `label`.
pub fn buffer_from_chunks(
    gpu: &GpuContext,
    label: &str,
    len: usize,
    usage: wgpu::BufferUsages,
    mut fill: impl FnMut(std::ops::Range<usize>, &mut [u8]),
) -> Result<wgpu::Buffer, UploadError> {
    let size = len
        .max(1)
        .next_multiple_of(wgpu::COPY_BUFFER_ALIGNMENT as usize);
    check_limits(&gpu.device.limits(), label, size as u64, usage)?;
    // A software adapter's buffers are process memory: there the chunks are written straight
    // into the buffer, mapped, not copied through staging (on the 1M package, kernel page
    // zeroing of the staging and the buffers was a quarter of the load's CPU time).
    let direct = gpu.has(wgpu::Features::MAPPABLE_PRIMARY_BUFFERS);
    let out_of_memory = gpu.device.push_error_scope(wgpu::ErrorFilter::OutOfMemory);
    let buffer = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some(label),
        size: size as u64,
        usage: if direct {
            usage | wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_WRITE
        } else {
            usage | wgpu::BufferUsages::COPY_DST
        },
        mapped_at_creation: direct,
    });
    if let Some(error) = pollster::block_on(out_of_memory.pop()) {
        return Err(UploadError::OutOfMemory {
            what: label.to_owned(),
            bytes: size as u64,
            adapter: gpu.adapter_info.name.clone(),
            allocated: gpu
                .device
                .generate_allocator_report()
                .map(|report| report.total_allocated_bytes),
            message: error.to_string(),
        });
    }
    // `u32`s, so that `out` is 4-byte aligned (callers cast it to `u32`s).
    let mut chunk = vec![0u32; size.min(UPLOAD_CHUNK_BYTES) / 4];
    let mut start = 0;
    while start < size {
        let end = (start + UPLOAD_CHUNK_BYTES).min(size);
        let out = &mut bytemuck::cast_slice_mut(&mut chunk)[..end - start];
        out.fill(0);
        // The padding past `len` stays zero.
        let filled = end.min(len).saturating_sub(start);
        fill(start..start + filled, &mut out[..filled]);
        if direct {
            buffer
                .slice(start as u64..end as u64)
                .get_mapped_range_mut()
                .map_err(|e| UploadError::Map {
                    what: label.to_owned(),
                    message: e.to_string(),
                })?
                .copy_from_slice(out);
        } else {
            gpu.queue.write_buffer(&buffer, start as u64, out);
            if size > UPLOAD_CHUNK_BYTES {
                // The staging of this chunk is freed once its copy has run.
                gpu.queue.submit([]);
                gpu.wait_idle();
            }
        }
        start = end;
    }
    if direct {
        buffer.unmap();
    }
    Ok(buffer)
}

/// Whether a buffer of `bytes` and `usage` fits `limits`: its size, and, for a `STORAGE`
/// buffer, the storage binding limit (`max_storage_buffer_binding_size`, 128 MiB on lavapipe),
/// since every pass binds its storage arrays whole. The vertex and index buffers (353 MiB each
/// at a million buildings) are no storage and are bound as vertices and indices, to which only
/// the buffer's size applies. Checking the scene's arrays here also covers the frames' own
/// buffers, which hold fewer bytes per draw id than the records (48 bytes): commands 20, lists,
/// stamps and marks 4; a city past the limit is refused at load with the array named, not by a
/// wgpu panic when a frame binds it.
fn check_limits(
    limits: &wgpu::Limits,
    label: &str,
    bytes: u64,
    usage: wgpu::BufferUsages,
) -> Result<(), UploadError> {
    let over = |limit_name, limit| UploadError::OverLimit {
        what: label.to_owned(),
        bytes,
        limit_name,
        limit,
    };
    if bytes > limits.max_buffer_size {
        return Err(over("max_buffer_size", limits.max_buffer_size));
    }
    let binding = limits.max_storage_buffer_binding_size;
    if usage.contains(wgpu::BufferUsages::STORAGE) && bytes > binding {
        return Err(over("max_storage_buffer_binding_size", binding));
    }
    Ok(())
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Reads a buffer back (it must allow `COPY_SRC`).
    fn read_back(gpu: &GpuContext, buffer: &wgpu::Buffer) -> Vec<u8> {
        let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
            label: Some("upload test readback"),
            size: buffer.size(),
            usage: wgpu::BufferUsages::MAP_READ | wgpu::BufferUsages::COPY_DST,
            mapped_at_creation: false,
        });
        let mut encoder = gpu.device.create_command_encoder(&Default::default());
        encoder.copy_buffer_to_buffer(buffer, 0, &staging, 0, buffer.size());
        gpu.queue.submit([encoder.finish()]);
        crate::render::targets::map_read(gpu, &staging).expect("read back")
    }

    /// An array of several chunks and a ragged end arrives whole, each source byte released
    /// exactly once; an empty one is one zeroed item.
    #[test]
    fn chunked_upload_equals_the_source_and_releases_every_byte_once() {
        let Ok(gpu) = GpuContext::headless() else {
            assert!(std::env::var_os("CI").is_none(), "no adapter in CI");
            return;
        };
        let len = 2 * UPLOAD_CHUNK_BYTES + 4 * 1001;
        let contents: Vec<u8> = (0..len).map(|i| (i * 7 + i / 251) as u8).collect();
        let released = std::cell::Cell::new(0usize);
        let last_end = std::cell::Cell::new(contents.as_ptr() as usize);
        let buffer = array_buffer(
            &gpu,
            "upload test",
            &contents,
            wgpu::BufferUsages::COPY_SRC,
            &|bytes| {
                assert_eq!(bytes.as_ptr() as usize, last_end.get(), "chunks in order");
                last_end.set(bytes.as_ptr() as usize + bytes.len());
                released.set(released.get() + bytes.len());
            },
        )
        .expect("within the limits");
        assert_eq!(released.get(), len);
        assert!(
            read_back(&gpu, &buffer) == contents,
            "the buffer holds the source"
        );

        let empty: &[[u32; 3]] = &[];
        let one = array_buffer(&gpu, "empty", empty, wgpu::BufferUsages::COPY_SRC, &|_| {})
            .expect("within the limits");
        assert_eq!(read_back(&gpu, &one), vec![0u8; 12]);
    }

    /// An array over the device's buffer limit is an error naming the array and the limit (and
    /// nothing is allocated); the storage binding limit does not apply to the buffer.
    #[test]
    fn an_array_over_the_limits_is_an_error_naming_it() {
        use wgpu::BufferUsages as U;
        let limits = wgpu::Limits {
            max_buffer_size: 1 << 20,
            max_storage_buffer_binding_size: 1 << 16,
            ..wgpu::Limits::default()
        };
        // A vertex buffer past the storage binding limit is bound as vertices: only its size
        // counts.
        assert!(check_limits(&limits, "a", 1 << 20, U::VERTEX).is_ok());
        let error = check_limits(&limits, "scene vertices", (1 << 20) + 4, U::VERTEX)
            .expect_err("over the limit");
        let text = error.to_string();
        assert!(
            text.contains("scene vertices")
                && text.contains("1048580 bytes (1.0 MiB)")
                && text.contains("max_buffer_size of 1048576 bytes (1.0 MiB)"),
            "{text}"
        );
        // A storage array is bound whole by the passes: the binding limit applies.
        assert!(check_limits(&limits, "b", 1 << 16, U::STORAGE).is_ok());
        let error = check_limits(&limits, "lod cull records", (1 << 16) + 4, U::STORAGE)
            .expect_err("over the binding limit");
        let text = error.to_string();
        assert!(
            text.contains("lod cull records")
                && text.contains("max_storage_buffer_binding_size of 65536 bytes (64.0 KiB)"),
            "{text}"
        );
    }

    #[test]
    fn sizes_in_binary_units() {
        assert_eq!(binary_size(0), "0.0 B");
        assert_eq!(binary_size(150_080), "146.6 KiB");
        assert_eq!(binary_size(353 << 20), "353.0 MiB");
        assert_eq!(binary_size(3 << 30), "3.0 GiB");
    }
}
