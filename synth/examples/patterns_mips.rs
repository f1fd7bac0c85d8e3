//! Mip coherence of the `patterns` demos against the exact 2×2 box chain of their level 0,
//! printed as a table: `cargo run --release -p vtex-synth --example patterns_mips`. (A
//! measurement, not a test: it renders whole 4096² demos.)

use vtex_synth::models::{self, patterns::demos};
use vtex_synth::texture::{level_count, render_image};
use vtex_synth::{mip, Region};

fn main() {
    let list = vec![
        demos::aperiodic(64),
        demos::two_materials(),
        demos::leaves(),
        demos::sprites(),
        demos::pixel_map_path(),
        demos::led_board(false),
    ];
    for b in list {
        let t = models::load(&b).unwrap();
        let (w, h) = (t.width() as u32, t.height() as u32);
        let frame = if t.animation().is_some() { 30 } else { 0 };
        let mut exact = render_image(&*t, &Region::new(0, 0, 0, w, h).at_frame(frame)).unwrap();
        let true_mean = mip::mean_rgba(&exact);
        let mut row = Vec::new();
        for level in 1..level_count(w as u64, h as u64) {
            exact = mip::downsample(&exact);
            let got = render_image(&*t, &Region::new(level, 0, 0, exact.width, exact.height).at_frame(frame)).unwrap();
            let db = mip::psnr(&got, &exact);
            row.push(if db.is_infinite() { format!("L{level} exact") } else { format!("L{level} {db:.1}") });
            if level == level_count(w as u64, h as u64) - 1 {
                let p = got.pixel(0, 0);
                row.push(format!(
                    "| top {:?} vs true mean [{:.1}, {:.1}, {:.1}]",
                    &p[..3],
                    true_mean[0],
                    true_mean[1],
                    true_mean[2]
                ));
            }
        }
        println!("{} :: {}", b.manifest.name, row.join(", "));
    }
}
