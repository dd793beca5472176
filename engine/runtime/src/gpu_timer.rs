//! Per-phase GPU time from timestamp queries.
//!
//! A [`GpuTimer`] owns a `Timestamp` query set with two slots per named phase (beginning and
//! end of the phase's pass). A pass asks for its writes with
//! [`GpuTimer::render_pass_writes`] / [`GpuTimer::compute_pass_writes`] and puts them in its
//! descriptor's `timestamp_writes`; after the frame's last pass, [`GpuTimer::resolve`] resolves
//! the phases that were written into a buffer and copies it to a mappable readback buffer; once
//! the frame's submission is done, [`GpuTimer::read`] maps it and converts the ticks to
//! milliseconds with `queue.get_timestamp_period()`.
//!
//! Only on devices with [`wgpu::Features::TIMESTAMP_QUERY`] (requested by
//! [`crate::gpu::GpuContext`] when the adapter offers it). Without it the timer hands out no
//! writes and reports every phase as `None`; the passes run the same either way.
//!
//! Timestamps are taken at pass boundaries only (the feature allows no more), so a phase is one
//! pass. Only phases whose pass was recorded since [`GpuTimer::begin_frame`] are resolved:
//! resolving a query that was never written waits forever on Vulkan (`vkCmdCopyQueryPoolResults`
//! with `WAIT`), so ask for a phase's writes only when its pass is really begun with them.
//!
//! On software adapters the numbers need care: lavapipe's compute-pass timestamps were seen far
//! below the pass's wall time (`shared/GPU-NOTES.md`); report CPU wall time beside them.

use std::sync::atomic::{AtomicBool, Ordering};

use crate::gpu::GpuContext;
use crate::render::targets::{ReadbackError, map_read};

/// The phases of the two-phase culling frame ([`crate::frame::CullingRenderer`]), one pass each,
/// in frame order: the occluder gate's occluders, pyramid and cull (or, without the gate, the
/// frustum-only early cull), the early pass, the occluder
/// pre-pass (with the gate: the merge of the early depth into the occluders'), the pyramid
/// build, the cull and the late pass. A phase whose pass does not run in a frame (no occluders,
/// no gate, no late draws) is `None` in that frame's times.
pub const FRAME_PHASES: &[&str] = &[
    "gate_occluders",
    "gate_pyramid",
    "gate",
    "early_cull",
    "early",
    "occluders",
    "pyramid",
    "cull",
    "late",
];

/// Bytes between two phases' results in the resolve buffer: each phase is resolved on its own
/// (only written queries may be resolved) and a resolve's destination offset must be aligned.
const PHASE_STRIDE_BYTES: u64 = wgpu::QUERY_RESOLVE_BUFFER_ALIGNMENT;

/// A phase's beginning and end on the GPU, in milliseconds since the earliest timestamp of the
/// frame.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct GpuSpan {
    pub begin_ms: f64,
    pub end_ms: f64,
}

impl GpuSpan {
    /// GPU time of the phase (ms).
    pub fn duration_ms(&self) -> f64 {
        self.end_ms - self.begin_ms
    }
}

/// One phase of a frame: its name and, when it was timed, its span.
#[derive(Debug, Clone, Copy, PartialEq, serde::Serialize)]
pub struct PhaseTime {
    pub name: &'static str,
    /// `None` when the device has no timestamp queries, the phase's pass did not run this
    /// frame, or the timestamps were not ordered (end before beginning).
    pub span: Option<GpuSpan>,
}

/// The GPU times of one frame, one entry per phase of the timer in its order (empty for a
/// frame that was not timed at all).
#[derive(Debug, Clone, Default, PartialEq, serde::Serialize)]
pub struct GpuTimes {
    pub phases: Vec<PhaseTime>,
}

impl GpuTimes {
    /// GPU time of phase `name` (ms), if it was timed.
    pub fn phase_ms(&self, name: &str) -> Option<f64> {
        self.phases
            .iter()
            .find(|p| p.name == name)
            .and_then(|p| p.span)
            .map(|s| s.duration_ms())
    }

