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
//! Map, Temporal Transitions); [`model`] composes them; [`demos`] and [`art`] make the demos.

pub mod animation;
pub mod art;
pub mod demos;
pub mod maps;
pub mod materials;
pub mod model;
pub mod params;
pub mod pixel_map;
pub mod random;
pub mod reference;
pub mod sigma;
pub mod sprites;
pub mod transform;
pub mod transitions;

pub use model::{PatternTexture, MODEL};
pub use params::Params;

use super::{InputInfo, Inputs, MipGuarantee, Model, ModelInfo};
use crate::{bundle::Bundle, Error, Result, Texture};
use std::sync::Arc;

/// The `patterns` registry entry.
pub struct PatternsModel;
pub static PATTERNS: PatternsModel = PatternsModel;

impl Model for PatternsModel {
    fn id(&self) -> &'static str {
        MODEL
    }
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
    fn create(&self, name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
        create(name, params, inputs)
    }
    fn load(&self, bundle: &Bundle) -> Result<Arc<dyn Texture>> {
        Ok(Arc::new(load(bundle)?))
    }
    fn demos(&self) -> Vec<Bundle> {
        demos()
    }
    fn mip_guarantee(&self) -> MipGuarantee {
        MipGuarantee { min_psnr_db: 22.0, max_mean_error: 6.0 }
    }
}

/// Makes an encoding from params (see [`Params`]) and input images: `reference` (the packed
/// patterns, required); any other input is an explicit map whose red channel gives its
/// values, stored as a section of the same name — compressed when a pixel map names it.
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    let p: Params = serde_json::from_value(params.clone()).map_err(|e| Error::param("params", e.to_string()))?;
    let reference = super::input_image(inputs, "reference")?;
    let mut bundle =
        Bundle::new(MODEL, name, params.clone()).with_section("reference.png", reference.to_png()).with_section(
            "sigma",
            sigma::to_bytes(&sigma::generate_all(p.reference[0].clamp(1, 256), p.reference[1].clamp(1, 256), p.seed)),
        );
    let pixel_maps: Vec<(String, u32)> = p
        .layers
        .iter()
        .filter_map(|l| match &l.choice {
            Some(params::Choice::Materials { pixel_map: Some(pm), .. }) => Some((pm.section.clone(), pm.block)),
            _ => None,
        })
        .collect();
    for (input, bytes) in inputs.iter().filter(|(k, _)| k.as_str() != "reference") {
        let img = crate::pixels::decode_png(input, bytes)?;
        let values: Vec<u8> = img.data.chunks_exact(4).map(|p| p[0]).collect();
        let data = match pixel_maps.iter().find(|(s, _)| s == input) {
            Some(&(_, block)) => {
                if block == 0 || !block.is_power_of_two() || img.width % block != 0 || img.height % block != 0 {
                    return Err(Error::image(
                        input,
                        format!("{}×{} is not a whole number of {block}-pixel blocks", img.width, img.height),
                    ));
                }
                pixel_map::encode(img.width, img.height, block, &values)
            }
            None => values,
        };
        bundle = bundle.with_section(input, data);
    }
    load(&bundle)?;
    Ok(bundle)
}

pub fn load(bundle: &Bundle) -> Result<PatternTexture> {
    PatternTexture::load(bundle)
}

pub use demos::demos;
