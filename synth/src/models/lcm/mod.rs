//! `lcm`: multi-scaled stochastic textures rendered with Layer Control Masks
//! (paper `layer-control-masks.txt`).
//!
//! A texture is scaled, rotated, mirrored, signed copies of one small base element, dropped
//! at half-element spacing on layers of decreasing resolution. Every replication point's
//! event is drawn once from an event table and stored as one byte in the layer's control
//! mask, so any pixel is evaluated alone from at most four LCM entries per layer. Mip level L
//! shifts every layer down L resolutions (§2.4), so coarse levels are native and prefiltered.
//!
//! * [`event`] — the one-byte event code of §5.
//! * [`table`] — event tables and the seeded drawing of LCMs.
//! * [`element`] (+ [`haar`]) — the base element and its scaled, oriented copies.
//! * [`layer`] — evaluation of one layer from its LCM, native or prefiltered.
//! * [`render`] — the texture: layers, order, background, colour; operation counting.
//! * [`period`] — the period that LCM sizes give the texture.
//! * [`packing`] — §6's coding of the zeros of an LCM section.
//! * [`colour`] — palette or per-channel planes.
//! * [`params`] — the creation parameters; `plan` — the sections, every check of a stored or
//!   given encoding, and the cost model; [`encoding`] — `create` and `load`.
//! * [`elements`], [`demos`] — project-made base elements and the paper's §3 examples.

#[cfg(feature = "create")]
pub mod demos;
pub mod encoding;
pub mod params;
mod plan;

pub mod colour;
pub mod element;
pub mod elements;
pub mod event;
pub mod haar;
pub mod layer;
pub mod packing;
pub mod period;
pub mod render;
pub mod table;

#[cfg(feature = "create")]
pub use demos::demos;
#[cfg(feature = "create")]
pub use encoding::create;
pub use encoding::load;
pub use params::Params;
pub use render::{LcmTexture, OpCount};

#[cfg(feature = "create")]
use super::{InputInfo, Inputs, ModelInfo};
use super::{MipGuarantee, Model, Plan};
use crate::{bundle::Bundle, Result, Texture};
use std::sync::Arc;

/// The model id.
pub const MODEL: &str = "lcm";

/// The `lcm` registry entry.
pub struct LcmModel;
pub static LCM: LcmModel = LcmModel;

impl Model for LcmModel {
    fn id(&self) -> &'static str {
        MODEL
    }
    #[cfg(feature = "create")]
    fn describe(&self) -> ModelInfo {
        ModelInfo {
            id: MODEL,
            title: "Layer Control Masks",
            paper: "A multi-scaled model for stochastic texture representation, rendered with Layer Control Masks",
            summary: "Scaled, rotated, mirrored, signed copies of one small base element on layers of \
                      decreasing resolution, one stored event byte per replication point.",
            params_schema: super::params_schema::<Params>(),
            inputs: &[InputInfo {
                name: "element",
                required: false,
                what: "the base element when `element` names no built-in: a square PNG of side 2^K whose \
                       grey level − 128 is the intensity (one plane with a palette, else one per channel)",
            }],
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
        MipGuarantee { min_psnr_db: 30.0, max_mean_error: 4.0, max_sigma_error: 0.15, beats_trivial_answers: true }
    }
}
