//! The `vtex` binary. Logs go to stderr (filter with `VTEX_LOG` or `RUST_LOG`, default
//! `info`); stdout carries only command results and the `vtex listening on …` line.

use clap::Parser;
use tracing_subscriber::EnvFilter;
use vtex_server::cli::{self, Cli, Command};

/// Encoding makes 64 KiB–1 MiB buffers (pixels, the encoded tile before `zerocopy::seal`
/// copies it into an arena). Taken from glibc's heap, buffers of this size fragment
/// it: after a long pan with a 256 MiB cache the process once held 605 MiB resident
/// (BENCHMARKS.md). Served by mmap instead, each returns to the OS when freed: ~300 MiB
/// resident for 255 MiB cached. (mimalloc was tried for the warm path: no measurable gain
/// once tile GETs skip the router, and ~100 MiB more resident after the same pan.)
#[cfg(all(target_os = "linux", target_env = "gnu"))]
fn tune_allocator() {
    // SAFETY: mallopt only sets an allocator parameter; called before any thread exists.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 64 * 1024);
    }
}

#[cfg(not(all(target_os = "linux", target_env = "gnu")))]
fn tune_allocator() {}

fn main() -> anyhow::Result<()> {
    tune_allocator();
    let filter = EnvFilter::try_from_env("VTEX_LOG")
        .or_else(|_| EnvFilter::try_from_default_env())
        .unwrap_or_else(|_| EnvFilter::new("info"));
    tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).init();
    match Cli::parse().command {
        Command::Serve(cfg) => tokio::runtime::Builder::new_current_thread()
            .enable_all()
            .build()?
            .block_on(vtex_server::serve::run(cfg, vtex_server::serve::shutdown_signal())),
        Command::Create(args) => cli::create(args),
        Command::Render(args) => cli::render(args),
        Command::Info(args) => cli::info(args),
    }
}
