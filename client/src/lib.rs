//! vtex-client: what a game engine needs to stream virtual-texture pages from a vtex server.
//!
//! * discovery of textures ([`Client::textures`]) and the URLs of pages and tiles;
//! * pages fetched alone or as the server's page metatile (an aligned block of pages) where
//!   most of one is wanted ([`Client::pages`]): immutable URLs that a cache in front shares
//!   between clients, several in flight at once, a metatile's frames parsed by [`frames`];
//!   pages already held answered from a byte-bounded LRU ([`cache`]);
//! * optionally, a byte-bounded cache on disk that outlives the process ([`disk`],
//!   [`ClientBuilder::disk_cache`]): every entry checked (BLAKE3) when read, a damaged one
//!   removed and fetched again, never served; written atomically; reused without a request
//!   while the server's `Cache-Control: max-age` holds (pages are `immutable`, their URLs name
//!   the texture's content hash), revalidated with `If-None-Match` after;
//! * HTTPS (rustls, the ring provider) with the system's roots and any root the game ships
//!   ([`ClientBuilder::root_certificate_pem`]), HTTP/2 where the server offers it (ALPN), else
//!   HTTP/1.1;
//! * retries with exponential back-off (honouring `Retry-After`) of what can succeed later:
//!   connection failures, 408, 429 and 5xx;
//! * ETag revalidation of a held page ([`Client::revalidate`]): a 304 keeps the bytes;
//! * the page-residency planner ([`planner`]): which pages a camera (or a GPU feedback buffer)
//!   needs, coarsest first, within a budget and beside the pages already resident.
//!
//! ```no_run
//! # async fn run() -> vtex_client::Result<()> {
//! use vtex_client::{Client, PageAddr, PageSpec};
//! let client = Client::builder("https://textures.example.com")
//!     .root_certificate_pem(&std::fs::read("game-ca.pem")?)?
//!     .disk_cache("/var/cache/game/pages", 1 << 30)
//!     .build()?;
//! let texture = &client.textures().await?[0];
//! let (pages, stats) = client.pages(&texture.id, &[PageAddr { level: 0, x: 0, y: 0 }], &PageSpec::default()).await?;
//! # Ok(()) }
//! ```

pub mod cache;
pub mod disk;
pub mod frames;
pub mod planner;

use bytes::Bytes;
use cache::PageCache;
use disk::DiskCache;
use futures_util::StreamExt;
use serde::Deserialize;
use std::collections::HashMap;
use std::path::PathBuf;
use std::sync::Mutex;
use std::time::Duration;
use vtex_wire::urls;

#[derive(Debug, thiserror::Error)]
pub enum Error {
    #[error("request failed: {0}")]
    Http(#[from] reqwest::Error),
    /// The server answered an error that retrying will not change (a 4xx), or retries ran out.
    #[error("the server answered {status}: {message}")]
    Status { status: u16, message: String },
    #[error("unexpected answer: {0}")]
    Protocol(String),
    /// A root certificate given to [`ClientBuilder`] is not one.
    #[error("root certificate: {0}")]
    Certificate(String),
    /// The disk cache's directory could not be opened.
    #[error("disk cache: {0}")]
    Io(#[from] std::io::Error),
}

pub type Result<T> = std::result::Result<T, Error>;

pub use vtex_wire::{Domain, TextureInfo};

/// Levels of `texture` pages are served at, down to 1×1.
pub fn page_levels(texture: &TextureInfo) -> u32 {
    vtex_wire::levels::level_count(texture.width, texture.height)
}

/// Pages of side `size` across and down `level` of `texture`.
pub fn page_grid(texture: &TextureInfo, level: u32, size: u32) -> (u64, u64) {
    vtex_wire::levels::grid(texture.width, texture.height, level, size)
}

/// A page's place: level and column, row of the level's page grid.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct PageAddr {
    pub level: u32,
    pub x: u32,
    pub y: u32,
}

/// How pages are encoded: the server's `format` and its KTX2 options.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum PageFormat {
    Rgba,
    Png,
    /// KTX2 with `codec` (`bc7`, `bc1`, `rgba8`), zstd-supercompressed or not.
    Ktx2 {
        codec: &'static str,
        zstd: bool,
    },
}

