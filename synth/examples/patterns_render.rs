//! Renders every `patterns` demo to PNG for looking at, and the animated ones (the LED board
//! across its temporal transition and its density ramp, the balls lighting LEDs) over time: `cargo run --release -p vtex-synth --example patterns_render` writes into
//! `$VTEX_RENDER_DIR` (default `target/patterns-renders`).

use vtex_synth::models::patterns::demos;
use vtex_synth::texture::{level_count, render_image};
use vtex_synth::{models, Region};

fn main() {
    render_demos();
    render_animated_frames();
}

fn render_demos() {
    let dir = std::env::var("VTEX_RENDER_DIR")
        .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../target/patterns-renders").into());
    std::fs::create_dir_all(&dir).unwrap();
    for (i, b) in demos::demos().iter().enumerate() {
        let tex = models::load(b).unwrap();
        let (w, h) = (tex.width(), tex.height());
        // A 1024² detail at level 0, and the whole texture at the level where it fits 1024.
        let detail =
            render_image(&*tex, &Region::new(0, 0, 0, 1024.min(w) as u32, 1024.min(h) as u32).at_frame(30)).unwrap();
        std::fs::write(format!("{dir}/{i}-detail.png"), detail.to_png()).unwrap();
        let level = (0..level_count(w, h)).find(|&l| (w >> l) <= 1024 && (h >> l) <= 1024).unwrap();
        let (lw, lh) = vtex_synth::texture::level_size(w, h, level);
        let whole = render_image(&*tex, &Region::new(level, 0, 0, lw as u32, lh as u32).at_frame(30)).unwrap();
        std::fs::write(format!("{dir}/{i}-level{level}.png"), whole.to_png()).unwrap();
        println!("{i}: {} {}×{} level {level}", b.manifest.name, w, h);
    }
}

fn render_animated_frames() {
    let dir = std::env::var("VTEX_RENDER_DIR")
        .unwrap_or_else(|_| concat!(env!("CARGO_MANIFEST_DIR"), "/../target/patterns-renders").into());
    std::fs::create_dir_all(&dir).unwrap();
    let board = Region::new(3, 0, 0, 1536, 192);
    let runs = [
        ("led-transition", demos::led_board(true), board, vec![100u32, 125, 140, 200]),
        ("led-ramp", demos::led_ramp(), board, vec![20, 70, 100, 130, 160, 190, 240]),
        ("distance", demos::distance_triggered(), Region::new(2, 0, 0, 1024, 1024), vec![0, 20, 40]),
    ];
    for (name, bundle, region, frames) in runs {
        let tex = models::load(&bundle).unwrap();
        for frame in frames {
            let img = render_image(&*tex, &region.at_frame(frame)).unwrap();
            std::fs::write(format!("{dir}/{name}-{frame}.png"), img.to_png()).unwrap();
        }
    }
}
