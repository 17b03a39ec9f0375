//! Keeping the server's resident memory near what it holds. A render allocates hundreds of
//! megabytes for a moment; glibc's allocator keeps what is freed in per-thread arenas (up to
//! eight per core) and hands little of it back, so after a burst of cold tiles the process
//! would stay several times larger than its caches. Fewer arenas, and the free memory at the
//! top of each handed back after every render, keep it down.

/// Arenas the allocator may make (glibc's default is eight per core).
const ARENAS: i32 = 2;

/// Limits the allocator's arenas; call once at start, before the render threads exist.
pub fn limit_arenas() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets a tunable of the allocator; M_ARENA_MAX takes any count.
    unsafe {
        libc::mallopt(libc::M_ARENA_MAX, ARENAS);
    }
}

/// Hands the allocator's free memory back to the system (after a render freed its buffers).
pub fn give_back() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: malloc_trim only releases free pages of the allocator's own heaps.
    unsafe {
        libc::malloc_trim(0);
    }
}
