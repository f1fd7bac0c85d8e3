//! The tile cache: encoded tiles in a sharded LRU bounded in bytes, with concurrent misses
//! on one key coalesced into a single computation.
//!
//! Each shard has an equal share of the budget and evicts least-recently-used tiles until
//! its bytes fit, under its own lock, so the sum over shards never exceeds the budget. A
//! tile larger than a quarter of a shard is served but not cached (it would flush the shard).
//!
//! The budget also covers the cache's bodies that live on outside it: a body evicted (or never
//! cached) while responses still send it keeps its memory until the last one is done. Every body
//! the cache makes is counted while it lives, and each insert shrinks the shards' share by what
//! lives outside, so the memory behind the cache stays within its budget while readers are slow.

use super::{ETag, Error};
use crate::byte_lru::ByteLru;
use crate::encode::Format;
use crate::transport::Transport;
use bytes::Bytes;
use std::collections::HashMap;
use std::future::Future;
use std::hash::{BuildHasher, Hash};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::watch;
use tokio::task::AbortHandle;
use vtex_synth::layer::Layer;

/// Bookkeeping charged per entry on top of the tile bytes (key, LRU links, map slot, the
/// `Arc<Tile>` with its ETag, the sealed body's arena handle and registry entry).
pub const ENTRY_OVERHEAD: u64 = 320;
/// Shards are at least this large, so tiny budgets still hold whole tiles.
const MIN_SHARD_BYTES: u64 = 8 << 20;
const MAX_SHARDS: u64 = 16;

/// Identifies an encoded tile or page: everything its bytes depend on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileKey {
    pub texture: [u8; 32],
    pub level: u32,
    pub x: u32,
    pub y: u32,
    pub frame: u32,
    pub format: Format,
    pub shape: Shape,
}

/// What (`level`, `x`, `y`) of a [`TileKey`] addresses.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Shape {
    /// A map tile of the server's `--tile-size`, clipped at the level's edges.
    Tile,
    /// An edge tile drawn on the whole `--tile-size` square, transparent beyond the level:
    /// XYZ clients stretch every tile image to a full square.
    Square,
    /// A metatile: the aligned block of `side` × `side` tiles whose top left tile is
    /// (`x`·side, `y`·side), clipped at the level's edges, as one body of
    /// [`vtex_wire::frame`]s (row by row). The tiles' own keys find their bytes in it.
    Metatile { side: u32 },
    /// A `size`² page of the page grid with `border` pixels of its neighbours on every side
    /// (`api/resources/pages.rs`), of one layer of the texture.
    Page { size: u32, border: u32, layer: Layer },
    /// A page metatile: the aligned block of `side` × `side` pages of the page grid whose top
    /// left page is (`x`·side, `y`·side), clipped at the grid's edges, as one body of frames.
    /// The pages' own keys find their bytes in it.
    PageMetatile { size: u32, border: u32, side: u32, layer: Layer },
}

impl Shape {
    /// The layer the key's pixels are of: pages may be of any, everything else is colour.
    pub fn layer(self) -> Layer {
        match self {
            Shape::Page { layer, .. } | Shape::PageMetatile { layer, .. } => layer,
            _ => Layer::Color,
        }
    }

    /// Whether the key names a block of tiles or pages, answered as frames.
    pub fn is_metatile(self) -> bool {
        matches!(self, Shape::Metatile { .. } | Shape::PageMetatile { .. })
    }
}

/// An encoded tile as served.
#[derive(Debug)]
pub struct Tile {
    pub body: Bytes,
    /// Its strong ETag, hashed once when the tile is made rather than on every hit.
    pub etag: ETag,
    pub width: u32,
    pub height: u32,
}

pub struct TileCache {
    shards: Vec<Mutex<ByteLru<TileKey, Arc<Tile>>>>,
    shard_budget: u64,
    budget: u64,
    bytes: AtomicU64,
    /// Memory of the bodies counted in `bytes` (their [`Transport::footprint`]).
    held: AtomicU64,
    /// Memory of every body this cache made that is still alive, cached or not.
    alive: Arc<AtomicU64>,
    evictions: AtomicU64,
    hasher: std::hash::RandomState,
    pending: Mutex<HashMap<TileKey, Flight>>,
    next_flight: AtomicU64,
    /// How bodies are held, which decides the memory each one takes.
    send: Transport,
}

