//! The figures of Wei & Levoy 2002, *Order-Independent Texture Synthesis* (spec §6), as CSV
//! files and PNG images. The cache figures (F3, F7a, F7bc, F4, F8, F9) are counted by the
//! reference evaluator in structure-only mode (which entries are computed does not depend on the
//! search); Fig. 5's quality panel (F5) sets the served model beside Wei & Levoy 2000 and the
//! paper's algorithm, and the mip PSNR table (Fmip) renders the served model.
//!
//! `cargo run --release -p vtex-quality --example oits_figures -- [OUT_DIR [FIGURE…]]`
//!
//! OUT_DIR defaults to `docs/models/oits-figures`; FIGURE (F3, F7, F4, F8, F9, F9b, F5, Fmip) limits
//! the run to those figures. `docs/models/order-independent-figures.md` sets the numbers beside
//! the paper's.

#[path = "oits_figures/plot.rs"]
mod plot;
#[path = "oits_figures/scenes.rs"]
mod scenes;
#[path = "oits_figures/served.rs"]
mod served;

use plot::{Axis, Canvas, Series, PALETTE};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::fmt::Write as _;
use std::path::PathBuf;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::time::Instant;
use vtex_synth::hash::hash4;
use vtex_synth::models::order_independent::reference::{entries, paper, toy, Reference, StructureOnly, UNBOUNDED};
use vtex_synth::models::order_independent::structure::{Entry, Structure};
use vtex_synth::Rgba8Image;

/// A pixel request: level s (paper convention, 0 = coarsest) and pixel (x, y).
type Request = (u8, i64, i64);

struct Out(PathBuf);

type Figure = fn(&Out);

impl Out {
    fn write(&self, name: &str, bytes: impl AsRef<[u8]>) {
        std::fs::write(self.0.join(name), bytes).unwrap_or_else(|e| panic!("writing {name}: {e}"));
        println!("  {name}");
    }

    fn png(&self, name: &str, image: &Rgba8Image) {
        self.write(name, image.to_png());
    }
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let dir = PathBuf::from(args.first().map_or("docs/models/oits-figures", String::as_str));
    let only = &args[args.len().min(1)..];
    std::fs::create_dir_all(&dir).expect("creating the output directory");
    let out = Out(dir);
    let start = Instant::now();
    let figures: [(&str, Figure); 8] = [
        ("F3", fig3),
        ("F7", fig7),
        ("F4", fig4),
        ("F8", fig8),
        ("F9", fig9),
        ("F9b", served::fig9b),
        ("F5", served::fig5),
        ("Fmip", served::fig_mip),
    ];
    for (name, figure) in figures {
        if !only.is_empty() && !only.iter().any(|f| f == name) {
            continue;
        }
        let t = Instant::now();
        println!("{name}");
        figure(&out);
        println!("{name}: {:.1} s", t.elapsed().as_secs_f64());
    }
    println!("all figures: {:.1} s", start.elapsed().as_secs_f64());
}

/// `f` of every item on every core, results in the items' order.
fn par_map<T: Sync, R: Send>(items: &[T], f: impl Fn(&T) -> R + Sync) -> Vec<R> {
    let next = AtomicUsize::new(0);
    let threads = std::thread::available_parallelism().map_or(1, |n| n.get()).min(items.len().max(1));
    let mut results: Vec<(usize, R)> = std::thread::scope(|scope| {
        let workers: Vec<_> = (0..threads)
            .map(|_| {
                scope.spawn(|| {
                    let mut done = Vec::new();
                    loop {
                        let i = next.fetch_add(1, Ordering::Relaxed);
                        let Some(item) = items.get(i) else { return done };
                        done.push((i, f(item)));
                    }
                })
            })
            .collect();
        workers.into_iter().flat_map(|w| w.join().expect("a figure worker panicked")).collect()
    });
    results.sort_by_key(|&(i, _)| i);
    results.into_iter().map(|(_, r)| r).collect()
}

/// The cache after `requests` into an unbounded cache: the footprint of the request set.
fn footprint(st: &Structure, requests: &[Request]) -> Reference<StructureOnly> {
    let mut r = Reference::new(st.clone(), StructureOnly, UNBOUNDED);
    for &(s, x, y) in requests {
        r.request(s, x, y);
    }
    r
}

