//! The figures of the served model: the paper's Fig. 5 quality panel (spec F5), the mip PSNR
//! table (spec Fmip) and a viewer session through the served cache (spec F9b), on the
//! project's own exemplars (the demos'), so they need nothing fetched. `scripts/synthesis-report.sh` makes the same panel on real
//! samples, with Embark beside it.

use super::plot::{self, Axis, Series, PALETTE};
use super::Out;
use serde_json::json;
use std::fmt::Write as _;
use std::time::Instant;
use vtex_quality::lattice::lattice_shares;
use vtex_quality::mip::psnr_by_level;
use vtex_quality::patch_sw::SwParams;
use vtex_quality::report::measure;
use vtex_quality::seam::Mask;
use vtex_quality::wei_levoy_2000;
use vtex_synth::bundle::Bundle;
use vtex_synth::models::order_independent::cache::BlockCache;
use vtex_synth::models::order_independent::{self, prefilter};
use vtex_synth::models::{self, Inputs};
use vtex_synth::pixels::decode_png;
use vtex_synth::texture::render_image;
use vtex_synth::{Region, Rgba8Image};

/// Side of the Fig. 5 outputs.
const SIDE: u32 = 256;

/// One panel of Fig. 5: the output and the sample pixel each of its pixels copies.
struct Panel {
    image: Rgba8Image,
    sources: Vec<(u32, u32)>,
    ms: f64,
}

/// A served order-independent texture's 256² window at the origin.
fn served_panel(bundle: &Bundle) -> Panel {
    let texture = order_independent::load(bundle).expect("a texture just created loads");
    let started = Instant::now();
    let image = render_image(&texture, &Region::new(0, 0, 0, SIDE, SIDE)).expect("a valid region");
    let ms = started.elapsed().as_secs_f64() * 1e3;
    Panel { image, sources: texture.sources(0, 0, SIDE, SIDE), ms }
}

/// Fig. 5: exemplar | Wei & Levoy 2000 (the paper's [19], sequential: one causal pass, and the
/// three passes the paper ran it with) | the paper's algorithm
/// (exhaustive search, three generations) | the served default | plain tiling, on each demo's
/// exemplar, with the metrics of each output against its exemplar. A verbatim copy (the
/// tiling) is the floor of patch SW, so repetition, seams, contrast, histogram and lattice
/// share judge; patch SW is beside them.
pub fn fig5(out: &Out) {
    let mut csv =
        String::from("exemplar,method,repetition,seam_ratio,contrast,histogram_w1,lattice_share_8,patch_sw,ms\n");
    let mut rows = Vec::new();
    for demo in order_independent::demos() {
        let name = demo_name(&demo);
        let sample = decode_png("sample", demo.section("sample.png").expect("a demo has its sample"))
            .expect("a demo's sample decodes");
        let wrap = demo.manifest.params["exemplar_wrap"].as_bool().unwrap_or(false);
        let wei_levoy = |passes: u32| {
            let params = wei_levoy_2000::Params { passes, ..wei_levoy_2000::Params::fig5(1, wrap) };
            let started = Instant::now();
            let s = wei_levoy_2000::synthesize(&sample, SIDE, SIDE, &params)
                .expect("the demo's sample suits Fig. 5's settings");
            Panel { image: s.image, sources: s.sources, ms: started.elapsed().as_secs_f64() * 1e3 }
        };
        let mut params = demo.manifest.params.clone();
        params["search"] = json!("exhaustive");
        let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
        let reference = models::create(order_independent::MODEL, &name, &params, &inputs).expect("a valid texture");
        let (w, h) = (sample.width, sample.height);
        let tiling_sources: Vec<(u32, u32)> = (0..SIDE * SIDE).map(|i| (i % SIDE % w, i / SIDE % h)).collect();
        let mut tiling = Rgba8Image::new(SIDE, SIDE);
        for (px, &(x, y)) in tiling.data.chunks_exact_mut(4).zip(&tiling_sources) {
            px.copy_from_slice(&sample.pixel(x, y));
        }
        let panels = [
            ("wei-levoy-2000", wei_levoy(1)),
            ("wei-levoy-2000 3 passes", wei_levoy(3)),
            ("order-independent exhaustive", served_panel(&reference)),
            ("served default", served_panel(&demo)),
            ("plain tiling", Panel { image: tiling, sources: tiling_sources, ms: 0.0 }),
        ];
        let mut row = vec![plot::captioned(&plot::captioned(&sample, ""), &name.to_uppercase())];
        for (method, p) in panels {
            let seams = Mask::from_sources(SIDE, SIDE, |x, y| p.sources[(y * SIDE + x) as usize]);
            let m = measure(&p.image, &sample, &seams, &SwParams::default()).expect("metrics of a 256² output");
            let lattice = lattice_shares(0, 0, SIDE, &p.sources, 3).expect("a full window of sources")[2].share;
            writeln!(
                csv,
                "{name},{method},{:.3},{:.3},{:.3},{:.2},{lattice:.3},{:.3},{:.0}",
                m.repetition.value,
                m.seam_ratio,
                m.contrast,
                m.histogram_w1_mean(),
                m.patch_sw.mean,
                p.ms
            )
            .unwrap();
            let label =
                format!("R {:.2} S {:.2} C {:.2} L {:.2}", m.repetition.value, m.seam_ratio, m.contrast, lattice);
            row.push(plot::captioned(&plot::captioned(&p.image, &label), &method.to_uppercase()));
        }
        rows.push(plot::beside(&row, 16, false));
    }
    out.write("fig5.csv", csv);
    out.png("fig5.png", &plot::beside(&rows, 16, true));
}

