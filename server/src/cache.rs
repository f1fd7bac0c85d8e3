//! The tile cache: encoded tiles in a sharded LRU bounded in bytes, with concurrent misses
//! on one key coalesced into a single computation.
//!
//! Each shard has an equal share of the budget and evicts least-recently-used tiles until
//! its bytes fit, under its own lock, so the sum over shards never exceeds the budget. A
//! tile larger than a quarter of a shard is served but not cached (it would flush the shard).

use crate::encode::Format;
use crate::transport::Transport;
use axum::http::HeaderValue;
use bytes::Bytes;
use lru::LruCache;
use std::collections::HashMap;
use std::future::Future;
use std::hash::{BuildHasher, Hash};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use tokio::sync::OnceCell;

/// Bookkeeping charged per entry on top of the tile bytes (key, LRU links, map slot, the
/// `Arc<Tile>` with its ETag, the sealed body's arena handle and registry entry).
pub const ENTRY_OVERHEAD: u64 = 320;
/// Shards are at least this large, so tiny budgets still hold whole tiles.
const MIN_SHARD_BYTES: u64 = 8 << 20;
const MAX_SHARDS: u64 = 16;

/// Identifies an encoded tile: everything its bytes depend on.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct TileKey {
    pub texture: [u8; 32],
    pub level: u32,
    pub x: u32,
    pub y: u32,
    pub frame: u32,
    pub format: Format,
}

/// An encoded tile as served.
#[derive(Debug)]
pub struct Tile {
    pub body: Bytes,
    /// Its strong ETag, hashed once when the tile is made rather than on every hit.
    pub etag: HeaderValue,
    pub width: u32,
    pub height: u32,
}

struct Shard {
    lru: LruCache<TileKey, Arc<Tile>>,
    bytes: u64,
}

type Pending = Arc<OnceCell<Arc<Tile>>>;

