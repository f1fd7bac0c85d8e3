//! What a tile costs when it is rendered alone and when it is rendered as part of an aligned
//! block of n × n tiles in one call (a metatile): the sharing between neighbours that decides
//! the metatile size a model is served with.
//!
//! `cargo run -p vtex-synth --release --example metatile_costs MODEL [NAME] [MAX_LEVEL]`
//!
//! For each demo whose name contains NAME and each level up to MAX_LEVEL (default 6): the
//! median over 3 distinct places of the milliseconds per 256² tile, for blocks of 1, 2, 4 and
//! 8 tiles a side, each place rendered once (cold) after one warm-up render elsewhere.

use std::time::Instant;
use vtex_synth::models;
use vtex_synth::texture::{level_count, level_size, Region};
use vtex_synth::Never;

const TILE: u64 = 256;
const SIDES: [u64; 4] = [1, 2, 4, 8];

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(model) = args.first() else {
        eprintln!("usage: metatile_costs MODEL [NAME] [MAX_LEVEL]");
        std::process::exit(2);
    };
    let name = args.get(1).map(String::as_str).unwrap_or("");
    let max: u32 = args.get(2).map(|s| s.parse().expect("MAX_LEVEL is a number")).unwrap_or(6);
    let demos = models::get(model).unwrap_or_else(|e| panic!("{e}")).demos();
    for bundle in demos.into_iter().filter(|b| b.manifest.name.contains(name)) {
        let tex = models::load(&bundle).unwrap();
        println!("\n{} — ms per 256² tile, by metatile side (tiles)", bundle.manifest.name);
        println!("| level | {} |", SIDES.map(|n| format!("{n}×{n}")).join(" | "));
        println!("|---|{}", "---|".repeat(SIDES.len()));
        for level in 0..level_count(tex.width(), tex.height()).min(max + 1) {
            let (w, h) = level_size(tex.width(), tex.height(), level);
            let costs = SIDES.map(|n| {
                let side = n * TILE;
                let (cols, rows) = (w.div_ceil(side), h.div_ceil(side));
                // Aligned blocks spread over the level; the first warms what loads once.
                let block = |i: u64| {
                    let (bx, by) = ((cols / 2 + 7 * i) % cols, (rows / 3 + 5 * i) % rows);
                    let (x, y) = (bx * side, by * side);
                    Region::new(level, x as i64, y as i64, (w - x).min(side) as u32, (h - y).min(side) as u32)
                };
                let time = |r: Region| {
                    let mut out = vec![0u8; r.byte_len()];
                    let t = Instant::now();
                    tex.render(&r, &mut out, &Never);
                    let tiles = (r.width as u64).div_ceil(TILE) * (r.height as u64).div_ceil(TILE);
                    t.elapsed().as_secs_f64() * 1e3 / tiles as f64
                };
                time(block(0));
                let mut after: Vec<f64> = (1..=3).map(|i| time(block(i))).collect();
                after.sort_by(f64::total_cmp);
                after[1]
            });
            println!("| L{level} | {} |", costs.map(|t| format!("{t:.2}")).join(" | "));
        }
    }
}
