//! The HTTP API, tested against servers in this process over real sockets: one binary, built
//! and linked once. What needs the real `vtex` process is in `tests/process/`.

#[path = "../support/mod.rs"]
mod support;

mod api;
mod batch;
mod consistency;
mod hostile;
mod http;
mod iiif;
mod inflight_bounds;
mod interop;
mod ktx2_spec;
mod layers;
mod metatiles;
mod metrics;
mod models;
mod openapi;
mod pages;
mod patterns;
mod recipes;
mod store_bounds;
