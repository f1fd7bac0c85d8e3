//! Order-independent synthesis speed on one core: a cold 256² level-0 tile of each demo (64²
//! exemplars, the served default; target ≤ 60 ms), a cold mip tile, the exhaustive reference over a
//! 128² window, and the load (pyramid and k-coherence sets); a chaos-mosaic tile is the
//! baseline of the same run. The pyramidal cache has no budget here, so every tile is cold.
//! The tiles are also timed in the thread's CPU time (`…_cpu`), which a shared machine's load
//! does not inflate.
//! `cargo bench -p vtex-synth --bench order_independent`

#![forbid(unsafe_code)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use serde_json::json;
use std::time::Duration;
use vtex_synth::models::{self, chaos_mosaic, order_independent, Inputs};
use vtex_synth::texture::{Region, Texture};
use vtex_synth::{samples, Never};

fn tile(c: &mut Criterion, group: &str, id: &str, t: &dyn Texture, region: Region) {
    let mut g = c.benchmark_group(group);
    g.sample_size(10)
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(3));
    g.throughput(Throughput::Elements(region.pixel_count()));
    let mut out = vec![0u8; region.byte_len()];
    g.bench_function(BenchmarkId::from_parameter(id), |b| b.iter(|| t.render(&region, &mut out, &Never)));
    g.finish();
}

/// CPU time this thread has run, from Linux's scheduler statistics; `None` elsewhere.
fn thread_cpu() -> Option<Duration> {
    let stat = std::fs::read_to_string("/proc/thread-self/schedstat").ok()?;
    Some(Duration::from_nanos(stat.split_whitespace().next()?.parse().ok()?))
}

/// [`tile`] timed in the rendering thread's CPU time rather than wall time: on a machine shared
/// with other work, wall time also counts the time the thread waited for a core.
fn tile_cpu(c: &mut Criterion, group: &str, id: &str, t: &dyn Texture, region: Region) {
    if thread_cpu().is_none() {
        return;
    }
    let mut g = c.benchmark_group(group);
    g.sample_size(10).warm_up_time(Duration::from_millis(500)).measurement_time(Duration::from_secs(3));
    g.throughput(Throughput::Elements(region.pixel_count()));
    let mut out = vec![0u8; region.byte_len()];
    g.bench_function(BenchmarkId::from_parameter(id), |b| {
        b.iter_custom(|iters| {
            let start = thread_cpu().expect("read before");
            for _ in 0..iters {
                t.render(&region, &mut out, &Never);
            }
            thread_cpu().expect("read before") - start
        })
    });
    g.finish();
}

fn sample_inputs(size: u32) -> Inputs {
    let mut inputs = Inputs::new();
    inputs.insert("sample".into(), samples::pebbles(size, 9, 22, false).to_png());
    inputs
}

fn served(c: &mut Criterion) {
    for b in order_independent::demos() {
        let t = models::load(&b).unwrap();
        let name = b.manifest.name.split(" — ").nth(1).unwrap_or("?").to_string();
        tile(c, "oits_cold_tile_256", &name, t.as_ref(), Region::new(0, 1024, 2048, 256, 256));
        tile_cpu(c, "oits_cold_tile_256_cpu", &name, t.as_ref(), Region::new(0, 1024, 2048, 256, 256));
    }
    let b = &order_independent::demos()[1];
    let t = models::load(b).unwrap();
    // Level 2 with lookahead: synthesis level fin − 1 over 512², four chunks.
    tile(c, "oits_cold_mip_tile_256", "level 2", t.as_ref(), Region::new(2, 256, 512, 256, 256));
    let mosaic = &chaos_mosaic::demos()[0];
    let m = models::load(mosaic).unwrap();
    tile(c, "baseline_chaos_mosaic_tile_256", &mosaic.manifest.name, m.as_ref(), Region::new(0, 1024, 2048, 256, 256));
    let region = Region::new(0, 1024, 2048, 256, 256);
    tile_cpu(c, "baseline_chaos_mosaic_tile_256_cpu", &mosaic.manifest.name, m.as_ref(), region);
}

fn exhaustive(c: &mut Criterion) {
    let params = json!({"seed": 5, "search": "exhaustive"});
    let t = models::load(&models::create("order-independent", "bench", &params, &sample_inputs(64)).unwrap()).unwrap();
    tile(c, "oits_exhaustive_window", "128x128", t.as_ref(), Region::new(0, 300, 700, 128, 128));
}

fn load(c: &mut Criterion) {
    let mut g = c.benchmark_group("oits_load");
    g.sample_size(10);
    for size in [64u32, 128] {
        let b = models::create("order-independent", "bench", &json!({"seed": 5}), &sample_inputs(size)).unwrap();
        g.bench_function(BenchmarkId::from_parameter(format!("{size}x{size}")), |bench| {
            bench.iter(|| models::load(&b).unwrap())
        });
    }
    g.finish();
}

criterion_group!(benches, served, exhaustive, load);
criterion_main!(benches);
