//! The conformance suite: the invariants every texture model promises, checked on every demo
//! of every model in `models::REGISTRY` with no per-model code, so a model added later is
//! covered as soon as it is registered. It prints one row per demo and one column per
//! invariant (pass/fail and the figure behind it), then the mip PSNR of every level, and
//! fails when any cell fails.
//!
//! `cargo test -p vtex-synth --test conformance`; `CONFORMANCE_ONLY=<text>` keeps the demos
//! whose `model/name` contains the text; `CONFORMANCE_LEVELS=<file>` also writes the per-level
//! table there (`docs/mip-levels.md` holds it for every demo).

use std::collections::BTreeMap;
use std::panic::{catch_unwind, AssertUnwindSafe};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex};
use std::thread;

use serde_json::{json, Value};
use vtex_synth::bundle::Bundle;
use vtex_synth::mip::{downsample_n, mean_rgba, psnr};
use vtex_synth::models::{self, Inputs, Limits, MipGuarantee, Model};
use vtex_synth::texture::{level_count, level_size, render_image, MAX_RENDER_WORKING_BYTES};
use vtex_synth::{samples, Animation, Domain, Error, Region, Rgba8Image, Stop, Texture};

#[path = "support/counting_alloc.rs"]
mod counting;
#[path = "../../wasm/src/probe.rs"]
mod probe;

/// Expected BLAKE3 of each demo's probe: `<hex>  <model>/<name>` a line.
const PINNED: &str = include_str!("conformance.pinned");

/// One demo under test.
struct Demo {
    model: &'static dyn Model,
    bundle: Bundle,
    tex: Arc<dyn Texture>,
}

impl Demo {
    fn label(&self) -> String {
        format!("{}/{}", self.model.id(), self.bundle.manifest.name)
    }

    fn levels(&self) -> u32 {
        level_count(self.tex.width(), self.tex.height())
    }

    fn level_size(&self, level: u32) -> (u64, u64) {
        level_size(self.tex.width(), self.tex.height(), level)
    }

    /// A later frame for animated textures, else only frame 0.
    fn frames(&self) -> Vec<u32> {
        if self.tex.animation().is_some() {
            vec![0, 37]
        } else {
            vec![0]
        }
    }

    fn render(&self, region: Region) -> Result<Rgba8Image, String> {
        render_image(&*self.tex, &region).map_err(|e| format!("{region:?}: {e}"))
    }
}

/// What one cell found: the figure shown, and whether the invariant holds.
type Outcome = Result<String, String>;

/// The answers each level is scored as: the served level, then the trivial answers every mip
/// gate must tell from it — a flat mean colour, point sampling, the finer level copied (the
/// texture not zoomed out) and the coarser level copied up (pixel doubling).
const ANSWERS: [&str; 5] = ["served", "flat", "point", "finer copy", "coarser copy"];

/// One answer against the exact box chain of one level's window.
#[derive(Clone, Copy)]
struct Score {
    psnr: f64,
    /// σ of the answer over σ of the exact chain (RGB, over the window).
    sigma_ratio: f64,
    /// Largest |mean difference| of a channel, 0–255.
    mean_error: f64,
}

/// One level's scores, in [`ANSWERS`] order (`None`: the answer does not exist at this level,
/// such as the coarser copy of the last level).
struct LevelScores {
    level: u32,
    pixels: u32,
    exact_sigma: f64,
    answers: [Option<Score>; 5],
}

impl LevelScores {
    /// Whether the window is large enough for its σ and mean to be judged.
    fn statistics(&self) -> bool {
        self.pixels >= STATISTIC_PIXELS
    }

    fn served(&self) -> Score {
        self.answers[0].expect("the served level is always scored")
    }
}

/// One invariant's check of a demo; the mip check also records its per-level figures.
type Check = fn(&Demo, &mut Vec<LevelScores>) -> Outcome;

/// The checks, in column order.
const COLUMNS: [(&str, Check); 12] = [
    ("tile = crop", |d, _| tile_equals_crop(d)),
    ("order/threads", |d, _| order_and_threads(d)),
    ("torus wrap", |d, _| torus_wrap(d)),
    ("mip vs box chain", mip_coherence),
    ("trivial answers", |d, levels| trivial_answers(d, levels)),
    ("coarsest mean", |d, _| coarsest_mean(d)),
    ("pinned", |d, _| pinned(d)),
    ("native ≡ wasm32", |d, _| wasm_probe(d)),
    ("bad params", |d, _| bad_params(d)),
    ("bad bundle", |d, _| bad_bundle(d)),
    ("plan", |d, _| plan(d)),
    ("working memory", |d, _| working_memory(d)),
];

// ---------------------------------------------------------------- 1. a tile is a crop

