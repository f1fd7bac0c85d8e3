//! The encoding: the exemplar as `sample.png`, the parameters in the manifest, and the coarse
//! levels' calibration as `calibration.bin` (measured by `create` on level-0 windows, which
//! would cost a texture's first coarse tile seconds); everything else derived (pyramid,
//! vectors, k-coherence sets) is recomputed at load. A bundle stored before the calibration
//! section existed has none, and measures it on first use as it always did.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::params::Params;
use super::plan::SAMPLE_SECTION;
use super::prefilter::SECTION as CALIBRATION_SECTION;
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
    // The calibration is measured once here, through a cache of its own (its windows' cones
    // overlap), and stored: opening the texture and its coarse tiles then synthesize no
    // level-0 window.
    let calibration = load_with(&bundle, &Resources::new(CALIBRATION_CACHE))?.calibration().to_bytes();
    let bundle = bundle.with_section(CALIBRATION_SECTION, calibration);
    load(&bundle)?;
    Ok(bundle)
}

/// Bytes of the cache through which `create` and [`verify`] measure the calibration.
#[cfg(feature = "create")]
const CALIBRATION_CACHE: u64 = VERIFY_CACHE;

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
    let texture = OrderIndependent::new(params, &sample, key, shared)?;
    match bundle.sections.iter().find(|s| s.name == CALIBRATION_SECTION) {
        Some(s) => texture.with_calibration(&s.data),
        None => Ok(texture),
    }
}

/// What [`load`] trusts, checked: the stored calibration must be the one measuring it gives,
/// or a crafted one would colour the coarse levels unlike the chain of level 0, breaking mip coherence.
/// It is measured again (seconds for a 100k demo), with resources of its own so that no
/// owner's cache or work counters see it; a bundle without the section has nothing to check.
/// Called where a bundle is accepted ([`crate::models::Model::verify`]), never on open.
pub fn verify(bundle: &Bundle) -> Result<()> {
    let Ok(stored) = bundle.section(CALIBRATION_SECTION) else { return Ok(()) };
    let mut plain = bundle.clone();
    plain.sections.retain(|s| s.name != CALIBRATION_SECTION);
    load_with(&plain, &Resources::new(VERIFY_CACHE))?.verify_calibration(stored)
}

/// Bytes of the cache through which [`verify`] measures the calibration.
const VERIFY_CACHE: u64 = 64 << 20;
