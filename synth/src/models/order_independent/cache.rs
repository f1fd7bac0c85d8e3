//! The pyramidal cache of the served evaluator (paper §3): blocks of side × side entries of one
//! (texture, level, generation) with a validity bit each, in an LRU bounded in bytes and sharded
//! against lock contention. The textures loaded with one [`Resources`](crate::Resources) share
//! one cache of 32 × 32 blocks ([`super::shared`]); figures make others to compare block sides.
//!
//! An entry's value is a pure function of its tag, so the cache never changes a result: with a
//! budget of 0 nothing is kept at all.

use super::rect::Rect;
use super::structure::Structure;
use crate::hash::fmix64;
use lru::LruCache;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};

/// Side of the shared cache's blocks, in entries.
pub const SIDE: i64 = 32;
const SHARDS: usize = 16;
/// Bytes one block of the shared cache holds.
pub const BLOCK_BYTES: u64 = block_bytes(SIDE);

/// Bytes one block of `side` holds: values, validity bits, and the LRU's bookkeeping.
const fn block_bytes(side: i64) -> u64 {
    (side * side) as u64 * 2 + (side * side) as u64 / 8 + 64
}

/// A pyramidal cache: blocks of `side` × `side` entries in a sharded LRU bounded in bytes.
pub struct BlockCache {
    side: i64,
    budget: AtomicU64,
    shards: [Mutex<LruCache<Key, Block>>; SHARDS],
}

impl BlockCache {
    /// An empty cache of `side` × `side` blocks, with no budget.
    pub fn new(side: i64) -> BlockCache {
        assert!(side > 0, "a block side is positive");
        BlockCache {
            side,
            budget: AtomicU64::new(0),
            shards: std::array::from_fn(|_| Mutex::new(LruCache::unbounded())),
        }
    }

    pub fn set_budget(&self, bytes: u64) {
        self.budget.store(bytes, Ordering::Relaxed);
        for shard in &self.shards {
            self.evict(&mut shard.lock().unwrap_or_else(|e| e.into_inner()));
        }
    }

    pub fn budget(&self) -> u64 {
        self.budget.load(Ordering::Relaxed)
    }

    pub fn bytes(&self) -> u64 {
        let blocks: usize = self.shards.iter().map(|s| s.lock().unwrap_or_else(|e| e.into_inner()).len()).sum();
        blocks as u64 * block_bytes(self.side)
    }

    fn evict(&self, lru: &mut LruCache<Key, Block>) {
        let cap = self.budget() / SHARDS as u64 / block_bytes(self.side);
        while lru.len() as u64 > cap {
            lru.pop_lru();
        }
    }

    fn shard(&self, key: &Key) -> std::sync::MutexGuard<'_, LruCache<Key, Block>> {
        self.shards[key.shard()].lock().unwrap_or_else(|e| e.into_inner())
    }
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
struct Key {
    texture: u64,
    s: u8,
    m: u8,
    bx: i64,
    by: i64,
}

impl Key {
    fn shard(&self) -> usize {
        let h = fmix64(
            self.texture ^ fmix64(self.bx as u64 ^ fmix64(self.by as u64 ^ ((self.s as u64) << 8 | self.m as u64))),
        );
        (h as usize) % SHARDS
    }
}

struct Block {
    values: Box<[u16]>,
    valid: Box<[u64]>,
}

impl Block {
    fn has(&self, k: usize) -> bool {
        self.valid[k / 64] >> (k % 64) & 1 == 1
    }
}

/// Pixels of one axis of a rectangle grouped by block: (block index, [(offset in the
/// rectangle, offset in the block)]), in the torus's reduced coordinates.
fn groups(side: i64, start: i64, n: usize, period: Option<u64>) -> Vec<(i64, Vec<(usize, usize)>)> {
    let mut out: Vec<(i64, Vec<(usize, usize)>)> = Vec::new();
    for i in 0..n {
        let mut v = start.wrapping_add(i as i64);
        if let Some(p) = period {
            v = v.rem_euclid(p as i64);
        }
        let (b, o) = (v.div_euclid(side), v.rem_euclid(side) as usize);
        match out.last_mut() {
            Some((last, pixels)) if *last == b => pixels.push((i, o)),
            _ => out.push((b, vec![(i, o)])),
        }
    }
    out
}

