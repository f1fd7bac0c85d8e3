//! Settings of `vtex serve`. Each one comes from its flag, else its environment variable,
//! else its default — one precedence for all, implemented by clap.

use crate::encode::Format;
use crate::store::{Bounds, Location, ObjectSettings};
use crate::transport::{SendLimits, Transport};
pub use crate::watch::WatchMode;
use clap::Args;
use ipnet::IpNet;
use std::net::IpAddr;
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

/// The headings `vtex serve --help` groups its options under, in the order they first appear.
pub mod heading {
    pub const NETWORK: &str = "Network";
    pub const STORE: &str = "Store";
    pub const BUDGETS: &str = "Budgets";
    pub const VIEWER: &str = "Tiles and viewer";
    pub const CONNECTIONS: &str = "Connections";
    pub const WRITES: &str = "Writes";
    pub const LOGGING: &str = "Logging";
}

// `vtex serve`'s options. Each doc comment's first paragraph is the option's line in `-h`; the
// whole comment, and its environment variable, is its `--help`.
#[derive(Args, Clone, Debug)]
#[command(mut_args = env_in_long_help)]
pub struct ServeConfig {
    /// Address to listen on.
    ///
    /// Port 0 picks a free one (the chosen address is printed).
    #[arg(
        long,
        value_name = "ADDR",
        env = "VTEX_BIND",
        default_value = "127.0.0.1:8080",
        help_heading = heading::NETWORK,
    )]
    pub bind: SocketAddr,
    /// The URL clients reach vtex at, behind a proxy or under a sub-path.
    ///
    /// For example `https://example.org/vtex/`: every absolute URL vtex writes (IIIF ids, TileJSON tiles, the OpenAPI
    /// server, model examples) starts with it, and forwarded headers are not used for them. Unset: the request's
    /// `Host`, or what trusted proxies forward.
    #[arg(long, env = "VTEX_PUBLIC_URL", value_name = "URL", help_heading = heading::NETWORK)]
    pub public_url: Option<PublicUrl>,
    /// Proxies whose forwarded headers are believed (IPs or CIDR ranges, comma-separated).
    ///
    /// `Forwarded` and `X-Forwarded-For/-Host/-Proto/-Port/-Prefix` give the client's address and, without
    /// --public-url, the URL it used. Ignored from other peers.
    #[arg(
        long,
        env = "VTEX_TRUSTED_PROXIES",
        value_delimiter = ',',
        value_name = "IP|CIDR",
        help_heading = heading::NETWORK,
    )]
    pub trusted_proxies: Vec<TrustedProxy>,
    /// Directory of the bundles, or of an object store's local copies.
    ///
    /// The bundles are files `<id>.vtex`; with `--store s3://…`, this replica's copies of them. Bundles are
    /// content-addressed. Created if missing; it must be readable, and writable unless `--read-only` (and
    /// always with an object store, see `--store`).
    #[arg(
        long,
        value_name = "DIR",
        env = "VTEX_DATA_DIR",
        default_value = "./vtex-data",
        help_heading = heading::STORE,
    )]
    pub data_dir: PathBuf,
    /// Where the bundles live: `s3://bucket/prefix`, or a directory [default: --data-dir].
    ///
    /// `s3://`: objects `<prefix>/<id>.vtex` of a bucket of an S3-compatible object store, which replicas share and
    /// nothing else; the client is configured by the usual variables (`AWS_ACCESS_KEY_ID`, `AWS_SECRET_ACCESS_KEY`,
    /// `AWS_REGION`, `AWS_ENDPOINT_URL`, `AWS_ALLOW_HTTP`), and `--data-dir` holds this replica's own copies of the
    /// encodings. A `file:///path` URL or a path: that data directory, in place of `--data-dir`.
    #[arg(long, value_name = "URL", env = "VTEX_STORE", help_heading = heading::STORE)]
    pub store: Option<Location>,
    /// Byte budget of the local copies of an object store's bundles, in MiB.
    ///
    /// Kept in `--data-dir`, least recently used removed first; a texture whose copy was removed is fetched again
    /// when it next loads.
    #[arg(
        long,
        value_name = "MIB",
        env = "VTEX_STORE_CACHE_MB",
        default_value_t = 1024.0,
        help_heading = heading::STORE,
    )]
    pub store_cache_mb: f64,
    /// Seconds between listings of an object store.
    ///
    /// How long a texture another replica stores may be missing from this replica's list, or one it deletes may
    /// stay in it (a request for its id finds a new one at once).
    #[arg(
        long,
        value_name = "SECS",
        env = "VTEX_STORE_POLL_SECS",
        default_value_t = 5.0,
        help_heading = heading::STORE,
    )]
    pub store_poll_secs: f64,
    /// Longest an object-store call may take, retries included, in seconds.
    ///
    /// Past it the request that needed it is answered 503 with `Retry-After`; for a second after a failure, calls
    /// fail at once.
    #[arg(
        long,
        value_name = "SECS",
        env = "VTEX_STORE_TIMEOUT_SECS",
        default_value_t = 10.0,
        help_heading = heading::STORE,
    )]
    pub store_timeout_secs: f64,
    /// Byte budget of the encoded-tile cache, in MiB.
    ///
    /// Fractions allowed.
    #[arg(long, value_name = "MIB", env = "VTEX_CACHE_MB", default_value_t = 512.0, help_heading = heading::BUDGETS)]
    pub cache_mb: f64,
    /// Byte budget of each model's synthesis cache, in MiB.
    ///
    /// The pyramidal cache of `order-independent`, shared by all its textures the server loads;
    /// 0 keeps nothing. It never changes a tile, only how much of a tile's dependencies is
    /// computed again.
    #[arg(
        long,
        value_name = "MIB",
        env = "VTEX_SYNTH_CACHE_MB",
        default_value_t = 64.0,
        help_heading = heading::BUDGETS,
    )]
    pub synth_cache_mb: f64,
    /// Serve the viewer from this directory, not the built-in copy.
    ///
    /// A `client-web/dist` build, instead of the copy built into the binary.
    #[arg(long, value_name = "DIR", env = "VTEX_WEB_DIR", help_heading = heading::VIEWER)]
    pub web_dir: Option<PathBuf>,
    /// Tile side in pixels (16..=2048).
    #[arg(long, value_name = "PX", env = "VTEX_TILE_SIZE", default_value_t = 256, help_heading = heading::VIEWER)]
    pub tile_size: u32,
    /// Syntheses running at once [default: CPU count].
    ///
    /// Further misses wait (back-pressure).
    #[arg(long, value_name = "N", env = "VTEX_MAX_SYNTHESES", help_heading = heading::BUDGETS)]
    pub max_syntheses: Option<usize>,
    /// Largest accepted request body (uploads, patches), in MiB.
    #[arg(
        long,
        value_name = "MIB",
        env = "VTEX_MAX_UPLOAD_MB",
        default_value_t = 64.0,
        help_heading = heading::BUDGETS,
    )]
    pub max_upload_mb: f64,
    /// Largest region request, in pixels (w × h).
    #[arg(
        long,
        value_name = "N",
        env = "VTEX_MAX_REGION_PIXELS",
        default_value_t = DEFAULT_MAX_REGION_PIXELS,
        help_heading = heading::BUDGETS,
    )]
    pub max_region_pixels: u64,
    /// Whole-request deadline in seconds, reading the body included.
    ///
    /// Slow clients get 408.
    #[arg(
        long,
        value_name = "SECS",
        env = "VTEX_REQUEST_TIMEOUT_SECS",
        default_value_t = 30.0,
        help_heading = heading::CONNECTIONS,
    )]
    pub request_timeout_secs: f64,
    /// Deadline for a client to send its request headers, in seconds.
    ///
    /// Counted from the connection's accept, and on HTTP/1.1 keep-alive from its previous
    /// response; the connection is closed after it. Covers HTTP/2's preface and first request.
    #[arg(
        long,
        value_name = "SECS",
        env = "VTEX_HEADER_TIMEOUT_SECS",
        default_value_t = 10.0,
        help_heading = heading::CONNECTIONS,
    )]
    pub header_timeout_secs: f64,
    /// Threads serving connections [default: CPU count].
    ///
    /// One single-threaded runtime each.
    #[arg(long, value_name = "N", env = "VTEX_IO_THREADS", help_heading = heading::CONNECTIONS)]
    pub io_threads: Option<usize>,
    /// How tile bodies reach the socket: `copy` or `splice`.
    ///
    /// `copy` is portable: bodies are written from the heap. `splice` (Linux) sends cached
    /// tiles by page reference, like nginx's sendfile. The default is `splice` on Linux, `copy`
    /// elsewhere.
    #[arg(
        long,
        value_name = "HOW",
        env = "VTEX_SEND",
        default_value_t = Transport::default(),
        help_heading = heading::CONNECTIONS,
    )]
    pub send: Transport,
    /// Do not write the demo textures into an empty data directory.
    #[arg(long, env = "VTEX_NO_DEMOS", help_heading = heading::STORE)]
    pub no_demos: bool,
    /// Seconds a response may make no progress into the socket.
    ///
    /// Past it the response is abandoned and its connection closed (slow or stalled readers
    /// free what they hold).
    #[arg(
        long,
        value_name = "SECS",
        env = "VTEX_SEND_TIMEOUT_SECS",
        default_value_t = 30.0,
        help_heading = heading::CONNECTIONS,
    )]
    pub send_timeout_secs: f64,
    /// Seconds after which an idle connection is closed.
    ///
    /// Idle: no request in flight and no bytes moving (HTTP/1.1 keep-alive and HTTP/2 alike,
    /// and a connection that never sends a byte).
    #[arg(
        long,
        value_name = "SECS",
        env = "VTEX_IDLE_TIMEOUT_SECS",
        default_value_t = 60.0,
        help_heading = heading::CONNECTIONS,
    )]
    pub idle_timeout_secs: f64,
    /// Open connections served at once [default: from the open-file limit].
    ///
    /// At it, the connection with no request in flight for longest is closed to admit a new one;
    /// only when every connection has a request in flight does a new one get a 503. The default
    /// is (open-file limit − 64) ÷ descriptors per connection (3 under `splice`, 1 under `copy`).
    #[arg(long, value_name = "N", env = "VTEX_MAX_CONNECTIONS", help_heading = heading::CONNECTIONS)]
    pub max_connections: Option<usize>,
    /// Open connections from one client address [default: no limit].
    ///
    /// Beyond it a new connection from that address gets a 429 and is closed. The address is the
    /// TCP peer's: behind a reverse proxy, every client shares the proxy's.
    #[arg(long, value_name = "N", env = "VTEX_MAX_CONNECTIONS_PER_CLIENT", help_heading = heading::CONNECTIONS)]
    pub max_connections_per_client: Option<usize>,
    /// Byte budget of loaded textures, in MiB.
    ///
    /// Each texture is charged what its plan says it holds: textures load on first use and the
    /// least recently used are dropped to stay within it. A texture that alone holds more is
    /// refused.
    #[arg(
        long,
        value_name = "MIB",
        env = "VTEX_TEXTURES_MB",
        default_value_t = 2048.0,
        help_heading = heading::BUDGETS,
    )]
    pub textures_mb: f64,
    /// Most work units one tile of a texture may cost.
    ///
    /// Work units are `vtex_synth::models::cost`'s; an upload over it is refused.
    #[arg(
        long,
        value_name = "N",
        env = "VTEX_MAX_TILE_WORK",
        default_value_t = Limits::SERVE.max_tile_work,
        help_heading = heading::BUDGETS,
    )]
    pub max_tile_work: u64,
    /// Most work units creating or loading one texture may cost.
    ///
    /// An upload over it is refused.
    #[arg(
        long,
        value_name = "N",
        env = "VTEX_MAX_BUILD_WORK",
        default_value_t = Limits::SERVE.max_build_work,
        help_heading = heading::BUDGETS,
    )]
    pub max_build_work: u64,
    /// Most textures the store holds.
    ///
    /// An upload past it is refused (507).
    #[arg(long, value_name = "N", env = "VTEX_MAX_TEXTURES", default_value_t = 10_000, help_heading = heading::STORE)]
    pub max_textures: usize,
    /// Most bytes of bundles the store holds on disk, in MiB.
    ///
    /// An upload past it is refused (507).
    #[arg(long, value_name = "MIB", env = "VTEX_STORE_MB", default_value_t = 4096.0, help_heading = heading::STORE)]
    pub store_mb: f64,
    /// Syntheses one texture may run at once [default: all slots but one].
    ///
    /// So that its misses, however slow, leave slots to the others; one when there is one slot.
    #[arg(long, value_name = "N", env = "VTEX_MAX_SYNTHESES_PER_TEXTURE", help_heading = heading::BUDGETS)]
    pub max_syntheses_per_texture: Option<usize>,
    // Its default is a constant's value, which a doc comment cannot show.
    #[arg(long, value_name = "N", env = "VTEX_MAX_QUEUED", help_heading = heading::BUDGETS,
        help = max_queued_help(false), long_help = max_queued_help(true))]
    pub max_queued: Option<usize>,
    /// Byte budget of bodies in flight, in MiB.
    ///
    /// Regions (from their render until sent), bundle downloads and batch frames reserve their
    /// bytes first, and uploads their body's length (`--max-upload-mb` when it declares none)
    /// until stored; past it, 503. Cached tiles are the tile cache's and are not charged.
    #[arg(
        long,
        value_name = "MIB",
        env = "VTEX_INFLIGHT_MB",
        default_value_t = DEFAULT_INFLIGHT_MB,
        help_heading = heading::BUDGETS,
    )]
    pub inflight_mb: f64,
    /// Fewest bytes a second a response must move to its reader.
    ///
    /// Counted while it waits for its reader, averaged over each `--send-timeout-secs` of waiting;
    /// a slower one is abandoned and its connection closed. 0 turns the check off.
    #[arg(
        long,
        value_name = "BYTES",
        env = "VTEX_MIN_SEND_RATE",
        default_value_t = 1024,
        help_heading = heading::CONNECTIONS,
    )]
    pub min_send_rate: u64,
    /// Bearer token writes (POST, PATCH, DELETE) must carry.
    ///
    /// In `Authorization: Bearer …`, from every client. Unset, only loopback clients may write (see `--open-writes`).
    /// Prefer the environment or `--write-token-file`: a flag shows in `ps`.
    #[arg(long, value_name = "TOKEN", env = "VTEX_WRITE_TOKEN", hide_env_values = true, help_heading = heading::WRITES)]
    pub write_token: Option<WriteToken>,
    /// File holding the write token (a container secret).
    ///
    /// Its surrounding whitespace is ignored.
    #[arg(
        long,
        value_name = "FILE",
        env = "VTEX_WRITE_TOKEN_FILE",
        conflicts_with = "write_token",
        help_heading = heading::WRITES,
    )]
    pub write_token_file: Option<PathBuf>,
    /// Without a write token, accept writes from every client, not only loopback ones.
    ///
    /// Anyone who reaches the port can then upload, rename and delete. Only behind a proxy that authenticates writes
    /// itself.
    #[arg(
        long,
        env = "VTEX_OPEN_WRITES",
        conflicts_with_all = ["write_token", "write_token_file"],
        help_heading = heading::WRITES,
    )]
    pub open_writes: bool,
    /// Refuse every write (403): serve only what the data directory holds.
    #[arg(long, env = "VTEX_READ_ONLY", help_heading = heading::WRITES)]
    pub read_only: bool,
    /// Other origins whose pages may write (comma-separated, or `*`).
    ///
    /// Each is `https://host[:port]` or `http://host[:port]`. By default only requests without an
    /// `Origin` or from the server's own origin may write. Reads are open to every origin.
    #[arg(
        long,
        value_name = "ORIGINS",
        env = "VTEX_CORS_WRITE_ORIGINS",
        value_delimiter = ',',
        help_heading = heading::WRITES,
    )]
    pub cors_write_origins: Vec<String>,
    /// Follow other processes' writes.
    ///
    /// How the store learns of bundles other processes add to or delete from the data directory.
    ///
    /// `off`: only a request for an unknown id finds a new bundle.
    #[arg(
        long,
        value_name = "HOW",
        env = "VTEX_WATCH",
        value_enum,
        default_value_t = WatchMode::Events,
        help_heading = heading::STORE,
    )]
    pub watch: WatchMode,
    /// Log one line per request at `info` (method, path, status, bytes, latency).
    ///
    /// Without it requests are logged at `debug`. Logs go to stderr, filtered by `VTEX_LOG` or
    /// `RUST_LOG` (default `info`), coloured only on a terminal and without `NO_COLOR`.
    #[arg(long, env = "VTEX_ACCESS_LOG", help_heading = heading::LOGGING)]
    pub access_log: bool,
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

