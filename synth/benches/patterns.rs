//! Synthesis speed of each `patterns` composition, in pixels per second on one core:
//! `cargo bench -p vtex-synth --bench patterns`. Each iteration renders one 256 × 256 tile of
//! level 0 (frame 30 for animated textures); criterion reports elements (pixels) per second.
//! A second group renders one tile of every level of the 100k demo (the cold tile cost per
//! level behind the viewer bench's cold views).
//! The paper's GeForceFX prototype did 320 × 200 at 113 / 73 / 36 / 5 fps for the basic /
//! areas map / dithered areas map / dithered + transitions fragment programs.

#![forbid(unsafe_code)]

use criterion::{criterion_group, criterion_main, Criterion, Throughput};
use std::hint::black_box;
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, patterns::demos};
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::Region;

/// The two-material demo with its transitions and/or dithering switched off.
fn two_materials(dithered: bool, transitions: bool) -> Bundle {
    let mut b = demos::two_materials();
    let layer = &mut b.manifest.params["layers"][0];
    layer["choice"]["areas"]["dithered"] = serde_json::Value::Bool(dithered);
    if !transitions {
        layer.as_object_mut().unwrap().remove("transitions");
    }
    b
}

fn compositions(c: &mut Criterion) {
    let cases: Vec<(&str, Bundle, i64, i64)> = vec![
        ("basic aperiodic tiling", demos::aperiodic(1563), 50_000, 50_000),
        ("areas map", two_materials(false, false), 1024, 1024),
        ("dithered areas map", two_materials(true, false), 1024, 1024),
        ("dithered areas map + transitions", two_materials(true, true), 1024, 1024),
        ("sparse convolution (leaves over tiling)", demos::leaves(), 1024, 1024),
        ("texture sprites over tiling", demos::sprites(), 600, 300),
        ("pixel map", demos::pixel_map_path(), 1800, 1800),
        ("animated tiling (LED board)", demos::led_board(false), 2048, 512),
        ("animated tiling, temporal transition", demos::led_board(true), 2048, 512),
    ];
    let mut g = c.benchmark_group("patterns 256x256 tile, level 0");
    g.throughput(Throughput::Elements(256 * 256));
    let mut out = vec![0u8; 256 * 256 * 4];
    for (name, bundle, x, y) in cases {
        let tex = models::load(&bundle).unwrap();
        let region = Region::new(0, x, y, 256, 256).at_frame(30);
        g.bench_function(name, |b| b.iter(|| tex.render(black_box(&region), &mut out, &vtex_synth::Never)));
    }
    g.finish();
    // Every level of the 100k demo (the viewer bench's texture): a tile in the middle of the
    // level, or the whole level once it is smaller than a tile. Nothing is cached between
    // iterations, so each is a cold tile.
    let mut g = c.benchmark_group("patterns 100k demo, 256x256 tile per level");
    g.throughput(Throughput::Elements(256 * 256));
    let tex = models::load(&demos::aperiodic(1563)).unwrap();
    for level in 0..level_count(tex.width(), tex.height()) {
        let (w, h) = level_size(tex.width(), tex.height(), level);
        let (tw, th) = (w.min(256) as u32, h.min(256) as u32);
        let region = Region::new(level, (w / 2 - tw as u64 / 2) as i64, (h / 2 - th as u64 / 2) as i64, tw, th);
        let mut out = vec![0u8; region.byte_len()];
        g.bench_function(format!("level {level}"), |b| {
            b.iter(|| tex.render(black_box(&region), &mut out, &vtex_synth::Never))
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(20).warm_up_time(std::time::Duration::from_millis(500)).measurement_time(std::time::Duration::from_secs(2));
    targets = compositions
}
criterion_main!(benches);
