//! What encoding an image really holds at its peak, against [`encode::peak_bytes`]: the bytes
//! a region reserves from the in-flight budget before it is rendered. A counting allocator
//! follows this thread's heap from the rendered pixels to the encoded body, for images that
//! compress well and for noise, which does not.

use rand::{Rng, SeedableRng};
use std::alloc::{GlobalAlloc, Layout, System};
use std::cell::Cell;
use vtex_server::encode::{self, Format};
use vtex_synth::Rgba8Image;

struct Counting;

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

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        count(layout.size() as i64);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        count(-(layout.size() as i64));
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        count(new_size as i64 - layout.size() as i64);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

/// Heap held at the peak of making a `w` × `h` image and encoding it, over what was held before.
fn measured_peak(format: Format, w: u32, h: u32, noise: bool) -> u64 {
    let before = LIVE.with(Cell::get);
    PEAK.with(|p| p.set(before));
    let mut img = Rgba8Image::new(w, h);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    for (i, px) in img.data.chunks_exact_mut(4).enumerate() {
        let (x, y) = ((i as u32 % w) as u8, (i as u32 / w) as u8);
        let v = if noise { rng.random() } else { [x, y, x ^ y, 255] };
        px.copy_from_slice(&v);
    }
    let body = encode::encode(img, format).expect("encodes");
    let peak = PEAK.with(Cell::get) - before;
    drop(body);
    peak as u64
}

#[test]
fn encoding_holds_no_more_than_its_reservation() {
    let mut over = Vec::new();
    for format in [Format::Png, Format::Webp, Format::Jpg, Format::Rgba] {
        for (w, h) in [(256, 256), (1024, 768), (2048, 2048)] {
            for noise in [false, true] {
                let (held, reserved) = (measured_peak(format, w, h, noise), encode::peak_bytes(format, w, h));
                println!("{format:?} {w}×{h} noise {noise}: held {held}, reserved {reserved}");
                if held > reserved {
                    over.push(format!("{format:?} {w}×{h} (noise {noise}): {held} held > {reserved} reserved"));
                }
            }
        }
    }
    assert!(over.is_empty(), "{over:#?}");
}
