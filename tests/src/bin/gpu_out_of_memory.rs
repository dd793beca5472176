//! Runs a real GPU out of memory (issue 14), for `tests/gpu_faults.rs`: after a first upload,
//! the process's address space is capped a little above what it uses, so that the driver's next
//! large allocation fails as it would on a GPU whose memory is spent (on a software adapter GPU
//! memory is host memory). Prints the upload's error, then lifts the cap and uploads again: the
//! device must still work.
//!
//! Exit codes: 0 when it ran (the output says what happened), 2 without a GPU.

use std::process::ExitCode;

use citywalk_runtime::gpu::GpuContext;
use citywalk_runtime::upload::{array_buffer, buffer_from_chunks};
use rustix::process::{Resource, Rlimit, getrlimit, setrlimit};

/// What the process may still map once capped: room for wgpu's and the driver's small
/// allocations, far under [`TOO_LARGE_BYTES`].
const HEADROOM_BYTES: u64 = 64 << 20;

/// The array that no longer fits.
const TOO_LARGE_BYTES: usize = 512 << 20;

fn main() -> ExitCode {
    let gpu = match GpuContext::headless() {
        Ok(gpu) => gpu,
        Err(e) => {
            eprintln!("no GPU context: {e}");
            return ExitCode::from(2);
        }
    };
    let usage = wgpu::BufferUsages::VERTEX;
    // The driver's pools and threads exist before the cap.
    let warm_up = array_buffer(&gpu, "warm-up vertices", &[0u32; 4096], usage, &|_| {});
    println!("warm-up: {}", outcome(&warm_up));
    let Some(used) = virtual_size_bytes() else {
        eprintln!("no VmSize in /proc/self/status");
        return ExitCode::FAILURE;
    };
    let uncapped = getrlimit(Resource::As);
    let cap = Rlimit {
        current: Some(used + HEADROOM_BYTES),
        maximum: uncapped.maximum,
    };
    if let Err(e) = setrlimit(Resource::As, cap) {
        eprintln!("cannot cap the address space: {e}");
        return ExitCode::FAILURE;
    }
    let too_large = buffer_from_chunks(&gpu, "probe vertices", TOO_LARGE_BYTES, usage, |_, _| {});
    println!("capped: {}", outcome(&too_large));
    drop(too_large);
    if let Err(e) = setrlimit(Resource::As, uncapped) {
        eprintln!("cannot lift the cap: {e}");
        return ExitCode::FAILURE;
    }
    let after = array_buffer(&gpu, "later vertices", &[1u32; 4096], usage, &|_| {});
    println!("after: {}", outcome(&after));
    ExitCode::SUCCESS
}

fn outcome<E: std::fmt::Display>(result: &Result<wgpu::Buffer, E>) -> String {
    match result {
        Ok(_) => "uploaded".to_owned(),
        Err(e) => format!("error: {e}"),
    }
}

/// The process's mapped address space (`VmSize`), which `RLIMIT_AS` caps.
fn virtual_size_bytes() -> Option<u64> {
    let status = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = status.lines().find(|l| l.starts_with("VmSize:"))?;
    let kib: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kib * 1024)
}
