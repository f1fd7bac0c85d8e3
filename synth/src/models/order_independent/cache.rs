//! The pyramidal cache of the served evaluator (paper §3), shared by every order-independent
//! texture of the process: blocks of 32 × 32 entries of one (texture, level, generation) with
//! a validity bit each, in an LRU bounded in bytes and sharded against lock contention.
//!
//! An entry's value is a pure function of its tag, so the cache never changes a result: with a
//! budget of 0 (the default until [`set_cache_budget`] is called) nothing is kept at all.

use super::served::Rect;
use super::structure::Structure;
use crate::hash::fmix64;
use lru::LruCache;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{LazyLock, Mutex};

/// Side of a block, in entries.
const SIDE: i64 = 32;
const SHARDS: usize = 16;
/// Bytes one block holds: values, validity bits, and the LRU's bookkeeping.
pub const BLOCK_BYTES: u64 = (SIDE * SIDE) as u64 * 2 + (SIDE * SIDE) as u64 / 8 + 64;

static BUDGET: AtomicU64 = AtomicU64::new(0);
static CACHE: LazyLock<[Mutex<LruCache<Key, Block>>; SHARDS]> =
    LazyLock::new(|| std::array::from_fn(|_| Mutex::new(LruCache::unbounded())));

/// Sets the bytes all order-independent textures of the process may keep in their pyramidal
/// cache (0: none), evicting the least recently used blocks beyond it.
pub fn set_cache_budget(bytes: u64) {
    BUDGET.store(bytes, Ordering::Relaxed);
    for shard in CACHE.iter() {
        evict(&mut shard.lock().unwrap_or_else(|e| e.into_inner()));
    }
}

/// The budget last set.
pub fn cache_budget() -> u64 {
    BUDGET.load(Ordering::Relaxed)
}

/// Bytes the cache holds now.
pub fn cache_bytes() -> u64 {
    CACHE.iter().map(|s| s.lock().unwrap_or_else(|e| e.into_inner()).len() as u64 * BLOCK_BYTES).sum()
}

fn evict(lru: &mut LruCache<Key, Block>) {
    let cap = cache_budget() / SHARDS as u64 / BLOCK_BYTES;
    while lru.len() as u64 > cap {
        lru.pop_lru();
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
    valid: [u64; (SIDE * SIDE / 64) as usize],
}

impl Block {
    fn has(&self, k: usize) -> bool {
        self.valid[k / 64] >> (k % 64) & 1 == 1
    }
}

/// Pixels of one axis of a rectangle grouped by block: (block index, [(offset in the
/// rectangle, offset in the block)]), in the torus's reduced coordinates.
fn groups(start: i64, n: usize, period: Option<u64>) -> Vec<(i64, Vec<(usize, usize)>)> {
    let mut out: Vec<(i64, Vec<(usize, usize)>)> = Vec::new();
    for i in 0..n {
        let mut v = start.wrapping_add(i as i64);
        if let Some(p) = period {
            v = v.rem_euclid(p as i64);
        }
        let (b, o) = (v.div_euclid(SIDE), v.rem_euclid(SIDE) as usize);
        match out.last_mut() {
            Some((last, pixels)) if *last == b => pixels.push((i, o)),
            _ => out.push((b, vec![(i, o)])),
        }
    }
    out
}

/// One texture's view of the shared cache.
#[derive(Clone, Copy, Debug)]
pub struct Pyramid {
    texture: u64,
}

impl Pyramid {
    /// The view of the texture keyed `texture` (the start of its bundle's hash).
    pub fn new(texture: u64) -> Pyramid {
        Pyramid { texture }
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
        let cols = groups(rect.x, rect.w, period.map(|p| p.0));
        let rows = groups(rect.y, rect.h, period.map(|p| p.1));
        for (by, ys) in &rows {
            for (bx, xs) in &cols {
                f(Key { texture: self.texture, s, m, bx: *bx, by: *by }, xs, ys);
            }
        }
    }

    /// Copies the cached entries of (s, m) under `rect` that are `missing` into `values`, and
    /// clears their `missing` flag.
    pub fn load(&self, st: &Structure, s: u8, m: u8, rect: &Rect, missing: &mut [bool], values: &mut [u16]) {
        self.blocks(st, s, m, rect, |key, xs, ys| {
            let mut lru = CACHE[key.shard()].lock().unwrap_or_else(|e| e.into_inner());
            let Some(block) = lru.get(&key) else { return };
            for &(j, oy) in ys {
                for &(i, ox) in xs {
                    let (at, k) = (j * rect.w + i, oy * SIDE as usize + ox);
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
        self.blocks(st, s, m, rect, |key, xs, ys| {
            let any = ys.iter().any(|&(j, _)| xs.iter().any(|&(i, _)| computed.is_none_or(|c| c[j * rect.w + i])));
            if !any {
                return;
            }
            let mut lru = CACHE[key.shard()].lock().unwrap_or_else(|e| e.into_inner());
            let block = lru.get_or_insert_mut(key, || Block {
                values: vec![0; (SIDE * SIDE) as usize].into_boxed_slice(),
                valid: [0; (SIDE * SIDE / 64) as usize],
            });
            for &(j, oy) in ys {
                for &(i, ox) in xs {
                    let (at, k) = (j * rect.w + i, oy * SIDE as usize + ox);
                    if computed.is_none_or(|c| c[at]) {
                        debug_assert!(!block.has(k) || block.values[k] == values[at], "two values for one entry");
                        block.values[k] = values[at];
                        block.valid[k / 64] |= 1 << (k % 64);
                    }
                }
            }
            evict(&mut lru);
        });
    }
}
