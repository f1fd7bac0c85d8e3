//! The parameters of an `lcm` encoding as `create` takes them: the layers with their event
//! tables, the background, order and colour, and where the base element comes from.

use super::packing::MaskCoding;
use super::table::Table;
use serde::{Deserialize, Serialize};

/// How the base element is stored.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Representation {
    /// Scaled copies in explicit form, like a mip chain (fast; what the paper counts).
    #[default]
    Explicit,
    /// The Haar transform of the element (§6).
    Haar,
}

/// Order of application of the layers (§2.2).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "snake_case")]
pub enum Order {
    /// Layer 0 (the largest elements) first.
    #[default]
    TopDown,
    /// The finest layer first, layer 0 last.
    BottomUp,
}

/// One layer as the manifest describes it.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct LayerParams {
    /// The paper's layer number n: resolution K + magnify − n.
    pub layer: u32,
    #[serde(default = "one")]
    pub weight: f64,
    /// LCM size in points, [width, height].
    pub lcm: [u32; 2],
    /// Use the LCM of this earlier entry of `layers` instead of one of its own (the paper's
    /// brick wall shares one 20 × 20 LCM between layers 2 and 3).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub share: Option<usize>,
    /// The event table the LCM was drawn from (needed by `create`, kept for the record).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub table: Option<Table>,
}

fn one() -> f64 {
    1.0
}
pub(super) fn one_tile() -> [u32; 2] {
    [1, 1]
}

/// A base element made in code, by name.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Builtin {
    /// `stroke`, `hole`, `brick` (one plane) or `pebble` (three).
    pub builtin: String,
    pub k: u32,
}

/// The parameters of an `lcm` encoding: what `create` takes. The derived fields (`k`, `planes`,
/// `stored_resolutions`, and `background` when not given) are filled in by `create` and kept in
/// the manifest's `derived`. A manifest's params posted back to `create` (with the element image
/// when `element` names no built-in) make the same encoding again; a derived field that is
/// given must agree with what it derives.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// A built-in element; without it the input image `element` is used: a square PNG of
    /// side 2^K whose grey level − 128 is the intensity (transparent pixels are 0), one plane
    /// with a palette, else one plane per channel.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub element: Option<Builtin>,
    /// Derived: the base element is 2^k pixels a side.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub k: Option<u32>,
    /// Magnification 2^magnify (§2.4): layer 0 at resolution K + magnify, elements stretched.
    #[serde(default)]
    pub magnify: u32,
    /// Derived: 1 (intensity through `palette`) or 3 (one element plane per RGB channel).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub planes: Option<u32>,
    #[serde(default)]
    pub representation: Representation,
    /// Derived (explicit representation): the resolutions held, K and those the layers use.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stored_resolutions: Vec<u32>,
    /// Background intensity per plane, added last; 0 when not given.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub background: Option<Vec<f64>>,
    #[serde(default)]
    pub order: Order,
    /// `[intensity, r, g, b]` stops, for one plane.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub palette: Vec<[f64; 4]>,
    /// The served size is the period times this.
    #[serde(default = "one_tile")]
    pub tiles: [u32; 2],
    /// How the LCM sections are stored: `raw`, `zeros` (§6: the zeros the event tables imply
    /// left out), or `drawn` (not stored: drawn again from the tables and the seed at load).
    #[serde(default)]
    pub mask_coding: MaskCoding,
    /// The seed the LCMs are drawn with.
    #[serde(default)]
    pub seed: u64,
    pub layers: Vec<LayerParams>,
}
