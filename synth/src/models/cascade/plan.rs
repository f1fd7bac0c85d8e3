//! The cascade's cost model: from the parameters and the image headers, what a loaded cascade
//! holds and what its dearest tile and its making cost, before anything is iterated. A
//! stage's window is its request grown by its margin on each side, shrinking by one step
//! margin per iteration, and a finer stage's window asks the coarser one for its upsampling
//! footprint: the work of a window is that recursion, counted exactly as `engine` runs it.
//! Constants are work units (≈ 1 ns of one core) per item, calibrated by
//! `examples/cost_calibration.rs`.

use super::encoding::{check, Params, CONTROL_SECTION, INITIAL_SECTION};
use super::engine::Stage;
use super::{palette, MODEL};
use crate::bundle::Bundle;
use crate::models::{cost, parse_params, Cost, Inputs, Measure, Plan};
use crate::pixels::png_dimensions;
use crate::texture::{level_count, level_size};
use crate::{Domain, Error, Result};

/// A lattice point's hashed noise; upsampling a point from the coarser stage.
const NOISE: f64 = 6.0;
const UPSAMPLE: f64 = 4.0;
/// One kernel tap of one iteration at one point: a multiply-add over a row, or with a
/// dilation map one per point (two kernels blended at most).
const TAP: f64 = 1.2;
const TAP_DILATED: f64 = 2.0;
/// The nonlinear map at one point of one iteration.
const MAP: f64 = 4.0;
/// Reading one point's value through the palette.
const COLOUR: f64 = 3.0;
/// Box-filtering one level-0 pixel into an exact level.
const DOWNSAMPLE: f64 = 1.5;
/// One sample of a prefiltered pixel: a bilinear read and a table look-up; one guide sample.
const SAMPLE: f64 = 6.0;
const GUIDE_SAMPLE: f64 = 6.0;
/// Decoding a control or initial image, per pixel; encoding it in `create`.
const IMAGE_PIXEL: f64 = 30.0;
const ENCODE_PIXEL: f64 = 60.0;
/// Fixed work of a load: parsing, kernels, maps, the palette table.
const LOAD: f64 = 50_000.0;

/// As in `prefilter`: calibration windows and their side, the bins of its tables.
const CALIBRATION_WINDOWS: f64 = 256.0;
const CALIBRATION_WINDOW: u64 = 32;
const BINS: f64 = 64.0;
/// As in `prefilter`: levels past the base carried up from the last measured level, their
/// spots and the spots' side at the base.
const CARRIED: u32 = 3;
const CARRY_SPOTS: f64 = 128.0;
const CARRIED_SIDE: u64 = 16;
/// As in `residual`: quantiles of a band's table, bands of a level.
const QUANTILES: f64 = 64.0;
const RESIDUAL_BANDS: f64 = 4.0;
/// As in `render::auto_range`: windows of the final stage and their side.
const RANGE_WINDOWS: f64 = 8.0;
const RANGE_WINDOW: u64 = 48;
/// As in `render`: level-0 pixels a side of one chunk of an exact level.
const CHUNK: u64 = 1024;
/// A tile's side.
const TILE: u64 = 256;

/// What loading `bundle` gives and costs, from its manifest and the images' headers.
pub fn plan(bundle: &Bundle) -> Result<Plan> {
    if bundle.manifest.model != MODEL {
        return Err(Error::bundle(format!("model `{}`, expected `{MODEL}`", bundle.manifest.model)));
    }
    if let Some(s) = bundle.sections.iter().find(|s| s.name != CONTROL_SECTION && s.name != INITIAL_SECTION) {
        return Err(Error::bundle(format!("unexpected section `{}`", s.name)));
    }
    let p: Params = parse_params(&bundle.manifest.full_params()?)?;
    let header = |section: &str, name: &str| {
        bundle.sections.iter().find(|s| s.name == section).map(|s| png_dimensions(name, &s.data)).transpose()
    };
    plan_params(&p, header(CONTROL_SECTION, "control")?, header(INITIAL_SECTION, "initial")?, false)
}

/// What `create` gives and costs, from the parameters and the input images' headers.
pub fn plan_create(params: &serde_json::Value, inputs: &Inputs) -> Result<Plan> {
    if let Some(other) = inputs.keys().find(|k| !["control", "initial"].contains(&k.as_str())) {
        return Err(Error::image(other.as_str(), "not an input of `cascade` (it takes `control` and `initial`)"));
    }
    let p: Params = parse_params(params)?;
    let header = |name: &str| inputs.get(name).map(|b| png_dimensions(name, b)).transpose();
    plan_params(&p, header("control")?, header("initial")?, true)
}