/// Which layer of the texture pages hold: its colour (sRGB), or the tangent-space normals of
/// its luminance height at each level (linear RGB, glTF's convention: +Y towards the first row).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum PageLayer {
    #[default]
    Color,
    Normal,
}

/// A page's size, border, format and layer.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct PageSpec {
    pub size: u32,
    pub border: u32,
    pub format: PageFormat,
    pub layer: PageLayer,
}

impl Default for PageSpec {
    /// 128² colour pages with a 4-pixel border in BC7.
    fn default() -> Self {
        PageSpec {
            size: 128,
            border: 4,
            format: PageFormat::Ktx2 { codec: "bc7", zstd: false },
            layer: PageLayer::Color,
        }
    }
}

impl PageSpec {
    fn ext(&self) -> &'static str {
        match self.format {
            PageFormat::Rgba => "rgba",
            PageFormat::Png => "png",
            PageFormat::Ktx2 { .. } => "ktx2",
        }
    }

    /// The query parameters besides the format.
    fn query(&self) -> String {
        let mut q = format!("size={}&border={}", self.size, self.border);
        if self.layer == PageLayer::Normal {
            q += "&layer=normal";
        }
        if let PageFormat::Ktx2 { codec, zstd } = self.format {
            q += &format!("&codec={codec}");
            if zstd {
                q += "&supercompression=zstd";
            }
        }
        q
    }
}

/// A page held by the client.
#[derive(Clone, Debug)]
pub struct Page {
    pub addr: PageAddr,
    /// Pixels across and down, border included.
    pub width: u32,
    pub height: u32,
    pub bytes: Bytes,
    /// The server's validator, when the page came from the single-page endpoint.
    pub etag: Option<String>,
}

/// A page's key in the client's cache.
#[derive(Clone, Debug, PartialEq, Eq, Hash)]
pub struct PageKey {
    pub texture: String,
    pub addr: PageAddr,
    pub spec: PageSpec,
}

/// How failed requests are retried: up to `attempts` tries, waiting `first_delay`, then twice
/// as long each time up to `max_delay` (or what `Retry-After` asks, if longer).
#[derive(Clone, Copy, Debug)]
pub struct Retry {
    pub attempts: u32,
    pub first_delay: Duration,
    pub max_delay: Duration,
}

impl Default for Retry {
    fn default() -> Self {
        Retry { attempts: 5, first_delay: Duration::from_millis(50), max_delay: Duration::from_secs(2) }
    }
}

impl Retry {
    fn delay(&self, attempt: u32, retry_after: Option<Duration>) -> Duration {
        let backoff = self.first_delay.saturating_mul(1 << attempt.min(16)).min(self.max_delay);
        retry_after.map_or(backoff, |r| r.max(backoff))
    }
}

/// What one call of [`Client::pages`] did.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct FetchStats {
    /// Pages answered from the client's cache.
    pub hits: usize,
    /// Pages requested from the server.
    pub requested: usize,
    /// Page metatiles fetched for them (the others came alone).
    pub metatiles: usize,
    /// Bytes of page bodies received.
    pub bytes: u64,
    /// Of those, the bytes of pages a metatile brought that were not asked for (kept in the
    /// cache, behind the pages asked for).
    pub unused: u64,
    /// Pages answered from the disk cache while fresh, without a request.
    pub disk_hits: usize,
    /// Pages of the disk cache past their freshness that the server confirmed (304): no body
    /// received. Counted in `requested` too.
    pub revalidated: usize,
}

/// Requests [`Client::pages`] has in flight at once: a browser's connections to one host.
pub const REQUESTS_IN_FLIGHT: usize = 6;

/// A fetch of [`Client::pages`]: a page metatile and the pages asked of it, one page alone, or
/// one held page whose validator is sent (`If-None-Match`).
enum Fetch {
    Metatile(PageAddr, Vec<PageAddr>),
    Page(PageAddr),
    Revalidate(Page),
}