/// Tiles inside a 96 × 80 region at several levels and origins (near, negative, far in both
/// directions) and frames must equal its crops.
fn tile_equals_crop(d: &Demo) -> Outcome {
    let levels = d.levels();
    let mut chosen = vec![0, 1, 3, levels / 2, levels - 1];
    chosen.retain(|&l| l < levels);
    chosen.dedup();
    let mut tiles = 0;
    for &level in &chosen {
        let (lw, lh) = d.level_size(level);
        for (ox, oy) in [(lw as i64 / 3, lh as i64 / 2), (-37, -21), ((1 << 33) + 11, -(1 << 34) - 5)] {
            for frame in d.frames() {
                let big = d.render(Region::new(level, ox, oy, 96, 80).at_frame(frame))?;
                for (dx, dy, w, h) in [(0, 0, 64, 64), (33, 17, 63, 63), (95, 79, 1, 1), (5, 50, 91, 30)] {
                    let tile = d.render(Region::new(level, ox + dx as i64, oy + dy as i64, w, h).at_frame(frame))?;
                    if tile != big.crop(dx, dy, w, h) {
                        return Err(format!("L{level} frame {frame}: tile ({dx},{dy}) {w}×{h} of ({ox},{oy}) ≠ crop"));
                    }
                    tiles += 1;
                }
            }
        }
    }
    Ok(format!("{tiles} tiles, levels {chosen:?}"))
}

// ---------------------------------------------------------------- 2. order and threads

/// The same tiles rendered in order, in reverse, on 2 and 4 threads (each taking every
/// k-th tile backwards) and from a fresh load of the bundle's bytes: identical bytes.
fn order_and_threads(d: &Demo) -> Outcome {
    let levels = d.levels();
    let frame = *d.frames().last().unwrap();
    let tiles: Vec<Region> = (0..12i64)
        .map(|i| {
            let level = (i as u32 % 3).min(levels - 1);
            Region::new(level, (i % 4) * 64 - 100, (i / 4) * 64 + (1 << 20), 64, 64).at_frame(frame)
        })
        .collect();
    let render_all = |tex: &dyn Texture, order: &[usize]| -> Result<Vec<(usize, Vec<u8>)>, String> {
        order.iter().map(|&i| Ok((i, render_image(tex, &tiles[i]).map_err(|e| e.to_string())?.data))).collect()
    };
    let forward: Vec<usize> = (0..tiles.len()).collect();
    let mut serial = render_all(&*d.tex, &forward)?;
    serial.sort();
    let mut runs = 1;
    let mut compare = |mut got: Vec<(usize, Vec<u8>)>, what: &str| -> Result<(), String> {
        got.sort();
        runs += 1;
        match got.iter().zip(&serial).find(|(a, b)| a != b) {
            Some(((i, _), _)) => Err(format!("{what}: tile {:?} differs", tiles[*i])),
            None => Ok(()),
        }
    };
    let backward: Vec<usize> = (0..tiles.len()).rev().collect();
    compare(render_all(&*d.tex, &backward)?, "reverse order")?;
    for threads in [2, 4] {
        let got = thread::scope(|s| {
            let workers: Vec<_> = (0..threads)
                .map(|k| {
                    let mine: Vec<usize> = (k..tiles.len()).step_by(threads).rev().collect();
                    let tex = Arc::clone(&d.tex);
                    let render_all = &render_all;
                    s.spawn(move || render_all(&*tex, &mine))
                })
                .collect();
            workers.into_iter().map(|w| w.join().expect("worker panicked")).collect::<Result<Vec<_>, _>>()
        })?;
        compare(got.into_iter().flatten().collect(), &format!("{threads} threads"))?;
    }
    let fresh = models::load(&Bundle::from_bytes(&d.bundle.to_bytes()).map_err(|e| e.to_string())?)
        .map_err(|e| e.to_string())?;
    let shuffled: Vec<usize> = (0..tiles.len()).map(|i| (i * 5 + 3) % tiles.len()).collect();
    compare(render_all(&*fresh, &shuffled)?, "fresh load, shuffled")?;
    Ok(format!("{} tiles × {runs} runs", tiles.len()))
}

// ---------------------------------------------------------------- 3. torus wrap

/// A torus texture repeats with its level size, and a region across its edge is the crop of
/// a larger region spanning it.
fn torus_wrap(d: &Demo) -> Outcome {
    if d.tex.domain() != Domain::Torus {
        return Ok("plane: n/a".into());
    }
    let levels = d.levels();
    let mut chosen = vec![0, 1, levels / 2];
    chosen.retain(|&l| l < levels);
    chosen.dedup();
    for &level in &chosen {
        let (lw, lh) = d.level_size(level);
        let (lw, lh) = (lw as i64, lh as i64);
        for frame in d.frames() {
            let at = |x: i64, y: i64, w: u32, h: u32| d.render(Region::new(level, x, y, w, h).at_frame(frame));
            let edge = at(-37, -21, 90, 60)?;
            for (x, y) in [(lw - 37, lh - 21), (3 * lw - 37, -lh - 21), (-5 * lw - 37, 7 * lh - 21)] {
                if at(x, y, 90, 60)? != edge {
                    return Err(format!("L{level} frame {frame}: ({x}, {y}) ≠ (−37, −21) one period away"));
                }
            }
            if at(lw - 100, lh - 80, 200, 160)?.crop(63, 59, 90, 60) != edge {
                return Err(format!("L{level} frame {frame}: the region across the edge ≠ crop of a larger one"));
            }
        }
    }
    Ok(format!("levels {chosen:?}"))
}

// ---------------------------------------------------------------- 4. mip coherence