/// Work of the windows of one texture's stages.
struct Windows<'a> {
    stages: &'a [Stage],
    dilated: bool,
    initial: bool,
}

impl Windows<'_> {
    fn step_margin(&self, s: usize) -> u64 {
        self.stages[s].kernels.iter().map(|k| k.reach).max().unwrap_or(0) as u64
    }

    /// Work of stage `s` on a `w × h` window, as `Engine::field` computes it: initial values
    /// (noise, or the coarser stage's footprint upsampled, plus jitter), then each iteration
    /// over a window one step margin smaller on each side.
    fn field(&self, s: usize, w: u64, h: u64) -> f64 {
        let st = &self.stages[s];
        let e = self.step_margin(s);
        let m = st.iterations as u64 * e;
        let (iw, ih) = (w + 2 * m, h + 2 * m);
        let points = (iw * ih) as f64;
        let init = if s == 0 {
            NOISE * points * if self.initial { 2.0 } else { 1.0 }
        } else {
            let fp = |n: u64| footprint(n, st.up);
            let jitter = if st.jitter > 0.0 { NOISE * points } else { 0.0 };
            self.field(s - 1, fp(iw), fp(ih)) + UPSAMPLE * points + jitter
        };
        // Under a dilation map a point blends two kernels of the ladder: count the largest twice.
        let per_point = if self.dilated {
            2.0 * st.kernels.iter().map(|k| k.taps.len()).max().unwrap_or(0) as f64 * TAP_DILATED + MAP
        } else {
            st.kernel().taps.len() as f64 * TAP + MAP
        };
        let iterations: f64 =
            (1..=st.iterations as u64).map(|i| ((iw - 2 * i * e) * (ih - 2 * i * e)) as f64 * per_point).sum();
        init + iterations
    }
}

/// Points of the coarser lattice under `n` finer points at its worst alignment
/// (`lattice::upsample_footprint`).
fn footprint(n: u64, up: u32) -> u64 {
    (((1u64 << up) - 1 + n - 1) >> up) + 2
}

