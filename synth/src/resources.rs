//! What the textures of one owner share: each model's caches, within one byte budget a model,
//! and the counters of the work their renders do.
//!
//! The owner — the server, a test, a command — makes one [`Resources`] and hands it to
//! [`crate::models::load_with`] for every texture it loads. Nothing is kept process-wide, so two
//! owners in one process (two servers in one test binary) never see each other's caches or
//! counts. A cache never changes a result: it only saves recomputing what it holds.

use crate::models::REGISTRY;
use std::any::Any;
use std::sync::Arc;

/// One model's shared part of a [`Resources`] (made by [`crate::models::Model::resources`]).
pub trait Part: Send + Sync + 'static {
    /// Bytes its caches hold now.
    fn cache_bytes(&self) -> u64;
    /// Running totals of the work its textures' renders have done, by kind (for
    /// `order-independent`, entries computed and pixels requested: their ratio is the paper's
    /// computation ratio).
    fn work(&self) -> Vec<(&'static str, u64)>;
}

/// A model's part, kept both as a [`Part`] (for the owner's metrics) and as [`Any`] (for the
/// model, which knows its concrete type).
#[derive(Clone)]
pub struct Shared {
    part: Arc<dyn Part>,
    any: Arc<dyn Any + Send + Sync>,
}

impl Shared {
    pub fn new<T: Part>(part: T) -> Shared {
        let part = Arc::new(part);
        Shared { part: part.clone(), any: part }
    }
}

/// The shared parts of every model that has one, in registry order.
pub struct Resources {
    cache_budget: u64,
    parts: Vec<(&'static str, Shared)>,
}

impl Resources {
    /// Every model's part, each model's caches holding at most `cache_budget` bytes (0: none).
    pub fn new(cache_budget: u64) -> Resources {
        let parts = REGISTRY.iter().filter_map(|m| Some((m.id(), m.resources(cache_budget)?))).collect();
        Resources { cache_budget, parts }
    }

    /// The byte budget of each model's caches.
    pub fn cache_budget(&self) -> u64 {
        self.cache_budget
    }

    /// The part of `model`, of type `T`: `None` when the model has none (or it is not a `T`).
    pub fn part<T: Part>(&self, model: &str) -> Option<Arc<T>> {
        let (_, shared) = self.parts.iter().find(|(id, _)| *id == model)?;
        shared.any.clone().downcast().ok()
    }

    /// Bytes the caches of `model` hold now (0 for a model without any).
    pub fn cache_bytes(&self, model: &str) -> u64 {
        self.parts.iter().find(|(id, _)| *id == model).map_or(0, |(_, s)| s.part.cache_bytes())
    }

    /// Every model's work counters, as (model, kind, total).
    pub fn work(&self) -> Vec<(&'static str, &'static str, u64)> {
        self.parts.iter().flat_map(|(id, s)| s.part.work().into_iter().map(move |(kind, n)| (*id, kind, n))).collect()
    }
}

/// Resources with no cache: what a texture loaded on its own uses.
impl Default for Resources {
    fn default() -> Resources {
        Resources::new(0)
    }
}

impl std::fmt::Debug for Resources {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let ids: Vec<_> = self.parts.iter().map(|(id, _)| *id).collect();
        write!(f, "Resources(budget {} bytes, parts {ids:?})", self.cache_budget)
    }
}
