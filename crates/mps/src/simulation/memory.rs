//! How the process's allocator keeps memory between steps (docs/decisions.md, "The PPE
//! assembled in place").

use std::sync::Once;

/// Largest block (bytes) glibc serves from its heap rather than from a fresh mapping: its own
/// upper bound for the dynamic threshold (32 MiB on 64-bit).
#[cfg(all(target_os = "linux", target_env = "gnu"))]
const MMAP_THRESHOLD: i32 = 32 << 20;

static KEEP: Once = Once::new();

/// Asks glibc, once per process, to keep freed heap memory instead of handing it back to the
/// system: a step frees and allocates the same large vectors every time, and an arena that
/// hands a freed block back faults it in again on the next step (133 000 page faults in 300
/// steps of `bench_dam_break` against 2 100). Sets the trim threshold out of reach and fixes
/// the mmap threshold at glibc's own upper bound (setting either turns glibc's dynamic
/// adjustment of both off). Also keeps one arena for all threads: a worker's own arena held
/// its freed buffers beside the main one's (the 1M-particle ladder rung peaked at 1.26 kB
/// per particle on 2 threads against 1.13 with one arena; the step allocates nothing, so
/// the arena's lock is not contended: docs/decisions.md, "One malloc arena"). Does nothing
/// on other platforms.
pub fn keep_freed_memory() {
    KEEP.call_once(|| {
        #[cfg(all(target_os = "linux", target_env = "gnu"))]
        // SAFETY: mallopt only sets allocator parameters, under glibc's own lock.
        unsafe {
            libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
            libc::mallopt(libc::M_TRIM_THRESHOLD, i32::MAX);
            libc::mallopt(libc::M_ARENA_MAX, 1);
        }
    });
}

/// Hands the heap's freed memory back to the system now (glibc's `malloc_trim`), so that a
/// measurement of peak resident memory that starts here does not count what an earlier run
/// in the same process freed and [`keep_freed_memory`] kept. Does nothing on other platforms.
pub fn release_freed_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only returns free heap pages, under glibc's own lock.
    unsafe {
        libc::malloc_trim(0);
    }
}