/// How a tile was obtained.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// Found in the cache.
    Hit,
    /// Computed for this request, or by a concurrent request for the same key it waited on.
    Miss,
}

impl TileCache {
    /// A cache of `budget_bytes` for bodies [`Transport::seal`]ed by `send`.
    pub fn new(budget_bytes: u64, send: Transport) -> Self {
        let n = (budget_bytes / MIN_SHARD_BYTES).clamp(1, MAX_SHARDS);
        let shards = (0..n).map(|_| Mutex::default()).collect();
        TileCache {
            shards,
            shard_budget: budget_bytes / n,
            budget: budget_bytes / n * n,
            bytes: AtomicU64::new(0),
            held: AtomicU64::new(0),
            alive: Arc::new(AtomicU64::new(0)),
            evictions: AtomicU64::new(0),
            hasher: std::hash::RandomState::new(),
            pending: Mutex::new(HashMap::new()),
            next_flight: AtomicU64::new(0),
            send,
        }
    }

    /// The budget actually enforced (the configured one rounded down to whole shards).
    pub fn budget(&self) -> u64 {
        self.budget
    }

    /// Bytes held now (tile bytes plus [`ENTRY_OVERHEAD`] each); never above [`Self::budget`].
    pub fn bytes(&self) -> u64 {
        self.bytes.load(Ordering::Relaxed)
    }

    /// Memory of bodies the cache made that it no longer holds (evicted, or too large to keep)
    /// but that responses still send: charged against its budget too.
    pub fn outside(&self) -> u64 {
        self.alive.load(Ordering::Relaxed).saturating_sub(self.held.load(Ordering::Relaxed))
    }

