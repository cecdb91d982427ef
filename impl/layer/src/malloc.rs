//! The C allocator's arenas, limited to one per process on glibc.
//!
//! glibc gives each thread that allocates while another holds the main arena an arena of its
//! own (up to eight per core), and each keeps what it once held: a controller with its
//! network monitor runs three DDS participants, each with an event-loop and a discovery
//! thread, and measured 28.6 MB resident, 20.7 MB of it anonymous, against 16.2 MB and 8.4 MB
//! with one arena (docs/performance.md, "Resources"). RL allocates at a few hundred samples a
//! second, far below where one arena's lock would cost anything. musl (the Raspberry Pi
//! build) has no per-thread arenas, so there is nothing to limit there.

/// Limits glibc's malloc to one arena. Call first thing in `main`, before any thread starts:
/// arenas made before stay. Returns false if glibc refused; true elsewhere (nothing to do).
pub fn limit_arenas() -> bool {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    {
        // SAFETY: mallopt only sets an allocator parameter; it touches no memory of ours, and
        // before any other thread exists nothing allocates concurrently.
        unsafe { libc::mallopt(libc::M_ARENA_MAX, 1) == 1 }
    }
    #[cfg(not(all(target_os = "linux", target_env = "gnu")))]
    {
        true
    }
}
