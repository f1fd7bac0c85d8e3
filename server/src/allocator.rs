//! The `vtex` binary's allocator: jemalloc with the `jemalloc` feature (the default) on Linux,
//! else the system's, tuned by [`vtex_server::transport::tune_allocator`].
//!
//! Why: a server whose budgets are full frees and allocates buffers of every size from many
//! threads. glibc's malloc keeps what is freed in per-thread arenas, and the soak's RSS passed
//! its budgets + 20 % (BENCHMARKS.md, "Bounds under load"); jemalloc hands freed pages back to
//! the system within a second, from a background thread. The library and its in-process tests
//! keep the system allocator, so both are tested.

#[cfg(all(feature = "jemalloc", target_os = "linux"))]
#[global_allocator]
static JEMALLOC: tikv_jemallocator::Jemalloc = tikv_jemallocator::Jemalloc;

/// jemalloc's options, read at its first allocation (`_RJEM_MALLOC_CONF` overrides them): pages
/// freed for a second are returned (not kept for the default 10 s), by a background thread so
/// that no request pays for it.
// Unsafe in that the name must be the one jemalloc reads, as a C string (a thin pointer to
// NUL-terminated bytes, which `&[u8; N]` is).
#[cfg(all(feature = "jemalloc", target_os = "linux"))]
#[allow(non_upper_case_globals, unsafe_code)]
#[export_name = "_rjem_malloc_conf"]
static malloc_conf: &[u8; 60] = b"background_thread:true,dirty_decay_ms:1000,muzzy_decay_ms:0\0";

/// Sets up the allocator, before anything else runs.
pub fn init() {
    #[cfg(not(all(feature = "jemalloc", target_os = "linux")))]
    vtex_server::transport::tune_allocator();
}