/// Every level L ≥ 1 against [`MIP_SPAN`] exact 2×2 box downsamples of a region of level
/// L − [`MIP_SPAN`] (fewer near level 0): the served level must pass every gate of the model's
/// [`MipGuarantee`](vtex_synth::models::MipGuarantee) — PSNR floor, σ and mean — at every level.
/// A chain of several levels is used because one level of point sampling (every other pixel)
/// aliases too little to fall below a floor the served levels keep, while over three levels
/// its error compounds. The trivial answers are scored on the same windows for
/// [`trivial_answers`].
fn mip_coherence(d: &Demo, out: &mut Vec<LevelScores>) -> Outcome {
    for level in 1..d.levels() {
        out.push(score_level(d, level, MIP_SPAN.min(level))?);
    }
    let g = d.model.mip_guarantee();
    let worst = out.iter().min_by(|a, b| a.served().psnr.total_cmp(&b.served().psnr)).expect("a texture has level 1");
    let failing: Vec<String> = out
        .iter()
        .filter_map(|l| {
            let gates = failed_gates(&l.served(), l, &g);
            (!gates.is_empty()).then(|| format!("L{} {}", l.level, gates.join("+")))
        })
        .collect();
    let text = format!("min {} (L{}) ≥ {}", db(worst.served().psnr), worst.level, g.min_psnr_db);
    if failing.is_empty() {
        Ok(text)
    } else {
        Err(format!("{text}; fails at {}", failing.join(", ")))
    }
}

/// Levels over which the served level is compared with the box chain.
const MIP_SPAN: u32 = 3;

/// The gates of `g` that `s` fails. σ and the mean are judged only on windows of
/// [`STATISTIC_PIXELS`] and more, and σ only where the exact chain has [`VISIBLE_SIGMA`]: a few
/// pixels at a coarse level, or a window the exact chain leaves almost flat, say nothing of
/// contrast.
fn failed_gates(s: &Score, l: &LevelScores, g: &MipGuarantee) -> Vec<&'static str> {
    let mut failed = Vec::new();
    if s.psnr < g.min_psnr_db {
        failed.push("psnr");
    }
    if l.statistics() && l.exact_sigma >= VISIBLE_SIGMA && (s.sigma_ratio - 1.0).abs() > g.max_sigma_error {
        failed.push("σ");
    }
    if l.statistics() && s.mean_error > g.max_mean_error {
        failed.push("mean");
    }
    failed
}

/// Pixels a level's window needs before its σ and mean are judged.
const STATISTIC_PIXELS: u32 = 64;

/// σ (grey levels) of the exact chain below which a window counts as flat.
const VISIBLE_SIGMA: f64 = 4.0;

/// Every level must score at least as well as a flat colour and as point sampling (RMS error
/// within one grey level of theirs) where the window has visible contrast, and the gates must
/// reject a flat colour and point sampling at some level (gates they pass everywhere are not
/// gates) — unless the model's guarantee says it cannot, when the cell names where it does
/// not. The cell counts, for each trivial answer, the levels where the gates reject it; the
/// per-level table shows where they do not (near level 0, one or two levels of point sampling
/// stay close to the box chain).
fn trivial_answers(d: &Demo, levels: &[LevelScores]) -> Outcome {
    if levels.is_empty() {
        return Err("no mip scores (the mip column failed)".into());
    }
    let g = d.model.mip_guarantee();
    let rmse = |psnr: f64| 255.0 * 10f64.powf(-psnr / 20.0);
    let mut problems = Vec::new();
    let mut rejected = [0usize; 5];
    let mut scored = [0usize; 5];
    for l in levels.iter() {
        let served = l.served();
        for (i, answer) in l.answers.iter().enumerate().skip(1) {
            let Some(a) = answer else { continue };
            scored[i] += 1;
            if !failed_gates(a, l, &g).is_empty() {
                rejected[i] += 1;
            }
        }
        if l.statistics() && l.exact_sigma >= VISIBLE_SIGMA {
            for i in [1, 2] {
                let a = l.answers[i].expect("flat and point answers exist at every level");
                if rmse(served.psnr) > rmse(a.psnr) + 1.0 {
                    problems.push(format!("L{} served {} < {} {}", l.level, db(served.psnr), ANSWERS[i], db(a.psnr)));
                }
            }
        }
    }
    for i in [1, 2] {
        if rejected[i] == 0 {
            problems.push(format!("the gates pass {} at every level", ANSWERS[i]));
        }
    }
    let text = (1..ANSWERS.len()).map(|i| format!("{} {}/{}", ANSWERS[i], rejected[i], scored[i])).collect::<Vec<_>>();
    let text = format!("rejected: {}", text.join(", "));
    match (problems.is_empty(), g.beats_trivial_answers) {
        (true, _) => Ok(text),
        (false, true) => Err(format!("{text}; {}", problems.join("; "))),
        (false, false) => Ok(format!("{text}; not promised: {}", problems.join("; "))),
    }
}

