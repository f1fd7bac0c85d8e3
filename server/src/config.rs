//! Settings of `vtex serve`. Each one comes from its flag, else its environment variable,
//! else its default — one precedence for all, implemented by clap.

use crate::api::origin::{PublicUrl, TrustedProxy};
use crate::encode::Format;
use crate::store::Bounds;
use crate::transport::{SendLimits, Transport};
pub use crate::watch::WatchMode;
use clap::Args;
use std::net::SocketAddr;
use std::path::PathBuf;
use std::time::Duration;
use vtex_synth::models::Limits;

/// Tile sizes the server accepts: a tile must encode in milliseconds and fit every format.
pub const TILE_SIZES: std::ops::RangeInclusive<u32> = 16..=2048;
/// Region requests are bounded in area; at least 4096 × 4096 must stay allowed.
pub const DEFAULT_MAX_REGION_PIXELS: u64 = 4096 * 4096;
/// Longest side of a region: WebP cannot encode more than 16383 pixels a side.
pub const MAX_REGION_SIDE: u32 = 16383;
/// Descriptors kept back from connections: standard streams, the listener, each runtime's
/// poller and wake-up descriptors, bundle and static files being read or written, and the
/// refusals of connections over the limit being answered.
pub const FD_RESERVE: u64 = 64;
/// The open-file limit assumed where the system does not report one.
const DEFAULT_FD_LIMIT: u64 = 1024;

