//! vtex-server: serves virtual textures over HTTP.
//!
//! Data flows one way: request → [`api`] → [`engine`]: texture lookup, the tile cache, (on a
//! miss) the model's render → [`encode`] → cache → response. The server never knows how a
//! model works; it only calls [`vtex_synth::Texture::render`] on regions it has validated.
//!
//! * [`config`] — settings of `vtex serve` (flags beat environment beat defaults).
//! * [`store`] — the data directory of content-addressed bundles, written atomically.
//! * [`byte_lru`] — the byte-weighed LRU under the tile cache and the store's loaded textures.
//! * [`engine`] — what is served, below HTTP: texture lookup, tile and page addressing and
//!   ETags, the sharded, byte-bounded tile LRU with coalesced misses, synthesis in bounded
//!   slots.
//! * [`encode`] — tile formats (PNG, WebP, JPEG, raw RGBA).
//! * [`ktx2`] — GPU-ready pages: BC7, BC1 or RGBA8 in KTX2, optionally zstd-supercompressed.
//! * [`metrics`] — Prometheus counters, gauges and histograms.
//! * [`api`] — the HTTP API v1 (axum).
//! * [`serve`] — the listener: connections, their timeouts and graceful shutdown, head checks,
//!   the fast path of warm tiles, the access log.
//! * [`transport`] — how bodies reach the socket (`--send copy|splice`); all platform-specific code.
//! * [`watch`] — follows bundles other processes add to or delete from the data directory.
//! * [`catalogue`] — every model's parameters, inputs and example, for the API and the CLI.
//! * [`cli`] — the offline subcommands `create`, `models`, `render`, `info`, `export-web`.
//! * [`probe`] — `vtex health`: a running server's readiness, for container health checks.
//! * [`export`] — `export-web`: the viewer, the synthesis module and an encoding as a static folder.

// Unsafe code is denied in every module but `transport`, which holds the mappings and system
// calls no safe crate covers (`forbid` could not be relaxed for that one module), and the one
// call into basisu (`ktx2::basis::encode`), whose crate marks its encoding functions unsafe.
#![deny(unsafe_code)]

pub mod api;
pub mod byte_lru;
pub mod catalogue;
pub mod cli;
pub mod config;
pub mod encode;
pub mod engine;
pub mod export;
pub mod ktx2;
pub mod metrics;
pub mod probe;
pub mod serve;
pub mod store;
#[allow(unsafe_code)]
pub mod transport;
pub mod watch;

#[cfg(test)]
mod tests {
    use std::path::{Path, PathBuf};

    /// The source files of `dir` (or the file itself), recursively.
    fn sources(path: &Path) -> Vec<PathBuf> {
        if path.is_file() {
            return vec![path.to_path_buf()];
        }
        std::fs::read_dir(path).unwrap().flat_map(|e| sources(&e.unwrap().path())).collect()
    }

    /// The floors below the API — the engine, the store, the catalogue and what they use, and
    /// the offline commands — name no HTTP type and nothing of the API or the listener.
    #[test]
    fn the_floors_below_the_api_know_no_http() {
        let src = Path::new(env!("CARGO_MANIFEST_DIR")).join("src");
        let floors = [
            "engine",
            "store",
            "byte_lru.rs",
            "catalogue.rs",
            "config.rs",
            "encode.rs",
            "ktx2.rs",
            "metrics.rs",
            "watch.rs",
            "cli.rs",
            "export.rs",
        ];
        let mut found = Vec::new();
        for file in floors.iter().flat_map(|f| sources(&src.join(f))) {
            let text = std::fs::read_to_string(&file).unwrap();
            for (n, line) in text.lines().enumerate().filter(|(_, l)| !l.trim_start().starts_with("//")) {
                for word in ["axum", "hyper", "http::", "crate::api", "crate::serve"] {
                    if line.contains(word) {
                        found.push(format!("{}:{}: {word}", file.display(), n + 1));
                    }
                }
            }
        }
        assert!(found.is_empty(), "{found:#?}");
    }
}
