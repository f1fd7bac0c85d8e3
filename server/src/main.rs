//! The `vtex` binary. Logs go to stderr (filter with `VTEX_LOG` or `RUST_LOG`, default
//! `info`); stdout carries only command results and the `vtex listening on …` line.

use clap::Parser;
use tracing_subscriber::EnvFilter;
use vtex_server::cli::{self, Cli, Command};

/// mimalloc: a warm tile request makes a few dozen small allocations (request, header maps,
/// futures); glibc's malloc spent 14 % of the server's CPU on them, much of it in
/// `malloc_consolidate` (perf, BENCHMARKS.md). Cached tiles are not on this heap at all: each
/// is its own mapping (`zerocopy::seal`), returned to the OS when evicted.
#[global_allocator]
static GLOBAL: mimalloc::MiMalloc = mimalloc::MiMalloc;

fn main() -> anyhow::Result<()> {
    let filter = EnvFilter::try_from_env("VTEX_LOG")
        .or_else(|_| EnvFilter::try_from_default_env())
        .unwrap_or_else(|_| EnvFilter::new("info"));
    tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).init();
    match Cli::parse().command {
        Command::Serve(cfg) => tokio::runtime::Builder::new_multi_thread()
            .enable_all()
            .build()?
            .block_on(vtex_server::serve::run(cfg, vtex_server::serve::shutdown_signal())),
        Command::Create(args) => cli::create(args),
        Command::Render(args) => cli::render(args),
        Command::Info(args) => cli::info(args),
    }
}
