//! The `lcm` encoding: manifest parameters plus binary sections, and its two directions —
//! [`create`] (base element + event tables → LCMs drawn with a seed) and [`load`] (every
//! field and byte checked before a texture is built).
//!
//! Sections:
//! * `element.{p}.{r}` — plane p of the base element at resolution r, 4^r signed bytes
//!   (explicit representation, one per stored resolution), or
//! * `haar.{p}` — the Haar pyramid of plane p, 4^K little-endian i16;
//! * `lcm.{n}` — the LCM of layer n, one event byte a point, row-major.

use super::colour::{Colour, QI};
use super::element::{self, Copies, Plane, Stored, MAX_K, MAX_TOP};
use super::event::Event;
use super::layer::{Layer, QW};
use super::period::{lcm, mask_period};
use super::render::LcmTexture;
use super::{elements, MODEL};

use super::params::one_tile;
pub use super::params::{Builtin, LayerParams, Order, Params, Representation};
use crate::bundle::Bundle;
use crate::models::{input_image, parse_params, Inputs};
use crate::{Error, Result};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// At most this many layers.
pub const MAX_LAYERS: usize = 16;
/// An LCM side is at most this many points.
pub const MAX_LCM_SIDE: u32 = 4096;
/// All LCMs together hold at most this many points (bytes).
/// (The summed-area tables of coarse levels take 16 bytes a point and plane.)
pub const MAX_LCM_POINTS: u64 = 1 << 20;
/// The served size is at most this many pixels a side.
pub const MAX_SIZE: u64 = 1 << 40;
/// Layer weights lie within ± this.
pub const MAX_WEIGHT: f64 = 64.0;

/// The manifest parameters of an `lcm` encoding: [`Params`] with the derived fields filled in
/// and the base element stored in sections.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct StoredParams {
    /// The base element is 2^k pixels a side.
    pub k: u32,
    /// Magnification 2^magnify (§2.4): layer 0 at resolution K + magnify, elements stretched.
    #[serde(default)]
    pub magnify: u32,
    /// 1 (intensity through `palette`) or 3 (one element plane per RGB channel).
    pub planes: u32,
    #[serde(default)]
    pub representation: Representation,
    /// Resolutions held explicitly (K and those the layers use).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub stored_resolutions: Vec<u32>,
    /// Background intensity per plane, added last.
    pub background: Vec<f64>,
    #[serde(default)]
    pub order: Order,
    /// `[intensity, r, g, b]` stops, for one plane.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub palette: Vec<[f64; 4]>,
    /// The served size is the period times this.
    #[serde(default = "one_tile")]
    pub tiles: [u32; 2],
    /// The seed the LCMs were drawn with (for the record).
    #[serde(default)]
    pub seed: u64,
    pub layers: Vec<LayerParams>,
}

/// The element planes of a built-in.
fn builtin_planes(b: &Builtin) -> Result<Vec<Plane>> {
    let k = element::side_exponent(1usize.checked_shl(b.k).unwrap_or(0), "element.k")?;
    let need = |min: u32| {
        if k < min {
            Err(Error::param("element.k", format!("`{}` needs k ≥ {min}", b.builtin)))
        } else {
            Ok(())
        }
    };
    Ok(match b.builtin.as_str() {
        "stroke" => vec![elements::stroke(k)],
        "hole" => vec![elements::hole(k)],
        "brick" => {
            need(3)?;
            vec![elements::brick(k)]
        }
        "pebble" => elements::pebble(k, PEBBLE_STONE, PEBBLE_SAND).to_vec(),
        other => {
            return Err(Error::param("element.builtin", format!("`{other}` is none of stroke, hole, brick, pebble")))
        }
    })
}

/// Colours of the pebble element: stone and the sand it is an offset from.
pub const PEBBLE_STONE: [f64; 3] = [120.0, 116.0, 112.0];
pub const PEBBLE_SAND: [f64; 3] = [176.0, 156.0, 120.0];

/// Element planes from the input image `element`.
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

