//! The cascade's encoding: the parameters in the manifest, the optional `control` and
//! `initial` images as sections, and their complete validation.

use super::engine::{Control, Engine, Initial, Stage};
use super::kernel::{Kernel, Shape};
use super::lattice::ImageField;
use super::maps::Map;
use super::render::{auto_range, Cascade};
use super::MODEL;
use crate::bundle::Bundle;
use crate::models::{input_image, parse_params, Inputs};
use crate::pixels::{decode_png, Rgba8Image};
use crate::{Error, Result};

pub use super::params::{DilationMapSpec, InitialSpec, Params, StageSpec};

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
    if p.exact_levels > MAX_EXACT_LEVELS {
        return Err(Error::param("exact_levels", format!("{}: at most {MAX_EXACT_LEVELS}", p.exact_levels)));
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

/// Decodes an optional image section of a bundle.
pub fn section_image(bundle: &crate::bundle::Bundle, section: &str, name: &str) -> Result<Option<Rgba8Image>> {
    match bundle.sections.iter().find(|s| s.name == section) {
        Some(s) => Ok(Some(decode_png(name, &s.data)?)),
        None => Ok(None),
    }
}

/// Makes an encoding from parameters and the optional `control` / `initial` images; a missing
/// `range` is estimated from a sample of the texture.
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    super::plan::plan_create(params, inputs)?;
    let mut p: Params = parse_params(params)?;
    let given = serde_json::to_value(&p).map_err(|e| Error::param("params", e.to_string()))?;
    let control = inputs.contains_key("control").then(|| input_image(inputs, "control")).transpose()?;
    let initial = inputs.contains_key("initial").then(|| input_image(inputs, "initial")).transpose()?;
    if p.range.is_none() {
        p.range = Some(auto_range(&build_engine(&p, control.as_ref(), initial.as_ref())?));
    }
    let complete = serde_json::to_value(&p).map_err(|e| Error::param("params", e.to_string()))?;
    let mut bundle = Bundle::created(MODEL, name, given, complete);
    if let Some(c) = control {
        bundle = bundle.with_section(CONTROL_SECTION, c.to_png());
    }
    if let Some(i) = initial {
        bundle = bundle.with_section(INITIAL_SECTION, i.to_png());
    }
    load(&Bundle::from_bytes(&bundle.to_bytes())?)?;
    Ok(bundle)
}

/// Validates an encoding completely and returns the texture.
pub fn load(bundle: &Bundle) -> Result<Cascade> {
    if bundle.manifest.model != MODEL {
        return Err(Error::bundle(format!("model `{}`, expected `{MODEL}`", bundle.manifest.model)));
    }
    if let Some(s) = bundle.sections.iter().find(|s| s.name != CONTROL_SECTION && s.name != INITIAL_SECTION) {
        return Err(Error::bundle(format!("unexpected section `{}`", s.name)));
    }
    super::plan::plan(bundle)?;
    let p: Params = parse_params(&bundle.manifest.full_params()?)?;
    let control = section_image(bundle, CONTROL_SECTION, "control")?;
    let initial = section_image(bundle, INITIAL_SECTION, "initial")?;
    Cascade::build(p, control.as_ref(), initial.as_ref())
}
