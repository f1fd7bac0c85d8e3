//! A zoom sequence of a cascade demo: the same spot at successive mip levels, 80 × 80 pixels
//! each, side by side in one PNG (each level covers twice the width of the one on its left):
//! `cargo run -p vtex-synth --release --example cascade_zoom -- OUT.png NAME_FILTER FIRST LAST`.

use vtex_synth::models::{cascade, load};
use vtex_synth::texture::{render_image, Region};
use vtex_synth::Rgba8Image;

const SIDE: u32 = 80;
/// The spot, in level-0 pixels: far from the origin, as the tests' regions.
const CENTRE: (i64, i64) = (3 << 30, -(5 << 28));

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let out = args.first().cloned().unwrap_or_else(|| "zoom.png".into());
    let filter = args.get(1).cloned().unwrap_or_default();
    let level = |i: usize, d: u32| args.get(i).and_then(|s| s.parse().ok()).unwrap_or(d);
    let (first, last) = (level(2, 1), level(3, 7));
    let b = cascade::demos().into_iter().find(|b| b.manifest.name.contains(&filter)).expect("no demo matches");
    let tex = load(&b).unwrap();
    let n = last - first + 1;
    let mut strip = Rgba8Image::new(SIDE * n, SIDE);
    for (k, l) in (first..=last).enumerate() {
        let (x, y) = ((CENTRE.0 >> l) - SIDE as i64 / 2, (CENTRE.1 >> l) - SIDE as i64 / 2);
        let img = render_image(tex.as_ref(), &Region::new(l, x, y, SIDE, SIDE)).unwrap();
        for j in 0..SIDE {
            for i in 0..SIDE {
                strip.set_pixel(k as u32 * SIDE + i, j, img.pixel(i, j));
            }
        }
    }
    std::fs::write(&out, strip.to_png()).unwrap();
    println!("{out}: {} levels {first}..={last}", b.manifest.name);
}