/// What one [`Fetch`] brought.
struct Fetched {
    asked: Vec<PageAddr>,
    pages: Vec<Page>,
    /// Until when they are fresh ([`freshness`]); `None`: not to be stored on disk.
    fresh_until: Option<u64>,
    /// The server answered 304: the held page stands.
    not_modified: bool,
}

/// Until when (seconds since the Unix epoch) an answer with `headers` is fresh, by its
/// `Cache-Control` (`max-age` less `Age`); 0 (revalidate on reuse) without one or with
/// `no-cache`; `None` for `no-store`.
fn freshness(headers: &reqwest::header::HeaderMap) -> Option<u64> {
    let cc = headers.get_all("cache-control").iter().filter_map(|v| v.to_str().ok()).collect::<Vec<_>>().join(",");
    let directives: Vec<String> = cc.split(',').map(|d| d.trim().to_ascii_lowercase()).collect();
    if directives.iter().any(|d| d == "no-store") {
        return None;
    }
    if directives.iter().any(|d| d == "no-cache") {
        return Some(0);
    }
    let age: u64 = headers.get("age").and_then(|v| v.to_str().ok()?.trim().parse().ok()).unwrap_or(0);
    let max_age = directives.iter().find_map(|d| d.strip_prefix("max-age=")?.trim_matches('"').parse::<u64>().ok());
    Some(max_age.map_or(0, |m| (disk::now() + m).saturating_sub(age)))
}

/// What [`Client::pages`] must ask the server for: pages of one page metatile that no cache
/// holds, or a page of the disk cache to revalidate.
enum Missing {
    Group(PageAddr, Vec<PageAddr>),
    Stale(Page),
}

/// The fetches of the pages `asked` of page metatile `m` (for pages of side `size`): the
/// metatile where at least half of a whole one is asked for, else each page alone.
fn fetch_plan(m: PageAddr, asked: Vec<PageAddr>, size: u32) -> Vec<Fetch> {
    let side = vtex_wire::levels::metatile_tiles(size) as usize;
    match 2 * asked.len() >= side * side {
        true => vec![Fetch::Metatile(m, asked)],
        false => asked.into_iter().map(Fetch::Page).collect(),
    }
}

/// A page from the single-page endpoint's answer: its size and validator from the headers.
fn page_from(addr: PageAddr, headers: &reqwest::header::HeaderMap, bytes: Bytes) -> Page {
    let dim = |name: &str| headers.get(name).and_then(|v| v.to_str().ok()?.parse().ok()).unwrap_or(0);
    let etag = headers.get("etag").and_then(|v| v.to_str().ok()).map(String::from);
    Page { addr, width: dim("x-vtex-width"), height: dim("x-vtex-height"), bytes, etag }
}

/// The page metatile holding page `addr` for pages of side `size`: its place in the level's
/// grid of metatiles ([`vtex_wire::levels::metatile_tiles`] pages a side).
pub fn page_metatile(addr: PageAddr, size: u32) -> PageAddr {
    let side = vtex_wire::levels::metatile_tiles(size);
    PageAddr { level: addr.level, x: addr.x / side, y: addr.y / side }
}

/// A client of one vtex server.
pub struct Client {
    http: reqwest::Client,
    base: String,
    cache: Mutex<PageCache>,
    disk: Option<Mutex<DiskCache>>,
    retry: Retry,
}

/// How a [`Client`] is made: [`Client::builder`].
pub struct ClientBuilder {
    base: String,
    cache_bytes: u64,
    retry: Retry,
    disk: Option<(PathBuf, u64)>,
    roots: Vec<reqwest::Certificate>,
    system_roots: bool,
    timeout: Duration,
    connect_timeout: Duration,
}

impl ClientBuilder {
    /// Bytes of pages the in-memory cache holds (default 256 MiB).
    pub fn cache_bytes(mut self, bytes: u64) -> Self {
        self.cache_bytes = bytes;
        self
    }