/// Cached entries by (level, generation), finest level and latest generation first.
fn by_level_and_generation(r: &Reference<StructureOnly>) -> Vec<((u8, u8), usize)> {
    let mut counts: BTreeMap<(u8, u8), usize> = BTreeMap::new();
    for e in r.cached() {
        *counts.entry((e.s, e.m)).or_default() += 1;
    }
    counts.into_iter().rev().collect()
}

/// F3: the toy of Fig. 3, its footprint by (level, generation) and its dependency graph with
/// the entries numbered as in the paper (level, generation, then row-major).
fn fig3(out: &Out) {
    let st = toy();
    let r = footprint(&st, &[(1, 0, 0)]);
    let mut csv = String::from("level,generation,count\n");
    for ((s, m), n) in by_level_and_generation(&r) {
        writeln!(csv, "{s},{m},{n}").unwrap();
    }
    writeln!(csv, "total,,{}", r.counters().computed).unwrap();
    out.write("fig3_footprint.csv", csv);

    let mut all: Vec<Entry> = r.cached().collect();
    all.sort_by_key(|e| (std::cmp::Reverse((e.s, e.m)), e.y, e.x));
    let number: HashMap<Entry, usize> = all.iter().enumerate().map(|(i, &e)| (e, i)).collect();
    let mut dot = String::from("digraph fig3 {\n  node [shape=circle];\n");
    for ((s, m), _) in by_level_and_generation(&r) {
        let members: Vec<String> = all.iter().filter(|e| (e.s, e.m) == (s, m)).map(|e| number[e].to_string()).collect();
        writeln!(dot, "  subgraph cluster_{s}_{m} {{ label=\"level {s}, generation {m}\"; {}; }}", members.join("; "))
            .unwrap();
    }
    let mut deps = Vec::new();
    for e in &all {
        deps.clear();
        st.dependencies(*e, &mut deps);
        for d in &deps {
            writeln!(dot, "  {} -> {};", number[e], number[d]).unwrap();
        }
    }
    dot.push_str("}\n");
    out.write("fig3_graph.dot", dot);
}

/// The footprint as masks laid out like Fig. 7: one row per level (finest on top), one column
/// per generation (latest on the left); black = in the cache, red = requested.
fn masks(st: &Structure, r: &Reference<StructureOnly>, requests: &[Request], title: &str) -> Rgba8Image {
    const ZOOM: u32 = 2;
    let cached: HashSet<Entry> = r.cached().collect();
    let requested: HashSet<Entry> = requests.iter().map(|&(s, x, y)| st.output(s, x, y)).collect();
    let mut rows = Vec::new();
    for s in (0..st.levels).rev() {
        let (w, h) = st.period(s).unwrap();
        let mut cells = Vec::new();
        for m in (0..st.generations).rev() {
            let mut c = Canvas::new(w as u32 * ZOOM, h as u32 * ZOOM);
            if m < st.generations_of(s) {
                for y in 0..h as i64 {
                    for x in 0..w as i64 {
                        let e = Entry { s, m, x, y };
                        let colour = match (requested.contains(&e), cached.contains(&e)) {
                            (true, _) => [230, 30, 30],
                            (false, true) => [0, 0, 0],
                            (false, false) => [225, 225, 225],
                        };
                        c.rect(x * ZOOM as i64, y * ZOOM as i64, ZOOM as i64, ZOOM as i64, colour);
                    }
                }
            }
            let n = cached.iter().filter(|e| (e.s, e.m) == (s, m)).count();
            let label = if m < st.generations_of(s) { format!("L{s} G{m}: {n}") } else { String::new() };
            cells.push(plot::captioned(&c.image, &label));
        }
        rows.push(plot::beside(&cells, 8, false));
    }
    let grid = plot::beside(&rows, 8, true);
    plot::captioned(&grid, &format!("{title}: {} ENTRIES", r.counters().computed))
}

/// `n` well-spread pixels of a `side`² torus: Mitchell's best candidate, an incremental
/// approximation of a Poisson-disk process.
fn poisson_disk(side: i64, n: usize, seed: u64) -> Vec<(i64, i64)> {
    const CANDIDATES: u64 = 16;
    let torus = |a: i64, b: i64| (a - b).rem_euclid(side).min((b - a).rem_euclid(side));
    let mut points: Vec<(i64, i64)> = Vec::with_capacity(n);
    for i in 0..n as u64 {
        let candidate = |k: u64| {
            let h = hash4(seed, i, k as i64, 0);
            ((h % side as u64) as i64, ((h >> 32) % side as u64) as i64)
        };
        let spacing = |&(x, y): &(i64, i64)| {
            points.iter().map(|&(px, py)| torus(x, px).pow(2) + torus(y, py).pow(2)).min().unwrap_or(i64::MAX)
        };
        let best = (0..CANDIDATES).map(candidate).max_by_key(spacing).expect("at least one candidate");
        points.push(best);
    }
    points
}

