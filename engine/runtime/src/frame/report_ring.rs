//! The frame's statistics on their way to the CPU, a frame or more late: a ring of mappable
//! buffers, each holding one submitted frame's GPU timestamps, cull status and early status.
//! A frame copies into a free slot and maps it after submission; nothing waits inside the frame.
//! The benchmark waits for a slot ([`ReportRing::wait`]); the viewer only takes slots that are
//! ready ([`ReportRing::take_ready`]). When every slot is still in flight the frame records no
//! report (the viewer's panel then skips a frame; nothing stalls).

use std::sync::Arc;
use std::sync::atomic::{AtomicU8, Ordering};

use crate::frame::grow_buffer::GrowBuffer;
use crate::gpu::GpuContext;
use crate::render::targets::{ReadbackError, map_read_prefix};

/// Slots in the ring: the frame being recorded, one the GPU works on, one being read. A report
/// arrives at most this many frames after its frame ([`crate::auto`] counts on it).
pub const SLOTS: usize = 3;

const FREE: u8 = 0;
const IN_FLIGHT: u8 = 1;
const MAPPED: u8 = 2;
const FAILED: u8 = 3;

/// Ids of each list a report copies at first ([`ReportRing`]'s slots grow when a frame lists
/// more).
pub(super) const FIRST_LIST_ENTRIES: u32 = 4096;

/// Where a frame's data lie in its slot (bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct SlotLayout {
    pub timestamps_bytes: u64,
    /// Words after the timestamps, before the two lists (the frame's counters and list
    /// lengths).
    pub header_words: u64,
    /// Entries copied of each list, `u32` each: the kept ids, then the early ids.
    pub candidates: u64,
}

impl SlotLayout {
    pub fn header_at(&self) -> u64 {
        self.timestamps_bytes
    }

    pub fn status_at(&self) -> u64 {
        self.timestamps_bytes + self.header_words * 4
    }

    pub fn early_at(&self) -> u64 {
        self.status_at() + self.candidates * 4
    }

    pub fn bytes(&self) -> u64 {
        (self.status_at() + self.candidates * 8).max(4)
    }
}

#[derive(Debug)]
struct Slot<T> {
    buffer: GrowBuffer,
    state: Arc<AtomicU8>,
    /// The frame's own data the CPU needs to read the slot (what it culled, its number).
    pending: Option<(SlotLayout, T)>,
}

/// The ring; `T` is what a frame keeps beside its slot until it is read.
#[derive(Debug)]
pub(super) struct ReportRing<T> {
    slots: Vec<Slot<T>>,
}

/// A slot reserved for the frame being recorded.
#[derive(Debug)]
pub(super) struct SlotTicket {
    index: usize,
}

/// One read slot: its bytes and the data the frame kept.
#[derive(Debug)]
pub(super) struct ReadSlot<T> {
    pub bytes: Vec<u8>,
    pub layout: SlotLayout,
    pub pending: T,
}

impl<T> ReportRing<T> {
    pub fn new(device: &wgpu::Device) -> ReportRing<T> {
        ReportRing {
            slots: (0..SLOTS)
                .map(|_| Slot {
                    buffer: GrowBuffer::new(
                        device,
                        "frame report",
                        wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
                    ),
                    state: Arc::new(AtomicU8::new(FREE)),
                    pending: None,
                })
                .collect(),
        }
    }

    /// A free slot with room for `layout`, or `None` when every slot is in flight.
    pub fn reserve(
        &mut self,
        gpu: &GpuContext,
        layout: SlotLayout,
    ) -> Option<(SlotTicket, &wgpu::Buffer)> {
        let index = self
            .slots
            .iter()
            .position(|s| s.state.load(Ordering::Acquire) == FREE)?;
        let slot = &mut self.slots[index];
        slot.buffer.reserve(&gpu.device, layout.bytes());
        Some((SlotTicket { index }, &slot.buffer.buffer))
    }

    /// After the frame's submission: maps the slot (asynchronously) and keeps `pending` with it.
    pub fn submitted(&mut self, ticket: SlotTicket, layout: SlotLayout, pending: T) {
        let slot = &mut self.slots[ticket.index];
        slot.state.store(IN_FLIGHT, Ordering::Release);
        slot.pending = Some((layout, pending));
        let state = Arc::clone(&slot.state);
        slot.buffer
            .buffer
            .slice(..layout.bytes())
            .map_async(wgpu::MapMode::Read, move |r| {
                state.store(if r.is_ok() { MAPPED } else { FAILED }, Ordering::Release);
            });
    }

    /// Reads and frees every slot whose mapping has completed, oldest frame first by `order`
    /// (the frames' numbers); never waits. Slots whose mapping failed are freed and reported as
    /// errors after the good ones.
    pub fn take_ready(
        &mut self,
        gpu: &GpuContext,
        order: impl Fn(&T) -> u64,
    ) -> Result<Vec<ReadSlot<T>>, ReadbackError> {
        gpu.device.poll(wgpu::PollType::Poll)?;
        self.collect(order)
    }