/// One texture's view of a cache.
#[derive(Clone)]
pub struct Pyramid {
    texture: u64,
    cache: Arc<BlockCache>,
}

impl std::fmt::Debug for Pyramid {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Pyramid({:016x}, blocks of {})", self.texture, self.cache.side)
    }
}

impl Pyramid {
    /// The view of `cache` of the texture keyed `texture` (the start of its bundle's hash).
    pub fn new(texture: u64, cache: Arc<BlockCache>) -> Pyramid {
        Pyramid { texture, cache }
    }

    /// The same texture's view of `cache` instead.
    pub fn in_cache(self, cache: Arc<BlockCache>) -> Pyramid {
        Pyramid { cache, ..self }
    }

    /// The cache this view reads and fills.
    pub fn cache(&self) -> &BlockCache {
        &self.cache
    }

    /// Visits every block under `rect` of (s, m) with the rectangle pixels it holds.
    fn blocks(
        &self,
        st: &Structure,
        s: u8,
        m: u8,
        rect: &Rect,
        mut f: impl FnMut(Key, &[(usize, usize)], &[(usize, usize)]),
    ) {
        let period = st.period(s);
        let side = self.cache.side;
        let cols = groups(side, rect.x, rect.w, period.map(|p| p.0));
        let rows = groups(side, rect.y, rect.h, period.map(|p| p.1));
        for (by, ys) in &rows {
            for (bx, xs) in &cols {
                f(Key { texture: self.texture, s, m, bx: *bx, by: *by }, xs, ys);
            }
        }
    }

    /// Copies the cached entries of (s, m) under `rect` that are `missing` into `values`, and
    /// clears their `missing` flag.
    pub fn load(&self, st: &Structure, s: u8, m: u8, rect: &Rect, missing: &mut [bool], values: &mut [u16]) {
        let side = self.cache.side as usize;
        self.blocks(st, s, m, rect, |key, xs, ys| {
            let mut lru = self.cache.shard(&key);
            let Some(block) = lru.get(&key) else { return };
            for &(j, oy) in ys {
                for &(i, ox) in xs {
                    let (at, k) = (j * rect.w + i, oy * side + ox);
                    if missing[at] && block.has(k) {
                        values[at] = block.values[k];
                        missing[at] = false;
                    }
                }
            }
        });
    }

    /// Merges the entries of (s, m) under `rect` that were `computed` (`None`: all).
    pub fn store(&self, st: &Structure, s: u8, m: u8, rect: &Rect, computed: Option<&[bool]>, values: &[u16]) {
        let side = self.cache.side as usize;
        self.blocks(st, s, m, rect, |key, xs, ys| {
            let any = ys.iter().any(|&(j, _)| xs.iter().any(|&(i, _)| computed.is_none_or(|c| c[j * rect.w + i])));
            if !any {
                return;
            }
            let mut lru = self.cache.shard(&key);
            let block = lru.get_or_insert_mut(key, || Block {
                values: vec![0; side * side].into_boxed_slice(),
                valid: vec![0; (side * side).div_ceil(64)].into_boxed_slice(),
            });
            for &(j, oy) in ys {
                for &(i, ox) in xs {
                    let (at, k) = (j * rect.w + i, oy * side + ox);
                    if computed.is_none_or(|c| c[at]) {
                        debug_assert!(!block.has(k) || block.values[k] == values[at], "two values for one entry");
                        block.values[k] = values[at];
                        block.valid[k / 64] |= 1 << (k % 64);
                    }
                }
            }
            self.cache.evict(&mut lru);
        });
    }
}
