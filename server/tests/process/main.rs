//! What needs the real `vtex` binary as a process: the command line, signals and exit codes,
//! the log, process limits and network namespaces, connection bounds, several processes on one
//! data directory. The one test binary `scripts/test` runs under both transports
//! (`VTEX_SEND=splice`, then `copy`).

#[path = "../support/mod.rs"]
mod support;

mod api;
mod cli;
mod connection_bounds;
mod consistency;
mod export_web;
mod hostile;
mod http;
mod metrics;
mod models;
mod shared_store;
mod store_bounds;
mod synthesis_bounds;
mod writes;
