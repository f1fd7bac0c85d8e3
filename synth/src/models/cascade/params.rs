//! The cascade's parameters, as given to `create` and stored in the manifest (`range`, when
//! not given, is derived: kept in the manifest's `derived`).
//!
//! ```json
//! {"seed": 7, "width": 100000, "height": 100000,
//!  "stages": [{"kernel": {"size": 5, "preset": "gauss"}, "map": {"kind": "logistic", "r": 3.7},
//!              "iterations": 5},
//!             {"upsample": 2, "jitter": 0.1, "kernel": {"size": 3, "weights": [0,1,0,1,4,1,0,1,0]},
//!              "map": {"kind": "sine", "r": 0.95}, "dilation": 1.5, "aspect": 3, "rotation": 20}],
//!  "palette": "earth", "range": [0.1, 0.9],
//!  "dilation_map": {"max": 3, "cell": 64},          // needs input/section `control`
//!  "initial": {"cell": 8, "strength": 0.7, "repeat": false},  // needs input/section `initial`
//!  "exact_levels": 0, "stage_budget": 1}
//! ```
//! Stages run coarse to fine; each after the first is `upsample` (1, 2, 4 or 8) times finer.

use super::kernel::KernelSpec;
use super::maps::MapSpec;
use super::palette::PaletteSpec;
use serde::{Deserialize, Serialize};

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
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
    /// A stored manifest without it means 2; `create` writes [`EXACT_LEVELS`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub exact_levels: Option<u32>,
    /// Level 1 (above `exact_levels`) is predicted by the finest stage whose window for a tile
    /// costs at most this many level-0 tiles (kernel taps and map × iterations × points), else
    /// by the cheapest stage that can predict it; a level the final stage predicts is exact. Without it (a stored manifest) every prefiltered level takes the finest stage at
    /// up to 4 × 4 samples a pixel, whatever that costs; `create` writes [`STAGE_BUDGET`].
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub stage_budget: Option<f64>,
}

/// What `create` writes for new textures: level 1 within about two level-0 tiles of work
/// where a coarser stage predicts it; levels the final stage predicts exact.
pub const EXACT_LEVELS: u32 = 0;
pub const STAGE_BUDGET: f64 = 2.5;

impl Params {
    /// Levels 1..=exact_levels are exact.
    pub fn exact_levels(&self) -> u32 {
        self.exact_levels.unwrap_or(2)
    }

    /// The parameters as stored: every default that depends on when the encoding was made
    /// filled in, so a later change of default never changes a stored texture.
    pub fn filled(mut self) -> Params {
        self.exact_levels = Some(self.exact_levels.unwrap_or(EXACT_LEVELS));
        self.stage_budget = Some(self.stage_budget.unwrap_or(STAGE_BUDGET));
        self
    }
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct StageSpec {
    #[serde(default)]
    pub kernel: KernelSpec,
    #[serde(default)]
    pub map: MapSpec,
    #[serde(default = "default_iterations")]
    pub iterations: u32,
    /// Scale of the kernel (≥ 1, real): features grow by this factor.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub dilation: f64,
    /// Extra stretch of the kernel's x axis (≥ 1): features elongate along it.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub aspect: f64,
    /// Rotation of the (stretched) kernel, degrees anticlockwise.
    #[serde(default, skip_serializing_if = "is_zero")]
    pub rotation: f64,
    /// Factor from the previous stage's lattice; not allowed on the first stage.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub upsample: Option<u32>,
    #[serde(default)]
    pub jitter: f64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct DilationMapSpec {
    /// Dilation where the control map is white (black is 1), real.
    pub max: f64,
    /// Pixels per control-map texel; the map repeats over the plane.
    pub cell: u64,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
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
fn one() -> f64 {
    1.0
}
fn is_one(v: &f64) -> bool {
    *v == 1.0
}
fn is_zero(v: &f64) -> bool {
    *v == 0.0
}
