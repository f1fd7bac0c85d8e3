//! Cascade synthesis speed: megapixels per second on one core for 256² tiles, and how the
//! cost grows with iterations, kernel size and cascade depth (throughput is reported in
//! elements = pixels, so criterion prints Melem/s = Mpx/s).
//! `cargo bench -p vtex-synth --bench cascade`

#![forbid(unsafe_code)]

use criterion::{criterion_group, criterion_main, BenchmarkId, Criterion, Throughput};
use serde_json::json;
use vtex_synth::models::{self, cascade, Inputs};
use vtex_synth::texture::{Region, Texture};

const TILE: u32 = 256;

fn tex(params: serde_json::Value) -> std::sync::Arc<dyn Texture> {
    models::load(&models::create("cascade", "bench", &params, &Inputs::new()).unwrap()).unwrap()
}

fn tile(c: &mut Criterion, group: &str, id: String, t: &dyn Texture, region: Region) {
    let mut g = c.benchmark_group(group);
    g.sample_size(10)
        .warm_up_time(std::time::Duration::from_millis(500))
        .measurement_time(std::time::Duration::from_secs(2));
    g.throughput(Throughput::Elements(region.pixel_count()));
    let mut out = vec![0u8; region.byte_len()];
    g.bench_function(BenchmarkId::from_parameter(id), |b| b.iter(|| t.render(&region, &mut out, &vtex_synth::Never)));
    g.finish();
}

fn demos(c: &mut Criterion) {
    for b in cascade::demos() {
        let t = models::load(&b).unwrap();
        let name = b.manifest.name.split(' ').nth(1).unwrap_or("?").to_string();
        tile(c, "demo_tile_256", name.clone(), t.as_ref(), Region::new(0, 1024, 2048, TILE, TILE));
        // Far from the origin: must cost the same.
        tile(c, "demo_tile_256_far", name, t.as_ref(), Region::new(0, (1 << 40) + 7, -(1 << 41), TILE, TILE));
    }
}

fn growth(c: &mut Criterion) {
    let stage = |size: u32, iterations: u32| json!({"kernel": {"size": size, "preset": "gauss"}, "map": {"kind": "logistic", "r": 3.7}, "iterations": iterations});
    for k in [1, 2, 5, 10, 20] {
        let t = tex(json!({"seed": 1, "stages": [stage(5, k)]}));
        tile(c, "iterations_k5x5", k.to_string(), t.as_ref(), Region::new(0, 0, 0, TILE, TILE));
    }
    for n in [1, 3, 5, 7] {
        let t = tex(json!({"seed": 1, "stages": [stage(n, 5)]}));
        tile(c, "kernel_size_5_iterations", format!("{n}x{n}"), t.as_ref(), Region::new(0, 0, 0, TILE, TILE));
    }
    for depth in [1usize, 2, 3, 4, 6] {
        let mut stages = vec![stage(5, 5)];
        for _ in 1..depth {
            let mut s = stage(5, 5);
            s["upsample"] = json!(2);
            s["jitter"] = json!(0.1);
            stages.push(s);
        }
        let t = tex(json!({"seed": 1, "stages": stages}));
        tile(c, "cascade_depth_5x5_5it", depth.to_string(), t.as_ref(), Region::new(0, 0, 0, TILE, TILE));
    }
    let t = tex(
        json!({"seed": 1, "stages": [stage(5, 5), {"upsample": 2, "kernel": {"size": 5, "preset": "gauss"}}, {"upsample": 2, "kernel": {"size": 5, "preset": "gauss"}}]}),
    );
    for level in [0, 1, 2, 3, 5, 8] {
        tile(c, "mip_level_3_stages", level.to_string(), t.as_ref(), Region::new(level, 0, 0, TILE, TILE));
    }
}

criterion_group!(benches, demos, growth);
criterion_main!(benches);