/// The `n` pixels nearest to pixel (c, c) of a `side`² texture, c = side / 2 + 3 (the phase
/// (3, 3) of Fig. 7a's 1148): a disk of exactly `n` pixels.
fn disk(side: i64, n: usize) -> Vec<(i64, i64)> {
    let c = side / 2 + 3;
    let mut all: Vec<(i64, i64)> = (0..side).flat_map(|y| (0..side).map(move |x| (x, y))).collect();
    all.sort_by_key(|&(x, y)| ((x - c).pow(2) + (y - c).pow(2), hash4(1, 0, x, y)));
    all.truncate(n);
    all
}

/// F7: the single-pixel phase table (512² torus) and the footprints of one pixel, of random
/// (Poisson-disk) pixels and of a disk of pixels, at the paper's image sizes (128² torus).
fn fig7(out: &Out) {
    let st = paper(512);
    let mut csv = String::from("y\\x,0,1,2,3,4,5,6,7\n");
    for y in 0..8 {
        let row: Vec<String> =
            (0..8).map(|x| footprint(&st, &[(3, 256 + x, 256 + y)]).counters().computed.to_string()).collect();
        writeln!(csv, "{y},{}", row.join(",")).unwrap();
    }
    out.write("fig7a_phase.csv", csv);

    let st = paper(128);
    let one = [(3, 67, 67)];
    out.png("fig7a_masks.png", &masks(&st, &footprint(&st, &one), &one, "FIG. 7A ONE PIXEL AT PHASE (3,3)"));

    let total = entries(&st);
    let mut csv = String::from("pattern,requested,touched,touched_fraction");
    for s in (0..st.levels).rev() {
        for m in (0..st.generations_of(s)).rev() {
            write!(csv, ",L{s}G{m}").unwrap();
        }
    }
    csv.push('\n');
    let mut record = |pattern: &str, requests: &[Request], r: &Reference<StructureOnly>| {
        let touched = r.counters().computed;
        write!(csv, "{pattern},{},{touched},{:.5}", requests.len(), touched as f64 / total as f64).unwrap();
        for (_, n) in by_level_and_generation(r) {
            write!(csv, ",{n}").unwrap();
        }
        csv.push('\n');
    };
    record("single", &one, &footprint(&st, &one));
    for n in [64, 256, 1024] {
        let mut panels = Vec::new();
        for (pattern, pixels) in [("random", poisson_disk(128, n, 7)), ("disk", disk(128, n))] {
            let requests: Vec<Request> = pixels.into_iter().map(|(x, y)| (3, x, y)).collect();
            let r = footprint(&st, &requests);
            record(pattern, &requests, &r);
            let title = format!("FIG. 7{} {} {n} PIXELS", if pattern == "random" { "B" } else { "C" }, pattern);
            panels.push(masks(&st, &r, &requests, &title));
        }
        out.png(&format!("fig7bc_{n}.png"), &plot::beside(&panels, 24, false));
    }
    out.write("fig7bc.csv", csv);
}

/// Every pixel of a `side`² texture in a jittered coarse-to-fine order: after 4^k pixels there
/// is one in each block of side `side` / 2^k, so every prefix is spread like a Poisson disk.
fn stratified(side: i64, seed: u64) -> Vec<(i64, i64)> {
    let mut taken = vec![false; (side * side) as usize];
    let mut order = Vec::with_capacity(taken.len());
    let mut block = side;
    while block >= 1 {
        let mut stage = Vec::new();
        for by in (0..side).step_by(block as usize) {
            for bx in (0..side).step_by(block as usize) {
                let inside = (by..by + block).flat_map(|y| (bx..bx + block).map(move |x| (x, y)));
                if inside.clone().any(|(x, y)| taken[(y * side + x) as usize]) {
                    continue;
                }
                let h = hash4(seed, block as u64, bx, by);
                let (x, y) = (bx + (h % block as u64) as i64, by + ((h >> 32) % block as u64) as i64);
                stage.push((hash4(seed, 1 << 40, x, y), (x, y)));
            }
        }
        stage.sort_unstable();
        for (_, (x, y)) in stage {
            taken[(y * side + x) as usize] = true;
            order.push((x, y));
        }
        block /= 2;
    }
    order
}

