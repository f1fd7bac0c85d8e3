//! The engine: what vtex serves, below HTTP — textures looked up in the store, tiles and pages
//! addressed ([`address`]), the tile cache with coalesced misses ([`cache`]), synthesis in
//! bounded slots ([`slots`]) with its stop, views of any rectangle at any output size
//! ([`view`]). It knows no HTTP type: `api` gives its [`Error`] a
//! status and puts its [`ETag`]s in headers.

pub mod address;
pub mod cache;
mod error;
pub mod slots;
pub mod view;

pub use address::{ETag, Mark};
pub use error::{echo, Cause, Error};

use crate::config::ServeConfig;
use crate::encode::{self, Format};
use crate::metrics::Metrics;
use crate::store::{Entry, Record, Store, StoreError};
use crate::transport::Transport;
use cache::{Source, Tile, TileCache, TileKey};
use slots::{Refused, Slots};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::Instant;
use vtex_synth::layer::Layer;
use vtex_synth::{Region, Rgba8Image, Stop};
use vtex_wire::frame::{FrameHeader, TileRef};

const SYNTHESIS_FAILED: &str = "synthesis failed inside the model; the texture cannot render this region";

/// The store, the tile cache and the synthesis slots, and how tiles are made from them.
pub struct Engine {
    pub store: Arc<Store>,
    pub cache: TileCache,
    /// Synthesis slots, shared fairly between textures, with a bounded queue.
    pub slots: Arc<Slots>,
    pub metrics: Arc<Metrics>,
    /// Set when shutdown stops the renders still running.
    stopping: Arc<AtomicBool>,
    /// How cached tiles are held for sending.
    send: Transport,
}

impl Engine {
    pub fn new(store: Arc<Store>, cfg: &ServeConfig, metrics: Arc<Metrics>) -> Engine {
        let cache = TileCache::new(cfg.cache_bytes(), cfg.send);
        metrics.cache_budget_bytes.set(cache.budget() as i64);
        let slots = Slots::new(cfg.syntheses(), cfg.syntheses_per_texture(), cfg.max_queued());
        Engine { store, cache, slots, metrics, stopping: Arc::new(AtomicBool::new(false)), send: cfg.send }
    }

    /// Shutdown: stops every render in progress and refuses every miss waiting or to come.
    pub fn stop_syntheses(&self) {
        self.stopping.store(true, Ordering::Relaxed);
        self.slots.close();
    }

    /// What the store knows of texture `id`, without loading it (found in the data directory
    /// when another process wrote it).
    pub async fn record(&self, id: &str) -> Result<Arc<Record>, Error> {
        check_id(id)?;
        self.store.find(id).await.map_err(store_failure)?.ok_or_else(|| no_texture(id))
    }

    /// Texture `id`, loaded: on its first use (or after its eviction) off the I/O threads.
    pub async fn lookup(&self, id: &str) -> Result<Arc<Entry>, Error> {
        check_id(id)?;
        match self.store.get(id).await {
            Ok(Some(entry)) => Ok(entry),
            Ok(None) => Err(no_texture(id)),
            Err(StoreError::Invalid(e)) => {
                Err(Error::failed("the stored texture failed validation when loaded; it is no longer served", e))
            }
            Err(e) => Err(store_failure(e)),
        }
    }

    /// Tile or page `key` if the cache holds it, on its own or inside its cached metatile (a
    /// view of the metatile's bytes, with the tile's or page's own ETag).
    pub fn cached(&self, entry: &Entry, key: &TileKey) -> Option<Arc<Tile>> {
        if let Some(tile) = self.cache.get(key) {
            return Some(tile);
        }
        let (block, index) = address::metatile_of(entry, key)?;
        let body = self.cache.get(&block)?.body.clone();
        let (header, bytes) = vtex_wire::frame::frame_at(&body, index)?;
        let tile = TileRef { level: key.level, x: key.x, y: key.y };
        debug_assert_eq!(header.tile, tile, "a metatile's frames are its parts, row by row");
        let etag = address::key_etag(entry, key);
        Some(Arc::new(Tile { body: body.slice(bytes), etag, width: header.width, height: header.height }))
    }

