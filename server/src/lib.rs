//! vtex-server: serves virtual textures over HTTP.
//!
//! Data flows one way: request → [`cache`] lookup → (miss) model render → [`encode`] →
//! cache → response. The server never knows how a model works; it only calls
//! [`vtex_synth::Texture::render`] on regions it has validated.
//!
//! * [`config`] — settings of `vtex serve` (flags beat environment beat defaults).
//! * [`store`] — the data directory of content-addressed bundles, written atomically.
//! * [`cache`] — the sharded, byte-bounded tile LRU with coalesced misses.
//! * [`encode`] — tile formats (PNG, WebP, JPEG, raw RGBA).
//! * [`ktx2`] — GPU-ready pages: BC7, BC1 or RGBA8 in KTX2, optionally zstd-supercompressed.
//! * [`metrics`] — Prometheus counters, gauges and histograms.
//! * [`api`] — the HTTP API v1 (axum).
//! * [`slots`] — synthesis slots shared fairly between textures, with a bounded queue.
//! * [`inflight`] — the byte budget of response bodies in flight.
//! * [`serve`] — the listener: connection timeouts and graceful shutdown.
//! * [`transport`] — how bodies reach the socket (`--send copy|splice`); all platform-specific code.
//! * [`watch`] — follows bundles other processes add to or delete from the data directory.
//! * [`cli`] — the offline subcommands `create`, `models`, `render`, `info`, `export-web`.
//! * [`probe`] — `vtex health`: a running server's readiness, for container health checks.
//! * [`export`] — `export-web`: the viewer, the synthesis module and an encoding as a static folder.

// Unsafe code is denied in every module but `transport`, which holds the mappings and system
// calls no safe crate covers (`forbid` could not be relaxed for that one module).
#![deny(unsafe_code)]

pub mod api;
pub mod cache;
pub mod cli;
pub mod config;
pub mod encode;
pub mod export;
pub mod inflight;
pub mod ktx2;
pub mod metrics;
pub mod probe;
pub mod serve;
pub mod slots;
pub mod store;
#[allow(unsafe_code)]
pub mod transport;
pub mod watch;
