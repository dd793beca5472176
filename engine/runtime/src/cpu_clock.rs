//! The engine's own CPU time: thread CPU time (`CLOCK_THREAD_CPUTIME_ID` on Unix), not wall
//! time, so that a wait for the GPU, a sleep or another process taking the core is not
//! counted as frame work. The benchmark's `cpu_ms` and the frame's `FrameStats::cpu_ms` both
//! read this clock, so the two mean the same thing.

use cpu_time::ThreadTime;

/// A running CPU-time clock of the calling thread. Not `Send`: a reading taken on another
/// thread would measure that thread.
#[derive(Debug, Clone, Copy)]
pub struct CpuClock(ThreadTime);

impl CpuClock {
    /// Starts the clock at the calling thread's CPU time now.
    ///
    /// # Panics
    ///
    /// If the OS has no per-thread CPU clock (Linux has had one since 2.6.12, macOS since 10.12).
    pub fn start() -> Self {
        Self(ThreadTime::now())
    }

    /// CPU time this thread has used since [`CpuClock::start`], in milliseconds.
    pub fn elapsed_ms(&self) -> f64 {
        self.0.elapsed().as_secs_f64() * 1e3
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::{Duration, Instant};

    #[test]
    fn counts_work_but_not_sleep() {
        let clock = CpuClock::start();
        std::thread::sleep(Duration::from_millis(60));
        let slept_ms = clock.elapsed_ms();
        // Sleeping costs next to no CPU: far less than the 60 ms of wall time.
        assert!(slept_ms < 30.0, "sleep counted as {slept_ms} ms of CPU");

        let clock = CpuClock::start();
        let wall = Instant::now();
        let mut x = 0u64;
        while wall.elapsed() < Duration::from_millis(40) {
            x = std::hint::black_box(x.wrapping_mul(6364136223846793005).wrapping_add(1));
        }
        let busy_ms = clock.elapsed_ms();
        // A busy loop is CPU time; on a shared core it may get less than its wall time, but
        // not nothing.
        assert!(busy_ms > 5.0, "40 ms busy loop counted as {busy_ms} ms");
        assert!(busy_ms <= wall.elapsed().as_secs_f64() * 1e3 + 1.0);
    }
}