/// Fmip: every coarse level of each demo against the exact box chain of a level-0 window, and
/// point sampling (the aliasing baseline) beside it.
pub fn fig_mip(out: &Out) {
    const WINDOW: u32 = 2048;
    const LEVELS: u32 = 7;
    let mut csv = String::from("demo,level,source,psnr_served_db,psnr_point_db\n");
    let mut lines = Vec::new();
    for (i, bundle) in order_independent::demos().iter().enumerate() {
        let name = demo_name(bundle);
        let texture = order_independent::load(bundle).expect("a demo loads");
        let mut points = Vec::new();
        for m in psnr_by_level(&texture, WINDOW, LEVELS).expect("valid regions") {
            let source = match prefilter::source(texture.params(), m.level) {
                prefilter::Source::Exact => "exact".to_string(),
                prefilter::Source::Pyramid { r, .. } => format!("pyramid r={r}"),
                prefilter::Source::Mean => "mean".to_string(),
            };
            writeln!(csv, "{name},{},{source},{:.2},{:.2}", m.level, m.served_db, m.point_db).unwrap();
            points.push((m.level as f64, m.served_db.min(60.0)));
        }
        lines.push(Series { name: name.to_uppercase(), color: PALETTE[i], points });
    }
    out.write("mip_psnr.csv", csv);
    let x = Axis {
        label: "VTEX LEVEL".into(),
        min: 1.0,
        max: LEVELS as f64,
        log: false,
        ticks: (1..=LEVELS).map(|l| (l as f64, l.to_string())).collect(),
    };
    let y = Axis {
        label: "PSNR DB (60: EXACT)".into(),
        min: 20.0,
        max: 60.0,
        log: false,
        ticks: (2..=6).map(|t| (t as f64 * 10.0, (t * 10).to_string())).collect(),
    };
    out.png("mip_psnr.png", &plot::chart("MIP LEVELS AGAINST THE EXACT BOX CHAIN", &x, &y, &lines, 800, 520));
}

fn demo_name(bundle: &Bundle) -> String {
    bundle.manifest.name.split(" — ").nth(1).unwrap_or(&bundle.manifest.name).to_string()
}