/// Scores the served level `level` and the trivial answers against `k` exact 2×2 box
/// downsamples of a region of level L−k: up to 32 × 32 at level L, inside the level so no box
/// straddles an odd edge; a side shorter than 2^k at L−k is taken whole.
fn score_level(d: &Demo, level: u32, k: u32) -> Result<LevelScores, String> {
    let (pw, ph) = d.level_size(level - k);
    let (lw, lh) = d.level_size(level);
    let side = |prev: u64| {
        let w = ((prev >> k).min(32) as u32).max(1);
        (w, ((w as u64) << k).min(prev) as u32)
    };
    let ((w, w2), (h, h2)) = (side(pw), side(ph));
    let (x, y) = (((lw - w as u64) / 3) as i64, ((lh - h as u64) / 2) as i64);
    let prev = d.render(Region::new(level - k, x << k, y << k, w2, h2))?;
    let exact = downsample_n(&prev, k);
    let served = d.render(Region::new(level, x, y, w, h))?;
    let mean = mean_rgba(&exact).map(|c| c.round() as u8);
    let mut flat = Rgba8Image::new(w, h);
    let mut point = Rgba8Image::new(w, h);
    for j in 0..h {
        for i in 0..w {
            flat.set_pixel(i, j, mean);
            point.set_pixel(i, j, prev.pixel((i << k).min(w2 - 1), (j << k).min(h2 - 1)));
        }
    }
    let finer = d.render(Region::new(level - 1, x, y, w, h))?;
    let coarser = if level + 1 < d.levels() {
        let up = d.render(Region::new(level + 1, x >> 1, y >> 1, w.div_ceil(2) + 1, h.div_ceil(2) + 1))?;
        let mut doubled = Rgba8Image::new(w, h);
        for j in 0..h {
            for i in 0..w {
                let (u, v) = (((x + i as i64) >> 1) - (x >> 1), ((y + j as i64) >> 1) - (y >> 1));
                doubled.set_pixel(i, j, up.pixel(u as u32, v as u32));
            }
        }
        Some(doubled)
    } else {
        None
    };
    let exact_sigma = sigma(&exact);
    let score = |img: &Rgba8Image| {
        let (a, b) = (mean_rgba(img), mean_rgba(&exact));
        Score {
            psnr: psnr(img, &exact),
            sigma_ratio: if exact_sigma > 0.0 { sigma(img) / exact_sigma } else { 1.0 + sigma(img) },
            mean_error: (0..3).map(|c| (a[c] - b[c]).abs()).fold(0.0, f64::max),
        }
    };
    Ok(LevelScores {
        level,
        pixels: w * h,
        exact_sigma,
        answers: [
            Some(score(&served)),
            Some(score(&flat)),
            Some(score(&point)),
            Some(score(&finer)),
            coarser.as_ref().map(score),
        ],
    })
}

/// Standard deviation over the RGB channels (each about its own mean), 0–255.
fn sigma(img: &Rgba8Image) -> f64 {
    let mean = mean_rgba(img);
    let n = (img.width as f64 * img.height as f64).max(1.0);
    let var: f64 =
        img.data.chunks_exact(4).map(|p| (0..3).map(|c| (p[c] as f64 - mean[c]).powi(2)).sum::<f64>()).sum::<f64>()
            / (3.0 * n);
    var.sqrt()
}

fn db(v: f64) -> String {
    if v.is_infinite() {
        "exact".into()
    } else {
        format!("{v:.1} dB")
    }
}

// ---------------------------------------------------------------- 4b. coarsest level's mean

/// Up to this many pixels a whole level-0 render gives the true mean exactly.
const EXACT_MEAN_PIXELS: u64 = 1 << 24;

/// The coarsest level's pixel against the texture's true mean colour. The true mean is the
/// mean of the whole level 0 when it has at most [`EXACT_MEAN_PIXELS`]; for larger textures
/// it is taken from the whole of the finest level with at most 2^22 pixels, which covers the
/// entire texture and is held to level 0 by the mip check above.
fn coarsest_mean(d: &Demo) -> Outcome {
    let bound = d.model.mip_guarantee().max_mean_error;
    let (w, h) = (d.tex.width(), d.tex.height());
    let reference = if w * h <= EXACT_MEAN_PIXELS {
        0
    } else {
        (0..d.levels()).find(|&l| d.level_size(l).0 * d.level_size(l).1 <= 1 << 22).expect("the last level is 1×1")
    };
    let (rw, rh) = d.level_size(reference);
    let mean = mean_rgba(&d.render(Region::new(reference, 0, 0, rw as u32, rh as u32))?);
    let top = d.render(Region::new(d.levels() - 1, 0, 0, 1, 1))?.pixel(0, 0);
    let err = (0..3).map(|c| (top[c] as f64 - mean[c]).abs()).fold(0.0, f64::max);
    let text = format!("Δ {err:.2} ≤ {bound} (mean of L{reference})");
    if err <= bound {
        Ok(text)
    } else {
        Err(text)
    }
}

// ---------------------------------------------------------------- 5. pinned determinism

/// BLAKE3 of the demo's probe hashes against `conformance.pinned`.
fn pinned(d: &Demo) -> Outcome {
    let digest = blake3::hash(probe::hashes(&*d.tex).join("\n").as_bytes()).to_hex().to_string();
    let label = d.label();
    let expected = PINNED.lines().filter_map(|l| l.split_once("  ")).find(|(_, name)| *name == label);
    match expected {
        Some((hex, _)) if hex == digest => Ok(digest[..12].to_string()),
        Some((hex, _)) => Err(format!("{} pinned, {} rendered", &hex[..12], &digest[..12])),
        None => Err(format!("not pinned; add to conformance.pinned: {digest}  {label}")),
    }
}

// ---------------------------------------------------------------- 6. native ≡ wasm32

