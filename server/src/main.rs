//! The `vtex` binary. Logs go to stderr (filter with `VTEX_LOG` or `RUST_LOG`, default `info`;
//! coloured only on a terminal, and never with `NO_COLOR` set); stdout carries only command
//! results and the `vtex listening on …` line. A failure prints one line, `error: …`, and
//! exits 1.

#![deny(unsafe_code)]

mod allocator;

use clap::Parser;
use std::io::IsTerminal;
use std::process::ExitCode;
use tracing_subscriber::EnvFilter;
use vtex_server::cli::{self, Cli, Command};

fn main() -> ExitCode {
    allocator::init();
    let filter = EnvFilter::try_from_env("VTEX_LOG")
        .or_else(|_| EnvFilter::try_from_default_env())
        .unwrap_or_else(|_| EnvFilter::new("info"));
    tracing_subscriber::fmt().with_env_filter(filter).with_writer(std::io::stderr).with_ansi(colour()).init();
    let done = match Cli::parse().command {
        Command::Serve(cfg) => vtex_server::serve::main(*cfg),
        Command::Create(args) => cli::create(args),
        Command::Models(args) => cli::models(args),
        Command::Render(args) => cli::render(args),
        Command::Info(args) => cli::info(args),
        Command::ExportWeb(args) => cli::export_web(args),
        Command::Health(args) => vtex_server::probe::health(args),
    };
    match done {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            // The causes on one line; never a backtrace, whatever RUST_BACKTRACE says.
            eprintln!("error: {e:#}");
            ExitCode::FAILURE
        }
    }
}

/// Colours are for a person at a terminal: not in a log file or a pipe, nor when `NO_COLOR` is
/// set to anything (no-color.org).
fn colour() -> bool {
    std::io::stderr().is_terminal() && std::env::var_os("NO_COLOR").is_none_or(|v| v.is_empty())
}
