//! Settings of `vtex serve`. Each one comes from its flag, else its environment variable,
//! else its default — one precedence for all, implemented by clap.

use crate::transport::Transport;
use clap::Args;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;

/// Tile sizes the server accepts: a tile must encode in milliseconds and fit every format.
pub const TILE_SIZES: std::ops::RangeInclusive<u32> = 16..=2048;
/// Region requests are bounded in area; at least 4096 × 4096 must stay allowed.
pub const DEFAULT_MAX_REGION_PIXELS: u64 = 4096 * 4096;
/// Longest side of a region: WebP cannot encode more than 16383 pixels a side.
pub const MAX_REGION_SIDE: u32 = 16383;

#[derive(Args, Clone, Debug)]
pub struct ServeConfig {
    /// Address to listen on; port 0 picks a free one (the chosen address is printed).
    #[arg(long, env = "VTEX_BIND", default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,
    /// Directory of content-addressed bundles (`<id>.vtex`); created if missing.
    #[arg(long, env = "VTEX_DATA_DIR", default_value = "./vtex-data")]
    pub data_dir: PathBuf,
    /// Byte budget of the encoded-tile cache, in MiB (fractions allowed).
    #[arg(long, env = "VTEX_CACHE_MB", default_value_t = 512.0)]
    pub cache_mb: f64,
    /// Directory of the static viewer, served at `/`.
    #[arg(long, env = "VTEX_WEB_DIR", default_value = "client-web/dist")]
    pub web_dir: PathBuf,
    /// Tile side in pixels (16..=2048).
    #[arg(long, env = "VTEX_TILE_SIZE", default_value_t = 256)]
    pub tile_size: u32,
    /// Syntheses running at once; further misses wait (back-pressure). Default: CPU count.
    #[arg(long, env = "VTEX_MAX_SYNTHESES")]
    pub max_syntheses: Option<usize>,
    /// Largest accepted request body (uploads, patches), in MiB.
    #[arg(long, env = "VTEX_MAX_UPLOAD_MB", default_value_t = 64.0)]
    pub max_upload_mb: f64,
    /// Largest region request, in pixels (w × h).
    #[arg(long, env = "VTEX_MAX_REGION_PIXELS", default_value_t = DEFAULT_MAX_REGION_PIXELS)]
    pub max_region_pixels: u64,
    /// Whole-request deadline in seconds (reading the body included): slow clients get 408.
    #[arg(long, env = "VTEX_REQUEST_TIMEOUT_SECS", default_value_t = 30.0)]
    pub request_timeout_secs: f64,
    /// Deadline for a client to send its request headers; the connection is closed after it.
    #[arg(long, env = "VTEX_HEADER_TIMEOUT_SECS", default_value_t = 10.0)]
    pub header_timeout_secs: f64,
    /// Threads serving connections, one single-threaded runtime each. Default: CPU count.
    #[arg(long, env = "VTEX_IO_THREADS")]
    pub io_threads: Option<usize>,
    /// How tile bodies reach the socket: `copy` (portable: written from the heap) or `splice`
    /// (Linux: cached tiles sent by page reference, like nginx's sendfile). Default: `splice`
    /// on Linux, `copy` elsewhere.
    #[arg(long, env = "VTEX_SEND", default_value_t = Transport::default())]
    pub send: Transport,
    /// Do not write the demo textures into an empty data directory.
    #[arg(long, env = "VTEX_NO_DEMOS")]
    pub no_demos: bool,
    /// Syntheses one texture may run at once, so that its misses, however slow, leave slots
    /// to the others. Default: all slots but one (one when there is one slot).
    #[arg(long, env = "VTEX_MAX_SYNTHESES_PER_TEXTURE")]
    pub max_syntheses_per_texture: Option<usize>,
    /// Misses waiting for a synthesis slot; one more is answered 503 at once. Default:
    /// [`QUEUED_PER_SLOT`] per slot.
    #[arg(long, env = "VTEX_MAX_QUEUED")]
    pub max_queued: Option<usize>,
}

/// Misses queued per synthesis slot by default: an ordinary tile renders in milliseconds, so a
/// full queue drains within a second or so, and a burst of every connection of a busy viewer
/// missing at once is absorbed; a queue longer than that would only be answered near or past
/// the request deadline, where a prompt 503 serves the client better.
pub const QUEUED_PER_SLOT: usize = 32;

impl ServeConfig {
    /// Checks ranges clap cannot express; the message names the setting.
    pub fn validate(&self) -> Result<(), String> {
        if !TILE_SIZES.contains(&self.tile_size) {
            return Err(format!(
                "tile size {} is outside {}..={}",
                self.tile_size,
                TILE_SIZES.start(),
                TILE_SIZES.end()
            ));
        }
        let positive = |v: f64, name: &str| {
            if v.is_finite() && v > 0.0 {
                Ok(())
            } else {
                Err(format!("{name} must be a positive number, got {v}"))
            }
        };
        positive(self.cache_mb, "cache-mb")?;
        positive(self.max_upload_mb, "max-upload-mb")?;
        positive(self.request_timeout_secs, "request-timeout-secs")?;
        positive(self.header_timeout_secs, "header-timeout-secs")?;
        if self.max_region_pixels < self.tile_size as u64 * self.tile_size as u64 {
            return Err("max-region-pixels must allow at least one tile".into());
        }
        if self.max_syntheses == Some(0) {
            return Err("max-syntheses must be at least 1".into());
        }
        if self.max_syntheses_per_texture.is_some_and(|n| n == 0 || n > self.syntheses()) {
            return Err(format!("max-syntheses-per-texture must be 1..={} (max-syntheses)", self.syntheses()));
        }
        if self.io_threads == Some(0) {
            return Err("io-threads must be at least 1".into());
        }
        Ok(())
    }

    pub fn cache_bytes(&self) -> u64 {
        (self.cache_mb * 1024.0 * 1024.0) as u64
    }

    pub fn max_upload_bytes(&self) -> usize {
        (self.max_upload_mb * 1024.0 * 1024.0) as usize
    }

    pub fn syntheses(&self) -> usize {
        self.max_syntheses.unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()))
    }

    /// Syntheses one texture may run at once.
    pub fn syntheses_per_texture(&self) -> usize {
        self.max_syntheses_per_texture.unwrap_or_else(|| self.syntheses().saturating_sub(1).max(1))
    }

    /// Misses that may wait for a synthesis slot.
    pub fn max_queued(&self) -> usize {
        self.max_queued.unwrap_or_else(|| QUEUED_PER_SLOT * self.syntheses())
    }

    /// Threads serving connections, one single-threaded runtime each: one per core by default.
    pub fn io_threads(&self) -> usize {
        self.io_threads.unwrap_or_else(|| std::thread::available_parallelism().map_or(2, |n| n.get()))
    }

    pub fn request_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.request_timeout_secs)
    }

    pub fn header_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.header_timeout_secs)
    }
}