    /// Tile, page or metatile `key` (inside `entry`'s pyramid or page grid): `cached` when the
    /// caller found it in the cache, else from the cache or synthesized, one computation
    /// shared by every concurrent request for it (holding a synthesis slot, and stopped once
    /// none of them waits any more). Counted as a hit or a miss. Every route that serves
    /// tiles, pages or metatiles comes through here, so they share the cache, coalescing and
    /// bounds.
    pub async fn tile(
        self: &Arc<Self>,
        entry: &Arc<Entry>,
        key: TileKey,
        cached: Option<Arc<Tile>>,
        etag: ETag,
    ) -> Result<(Arc<Tile>, Source), Error> {
        let (tile, source) = match cached {
            Some(tile) => (tile, Source::Hit),
            None => {
                let (owner, entry) = (self.clone(), entry.clone());
                self.cache
                    .get_or_compute(key, move || async move {
                        let (region, (width, height)) = address::key_region(&entry, &key);
                        let send = owner.send;
                        let parts = match key.shape.is_metatile() {
                            true => address::metatile_parts(&entry, &key),
                            false => Vec::new(),
                        };
                        let encode = owner.encoder(key.format);
                        let body = owner
                            .render_then(entry, region, key.shape.layer(), move |img| {
                                let body = match parts.is_empty() {
                                    true => encode.image(img, (width, height))?,
                                    false => encode.frames(&img, &region, &parts)?,
                                };
                                Ok(send.seal(body))
                            })
                            .await?;
                        Ok(Tile { body, etag, width, height })
                    })
                    .await?
            }
        };
        match source {
            Source::Hit => self.metrics.cache_hit(key.level),
            Source::Miss => self.metrics.cache_miss(key.level),
        }
        Ok((tile, source))
    }

    /// Renders `region` of `entry`'s `layer` and encodes it, on the blocking pool, holding a
    /// slot. Returns the encoded bytes. A bad region is the model's error; a panicking model a
    /// failure; no slot (queue full, shutting down) or a render stopped by shutdown is busy.
    pub async fn synthesize(
        &self,
        entry: Arc<Entry>,
        region: Region,
        layer: Layer,
        format: Format,
    ) -> Result<Vec<u8>, Error> {
        let encode = self.encoder(format);
        self.render_then(entry, region, layer, move |img| encode.image(img, (region.width, region.height))).await
    }

    /// The encoder of `format`, timing each image in the metrics.
    pub fn encoder(&self, format: Format) -> Encoder {
        Encoder { format, seconds: self.metrics.encode_seconds.with_label_values(&[format.ext()]) }
    }

    /// Renders `region` of `entry`'s `layer` (a layer other than colour from the colour of
    /// [`Layer::source`]), then `finish` on the image in the same blocking task
    /// (encoding, and for cached bodies [`Transport::seal`], whose copy and the first touch of
    /// a fresh huge-page arena, which may wait for the kernel to compact memory, then stay off
    /// the I/O runtimes), holding a synthesis slot throughout.
    ///
    /// Dropping the future (its request gone) stops the render: the model returns at its next
    /// band, and the slot is free again.
    pub async fn render_then<T: Send + 'static>(
        &self,
        entry: Arc<Entry>,
        region: Region,
        layer: Layer,
        finish: impl FnOnce(Rgba8Image) -> Result<T, Error> + Send + 'static,
    ) -> Result<T, Error> {
        let slot = self.slot(&entry).await?;
        let stop = Arc::new(SynthesisStop { abandoned: AtomicBool::new(false), server: self.stopping.clone() });
        let _stop_on_drop = StopOnDrop(stop.clone());
        let m = &self.metrics;
        let (synth_s, in_flight, count, stopped) = (
            m.synthesis_seconds.with_label_values(&[entry.model.as_str()]),
            m.syntheses_in_flight.clone(),
            m.syntheses.clone(),
            m.syntheses_stopped.clone(),
        );
        // The slot moves into the blocking work, not this future: a request dropped while its
        // tile renders must not free the slot before the render has returned, or more
        // syntheses than slots would run at once.
        tokio::task::spawn_blocking(move || {
            count.inc();
            in_flight.inc();
            let work = || {
                let t0 = Instant::now();
                let source = layer.source(&region);
                let Some(img) = vtex_synth::texture::render_image_until(&*entry.texture, &source, &*stop)? else {
                    stopped.inc();
                    return Err(busy(Refused::Closed));
                };
                let img = layer.derive(img, region.level);
                synth_s.observe(t0.elapsed().as_secs_f64());
                finish(img)
            };
            let result = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
            in_flight.dec();
            drop(slot);
            result.unwrap_or_else(|panic| Err(Error::failed(SYNTHESIS_FAILED, panic_message(panic))))
        })
        .await
        .map_err(|e| Error::failed(SYNTHESIS_FAILED, e))?
    }
}

impl Engine {
    /// One of `entry`'s synthesis slots, or the 503 of a full queue (counted as shed) or of a
    /// server shutting down.
    async fn slot(&self, entry: &Entry) -> Result<slots::Slot, Error> {
        self.slots.acquire(entry.key).await.map_err(|refused| {
            if refused == Refused::Full {
                self.metrics.syntheses_shed.inc();
            }
            busy(refused)
        })
    }

