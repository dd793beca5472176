//! The process's allocator, and the one call that asks it to give freed memory back.

/// mimalloc instead of glibc's allocator: preprocessing allocates and frees millions of small
/// rings, vectors and strings, and a sixth of its time was in glibc's malloc and free; with
/// mimalloc the generated 1M city preprocesses in 104 s instead of 143 s, for 3 % more peak
/// memory (BENCHMARKS.md "The allocator").
#[global_allocator]
static ALLOCATOR: mimalloc::MiMalloc = mimalloc::MiMalloc;

/// Gives the memory freed on every thread back to the system. mimalloc keeps a thread's freed
/// pages for that thread's next allocations and returns them only when the thread allocates
/// again: after preprocessing's parallel phases, the worker threads' freed working memory
/// stayed resident while the main thread went on alone (a quarter of a gigabyte while the
/// cluster tree's tiles were joined at a million buildings). The collection is forced (pages
/// returned now, not after mimalloc's purge delay): unforced, the raw polygons the load freed
/// stayed resident into the stages (100k buildings: 195 MiB after the load, 98 forced).
#[expect(
    unsafe_code,
    reason = "mi_collect is a plain C call into the allocator that serves this process"
)]
pub fn give_back_freed_memory() {
    // SAFETY: mi_collect takes no pointers and may be called from any thread at any time.
    let collect = || unsafe { libmimalloc_sys::mi_collect(true) };
    rayon::broadcast(|_| collect());
    collect();
}
