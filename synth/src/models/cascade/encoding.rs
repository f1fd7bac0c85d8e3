//! The cascade's encoding: the parameters in the manifest, the optional `control` and
//! `initial` images as sections, and their complete validation.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::exact::auto_range;
use super::plan::{build_engine, CONTROL_SECTION, INITIAL_SECTION};
use super::render::Cascade;
use super::MODEL;
use crate::bundle::Bundle;
use crate::models::parse_params;
#[cfg(feature = "create")]
use crate::models::{input_image, Inputs};
use crate::pixels::{decode_png, Rgba8Image};
use crate::{Error, Result};

use super::params::Params;

/// Decodes an optional image section of a bundle.
pub fn section_image(bundle: &crate::bundle::Bundle, section: &str, name: &str) -> Result<Option<Rgba8Image>> {
    match bundle.sections.iter().find(|s| s.name == section) {
        Some(s) => Ok(Some(decode_png(name, &s.data)?)),
        None => Ok(None),
    }
}

/// Makes an encoding from parameters and the optional `control` / `initial` images; a missing
/// `range` is estimated from a sample of the texture, and the defaults that depend on when
/// the encoding was made are written ([`Params::filled`]).
#[cfg(feature = "create")]
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    super::plan::plan_create(params, inputs)?;
    let mut p: Params = parse_params(params)?;
    let given = serde_json::to_value(&p).map_err(|e| Error::param("params", e.to_string()))?;
    p = p.filled();
    let control = inputs.contains_key("control").then(|| input_image(inputs, "control")).transpose()?;
    let initial = inputs.contains_key("initial").then(|| input_image(inputs, "initial")).transpose()?;
    if p.range.is_none() {
        p.range = Some(auto_range(&build_engine(&p, control.as_ref(), initial.as_ref())?));
    }
    let complete = serde_json::to_value(&p).map_err(|e| Error::param("params", e.to_string()))?;
    let mut bundle = Bundle::created(MODEL, name, given, complete);
    if let Some(c) = control {
        bundle = bundle.with_section(CONTROL_SECTION, c.to_png());
    }
    if let Some(i) = initial {
        bundle = bundle.with_section(INITIAL_SECTION, i.to_png());
    }
    load(&Bundle::from_bytes(&bundle.to_bytes())?)?;
    Ok(bundle)
}

/// Validates an encoding completely and returns the texture.
pub fn load(bundle: &Bundle) -> Result<Cascade> {
    if bundle.manifest.model != MODEL {
        return Err(Error::bundle(format!("model `{}`, expected `{MODEL}`", bundle.manifest.model)));
    }
    if let Some(s) = bundle.sections.iter().find(|s| s.name != CONTROL_SECTION && s.name != INITIAL_SECTION) {
        return Err(Error::bundle(format!("unexpected section `{}`", s.name)));
    }
    super::plan::plan(bundle)?;
    let p: Params = bundle.params()?;
    let control = section_image(bundle, CONTROL_SECTION, "control")?;
    let initial = section_image(bundle, INITIAL_SECTION, "initial")?;
    Cascade::build(p, control.as_ref(), initial.as_ref())
}