    /// The timed phases and their GPU time (ms), in phase order.
    pub fn timed(&self) -> impl Iterator<Item = (&'static str, f64)> + '_ {
        self.phases
            .iter()
            .filter_map(|p| p.span.map(|s| (p.name, s.duration_ms())))
    }

    /// Sum of the timed phases' GPU time (ms); `None` when no phase was timed.
    pub fn total_ms(&self) -> Option<f64> {
        let mut timed = self.timed().peekable();
        timed.peek()?;
        Some(timed.map(|(_, ms)| ms).sum())
    }
}

/// The query set and buffers of an enabled timer.
#[derive(Debug)]
struct Queries {
    set: wgpu::QuerySet,
    resolve: wgpu::Buffer,
    readback: wgpu::Buffer,
    /// Nanoseconds per timestamp tick.
    period_ns: f64,
}

/// Timestamps around named phases (passes) of a frame.
#[derive(Debug)]
pub struct GpuTimer {
    phases: &'static [&'static str],
    /// `None` without `TIMESTAMP_QUERY` (or with no phases).
    queries: Option<Queries>,
    /// Per phase: its pass was given timestamp writes since the last `begin_frame`. Atomic so
    /// that passes recorded through `&self` can ask for writes; a frame is recorded on one
    /// thread, so relaxed ordering is enough.
    written: Vec<AtomicBool>,
}