pub struct TileCache {
    shards: Vec<Mutex<Shard>>,
    shard_budget: u64,
    budget: u64,
    bytes: AtomicU64,
    evictions: AtomicU64,
    hasher: std::hash::RandomState,
    pending: Mutex<HashMap<TileKey, Pending>>,
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
        let shards = (0..n).map(|_| Mutex::new(Shard { lru: LruCache::unbounded(), bytes: 0 })).collect();
        TileCache {
            shards,
            shard_budget: budget_bytes / n,
            budget: budget_bytes / n * n,
            bytes: AtomicU64::new(0),
            evictions: AtomicU64::new(0),
            hasher: std::hash::RandomState::new(),
            pending: Mutex::new(HashMap::new()),
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

    pub fn len(&self) -> usize {
        self.shards.iter().map(|s| s.lock().unwrap().lru.len()).sum()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    pub fn evictions(&self) -> u64 {
        self.evictions.load(Ordering::Relaxed)
    }

    fn shard(&self, key: &TileKey) -> &Mutex<Shard> {
        let i = self.hasher.hash_one(key) % self.shards.len() as u64;
        &self.shards[i as usize]
    }

    pub fn get(&self, key: &TileKey) -> Option<Arc<Tile>> {
        self.shard(key).lock().unwrap().lru.get(key).cloned()
    }

    /// What `tile` is charged: the memory its body takes, plus [`ENTRY_OVERHEAD`].
    fn cost(&self, tile: &Tile) -> u64 {
        self.send.footprint(tile.body.len()) as u64 + ENTRY_OVERHEAD
    }

    pub fn insert(&self, key: TileKey, tile: Arc<Tile>) {
        let cost = self.cost(&tile);
        if cost > self.shard_budget / 4 {
            return;
        }
        let mut shard = self.shard(&key).lock().unwrap();
        if let Some(old) = shard.lru.put(key, tile) {
            shard.bytes -= self.cost(&old);
            self.bytes.fetch_sub(self.cost(&old), Ordering::Relaxed);
        }
        shard.bytes += cost;
        self.bytes.fetch_add(cost, Ordering::Relaxed);
        while shard.bytes > self.shard_budget {
            let (_, evicted) = shard.lru.pop_lru().expect("bytes > 0 implies an entry");
            shard.bytes -= self.cost(&evicted);
            self.bytes.fetch_sub(self.cost(&evicted), Ordering::Relaxed);
            self.evictions.fetch_add(1, Ordering::Relaxed);
        }
    }

    /// The tile for `key`, computing it with `compute` on a miss. Concurrent callers with
    /// the same key share one computation; a failed computation is retried by the next.
    pub async fn get_or_compute<F, Fut, E>(&self, key: TileKey, compute: F) -> Result<(Arc<Tile>, Source), E>
    where
        F: FnOnce() -> Fut,
        Fut: Future<Output = Result<Tile, E>>,
    {
        if let Some(tile) = self.get(&key) {
            return Ok((tile, Source::Hit));
        }
        let cell = self.pending.lock().unwrap().entry(key).or_default().clone();
        let result = cell
            .get_or_try_init(|| async {
                // A computation for this key may have finished between our miss and now.
                if let Some(tile) = self.get(&key) {
                    return Ok(tile);
                }
                let tile = Arc::new(compute().await?);
                self.insert(key, tile.clone());
                Ok(tile)
            })
            .await
            .cloned();
        {
            let mut pending = self.pending.lock().unwrap();
            if pending.get(&key).is_some_and(|c| Arc::ptr_eq(c, &cell)) && (cell.initialized() || result.is_err()) {
                pending.remove(&key);
            }
        }
        result.map(|t| (t, Source::Miss))
    }

    /// Keys waiting on a computation now (for tests and metrics).
    pub fn pending(&self) -> usize {
        self.pending.lock().unwrap().len()
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::atomic::AtomicUsize;

    fn key(x: u32) -> TileKey {
        TileKey { texture: [7; 32], level: 0, x, y: 0, frame: 0, format: Format::Png }
    }

    fn tile(n: usize) -> Arc<Tile> {
        Arc::new(Tile { body: Bytes::from(vec![1u8; n]), etag: HeaderValue::from_static("\"t\""), width: 1, height: 1 })
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

    #[tokio::test(flavor = "multi_thread", worker_threads = 4)]
    async fn concurrent_misses_compute_once() {
        let cache = Arc::new(TileCache::new(1 << 20, Transport::Copy));
        let runs = Arc::new(AtomicUsize::new(0));
        let mut tasks = Vec::new();
        for _ in 0..64 {
            let (cache, runs) = (cache.clone(), runs.clone());
            tasks.push(tokio::spawn(async move {
                cache
                    .get_or_compute(key(3), || async {
                        runs.fetch_add(1, Ordering::SeqCst);
                        tokio::time::sleep(std::time::Duration::from_millis(50)).await;
                        Ok::<_, ()>(Tile {
                            body: Bytes::from_static(b"abc"),
                            etag: HeaderValue::from_static("\"t\""),
                            width: 1,
                            height: 1,
                        })
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
        let (_, src) = cache.get_or_compute(key(3), || async { Err::<Tile, _>(()) }).await.unwrap();
        assert_eq!(src, Source::Hit);
    }

    #[tokio::test]
    async fn a_failed_computation_is_retried() {
        let cache = TileCache::new(1 << 20, Transport::Copy);
        assert!(cache.get_or_compute(key(1), || async { Err::<Tile, _>("boom") }).await.is_err());
        assert_eq!(cache.pending(), 0);
        let (t, src) = cache
            .get_or_compute(key(1), || async {
                Ok::<_, &str>(Tile {
                    body: Bytes::from_static(b"x"),
                    etag: HeaderValue::from_static("\"t\""),
                    width: 1,
                    height: 1,
                })
            })
            .await
            .unwrap();
        assert_eq!((&t.body[..], src), (&b"x"[..], Source::Miss));
    }
}
