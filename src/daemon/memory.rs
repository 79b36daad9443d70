//! The daemon's use of the C allocator: set once at start so that a long run stays at the size
//! its work needs, and trimmed after bursts of clients.
//!
//! glibc's malloc raises its mmap threshold each time a block it had mapped is freed, up to
//! 32 MiB: after the first sweep's buffers or a hostile client's long line, blocks of a few
//! hundred kilobytes to megabytes come from the arenas instead, and the arenas keep what is
//! freed between the small blocks that stay in use. A soak run's heap never held more than
//! 12 MB (heaptrack), yet the resident size stepped up after each burst of clients and grew by
//! 100-120 KB a minute over an hour. Fixed thresholds keep large blocks mapped (returned to the
//! system when freed), and few arenas keep the fragments of the blocking pool's threads in few
//! places.

/// Blocks at least this large are mapped on their own and unmapped when freed (bytes).
const MMAP_THRESHOLD: i32 = 128 << 10;
/// Free memory at the top of an arena beyond this is returned at once (bytes).
const TRIM_THRESHOLD: i32 = 256 << 10;
/// Arenas the allocator may create: the runtime's workers and the detections on the blocking
/// pool share them (glibc's default is 8 a core).
const ARENA_MAX: i32 = 4;

/// Fixes the allocator's thresholds. Call before any thread is started.
pub fn tune_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only changes the allocator's parameters; it is called before the
    // runtime's threads exist.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, MMAP_THRESHOLD);
        libc::mallopt(libc::M_TRIM_THRESHOLD, TRIM_THRESHOLD);
        libc::mallopt(libc::M_ARENA_MAX, ARENA_MAX);
    }
}

/// Returns the heap's free pages to the system. The clients' tasks and queues free what they
/// held in whichever arena their thread used, between blocks that stay in use; without this
/// the daemon stays at the size its busiest moment took.
pub(crate) fn give_back_memory() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free memory of the allocator's own arenas.
    unsafe {
        libc::malloc_trim(0);
    }
}
