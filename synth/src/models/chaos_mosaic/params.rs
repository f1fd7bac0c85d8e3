//! The parameters of a chaos mosaic, as stored in the bundle manifest, and their validation.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Most blocks (tiles) one texture may have: bounds the block index's memory (~30 B a block).
pub const MAX_BLOCKS: u64 = 1 << 22;
/// Longest texture side: block locations are stored as `u32`.
pub const MAX_SIDE: u64 = u32::MAX as u64;
/// Largest sample side for an explicit block sequence: 12-byte records hold sides as `u8`.
pub const MAX_EXPLICIT_SAMPLE_SIDE: u32 = 256;
pub const MAX_ITERATIONS: u32 = 1000;
pub const MAX_BLOCKS_PER_TILE: u32 = 8;
pub const MAX_FILTER_WIDTH: u32 = 8;

/// How the random block sequence R_ε is kept.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum Sequence {
    /// Derived from `seed` when loaded: a few bytes for any texture size.
    #[default]
    Seed,
    /// Stored in the bundle's `blocks` section, 12 bytes a block, as in the paper (§3.1).
    Explicit,
}

/// T_ε and the recipe of R_ε (paper §3.1). The texture is `tiles_x·n_w × tiles_y·n_h`
/// for an `n_w × n_h` sample, and is a torus of exactly that size.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// m_τ: tiles across.
    pub tiles_x: u32,
    /// n_τ: tiles down.
    pub tiles_y: u32,
    /// Random blocks cut from each tile. The paper uses one (§2.3: "the precise number of
    /// random blocks per tile is immaterial"); with one, about e^−0.625 ≈ 54% of the plain
    /// tiling stays uncovered, which bounds how far long-range repetition can fall.
    #[serde(default = "default_blocks_per_tile")]
    pub blocks_per_tile: u32,
    /// Cat map iterations i; 0 leaves every block where it was cut, i.e. the plain tiling.
    #[serde(default = "default_iterations")]
    pub iterations: u32,
    /// c_λ: smallest block area as a fraction of the sample's.
    #[serde(default = "default_c_lambda")]
    pub c_lambda: f64,
    /// c_μ: largest block area as a fraction of the sample's.
    #[serde(default = "default_c_mu")]
    pub c_mu: f64,
    #[serde(default)]
    pub seed: u64,
    #[serde(default)]
    pub sequence: Sequence,
    /// Whether the sample tiles without a seam. Unset when creating: measured from the sample.
    /// When false, tile edges are cross-edge filtered like block edges (§2.4).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub seamless: Option<bool>,
    /// Pixels filtered on each side of a block edge (the paper uses 3); 0 disables filtering.
    #[serde(default = "default_filter_width")]
    pub filter_width: u32,
}

fn default_blocks_per_tile() -> u32 {
    1
}
fn default_iterations() -> u32 {
    10
}
fn default_c_lambda() -> f64 {
    0.5
}
fn default_c_mu() -> f64 {
    0.75
}
fn default_filter_width() -> u32 {
    3
}

impl Params {
    /// Checks every parameter that does not depend on the sample.
    pub fn validate(&self) -> Result<()> {
        if self.tiles_x == 0 || self.tiles_y == 0 {
            return Err(Error::param("tiles_x/tiles_y", "must be at least 1"));
        }
        if !(1..=MAX_BLOCKS_PER_TILE).contains(&self.blocks_per_tile) {
            return Err(Error::param(
                "blocks_per_tile",
                format!("{}; must be 1..={MAX_BLOCKS_PER_TILE}", self.blocks_per_tile),
            ));
        }
        let blocks = self.tiles_x as u64 * self.tiles_y as u64 * self.blocks_per_tile as u64;
        if blocks > MAX_BLOCKS {
            return Err(Error::param("tiles_x/tiles_y", format!("{blocks} blocks; at most {MAX_BLOCKS}")));
        }
        if self.iterations > MAX_ITERATIONS {
            return Err(Error::param("iterations", format!("{}; at most {MAX_ITERATIONS}", self.iterations)));
        }
        let (l, u) = (self.c_lambda, self.c_mu);
        if !(l > 0.0 && l <= u && u < 1.0) {
            return Err(Error::param("c_lambda/c_mu", format!("need 0 < c_lambda ≤ c_mu < 1, got {l} and {u}")));
        }
        if self.filter_width > MAX_FILTER_WIDTH {
            return Err(Error::param("filter_width", format!("{}; at most {MAX_FILTER_WIDTH}", self.filter_width)));
        }
        Ok(())
    }
}
