//! The `patterns` encoding: the parameters in the manifest, the reference texture as
//! `reference.png`, the permutation tables σ as `sigma`, and explicit maps as sections.

use super::model::{PatternTexture, MODEL};
use super::params::{self, Params};
use super::{pixel_map, sigma};
use crate::models::{input_image, parse_params, Inputs};
use crate::{bundle::Bundle, Error, Result};

/// Makes an encoding from params (see [`Params`]) and input images: `reference` (the packed
/// patterns, required); any other input is an explicit map whose red channel gives its
/// values, stored as a section of the same name — compressed when a pixel map names it.
/// The parameters are checked ([`super::plan::plan_create`]) before any image is decoded.
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    super::plan::plan_create(params, inputs)?;
    let p: Params = parse_params(params)?;
    let reference = input_image(inputs, "reference")?;
    let bundle = Bundle::new(MODEL, name, params.clone())
        .with_section("reference.png", reference.to_png())
        .with_section("sigma", sigma::to_bytes(&super::plan::tables(&p)));
    let mut bundle = super::plan::with_range_tables(bundle, &p);
    let pixel_maps: Vec<(String, u32)> = p
        .layers
        .iter()
        .filter_map(|l| match &l.choice {
            Some(params::Choice::Materials { pixel_map: Some(pm), .. }) => Some((pm.section.clone(), pm.block)),
            _ => None,
        })
        .collect();
    for (input, bytes) in inputs.iter().filter(|(k, _)| k.as_str() != "reference") {
        bundle = bundle.with_section(input, map_section(input, bytes, &pixel_maps)?);
    }
    load(&bundle)?;
    Ok(bundle)
}

/// The section an explicit map input is stored as: its red channel, one byte a pixel, or
/// compressed when `pixel_maps` (section, block side) names it.
pub(super) fn map_section(input: &str, bytes: &[u8], pixel_maps: &[(String, u32)]) -> Result<Vec<u8>> {
    let img = crate::pixels::decode_png(input, bytes)?;
    let values: Vec<u8> = img.data.chunks_exact(4).map(|p| p[0]).collect();
    match pixel_maps.iter().find(|(s, _)| s == input) {
        Some(&(_, block)) => {
            if block == 0 || !block.is_power_of_two() || img.width % block != 0 || img.height % block != 0 {
                return Err(Error::image(
                    input,
                    format!("{}×{} is not a whole number of {block}-pixel blocks", img.width, img.height),
                ));
            }
            Ok(pixel_map::encode(img.width, img.height, block, &values))
        }
        None => Ok(values),
    }
}

/// Validates an encoding completely and builds the texture: its plan first, which checks
/// what bounds the work before the reference is decoded.
pub fn load(bundle: &Bundle) -> Result<PatternTexture> {
    super::plan::plan(bundle)?;
    PatternTexture::load(bundle)
}
