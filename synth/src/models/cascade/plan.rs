//! The cascade's cost model: from the parameters and the image headers, what a loaded cascade
//! holds and what its dearest tile and its making cost, before anything is iterated. A
//! stage's window is its request grown by its margin on each side, shrinking by one step
//! margin per iteration, and a finer stage's window asks the coarser one for its upsampling
//! footprint: the work of a window is that recursion, counted exactly as `engine` runs it.
//! Constants are work units (≈ 1 ns of one core) per item, calibrated by
//! `examples/cost_calibration.rs`.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::engine::{Control, Engine, Initial, Stage};
use super::kernel::{Kernel, Shape};
use super::lattice::ImageField;
use super::maps::Map;
use super::params::Params;
use super::prefilter::predicting_stage;
use super::{palette, MODEL};
use crate::bundle::Bundle;
#[cfg(feature = "create")]
use crate::models::Inputs;
use crate::models::{cost, parse_params, Cost, Measure, Plan};
use crate::pixels::{png_dimensions, Rgba8Image};
use crate::texture::{level_count, level_size};
use crate::{Domain, Error, Result};

pub const MAX_STAGES: usize = 12;
/// More iterations than this is absurd: the transient patterns the paper uses are gone and
/// the dependency window keeps growing.
pub const MAX_ITERATIONS: u32 = 64;
/// Largest dependency margin of one stage, in its lattice units.
pub const MAX_MARGIN: usize = 512;
/// Largest dilation (a stage's dilation × aspect × the control map's maximum).
pub const MAX_DILATION: f64 = 16.0;
/// Coarsest stage spacing: 2^20 pixels.
pub const MAX_TOTAL_SHIFT: u32 = 20;
/// Control maps are low resolution by definition.
pub const MAX_CONTROL_SIDE: u32 = 256;
/// Largest served extent per side (the plane itself is unbounded).
pub const MAX_EXTENT: u64 = 1 << 40;
pub const MAX_CELL: u64 = 1 << 16;
/// Levels rendered exactly by brute force; at most this many.
pub const MAX_EXACT_LEVELS: u32 = 3;

pub const CONTROL_SECTION: &str = "control.png";
pub const INITIAL_SECTION: &str = "initial.png";

/// Validates everything and builds the engine. `control` / `initial` are the decoded images.
pub fn build_engine(p: &Params, control: Option<&Rgba8Image>, initial: Option<&Rgba8Image>) -> Result<Engine> {
    let size = |img: Option<&Rgba8Image>| img.map(|i| (i.width, i.height));
    let stages = check(p, size(control), size(initial))?;
    let control = p
        .dilation_map
        .as_ref()
        .zip(control)
        .map(|(d, img)| Control { field: ImageField::from_image(img, d.cell, true), max: d.max });
    let initial = p
        .initial
        .as_ref()
        .zip(initial)
        .map(|(i, img)| Initial { field: ImageField::from_image(img, i.cell, i.repeat), strength: i.strength as f32 });
    Ok(Engine { seed: p.seed, stages, control, initial })
}