/// The bytes are compared with the WebAssembly build by `tests/wasm/api.test.mjs`, over
/// the probe regions of every demo; here the probe is held to cover what the invariant needs.
fn wasm_probe(d: &Demo) -> Outcome {
    let regions = probe::regions(&*d.tex);
    let levels = d.levels();
    let renderable: Vec<&Region> = regions.iter().filter(|r| r.level < levels).collect();
    let has = |what: &str, ok: bool| if ok { Ok(()) } else { Err(format!("the probe lacks {what}")) };
    has("a level above 0", renderable.iter().any(|r| r.level > 0))?;
    has("the coarsest level", renderable.iter().any(|r| r.level == levels - 1))?;
    has("far coordinates", renderable.iter().any(|r| r.x.unsigned_abs().max(r.y.unsigned_abs()) > 1 << 32))?;
    has("negative coordinates", renderable.iter().any(|r| r.x < 0 && r.y < 0))?;
    has("a later frame", renderable.iter().any(|r| r.frame > 0))?;
    Ok(format!("{} regions → tests/wasm/api.test.mjs", regions.len()))
}

// ---------------------------------------------------------------- 7. bad parameters

/// The JSON types a schema accepts; empty when it accepts anything.
fn accepted_types(schema: &Value, root: &Value, out: &mut Vec<String>) {
    if let Some(r) = schema.get("$ref").and_then(Value::as_str) {
        let path = r.trim_start_matches('#');
        if let Some(target) = root.pointer(path) {
            accepted_types(target, root, out);
        }
    }
    match schema.get("type") {
        Some(Value::String(t)) => out.push(t.clone()),
        Some(Value::Array(ts)) => out.extend(ts.iter().filter_map(Value::as_str).map(String::from)),
        _ => {}
    }
    if let Some(values) = schema.get("enum").and_then(Value::as_array) {
        out.extend(values.iter().map(|v| json_type(v).to_string()));
    }
    if let Some(v) = schema.get("const") {
        out.push(json_type(v).to_string());
    }
    for key in ["anyOf", "oneOf", "allOf"] {
        for branch in schema.get(key).and_then(Value::as_array).into_iter().flatten() {
            accepted_types(branch, root, out);
        }
    }
}

fn json_type(v: &Value) -> &'static str {
    match v {
        Value::Null => "null",
        Value::Bool(_) => "boolean",
        Value::Number(n) if n.is_f64() => "number",
        Value::Number(_) => "integer",
        Value::String(_) => "string",
        Value::Array(_) => "array",
        Value::Object(_) => "object",
    }
}

/// A value of a JSON type `types` does not accept (`integer` accepts no fraction, `number`
/// accepts every number), or `None` when it accepts every type.
fn wrong_value(types: &[String]) -> Option<Value> {
    let takes = |t: &str| types.iter().any(|a| a == t);
    [
        (json!(true), takes("boolean")),
        (json!("conformance"), takes("string")),
        (json!(1.5), takes("number")),
        (json!([]), takes("array")),
        (json!({}), takes("object")),
        (Value::Null, takes("null")),
    ]
    .into_iter()
    .find(|(_, ok)| !ok)
    .map(|(v, _)| v)
}

/// Generic refusals derived from the model's parameter schema: a non-object, an unknown
/// top-level key, and a wrong-typed value for each top-level property, each an
/// `Error::Param` naming what is wrong. Required input images are given, so only the
/// parameters can be at fault.
fn bad_params(d: &Demo) -> Outcome {
    let info = d.model.describe();
    let schema = &info.params_schema;
    let image = samples::lichen(16, 1).to_png();
    let inputs: Inputs = info
        .inputs
        .iter()
        .filter(|i| i.required && i.name != "*")
        .map(|i| (i.name.to_string(), image.clone()))
        .collect();
    let refuse = |params: Value, names: &str| -> Result<(), String> {
        match catch_unwind(AssertUnwindSafe(|| d.model.create("conformance", &params, &inputs))) {
            Err(_) => Err(format!("{params} panicked")),
            Ok(Ok(_)) => Err(format!("{params} was accepted")),
            Ok(Err(Error::Param { name, reason }))
                if names.is_empty() || name.contains(names) || reason.contains(names) =>
            {
                Ok(())
            }
            Ok(Err(e)) => Err(format!("{params}: `{e}` does not name `{names}` as a parameter")),
        }
    };
    let mut checked = 0;
    for v in [json!("params"), json!(7), json!([1, 2]), Value::Null] {
        refuse(v, "")?;
        checked += 1;
    }
    refuse(json!({"conformance_unknown_key": 1}), "conformance_unknown_key")?;
    checked += 1;
    let properties = schema.get("properties").and_then(Value::as_object).ok_or("the schema has no properties")?;
    let mut open = Vec::new();
    for (name, property) in properties {
        let mut types = Vec::new();
        accepted_types(property, schema, &mut types);
        match (types.is_empty(), wrong_value(&types)) {
            (false, Some(v)) => {
                refuse(json!({ name.as_str(): v }), name)?;
                checked += 1;
            }
            _ => open.push(name.as_str()),
        }
    }
    let open = if open.is_empty() { String::new() } else { format!(" (any type: {})", open.join(", ")) };
    Ok(format!("{checked} refused{open}"))
}

// ---------------------------------------------------------------- 7b. bad bundles

