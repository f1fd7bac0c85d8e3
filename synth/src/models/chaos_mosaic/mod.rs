//! The chaos mosaic of Xu, Guo and Shum (MSR-TR-2000-32) as a virtual texture.
//!
//! A tiling T of the sample S is overlaid with one random block of S per tile, each moved by
//! i iterations of the cat map, pasted in sequence order, and cross-edge filtered over
//! `filter_width` pixels each side of every seam. The encoding V = (S, T_ε, R_ε) keeps the
//! sample, the tiling and either the explicit block sequence (12 bytes a block) or the seed
//! it is derived from. The texture is a torus of `tiles_x·n_w × tiles_y·n_h` pixels.
//!
//! Supported inputs: any sample from 2 × 2 up to 4096 × 4096 (non-square and non-power-of-two
//! included; explicit sequences need sides ≤ 256, as the 12-byte records do) whose size admits
//! a block under the area constraint; alpha is kept and filtered like the colour channels
//! (straight alpha); non-square textures run the cat map on a square torus of side
//! lcm(W, H) scaled onto the texture (see [`catmap::iterate`]).

#[cfg(feature = "create")]
mod demos;
mod encoding;
mod params;
mod plan;

mod blocks;
pub mod catmap;
mod compose;
mod homes;
mod index;
mod layout;
mod prefilter;
mod render;
mod sums;

pub use blocks::{Block, RECORD_BYTES};
#[cfg(feature = "create")]
pub use demos::demos;
#[cfg(feature = "create")]
pub use encoding::create;
pub use encoding::{is_seamless, load};
pub use params::{Params, Sequence};
pub use prefilter::EXACT_LEVELS;
pub use render::ChaosMosaic;

#[cfg(feature = "create")]
use super::{InputInfo, Inputs, ModelInfo};
use super::{MipGuarantee, Model, Plan};
use crate::{bundle::Bundle, Result, Texture};
use std::sync::Arc;

pub const MODEL: &str = "chaos-mosaic";

/// The chaos mosaic's registry entry.
pub struct ChaosMosaicModel;
pub static CHAOS_MOSAIC: ChaosMosaicModel = ChaosMosaicModel;

impl Model for ChaosMosaicModel {
    fn id(&self) -> &'static str {
        MODEL
    }
    #[cfg(feature = "create")]
    fn describe(&self) -> ModelInfo {
        ModelInfo {
            id: MODEL,
            title: "Chaos mosaic",
            paper: "Xu, Guo, Shum 2000, Chaos Mosaic: Fast and Memory Efficient Texture Synthesis",
            summary: "A tiling of the sample overlaid with random blocks of it, scattered by the cat map and \
                      cross-edge filtered: a seamless torus of any size from one small sample.",
            params_schema: super::params_schema::<Params>(),
            inputs: &[InputInfo {
                name: "sample",
                required: true,
                what: "the example texture, 2 × 2 up to 4096 × 4096 pixels (straight alpha kept)",
            }],
        }
    }
    #[cfg(feature = "create")]
    fn create(&self, name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
        create(name, params, inputs)
    }
    #[cfg(feature = "create")]
    fn inputs_of(&self, bundle: &Bundle) -> Result<Inputs> {
        Ok(super::section_inputs(bundle, &[("sample", plan::SAMPLE_SECTION)]))
    }
    fn load(&self, bundle: &Bundle, _: &crate::Resources) -> Result<Arc<dyn Texture>> {
        Ok(Arc::new(load(bundle)?))
    }
    fn plan(&self, bundle: &Bundle) -> Result<Plan> {
        plan::plan(bundle)
    }
    #[cfg(feature = "create")]
    fn plan_create(&self, params: &serde_json::Value, inputs: &Inputs) -> Result<Plan> {
        plan::plan_create(params, inputs)
    }
    #[cfg(feature = "create")]
    fn demos(&self) -> Vec<Bundle> {
        demos()
    }
    #[cfg(feature = "create")]
    fn example(&self) -> super::Example {
        demos::example()
    }
    fn mip_guarantee(&self) -> MipGuarantee {
        MipGuarantee { min_psnr_db: 34.0, max_mean_error: 2.0, max_sigma_error: 0.15, beats_trivial_answers: true }
    }
}