#[derive(Args, Clone, Debug)]
pub struct ServeConfig {
    /// Address to listen on; port 0 picks a free one (the chosen address is printed).
    #[arg(long, env = "VTEX_BIND", default_value = "127.0.0.1:8080")]
    pub bind: SocketAddr,
    /// The URL clients reach vtex at, when a proxy serves it elsewhere or under a sub-path
    /// (`https://example.org/vtex/`): every absolute URL vtex writes (IIIF ids, TileJSON tiles,
    /// the OpenAPI server, model examples) starts with it, and forwarded headers are not used
    /// for them. Unset: the request's `Host`, or what trusted proxies forward.
    #[arg(long, env = "VTEX_PUBLIC_URL", value_name = "URL")]
    pub public_url: Option<PublicUrl>,
    /// Proxies whose forwarded headers are believed (IP addresses or CIDR ranges,
    /// comma-separated): `Forwarded` and `X-Forwarded-For/-Host/-Proto/-Port/-Prefix` give the
    /// client's address and, without --public-url, the URL it used. Ignored from other peers.
    #[arg(long, env = "VTEX_TRUSTED_PROXIES", value_delimiter = ',', value_name = "IP|CIDR")]
    pub trusted_proxies: Vec<TrustedProxy>,
    /// Directory of content-addressed bundles (`<id>.vtex`); created if missing.
    #[arg(long, env = "VTEX_DATA_DIR", default_value = "./vtex-data")]
    pub data_dir: PathBuf,
    /// Byte budget of the encoded-tile cache, in MiB (fractions allowed).
    #[arg(long, env = "VTEX_CACHE_MB", default_value_t = 512.0)]
    pub cache_mb: f64,
    /// Byte budget, in MiB, of each model's process-wide synthesis cache (the pyramidal cache
    /// of `order-independent`), shared by all its textures; 0 keeps nothing. It never changes
    /// a tile, only how much of a tile's dependencies is computed again.
    #[arg(long, env = "VTEX_SYNTH_CACHE_MB", default_value_t = 64.0)]
    pub synth_cache_mb: f64,
    /// Serve the viewer from this directory (a `client-web/dist` build) instead of the copy
    /// built into the binary.
    #[arg(long, env = "VTEX_WEB_DIR")]
    pub web_dir: Option<PathBuf>,
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
    /// A response whose bytes make no progress into the socket for this long is abandoned and
    /// its connection closed (slow or stalled readers free what they hold).
    #[arg(long, env = "VTEX_SEND_TIMEOUT_SECS", default_value_t = 30.0)]
    pub send_timeout_secs: f64,
    /// A connection with no request in flight and no bytes moving for this long is closed
    /// (HTTP/1.1 keep-alive and HTTP/2 alike, and one that never sends a byte).
    #[arg(long, env = "VTEX_IDLE_TIMEOUT_SECS", default_value_t = 60.0)]
    pub idle_timeout_secs: f64,
    /// Open connections served at once; beyond it a new one gets a 503 and is closed.
    /// Default: (open-file limit − 64) ÷ descriptors per connection (3 under `splice`, 1 under
    /// `copy`).
    #[arg(long, env = "VTEX_MAX_CONNECTIONS")]
    pub max_connections: Option<usize>,
    /// Byte budget of loaded textures, in MiB, charged what each one's plan says it holds:
    /// textures load on first use and the least recently used are dropped to stay within it.
    /// A texture that alone holds more is refused.
    #[arg(long, env = "VTEX_TEXTURES_MB", default_value_t = 2048.0)]
    pub textures_mb: f64,
    /// Most work units one tile of a texture may cost (`vtex_synth::models::cost`); an upload
    /// over it is refused.
    #[arg(long, env = "VTEX_MAX_TILE_WORK", default_value_t = Limits::SERVE.max_tile_work)]
    pub max_tile_work: u64,
    /// Most work units creating or loading one texture may cost; an upload over it is refused.
    #[arg(long, env = "VTEX_MAX_BUILD_WORK", default_value_t = Limits::SERVE.max_build_work)]
    pub max_build_work: u64,
    /// Most textures the store holds; an upload past it is refused (507).
    #[arg(long, env = "VTEX_MAX_TEXTURES", default_value_t = 10_000)]
    pub max_textures: usize,
    /// Most bytes of bundles the store holds on disk, in MiB; an upload past it is refused (507).
    #[arg(long, env = "VTEX_STORE_MB", default_value_t = 4096.0)]
    pub store_mb: f64,
    /// Syntheses one texture may run at once, so that its misses, however slow, leave slots
    /// to the others. Default: all slots but one (one when there is one slot).
    #[arg(long, env = "VTEX_MAX_SYNTHESES_PER_TEXTURE")]
    pub max_syntheses_per_texture: Option<usize>,
    /// Misses waiting for a synthesis slot; one more is answered 503 at once. Default:
    /// [`QUEUED_PER_SLOT`] per slot.
    #[arg(long, env = "VTEX_MAX_QUEUED")]
    pub max_queued: Option<usize>,
    /// Byte budget of response bodies in flight, in MiB: regions (from their render until
    /// sent), bundle downloads and batch frames reserve their bytes first; past it, 503.
    /// Cached tiles are the tile cache's and are not charged.
    #[arg(long, env = "VTEX_INFLIGHT_MB", default_value_t = DEFAULT_INFLIGHT_MB)]
    pub inflight_mb: f64,
    /// Fewest bytes a second a response must move while it waits for its reader, averaged over
    /// each `--send-timeout-secs` of waiting; a slower one is abandoned and its connection
    /// closed. 0 turns the check off.
    #[arg(long, env = "VTEX_MIN_SEND_RATE", default_value_t = 1024)]
    pub min_send_rate: u64,
    /// Bearer token every write (POST, PATCH, DELETE) must carry in `Authorization`; unset,
    /// writes need none. Prefer the environment or `--write-token-file`: a flag shows in `ps`.
    #[arg(long, env = "VTEX_WRITE_TOKEN", hide_env_values = true)]
    pub write_token: Option<WriteToken>,
    /// File holding the write token (a container secret); its surrounding whitespace is ignored.
    #[arg(long, env = "VTEX_WRITE_TOKEN_FILE", conflicts_with = "write_token")]
    pub write_token_file: Option<PathBuf>,
    /// Refuse every write (403): a replica that only serves what the data directory holds.
    #[arg(long, env = "VTEX_READ_ONLY")]
    pub read_only: bool,
    /// Origins (`https://host[:port]`, comma-separated, or `*`) whose pages may write across
    /// origins; by default only requests without an `Origin` or from the server's own origin
    /// may write. Reads are open to every origin.
    #[arg(long, env = "VTEX_CORS_WRITE_ORIGINS", value_delimiter = ',')]
    pub cors_write_origins: Vec<String>,
    /// How the store learns of bundles other processes add to or delete from the data
    /// directory: `events` (inotify, else polling), `poll`, or `off` (then only a request for
    /// an unknown id finds a new bundle).
    #[arg(long, env = "VTEX_WATCH", value_enum, default_value_t = WatchMode::Events)]
    pub watch: WatchMode,
}