    pub fn len(&self) -> usize {
        self.shards.iter().map(|s| s.lock().unwrap().len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn evictions(&self) -> u64 {
        self.evictions.load(Ordering::Relaxed)
    }

    fn shard(&self, key: &TileKey) -> &Mutex<ByteLru<TileKey, Arc<Tile>>> {
        let i = self.hasher.hash_one(key) % self.shards.len() as u64;
        &self.shards[i as usize]
    }

    pub fn get(&self, key: &TileKey) -> Option<Arc<Tile>> {
        self.shard(key).lock().unwrap().get(key).cloned()
    }

    /// What `tile` is charged: the memory its body takes, plus [`ENTRY_OVERHEAD`].
    fn cost(&self, tile: &Tile) -> u64 {
        self.send.footprint(tile.body.len()) as u64 + ENTRY_OVERHEAD
    }

    /// What a computation passes its tile through: its body counted in `alive` for as long as
    /// any part of it lives (a slice served from a metatile included).
    fn counter(&self) -> impl FnOnce(Tile) -> Tile + Send + 'static {
        let (alive, send) = (self.alive.clone(), self.send);
        move |tile| {
            let memory = send.footprint(tile.body.len()) as u64;
            alive.fetch_add(memory, Ordering::Relaxed);
            Tile { body: Bytes::from_owner(Counted { body: tile.body, memory, alive }), ..tile }
        }
    }

    fn insert(&self, key: TileKey, tile: Arc<Tile>) {
        let cost = self.cost(&tile);
        if cost > self.shard_budget / 4 {
            return;
        }
        let mut shard = self.shard(&key).lock().unwrap();
        self.bytes.fetch_add(cost, Ordering::Relaxed);
        self.held.fetch_add(cost - ENTRY_OVERHEAD, Ordering::Relaxed);
        if let Some(old) = shard.put(key, tile, cost) {
            self.release(old, 1);
        }
        let share = self.shard_budget.saturating_sub(self.outside() / self.shards.len() as u64);
        let (evicted, freed) = shard.evict_to(share);
        self.release(freed, evicted);
        self.evictions.fetch_add(evicted, Ordering::Relaxed);
    }

    /// Uncharges `entries` tiles that were charged `cost` in all.
    fn release(&self, cost: u64, entries: u64) {
        self.bytes.fetch_sub(cost, Ordering::Relaxed);
        self.held.fetch_sub(cost - entries * ENTRY_OVERHEAD, Ordering::Relaxed);
    }

    /// The tile for `key`, computing it with `compute` on a miss. Concurrent callers with
    /// the same key share one computation, which runs as a task of its own for as long as one
    /// of them still waits: when the last leaves (its request dropped: a client gone, a
    /// deadline passed), the task is aborted. An error answers every caller waiting then;
    /// the next caller computes again.
    pub async fn get_or_compute<F, Fut>(&self, key: TileKey, compute: F) -> Result<(Arc<Tile>, Source), Error>
    where
        F: FnOnce() -> Fut,
        Fut: Future<Output = Result<Tile, Error>> + Send + 'static,
    {
        if let Some(tile) = self.get(&key) {
            return Ok((tile, Source::Hit));
        }
        let (mut result, id) = {
            let mut pending = self.pending.lock().unwrap();
            if let Some(flight) = pending.get_mut(&key) {
                flight.waiters += 1;
                (flight.result.clone(), flight.id)
            } else {
                // A computation for this key may have finished between our miss and now: it
                // inserts its tile before it leaves `pending`, under this lock.
                if let Some(tile) = self.get(&key) {
                    return Ok((tile, Source::Miss));
                }
                let (tx, rx) = watch::channel(None);
                let fut = compute();
                let counted = self.counter();
                let task = tokio::spawn(async move {
                    let _ = tx.send(Some(fut.await.map(|tile| Arc::new(counted(tile)))));
                });
                let id = self.next_flight.fetch_add(1, Ordering::Relaxed);
                pending.insert(key, Flight { result: rx.clone(), waiters: 1, task: task.abort_handle(), id });
                (rx, id)
            }
        };
        let waiting = Waiting { cache: self, key, id };
        let outcome = match result.wait_for(Option::is_some).await {
            Ok(done) => done.clone().expect("waited for a result"),
            // The task panicked, or its runtime ended.
            Err(_) => Err(Error::failed("synthesis failed", "the computation ended without a result")),
        };
        // Whichever waiter sees the result first caches it and retires the flight.
        let mut pending = self.pending.lock().unwrap();
        if pending.get(&key).is_some_and(|f| f.id == id) {
            pending.remove(&key);
            if let Ok(tile) = &outcome {
                self.insert(key, tile.clone());
            }
        }
        drop(pending);
        // The flight is retired: leaving it changes nothing.
        drop(waiting);
        outcome.map(|t| (t, Source::Miss))
    }

    /// Keys waiting on a computation now (for tests and metrics).
    pub fn pending(&self) -> usize {
        self.pending.lock().unwrap().len()
    }
}

/// A body made by the cache, uncounted from its `alive` when the last reference goes.
struct Counted {
    body: Bytes,
    memory: u64,
    alive: Arc<AtomicU64>,
}

impl AsRef<[u8]> for Counted {
    fn as_ref(&self) -> &[u8] {
        &self.body
    }
}

impl Drop for Counted {
    fn drop(&mut self) {
        self.alive.fetch_sub(self.memory, Ordering::Relaxed);
    }
}

/// A computation in progress and the requests waiting for it.
struct Flight {
    result: watch::Receiver<Option<Result<Arc<Tile>, Error>>>,
    waiters: usize,
    task: AbortHandle,
    /// Tells this flight from a later one for the same key.
    id: u64,
}

/// One request waiting on a [`Flight`]; dropped before the result came, it leaves, and the
/// last to leave aborts the computation.
struct Waiting<'a> {
    cache: &'a TileCache,
    key: TileKey,
    id: u64,
}

