//! `patterns`: Pattern Based Procedural Textures (Lefebvre & Neyret, I3D 2003).
//!
//! The encoding is a reference texture of T patterns, the permutation tables σ, and a
//! composition of the paper's §3 blocks written as data (see [`params`]); any pixel of any
//! level and frame is evaluated on demand by [`model::PatternTexture`].
//!
//! One module per block: [`reference`] (Reference Texture with per-pattern mip chains),
//! [`sigma`] (Virtual Indirection Map), [`random`] (Virtual Random Map), [`maps`] (explicit
//! maps), [`materials`] (Explicit Indirection, Probability, Materials, Areas and Dithered Areas
//! Maps), [`pixel_map`], [`transitions`] (Transition Tiles), [`transform`] (Tile Transform with
//! overflow), [`sprites`] (Explicit Positioning), [`animation`] (Animation Sequence, Animation
//! Map, Temporal Transitions); [`render`] composes them into the texture. `plan` holds the
//! encoding's limits and checks and the cost model, [`encoding`] `create` and `load`;
//! [`demos`] and [`art`] make the demos.

#[cfg(feature = "create")]
pub mod demos;
pub mod encoding;
pub mod params;
mod plan;

pub mod animation;
pub mod art;
pub mod maps;
pub mod materials;
pub mod pixel_map;
pub mod random;
pub mod reference;
pub mod render;
pub mod sigma;
pub mod sprites;
pub mod transform;
pub mod transitions;

#[cfg(feature = "create")]
pub use demos::demos;
#[cfg(feature = "create")]
pub use encoding::create;
pub use encoding::load;
pub use params::Params;
pub use render::PatternTexture;

#[cfg(feature = "create")]
use super::{InputInfo, Inputs, ModelInfo};
use super::{MipGuarantee, Model, Plan};
use crate::{bundle::Bundle, Result, Texture};
use std::sync::Arc;

/// The model id.
pub const MODEL: &str = "patterns";

/// The `patterns` registry entry.
pub struct PatternsModel;
pub static PATTERNS: PatternsModel = PatternsModel;

impl Model for PatternsModel {
    fn id(&self) -> &'static str {
        MODEL
    }
    #[cfg(feature = "create")]
    fn describe(&self) -> ModelInfo {
        ModelInfo {
            id: MODEL,
            title: "Pattern-based procedural textures",
            paper: "Lefebvre, Neyret 2003, Pattern Based Procedural Textures",
            summary: "A reference texture of small patterns composed per pixel through virtual and explicit \
                      indirection, probability, area, transition and animation maps.",
            params_schema: super::params_schema::<Params>(),
            inputs: &[
                InputInfo {
                    name: "reference",
                    required: true,
                    what: "the reference texture: `reference[0] × reference[1]` patterns of `pattern_size` \
                           pixels, packed row-major",
                },
                InputInfo {
                    name: "*",
                    required: false,
                    what: "an explicit map, named by the section the parameters give it; its red channel \
                           holds the values",
                },
            ],
        }
    }
    #[cfg(feature = "create")]
    fn create(&self, name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
        create(name, params, inputs)
    }
    #[cfg(feature = "create")]
    fn inputs_of(&self, bundle: &Bundle) -> Result<Inputs> {
        encoding::inputs_of(bundle)
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
        MipGuarantee { min_psnr_db: 27.0, max_mean_error: 7.0, max_sigma_error: 0.3, beats_trivial_answers: true }
    }
}