/// Validates the parameters against the sizes of the `control` / `initial` images (read from
/// their headers, or decoded) and returns the stages: everything `build_engine` checks,
/// before any image is decoded.
pub fn check(p: &Params, control: Option<(u32, u32)>, initial: Option<(u32, u32)>) -> Result<Vec<Stage>> {
    for (name, v) in [("width", p.width), ("height", p.height)] {
        if !(1..=MAX_EXTENT).contains(&v) {
            return Err(Error::param(name, format!("{v}: must be 1..=2^40")));
        }
    }
    if p.stages.is_empty() || p.stages.len() > MAX_STAGES {
        return Err(Error::param("stages", format!("{} stages; 1 to {MAX_STAGES}", p.stages.len())));
    }
    if p.exact_levels() > MAX_EXACT_LEVELS {
        return Err(Error::param("exact_levels", format!("{}: at most {MAX_EXACT_LEVELS}", p.exact_levels())));
    }
    if let Some(b) = p.stage_budget {
        if !(b.is_finite() && b >= 0.0) {
            return Err(Error::param("stage_budget", format!("{b}: level-0 tiles, a number ≥ 0")));
        }
    }
    if let Some([lo, hi]) = p.range {
        if !(lo.is_finite() && hi.is_finite() && lo < hi) {
            return Err(Error::param("range", format!("[{lo}, {hi}]: needs finite lo < hi")));
        }
    }
    let control_max = match (&p.dilation_map, control) {
        (None, None) => 1.0,
        (Some(_), None) => return Err(Error::image("control", "missing; `dilation_map` needs a control image")),
        (None, Some(_)) => return Err(Error::image("control", "given but `dilation_map` is not set")),
        (Some(d), Some((w, h))) => {
            if !(d.max.is_finite() && (1.0..=MAX_DILATION).contains(&d.max)) {
                return Err(Error::param("dilation_map.max", format!("{}: must be in [1, {MAX_DILATION}]", d.max)));
            }
            check_cell("dilation_map.cell", d.cell)?;
            let side = 2..=MAX_CONTROL_SIDE;
            if !side.contains(&w) || !side.contains(&h) {
                return Err(Error::image(
                    "control",
                    format!("{w}×{h}: a control map is low resolution, each side 2..={MAX_CONTROL_SIDE}"),
                ));
            }
            d.max
        }
    };
    match (&p.initial, initial) {
        (None, None) => {}
        (Some(_), None) => return Err(Error::image("initial", "missing; `initial` needs an initial image")),
        (None, Some(_)) => return Err(Error::image("initial", "given but `initial` is not set")),
        (Some(i), Some(_)) => {
            check_cell("initial.cell", i.cell)?;
            if !(i.strength.is_finite() && (0.0..=1.0).contains(&i.strength)) {
                return Err(Error::param("initial.strength", format!("{}: must be in [0, 1]", i.strength)));
            }
        }
    }
    let mut stages = Vec::with_capacity(p.stages.len());
    for (s, sp) in p.stages.iter().enumerate() {
        let at = format!("stages[{s}]");
        if sp.iterations == 0 || sp.iterations > MAX_ITERATIONS {
            return Err(Error::param(
                format!("{at}.iterations"),
                format!("{}: must be 1..={MAX_ITERATIONS} (the paper uses about 5)", sp.iterations),
            ));
        }
        for (name, v) in [("dilation", sp.dilation), ("aspect", sp.aspect)] {
            if !(v.is_finite() && (1.0..=MAX_DILATION).contains(&v)) {
                return Err(Error::param(format!("{at}.{name}"), format!("{v}: must be in [1, {MAX_DILATION}]")));
            }
        }
        let max_d = sp.dilation * sp.aspect * control_max;
        if max_d > MAX_DILATION {
            return Err(Error::param(
                format!("{at}.dilation"),
                format!("dilation × aspect × the control map's max = {max_d}; at most {MAX_DILATION}"),
            ));
        }
        if !(sp.rotation.is_finite() && sp.rotation.abs() <= 360.0) {
            return Err(Error::param(format!("{at}.rotation"), format!("{}: degrees in [−360, 360]", sp.rotation)));
        }
        let up = match (s, sp.upsample) {
            (0, None) => 0,
            (0, Some(_)) => return Err(Error::param(format!("{at}.upsample"), "the first stage starts from noise")),
            (_, None) => 1,
            (_, Some(f @ (1 | 2 | 4 | 8))) => f.trailing_zeros(),
            (_, Some(f)) => return Err(Error::param(format!("{at}.upsample"), format!("{f}: must be 1, 2, 4 or 8"))),
        };
        if !(sp.jitter.is_finite() && (0.0..=1.0).contains(&sp.jitter)) {
            return Err(Error::param(format!("{at}.jitter"), format!("{}: must be in [0, 1]", sp.jitter)));
        }
        let kernel = Kernel::build(&sp.kernel, &format!("{at}.kernel"))?;
        let shape = Shape { sx: sp.dilation * sp.aspect, sy: sp.dilation, angle: sp.rotation.to_radians() };
        let (kernels, gains) = Stage::kernels(&kernel, shape, control_max, &format!("{at}.kernel"))?;
        let reach = kernels.iter().map(|k| k.reach).max().unwrap_or(0);
        let margin = sp.iterations as usize * reach as usize;
        if margin > MAX_MARGIN {
            return Err(Error::param(
                &at,
                format!("iterations × the dilated kernel's reach = {margin}; at most {MAX_MARGIN}"),
            ));
        }
        stages.push(Stage {
            kernels,
            gains,
            map: Map::build(&sp.map, &format!("{at}.map"))?,
            iterations: sp.iterations,
            shift: 0,
            up,
            jitter: sp.jitter as f32,
        });
    }
    let total: u32 = stages.iter().map(|s| s.up).sum();
    if total > MAX_TOTAL_SHIFT {
        return Err(Error::param(
            "stages",
            format!("the coarsest stage is 2^{total} pixels apart; at most 2^{MAX_TOTAL_SHIFT}"),
        ));
    }
    let mut shift = 0;
    for st in stages.iter_mut().rev() {
        st.shift = shift;
        shift += st.up;
    }
    Ok(stages)
}

