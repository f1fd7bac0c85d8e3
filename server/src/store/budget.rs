//! The loaded textures: kept within a byte budget, least recently used evicted first.

use crate::byte_lru::ByteLru;
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Condvar, Mutex};

/// Values charged against a byte budget, kept least recently used first. A load reserves its
/// charge before it starts — evicting, or waiting for loads in progress to finish — so the sum
/// charged, kept values and loads in progress together, never exceeds the budget.
pub(super) struct Budgeted<V> {
    budget: u64,
    state: Mutex<Charged<V>>,
    /// Signalled when charge is released or a value is kept (and so becomes evictable).
    room: Condvar,
    evictions: AtomicU64,
}

struct Charged<V> {
    kept: ByteLru<String, V>,
    /// Bytes reserved by loads in progress.
    reserved: u64,
}

impl<V> Charged<V> {
    fn bytes(&self) -> u64 {
        self.kept.bytes() + self.reserved
    }
}

/// A charge reserved for a load in progress: released when dropped, unless kept.
#[must_use]
pub(super) struct Charge<'a, V> {
    set: &'a Budgeted<V>,
    bytes: u64,
}

impl<V> Drop for Charge<'_, V> {
    fn drop(&mut self) {
        if self.bytes > 0 {
            self.set.state.lock().unwrap().reserved -= self.bytes;
            self.set.room.notify_all();
        }
    }
}

impl<V: Clone> Budgeted<V> {
    pub(super) fn new(budget: u64) -> Self {
        Budgeted {
            budget,
            state: Mutex::new(Charged { kept: ByteLru::default(), reserved: 0 }),
            room: Condvar::new(),
            evictions: AtomicU64::new(0),
        }
    }

    pub(super) fn get(&self, key: &str) -> Option<V> {
        self.state.lock().unwrap().kept.get(key).cloned()
    }

    /// Reserves `bytes`, evicting least recently used values, or waiting for loads in progress
    /// when none is left to evict. Blocking.
    pub(super) fn reserve(&self, bytes: u64) -> Charge<'_, V> {
        let mut state = self.state.lock().unwrap();
        while state.bytes().saturating_add(bytes) > self.budget {
            if state.kept.pop_lru().is_some() {
                self.evictions.fetch_add(1, Ordering::Relaxed);
            } else if state.reserved > 0 {
                state = self.room.wait(state).unwrap();
            } else {
                // Alone over the budget: callers check each value against it first.
                break;
            }
        }
        state.reserved += bytes;
        Charge { set: self, bytes }
    }

    /// Keeps `value` under `key`, charged what `charge` reserved.
    pub(super) fn keep(&self, mut charge: Charge<'_, V>, key: String, value: V) {
        let mut state = self.state.lock().unwrap();
        state.reserved -= charge.bytes;
        state.kept.put(key, value, charge.bytes);
        charge.bytes = 0;
        drop(state);
        self.room.notify_all();
    }

    pub(super) fn remove(&self, key: &str) {
        let mut state = self.state.lock().unwrap();
        if state.kept.pop(key).is_some() {
            drop(state);
            self.room.notify_all();
        }
    }

    pub(super) fn len(&self) -> usize {
        self.state.lock().unwrap().kept.len()
    }

    /// Bytes charged: kept values and loads in progress.
    pub(super) fn charged(&self) -> u64 {
        self.state.lock().unwrap().bytes()
    }

    pub(super) fn evictions(&self) -> u64 {
        self.evictions.load(Ordering::Relaxed)
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::sync::Arc;

    #[test]
    fn the_budget_evicts_least_recently_used_first() {
        let set: Budgeted<u32> = Budgeted::new(100);
        set.keep(set.reserve(40), "a".into(), 1);
        set.keep(set.reserve(40), "b".into(), 2);
        assert_eq!(set.get("a"), Some(1), "a is now the most recently used");
        set.keep(set.reserve(40), "c".into(), 3);
        assert_eq!((set.get("a"), set.get("b"), set.get("c")), (Some(1), None, Some(3)));
        assert_eq!((set.charged(), set.evictions(), set.len()), (80, 1, 2));
        // A failed load gives its reservation back.
        drop(set.reserve(60));
        assert_eq!((set.charged(), set.evictions()), (40, 2));
        set.remove("c");
        assert_eq!((set.charged(), set.len()), (0, 0));
    }

    #[test]
    fn loads_in_progress_count_against_the_budget() {
        let set: Arc<Budgeted<u32>> = Arc::new(Budgeted::new(100));
        let first = set.reserve(70);
        let (tx, rx) = std::sync::mpsc::channel();
        let waiter = {
            let set = set.clone();
            std::thread::spawn(move || {
                let charge = set.reserve(70);
                tx.send(set.charged()).unwrap();
                set.keep(charge, "second".into(), 2);
            })
        };
        // Nothing is evictable while the first load runs: the second waits for it.
        assert!(rx.recv_timeout(std::time::Duration::from_millis(200)).is_err(), "the budget was overcommitted");
        set.keep(first, "first".into(), 1);
        assert_eq!(rx.recv_timeout(std::time::Duration::from_secs(10)).unwrap(), 70, "the first was evicted");
        waiter.join().unwrap();
        assert_eq!((set.get("first"), set.get("second"), set.charged()), (None, Some(2), 70));
    }
}
