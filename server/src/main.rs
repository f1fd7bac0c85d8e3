//! The `vtex` binary. Logs go to stderr (filter with `VTEX_LOG` or `RUST_LOG`, default
//! `info`); stdout carries only command results and the `vtex listening on …` line.

#![forbid(unsafe_code)]

use clap::Parser;
use tracing_subscriber::EnvFilter;
use vtex_server::cli::{self, Cli, Command};

fn main() -> anyhow::Result<()> {
    vtex_server::transport::tune_allocator();
    let filter = EnvFilter::try_from_env("VTEX_LOG")
        .or_else(|_| EnvFilter::try_from_default_env())
        .unwrap_or_else(|_| EnvFilter::new("info"));
    tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).init();
    match Cli::parse().command {
        Command::Serve(cfg) => vtex_server::serve::main(*cfg),
        Command::Create(args) => cli::create(args),
        Command::Models(args) => cli::models(args),
        Command::Render(args) => cli::render(args),
        Command::Info(args) => cli::info(args),
        Command::ExportWeb(args) => cli::export_web(args),
        Command::Health(args) => vtex_server::probe::health(args),
    }
}