impl Drop for Waiting<'_> {
    fn drop(&mut self) {
        let mut pending = self.cache.pending.lock().unwrap();
        if let Some(flight) = pending.get_mut(&self.key).filter(|f| f.id == self.id) {
            flight.waiters -= 1;
            if flight.waiters == 0 {
                flight.task.abort();
                pending.remove(&self.key);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::{AtomicBool, AtomicUsize};

    fn key(x: u32) -> TileKey {
        TileKey { texture: [7; 32], level: 0, x, y: 0, frame: 0, format: Format::Png, shape: Shape::Tile }
    }

    fn tile(n: usize) -> Arc<Tile> {
        Arc::new(Tile {
            body: Bytes::from(vec![1u8; n]),
            etag: ETag::new(&[0; 32], None, &[], Format::Png),
            width: 1,
            height: 1,
        })
    }

    #[test]
    fn budget_holds_and_lru_evicts_oldest() {
        let cache = TileCache::new(1 << 20, Transport::Copy);
        assert_eq!(cache.budget(), 1 << 20);
        for x in 0..1000 {
            cache.insert(key(x), tile(10_000));
            assert!(cache.bytes() <= cache.budget());
        }
        let per = 10_000 + ENTRY_OVERHEAD;
        assert_eq!(cache.len() as u64, (1 << 20) / per);
        assert!(cache.get(&key(999)).is_some());
        assert!(cache.get(&key(0)).is_none());
        // Touching an old entry protects it from the next eviction.
        let oldest = 1000 - cache.len() as u32;
        assert!(cache.get(&key(oldest)).is_some());
        cache.insert(key(5000), tile(10_000));
        assert!(cache.get(&key(oldest)).is_some());
        assert!(cache.get(&key(oldest + 1)).is_none());
    }

    #[test]
    fn oversized_tiles_are_not_cached() {
        let cache = TileCache::new(1 << 20, Transport::Copy);
        cache.insert(key(1), tile(300_000));
        assert!(cache.is_empty());
        assert_eq!(cache.bytes(), 0);
    }

    #[test]
    fn replacing_a_key_keeps_the_count_exact() {
        let cache = TileCache::new(1 << 20, Transport::Copy);
        cache.insert(key(1), tile(100));
        cache.insert(key(1), tile(200));
        assert_eq!(cache.bytes(), 200 + ENTRY_OVERHEAD);
    }

    /// Sealed bodies take whole pages, and the budget counts them so.
    #[cfg(target_os = "linux")]
    #[test]
    fn splice_charges_the_pages_a_sealed_body_takes() {
        let cache = TileCache::new(1 << 20, Transport::Splice);
        cache.insert(key(1), tile(20_000));
        assert_eq!(cache.bytes(), 5 * 4096 + ENTRY_OVERHEAD);
        cache.insert(key(2), tile(100));
        assert_eq!(cache.bytes(), 5 * 4096 + 100 + 2 * ENTRY_OVERHEAD, "small bodies stay unsealed");
    }

    /// Tiles still being sent after their eviction keep their memory: the cache holds less
    /// while they live, and fills its budget again once they are gone.
    #[tokio::test]
    async fn bodies_alive_outside_the_cache_count_against_its_budget() {
        let cache = TileCache::new(1 << 20, Transport::Copy);
        let make = |x| cache.get_or_compute(key(x), || async { Ok(Arc::into_inner(tile(100_000)).unwrap()) });
        let per = 100_000 + ENTRY_OVERHEAD;
        let mut sending = Vec::new();
        for x in 0..6 {
            sending.push(make(x).await.unwrap().0);
        }
        for x in 6..40 {
            make(x).await.unwrap();
            // From the insert after the last of the six was evicted on.
            if x >= 20 {
                assert!(cache.bytes() + cache.outside() <= cache.budget(), "tile {x}: cached and still sent");
            }
        }
        assert_eq!(cache.outside(), 6 * 100_000, "the six tiles being sent were evicted");
        assert_eq!(cache.len() as u64, ((1 << 20) - 6 * 100_000) / per);
        drop(sending);
        assert_eq!(cache.outside(), 0);
        for x in 40..60 {
            make(x).await.unwrap();
        }
        assert_eq!(cache.len() as u64, (1 << 20) / per, "the whole budget is the cache's again");
    }

    fn small(body: &'static [u8]) -> Tile {
        Tile { body: Bytes::from_static(body), etag: ETag::new(&[0; 32], None, &[], Format::Png), width: 1, height: 1 }
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 4)]
    async fn concurrent_misses_compute_once() {
        let cache = Arc::new(TileCache::new(1 << 20, Transport::Copy));
        let runs = Arc::new(AtomicUsize::new(0));
        let mut tasks = Vec::new();
        for _ in 0..64 {
            let (cache, runs) = (cache.clone(), runs.clone());
            tasks.push(tokio::spawn(async move {
                cache
                    .get_or_compute(key(3), || async move {
                        runs.fetch_add(1, Ordering::SeqCst);
                        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                        Ok(small(b"abc"))
                    })
                    .await
                    .unwrap()
            }));
        }
        for t in tasks {
            assert_eq!(&t.await.unwrap().0.body[..], b"abc");
        }
        assert_eq!(runs.load(Ordering::SeqCst), 1);
        assert_eq!(cache.pending(), 0);
        let (_, src) = cache.get_or_compute(key(3), || async { Err(Error::Invalid("unused".into())) }).await.unwrap();
        assert_eq!(src, Source::Hit);
    }

    #[tokio::test]
    async fn a_failed_computation_is_retried() {
        let cache = TileCache::new(1 << 20, Transport::Copy);
        let failed = cache.get_or_compute(key(1), || async { Err(Error::Invalid("boom".into())) }).await;
        assert!(failed.is_err());
        assert_eq!(cache.pending(), 0);
        let (t, src) = cache.get_or_compute(key(1), || async { Ok(small(b"x")) }).await.unwrap();
        assert_eq!((&t.body[..], src), (&b"x"[..], Source::Miss));
    }

    /// A computation that waits for `go`, and sets `dropped` if it is dropped unfinished.
    fn gated(go: Arc<tokio::sync::Notify>, dropped: Arc<AtomicBool>) -> impl Future<Output = Result<Tile, Error>> {
        struct SetOnDrop(Option<Arc<AtomicBool>>);
        impl Drop for SetOnDrop {
            fn drop(&mut self) {
                if let Some(flag) = &self.0 {
                    flag.store(true, Ordering::SeqCst);
                }
            }
        }
        async move {
            let mut armed = SetOnDrop(Some(dropped));
            go.notified().await;
            armed.0 = None;
            Ok(small(b"done"))
        }
    }

    /// Lets spawned tasks run until `cond` holds.
    async fn until(cond: impl Fn() -> bool) {
        for _ in 0..1000 {
            if cond() {
                return;
            }
            tokio::time::sleep(std::time::Duration::from_millis(1)).await;
        }
        panic!("condition not reached");
    }

    #[tokio::test]
    async fn one_waiter_leaving_does_not_stop_the_computation_another_waits_for() {
        let cache = Arc::new(TileCache::new(1 << 20, Transport::Copy));
        let (go, dropped) = (Arc::new(tokio::sync::Notify::new()), Arc::new(AtomicBool::new(false)));
        let first = {
            let (cache, go, dropped) = (cache.clone(), go.clone(), dropped.clone());
            tokio::spawn(async move { cache.get_or_compute(key(5), || gated(go, dropped)).await })
        };
        until(|| cache.pending() == 1).await;
        let second = {
            let cache = cache.clone();
            tokio::spawn(async move { cache.get_or_compute(key(5), || async { unreachable!("coalesced") }).await })
        };
        until(|| cache.pending.lock().unwrap().get(&key(5)).is_some_and(|f| f.waiters == 2)).await;
        first.abort();
        assert!(first.await.unwrap_err().is_cancelled());
        assert!(!dropped.load(Ordering::SeqCst), "the second waiter still waits: the computation goes on");
        go.notify_one();
        let (tile, src) = second.await.unwrap().unwrap();
        assert_eq!((&tile.body[..], src), (&b"done"[..], Source::Miss));
        assert!(cache.get(&key(5)).is_some() && cache.pending() == 0);
    }

    #[tokio::test]
    async fn the_last_waiter_leaving_aborts_the_computation() {
        let cache = Arc::new(TileCache::new(1 << 20, Transport::Copy));
        let (go, dropped) = (Arc::new(tokio::sync::Notify::new()), Arc::new(AtomicBool::new(false)));
        let only = {
            let (cache, go, dropped) = (cache.clone(), go.clone(), dropped.clone());
            tokio::spawn(async move { cache.get_or_compute(key(6), || gated(go, dropped)).await })
        };
        until(|| cache.pending() == 1).await;
        only.abort();
        until(|| dropped.load(Ordering::SeqCst)).await;
        assert_eq!(cache.pending(), 0);
        // The next request computes afresh.
        let (tile, _) = cache.get_or_compute(key(6), || async { Ok(small(b"again")) }).await.unwrap();
        assert_eq!(&tile.body[..], b"again");
    }
}
