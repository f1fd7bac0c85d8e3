//! Cold tiles: synthesis + encode of 256² tiles never seen before, per format, exactly as
//! the server does on a cache miss (render the tile's region, encode it). The texture is
//! the 100k × 100k chaos mosaic demo; every iteration takes the next tile of level 0.
//! Baseline in the same run: synthesis alone (`render_only`), and encoding alone.

#![forbid(unsafe_code)]

use criterion::{criterion_group, criterion_main, BatchSize, Criterion};
use std::hint::black_box;
use vtex_server::encode::{encode, Format};
use vtex_server::store::Entry;
use vtex_synth::texture::render_image;
use vtex_synth::Region;

fn big_mosaic() -> Entry {
    let demo = vtex_synth::models::demos()
        .into_iter()
        .find(|b| b.manifest.model == "chaos-mosaic" && b.manifest.name.contains("100k"))
        .expect("the 100k chaos mosaic demo");
    Entry::from_bytes(&demo.to_bytes(), 256).expect("demo loads")
}

/// Tile coordinates walking level 0 row by row, never repeating within a run.
fn next_tile(entry: &Entry, n: &mut u64) -> Region {
    let (cols, rows) = entry.tiles_at(0);
    let i = *n % (cols * rows);
    *n += 1;
    let (x, y) = (i % cols, i / cols);
    let w = (entry.texture.width() - x * 256).min(256) as u32;
    let h = (entry.texture.height() - y * 256).min(256) as u32;
    Region::new(0, (x * 256) as i64, (y * 256) as i64, w, h)
}

fn cold_tiles(c: &mut Criterion) {
    let entry = big_mosaic();
    let mut g = c.benchmark_group("cold_tile_256");
    let mut n = 0u64;
    g.bench_function("render_only", |b| {
        b.iter(|| black_box(render_image(&*entry.texture, &next_tile(&entry, &mut n)).unwrap()))
    });
    for format in Format::ALL {
        g.bench_function(format.ext(), |b| {
            b.iter(|| {
                let img = render_image(&*entry.texture, &next_tile(&entry, &mut n)).unwrap();
                black_box(encode(img, format).unwrap())
            })
        });
    }
    g.finish();
    let img = render_image(&*entry.texture, &Region::new(0, 0, 0, 256, 256)).unwrap();
    let mut g = c.benchmark_group("encode_only_256");
    for format in Format::ALL {
        // Encoding takes its image; the copy for each run is made outside the timing.
        g.bench_function(format.ext(), |b| {
            b.iter_batched(|| img.clone(), |img| black_box(encode(img, format).unwrap()), BatchSize::LargeInput)
        });
    }
    g.finish();
}

criterion_group! {
    name = benches;
    config = Criterion::default().sample_size(60).measurement_time(std::time::Duration::from_secs(4));
    targets = cold_tiles
}
criterion_main!(benches);
