//! The encoding: the exemplar as `sample.png` and the parameters in the manifest; everything
//! derived (pyramid, vectors, k-coherence sets) is recomputed at load.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::params::Params;
use super::plan::SAMPLE_SECTION;
use super::render::OrderIndependent;
use super::shared::Shared;
use super::MODEL;
use crate::bundle::Bundle;
use crate::models::parse_params;
#[cfg(feature = "create")]
use crate::models::{input_image, Inputs};
use crate::pixels::decode_png;
use crate::{Resources, Result};

/// Makes an encoding from `params` (JSON, see [`Params`]) and the input image `sample`.
#[cfg(feature = "create")]
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    super::plan::plan_create(params, inputs)?;
    let p: Params = parse_params(params)?;
    let given = serde_json::to_value(&p).expect("params serialize");
    let p = p.filled();
    let sample = input_image(inputs, "sample")?;
    let bundle = Bundle::created(MODEL, name, given, serde_json::to_value(&p).expect("params serialize"))
        .with_section(SAMPLE_SECTION, sample.to_png());
    load(&bundle)?;
    Ok(bundle)
}

/// Validates a stored encoding completely and builds the texture, with resources of its own
/// (no cache).
pub fn load(bundle: &Bundle) -> Result<OrderIndependent> {
    load_with(bundle, &Resources::default())
}

/// [`load`], the texture sharing `resources` with the others loaded with them.
pub fn load_with(bundle: &Bundle, resources: &Resources) -> Result<OrderIndependent> {
    super::plan::plan(bundle)?;
    let params: Params = bundle.params()?;
    let sample = decode_png(SAMPLE_SECTION, bundle.section(SAMPLE_SECTION)?)?;
    let hash = blake3::hash(&bundle.to_bytes());
    let key = u64::from_le_bytes(hash.as_bytes()[..8].try_into().expect("8 bytes"));
    let shared = resources.part::<Shared>(MODEL).expect("the model's part of every Resources");
    OrderIndependent::new(params, &sample, key, shared)
}
