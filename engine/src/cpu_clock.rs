//! The CPU time the calling thread spends, not wall time: what a frame's own code costs,
//! without the time it waits for the GPU or is preempted.

use cpu_time::ThreadTime;

/// Thread CPU time since [`CpuClock::start`].
#[derive(Debug, Clone, Copy)]
pub struct CpuClock(ThreadTime);

impl CpuClock {
    pub fn start() -> CpuClock {
        CpuClock(ThreadTime::now())
    }

    /// CPU time of this thread since the start (ms).
    pub fn elapsed_ms(&self) -> f64 {
        self.0.elapsed().as_secs_f64() * 1e3
    }
}
