//! How the one-shot `cliffwatch adjust` asks glibc's malloc to grow its heaps.

/// Bytes by which malloc grows a heap beyond a request (`M_TOP_PAD`; glibc's default is 128 KiB).
/// With the default, the rayon workers' heaps grow one `mprotect` of a few KiB at a time (609
/// calls for the 20 × 500 network); with 16 MiB, 12. Address space only: pages become resident
/// when touched.
const TOP_PAD_BYTES: i32 = 16 << 20;

/// Lets every malloc heap of this process grow [`TOP_PAD_BYTES`] at a time. For a short-lived
/// command that allocates its working set once (`cliffwatch adjust` of the 20 × 500 network: 2 ms,
/// 3 % less as a whole process, `docs/performance.md`), not for the daemon, whose heaps would then
/// keep up to that much each after their peak. Call it before any other thread starts.
pub fn grow_heaps_in_large_steps() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt sets one of malloc's parameters and touches no memory of ours; glibc
    // serialises it with the allocator.
    unsafe {
        libc::mallopt(libc::M_TOP_PAD, TOP_PAD_BYTES);
    }
}
