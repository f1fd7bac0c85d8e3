//! Times 256² tiles of the 100,000² chaos mosaic demo at chosen levels, one core: the minimum
//! and median over `count` tiles (minimum: the figure least disturbed by a shared machine).
//!
//! `cargo run -p vtex-synth --release --example chaos_tiles -- [count] [levels…]`
//! (CHAOS_PNG=dir also writes each level's tile to dir/level-L.png).
//!
//! With count 0, instead prints each level's PSNR against the exact downsample of level 0 over
//! three 4096² level-0 windows of the demo (what the mip-coherence tests measure on small
//! mosaics, here on the 100k one).

use std::time::Instant;
use vtex_synth::models::{self, chaos_mosaic, Inputs};
use vtex_synth::{mip, samples, texture::level_size, Region, Texture};

fn main() {
    let args: Vec<u32> = std::env::args().skip(1).map(|a| a.parse().expect("numbers")).collect();
    let count = args.first().copied().unwrap_or(40) as usize;
    let levels = if args.len() > 1 { args[1..].to_vec() } else { (0..=9).collect() };
    // The bench's mosaic (benches/chaos_mosaic.rs: one block a tile, seed 1), or with
    // CHAOS_DEMO=1 the served demo (two blocks a tile).
    let bundle = match std::env::var("CHAOS_DEMO").is_ok() {
        true => chaos_mosaic::demos().swap_remove(0),
        false => {
            let sample = samples::pebbles(160, 24, 11, true);
            let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
            let params = serde_json::json!({"tiles_x": 625, "tiles_y": 625, "seed": 1});
            models::create("chaos-mosaic", "t", &params, &inputs).unwrap()
        }
    };
    let tex = chaos_mosaic::load(&bundle).unwrap();
    if count == 0 {
        return psnr(&tex, &levels);
    }
    let mut out = vec![0u8; 256 * 256 * 4];
    for level in levels {
        let (lw, _) = level_size(tex.width(), tex.height(), level);
        let at = (lw as i64 / 2 / 256) * 256;
        let mut times: Vec<f64> = (0..count)
            .map(|_| {
                let t = Instant::now();
                tex.render(&Region::new(level, at, at, 256, 256), &mut out, &vtex_synth::Never);
                t.elapsed().as_secs_f64() * 1e3
            })
            .collect();
        times.sort_by(|a, b| a.total_cmp(b));
        if let Ok(dir) = std::env::var("CHAOS_PNG") {
            let img = vtex_synth::Rgba8Image { width: 256, height: 256, data: out.clone() };
            std::fs::write(format!("{dir}/level-{level}.png"), img.to_png()).unwrap();
        }
        println!("level {level}: min {:.3} ms, median {:.3} ms", times[0], times[count / 2]);
    }
}

fn psnr(tex: &dyn Texture, levels: &[u32]) {
    const E: u32 = 4096;
    let windows = [(12_288i64, 45_056i64), (57_344, 8_192), (81_920, 69_632)];
    let exact: Vec<_> = windows
        .iter()
        .map(|&(x, y)| vtex_synth::texture::render_image(tex, &Region::new(0, x, y, E, E)).unwrap())
        .collect();
    for &level in levels.iter().filter(|&&l| l >= 1 && E >> l > 0) {
        let n = E >> level;
        let mse: f64 = windows
            .iter()
            .zip(&exact)
            .map(|(&(x, y), full)| {
                let got =
                    vtex_synth::texture::render_image(tex, &Region::new(level, x >> level, y >> level, n, n)).unwrap();
                let db = mip::psnr(&got, &mip::downsample_n(full, level));
                255.0f64.powi(2) / 10f64.powf(db / 10.0)
            })
            .sum::<f64>()
            / windows.len() as f64;
        println!("level {level}: {:.1} dB ({n}² pixels × {})", 10.0 * (255.0f64.powi(2) / mse).log10(), windows.len());
    }
}