/// Truncations of the bundle's bytes are refused by the container; each section cut to half
/// is refused by `load`; flipped bytes anywhere are refused or load into a texture that
/// renders. Nothing may panic.
fn bad_bundle(d: &Demo) -> Outcome {
    let bytes = d.bundle.to_bytes();
    let n = bytes.len();
    let guard = |what: String, f: &dyn Fn() -> Result<(), String>| {
        catch_unwind(AssertUnwindSafe(f)).unwrap_or_else(|_| Err(format!("{what}: panicked")))
    };
    let mut cuts: Vec<usize> = (0..32).chain((0..48).map(|k| k * n / 48)).chain([n - 1]).collect();
    cuts.sort();
    cuts.dedup();
    for &cut in &cuts {
        guard(format!("cut at {cut}"), &|| match Bundle::from_bytes(&bytes[..cut]) {
            Ok(_) => Err(format!("cut at {cut} of {n} bytes parsed")),
            Err(_) => Ok(()),
        })?;
    }
    for (i, section) in d.bundle.sections.iter().enumerate() {
        guard(format!("section `{}` halved", section.name), &|| {
            let mut b = d.bundle.clone();
            b.sections[i].data.truncate(section.data.len() / 2);
            match models::load(&b) {
                Ok(_) => Err(format!("section `{}` cut to half loaded", section.name)),
                Err(_) => Ok(()),
            }
        })?;
    }
    let flips = 64.min(n);
    let mut loaded = 0;
    for k in 0..flips {
        let at = k * n / flips;
        let ok = guard(format!("byte {at} flipped"), &|| {
            let mut b = bytes.clone();
            b[at] ^= 0x5a;
            if let Ok(t) = Bundle::from_bytes(&b).and_then(|b| models::load(&b)) {
                let top = level_count(t.width(), t.height()) - 1;
                for region in [Region::new(0, -5, -5, 24, 24), Region::new(top, 0, 0, 1, 1)] {
                    render_image(&*t, &region).map_err(|e| e.to_string())?;
                }
                return Err(String::new());
            }
            Ok(())
        });
        match ok {
            Ok(()) => {}
            Err(e) if e.is_empty() => loaded += 1,
            Err(e) => return Err(e),
        }
    }
    Ok(format!("{} cuts, {} sections, {flips} flips ({loaded} still load)", cuts.len(), d.bundle.sections.len()))
}

// ---------------------------------------------------------------- 8. the cost plan

#[global_allocator]
static COUNTING: counting::Counting = counting::Counting;

/// The plan read from the bundle alone: the loaded texture's shape, within the public
/// server's bounds, and a resident size that bounds the heap a fresh load holds after a tile
/// of every level (and frame) has filled its caches, without exceeding 4× that + 1 MiB.
fn plan(d: &Demo) -> Outcome {
    let plan = models::plan(&d.bundle).map_err(|e| e.to_string())?;
    let t = &d.tex;
    let shape = (plan.width, plan.height, plan.domain, plan.animation);
    if shape != (t.width(), t.height(), t.domain(), t.animation()) {
        return Err(format!("plan {shape:?} ≠ texture {:?}", (t.width(), t.height(), t.domain(), t.animation())));
    }
    Limits::SERVE.check(d.model.id(), &plan).map_err(|e| e.to_string())?;
    let before = counting::live();
    let tex = models::load(&d.bundle).map_err(|e| e.to_string())?;
    for level in 0..d.levels() {
        let (lw, lh) = d.level_size(level);
        for frame in d.frames() {
            let region = Region::new(level, lw as i64 / 2 - 32, lh as i64 / 2 - 32, 64, 64).at_frame(frame);
            render_image(&*tex, &region).map_err(|e| e.to_string())?;
        }
    }
    let held = (counting::live() - before).max(0) as u64;
    drop(tex);
    let resident = plan.cost.resident_bytes.value;
    let mib = |b: u64| b as f64 / (1 << 20) as f64;
    let text = format!("{:.2} MiB planned, {:.2} MiB held", mib(resident), mib(held));
    if resident < held || resident > 4 * held + (1 << 20) {
        Err(text)
    } else {
        Ok(text)
    }
}

/// The heap a render holds at its peak besides its output and what it leaves in the
/// texture's caches, on a fresh load, for regions from a tile to 2048² at level 0 and 1024²
/// at coarser levels (or the whole level, when smaller): within `MAX_RENDER_WORKING_BYTES`.
fn working_memory(d: &Demo) -> Outcome {
    let mut worst = (0, String::new());
    for (level, side) in [(0, 256u64), (0, 1024), (0, 2048), (2, 1024), (4, 1024), (6, 1024)] {
        if level >= d.levels() {
            continue;
        }
        let (lw, lh) = d.level_size(level);
        let (w, h) = (side.min(lw), side.min(lh));
        for frame in d.frames() {
            let region = Region::new(level, ((lw - w) / 2) as i64, ((lh - h) / 2) as i64, w as u32, h as u32);
            let tex = models::load(&d.bundle).map_err(|e| e.to_string())?;
            counting::reset_peak();
            let image = render_image(&*tex, &region.at_frame(frame)).map_err(|e| e.to_string())?;
            let held = (counting::peak() - counting::live()).max(0) as u64;
            drop(image);
            if held > worst.0 {
                worst = (held, format!("level {level}, {w}×{h}, frame {frame}"));
            }
        }
    }
    let text = format!("{:.2} MiB at most ({})", worst.0 as f64 / (1 << 20) as f64, worst.1);
    if worst.0 > MAX_RENDER_WORKING_BYTES {
        Err(text)
    } else {
        Ok(text)
    }
}

