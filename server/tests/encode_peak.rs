//! What encoding an image really holds at its peak, against [`encode::peak_bytes`]: the bytes
//! a region reserves from the in-flight budget before it is rendered. A counting allocator
//! follows this thread's heap from the rendered pixels to the encoded body, for images that
//! compress well and for noise, which does not.

#[path = "../../synth/tests/support/counting_alloc.rs"]
mod counting;

use rand::{Rng, SeedableRng};
use vtex_server::encode::{self, Format};
use vtex_synth::Rgba8Image;

#[global_allocator]
static COUNTING: counting::Counting = counting::Counting;

/// Heap held at the peak of making a `w` × `h` image and encoding it, over what was held before.
fn measured_peak(format: Format, w: u32, h: u32, noise: bool) -> u64 {
    let before = counting::live();
    counting::reset_peak();
    let mut img = Rgba8Image::new(w, h);
    let mut rng = rand::rngs::StdRng::seed_from_u64(7);
    for (i, px) in img.data.chunks_exact_mut(4).enumerate() {
        let (x, y) = ((i as u32 % w) as u8, (i as u32 / w) as u8);
        let v = if noise { rng.random() } else { [x, y, x ^ y, 255] };
        px.copy_from_slice(&v);
    }
    let body = encode::encode(img, format).expect("encodes");
    let peak = counting::peak() - before;
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
