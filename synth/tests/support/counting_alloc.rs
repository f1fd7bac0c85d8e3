//! A global allocator that counts the heap bytes each thread holds (what it allocated less
//! what it freed) and the most it has held since [`reset_peak`], for tests that bound memory.
//! A test binary installs it with `#[global_allocator] static A: Counting = Counting;`.

use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;

pub struct Counting;

thread_local! {
    static LIVE: Cell<i64> = const { Cell::new(0) };
    static PEAK: Cell<i64> = const { Cell::new(0) };
}

fn count(delta: i64) {
    let live = LIVE.with(|l| {
        l.set(l.get() + delta);
        l.get()
    });
    PEAK.with(|p| p.set(p.get().max(live)));
}

/// Bytes this thread holds now.
pub fn live() -> i64 {
    LIVE.with(Cell::get)
}

/// The most this thread has held since [`reset_peak`].
pub fn peak() -> i64 {
    PEAK.with(Cell::get)
}

/// Starts the peak over from what this thread holds now.
pub fn reset_peak() {
    PEAK.with(|p| p.set(live()));
}

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(layout.size() as i64);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count(-(layout.size() as i64));
        System.dealloc(ptr, layout)
    }
    /// Growth counted as a move, the new block beside the old for a moment (what an allocator
    /// that cannot grow a block in place holds); shrinking in place.
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        let old = layout.size() as i64;
        if new_size as i64 > old {
            count(new_size as i64);
            count(-old);
        } else {
            count(new_size as i64 - old);
        }
        System.realloc(ptr, layout, new_size)
    }
}