fn plan_params(p: &Params, control: Option<(u32, u32)>, initial: Option<(u32, u32)>, create: bool) -> Result<Plan> {
    let stages = check(p, control, initial)?;
    palette::build(&p.palette)?;
    let win = Windows { stages: &stages, dilated: control.is_some(), initial: initial.is_some() };
    let last = stages.len() - 1;
    let px = |size: Option<(u32, u32)>| size.map_or(0.0, |(w, h)| w as f64 * h as f64);
    let images = px(control) + px(initial);
    let levels = level_count(p.width, p.height);

    // Level 0 and the exact levels: the final stage's window of each chunk, read through the
    // palette, box-filtered down to the level.
    let exact = |l: u32| -> f64 {
        let side = TILE << l;
        let chunk = side.min(CHUNK);
        let chunks = ((side / chunk) * (side / chunk)) as f64;
        let area = (side * side) as f64;
        chunks * win.field(last, chunk, chunk) + area * COLOUR + if l > 0 { area * DOWNSAMPLE } else { 0.0 }
    };
    // The first prefiltered tile measures the conditional means: windows of the final stage
    // and of every coarser stage upsampled to their pixels.
    let calibration = {
        let n = CALIBRATION_WINDOW;
        let coarse: f64 = (0..last)
            .map(|s| {
                let k = stages[s].shift;
                win.field(s, footprint(n, k), footprint(n, k)) + (n * n) as f64 * UPSAMPLE
            })
            .sum();
        let guide = if control.is_some() || initial.is_some() { (n * n) as f64 * GUIDE_SAMPLE } else { 0.0 };
        CALIBRATION_WINDOWS * (win.field(last, n, n) + (n * n) as f64 * (COLOUR + SAMPLE) + coarse + guide)
    };
    let cell = p.initial.as_ref().map(|i| i.cell).or(p.dilation_map.as_ref().map(|d| d.cell));
    // Coarser levels: the finest stage whose lattice is at most 4 × 4 points a pixel, its
    // window evaluated and sampled q² times a pixel; beyond the coarsest stage, a guide image
    // sampled n² times a pixel (n up to 64), or a flat colour.
    // Each pixel also sums its residual's terms, a hash a level.
    let predicted = |l: u32, side: u64| -> f64 {
        let pixels = (side * side) as f64;
        let residual = pixels * (levels - l) as f64 * NOISE;
        residual
            + match (0..=last).rev().find(|&s| stages[s].shift + 2 >= l) {
                Some(s) => {
                    let shift = stages[s].shift;
                    let q = 1u64 << l.saturating_sub(shift);
                    let span = (((side << l) + (1 << shift)) >> shift) + 3;
                    win.field(s, span, span) + pixels * (q * q) as f64 * SAMPLE
                }
                None => match cell {
                    Some(cell) => {
                        let per_texel = ((1u64 << l.min(40)) / cell).clamp(4, 64);
                        let (lw, lh) = level_size(p.width, p.height, l);
                        let budget = libm::sqrt((1u64 << 22) as f64 / (lw * lh).min(TILE * TILE) as f64) as u64;
                        let n = per_texel.min(budget.max(4)).next_power_of_two().min(1 << (l - 1));
                        pixels * (n * n) as f64 * GUIDE_SAMPLE
                    }
                    None => pixels,
                },
            }
    };
    // The calibration's residuals: predictions of the windows' blocks at the levels they
    // hold; beyond, on each spot the level below served over 4 × 4 pixels and the level's
    // prediction over 2 × 2, or past the base the prediction on the carried chain's spots,
    // whose 16·2^depth-pixel side at the last measured level is served once.
    let measured = CALIBRATION_WINDOW.trailing_zeros();
    let base = stages.iter().map(|s| s.shift + 2).max().unwrap_or(0).max(measured);
    let residuals: f64 = (p.exact_levels + 1..levels)
        .map(|l| {
            if l <= measured {
                CALIBRATION_WINDOWS * predicted(l, CALIBRATION_WINDOW >> l)
            } else if (1..=CARRIED).contains(&(l - base)) {
                let chain = if l == base + 1 { predicted(measured, CARRIED_SIDE << (base - measured)) } else { 0.0 };
                CARRY_SPOTS * (chain + predicted(l, CARRIED_SIDE >> (l - base)))
            } else {
                CALIBRATION_WINDOWS * (predicted(l - 1, 4) + predicted(l, 2))
            }
        })
        .sum();
    let prefiltered = |l: u32| predicted(l, TILE) + calibration + residuals;
    let (tile_work, worst) = (0..levels)
        .map(|l| (if l <= p.exact_levels { exact(l) } else { prefiltered(l) }, l))
        .fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
    let taps: Vec<String> = stages.iter().map(|s| s.kernel().taps.len().to_string()).collect();
    let iterations: Vec<String> = stages.iter().map(|s| s.iterations.to_string()).collect();
    let tile_why = format!(
        "{} stages × iterations [{}] × taps [{}] over margin-grown windows, level {worst} of a 256² tile",
        stages.len(),
        iterations.join(", "),
        taps.join(", ")
    );

    // Resident: the palette table, the calibration's tables, kernels and maps, the images as
    // one byte a texel.
    let taps_total: f64 = stages.iter().flat_map(|s| &s.kernels).map(|k| k.taps.len() as f64).sum();
    let resident = 8.0 * palette::LUT_SIZE as f64
        + (stages.len() as f64 + 1.0) * BINS * 12.0
        + levels as f64 * (RESIDUAL_BANDS * (QUANTILES * 12.0 + 4.0 + 24.0) + 64.0)
        + 32.0 * taps_total
        + 512.0 * stages.len() as f64
        + images
        + 4096.0;
    let resident_why = format!("palette, {} stages' kernels and tables, images of {images} texels", stages.len());

    // Making it: decoding the images, and estimating `range` when it is absent (windows of the
    // final stage); `create` also encodes the images and loads what it made.
    let range = RANGE_WINDOWS * win.field(last, RANGE_WINDOW, RANGE_WINDOW);
    let load = LOAD + IMAGE_PIXEL * images;
    let estimate = if p.range.is_none() { range } else { 0.0 };
    let build = if create { estimate + 2.0 * load + ENCODE_PIXEL * images } else { load + estimate };
    let build_why = format!(
        "{}images of {images} texels{}",
        if p.range.is_none() { "range estimated from 8 windows of 48² of the final stage, " } else { "" },
        if create { ", made and loaded" } else { "" }
    );
    Ok(Plan {
        width: p.width,
        height: p.height,
        domain: Domain::Plane,
        animation: None,
        cost: Cost {
            resident_bytes: Measure::new(cost::units(resident), resident_why),
            tile_work: Measure::new(cost::units(tile_work), tile_why),
            build_work: Measure::new(cost::units(build), build_why),
        },
    })
}