    /// Runs `work` on a blocking thread holding one of `entry`'s synthesis slots, so that CPU
    /// work beside synthesis (a mip chain's encoding, which Basis Universal makes seconds long)
    /// is bounded as syntheses are: shed with a 503 when the queue is full.
    pub async fn in_slot<T: Send + 'static>(
        &self,
        entry: &Entry,
        work: impl FnOnce() -> T + Send + 'static,
    ) -> Result<T, Error> {
        let slot = self.slot(entry).await?;
        tokio::task::spawn_blocking(move || {
            let out = std::panic::catch_unwind(std::panic::AssertUnwindSafe(work));
            drop(slot);
            out.map_err(|panic| Error::failed(SYNTHESIS_FAILED, panic_message(panic)))
        })
        .await
        .map_err(|e| Error::failed(SYNTHESIS_FAILED, e))?
    }
}

/// Encodes rendered images in one format, timing each in the metrics.
pub struct Encoder {
    format: Format,
    seconds: prometheus::Histogram,
}

impl Encoder {
    /// `img` drawn at the top left of a transparent `canvas` (width, height) — for tiles that
    /// must be whole squares though the texture ends inside them — and encoded.
    pub fn image(&self, img: Rgba8Image, canvas: (u32, u32)) -> Result<Vec<u8>, Error> {
        let img = if (img.width, img.height) == canvas {
            img
        } else {
            let mut on = Rgba8Image::new(canvas.0, canvas.1);
            on.blit(&img, 0, 0);
            on
        };
        let t = Instant::now();
        let bytes = encode::encode(img, self.format).map_err(|e| Error::failed("encoding failed", e))?;
        self.seconds.observe(t.elapsed().as_secs_f64());
        Ok(bytes)
    }

    /// The tiles or pages of a metatile, cut from `img` (its `region`; pages overlap by their
    /// borders) and encoded, as one body of frames in the order given.
    pub fn frames(&self, img: &Rgba8Image, region: &Region, parts: &[(TileKey, Region)]) -> Result<Vec<u8>, Error> {
        let mut body = Vec::new();
        for (key, r) in parts {
            let (x, y) = ((r.x - region.x) as u32, (r.y - region.y) as u32);
            let bytes = self.image(img.crop(x, y, r.width, r.height), (r.width, r.height))?;
            let tile = TileRef { level: key.level, x: key.x, y: key.y };
            let header =
                FrameHeader { tile, status: 200, cache: 0, width: r.width, height: r.height, len: bytes.len() as u32 };
            body.extend_from_slice(&header.encode());
            body.extend_from_slice(&bytes);
        }
        Ok(body)
    }
}

/// The stop of one synthesis: requested when nobody waits for it any more, or for all at
/// shutdown.
struct SynthesisStop {
    abandoned: AtomicBool,
    server: Arc<AtomicBool>,
}

impl Stop for SynthesisStop {
    fn requested(&self) -> bool {
        self.abandoned.load(Ordering::Relaxed) || self.server.load(Ordering::Relaxed)
    }
}

/// Requests the stop of a synthesis when the future waiting for it ends, finished or dropped.
struct StopOnDrop(Arc<SynthesisStop>);

impl Drop for StopOnDrop {
    fn drop(&mut self) {
        self.0.abandoned.store(true, Ordering::Relaxed);
    }
}

/// What a caught panic says, for the log.
fn panic_message(panic: Box<dyn std::any::Any + Send>) -> String {
    match panic.downcast::<String>() {
        Ok(s) => format!("panic: {s}"),
        Err(p) => format!("panic: {}", p.downcast_ref::<&str>().unwrap_or(&"(no message)")),
    }
}

/// A miss that got no slot, or whose render shutdown stopped (a render stopped because its
/// requests left answers nobody).
fn busy(why: Refused) -> Error {
    Error::Busy(match why {
        Refused::Full => "too many tiles wait for synthesis; retry shortly".into(),
        Refused::Closed => "the server is shutting down".into(),
    })
}

/// A texture id from a request: checked before it can reach a file name.
pub fn check_id(id: &str) -> Result<(), Error> {
    if vtex_synth::bundle::is_valid_id(id) {
        return Ok(());
    }
    Err(Error::Invalid(format!("invalid texture id `{}`: expected 64 lowercase hex characters", echo(id))))
}

/// A store that cannot be reached now is a 503 to retry; anything else the server's failure.
pub fn store_failure(e: StoreError) -> Error {
    match e {
        StoreError::Unavailable(_) => Error::Busy(STORE_UNAVAILABLE.into()),
        e => Error::failed("reading the store failed", e),
    }
}

/// What a client is told when the object store does not answer (its cause is logged).
pub const STORE_UNAVAILABLE: &str = "the object store holding the encodings cannot be reached now; retry shortly";

fn no_texture(id: &str) -> Error {
    Error::Missing(format!("no texture with id {id}"))
}
