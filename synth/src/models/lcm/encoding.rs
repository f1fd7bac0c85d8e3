//! The `lcm` encoding: [`create`] (base element + event tables → LCMs drawn with a seed) and
//! [`load`]; both check everything first ([`super::plan`], which holds the sections' layout
//! and their checks).

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::colour::QI;
use super::element::{self, Copies, Plane, Stored};
use super::haar;
use super::layer::Layer;
use super::packing::{self, MaskCoding};
use super::params::{Builtin, Order, Params, Representation};
use super::plan::{check, drawn_lcms, quantized_weight, stored_resolutions, Checked};
use super::render::LcmTexture;
use super::{elements, MODEL};
use crate::bundle::Bundle;
use crate::models::parse_params;
#[cfg(feature = "create")]
use crate::models::{input_image, Inputs};
use crate::{Error, Result, Rgba8Image};

/// The element planes of a built-in that [`element_shape`](super::plan::element_shape) accepted.
fn builtin_planes(b: &Builtin) -> Vec<Plane> {
    match b.builtin.as_str() {
        "stroke" => vec![elements::stroke(b.k)],
        "hole" => vec![elements::hole(b.k)],
        "brick" => vec![elements::brick(b.k)],
        _ => elements::pebble(b.k, PEBBLE_STONE, PEBBLE_SAND).to_vec(),
    }
}

/// Colours of the pebble element: stone and the sand it is an offset from.
pub const PEBBLE_STONE: [f64; 3] = [120.0, 116.0, 112.0];
pub const PEBBLE_SAND: [f64; 3] = [176.0, 156.0, 120.0];

/// Element planes from the input image `element`.
#[cfg(feature = "create")]
fn image_planes(inputs: &Inputs, planes: usize) -> Result<Vec<Plane>> {
    let img = input_image(inputs, "element")?;
    if img.width != img.height {
        return Err(Error::image("element", format!("{}×{} is not square", img.width, img.height)));
    }
    element::side_exponent(img.width as usize, "element").map_err(|e| Error::image("element", e.to_string()))?;
    let px = |c: usize| -> Vec<i8> {
        img.data
            .chunks_exact(4)
            .map(|p| {
                if p[3] < 128 {
                    0
                } else if c == 3 {
                    ((p[0] as i32 + p[1] as i32 + p[2] as i32 + 1) / 3 - 128) as i8
                } else {
                    (p[c] as i32 - 128) as i8
                }
            })
            .collect()
    };
    let chans: Vec<usize> = if planes == 1 { vec![3] } else { vec![0, 1, 2] };
    chans.into_iter().map(|c| Plane::new(img.width as usize, px(c), "element")).collect()
}

/// Makes an encoding: the base element, the LCMs drawn from the tables with the seed. Every
/// parameter is checked ([`super::plan::plan_create`]) before anything is drawn.
#[cfg(feature = "create")]
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    super::plan::plan_create(params, inputs)?;
    let mut p: Params = parse_params(params)?;
    let given = serde_json::to_value(&p).map_err(|e| Error::param("params", e.to_string()))?;
    let planes = match &p.element {
        Some(b) => builtin_planes(b),
        None => image_planes(inputs, if p.palette.is_empty() { 3 } else { 1 })?,
    };
    let k = planes[0].k;
    let mut sections: Vec<(String, Vec<u8>)> = drawn_lcms(&p)?
        .into_iter()
        .enumerate()
        .filter_map(|(n, codes)| {
            let codes = codes?;
            let l = &p.layers[n];
            let data = match (p.mask_coding, &l.table) {
                (MaskCoding::Drawn, _) => return None,
                (MaskCoding::Zeros, Some(t)) => packing::pack(&codes, t, l.lcm[0] as usize),
                _ => codes,
            };
            Some((format!("lcm.{n}"), data))
        })
        .collect();
    let resolutions = stored_resolutions(&p, k);
    for (i, plane) in planes.iter().enumerate() {
        match p.representation {
            Representation::Explicit => {
                let Stored::Explicit(copies) = Stored::explicit(plane, &resolutions) else { unreachable!() };
                for c in copies {
                    sections.push((format!("element.{i}.{}", c.k), c.pixels.iter().map(|&v| v as u8).collect()));
                }
            }
            Representation::Haar => {
                let Stored::Haar(coef) = Stored::haar(plane) else { unreachable!() };
                sections.push((format!("haar.{i}"), coef.iter().flat_map(|c| c.to_le_bytes()).collect()));
            }
        }
    }
    p.k = Some(k);
    p.planes = Some(planes.len() as u32);
    p.stored_resolutions = if p.representation == Representation::Explicit { resolutions } else { vec![] };
    p.background.get_or_insert_with(|| vec![0.0; planes.len()]);
    let complete = serde_json::to_value(&p).map_err(|e| Error::param("params", e.to_string()))?;
    let mut bundle = Bundle::created(MODEL, name, given, complete);
    sections.sort();
    for (n, d) in sections {
        bundle = bundle.with_section(&n, d);
    }
    load(&bundle)?;
    Ok(bundle)
}

