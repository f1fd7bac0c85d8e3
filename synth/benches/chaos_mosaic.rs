//! Chaos mosaic speed beside plain tiling, measured in the same run.
//!
//! `cargo bench -p vtex-synth --bench chaos_mosaic`
//!
//! * level 0, 512 × 512 from a 64 × 64 sample (the paper: 0.03 s on a 450 MHz Pentium III),
//!   against the cheapest possible tiler (row copies) as the baseline;
//! * prefiltered 256 × 256 tiles at coarse levels of the 100,000² demo;
//! * opening the 100,000² mosaic and rendering a first level-0 tile (the blocks of that tile's
//!   neighbourhood found on demand), and drawing and indexing its whole block sequence, at the
//!   paper's 10 cat map iterations and at the most allowed (1000).

#![forbid(unsafe_code)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use serde_json::json;
use std::hint::black_box;
use vtex_synth::models::{self, chaos_mosaic, Inputs};
use vtex_synth::{samples, Region, Rgba8Image, Texture};

fn bundle(sample: &Rgba8Image, tiles: u32) -> vtex_synth::bundle::Bundle {
    bundle_iterated(sample, tiles, 10)
}

fn bundle_iterated(sample: &Rgba8Image, tiles: u32, iterations: u32) -> vtex_synth::bundle::Bundle {
    let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
    let params = json!({"tiles_x": tiles, "tiles_y": tiles, "seed": 1, "iterations": iterations});
    models::create("chaos-mosaic", "bench", &params, &inputs).unwrap()
}

/// The baseline: plain tiling by copying sample rows, the least work any tiler can do.
fn plain_tiling(sample: &Rgba8Image, w: usize, h: usize, out: &mut [u8]) {
    let (sw, sh) = (sample.width as usize, sample.height as usize);
    for y in 0..h {
        let src = &sample.data[(y % sh) * sw * 4..(y % sh + 1) * sw * 4];
        let row = &mut out[y * w * 4..(y + 1) * w * 4];
        for chunk in row.chunks_mut(sw * 4) {
            chunk.copy_from_slice(&src[..chunk.len()]);
        }
    }
}

fn level0(c: &mut Criterion) {
    let sample = samples::pebbles(64, 9, 1, true);
    let tex = chaos_mosaic::load(&bundle(&sample, 8)).unwrap();
    let mut out = vec![0u8; 512 * 512 * 4];
    let mut g = c.benchmark_group("level0_512x512_from_64x64");
    g.throughput(Throughput::Elements(512 * 512));
    g.bench_function("chaos_mosaic", |b| {
        b.iter(|| tex.render(black_box(&Region::new(0, 0, 0, 512, 512)), &mut out, &vtex_synth::Never))
    });
    g.bench_function("plain_tiling_baseline", |b| b.iter(|| plain_tiling(black_box(&sample), 512, 512, &mut out)));
    g.finish();
}

fn hundred_k() -> vtex_synth::bundle::Bundle {
    bundle(&samples::pebbles(160, 24, 11, true), 625)
}

fn coarse_levels(c: &mut Criterion) {
    let tex = chaos_mosaic::load(&hundred_k()).unwrap();
    let mut out = vec![0u8; 256 * 256 * 4];
    let mut g = c.benchmark_group("tile_256_of_100k");
    g.throughput(Throughput::Elements(256 * 256));
    g.sample_size(20);
    for level in [0u32, 1, 2, 3, 4, 5, 6, 7, 8, 9] {
        // A tile in the middle of the level, away from the origin.
        let (lw, _) = vtex_synth::texture::level_size(tex.width(), tex.height(), level);
        let at = (lw as i64 / 2 / 256) * 256;
        g.bench_with_input(BenchmarkId::new("level", level), &level, |b, &level| {
            b.iter(|| tex.render(&Region::new(level, at, at, 256, 256), &mut out, &vtex_synth::Never))
        });
    }
    g.finish();
}

fn load_100k(c: &mut Criterion) {
    let b = hundred_k();
    let tex = chaos_mosaic::load(&b).unwrap();
    eprintln!(
        "100,000² chaos mosaic: {} blocks, block list + tile index {:.1} MiB of heap, bundle {} bytes",
        tex.blocks().len(),
        tex.structure_heap_bytes() as f64 / (1 << 20) as f64,
        b.to_bytes().len()
    );
    let most = bundle_iterated(&samples::pebbles(160, 24, 11, true), 625, 1000);
    let mut out = vec![0u8; 256 * 256 * 4];
    let mut g = c.benchmark_group("load_100k");
    g.sample_size(10);
    // The cat map's cost must not grow with its iteration count: the paper's 10 is the baseline.
    for (name, bundle) in [("iterations_10", &b), ("iterations_1000", &most)] {
        g.bench_function(BenchmarkId::new("open_and_first_tile", name), |bench| {
            bench.iter(|| {
                let tex = chaos_mosaic::load(black_box(bundle)).unwrap();
                tex.render(&Region::new(0, 51_200, 51_200, 256, 256), &mut out, &vtex_synth::Never);
            })
        });
        g.bench_function(BenchmarkId::new("whole_index", name), |bench| {
            bench.iter(|| chaos_mosaic::load(black_box(bundle)).unwrap().blocks())
        });
    }
    g.finish();
}

criterion_group!(benches, level0, coarse_levels, load_100k);
criterion_main!(benches);
