//! Synthesis speed of the `lcm` demos: 256 × 256 tiles at level 0 and at coarser levels,
//! in pixels per second on one core, with the operation counts per pixel beside the paper's
//! bound of 4N additions and N multiplications for N layers (§6).
//!
//! `lcm_cold_tile` is what a viewer's first look at the 100k demo costs: at every level, one
//! tile of a freshly loaded texture (so it builds the summed-area tables that level needs),
//! beside the chaos mosaic 100k's cold tile at the same level as the baseline.
//!
//! `cargo bench -p vtex-synth --bench lcm` (`-- lcm_cold_tile` for the cold table alone)

#![forbid(unsafe_code)]

use criterion::{criterion_group, criterion_main, BatchSize, BenchmarkId, Criterion, Throughput};
use vtex_synth::models::lcm::{demos, load, OpCount};
use vtex_synth::models::{self, chaos_mosaic};
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::{Region, Texture};

const TILE: u32 = 256;

fn bench(c: &mut Criterion) {
    let mut group = c.benchmark_group("lcm");
    group.throughput(Throughput::Elements((TILE * TILE) as u64));
    group.sample_size(20);
    for (name, params) in demos::all_params() {
        let tex = load(&demos::make(name, &params).unwrap()).unwrap();
        let short = name.trim_start_matches("LCM ").replace(' ', "-");
        // Operation counts of one level-0 tile, per intensity plane.
        let mut count = OpCount::default();
        let region = Region::new(0, 4096, 2048, TILE, TILE);
        let mut out = vec![0u8; region.byte_len()];
        tex.render_counted(&region, &mut out, &mut count);
        let (n, planes) = (tex.layer_count(), tex.planes() as f64);
        eprintln!(
            "{short}: N = {n} layers, {planes} plane(s); per pixel and plane: additions {:.2} (max {:.0}; 4N = {}), \
             multiplications {:.2} (max {:.0}; N = {n})",
            count.mean_adds() / planes,
            count.max_adds as f64 / planes,
            4 * n,
            count.mean_muls() / planes,
            count.max_muls as f64 / planes,
        );
        for level in [0u32, 3, 6] {
            let mut out = vec![0u8; (TILE * TILE * 4) as usize];
            let mut k = 0i64;
            group.bench_with_input(BenchmarkId::new(short.as_str(), format!("L{level}")), &level, |b, &level| {
                b.iter(|| {
                    // Walk over different tiles so the LCM reads are not all cache-hot.
                    k += 1;
                    let region = Region::new(level, (k * 7919) % 50_000, (k * 104_729) % 50_000, TILE, TILE);
                    tex.render(&region, &mut out, &vtex_synth::Never);
                    out[0]
                })
            });
        }
    }
    group.finish();
}

/// One 256² tile (or the whole level, when smaller) at the centre of `level` of a texture
/// loaded afresh for every sample.
fn cold_tiles(c: &mut Criterion, label: &str, load: &dyn Fn() -> std::sync::Arc<dyn Texture>) {
    let mut group = c.benchmark_group("lcm_cold_tile");
    group.sample_size(10);
    let probe = load();
    for level in 0..level_count(probe.width(), probe.height()) {
        let (w, h) = level_size(probe.width(), probe.height(), level);
        let (tw, th) = (w.min(TILE as u64) as u32, h.min(TILE as u64) as u32);
        let region = Region::new(level, (w / 2) as i64 / 256 * 256, (h / 2) as i64 / 256 * 256, tw, th);
        let mut out = vec![0u8; region.byte_len()];
        group.bench_function(BenchmarkId::new(label, format!("L{level}")), |b| {
            b.iter_batched(
                load,
                |tex| {
                    tex.render(&region, &mut out, &vtex_synth::Never);
                    out[0]
                },
                BatchSize::PerIteration,
            )
        });
    }
    group.finish();
}

fn cold(c: &mut Criterion) {
    let pebbles = demos::make("LCM pebbles 100k", &demos::pebbles()).unwrap();
    cold_tiles(c, "pebbles-100k", &|| models::load(&pebbles).unwrap());
    let mosaic = chaos_mosaic::demos().swap_remove(0);
    assert_eq!(mosaic.manifest.name, "Pebbles — chaos mosaic 100k");
    cold_tiles(c, "baseline-chaos-mosaic-100k", &|| models::load(&mosaic).unwrap());
}

criterion_group!(benches, bench, cold);
criterion_main!(benches);
