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
use crate::render::targets::ReadbackError;

/// Slots in the ring: the frame being recorded, one the GPU works on, one being read. A report
/// arrives at most this many frames after its frame ([`crate::auto`] counts on it).
pub const SLOTS: usize = 3;

const FREE: u8 = 0;
const IN_FLIGHT: u8 = 1;
const MAPPED: u8 = 2;
const FAILED: u8 = 3;

/// Where a frame's data lie in its slot (bytes).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(super) struct SlotLayout {
    pub timestamps_bytes: u64,
    /// Words after the timestamps, before the two arrays (a tree frame's counters and list
    /// header; 0 otherwise).
    pub header_words: u64,
    /// Candidates: the cull's and the early entry's status, `u32` each (a tree frame: its kept
    /// ids and early ids, up to this many each).
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