/// The default of `--inflight-mb`: two of the largest regions rendering at once (one a
/// synthesis slot on two cores; each reserves its pixels and its encoding, 128 MiB at 4096²),
/// or four of them waiting for their readers.
pub const DEFAULT_INFLIGHT_MB: f64 = 256.0;

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
        if !(self.synth_cache_mb.is_finite() && self.synth_cache_mb >= 0.0) {
            return Err(format!("synth-cache-mb must be 0 or more, got {}", self.synth_cache_mb));
        }
        positive(self.max_upload_mb, "max-upload-mb")?;
        positive(self.request_timeout_secs, "request-timeout-secs")?;
        positive(self.header_timeout_secs, "header-timeout-secs")?;
        positive(self.textures_mb, "textures-mb")?;
        positive(self.store_mb, "store-mb")?;
        positive(self.inflight_mb, "inflight-mb")?;
        let largest = self.largest_response_bytes();
        if self.inflight_bytes() < largest {
            return Err(format!(
                "inflight-mb ({} MiB) must hold the largest response, {:.1} MiB (a region of max-region-pixels \
                 encoded, or the largest bundle)",
                self.inflight_mb,
                largest as f64 / (1 << 20) as f64
            ));
        }
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
        positive(self.send_timeout_secs, "send-timeout-secs")?;
        positive(self.idle_timeout_secs, "idle-timeout-secs")?;
        if self.max_connections == Some(0) {
            return Err("max-connections must be at least 1".into());
        }
        for origin in &self.cors_write_origins {
            if origin != "*" && !(origin.starts_with("http://") || origin.starts_with("https://")) {
                return Err(format!(
                    "cors-write-origins: `{origin}` is not `*` nor an origin like https://host[:port]"
                ));
            }
        }
        Ok(())
    }

    /// Reads `--write-token-file` into the write token, so that the rest of the server sees
    /// one setting.
    pub fn resolve_write_token(&mut self) -> Result<(), String> {
        if let Some(path) = &self.write_token_file {
            let text =
                std::fs::read_to_string(path).map_err(|e| format!("write-token-file {}: {e}", path.display()))?;
            self.write_token = Some(text.parse()?);
        }
        Ok(())
    }

    pub fn cache_bytes(&self) -> u64 {
        (self.cache_mb * 1024.0 * 1024.0) as u64
    }

    pub fn inflight_bytes(&self) -> u64 {
        (self.inflight_mb * 1024.0 * 1024.0) as u64
    }

    /// The most one response reserves from the in-flight budget: the largest region at its
    /// peak, or the largest bundle.
    fn largest_response_bytes(&self) -> u64 {
        let side = MAX_REGION_SIDE as u64;
        let pixels = self.max_region_pixels.min(side * side) as u32;
        let region = crate::encode::peak_bytes(Format::Png, pixels, 1);
        region.max(vtex_synth::bundle::MAX_BUNDLE_BYTES as u64)
    }

    pub fn synth_cache_bytes(&self) -> u64 {
        (self.synth_cache_mb * 1024.0 * 1024.0) as u64
    }

    pub fn max_upload_bytes(&self) -> usize {
        (self.max_upload_mb * 1024.0 * 1024.0) as usize
    }

    /// The bounds of the store: what one texture may cost (holding at most the whole texture
    /// budget), the budget of loaded textures, and the caps on what is stored.
    pub fn store_bounds(&self) -> Bounds {
        let mib = |v: f64| (v * 1024.0 * 1024.0) as u64;
        Bounds {
            tile_size: self.tile_size,
            limits: Limits {
                max_resident_bytes: mib(self.textures_mb),
                max_tile_work: self.max_tile_work,
                max_build_work: self.max_build_work,
            },
            max_textures: self.max_textures,
            max_store_bytes: mib(self.store_mb),
        }
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

    pub fn send_limits(&self) -> SendLimits {
        SendLimits { timeout: Duration::from_secs_f64(self.send_timeout_secs), min_rate: self.min_send_rate }
    }

    pub fn idle_timeout(&self) -> Duration {
        Duration::from_secs_f64(self.idle_timeout_secs)
    }

    /// `--max-connections`, else what the open-file limit allows after [`FD_RESERVE`]:
    /// descriptors a connection may hold under `--send` divide the rest.
    pub fn max_connections(&self) -> usize {
        self.max_connections.unwrap_or_else(|| {
            let limit = crate::transport::descriptor_limit().unwrap_or(DEFAULT_FD_LIMIT);
            let per = self.send.descriptors_per_connection();
            usize::try_from(limit.saturating_sub(FD_RESERVE) / per).unwrap_or(usize::MAX).max(1)
        })
    }
}

/// The write token: compared in constant time, never printed.
#[derive(Clone)]
pub struct WriteToken(String);

impl WriteToken {
    /// True when `presented` is the token. Both sides are hashed first, so the comparison takes
    /// the same time whatever the presented value.
    pub fn matches(&self, presented: &str) -> bool {
        blake3::hash(self.0.as_bytes()) == blake3::hash(presented.as_bytes())
    }
}

impl std::str::FromStr for WriteToken {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let token = s.trim();
        if token.is_empty() {
            return Err("the write token is empty".into());
        }
        if !token.bytes().all(|b| b.is_ascii_graphic()) {
            return Err("the write token must be printable ASCII without spaces".into());
        }
        Ok(WriteToken(token.to_string()))
    }
}

impl std::fmt::Debug for WriteToken {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("WriteToken(…)")
    }
}
