//! What synthesis threads give: cold 256² tiles per second of a demo at every tile level, with
//! one thread and with two rendering distinct tiles at once — the sizing figures of
//! `docs/deployment.md`.
//!
//! `cargo run -p vtex-synth --release --example sizing MODEL [NAME] [TILES]`
//!
//! NAME keeps the first demo whose name contains it; TILES (default 8) distinct tiles are
//! rendered per thread and level, each once, after one warm-up tile of the level (tables a
//! level builds once per texture are not counted).

use std::time::Instant;
use vtex_synth::models;
use vtex_synth::texture::{level_size, Region};
use vtex_synth::{Never, Texture};

const TILE: u64 = 256;

/// Tile `i` of `level`, spread over the level (distinct for distinct `i` where it has that many).
fn tile(tex: &dyn Texture, level: u32, i: u64) -> Region {
    let (w, h) = level_size(tex.width(), tex.height(), level);
    let (cols, rows) = (w.div_ceil(TILE), h.div_ceil(TILE));
    let (x, y) = ((cols / 2 + 7 * i) % cols * TILE, (rows / 3 + 5 * i) % rows * TILE);
    Region::new(level, x as i64, y as i64, (w - x).min(TILE) as u32, (h - y).min(TILE) as u32)
}

/// Tiles per second of `threads` threads each rendering `n` distinct tiles of `level`.
fn rate(tex: &dyn Texture, level: u32, threads: u64, n: u64) -> f64 {
    let t = Instant::now();
    std::thread::scope(|s| {
        for k in 0..threads {
            s.spawn(move || {
                for i in 0..n {
                    let r = tile(tex, level, 1 + k * n + i);
                    let mut out = vec![0u8; r.byte_len()];
                    tex.render(&r, &mut out, &Never);
                }
            });
        }
    });
    (threads * n) as f64 / t.elapsed().as_secs_f64()
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let Some(model) = args.first() else {
        eprintln!("usage: sizing MODEL [NAME] [TILES]");
        std::process::exit(2);
    };
    let name = args.get(1).map(String::as_str).unwrap_or("");
    let n: u64 = args.get(2).map(|s| s.parse().expect("TILES is a number")).unwrap_or(8);
    let bundle = models::get(model)
        .unwrap_or_else(|e| panic!("{e}"))
        .demos()
        .into_iter()
        .find(|b| b.manifest.name.contains(name))
        .unwrap_or_else(|| panic!("no demo of {model} is called like `{name}`"));
    let tex = models::load(&bundle).unwrap();
    let levels = vtex_wire::levels::tile_levels(tex.width(), tex.height(), TILE as u32);
    println!("\n{} — cold 256² tiles/s, 1 thread / 2 threads", bundle.manifest.name);
    for level in 0..levels {
        let r = tile(&*tex, level, 0);
        tex.render(&r, &mut vec![0u8; r.byte_len()], &Never);
        let (one, two) = (rate(&*tex, level, 1, n), rate(&*tex, level, 2, n));
        println!("| L{level} | {one:.0} | {two:.0} |");
    }
}
