//! A counting global allocator that holds each input to its target's bounds: the largest single
//! allocation and the live heap an input may add. A violation is reported the moment it
//! happens (before the memory is touched), because the allocation that breaks a bound may be
//! the one that takes the machine down.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering::Relaxed};
use std::sync::OnceLock;

/// Wraps the system allocator; install with `#[global_allocator]`.
pub struct Counting;

static LIVE: AtomicUsize = AtomicUsize::new(0);
/// The live heap when the current input started.
static BASE: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);
static LARGEST: AtomicUsize = AtomicUsize::new(0);
static MAX_ONE: AtomicUsize = AtomicUsize::new(usize::MAX);
static MAX_LIVE: AtomicUsize = AtomicUsize::new(usize::MAX);
/// Bounds are enforced only while an input runs, not while the harness makes its next one.
static ARMED: AtomicBool = AtomicBool::new(false);
static ON_VIOLATION: OnceLock<fn(Violation)> = OnceLock::new();

/// A bound an input broke.
#[derive(Clone, Copy, Debug)]
pub enum Violation {
    /// One allocation of this many bytes.
    Single { bytes: usize, bound: usize },
    /// The live heap grew by this many bytes during the input.
    Live { bytes: usize, bound: usize },
}

impl std::fmt::Display for Violation {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match *self {
            Violation::Single { bytes, bound } => write!(f, "one allocation of {bytes} bytes; bound {bound}"),
            Violation::Live { bytes, bound } => write!(f, "live heap grew by {bytes} bytes; bound {bound}"),
        }
    }
}

/// Sets what is called (once, with bounds disarmed) on the first violation; it must not return.
pub fn on_violation(f: fn(Violation)) {
    let _ = ON_VIOLATION.set(f);
}

/// Starts holding allocations to `max_one` and `max_live` (growth over the heap as it is now).
pub fn arm(max_one: usize, max_live: usize) {
    MAX_ONE.store(max_one, Relaxed);
    MAX_LIVE.store(max_live, Relaxed);
    let live = LIVE.load(Relaxed);
    BASE.store(live, Relaxed);
    PEAK.store(0, Relaxed);
    LARGEST.store(0, Relaxed);
    ARMED.store(true, Relaxed);
}

/// Stops enforcing; returns (largest single allocation, peak live growth) since [`arm`].
pub fn disarm() -> (usize, usize) {
    ARMED.store(false, Relaxed);
    (LARGEST.load(Relaxed), PEAK.load(Relaxed))
}

fn note(size: usize, live: usize) {
    if !ARMED.load(Relaxed) {
        return;
    }
    let grown = live.saturating_sub(BASE.load(Relaxed));
    LARGEST.fetch_max(size, Relaxed);
    PEAK.fetch_max(grown, Relaxed);
    let (max_one, max_live) = (MAX_ONE.load(Relaxed), MAX_LIVE.load(Relaxed));
    let violation = if size > max_one {
        Violation::Single { bytes: size, bound: max_one }
    } else if grown > max_live {
        Violation::Live { bytes: grown, bound: max_live }
    } else {
        return;
    };
    // Only the first violation reports; the report itself allocates freely.
    if ARMED.swap(false, Relaxed) {
        if let Some(report) = ON_VIOLATION.get() {
            report(violation);
        }
    }
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        note(layout.size(), LIVE.fetch_add(layout.size(), Relaxed) + layout.size());
        System.alloc(layout)
    }

    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        note(layout.size(), LIVE.fetch_add(layout.size(), Relaxed) + layout.size());
        System.alloc_zeroed(layout)
    }

    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size(), Relaxed);
        System.dealloc(ptr, layout)
    }

    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let live = if new_size >= layout.size() {
            LIVE.fetch_add(new_size - layout.size(), Relaxed) + (new_size - layout.size())
        } else {
            LIVE.fetch_sub(layout.size() - new_size, Relaxed) - (layout.size() - new_size)
        };
        note(new_size, live);
        System.realloc(ptr, layout, new_size)
    }
}
