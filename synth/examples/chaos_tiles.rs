//! Times 256² tiles of the 100,000² chaos mosaic demo at chosen levels, one core: the minimum
//! and median over `count` tiles (minimum: the figure least disturbed by a shared machine).
//!
//! `cargo run -p vtex-synth --release --example chaos_tiles -- [count] [levels…]`

use std::time::Instant;
use vtex_synth::models::{self, chaos_mosaic, Inputs};
use vtex_synth::{samples, texture::level_size, Region, Texture};

fn main() {
    let args: Vec<u32> = std::env::args().skip(1).map(|a| a.parse().expect("numbers")).collect();
    let count = args.first().copied().unwrap_or(40) as usize;
    let levels = if args.len() > 1 { args[1..].to_vec() } else { (0..=9).collect() };
    // The bench's mosaic (benches/chaos_mosaic.rs): one block a tile, seed 1.
    let sample = samples::pebbles(160, 24, 11, true);
    let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
    let params = serde_json::json!({"tiles_x": 625, "tiles_y": 625, "seed": 1});
    let tex = chaos_mosaic::load(&models::create("chaos-mosaic", "t", &params, &inputs).unwrap()).unwrap();
    let mut out = vec![0u8; 256 * 256 * 4];
    for level in levels {
        let (lw, _) = level_size(tex.width(), tex.height(), level);
        let at = (lw as i64 / 2 / 256) * 256;
        let mut times: Vec<f64> = (0..count)
            .map(|_| {
                let t = Instant::now();
                tex.render(&Region::new(level, at, at, 256, 256), &mut out);
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        times.sort_by(|a, b| a.total_cmp(b));
        println!("level {level}: min {:.3} ms, median {:.3} ms", times[0], times[count / 2]);
    }
}