fn check_cell(name: &str, cell: u64) -> Result<()> {
    if !(1..=MAX_CELL).contains(&cell) {
        return Err(Error::param(name, format!("{cell}: must be 1..={MAX_CELL} pixels per texel")));
    }
    Ok(())
}

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
    let p: Params = bundle.params()?;
    let header = |section: &str, name: &str| {
        bundle.sections.iter().find(|s| s.name == section).map(|s| png_dimensions(name, &s.data)).transpose()
    };
    plan_params(&p, header(CONTROL_SECTION, "control")?, header(INITIAL_SECTION, "initial")?, false)
}

/// What `create` gives and costs, from the parameters and the input images' headers.
#[cfg(feature = "create")]
pub fn plan_create(params: &serde_json::Value, inputs: &Inputs) -> Result<Plan> {
    if let Some(other) = inputs.keys().find(|k| !["control", "initial"].contains(&k.as_str())) {
        return Err(Error::image(other.as_str(), "not an input of `cascade` (it takes `control` and `initial`)"));
    }
    let p: Params = parse_params::<Params>(params)?.filled();
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
            + match predicting_stage(&stages, control.is_some(), p.stage_budget, l) {
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
    let is_exact = |l: u32| {
        l <= p.exact_levels()
            || p.stage_budget.is_some() && predicting_stage(&stages, control.is_some(), p.stage_budget, l) == Some(last)
    };
    let residuals: f64 = (p.exact_levels() + 1..levels)
        .map(|l| {
            if is_exact(l) {
                0.0
            } else if l <= measured {
                CALIBRATION_WINDOWS * predicted(l, CALIBRATION_WINDOW >> l)
            } else if l.checked_sub(base).is_some_and(|d| (1..=CARRIED).contains(&d)) {
                let chain = if l == base + 1 { predicted(measured, CARRIED_SIDE << (base - measured)) } else { 0.0 };
                CARRY_SPOTS * (chain + predicted(l, CARRIED_SIDE >> (l - base)))
            } else {
                CALIBRATION_WINDOWS * (predicted(l - 1, 4) + predicted(l, 2))
            }
        })
        .sum();
    let prefiltered = |l: u32| predicted(l, TILE) + calibration + residuals;
    let (tile_work, worst) = (0..levels)
        .map(|l| (if is_exact(l) { exact(l) } else { prefiltered(l) }, l))
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
