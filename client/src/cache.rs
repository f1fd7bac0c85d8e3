//! The client's page cache: pages by address, least recently used evicted first, bounded in
//! the bytes of their bodies.

use crate::{Page, PageKey};
use lru::LruCache;

pub struct PageCache {
    lru: LruCache<PageKey, Page>,
    bytes: u64,
    budget: u64,
}

impl PageCache {
    pub fn new(budget_bytes: u64) -> Self {
        PageCache { lru: LruCache::unbounded(), bytes: 0, budget: budget_bytes }
    }

    pub fn get(&mut self, key: &PageKey) -> Option<Page> {
        self.lru.get(key).cloned()
    }

    /// Whether `key` is held, without making it the most recently used.
    pub fn contains(&self, key: &PageKey) -> bool {
        self.lru.contains(key)
    }

    /// Holds `page` under `key`, evicting the least recently used pages until the budget
    /// holds. A page larger than the whole budget is not kept.
    pub fn insert(&mut self, key: PageKey, page: Page) {
        let cost = page.bytes.len() as u64;
        if cost > self.budget {
            return;
        }
        if let Some(old) = self.lru.put(key, page) {
            self.bytes -= old.bytes.len() as u64;
        }
        self.bytes += cost;
        while self.bytes > self.budget {
            let (_, evicted) = self.lru.pop_lru().expect("bytes over budget means pages are held");
            self.bytes -= evicted.bytes.len() as u64;
        }
    }

    /// Bytes of the pages held; never above the budget.
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
    use crate::{PageAddr, PageSpec};

    fn page(n: usize) -> Page {
        Page { addr: PageAddr { level: 0, x: 0, y: 0 }, width: 1, height: 1, bytes: vec![0; n].into(), etag: None }
    }

    fn key(x: u32) -> PageKey {
        PageKey { texture: "t".into(), addr: PageAddr { level: 0, x, y: 0 }, spec: PageSpec::default() }
    }

    #[test]
    fn the_budget_holds_and_the_least_recent_goes_first() {
        let mut c = PageCache::new(100);
        for x in 0..3 {
            c.insert(key(x), page(40));
        }
        assert_eq!((c.len(), c.bytes()), (2, 80));
        assert!(!c.contains(&key(0)));
        c.get(&key(1));
        c.insert(key(3), page(40));
        assert!(c.contains(&key(1)) && !c.contains(&key(2)), "a page read recently stays");
        c.insert(key(9), page(101));
        assert!(!c.contains(&key(9)), "larger than the budget: not kept");
        assert!(c.bytes() <= 100);
    }
}
