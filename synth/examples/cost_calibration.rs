//! Holds every demo's cost plan against the time its work takes here: the worst 256² tile of
//! each level (each level on a fresh load, so caches a level fills on first use are paid by
//! its first tile), `load`, and for models whose manifest parameters are `create`'s own, the
//! `create` that made it (a cascade's without its `range`, so the estimate runs too). A work
//! unit is meant to be about one nanosecond of one core: the ratios say how far off it is.
//!
//! `flock /tmp/vtex-bench.lock cargo run -p vtex-synth --release --example cost_calibration [-- filter]`
//! (`-v` after the filter also prints each level's worst tile).

use std::time::Instant;
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, Inputs};
use vtex_synth::texture::{level_count, level_size, render_image};
use vtex_synth::Region;

/// Seconds of the fastest of `runs` runs of `f`.
fn best<T>(runs: usize, mut f: impl FnMut() -> T) -> f64 {
    (0..runs)
        .map(|_| {
            let t = Instant::now();
            std::hint::black_box(f());
            t.elapsed().as_secs_f64()
        })
        .fold(f64::INFINITY, f64::min)
}

/// The worst time of a tile of `level` over a few positions (and a later frame when animated),
/// on a texture loaded afresh.
fn worst_tile(bundle: &Bundle, level: u32) -> f64 {
    let tex = models::load(bundle).expect("demos load");
    let (lw, lh) = level_size(tex.width(), tex.height(), level);
    let frames: &[u32] = if tex.animation().is_some() { &[0, 37] } else { &[0] };
    let mut worst = 0.0f64;
    for (fx, fy) in [(0, 0), (1, 2), (3, 3)] {
        for &frame in frames {
            let (x, y) = ((lw * fx / 3) as i64 - 128, (lh * fy / 3) as i64 - 128);
            let region = Region::new(level, x, y, 256, 256).at_frame(frame);
            let t = Instant::now();
            std::hint::black_box(render_image(&*tex, &region).expect("tiles render"));
            worst = worst.max(t.elapsed().as_secs_f64());
        }
    }
    worst
}

/// `create`'s parameters and inputs for a demo, when its manifest holds them as `create` takes
/// them: the chaos mosaic's (the sample as input) and the cascade's (less `range`).
fn create_inputs(bundle: &Bundle) -> Option<(serde_json::Value, Inputs)> {
    let mut params = bundle.manifest.params.clone();
    let input = |section: &str| section.trim_end_matches(".png").to_string();
    match bundle.manifest.model.as_str() {
        "chaos-mosaic" => {}
        "cascade" => {
            params.as_object_mut()?.remove("range");
        }
        _ => return None,
    }
    let images = bundle.sections.iter().filter(|s| s.name.ends_with(".png"));
    Some((params, images.map(|s| (input(&s.name), s.data.clone())).collect()))
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let filter = args.first().filter(|a| *a != "-v").cloned().unwrap_or_default();
    let verbose = args.iter().any(|a| a == "-v");
    println!("| demo | tile: plan / worst measured (level) = ratio | load: plan / measured = ratio | create+load: plan / measured = ratio |");
    println!("|---|---|---|---|");
    let mut ratios: Vec<(String, f64)> = Vec::new();
    for bundle in models::demos() {
        let label = format!("{}/{}", bundle.manifest.model, bundle.manifest.name);
        if !label.contains(&filter) {
            continue;
        }
        let plan = models::plan(&bundle).expect("demos plan");
        let tex = models::load(&bundle).expect("demos load");
        let levels = level_count(tex.width(), tex.height());
        let mut per_level = Vec::new();
        for level in 0..levels {
            per_level.push(worst_tile(&bundle, level));
        }
        let (worst_level, worst) =
            per_level.iter().copied().enumerate().fold((0, 0.0), |a, (l, t)| if t > a.1 { (l, t) } else { a });
        if verbose {
            let cells: Vec<String> = per_level.iter().map(|t| format!("{:.2}", t * 1e3)).collect();
            println!("  {label}: worst tile ms per level: {}", cells.join(" "));
        }
        let load = best(3, || models::load(&bundle).expect("demos load"));
        let ns = |s: f64| s * 1e9;
        let tile_ratio = plan.cost.tile_work.value as f64 / ns(worst);
        let load_ratio = plan.cost.build_work.value as f64 / ns(load);
        ratios.push((format!("{label} tile"), tile_ratio));
        ratios.push((format!("{label} load"), load_ratio));
        let create = create_inputs(&bundle).map(|(params, inputs)| {
            let model = models::get(&bundle.manifest.model).expect("a registered model");
            let planned = model.plan_create(&params, &inputs).expect("demo parameters plan");
            let took = best(1, || {
                let b = model.create("calibration", &params, &inputs).expect("demo parameters create");
                models::load(&b).expect("created bundles load")
            });
            let ratio = planned.cost.build_work.value as f64 / ns(took);
            ratios.push((format!("{label} create+load"), ratio));
            format!("{:.1} ms / {:.1} ms = {ratio:.2}", planned.cost.build_work.value as f64 / 1e6, took * 1e3)
        });
        println!(
            "| {label} | {:.2} ms / {:.2} ms (L{worst_level}) = {tile_ratio:.2} | {:.2} ms / {:.2} ms = {load_ratio:.2} | {} |",
            plan.cost.tile_work.value as f64 / 1e6,
            worst * 1e3,
            plan.cost.build_work.value as f64 / 1e6,
            load * 1e3,
            create.unwrap_or_else(|| "n/a".into()),
        );
    }
    let far = |r: f64| if r >= 1.0 { r } else { 1.0 / r };
    if let Some((what, r)) = ratios.iter().max_by(|a, b| far(a.1).total_cmp(&far(b.1))) {
        println!("\nfarthest from 1 ns a unit: {what}, plan / measured = {r:.2}");
    }
}