    /// Waits until the slot whose pending data satisfies `is_it` is mapped, then reads every
    /// ready slot as [`ReportRing::take_ready`].
    pub fn wait(
        &mut self,
        gpu: &GpuContext,
        order: impl Fn(&T) -> u64,
        is_it: impl Fn(&T) -> bool,
    ) -> Result<Vec<ReadSlot<T>>, ReadbackError> {
        let waiting = self
            .slots
            .iter()
            .any(|s| s.pending.as_ref().is_some_and(|(_, p)| is_it(p)));
        if waiting {
            gpu.device.poll(wgpu::PollType::wait_indefinitely())?;
        }
        self.collect(order)
    }

    fn collect(&mut self, order: impl Fn(&T) -> u64) -> Result<Vec<ReadSlot<T>>, ReadbackError> {
        let mut out = Vec::new();
        let mut failed = false;
        for slot in &mut self.slots {
            match slot.state.load(Ordering::Acquire) {
                MAPPED => {}
                FAILED => {
                    slot.pending = None;
                    slot.state.store(FREE, Ordering::Release);
                    failed = true;
                    continue;
                }
                _ => continue,
            }
            let Some((layout, pending)) = slot.pending.take() else {
                slot.buffer.buffer.unmap();
                slot.state.store(FREE, Ordering::Release);
                continue;
            };
            let bytes = {
                let range = slot
                    .buffer
                    .buffer
                    .slice(..layout.bytes())
                    .get_mapped_range()
                    .map_err(|e| ReadbackError::MappedRange(e.to_string()));
                let bytes = range.map(|r| r.to_vec());
                slot.buffer.buffer.unmap();
                slot.state.store(FREE, Ordering::Release);
                bytes?
            };
            out.push(ReadSlot {
                bytes,
                layout,
                pending,
            });
        }
        out.sort_by_key(|r| order(&r.pending));
        if failed && out.is_empty() {
            return Err(ReadbackError::MappedRange(
                "mapping a frame report failed".into(),
            ));
        }
        Ok(out)
    }
}

/// Where a frame's kept and early lists lie on the GPU: buffer and byte offset of each.
#[derive(Debug)]
pub(super) struct ListSources {
    pub kept: (wgpu::Buffer, u64),
    pub early: (wgpu::Buffer, u64),
}

/// A frame's kept ids and early ids.
pub(super) type KeptAndEarly = (Vec<u32>, Vec<u32>);

/// A frame's kept and early lists, `kept_count` and `early_count` long, from its read `slot`
/// (`bytes` in `layout`) when the slot holds them whole; else read whole from `sources` when
/// `gpu` is given (a frame waited for right after its submission: nothing has written the
/// lists since); else `None`, never a part of a list, which would undercount what was drawn.
/// `entries` (what later reports copy) grows to hold them.
pub(super) fn read_lists(
    (bytes, layout): (&[u8], SlotLayout),
    (kept_count, early_count): (usize, usize),
    sources: &ListSources,
    gpu: Option<&GpuContext>,
    entries: &mut u32,
) -> Result<Option<KeptAndEarly>, ReadbackError> {
    let needed = kept_count.max(early_count);
    if needed as u64 > u64::from(*entries) {
        *entries = (needed as u32).saturating_mul(2).next_power_of_two();
    }
    let words = |at: u64, n: usize| -> Vec<u32> {
        let at = at as usize;
        bytemuck::pod_collect_to_vec(&bytes[at..at + n * 4])
    };
    if needed as u64 <= layout.candidates {
        return Ok(Some((
            words(layout.status_at(), kept_count),
            words(layout.early_at(), early_count),
        )));
    }
    let Some(gpu) = gpu else {
        return Ok(None);
    };
    Ok(Some((
        read_words(gpu, &sources.kept, kept_count)?,
        read_words(gpu, &sources.early, early_count)?,
    )))
}

/// `n` words of `buffer` from byte `at`, through a staging copy (waits for the GPU).
fn read_words(
    gpu: &GpuContext,
    (buffer, at): &(wgpu::Buffer, u64),
    n: usize,
) -> Result<Vec<u32>, ReadbackError> {
    if n == 0 {
        return Ok(Vec::new());
    }
    let bytes = n as u64 * 4;
    let staging = gpu.device.create_buffer(&wgpu::BufferDescriptor {
        label: Some("frame report lists"),
        size: bytes,
        usage: wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ,
        mapped_at_creation: false,
    });
    let mut encoder = gpu
        .device
        .create_command_encoder(&wgpu::CommandEncoderDescriptor {
            label: Some("frame report lists"),
        });
    encoder.copy_buffer_to_buffer(buffer, *at, &staging, 0, bytes);
    gpu.queue.submit([encoder.finish()]);
    let read = map_read_prefix(gpu, &staging, bytes)?;
    Ok(bytemuck::pod_collect_to_vec(&read))
}