/// Names an option's environment variable at the end of its `--help` rather than in `-h`,
/// which then fits each option on one line.
fn env_in_long_help(arg: clap::Arg) -> clap::Arg {
    let Some(env) = arg.get_env().map(|e| e.to_string_lossy().into_owned()) else { return arg };
    let help = arg.get_long_help().or(arg.get_help()).map(ToString::to_string).unwrap_or_default();
    arg.hide_env(true).long_help(format!("{help}\n\n[env: {env}]"))
}

/// `--max-queued`'s help, short or long.
fn max_queued_help(long: bool) -> String {
    let short = format!("Misses waiting for a synthesis slot [default: {QUEUED_PER_SLOT} per slot]");
    if long {
        format!("{short}.\n\nOne more is answered 503 at once.")
    } else {
        short
    }
}

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
        positive(self.store_cache_mb, "store-cache-mb")?;
        positive(self.store_poll_secs, "store-poll-secs")?;
        positive(self.store_timeout_secs, "store-timeout-secs")?;
        let largest = self.largest_response_bytes();
        if self.inflight_bytes() < largest {
            return Err(format!(
                "inflight-mb ({} MiB) must hold the largest response, {:.1} MiB (a region of max-region-pixels \
                 encoded, or the largest bundle)",
                self.inflight_mb,
                largest as f64 / (1 << 20) as f64
            ));
        }
        if self.inflight_bytes() < self.max_upload_bytes() as u64 {
            return Err(format!(
                "inflight-mb ({} MiB) must hold the largest upload, max-upload-mb ({} MiB): an upload reserves \
                 its body there while it is read and stored",
                self.inflight_mb, self.max_upload_mb
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
        if self.max_connections_per_client == Some(0) {
            return Err("max-connections-per-client must be at least 1".into());
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

    /// The most one response reserves from the in-flight budget: the largest PNG region at its
    /// peak (formats whose encoders hold more may be refused at that size), or the largest
    /// bundle.
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

    /// Where the bundles live: `--store`, else `--data-dir`.
    pub fn location(&self) -> Location {
        self.store.clone().unwrap_or_else(|| Location::Dir(self.data_dir.clone()))
    }

    /// The settings of the object store `--store` names: its bucket and prefix.
    pub fn object_settings(&self, bucket: String, prefix: String) -> ObjectSettings {
        ObjectSettings {
            bucket,
            prefix,
            cache_dir: self.data_dir.clone(),
            cache_bytes: (self.store_cache_mb * 1024.0 * 1024.0) as u64,
            deadline: Duration::from_secs_f64(self.store_timeout_secs),
        }
    }

    pub fn store_poll(&self) -> Duration {
        Duration::from_secs_f64(self.store_poll_secs)
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

/// `--public-url`: an `http` or `https` URL without credentials, query or fragment, kept as
/// its origin and path without the trailing slash.
#[derive(Clone, Debug, PartialEq)]
pub struct PublicUrl(pub(crate) String);

impl std::str::FromStr for PublicUrl {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let bad = |why: &str| Err(format!("`{s}` is not a public URL like https://example.org/vtex/: {why}"));
        let url = match url::Url::parse(s.trim()) {
            Ok(url) => url,
            Err(e) => return bad(&e.to_string()),
        };
        if !matches!(url.scheme(), "http" | "https") {
            return bad("the scheme must be http or https");
        }
        if url.host().is_none() {
            return bad("it names no host");
        }
        if !url.username().is_empty() || url.password().is_some() {
            return bad("it must not carry credentials");
        }
        if url.query().is_some() || url.fragment().is_some() {
            return bad("it must not have a query or a fragment");
        }
        Ok(PublicUrl(format!("{}{}", url.origin().ascii_serialization(), url.path().trim_end_matches('/'))))
    }
}

/// One entry of `--trusted-proxies`: an address, or a CIDR range.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct TrustedProxy(pub(crate) IpNet);

impl std::str::FromStr for TrustedProxy {
    type Err = String;
    fn from_str(s: &str) -> Result<Self, String> {
        let s = s.trim();
        let net = match s.contains('/') {
            true => s.parse::<IpNet>().map(|n| n.trunc()).ok(),
            false => s.parse::<IpAddr>().map(IpNet::from).ok(),
        };
        net.map(TrustedProxy)
            .ok_or_else(|| format!("`{s}` is not an IP address or a CIDR range (like 127.0.0.1, 10.0.0.0/8 or ::1)"))
    }
}