/// F4: the fraction of a cache holding all 1,036,288 entries of a 512² texture that requests
/// touch, as the requested fraction grows: a growing disk, Poisson-disk-like spread pixels and
/// uniformly random pixels.
fn fig4(out: &Out) {
    const SIDE: i64 = 512;
    let st = paper(SIDE as u64);
    let total = entries(&st) as f64;
    let pixels = (SIDE * SIDE) as usize;
    let checkpoints: Vec<usize> = (0..18).map(|k| 1 << k).chain((1..=256).map(|i| i * pixels / 256)).collect();
    let mut random: Vec<(u64, (i64, i64))> =
        (0..SIDE).flat_map(|y| (0..SIDE).map(move |x| (hash4(11, 0, x, y), (x, y)))).collect();
    random.sort_unstable();
    let patterns: Vec<(&str, Vec<(i64, i64)>)> = vec![
        ("disk", disk(SIDE, pixels)),
        ("poisson", stratified(SIDE, 5)),
        ("random", random.into_iter().map(|(_, p)| p).collect()),
    ];
    let curves = par_map(&patterns, |(_, order)| {
        let mut r = Reference::new(st.clone(), StructureOnly, UNBOUNDED);
        let mut curve = Vec::new();
        for (i, &(x, y)) in order.iter().enumerate() {
            r.request(3, x, y);
            if checkpoints.binary_search(&(i + 1)).is_ok() {
                curve.push((i + 1, r.counters().computed));
            }
        }
        curve
    });
    let mut csv = String::from("pattern,requested,touched,requested_fraction,touched_fraction\n");
    let mut linear = Vec::new();
    let mut log = Vec::new();
    for (((name, _), curve), colour) in patterns.iter().zip(&curves).zip([PALETTE[0], PALETTE[2], PALETTE[1]]) {
        let points: Vec<(f64, f64)> =
            curve.iter().map(|&(n, t)| (n as f64 / pixels as f64, t as f64 / total)).collect();
        for (&(n, t), &(fx, fy)) in curve.iter().zip(&points) {
            writeln!(csv, "{name},{n},{t},{fx:.6},{fy:.6}").unwrap();
        }
        linear.push(Series { name: name.to_string(), color: colour, points: points.clone() });
        log.push(Series { name: name.to_string(), color: colour, points });
    }
    out.write("fig4.csv", csv);
    let ideal = Series { name: "ideal".into(), color: plot::BLACK, points: vec![(0.0, 0.0), (1.0, 1.0)] };
    let tenths = |v: f64| (v, format!("{v:.1}"));
    let axis = |label: &str| Axis {
        label: label.into(),
        min: 0.0,
        max: 1.0,
        log: false,
        ticks: (0..=10).map(|i| tenths(i as f64 / 10.0)).collect(),
    };
    linear.push(ideal);
    let chart = plot::chart(
        "FIG. 4  CACHE USAGE, 512X512",
        &axis("REQUESTED FRACTION"),
        &axis("TOUCHED FRACTION"),
        &linear,
        900,
        640,
    );
    out.png("fig4.png", &chart);
    let decades = |min: i32| (min..=0).map(|k| (10f64.powi(k), format!("1E{k}"))).collect::<Vec<_>>();
    let x =
        Axis { label: "REQUESTED FRACTION".into(), min: 1.0 / pixels as f64, max: 1.0, log: true, ticks: decades(-5) };
    let y = Axis { label: "TOUCHED FRACTION".into(), min: 1e-3, max: 1.0, log: true, ticks: decades(-3) };
    log.push(Series { name: "ideal".into(), color: plot::BLACK, points: vec![(1e-3, 1e-3), (1.0, 1.0)] });
    out.png("fig4_log.png", &plot::chart("FIG. 4 ON LOG AXES: INTERCEPT 1148/1036288", &x, &y, &log, 900, 640));
}

