//! What a viewer's cold look at a demo costs, level by level: the load, then at every level
//! the first 256² tile (it builds whatever tables that level needs once per texture) and the
//! median of 5 distinct tiles after it, each rendered once, on one core.
//!
//! `cargo run -p vtex-synth --release --example level_costs MODEL [NAME] [MAX_LEVEL]`
//!
//! NAME keeps the demos whose name contains it; MAX_LEVEL (default 17) caps the levels.
//! Below 256² a level is smaller than a tile and the whole level is one tile.

use std::time::Instant;
use vtex_synth::models;
use vtex_synth::texture::{level_count, level_size, Region};
use vtex_synth::Never;

const TILE: u64 = 256;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(model) = args.first() else {
        eprintln!("usage: level_costs MODEL [NAME] [MAX_LEVEL]");
        std::process::exit(2);
    };
    let name = args.get(1).map(String::as_str).unwrap_or("");
    let max: u32 = args.get(2).map(|s| s.parse().expect("MAX_LEVEL is a number")).unwrap_or(17);
    let demos: Vec<_> = models::get(model)
        .unwrap_or_else(|e| panic!("{e}"))
        .demos()
        .into_iter()
        .filter(|b| b.manifest.name.contains(name))
        .collect();
    let mut out = vec![0u8; (TILE * TILE * 4) as usize];
    for bundle in demos {
        let t = Instant::now();
        let tex = models::load(&bundle).unwrap();
        println!(
            "\n{} — load {:.1} ms; ms per 256² tile, first (builds tables) / median of 5 after",
            bundle.manifest.name,
            ms(t)
        );
        let levels = level_count(tex.width(), tex.height()).min(max + 1);
        println!("| level | {} |", (0..levels).map(|l| format!("L{l}")).collect::<Vec<_>>().join(" | "));
        println!("|---|{}", "---|".repeat(levels as usize));
        let (mut first, mut median) = (Vec::new(), Vec::new());
        for level in 0..levels {
            let (w, h) = level_size(tex.width(), tex.height(), level);
            let (tw, th) = (w.min(TILE), h.min(TILE));
            let (cols, rows) = (w.div_ceil(TILE), h.div_ceil(TILE));
            // Tiles spread over the level, distinct where the level has that many.
            let tile = |i: u64| {
                let (x, y) = ((cols / 2 + 7 * i) % cols, (rows / 3 + 5 * i) % rows);
                Region::new(level, (x * TILE) as i64, (y * TILE) as i64, tw as u32, th as u32)
            };
            let mut time = |r: &Region| {
                let t = Instant::now();
                tex.render(r, &mut out[..r.byte_len()], &Never);
                ms(t)
            };
            first.push(time(&tile(0)));
            let mut after: Vec<f64> = (1..=5).map(|i| time(&tile(i))).collect();
            after.sort_by(f64::total_cmp);
            median.push(after[2]);
        }
        let row = |v: &[f64]| v.iter().map(|t| format!("{t:.1}")).collect::<Vec<_>>().join(" | ");
        println!("| first | {} |", row(&first));
        println!("| median | {} |", row(&median));
    }
}