    pub fn retry(mut self, retry: Retry) -> Self {
        self.retry = retry;
        self
    }

    /// Keeps pages on disk in `dir` (created if need be), at most `bytes` of files ([`disk`]).
    pub fn disk_cache(mut self, dir: impl Into<PathBuf>, bytes: u64) -> Self {
        self.disk = Some((dir.into(), bytes));
        self
    }

    /// Trusts the root certificates in `pem` (one or more `CERTIFICATE` blocks): the CA a game
    /// ships for its own servers. Added to the system's roots unless
    /// [`system_roots(false)`](Self::system_roots).
    pub fn root_certificate_pem(mut self, pem: &[u8]) -> Result<Self> {
        let certs = reqwest::Certificate::from_pem_bundle(pem)?;
        if certs.is_empty() {
            return Err(Error::Certificate("no CERTIFICATE block in the PEM".into()));
        }
        self.roots.extend(certs);
        Ok(self)
    }

    /// Trusts the root certificate `der` (DER-encoded).
    pub fn root_certificate_der(mut self, der: &[u8]) -> Result<Self> {
        self.roots.push(reqwest::Certificate::from_der(der)?);
        Ok(self)
    }

    /// Whether the operating system's roots are trusted too (default: yes). Off, only the roots
    /// given here are: a game that talks to its own servers only.
    pub fn system_roots(mut self, trust: bool) -> Self {
        self.system_roots = trust;
        self
    }

    /// The longest a request may take, retries apart (default 60 s), and the longest a
    /// connection may take to open (default 10 s).
    pub fn timeouts(mut self, request: Duration, connect: Duration) -> Self {
        (self.timeout, self.connect_timeout) = (request, connect);
        self
    }

    pub fn build(self) -> Result<Client> {
        let mut http = reqwest::Client::builder()
            .use_rustls_tls()
            .tls_built_in_root_certs(self.system_roots)
            .timeout(self.timeout)
            .connect_timeout(self.connect_timeout);
        for root in self.roots {
            http = http.add_root_certificate(root);
        }
        let disk = match self.disk {
            Some((dir, bytes)) => Some(Mutex::new(DiskCache::open(dir, bytes)?)),
            None => None,
        };
        Ok(Client {
            http: http.build()?,
            base: self.base.trim_end_matches('/').to_string(),
            cache: Mutex::new(PageCache::new(self.cache_bytes)),
            disk,
            retry: self.retry,
        })
    }
}

impl Client {
    /// A client of the server at `base` (`http://host:port` or `https://host:port`, system
    /// roots trusted) with an in-memory page cache of `cache_bytes`, no disk cache and the
    /// default [`Retry`]. [`Client::builder`] sets the rest.
    pub fn new(base: &str, cache_bytes: u64) -> Client {
        Client::builder(base).cache_bytes(cache_bytes).build().expect("an HTTP client without a disk cache")
    }

    /// A client of the server at `base`, to configure: caches, retries, TLS roots, timeouts.
    pub fn builder(base: &str) -> ClientBuilder {
        ClientBuilder {
            base: base.to_string(),
            cache_bytes: 256 << 20,
            retry: Retry::default(),
            disk: None,
            roots: Vec::new(),
            system_roots: true,
            timeout: Duration::from_secs(60),
            connect_timeout: Duration::from_secs(10),
        }
    }

    pub fn with_retry(mut self, retry: Retry) -> Client {
        self.retry = retry;
        self
    }

    /// Whether page `addr` is held by the in-memory cache, without making it recently used.
    pub fn is_cached(&self, texture: &str, addr: PageAddr, spec: &PageSpec) -> bool {
        self.cache.lock().unwrap().contains(&PageKey { texture: texture.to_string(), addr, spec: *spec })
    }

    /// Pages and bytes held by the disk cache now, if there is one.
    pub fn disk_cached(&self) -> Option<(usize, u64)> {
        self.disk.as_ref().map(|d| {
            let d = d.lock().unwrap();
            (d.len(), d.bytes())
        })
    }