// ---------------------------------------------------------------- models broken on purpose

/// How a texture is broken on purpose, to show the mip gates reject it: every level above 0
/// served as one flat colour, with half its contrast about its mean (coarse levels that
/// collapse toward the mean), or point-sampled from the level below (mips without a filter).
#[derive(Clone, Copy, Debug)]
enum Breakage {
    Flat,
    HalfContrast,
    PointSampled,
}

struct Broken {
    inner: Arc<dyn Texture>,
    breakage: Breakage,
}

impl Texture for Broken {
    fn model(&self) -> &'static str {
        self.inner.model()
    }
    fn width(&self) -> u64 {
        self.inner.width()
    }
    fn height(&self) -> u64 {
        self.inner.height()
    }
    fn domain(&self) -> Domain {
        self.inner.domain()
    }
    fn animation(&self) -> Option<Animation> {
        self.inner.animation()
    }
    fn render(&self, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        if region.level == 0 {
            return self.inner.render(region, out, stop);
        }
        if let Breakage::PointSampled = self.breakage {
            let below = Region {
                level: region.level - 1,
                x: region.x * 2,
                y: region.y * 2,
                width: region.width * 2,
                height: region.height * 2,
                frame: region.frame,
            };
            let mut fine = vec![0u8; below.width as usize * below.height as usize * 4];
            self.inner.render(&below, &mut fine, stop);
            let row = below.width as usize * 4;
            for (j, out_row) in out.chunks_exact_mut(region.width as usize * 4).enumerate() {
                for (i, p) in out_row.chunks_exact_mut(4).enumerate() {
                    let at = 2 * j * row + 2 * i * 4;
                    p.copy_from_slice(&fine[at..at + 4]);
                }
            }
            return;
        }
        self.inner.render(region, out, stop);
        let top = level_count(self.width(), self.height()) - 1;
        let mut mean = [0u8; 4];
        self.inner.render(&Region::new(top, 0, 0, 1, 1).at_frame(region.frame), &mut mean, stop);
        for p in out.chunks_exact_mut(4) {
            for c in 0..3 {
                p[c] = match self.breakage {
                    Breakage::Flat => mean[c],
                    Breakage::HalfContrast => (p[c] as u16 + mean[c] as u16).div_ceil(2) as u8,
                    Breakage::PointSampled => unreachable!("served above"),
                };
            }
        }
    }
}

/// The first demo of each model, broken each way: its mip gates must reject every one its
/// σ tolerance can tell (half the contrast needs one under ½).
fn broken_on_purpose(demos: &[Demo]) -> Vec<(String, &'static str, String)> {
    let mut seen = Vec::new();
    let mut failed = Vec::new();
    for d in demos {
        if seen.contains(&d.model.id()) {
            continue;
        }
        seen.push(d.model.id());
        for breakage in [Breakage::Flat, Breakage::HalfContrast, Breakage::PointSampled] {
            let tolerance = d.model.mip_guarantee().max_sigma_error;
            if matches!(breakage, Breakage::HalfContrast) && tolerance >= 0.5 {
                println!("{} broken: {breakage:?}: not checked, the σ tolerance {tolerance} admits it", d.label());
                continue;
            }
            let broken = Demo {
                model: d.model,
                bundle: d.bundle.clone(),
                tex: Arc::new(Broken { inner: Arc::clone(&d.tex), breakage }),
            };
            let mut levels = Vec::new();
            let verdict = mip_coherence(&broken, &mut levels).and_then(|_| trivial_answers(&broken, &levels));
            let label = format!("{} broken: {breakage:?}", d.label());
            match verdict {
                Err(why) => println!("{label}: rejected ({})", why.chars().take(160).collect::<String>()),
                Ok(text) => {
                    println!("{label}: ACCEPTED ({text})");
                    failed.push((label, "broken on purpose", "the mip gates accept it".to_string()));
                }
            }
        }
    }
    failed
}

// ---------------------------------------------------------------- the table

/// Writes the per-level table to `path` (relative to the workspace root), after the prose that
/// comes before the table in the file already there.
fn write_levels(path: &str, table: &str) {
    let path = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join(path);
    let old = std::fs::read_to_string(&path).unwrap_or_default();
    let prose: String = old.lines().take_while(|l| !l.starts_with('|')).map(|l| format!("{l}\n")).collect();
    std::fs::write(&path, prose + table).unwrap_or_else(|e| panic!("{}: {e}", path.display()));
}

struct Row {
    label: String,
    cells: Vec<Outcome>,
    mip: Vec<LevelScores>,
}

fn run(d: &Demo) -> Row {
    let mut mip = Vec::new();
    let cells = COLUMNS
        .iter()
        .map(|(name, check)| {
            catch_unwind(AssertUnwindSafe(|| check(d, &mut mip)))
                .unwrap_or_else(|p| Err(format!("{name} panicked: {}", panic_text(&p))))
        })
        .collect();
    Row { label: d.label(), cells, mip }
}

fn panic_text(p: &Box<dyn std::any::Any + Send>) -> String {
    p.downcast_ref::<String>().cloned().or_else(|| p.downcast_ref::<&str>().map(|s| s.to_string())).unwrap_or_default()
}

