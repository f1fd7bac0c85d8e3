//! The `lcm` encoding: manifest parameters plus binary sections, and its two directions —
//! [`create`] (base element + event tables → LCMs drawn with a seed) and [`load`] (every
//! field and byte checked before a texture is built).
//!
//! Sections:
//! * `element.{p}.{r}` — plane p of the base element at resolution r, 4^r signed bytes
//!   (explicit representation, one per stored resolution), or
//! * `haar.{p}` — the Haar pyramid of plane p, 4^K little-endian i16;
//! * `lcm.{n}` — the LCM of layer n, row-major: one event byte a point, or with §6's zeros
//!   left out ([`packing`]).

use super::colour::{Colour, QI};
use super::element::{self, Copies, Plane, Stored, MAX_K, MAX_TOP};
use super::event::Event;
use super::haar;
use super::layer::{Layer, QW};
use super::packing::{self, MaskCoding};
use super::period::{lcm, mask_period};
use super::render::LcmTexture;
use super::{elements, MODEL};

pub use super::params::{Builtin, LayerParams, Order, Params, Representation};
use crate::bundle::Bundle;
use crate::models::{input_image, parse_params, Inputs};
use crate::{Error, Result, Rgba8Image};

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

/// The side exponent K and plane count of the element `create` would use, checked from the
/// parameters and the input image's header, without drawing or decoding it.
pub(super) fn element_shape(p: &Params, inputs: &Inputs) -> Result<(u32, u32)> {
    let Some(b) = &p.element else {
        let bytes = inputs.get("element").ok_or_else(|| Error::image("element", "missing; this model needs it"))?;
        let (w, h) = crate::pixels::png_dimensions("element", bytes)?;
        if w != h {
            return Err(Error::image("element", format!("{w}×{h} is not square")));
        }
        let k = element::side_exponent(w as usize, "element").map_err(|e| Error::image("element", e.to_string()))?;
        return Ok((k, if p.palette.is_empty() { 3 } else { 1 }));
    };
    let k = element::side_exponent(1usize.checked_shl(b.k).unwrap_or(0), "element.k")?;
    let (min_k, planes) = match b.builtin.as_str() {
        "stroke" | "hole" => (1, 1),
        "brick" => (3, 1),
        "pebble" => (1, 3),
        other => {
            return Err(Error::param("element.builtin", format!("`{other}` is none of stroke, hole, brick, pebble")))
        }
    };
    if k < min_k {
        return Err(Error::param("element.k", format!("`{}` needs k ≥ {min_k}", b.builtin)));
    }
    Ok((k, planes))
}

/// The element planes of a built-in that [`element_shape`] accepted.
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

/// Checks the derived fields `create` is given (a stored manifest posted back) against what
/// it derives from the element of side 2^`k` with `planes` planes.
pub(super) fn check_derived(p: &Params, k: u32, planes: u32) -> Result<()> {
    let disagree = |name: &str, given: String, derived: String| {
        Err(Error::param(name, format!("{given} disagrees with {derived}, what the element and layers give")))
    };
    if let Some(given) = p.k.filter(|&g| g != k) {
        return disagree("k", given.to_string(), k.to_string());
    }
    if let Some(given) = p.planes.filter(|&g| g != planes) {
        return disagree("planes", given.to_string(), planes.to_string());
    }
    let resolutions = if p.representation == Representation::Explicit { stored_resolutions(p, k) } else { Vec::new() };
    if !p.stored_resolutions.is_empty() && p.stored_resolutions != resolutions {
        return disagree("stored_resolutions", format!("{:?}", p.stored_resolutions), format!("{resolutions:?}"));
    }
    Ok(())
}

/// A derived field a stored manifest must carry.
fn stored<T: Clone>(value: &Option<T>, name: &str) -> Result<T> {
    value.clone().ok_or_else(|| Error::param(name, "must be set in a stored encoding"))
}

/// The resolutions an explicit element stores: K and those the layers use at level 0.
pub(super) fn stored_resolutions(p: &Params, k: u32) -> Vec<u32> {
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
    stored_resolutions
}

