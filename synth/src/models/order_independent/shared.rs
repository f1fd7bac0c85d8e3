//! What the order-independent textures loaded with one [`Resources`](crate::Resources) share:
//! the pyramidal cache (paper §3) and the counters of the work their renders do.

use super::cache::{BlockCache, SIDE};
use crate::resources::Part;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::Arc;

/// The model's part of a [`Resources`](crate::Resources).
pub struct Shared {
    pub(super) cache: Arc<BlockCache>,
    pub(super) work: Work,
}

impl Shared {
    /// A cache of blocks of [`SIDE`] holding at most `cache_budget` bytes, and zeroed counters.
    pub fn new(cache_budget: u64) -> Shared {
        let cache = BlockCache::new(SIDE);
        cache.set_budget(cache_budget);
        Shared { cache: Arc::new(cache), work: Work::default() }
    }
}

impl Part for Shared {
    fn cache_bytes(&self) -> u64 {
        self.cache.bytes()
    }
    fn work(&self) -> Vec<(&'static str, u64)> {
        self.work.counters()
    }
}

/// Work counted by renders, by kind: `entries_computed` is every entry filled, noise included
/// as the paper counts it, so that over `pixels_requested` it is the paper's computation ratio;
/// `noise_entries` is the noise part of it.
#[derive(Default)]
pub(super) struct Work {
    computed: AtomicU64,
    noise: AtomicU64,
    requested: AtomicU64,
}

impl Work {
    pub(super) fn add(&self, computed: u64, noise: u64, requested: u64) {
        self.computed.fetch_add(computed, Ordering::Relaxed);
        self.noise.fetch_add(noise, Ordering::Relaxed);
        self.requested.fetch_add(requested, Ordering::Relaxed);
    }

    pub(super) fn counters(&self) -> Vec<(&'static str, u64)> {
        vec![
            ("entries_computed", self.computed.load(Ordering::Relaxed)),
            ("noise_entries", self.noise.load(Ordering::Relaxed)),
            ("pixels_requested", self.requested.load(Ordering::Relaxed)),
        ]
    }
}
