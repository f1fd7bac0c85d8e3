//! Cold 256² tiles of every cascade demo, level by level: the one-time calibration of the
//! prefiltered levels, then the median of 5 distinct tiles per level (each rendered once):
//! `cargo run -p vtex-synth --release --example cascade_levels [MAX_LEVEL]`.

use std::time::Instant;
use vtex_synth::models::{cascade, load};
use vtex_synth::texture::Region;
use vtex_synth::Never;

fn ms(t: Instant) -> f64 {
    t.elapsed().as_secs_f64() * 1e3
}

fn main() {
    let max: u32 = std::env::args().nth(1).and_then(|s| s.parse().ok()).unwrap_or(8);
    let mut out = vec![0u8; 256 * 256 * 4];
    println!("| demo | calibration ms | {} |", (0..=max).map(|l| format!("L{l}")).collect::<Vec<_>>().join(" | "));
    for b in cascade::demos() {
        let tex = load(&b).unwrap();
        let t = Instant::now();
        tex.render(&Region::new(max, 0, 0, 1, 1), &mut out[..4], &Never);
        let calibration = ms(t);
        let cells: Vec<String> = (0..=max)
            .map(|l| {
                let mut times: Vec<f64> = (0..5i64)
                    .map(|i| {
                        let t = Instant::now();
                        tex.render(&Region::new(l, (7 + 3 * i) << 8, (11 - 5 * i) << 8, 256, 256), &mut out, &Never);
                        ms(t)
                    })
                    .collect();
                times.sort_by(f64::total_cmp);
                format!("{:.1}", times[2])
            })
            .collect();
        println!("| {} | {calibration:.0} | {} |", b.manifest.name, cells.join(" | "));
    }
}
