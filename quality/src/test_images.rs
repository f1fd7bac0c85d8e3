//! Images with known statistics for the metrics' unit tests.

use vtex_synth::{hash, Rgba8Image};

/// Independent uniform noise in every RGB channel, opaque.
pub fn noise(w: u32, h: u32, seed: u64) -> Rgba8Image {
    let mut img = Rgba8Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let v = hash::hash4(seed, 0, x as i64, y as i64);
            img.set_pixel(x, y, [v as u8, (v >> 8) as u8, (v >> 16) as u8, 255]);
        }
    }
    img
}

/// Grey image from a function of (x, y), rounded and clamped to 0..=255.
pub fn grey(w: u32, h: u32, f: impl Fn(f64, f64) -> f64) -> Rgba8Image {
    let mut img = Rgba8Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let v = f(x as f64, y as f64).round().clamp(0.0, 255.0) as u8;
            img.set_pixel(x, y, [v, v, v, 255]);
        }
    }
    img
}

/// `tile` repeated to fill `w × h`.
pub fn tiled(tile: &Rgba8Image, w: u32, h: u32) -> Rgba8Image {
    let mut img = Rgba8Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            img.set_pixel(x, y, tile.pixel(x % tile.width, y % tile.height));
        }
    }
    img
}