impl GpuTimer {
    /// A timer for `phases` (unique names, in frame order). Disabled, reporting `None` per
    /// phase, when the device lacks [`wgpu::Features::TIMESTAMP_QUERY`].
    pub fn new(gpu: &GpuContext, label: &str, phases: &'static [&'static str]) -> GpuTimer {
        let enabled = gpu.has(wgpu::Features::TIMESTAMP_QUERY)
            && !phases.is_empty()
            && phases.len() * 2 <= wgpu::QUERY_SET_MAX_QUERIES as usize;
        let queries = enabled.then(|| {
            let device = &gpu.device;
            let bytes = phases.len() as u64 * PHASE_STRIDE_BYTES;
            let buffer = |usage| {
                device.create_buffer(&wgpu::BufferDescriptor {
                    label: Some(label),
                    size: bytes,
                    usage,
                    mapped_at_creation: false,
                })
            };
            Queries {
                set: device.create_query_set(&wgpu::QuerySetDescriptor {
                    label: Some(label),
                    ty: wgpu::QueryType::Timestamp,
                    count: phases.len() as u32 * 2,
                }),
                resolve: buffer(wgpu::BufferUsages::QUERY_RESOLVE | wgpu::BufferUsages::COPY_SRC),
                readback: buffer(wgpu::BufferUsages::COPY_DST | wgpu::BufferUsages::MAP_READ),
                period_ns: f64::from(gpu.queue.get_timestamp_period()),
            }
        });
        GpuTimer {
            phases,
            queries,
            written: phases.iter().map(|_| AtomicBool::new(false)).collect(),
        }
    }

    /// Whether the device takes timestamps (otherwise every phase reads `None`).
    pub fn is_enabled(&self) -> bool {
        self.queries.is_some()
    }

    /// The phase names, in frame order.
    pub fn phases(&self) -> &'static [&'static str] {
        self.phases
    }

    /// Starts a frame: no phase written yet.
    pub fn begin_frame(&self) {
        for w in &self.written {
            w.store(false, Ordering::Relaxed);
        }
    }

    /// Whether phase `i` was given writes this frame.
    fn was_written(&self, i: usize) -> bool {
        self.written[i].load(Ordering::Relaxed)
    }

    fn any_written(&self) -> bool {
        (0..self.written.len()).any(|i| self.was_written(i))
    }

    /// The query slots of `phase` (marked written), or `None` when disabled or unknown.
    fn slots(&self, phase: &str) -> Option<(&wgpu::QuerySet, u32)> {
        let index = self.phases.iter().position(|&p| p == phase);
        debug_assert!(index.is_some(), "unknown GPU timer phase {phase:?}");
        let (index, queries) = (index?, self.queries.as_ref()?);
        self.written[index].store(true, Ordering::Relaxed);
        Some((&queries.set, index as u32 * 2))
    }

    /// Timestamp writes at the beginning and end of the render pass of `phase`. Ask only when
    /// that pass is begun with them (see the module documentation).
    pub fn render_pass_writes(&self, phase: &str) -> Option<wgpu::RenderPassTimestampWrites<'_>> {
        self.slots(phase)
            .map(|(query_set, first)| wgpu::RenderPassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(first),
                end_of_pass_write_index: Some(first + 1),
            })
    }

    /// Timestamp writes at the beginning and end of the compute pass of `phase`. Ask only when
    /// that pass is begun with them.
    pub fn compute_pass_writes(&self, phase: &str) -> Option<wgpu::ComputePassTimestampWrites<'_>> {
        self.slots(phase)
            .map(|(query_set, first)| wgpu::ComputePassTimestampWrites {
                query_set,
                beginning_of_pass_write_index: Some(first),
                end_of_pass_write_index: Some(first + 1),
            })
    }

    /// Records the resolve of the written phases and the copy to the readback buffer, after the
    /// frame's last timed pass.
    pub fn resolve(&self, encoder: &mut wgpu::CommandEncoder) {
        if let Some(q) = &self.queries {
            self.resolve_to(encoder, &q.readback, 0);
        }
    }

    /// Bytes [`GpuTimer::resolve_to`] copies (0 when disabled).
    pub fn resolved_bytes(&self) -> u64 {
        self.queries
            .as_ref()
            .map_or(0, |_| self.phases.len() as u64 * PHASE_STRIDE_BYTES)
    }

    /// As [`GpuTimer::resolve`], but copies the resolved timestamps to `dst` at `offset`
    /// ([`GpuTimer::resolved_bytes`] bytes) instead of the timer's own readback buffer, so that
    /// several frames can be in flight, each with its own copy. Returns which phases this frame
    /// wrote, for [`GpuTimer::times_from`].
    pub fn resolve_to(
        &self,
        encoder: &mut wgpu::CommandEncoder,
        dst: &wgpu::Buffer,
        offset: u64,
    ) -> TimedPhases {
        let written = (0..self.phases.len())
            .map(|i| self.was_written(i))
            .collect();
        if let Some(q) = &self.queries
            && self.any_written()
        {
            for i in (0..self.phases.len()).filter(|&i| self.was_written(i)) {
                let first = i as u32 * 2;
                encoder.resolve_query_set(
                    &q.set,
                    first..first + 2,
                    &q.resolve,
                    i as u64 * PHASE_STRIDE_BYTES,
                );
            }
            encoder.copy_buffer_to_buffer(&q.resolve, 0, dst, offset, q.resolve.size());
        }
        TimedPhases { written }
    }

    /// The phase times of a frame from the bytes [`GpuTimer::resolve_to`] copied for it.
    pub fn times_from(&self, phases: &TimedPhases, bytes: &[u8]) -> GpuTimes {
        let enabled = self.queries.is_some() && phases.written.iter().any(|&w| w);
        let words: Vec<u64> = if enabled {
            bytemuck::pod_collect_to_vec(&bytes[..bytes.len() / 8 * 8])
        } else {
            Vec::new()
        };
        self.times_of(&words, |i| phases.written.get(i).copied().unwrap_or(false))
    }

    /// Phase times from resolved `words` (two per [`PHASE_STRIDE_BYTES`]), for the phases
    /// `written` says were timed.
    fn times_of(&self, words: &[u64], written: impl Fn(usize) -> bool) -> GpuTimes {
        let stride = (PHASE_STRIDE_BYTES / 8) as usize;
        let ticks: Vec<Option<(u64, u64)>> = (0..self.phases.len())
            .map(|i| {
                let at = i * stride;
                written(i)
                    .then(|| Some((*words.get(at)?, *words.get(at + 1)?)))
                    .flatten()
            })
            .collect();
        let period_ns = self.queries.as_ref().map_or(0.0, |q| q.period_ns);
        let spans = spans_from_ticks(&ticks, period_ns);
        GpuTimes {
            phases: self
                .phases
                .iter()
                .zip(spans)
                .map(|(&name, span)| PhaseTime { name, span })
                .collect(),
        }
    }

    /// The frame's phase times, after the encoder holding [`GpuTimer::resolve`] was submitted
    /// (waits for the GPU). Every phase is `None` when disabled.
    pub fn read(&self, gpu: &GpuContext) -> Result<GpuTimes, ReadbackError> {
        let none = || GpuTimes {
            phases: self
                .phases
                .iter()
                .map(|&name| PhaseTime { name, span: None })
                .collect(),
        };
        let Some(q) = &self.queries else {
            return Ok(none());
        };
        if !self.any_written() {
            return Ok(none());
        }
        let words: Vec<u64> = bytemuck::pod_collect_to_vec(&map_read(gpu, &q.readback)?);
        Ok(self.times_of(&words, |i| self.was_written(i)))
    }
}