/// The pixels of a `side`² texture in tiled rasterization order: tiles of `tile`² in scanline
/// order, scanline order inside each tile.
fn tiled(side: i64, tile: i64) -> impl Iterator<Item = (i64, i64)> {
    (0..side).step_by(tile as usize).flat_map(move |ty| {
        (0..side)
            .step_by(tile as usize)
            .flat_map(move |tx| (ty..ty + tile).flat_map(move |y| (tx..tx + tile).map(move |x| (x, y))))
    })
}

/// F8: the computation ratio of a 512² texture requested in tiled rasterization order, for
/// every tile size and LRU capacity.
fn fig8(out: &Out) {
    const SIDE: i64 = 512;
    let st = paper(SIDE as u64);
    let tiles: Vec<i64> = (0..10).map(|k| 1 << k).collect();
    let caches: Vec<usize> = (0..9).map(|k| 1024 << k).collect();
    let runs: Vec<(i64, usize)> = tiles.iter().flat_map(|&t| caches.iter().map(move |&c| (t, c))).collect();
    let results = par_map(&runs, |&(tile, cache)| {
        let mut r = Reference::new(st.clone(), StructureOnly, cache);
        for (x, y) in tiled(SIDE, tile) {
            r.request(3, x, y);
        }
        r.counters()
    });
    let mut csv = String::from("tile,cache,requests,computed,computed_without_noise,ratio,ratio_without_noise\n");
    let mut series: BTreeMap<i64, Vec<(f64, f64)>> = BTreeMap::new();
    for (&(tile, cache), c) in runs.iter().zip(&results) {
        let ratio = c.computed as f64 / c.requests as f64;
        let without = c.computed_without_noise as f64 / c.requests as f64;
        writeln!(
            csv,
            "{tile},{cache},{},{},{},{ratio:.4},{without:.4}",
            c.requests, c.computed, c.computed_without_noise
        )
        .unwrap();
        series.entry(tile).or_default().push((cache as f64, ratio));
    }
    out.write("fig8.csv", csv);
    let max = results.iter().map(|c| c.computed as f64 / c.requests as f64).fold(4.0, f64::max);
    let x = Axis {
        label: "CACHE SIZE (ENTRIES)".into(),
        min: 1024.0,
        max: 262144.0,
        log: true,
        ticks: plot::powers_of_two(1024, 262144, |v| format!("{}K", v / 1024)),
    };
    let y = Axis {
        label: "COMPUTATION RATIO".into(),
        min: 3.0,
        max: max * 1.1,
        log: true,
        ticks: [3.0, 4.0, 5.0, 7.0, 10.0, 20.0, 50.0, 100.0, 200.0, 500.0, 1000.0]
            .into_iter()
            .filter(|&v| v <= max * 1.1)
            .map(|v| (v, format!("{v}")))
            .collect(),
    };
    let panel = |title: &str, range: std::ops::RangeInclusive<i64>| {
        let lines: Vec<Series> = series
            .iter()
            .filter(|(t, _)| range.contains(t))
            .enumerate()
            .map(|(i, (t, points))| Series { name: format!("{t}X{t}"), color: PALETTE[i], points: points.clone() })
            .collect();
        plot::chart(title, &x, &y, &lines, 700, 560)
    };
    let panels = [panel("FIG. 8A  TILES 1-16", 1..=16), panel("FIG. 8B  TILES 16-512", 16..=512)];
    out.png("fig8.png", &plot::beside(&panels, 16, false));
}

/// The entries a scene preloads: the boundary ring of its `border` texels at the finest level
/// (proportionally narrower at coarser levels), at each level's latest generation.
fn border_pins(st: &Structure, border: u64) -> Vec<Entry> {
    let mut pins = Vec::new();
    for s in 0..st.levels {
        let (w, h) = st.period(s).unwrap();
        let ring = (border >> (st.finest() - s)) as i64;
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                if x < ring || y < ring || x >= w as i64 - ring || y >= h as i64 - ring {
                    pins.push(st.output(s, x, y));
                }
            }
        }
    }
    pins
}

