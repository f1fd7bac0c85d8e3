//! The cascade's encoding: manifest parameters, input images and their validation.
//!
//! ```json
//! {"seed": 7, "width": 100000, "height": 100000,
//!  "stages": [{"kernel": {"size": 5, "preset": "gauss"}, "map": {"kind": "logistic", "r": 3.7},
//!              "iterations": 5},
//!             {"upsample": 2, "jitter": 0.1, "kernel": {"size": 3, "weights": [0,1,0,1,4,1,0,1,0]},
//!              "map": {"kind": "sine", "r": 0.95}}],
//!  "palette": "earth", "range": [0.1, 0.9],
//!  "dilation_map": {"max": 3, "cell": 64},          // needs input/section `control`
//!  "initial": {"cell": 8, "strength": 0.7, "repeat": false},  // needs input/section `initial`
//!  "exact_levels": 2}
//! ```
//! Stages run coarse to fine; each after the first is `upsample` (1, 2, 4 or 8) times finer.

use super::engine::{Control, Engine, Initial, Stage};
use super::kernel::{Kernel, KernelSpec};
use super::lattice::ImageField;
use super::maps::{Map, MapSpec};
use super::palette::PaletteSpec;
use crate::pixels::{decode_png, Rgba8Image};
use crate::{Error, Result};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

pub const MAX_STAGES: usize = 12;
/// More iterations than this is absurd: the transient patterns the paper uses are gone and
/// the dependency window keeps growing.
pub const MAX_ITERATIONS: u32 = 64;
/// Largest dependency margin of one stage, in its lattice units.
pub const MAX_MARGIN: usize = 512;
/// Largest dilation (base × control map maximum).
pub const MAX_DILATION: u32 = 16;
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

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct Params {
    pub seed: u64,
    /// Served extent in pixels; the texture is defined on the whole plane.
    #[serde(default = "default_extent")]
    pub width: u64,
    #[serde(default = "default_extent")]
    pub height: u64,
    pub stages: Vec<StageSpec>,
    #[serde(default)]
    pub palette: PaletteSpec,
    /// Values mapped to the palette's ends; computed by `create` from a sample when absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub range: Option<[f64; 2]>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub dilation_map: Option<DilationMapSpec>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub initial: Option<InitialSpec>,
    /// Mip levels 1..=exact_levels are the exact box downsample; coarser ones prefiltered.
    #[serde(default = "default_exact_levels")]
    pub exact_levels: u32,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    #[serde(default)]
    pub kernel: KernelSpec,
    #[serde(default)]
    pub map: MapSpec,
    #[serde(default = "default_iterations")]
    pub iterations: u32,
    #[serde(default = "one")]
    pub dilation: u32,
    /// Factor from the previous stage's lattice; not allowed on the first stage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upsample: Option<u32>,
    #[serde(default)]
    pub jitter: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct DilationMapSpec {
    /// Dilation where the control map is white (black is 1).
    pub max: u32,
    /// Pixels per control-map texel; the map repeats over the plane.
    pub cell: u64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct InitialSpec {
    /// Pixels per image texel.
    pub cell: u64,
    /// Weight of the image against the noise, in [0, 1].
    pub strength: f64,
    /// Repeat the image over the plane; otherwise noise surrounds it.
    #[serde(default)]
    pub repeat: bool,
}

fn default_extent() -> u64 {
    100_000
}
fn default_iterations() -> u32 {
    5
}
fn one() -> u32 {
    1
}
fn default_exact_levels() -> u32 {
    2
}

impl Params {
    pub fn from_json(v: &serde_json::Value) -> Result<Self> {
        serde_json::from_value(v.clone()).map_err(|e| Error::param("params", e.to_string()))
    }
}

/// Validates everything and builds the engine. `control` / `initial` are the decoded images.
pub fn build_engine(p: &Params, control: Option<&Rgba8Image>, initial: Option<&Rgba8Image>) -> Result<Engine> {
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
    let control = match (&p.dilation_map, control) {
        (None, None) => None,
        (Some(_), None) => return Err(Error::image("control", "missing; `dilation_map` needs a control image")),
        (None, Some(_)) => return Err(Error::image("control", "given but `dilation_map` is not set")),
        (Some(d), Some(img)) => {
            if !(1..=MAX_DILATION).contains(&d.max) {
                return Err(Error::param("dilation_map.max", format!("{}: must be 1..={MAX_DILATION}", d.max)));
            }
            check_cell("dilation_map.cell", d.cell)?;
            let side = 2..=MAX_CONTROL_SIDE;
            if !side.contains(&img.width) || !side.contains(&img.height) {
                return Err(Error::image(
                    "control",
                    format!(
                        "{}×{}: a control map is low resolution, each side 2..={MAX_CONTROL_SIDE}",
                        img.width, img.height
                    ),
                ));
            }
            Some(Control { field: ImageField::from_image(img, d.cell, true), max: d.max })
        }
    };
    let initial = match (&p.initial, initial) {
        (None, None) => None,
        (Some(_), None) => return Err(Error::image("initial", "missing; `initial` needs an initial image")),
        (None, Some(_)) => return Err(Error::image("initial", "given but `initial` is not set")),
        (Some(i), Some(img)) => {
            check_cell("initial.cell", i.cell)?;
            if !(i.strength.is_finite() && (0.0..=1.0).contains(&i.strength)) {
                return Err(Error::param("initial.strength", format!("{}: must be in [0, 1]", i.strength)));
            }
            Some(Initial { field: ImageField::from_image(img, i.cell, i.repeat), strength: i.strength as f32 })
        }
    };
    let mut stages = Vec::with_capacity(p.stages.len());
    for (s, sp) in p.stages.iter().enumerate() {
        let at = format!("stages[{s}]");
        if sp.iterations == 0 || sp.iterations > MAX_ITERATIONS {
            return Err(Error::param(
                format!("{at}.iterations"),
                format!("{}: must be 1..={MAX_ITERATIONS} (the paper uses about 5)", sp.iterations),
            ));
        }
        let max_d = sp.dilation * control.as_ref().map_or(1, |c| c.max);
        if sp.dilation == 0 || max_d > MAX_DILATION {
            return Err(Error::param(
                format!("{at}.dilation"),
                format!("{}: dilation (times the control map's max) must be 1..={MAX_DILATION}", sp.dilation),
            ));
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
        let margin = sp.iterations as usize * kernel.radius as usize * max_d as usize;
        if margin > MAX_MARGIN {
            return Err(Error::param(
                &at,
                format!("iterations × kernel radius × dilation = {margin}; at most {MAX_MARGIN}"),
            ));
        }
        stages.push(Stage {
            kernel,
            map: Map::build(&sp.map, &format!("{at}.map"))?,
            iterations: sp.iterations,
            dilation: sp.dilation,
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
    Ok(Engine { seed: p.seed, stages, control, initial })
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