/// Which phases of one frame were timed ([`GpuTimer::resolve_to`]).
#[derive(Debug, Clone, Default, PartialEq, Eq)]
pub struct TimedPhases {
    written: Vec<bool>,
}

/// Converts per-phase (beginning, end) ticks to spans in milliseconds since the earliest
/// beginning, with `period_ns` nanoseconds per tick. A phase whose end precedes its beginning
/// is reported as `None` (an unordered reading is no measurement), as is everything when the
/// period is not a positive finite number.
pub fn spans_from_ticks(ticks: &[Option<(u64, u64)>], period_ns: f64) -> Vec<Option<GpuSpan>> {
    let valid = |t: &Option<(u64, u64)>| t.filter(|(b, e)| e >= b);
    if !(period_ns.is_finite() && period_ns > 0.0) {
        return vec![None; ticks.len()];
    }
    let Some(origin) = ticks.iter().filter_map(valid).map(|(b, _)| b).min() else {
        return vec![None; ticks.len()];
    };
    let ms = |t: u64| (t - origin) as f64 * period_ns * 1e-6;
    ticks
        .iter()
        .map(|t| {
            valid(t).map(|(b, e)| GpuSpan {
                begin_ms: ms(b),
                end_ms: ms(e),
            })
        })
        .collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn ticks_convert_to_milliseconds_from_the_earliest_beginning() {
        let ticks = [
            Some((1_000, 3_000)),
            None,
            Some((3_500, 3_500)),
            Some((9_000, 8_000)),
        ];
        // 2.5 ns per tick.
        let spans = spans_from_ticks(&ticks, 2.5);
        assert_eq!(spans.len(), 4);
        let s0 = spans[0].expect("timed");
        assert_eq!(s0.begin_ms, 0.0);
        assert!((s0.end_ms - 2_000.0 * 2.5e-6).abs() < 1e-12);
        assert!(spans[1].is_none());
        let s2 = spans[2].expect("timed");
        assert!((s2.begin_ms - 2_500.0 * 2.5e-6).abs() < 1e-12);
        assert_eq!(s2.duration_ms(), 0.0);
        // End before beginning: no measurement.
        assert!(spans[3].is_none());
    }

    #[test]
    fn no_period_or_no_ticks_means_no_times() {
        assert_eq!(spans_from_ticks(&[Some((1, 2))], 0.0), vec![None]);
        assert_eq!(spans_from_ticks(&[Some((1, 2))], f64::NAN), vec![None]);
        assert_eq!(spans_from_ticks(&[None, None], 1.0), vec![None, None]);
    }

    #[test]
    fn totals_sum_the_timed_phases() {
        let span = |begin_ms, end_ms| Some(GpuSpan { begin_ms, end_ms });
        let times = GpuTimes {
            phases: vec![
                PhaseTime {
                    name: "early",
                    span: span(0.0, 1.5),
                },
                PhaseTime {
                    name: "occluders",
                    span: None,
                },
                PhaseTime {
                    name: "late",
                    span: span(2.0, 2.25),
                },
            ],
        };
        assert_eq!(times.phase_ms("early"), Some(1.5));
        assert_eq!(times.phase_ms("occluders"), None);
        assert_eq!(times.phase_ms("nope"), None);
        assert_eq!(times.total_ms(), Some(1.75));
        assert_eq!(
            times.timed().map(|(n, _)| n).collect::<Vec<_>>(),
            ["early", "late"]
        );
        let untimed = GpuTimes {
            phases: vec![PhaseTime {
                name: "early",
                span: None,
            }],
        };
        assert_eq!(untimed.total_ms(), None);
        assert_eq!(GpuTimes::default().total_ms(), None);
    }
}