/// Makes an encoding: the base element, the LCMs drawn from the tables with the seed.
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    let p: Params = parse_params(params)?;
    let planes = match &p.element {
        Some(b) => builtin_planes(b)?,
        None => image_planes(inputs, if p.palette.is_empty() { 3 } else { 1 })?,
    };
    let k = planes[0].k;
    if p.magnify > MAX_TOP - k {
        return Err(Error::param("magnify", format!("{}: k + magnify may not exceed {MAX_TOP}", p.magnify)));
    }
    let background = p.background.clone().unwrap_or_else(|| vec![0.0; planes.len()]);
    let mut sections: Vec<(String, Vec<u8>)> = Vec::new();
    for (n, l) in p.layers.iter().enumerate() {
        if l.share.is_some() {
            continue;
        }
        let what = format!("layers[{n}].table");
        let table = l.table.as_ref().ok_or_else(|| Error::param(&what, "needed to draw the LCM"))?;
        check_lcm_size(l.lcm, n)?;
        table.check(l.lcm, &what)?;
        sections.push((format!("lcm.{n}"), table.generate(l.lcm, p.seed, n as u64)));
    }
    let top = k + p.magnify;
    let mut stored_resolutions: Vec<u32> = vec![k];
    if p.representation == Representation::Explicit {
        for l in &p.layers {
            let r = top.saturating_sub(l.layer);
            if (1..k).contains(&r) && !stored_resolutions.contains(&r) {
                stored_resolutions.push(r);
            }
        }
        stored_resolutions.sort_unstable_by(|a, b| b.cmp(a));
    }
    for (i, plane) in planes.iter().enumerate() {
        match p.representation {
            Representation::Explicit => {
                let Stored::Explicit(copies) = Stored::explicit(plane, &stored_resolutions) else { unreachable!() };
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
    let manifest = StoredParams {
        k,
        magnify: p.magnify,
        planes: planes.len() as u32,
        representation: p.representation,
        stored_resolutions: if p.representation == Representation::Explicit { stored_resolutions } else { vec![] },
        background,
        order: p.order,
        palette: p.palette,
        tiles: p.tiles,
        seed: p.seed,
        layers: p.layers,
    };
    let json = serde_json::to_value(&manifest).map_err(|e| Error::param("params", e.to_string()))?;
    let mut bundle = Bundle::new(MODEL, name, json);
    sections.sort();
    for (n, d) in sections {
        bundle = bundle.with_section(&n, d);
    }
    load(&bundle)?;
    Ok(bundle)
}

fn check_lcm_size(size: [u32; 2], n: usize) -> Result<()> {
    if size.iter().any(|&s| s == 0 || s > MAX_LCM_SIDE) {
        return Err(Error::param(
            format!("layers[{n}].lcm"),
            format!("LCM size {}×{} is not within 1..={MAX_LCM_SIDE} a side", size[0], size[1]),
        ));
    }
    Ok(())
}

/// Checks an encoding completely and builds its texture.
pub fn load(bundle: &Bundle) -> Result<LcmTexture> {
    let p: StoredParams = bundle.params()?;
    if !(1..=MAX_K).contains(&p.k) {
        return Err(Error::param("k", format!("{}: the base element side must be 2^k with 1 ≤ k ≤ {MAX_K}", p.k)));
    }
    if p.magnify > MAX_TOP - p.k {
        return Err(Error::param("magnify", format!("{}: k + magnify may not exceed {MAX_TOP}", p.magnify)));
    }
    let top = p.k + p.magnify;
    let colour = match (p.planes, p.palette.is_empty()) {
        (1, false) => Colour::palette(&p.palette)?,
        (3, true) => Colour::Channels,
        (1, true) => return Err(Error::param("palette", "one intensity plane needs a palette")),
        (3, false) => return Err(Error::param("palette", "three planes are the RGB channels; no palette")),
        (n, _) => return Err(Error::param("planes", format!("{n}; must be 1 (palette) or 3 (RGB)"))),
    };
    let planes = p.planes as usize;
    if p.background.len() != planes || p.background.iter().any(|b| !b.is_finite() || b.abs() > 1e6) {
        return Err(Error::param("background", format!("needs {planes} finite intensities within ±1e6")));
    }
    let mut expected: Vec<String> = Vec::new();
    // The element.
    let copies = (0..planes)
        .map(|i| {
            let stored = match p.representation {
                Representation::Explicit => {
                    let mut res = p.stored_resolutions.clone();
                    res.sort_unstable_by(|a, b| b.cmp(a));
                    res.dedup();
                    if res.len() != p.stored_resolutions.len() || res.first() != Some(&p.k) || res.contains(&0) {
                        return Err(Error::param(
                            "stored_resolutions",
                            format!("{:?}: distinct resolutions 1..=k that include k = {}", p.stored_resolutions, p.k),
                        ));
                    }
                    let copies = res
                        .iter()
                        .map(|&r| {
                            let name = format!("element.{i}.{r}");
                            let data = bundle.section(&name)?;
                            expected.push(name.clone());
                            Plane::new(1 << r, data.iter().map(|&b| b as i8).collect(), &name)
                        })
                        .collect::<Result<Vec<_>>>()?;
                    Stored::Explicit(copies)
                }
                Representation::Haar => {
                    let name = format!("haar.{i}");
                    let data = bundle.section(&name)?;
                    expected.push(name.clone());
                    let n = 1usize << (2 * p.k);
                    if data.len() != 2 * n {
                        return Err(Error::param(
                            &name,
                            format!("{} bytes; 2^{}×2^{} i16 need {}", data.len(), p.k, p.k, 2 * n),
                        ));
                    }
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
            Ok(Copies::build(&stored, p.k, p.magnify))
        })
        .collect::<Result<Vec<_>>>()?;
    // The layers.
    if p.layers.is_empty() || p.layers.len() > MAX_LAYERS {
        return Err(Error::param("layers", format!("{} layers; 1..={MAX_LAYERS}", p.layers.len())));
    }
    let mut points = 0u64;
    let mut layers = Vec::with_capacity(p.layers.len());
    let mut period = (1u64, 1u64);
    for (n, l) in p.layers.iter().enumerate() {
        let what = format!("layers[{n}]");
        if l.layer >= top {
            return Err(Error::param(
                format!("{what}.layer"),
                format!("layer {} would be below resolution 1 (k + magnify = {top})", l.layer),
            ));
        }
        if !l.weight.is_finite() || l.weight.abs() > MAX_WEIGHT {
            return Err(Error::param(format!("{what}.weight"), format!("{} is not within ±{MAX_WEIGHT}", l.weight)));
        }
        check_lcm_size(l.lcm, n)?;
        let source = match l.share {
            Some(s) if s >= n || p.layers[s].share.is_some() || p.layers[s].lcm != l.lcm => {
                return Err(Error::param(
                    format!("{what}.share"),
                    format!("{s}: must name an earlier layer with an LCM of its own of the same size"),
                ))
            }
            Some(s) => s,
            None => n,
        };
        if let Some(t) = &l.table {
            t.check(l.lcm, &format!("{what}.table"))?;
        }
        let name = format!("lcm.{source}");
        let codes = bundle.section(&name)?;
        let (w, h) = (l.lcm[0] as usize, l.lcm[1] as usize);
        if codes.len() != w * h {
            return Err(Error::param(&name, format!("{} bytes for an LCM of {w}×{h} = {} points", codes.len(), w * h)));
        }
        if source == n {
            expected.push(name.clone());
            points += codes.len() as u64;
            if let Some((at, e)) = codes.iter().enumerate().find_map(|(i, &c)| Event::decode(c).err().map(|e| (i, e))) {
                return Err(Error::param(&name, format!("point ({}, {}): {e}", at % w, at / w)));
            }
        }
        let weight = libm::floor(l.weight * (1u64 << QW) as f64 + 0.5) as i64;
        let layer = Layer::new(l.layer, weight, w, h, codes, planes);
        // The layer's period in pixels: its mask's own period times the point spacing.
        if weight != 0 && layer.codes.iter().any(|&c| c != 0) {
            let (dx, dy) = mask_period(&layer.codes, w, h);
            let spacing = 1u64 << (top - l.layer - 1);
            let too_big = || Error::param("layers", format!("the texture's period exceeds {MAX_SIZE} pixels"));
            period.0 = lcm(period.0, dx * spacing).filter(|&v| v <= MAX_SIZE).ok_or_else(too_big)?;
            period.1 = lcm(period.1, dy * spacing).filter(|&v| v <= MAX_SIZE).ok_or_else(too_big)?;
        }
        layers.push(layer);
    }
    if points > MAX_LCM_POINTS {
        return Err(Error::param("layers", format!("{points} LCM points in all; at most {MAX_LCM_POINTS}")));
    }
    if let Some(extra) = bundle.sections.iter().find(|s| !expected.contains(&s.name)) {
        return Err(Error::bundle(format!("unexpected section `{}` in an lcm encoding", extra.name)));
    }
    if p.order == Order::BottomUp {
        layers.sort_by_key(|l| std::cmp::Reverse(l.index));
    } else {
        layers.sort_by_key(|l| l.index);
    }
    let size = (period.0 * p.tiles[0] as u64, period.1 * p.tiles[1] as u64);
    if p.tiles.contains(&0) || size.0 > MAX_SIZE || size.1 > MAX_SIZE {
        return Err(Error::param(
            "tiles",
            format!(
                "{:?} periods of {}×{}: each at least 1 and at most {MAX_SIZE} px a side",
                p.tiles, period.0, period.1
            ),
        ));
    }
    let background = p.background.iter().map(|b| libm::floor(b * (1u64 << QI) as f64 + 0.5) as i64).collect();
    Ok(LcmTexture { k: p.k, magnify: p.magnify, copies, layers, background, colour, period, size })
}