/// F9: the computation ratio of four synthetic scenes for LRU capacities of 1K to 64K entries
/// (and unbounded); a request at mip level j is entry (fin − j, last).
fn fig9(out: &Out) {
    let scenes = [scenes::polygon(), scenes::quake("quake-I", 64), scenes::quake("quake-II", 512), scenes::qtvr()];
    let caches: Vec<usize> = (0..7).map(|k| 1024 << k).chain([UNBOUNDED]).collect();
    let runs: Vec<(usize, usize)> = (0..scenes.len()).flat_map(|i| caches.iter().map(move |&c| (i, c))).collect();
    let results = par_map(&runs, |&(i, cache)| {
        let scene = &scenes[i];
        let st = paper(scene.texture);
        let mut r = Reference::new(st.clone(), StructureOnly, cache);
        for e in border_pins(&st, scene.pinned_border) {
            r.pin(e, 0);
        }
        for read in &scene.reads {
            r.request(st.finest() - read.j, read.x, read.y);
        }
        r.counters()
    });
    let mut csv = String::from(
        "scene,cache,reads,texels_requested,requested_percent,computed,computed_percent,ratio,ratio_without_noise\n",
    );
    let mut lines = Vec::new();
    for (i, scene) in scenes.iter().enumerate() {
        let st = paper(scene.texture);
        let distinct: HashSet<Entry> = scene.reads.iter().map(|r| st.output(st.finest() - r.j, r.x, r.y)).collect();
        let levels = scene.reads.iter().map(|r| r.j).max().unwrap_or(0);
        let texels: u64 = (0..=levels).map(|j| (scene.texture >> j).pow(2)).sum();
        let requested = 100.0 * distinct.len() as f64 / texels as f64;
        let mut points = Vec::new();
        for (&(_, cache), c) in runs.iter().zip(&results).filter(|((j, _), _)| *j == i) {
            let ratio = c.computed as f64 / c.requests as f64;
            let without = c.computed_without_noise as f64 / c.requests as f64;
            let computed = 100.0 * c.computed as f64 / entries(&st) as f64;
            let cache_label = if cache == UNBOUNDED { "unbounded".to_string() } else { cache.to_string() };
            writeln!(
                csv,
                "{},{cache_label},{},{},{requested:.1},{},{computed:.1},{ratio:.4},{without:.4}",
                scene.name,
                c.requests,
                distinct.len(),
                c.computed
            )
            .unwrap();
            if cache != UNBOUNDED {
                points.push((cache as f64, ratio));
            }
        }
        lines.push(Series { name: scene.name.to_uppercase(), color: PALETTE[i], points });
        out.png(&format!("fig9_requests_{}.png", scene.name), &requested_texels(&st, &distinct, levels));
    }
    out.write("fig9.csv", csv);
    let x = Axis {
        label: "CACHE SIZE (ENTRIES)".into(),
        min: 1024.0,
        max: 65536.0,
        log: true,
        ticks: plot::powers_of_two(1024, 65536, |v| format!("{}K", v / 1024)),
    };
    // Log axes: the ratios span four decades, from quake-I's plateau to the 1K cache's thrashing.
    let points = || lines.iter().flat_map(|l| l.points.iter().map(|p| p.1));
    let (low, high) = (points().fold(f64::INFINITY, f64::min), points().fold(0.0, f64::max));
    let (min, max) = (10f64.powf(low.log10().floor()), 10f64.powf(high.log10().ceil()));
    let y = Axis {
        label: "COMPUTATION RATIO".into(),
        min,
        max,
        log: true,
        ticks: [0.001, 0.01, 0.1, 0.25, 0.5, 1.0, 2.0, 3.5, 10.0, 20.0, 100.0]
            .into_iter()
            .filter(|v| (min..=max).contains(v))
            .map(|v| (v, format!("{v}")))
            .collect(),
    };
    out.png("fig9.png", &plot::chart("FIG. 9  SYNTHETIC SCENES", &x, &y, &lines, 900, 600));
}

/// The requested texels of mip levels 0 to `levels`, side by side like Fig. 6(b): black =
/// requested, grey = never requested.
fn requested_texels(st: &Structure, distinct: &HashSet<Entry>, levels: u8) -> Rgba8Image {
    let images: Vec<Rgba8Image> = (0..=levels)
        .map(|j| {
            let s = st.finest() - j;
            let (w, h) = st.period(s).unwrap();
            let mut c = Canvas::new(w as u32, h as u32);
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    let colour = if distinct.contains(&st.output(s, x, y)) { [0, 0, 0] } else { [200, 200, 200] };
                    c.set(x, y, colour);
                }
            }
            plot::captioned(&c.image, &format!("MIP {j}"))
        })
        .collect();
    plot::beside(&images, 8, false)
}
