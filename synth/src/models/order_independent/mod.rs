//! `order-independent`: texture synthesis by example in which any pixel can be computed alone,
//! in any order, identically every time (Wei & Levoy 2002, *Order-Independent Texture
//! Synthesis*).
//!
//! The output is a K-level pyramid whose pixels keep several generations. An entry (level s,
//! generation m, pixel p) is the exemplar pixel whose neighbourhood best matches the values it
//! reads: the previous generation of its own level around p and the latest generation of the
//! coarser level around p's parent. Reads go only to lexically smaller (level, generation)
//! pairs, so the dependency graph is acyclic and every entry is a function of the hashed noise
//! at the coarsest level. Entries hold exemplar coordinates, not colours.
//!
//! * [`structure`] — what each entry reads (levels, generations, neighbourhoods, ≺);
//! * [`params`] — the parameters; [`encoding`] — `create`, `load` and validation;
//! * [`exemplar`] — the exemplar pyramid, valid masks, neighbourhood vectors, k-coherence sets;
//! * [`search`] — the per-entry function ([`Synthesizer`], a [`structure::Synthesis`]);
//! * [`served`] — the dense evaluator of a rectangle's dependency cone;
//! * [`cache`] — the pyramidal cache; [`shared`] — the cache and work counters that the
//!   textures loaded with one [`Resources`] share;
//! * [`prefilter`] — coarse mip levels from the synthesis pyramid;
//! * [`demos`] — the demo encodings.

pub mod cache;
#[cfg(feature = "create")]
pub mod demos;
pub mod encoding;
pub mod exemplar;
pub mod levels;
pub mod params;
mod plan;
pub mod prefilter;
pub mod rect;
pub mod reference;
mod render;
pub mod search;
pub mod served;
pub mod shared;
pub mod structure;

#[cfg(feature = "create")]
use super::{InputInfo, Inputs, ModelInfo};
use super::{MipGuarantee, Model, Plan};
use crate::bundle::Bundle;
use crate::texture::Texture;
use crate::{Resources, Result};
use std::sync::Arc;

#[cfg(feature = "create")]
pub use demos::demos;
#[cfg(feature = "create")]
pub use encoding::create;
pub use encoding::{load, load_with, verify};
pub use params::Params;
pub use render::OrderIndependent;
pub use search::Synthesizer;

pub const MODEL: &str = "order-independent";

/// The model's registry entry.
pub struct OrderIndependentModel;
pub static ORDER_INDEPENDENT: OrderIndependentModel = OrderIndependentModel;

impl Model for OrderIndependentModel {
    fn id(&self) -> &'static str {
        MODEL
    }
    #[cfg(feature = "create")]
    fn describe(&self) -> ModelInfo {
        ModelInfo {
            id: MODEL,
            title: "Order-independent synthesis",
            paper: "Wei, Levoy 2002, Order-Independent Texture Synthesis",
            summary: "Multiresolution neighbourhood search in which every pixel keeps several generations and reads \
                      only coarser levels and earlier generations, so any pixel is computed alone from hashed \
                      noise, in any order, through a pyramidal cache.",
            params_schema: super::params_schema::<Params>(),
            inputs: &[InputInfo {
                name: "sample",
                required: true,
                what: "the exemplar (RGB; alpha ignored), sides multiples of 2^(levels − 1), at least 4× that, at most 256",
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
    fn load(&self, bundle: &Bundle, resources: &Resources) -> Result<Arc<dyn Texture>> {
        Ok(Arc::new(load_with(bundle, resources)?))
    }
    fn plan(&self, bundle: &Bundle) -> Result<Plan> {
        plan::plan(bundle)
    }
    #[cfg(feature = "create")]
    fn verify(&self, bundle: &Bundle) -> Result<()> {
        verify(bundle)
    }
    #[cfg(feature = "create")]
    fn cached_sections(&self) -> &'static [&'static str] {
        &[prefilter::SECTION]
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
        MipGuarantee { min_psnr_db: 22.0, max_mean_error: 2.0, max_sigma_error: 0.15, beats_trivial_answers: true }
    }
    fn resources(&self, cache_budget: u64) -> Option<crate::resources::Shared> {
        Some(crate::resources::Shared::new(shared::Shared::new(cache_budget)))
    }
}