    /// Every texture the server serves.
    pub async fn textures(&self) -> Result<Vec<TextureInfo>> {
        #[derive(Deserialize)]
        struct List {
            textures: Vec<TextureInfo>,
        }
        let body = self.get(&format!("{}/api/v1/textures", self.base), None).await?.1;
        let list: List = serde_json::from_slice(&body).map_err(|e| Error::Protocol(format!("texture list: {e}")))?;
        Ok(list.textures)
    }

    pub fn page_url(&self, texture: &str, addr: PageAddr, spec: &PageSpec) -> String {
        let PageAddr { level, x, y } = addr;
        format!("{}{}?{}", self.base, urls::page_path(texture, level, x, y, spec.ext()), spec.query())
    }

    pub fn tile_url(&self, texture: &str, level: u32, x: u32, y: u32, ext: &str) -> String {
        format!("{}{}", self.base, urls::tile_path(texture, level, x, y, ext))
    }

    /// The URL of page metatile `m` ([`page_metatile`]).
    pub fn page_metatile_url(&self, texture: &str, m: PageAddr, spec: &PageSpec) -> String {
        let path = urls::page_metatile_path(texture, m.level, m.x, m.y, spec.ext());
        format!("{}{path}?{}", self.base, spec.query())
    }

    /// Pages held by the client's cache now.
    pub fn cached_pages(&self) -> usize {
        self.cache.lock().unwrap().len()
    }

    /// Bytes held by the client's cache now.
    pub fn cached_bytes(&self) -> u64 {
        self.cache.lock().unwrap().bytes()
    }

    /// Pages `addrs` of `texture` in `spec`, in the order asked: from the cache in memory, then
    /// from the disk cache while fresh (a stale one with an ETag revalidated), the others
    /// fetched — grouped by page metatile, a group as its metatile when it asks for at least
    /// half of a whole one (one request; the metatile's other pages are kept in the cache,
    /// behind the pages asked for), else page by page, so no fetch brings more than twice the
    /// bytes asked for. Requests go out in the order of each group's first page asked for (a
    /// plan's priority), [`REQUESTS_IN_FLIGHT`] at once, each retried until
    /// [`Retry::attempts`] run out; their pages enter the caches in the order of the fetches.
    pub async fn pages(&self, texture: &str, addrs: &[PageAddr], spec: &PageSpec) -> Result<(Vec<Page>, FetchStats)> {
        let mut stats = FetchStats::default();
        let key = |addr: PageAddr| PageKey { texture: texture.to_string(), addr, spec: *spec };
        let mut found: HashMap<PageAddr, Page> = HashMap::new();
        // By page metatile, in the order of each one's first page asked for, and the stale
        // pages of the disk cache where they are asked for: the caller's priority (the
        // planner's coarsest first) is the order of the requests.
        let mut missing: Vec<Missing> = Vec::new();
        let mut group: HashMap<PageAddr, usize> = HashMap::new();
        let mut seen = std::collections::HashSet::new();
        {
            let mut cache = self.cache.lock().unwrap();
            let mut disk = self.disk.as_ref().map(|d| d.lock().unwrap());
            for &a in addrs {
                if !seen.insert(a) {
                    continue;
                }
                if let Some(p) = cache.get(&key(a)) {
                    stats.hits += 1;
                    found.insert(a, p);
                    continue;
                }
                match disk.as_mut().and_then(|d| d.get(&key(a))) {
                    Some(e) if e.is_fresh() => {
                        stats.disk_hits += 1;
                        cache.insert(key(a), e.page.clone());
                        found.insert(a, e.page);
                    }
                    Some(e) if e.page.etag.is_some() => missing.push(Missing::Stale(e.page)),
                    _ => {
                        let m = page_metatile(a, spec.size);
                        let g = *group.entry(m).or_insert_with(|| {
                            missing.push(Missing::Group(m, Vec::new()));
                            missing.len() - 1
                        });
                        if let Missing::Group(_, asked) = &mut missing[g] {
                            asked.push(a);
                        }
                    }
                }
            }
        }
        stats.requested = missing.iter().map(|m| if let Missing::Group(_, asked) = m { asked.len() } else { 1 }).sum();
        let plan: Vec<Fetch> = missing
            .into_iter()
            .flat_map(|m| match m {
                Missing::Group(m, asked) => fetch_plan(m, asked, spec.size),
                Missing::Stale(page) => vec![Fetch::Revalidate(page)],
            })
            .collect();
        stats.metatiles = plan.iter().filter(|f| matches!(f, Fetch::Metatile(..))).count();
        let fetches = plan.into_iter().map(|f| self.fetch(texture, f, spec));
        let mut fetched = futures_util::stream::iter(fetches).buffered(REQUESTS_IN_FLIGHT);
        while let Some(result) = fetched.next().await {
            let Fetched { asked, pages, fresh_until, not_modified } = result?;
            stats.revalidated += not_modified as usize;
            let (asked_for, others): (Vec<_>, Vec<_>) = pages.into_iter().partition(|p| asked.contains(&p.addr));
            let mut cache = self.cache.lock().unwrap();
            let mut disk = self.disk.as_ref().map(|d| d.lock().unwrap());
            for page in others.into_iter().chain(asked_for) {
                if !not_modified {
                    stats.bytes += page.bytes.len() as u64;
                }
                cache.insert(key(page.addr), page.clone());
                if let (Some(disk), Some(fresh_until)) = (disk.as_mut(), fresh_until) {
                    // The disk cache is an optimisation: a page it cannot write is fetched
                    // again next run.
                    let _ = disk.put(&key(page.addr), &page, fresh_until);
                }
                match asked.contains(&page.addr) {
                    true => _ = found.insert(page.addr, page),
                    false => stats.unused += page.bytes.len() as u64,
                }
            }
        }
        addrs
            .iter()
            .map(|a| {
                found.get(a).cloned().ok_or_else(|| Error::Protocol(format!("page {a:?} missing from its answer")))
            })
            .collect::<Result<Vec<_>>>()
            .map(|pages| (pages, stats))
    }