/// The input images `create` made `bundle` from: none for a built-in element, else the image
/// `element` rebuilt from the resolution-K plane(s), grey level − 128 the intensity.
#[cfg(feature = "create")]
pub fn inputs_of(bundle: &Bundle) -> Result<Inputs> {
    let p: Params = bundle.params()?;
    if p.element.is_some() {
        return Ok(Inputs::new());
    }
    let Checked { k, planes, .. } = check(&p, bundle)?;
    let plane = |i: u32| -> Result<Vec<i8>> {
        Ok(match p.representation {
            Representation::Explicit => bundle.section(&format!("element.{i}.{k}"))?.iter().map(|&b| b as i8).collect(),
            Representation::Haar => {
                let data = bundle.section(&format!("haar.{i}"))?;
                let coef: Vec<i32> = data.chunks_exact(2).map(|b| i16::from_le_bytes([b[0], b[1]]) as i32).collect();
                let full = haar::low_passes(&coef, 1 << k).swap_remove(0);
                full.into_iter().map(|v| v.clamp(-128, 127) as i8).collect()
            }
        })
    };
    let planes = (0..planes).map(plane).collect::<Result<Vec<_>>>()?;
    let mut img = Rgba8Image::new(1 << k, 1 << k);
    for (n, px) in img.data.chunks_exact_mut(4).enumerate() {
        let grey = |i: usize| (planes[i.min(planes.len() - 1)][n] as i32 + 128) as u8;
        px.copy_from_slice(&[grey(0), grey(1), grey(2), 255]);
    }
    Ok(Inputs::from([("element".to_string(), img.to_png())]))
}

/// Checks an encoding completely ([`check`]) and builds its texture.
pub fn load(bundle: &Bundle) -> Result<LcmTexture> {
    let p: Params = bundle.params()?;
    let Checked { k, planes, background, colour, period, size, resolutions, masks } = check(&p, bundle)?;
    let planes = planes as usize;
    let copies = (0..planes)
        .map(|i| {
            let stored = match p.representation {
                Representation::Explicit => {
                    let copies = resolutions
                        .iter()
                        .map(|&r| {
                            let name = format!("element.{i}.{r}");
                            Plane::new(1 << r, bundle.section(&name)?.iter().map(|&b| b as i8).collect(), &name)
                        })
                        .collect::<Result<Vec<_>>>()?;
                    Stored::Explicit(copies)
                }
                Representation::Haar => {
                    let name = format!("haar.{i}");
                    let data = bundle.section(&name)?;
                    let coef: Vec<i16> = data.chunks_exact(2).map(|b| i16::from_le_bytes([b[0], b[1]])).collect();
                    if let Some(c) = coef.iter().find(|c| c.abs() > 1020) {
                        return Err(Error::param(
                            &name,
                            format!("coefficient {c} is beyond what an 8-bit element gives"),
                        ));
                    }
                    Stored::Haar(coef)
                }
            };
            Ok(Copies::build(&stored, k, p.magnify))
        })
        .collect::<Result<Vec<_>>>()?;
    let mut layers = p
        .layers
        .iter()
        .enumerate()
        .map(|(n, l)| {
            let codes =
                masks[l.share.unwrap_or(n)].as_deref().expect("checked: shared LCMs are an earlier layer's own");
            let (w, h) = (l.lcm[0] as usize, l.lcm[1] as usize);
            Layer::new(l.layer, quantized_weight(l.weight), w, h, codes)
        })
        .collect::<Vec<_>>();
    if p.order == Order::BottomUp {
        layers.sort_by_key(|l| std::cmp::Reverse(l.index));
    } else {
        layers.sort_by_key(|l| l.index);
    }
    let background = background.iter().map(|b| libm::floor(b * (1u64 << QI) as f64 + 0.5) as i64).collect();
    Ok(LcmTexture { k, magnify: p.magnify, copies, layers, background, colour, period, size })
}
