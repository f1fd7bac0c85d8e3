//! What opening an order-independent demo and rendering its first coarse tile cost,
//! with the calibration stored in the bundle (`calibration.bin`, written by `create`) and
//! without it (a bundle stored before the section existed, which measures it on that tile).
//! Prints, per demo and bundle, the encoding's size and the median milliseconds of opening and
//! of the first 256² tile of LEVEL (7 by default) at its centre, each run on a freshly opened
//! texture with resources of its own (a 64 MiB synthesis cache, as a server's).
//!
//! `flock /tmp/vtex-bench.lock cargo run --release -p vtex-synth --example oi_coarse_open [-- LEVEL [RUNS]]`

use std::time::Instant;
use vtex_synth::models::{self, order_independent};
use vtex_synth::texture::{level_size, render_image};
use vtex_synth::{Region, Resources};

fn main() {
    let mut args = std::env::args().skip(1);
    let level: u32 = args.next().map_or(7, |a| a.parse().expect("LEVEL is a number"));
    let runs: usize = args.next().map_or(3, |a| a.parse().expect("RUNS is a number"));
    for bundle in order_independent::demos() {
        let mut old = bundle.clone();
        old.sections.retain(|s| s.name != "calibration.bin");
        for (label, b) in [("stored", &bundle), ("lazy", &old)] {
            let bytes = b.to_bytes();
            let (mut open, mut tile): (Vec<f64>, Vec<f64>) = (0..runs)
                .map(|_| {
                    let start = Instant::now();
                    let parsed = vtex_synth::bundle::Bundle::from_bytes(&bytes).unwrap();
                    let tex = models::load_with(&parsed, &Resources::new(64 << 20)).unwrap();
                    let opened = start.elapsed().as_secs_f64() * 1e3;
                    let (w, h) = level_size(tex.width(), tex.height(), level);
                    let region = Region::new(level, (w as i64 / 2) & !255, (h as i64 / 2) & !255, 256, 256);
                    render_image(&*tex, &region).unwrap();
                    (opened, start.elapsed().as_secs_f64() * 1e3 - opened)
                })
                .unzip();
            let median = |v: &mut Vec<f64>| {
                v.sort_by(f64::total_cmp);
                v[runs / 2]
            };
            println!(
                "{:<36} {label:<6} {:>6} bytes  open {:>7.1} ms  level-{level} tile {:>7.1} ms",
                bundle.manifest.name,
                bytes.len(),
                median(&mut open),
                median(&mut tile)
            );
        }
    }
}