    /// One fetch of [`Client::pages`]: the pages asked of it, and every page it brought.
    async fn fetch(&self, texture: &str, fetch: Fetch, spec: &PageSpec) -> Result<Fetched> {
        match fetch {
            Fetch::Page(addr) => {
                let (headers, body) = self.get(&self.page_url(texture, addr, spec), None).await?;
                let fresh_until = freshness(&headers);
                Ok(Fetched {
                    asked: vec![addr],
                    pages: vec![page_from(addr, &headers, body)],
                    fresh_until,
                    not_modified: false,
                })
            }
            Fetch::Revalidate(held) => {
                let addr = held.addr;
                let (headers, body) = self.get(&self.page_url(texture, addr, spec), held.etag.as_deref()).await?;
                let fresh_until = freshness(&headers);
                let (page, not_modified) = match body_if_modified(&headers, &body) {
                    None => (held, true),
                    Some(body) => (page_from(addr, &headers, body), false),
                };
                Ok(Fetched { asked: vec![addr], pages: vec![page], fresh_until, not_modified })
            }
            Fetch::Metatile(m, asked) => {
                let (headers, body) = self.get(&self.page_metatile_url(texture, m, spec), None).await?;
                let pages = frames::parse(&body)?
                    .into_iter()
                    .map(|f| match f.status {
                        200 => Ok(Page { addr: f.addr(), width: f.width, height: f.height, bytes: f.body, etag: None }),
                        status => {
                            Err(Error::Protocol(format!("page {:?} of a metatile has status {status}", f.addr())))
                        }
                    })
                    .collect::<Result<Vec<_>>>()?;
                Ok(Fetched { asked, pages, fresh_until: freshness(&headers), not_modified: false })
            }
        }
    }

