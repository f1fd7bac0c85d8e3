//! A zoom sequence of a demo: the same spot at successive mip levels, 80 × 80 pixels each, side
//! by side in one PNG (each level covers twice the width of the one on its left). The top row
//! is the served level, the bottom row the exact 2×2 box chain of level FIRST over the same
//! spot (left white where it would take more than 8192² pixels of level FIRST):
//! `cargo run -p vtex-synth --release --example zoom -- OUT.png NAME_FILTER FIRST LAST`, the
//! first demo (of any model) whose name contains NAME_FILTER.

use vtex_synth::mip::downsample_n;
use vtex_synth::models::{demos, load};
use vtex_synth::texture::{render_image, Region};
use vtex_synth::Rgba8Image;

const SIDE: u32 = 80;
/// The spot, in level-0 pixels: far from the origin, as the tests' regions.
const CENTRE: (i64, i64) = (3 << 30, -(5 << 28));
/// The largest side of level FIRST rendered for the exact chain.
const MAX_CHAIN_SIDE: u32 = 8192;

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args.first().cloned().unwrap_or_else(|| "zoom.png".into());
    let filter = args.get(1).cloned().unwrap_or_default();
    let level = |i: usize, d: u32| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (first, last) = (level(2, 1), level(3, 7));
    let b = demos().into_iter().find(|b| b.manifest.name.contains(&filter)).expect("no demo matches");
    let tex = load(&b).unwrap();
    let n = last - first + 1;
    let mut strip = Rgba8Image::new(SIDE * n, 2 * SIDE);
    strip.data.fill(255);
    let mut paste = |k: u32, row: u32, img: &Rgba8Image| {
        for j in 0..SIDE {
            for i in 0..SIDE {
                strip.set_pixel(k * SIDE + i, row * SIDE + j, img.pixel(i, j));
            }
        }
    };
    for (k, l) in (first..=last).enumerate() {
        let (x, y) = ((CENTRE.0 >> l) - SIDE as i64 / 2, (CENTRE.1 >> l) - SIDE as i64 / 2);
        paste(k as u32, 0, &render_image(tex.as_ref(), &Region::new(l, x, y, SIDE, SIDE)).unwrap());
        let d = l - first;
        if SIDE << d <= MAX_CHAIN_SIDE {
            let finer = render_image(tex.as_ref(), &Region::new(first, x << d, y << d, SIDE << d, SIDE << d)).unwrap();
            paste(k as u32, 1, &downsample_n(&finer, d));
        }
    }
    std::fs::write(&out, strip.to_png()).unwrap();
    println!("{out}: {} levels {first}..={last}, served above, exact chain of level {first} below", b.manifest.name);
}