fn cell_text(o: &Outcome) -> String {
    match o {
        Ok(t) => format!("pass: {t}"),
        Err(t) => format!("FAIL: {t}"),
    }
}

fn main() {
    let only = std::env::var("CONFORMANCE_ONLY").ok();
    let mut demos = Vec::new();
    for model in models::REGISTRY {
        for bundle in model.demos() {
            let tex = match model.load(&bundle, &vtex_synth::Resources::default()) {
                Ok(t) => t,
                Err(e) => {
                    eprintln!("{}/{}: the demo does not load: {e}", model.id(), bundle.manifest.name);
                    std::process::exit(1);
                }
            };
            let demo = Demo { model: *model, bundle, tex };
            if only.as_deref().is_none_or(|o| demo.label().contains(o)) {
                demos.push(demo);
            }
        }
    }
    let next = AtomicUsize::new(0);
    let rows: Mutex<BTreeMap<usize, Row>> = Mutex::new(BTreeMap::new());
    let workers = thread::available_parallelism().map_or(2, |n| n.get()).min(demos.len().max(1));
    thread::scope(|s| {
        for _ in 0..workers {
            s.spawn(|| loop {
                let i = next.fetch_add(1, Ordering::Relaxed);
                let Some(d) = demos.get(i) else { break };
                let row = run(d);
                rows.lock().unwrap().insert(i, row);
            });
        }
    });
    let rows: Vec<Row> = rows.into_inner().unwrap().into_values().collect();

    let mut header = vec!["demo (model/name)".to_string()];
    header.extend(COLUMNS.iter().map(|(n, _)| n.to_string()));
    let table: Vec<Vec<String>> =
        rows.iter().map(|r| std::iter::once(r.label.clone()).chain(r.cells.iter().map(cell_text)).collect()).collect();
    print!("{}", table_text(&header, &table));

    println!(
        "\nmip levels against the exact 2×2 box chain from level L−{MIP_SPAN}: PSNR, σ over the exact σ, |Δ mean|; \
         ✗ marks an answer the model's gates reject"
    );
    let mut header = vec!["demo (model/name)".to_string(), "L".to_string(), "exact σ".to_string()];
    header.extend(ANSWERS.iter().map(|a| a.to_string()));
    let table: Vec<Vec<String>> = rows
        .iter()
        .zip(&demos)
        .flat_map(|(r, d)| {
            let g = d.model.mip_guarantee();
            // Levels where every answer is exact (a flat region) say nothing.
            r.mip.iter().filter(|l| l.answers.iter().flatten().any(|a| a.psnr.is_finite())).map(move |l| {
                let mut line = vec![r.label.clone(), l.level.to_string(), format!("{:.1}", l.exact_sigma)];
                line.extend(l.answers.iter().map(|a| match a {
                    None => "n/a".to_string(),
                    Some(s) => {
                        let mark = if failed_gates(s, l, &g).is_empty() { "" } else { " ✗" };
                        format!("{} σ×{:.2} Δ{:.1}{mark}", short_db(s.psnr), s.sigma_ratio, s.mean_error)
                    }
                }));
                line
            })
        })
        .collect();
    let levels = table_text(&header, &table);
    print!("{levels}");
    if let Ok(path) = std::env::var("CONFORMANCE_LEVELS") {
        write_levels(&path, &levels);
    }

    println!("\nmodels broken on purpose, held to the same mip gates");
    let broken = broken_on_purpose(&demos);

    let failed: Vec<(String, &str, &String)> = rows
        .iter()
        .flat_map(|r| {
            r.cells
                .iter()
                .zip(COLUMNS)
                .filter_map(|(c, (name, _))| c.as_ref().err().map(|e| (r.label.clone(), name, e)))
        })
        .chain(broken.iter().map(|(label, column, why)| (label.clone(), *column, why)))
        .collect();
    println!(
        "\n{} demos of {} models, {} cells, {} failed",
        rows.len(),
        models::REGISTRY.len(),
        rows.len() * COLUMNS.len(),
        failed.len()
    );
    for (label, column, why) in &failed {
        println!("FAILED {label} · {column}: {why}");
    }
    if !failed.is_empty() {
        std::process::exit(1);
    }
}

fn short_db(v: f64) -> String {
    if v.is_infinite() {
        "∞".into()
    } else {
        format!("{v:.1}")
    }
}

/// A Markdown table, its columns padded to their widest cell.
fn table_text(header: &[String], rows: &[Vec<String>]) -> String {
    let width = |i: usize| {
        rows.iter().map(|r| r.get(i).map_or(0, |c| c.chars().count())).chain([header[i].chars().count()]).max().unwrap()
    };
    let widths: Vec<usize> = (0..header.len()).map(width).collect();
    let line = |cells: &[String]| {
        let padded: Vec<String> = (0..header.len())
            .map(|i| {
                let c = cells.get(i).map_or("", String::as_str);
                format!("{c}{}", " ".repeat(widths[i] - c.chars().count()))
            })
            .collect();
        format!("| {} |\n", padded.join(" | "))
    };
    let mut text = line(header);
    text += &format!("|{}|\n", widths.iter().map(|w| "-".repeat(w + 2)).collect::<Vec<_>>().join("|"));
    for r in rows {
        text += &line(r);
    }
    text
}