/// Each layer's LCM drawn from its table with the seed (`None` for a layer that shares one).
/// Callers check the layers first ([`check_layers`]), which bounds what this draws.
pub(super) fn drawn_lcms(p: &Params) -> Result<Vec<Option<Vec<u8>>>> {
    p.layers
        .iter()
        .enumerate()
        .map(|(n, l)| {
            if l.share.is_some() {
                return Ok(None);
            }
            let what = format!("layers[{n}].table");
            let table = l.table.as_ref().ok_or_else(|| Error::param(&what, "needed to draw the LCM"))?;
            Ok(Some(table.generate(l.lcm, p.seed, n as u64)))
        })
        .collect()
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

/// Checks every layer's parameters — count, resolution, weight, LCM size, sharing, table —
/// and the LCM points they hold in all, from the parameters alone; returns that count.
pub(super) fn check_layers(layers: &[LayerParams], top: u32) -> Result<u64> {
    if layers.is_empty() || layers.len() > MAX_LAYERS {
        return Err(Error::param("layers", format!("{} layers; 1..={MAX_LAYERS}", layers.len())));
    }
    let mut points = 0u64;
    for (n, l) in layers.iter().enumerate() {
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
        match l.share {
            Some(s) if s >= n || layers[s].share.is_some() || layers[s].lcm != l.lcm => {
                return Err(Error::param(
                    format!("{what}.share"),
                    format!("{s}: must name an earlier layer with an LCM of its own of the same size"),
                ))
            }
            Some(_) => {}
            None => points += l.lcm[0] as u64 * l.lcm[1] as u64,
        }
        if let Some(t) = &l.table {
            t.check(l.lcm, &format!("{what}.table"))?;
        }
    }
    if points > MAX_LCM_POINTS {
        return Err(Error::param("layers", format!("{points} LCM points in all; at most {MAX_LCM_POINTS}")));
    }
    Ok(points)
}

/// A layer weight in fixed point (Q12).
fn quantized_weight(weight: f64) -> i64 {
    libm::floor(weight * (1u64 << QW) as f64 + 0.5) as i64
}

/// The texture's period in pixels from layers that passed [`check_layers`] and their LCMs
/// (`codes(n)`: layer n's own, or the one it shares): each LCM's length and events checked,
/// and the least common multiple of every visible layer's mask period times its spacing.
pub(super) fn period<'a>(
    layers: &[LayerParams],
    top: u32,
    codes: impl Fn(usize) -> Result<&'a [u8]>,
) -> Result<(u64, u64)> {
    let mut period = (1u64, 1u64);
    for (n, l) in layers.iter().enumerate() {
        let source = l.share.unwrap_or(n);
        let name = format!("lcm.{source}");
        let codes = codes(source)?;
        let (w, h) = (l.lcm[0] as usize, l.lcm[1] as usize);
        if codes.len() != w * h {
            return Err(Error::param(&name, format!("{} bytes for an LCM of {w}×{h} = {} points", codes.len(), w * h)));
        }
        if source == n {
            if let Some((at, e)) = codes.iter().enumerate().find_map(|(i, &c)| Event::decode(c).err().map(|e| (i, e))) {
                return Err(Error::param(&name, format!("point ({}, {}): {e}", at % w, at / w)));
            }
        }
        if quantized_weight(l.weight) != 0 && codes.iter().any(|&c| Event::canonical(c) != 0) {
            let (dx, dy) = mask_period(codes, w, h);
            let spacing = 1u64 << (top - l.layer - 1);
            let too_big = || Error::param("layers", format!("the texture's period exceeds {MAX_SIZE} pixels"));
            period.0 = lcm(period.0, dx * spacing).filter(|&v| v <= MAX_SIZE).ok_or_else(too_big)?;
            period.1 = lcm(period.1, dy * spacing).filter(|&v| v <= MAX_SIZE).ok_or_else(too_big)?;
        }
    }
    Ok(period)
}

/// The served size: `tiles` periods, each side within [`MAX_SIZE`].
pub(super) fn served_size(period: (u64, u64), tiles: [u32; 2]) -> Result<(u64, u64)> {
    let size = (period.0 * tiles[0] as u64, period.1 * tiles[1] as u64);
    if tiles.contains(&0) || size.0 > MAX_SIZE || size.1 > MAX_SIZE {
        return Err(Error::param(
            "tiles",
            format!(
                "{:?} periods of {}×{}: each at least 1 and at most {MAX_SIZE} px a side",
                tiles, period.0, period.1
            ),
        ));
    }
    Ok(size)
}

/// How intensities become colour, checked with the background against the plane count.
pub(super) fn colour(planes: u32, palette: &[[f64; 4]], background: &[f64]) -> Result<Colour> {
    let colour = match (planes, palette.is_empty()) {
        (1, false) => Colour::palette(palette)?,
        (3, true) => Colour::Channels,
        (1, true) => return Err(Error::param("palette", "one intensity plane needs a palette")),
        (3, false) => return Err(Error::param("palette", "three planes are the RGB channels; no palette")),
        (n, _) => return Err(Error::param("planes", format!("{n}; must be 1 (palette) or 3 (RGB)"))),
    };
    let planes = planes as usize;
    if background.len() != planes || background.iter().any(|b| !b.is_finite() || b.abs() > 1e6) {
        return Err(Error::param("background", format!("needs {planes} finite intensities within ±1e6")));
    }
    Ok(colour)
}

