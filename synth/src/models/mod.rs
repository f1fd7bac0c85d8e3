//! The texture models, and the registry that creates and loads any of them by model id.
//!
//! Each model module offers the same three functions, wired in below:
//! `create(name, params, inputs) -> Bundle` makes an encoding from parameters and input
//! images, `load(&Bundle) -> Model` validates an encoding completely before use, and
//! `demos() -> Vec<Bundle>` makes its demo encodings from project-made inputs.

use crate::{bundle::Bundle, Error, Result, Texture};
use std::collections::BTreeMap;
use std::sync::Arc;

pub mod cascade;
pub mod chaos_mosaic;
pub mod lcm;
pub mod patterns;

/// Input images by name (PNG bytes), e.g. `sample` for the chaos mosaic.
pub type Inputs = BTreeMap<String, Vec<u8>>;

/// The model ids this build knows.
pub const MODELS: &[&str] = &[cascade::MODEL, chaos_mosaic::MODEL, lcm::MODEL, patterns::MODEL];

/// Makes a new encoding of `model` from its JSON parameters and input images.
pub fn create(model: &str, name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    check_name(name)?;
    match model {
        cascade::MODEL => cascade::create(name, params, inputs),
        chaos_mosaic::MODEL => chaos_mosaic::create(name, params, inputs),
        lcm::MODEL => lcm::create(name, params, inputs),
        patterns::MODEL => patterns::create(name, params, inputs),
        other => Err(Error::UnknownModel(other.into())),
    }
}

/// Validates an encoding completely and returns the texture it describes.
pub fn load(bundle: &Bundle) -> Result<Arc<dyn Texture>> {
    match bundle.manifest.model.as_str() {
        cascade::MODEL => Ok(Arc::new(cascade::load(bundle)?)),
        chaos_mosaic::MODEL => Ok(Arc::new(chaos_mosaic::load(bundle)?)),
        lcm::MODEL => Ok(Arc::new(lcm::load(bundle)?)),
        patterns::MODEL => Ok(Arc::new(patterns::load(bundle)?)),
        other => Err(Error::UnknownModel(other.into())),
    }
}

/// Every model's demo encodings.
pub fn demos() -> Vec<Bundle> {
    let mut all = chaos_mosaic::demos();
    all.extend(cascade::demos());
    all.extend(lcm::demos());
    all.extend(patterns::demos());
    all.sort_by(|a, b| a.manifest.name.cmp(&b.manifest.name));
    all
}

fn check_name(name: &str) -> Result<()> {
    let n = name.chars().count();
    if n == 0 || n > 200 || name.chars().any(char::is_control) {
        return Err(Error::param("name", "1 to 200 printable characters"));
    }
    Ok(())
}

/// The input image called `name`, decoded, or an error naming it.
pub fn input_image(inputs: &Inputs, name: &str) -> Result<crate::Rgba8Image> {
    let bytes = inputs.get(name).ok_or_else(|| Error::image(name, "missing; this model needs it"))?;
    crate::pixels::decode_png(name, bytes)
}
