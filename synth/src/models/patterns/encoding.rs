//! The `patterns` encoding: the parameters in the manifest, the reference texture as
//! `reference.png`, the permutation tables σ as `sigma`, and explicit maps as sections.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::params::{self, Params};
use super::plan::{map_section, tables, with_range_tables};
use super::render::PatternTexture;
use super::{pixel_map, sigma, MODEL};
use crate::models::parse_params;
#[cfg(feature = "create")]
use crate::models::{input_image, Inputs};
use crate::{bundle::Bundle, Error, Result};

/// Makes an encoding from params (see [`Params`]) and input images: `reference` (the packed
/// patterns, required); any other input is an explicit map whose red channel gives its
/// values, stored as a section of the same name — compressed when a pixel map names it.
/// The parameters are checked ([`super::plan::plan_create`]) before any image is decoded.
#[cfg(feature = "create")]
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    super::plan::plan_create(params, inputs)?;
    let p: Params = parse_params(params)?;
    let reference = input_image(inputs, "reference")?;
    let bundle = Bundle::new(MODEL, name, params.clone())
        .with_section("reference.png", reference.to_png())
        .with_section("sigma", sigma::to_bytes(&tables(&p)));
    let mut bundle = with_range_tables(bundle, &p);
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

/// The input images `create` made `bundle` from: the reference as stored, and every map
/// section the params name (an object with `section`: a pixel map when it has a `block`,
/// else a map of one byte a value) as a PNG whose red channel holds its values.
#[cfg(feature = "create")]
pub fn inputs_of(bundle: &Bundle) -> Result<Inputs> {
    let mut inputs = Inputs::from([("reference".to_string(), bundle.section("reference.png")?.to_vec())]);
    let mut refs = Vec::new();
    let params = bundle.manifest.full_params()?;
    section_refs(&params, &mut refs);
    for r in refs {
        let (name, [w, h], values) = if r.get("block").is_some() {
            let pm: params::PixelMapParams = parse_params(r)?;
            let values = pixel_map::decode(pm.size[0], pm.size[1], pm.block, bundle.section(&pm.section)?)?;
            (pm.section, pm.size, values)
        } else {
            let map: params::MapRef = parse_params(r)?;
            let name = map.section.expect("found by its `section`");
            if map.depth != 1 {
                return Err(Error::param(name, "a map of 2 bytes a value is no PNG input of `create`"));
            }
            (name.clone(), map.size, bundle.section(&name)?.to_vec())
        };
        if values.len() != w as usize * h as usize {
            return Err(Error::param(&name, format!("{} values for a {w}×{h} map", values.len())));
        }
        let mut img = crate::Rgba8Image::new(w, h);
        for (px, v) in img.data.chunks_exact_mut(4).zip(values) {
            px.copy_from_slice(&[v, 0, 0, 255]);
        }
        inputs.insert(name, img.to_png());
    }
    Ok(inputs)
}

/// Every object within `v` that names a `section`.
fn section_refs<'a>(v: &'a serde_json::Value, out: &mut Vec<&'a serde_json::Value>) {
    match v {
        serde_json::Value::Object(m) if m.get("section").is_some_and(|s| s.is_string()) => out.push(v),
        serde_json::Value::Object(m) => m.values().for_each(|v| section_refs(v, out)),
        serde_json::Value::Array(a) => a.iter().for_each(|v| section_refs(v, out)),
        _ => {}
    }
}

/// Validates an encoding completely and builds the texture: its plan first, which checks
/// what bounds the work before the reference is decoded.
pub fn load(bundle: &Bundle) -> Result<PatternTexture> {
    super::plan::plan(bundle)?;
    PatternTexture::load(bundle)
}
