//! [`ByteLru`]: values in least-recently-used order, each weighed in bytes — the one such
//! structure of the server, under the tile cache's shards and the store's loaded textures.
//!
//! It keeps the weights and their sum; the owner decides what the budget is and when to evict
//! ([`ByteLru::evict_to`]), since the tile cache evicts per shard after an insert and the store
//! evicts before a load, counting loads in progress against the same budget.

use lru::LruCache;
use std::borrow::Borrow;
use std::hash::Hash;

pub struct ByteLru<K, V> {
    lru: LruCache<K, (V, u64)>,
    bytes: u64,
}

impl<K: Hash + Eq, V> Default for ByteLru<K, V> {
    fn default() -> Self {
        ByteLru { lru: LruCache::unbounded(), bytes: 0 }
    }
}

impl<K: Hash + Eq, V> ByteLru<K, V> {
    /// The value of `key`, now the most recently used.
    pub fn get<Q>(&mut self, key: &Q) -> Option<&V>
    where
        K: Borrow<Q>,
        Q: Hash + Eq + ?Sized,
    {
        self.lru.get(key).map(|(v, _)| v)
    }

    /// Keeps `value` under `key`, weighing `bytes`, as the most recently used; returns the
    /// weight of the value it replaced.
    pub fn put(&mut self, key: K, value: V, bytes: u64) -> Option<u64> {
        self.bytes += bytes;
        let old = self.lru.put(key, (value, bytes)).map(|(_, w)| w);
        self.bytes -= old.unwrap_or(0);
        old
    }

    /// Removes `key`; returns the weight it had.
    pub fn pop<Q>(&mut self, key: &Q) -> Option<u64>
    where
        K: Borrow<Q>,
        Q: Hash + Eq + ?Sized,
    {
        let (_, w) = self.lru.pop(key)?;
        self.bytes -= w;
        Some(w)
    }

    /// Removes the least recently used value; returns its key and weight.
    pub fn pop_lru(&mut self) -> Option<(K, u64)> {
        let (k, (_, w)) = self.lru.pop_lru()?;
        self.bytes -= w;
        Some((k, w))
    }

    /// Removes least recently used values until the weights sum to at most `budget`; returns
    /// how many values it removed and their weight.
    pub fn evict_to(&mut self, budget: u64) -> (u64, u64) {
        let (mut count, mut bytes) = (0, 0);
        while self.bytes > budget {
            let Some((_, w)) = self.pop_lru() else { break };
            (count, bytes) = (count + 1, bytes + w);
        }
        (count, bytes)
    }

    /// The sum of the weights.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    pub fn len(&self) -> usize {
        self.lru.len()
    }

    pub fn is_empty(&self) -> bool {
        self.lru.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weights_follow_puts_pops_and_evictions() {
        let mut lru: ByteLru<&str, u32> = ByteLru::default();
        assert_eq!(lru.put("a", 1, 40), None);
        lru.put("b", 2, 40);
        assert_eq!(lru.put("b", 3, 30), Some(40), "a replaced value gives its weight back");
        assert_eq!((lru.bytes(), lru.len()), (70, 2));
        assert_eq!(lru.get("a"), Some(&1), "a is now the most recently used");
        lru.put("c", 4, 50);
        assert_eq!(lru.evict_to(100), (1, 30), "b, the least recently used, goes");
        assert_eq!(lru.get("b"), None);
        assert_eq!(lru.bytes(), 90);
        assert_eq!(lru.pop("a"), Some(40));
        assert_eq!(lru.pop_lru(), Some(("c", 50)));
        assert!(lru.is_empty() && lru.bytes() == 0);
    }
}