/// The checked shape of a stored encoding: its derived fields, colour, period and served size, and the
/// element's stored resolutions (explicit only), from the manifest and section bytes.
pub(super) struct Checked {
    pub k: u32,
    pub planes: u32,
    pub background: Vec<f64>,
    pub colour: Colour,
    pub period: (u64, u64),
    pub size: (u64, u64),
    pub resolutions: Vec<u32>,
    /// Each layer's own LCM, unpacked (`None` where it shares one).
    pub masks: Vec<Option<Vec<u8>>>,
}

/// Checks a stored encoding's manifest and every section's length and LCM bytes, before any
/// element copy or layer is built.
pub(super) fn check(p: &Params, bundle: &Bundle) -> Result<Checked> {
    let (k, planes) = (stored(&p.k, "k")?, stored(&p.planes, "planes")?);
    if !(1..=MAX_K).contains(&k) {
        return Err(Error::param("k", format!("{k}: the base element side must be 2^k with 1 ≤ k ≤ {MAX_K}")));
    }
    if p.magnify > MAX_TOP - k {
        return Err(Error::param("magnify", format!("{}: k + magnify may not exceed {MAX_TOP}", p.magnify)));
    }
    let top = k + p.magnify;
    let background = stored(&p.background, "background")?;
    let colour = colour(planes, &p.palette, &background)?;
    let mut expected: Vec<String> = Vec::new();
    let mut resolutions = p.stored_resolutions.clone();
    resolutions.sort_unstable_by(|a, b| b.cmp(a));
    resolutions.dedup();
    for i in 0..planes {
        match p.representation {
            Representation::Explicit => {
                if resolutions.len() != p.stored_resolutions.len()
                    || resolutions.first() != Some(&k)
                    || resolutions.contains(&0)
                {
                    return Err(Error::param(
                        "stored_resolutions",
                        format!("{:?}: distinct resolutions 1..=k that include k = {k}", p.stored_resolutions),
                    ));
                }
                for &r in &resolutions {
                    let name = format!("element.{i}.{r}");
                    let len = bundle.section(&name)?.len();
                    if len != 1 << (2 * r) {
                        return Err(Error::param(&name, format!("{len} pixels for a {0}×{0} element", 1u32 << r)));
                    }
                    expected.push(name);
                }
            }
            Representation::Haar => {
                let name = format!("haar.{i}");
                let len = bundle.section(&name)?.len();
                let n = 1usize << (2 * k);
                if len != 2 * n {
                    return Err(Error::param(&name, format!("{len} bytes; 2^{k}×2^{k} i16 need {}", 2 * n)));
                }
                expected.push(name);
            }
        }
    }
    check_layers(&p.layers, top)?;
    expected.extend(p.layers.iter().enumerate().filter(|(_, l)| l.share.is_none()).map(|(n, _)| format!("lcm.{n}")));
    if let Some(extra) = bundle.sections.iter().find(|s| !expected.contains(&s.name)) {
        return Err(Error::bundle(format!("unexpected section `{}` in an lcm encoding", extra.name)));
    }
    let masks = masks(p, bundle)?;
    let period = period(&p.layers, top, |n| {
        Ok(masks[n].as_deref().expect("`check_layers` lets layers share only an earlier layer's own LCM"))
    })?;
    let size = served_size(period, p.tiles)?;
    Ok(Checked { k, planes, background, colour, period, size, resolutions, masks })
}

/// Each layer's own LCM as event bytes, from its section as `p.mask_coding` codes it (`None`
/// for a layer that shares one).
fn masks(p: &Params, bundle: &Bundle) -> Result<Vec<Option<Vec<u8>>>> {
    p.layers
        .iter()
        .enumerate()
        .map(|(n, l)| {
            if l.share.is_some() {
                return Ok(None);
            }
            let name = format!("lcm.{n}");
            let data = bundle.section(&name)?;
            Ok(Some(match (p.mask_coding, &l.table) {
                (MaskCoding::Raw, _) => data.to_vec(),
                (MaskCoding::Zeros, Some(t)) => packing::unpack(data, t, l.lcm[0] as usize, l.lcm[1] as usize, &name)?,
                (MaskCoding::Zeros, None) => {
                    return Err(Error::param(format!("layers[{n}].table"), "needed to decode a zero-coded LCM"))
                }
            }))
        })
        .collect()
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