/// F9b: a viewer's session — zoom in from level 4 to level 0, pan at level 0, zoom out to
/// level 1 and pan there — through the served evaluator of the lichen demo, for each block
/// side and cache budget: entries computed per requested pixel and time per tile. The viewer
/// keeps the tiles it has, so each tile is requested once.
pub fn fig9b(out: &Out) {
    const BUDGETS_MIB: [u64; 4] = [0, 8, 32, 128];
    let bundle = &order_independent::demos()[0];
    let tiles = viewer_trace();
    let mut csv = String::from("block,cache_mib,tiles,entries_per_pixel,ms_per_tile\n");
    let mut lines = Vec::new();
    for (i, side) in [16i64, 32, 64].into_iter().enumerate() {
        let mut points = Vec::new();
        for (k, mib) in BUDGETS_MIB.into_iter().enumerate() {
            let cache = std::sync::Arc::new(BlockCache::new(side));
            cache.set_budget(mib << 20);
            let texture = order_independent::load(bundle).expect("a demo loads").in_cache(cache);
            let started = Instant::now();
            for &(l, tx, ty) in &tiles {
                render_image(&texture, &Region::new(l, tx * 256, ty * 256, 256, 256)).expect("a valid tile");
            }
            let ms = started.elapsed().as_secs_f64() * 1e3 / tiles.len() as f64;
            let work: std::collections::HashMap<_, _> = texture.work_counters().into_iter().collect();
            let ratio = work["entries_computed"] as f64 / work["pixels_requested"] as f64;
            writeln!(csv, "{side},{mib},{},{ratio:.3},{ms:.1}", tiles.len()).unwrap();
            points.push((k as f64, ratio));
        }
        lines.push(Series { name: format!("{side}X{side} BLOCKS"), color: PALETTE[i], points });
    }
    out.write("tiles.csv", csv);
    let x = Axis {
        label: "CACHE MIB".into(),
        min: 0.0,
        max: (BUDGETS_MIB.len() - 1) as f64,
        log: false,
        ticks: BUDGETS_MIB.iter().enumerate().map(|(k, m)| (k as f64, m.to_string())).collect(),
    };
    let top = lines.iter().flat_map(|l| l.points.iter().map(|p| p.1)).fold(1.0, f64::max).ceil() as u32 + 1;
    let y = Axis {
        label: "ENTRIES PER PIXEL".into(),
        min: 0.0,
        max: top as f64,
        log: false,
        ticks: (0..=top).map(|t| (t as f64, t.to_string())).collect(),
    };
    out.png("tiles.png", &plot::chart("F9B: A VIEWER SESSION THROUGH THE SERVED CACHE", &x, &y, &lines, 800, 520));
}

/// The 256² tiles (level, column, row) a 1280×800 viewer requests, in order, each once.
fn viewer_trace() -> Vec<(u32, i64, i64)> {
    let (w, h) = (1280i64, 800i64);
    let mut views: Vec<(u32, i64, i64)> = (0..=4).rev().map(|l| (l, 0, 0)).collect();
    views.extend((1..=4).map(|k| (0, k * 256, k * 128)));
    views.extend((1..=4).map(|k| (1, -k * 512, 0)));
    let mut seen = std::collections::HashSet::new();
    let mut tiles = Vec::new();
    for (l, cx, cy) in views {
        // The view's centre is given in level-0 pixels.
        let (cx, cy) = (cx >> l, cy >> l);
        for ty in (cy - h / 2).div_euclid(256)..=(cy + h / 2 - 1).div_euclid(256) {
            for tx in (cx - w / 2).div_euclid(256)..=(cx + w / 2 - 1).div_euclid(256) {
                if seen.insert((l, tx, ty)) {
                    tiles.push((l, tx, ty));
                }
            }
        }
    }
    tiles
}