    /// Page `addr` from the single-page endpoint, asking the server whether the copy held is
    /// still current (`If-None-Match`): the held copy on a 304, the new one otherwise. Returns
    /// the page and whether the server answered 304.
    pub async fn revalidate(&self, texture: &str, addr: PageAddr, spec: &PageSpec) -> Result<(Page, bool)> {
        let key = PageKey { texture: texture.to_string(), addr, spec: *spec };
        let held = self.cache.lock().unwrap().get(&key);
        let held = held.or_else(|| Some(self.disk.as_ref()?.lock().unwrap().get(&key)?.page));
        let etag = held.as_ref().and_then(|p| p.etag.clone());
        let (headers, body) = self.get(&self.page_url(texture, addr, spec), etag.as_deref()).await?;
        let (page, not_modified) = match (held, body_if_modified(&headers, &body)) {
            (Some(held), None) => (held, true),
            (_, body) => (page_from(addr, &headers, body.unwrap_or_default()), false),
        };
        self.cache.lock().unwrap().insert(key.clone(), page.clone());
        if let (Some(disk), Some(fresh_until)) = (&self.disk, freshness(&headers)) {
            let _ = disk.lock().unwrap().put(&key, &page, fresh_until);
        }
        Ok((page, not_modified))
    }

    /// GET with retries; `if_none_match` makes a 304 an answer (empty body, `x-vtex-304` set).
    async fn get(&self, url: &str, if_none_match: Option<&str>) -> Result<(reqwest::header::HeaderMap, Bytes)> {
        let mut attempt = 0;
        loop {
            match self.try_get(url, if_none_match).await {
                Ok(ok) => return Ok(ok),
                Err(Retryable { error, retry_after }) => {
                    attempt += 1;
                    if attempt >= self.retry.attempts || retry_after.is_none() && !matches!(error, Error::Http(_)) {
                        return Err(error);
                    }
                    tokio::time::sleep(self.retry.delay(attempt - 1, retry_after)).await;
                }
            }
        }
    }

    async fn try_get(
        &self,
        url: &str,
        if_none_match: Option<&str>,
    ) -> std::result::Result<(reqwest::header::HeaderMap, Bytes), Retryable> {
        let mut req = self.http.get(url);
        if let Some(tag) = if_none_match {
            req = req.header("if-none-match", tag);
        }
        let resp = req.send().await.map_err(|e| Retryable { error: e.into(), retry_after: None })?;
        let status = resp.status().as_u16();
        let mut headers = resp.headers().clone();
        let retry_after = headers
            .get("retry-after")
            .and_then(|v| v.to_str().ok()?.parse::<u64>().ok())
            .map(Duration::from_secs)
            .or(Some(Duration::ZERO));
        let body = resp.bytes().await.map_err(|e| Retryable { error: e.into(), retry_after: None })?;
        match status {
            200 => Ok((headers, body)),
            304 => {
                headers.insert(NOT_MODIFIED, reqwest::header::HeaderValue::from_static("1"));
                Ok((headers, body))
            }
            s if retryable(s) => {
                Err(Retryable { error: Error::Status { status: s, message: error_message(&body) }, retry_after })
            }
            s => {
                Err(Retryable { error: Error::Status { status: s, message: error_message(&body) }, retry_after: None })
            }
        }
    }
}

/// Set on the headers of a 304 by [`Client::try_get`].
const NOT_MODIFIED: &str = "x-vtex-client-not-modified";

/// The body, unless the answer was a 304.
fn body_if_modified(headers: &reqwest::header::HeaderMap, body: &Bytes) -> Option<Bytes> {
    (!headers.contains_key(NOT_MODIFIED)).then(|| body.clone())
}

/// A failure, with the wait the server asked for when it is worth retrying (`None`: a 4xx,
/// or a connection failure, which is retried on the back-off alone).
struct Retryable {
    error: Error,
    retry_after: Option<Duration>,
}

/// Statuses that may succeed later: the request timed out, too many requests, server errors.
fn retryable(status: u16) -> bool {
    status == 408 || status == 429 || status >= 500
}

fn error_message(body: &[u8]) -> String {
    serde_json::from_slice::<serde_json::Value>(body)
        .ok()
        .and_then(|v| v["error"].as_str().map(String::from))
        .unwrap_or_else(|| String::from_utf8_lossy(&body[..body.len().min(200)]).into_owned())
}
