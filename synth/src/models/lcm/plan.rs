//! The `lcm` encoding's layout and cost model.
//!
//! Sections:
//! * `element.{p}.{r}` — plane p of the base element at resolution r, 4^r signed bytes
//!   (explicit representation, one per stored resolution), or
//! * `haar.{p}` — the Haar pyramid of plane p, 4^K little-endian i16;
//! * `lcm.{n}` — the LCM of layer n, row-major: one event byte a point, or with §6's zeros
//!   left out ([`packing`](super::packing)).
//!
//! Every field and section is checked here ([`check`], [`plan_create`]'s checks) before
//! `create` or `load` builds anything. The cost model: from the manifest, the section lengths
//! and the LCM bytes (the encoding's few kilobytes of structure, whose own period sets the
//! texture's size), what a loaded texture holds and what its dearest tile and its making cost —
//! before any element copy, layer or summed-area table is built. `create`'s plan draws the LCMs
//! (the encoding itself, at most `MAX_LCM_POINTS` bytes, checked first) to know that period.
//! Constants are work units (≈ 1 ns of one core) per item, calibrated by
//! `examples/cost_calibration.rs`.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::colour::Colour;
use super::element::{self, MAX_K, MAX_TOP};
use super::event::Event;
use super::layer::QW;
use super::packing::{self, MaskCoding};
use super::params::{LayerParams, Params, Representation};
use super::period::{lcm, mask_period};
use crate::bundle::Bundle;
#[cfg(feature = "create")]
use crate::models::Inputs;
use crate::models::{cost, parse_params, Cost, Measure, Plan};
use crate::texture::level_count;
use crate::{Domain, Error, Result};

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
#[cfg(feature = "create")]
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
pub(super) fn quantized_weight(weight: f64) -> i64 {
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
    if p.mask_coding != MaskCoding::Drawn {
        expected
            .extend(p.layers.iter().enumerate().filter(|(_, l)| l.share.is_none()).map(|(n, _)| format!("lcm.{n}")));
    }
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

/// Each layer's own LCM as event bytes, from its section as `p.mask_coding` codes it, or drawn
/// again (`None` for a layer that shares one).
fn masks(p: &Params, bundle: &Bundle) -> Result<Vec<Option<Vec<u8>>>> {
    if p.mask_coding == MaskCoding::Drawn {
        return drawn_lcms(p);
    }
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
                (MaskCoding::Zeros, Some(t)) => packing::unpack(data, t, l.lcm[0] as usize, l.lcm[1] as usize, &name)?,
                (MaskCoding::Zeros, None) => {
                    return Err(Error::param(format!("layers[{n}].table"), "needed to decode a zero-coded LCM"))
                }
                _ => data.to_vec(),
            }))
        })
        .collect()
}

/// A tile's pixels.
const TILE: f64 = 256.0 * 256.0;
/// One layer at one pixel of one plane: natively (up to four replications), or prefiltered
/// from its summed-area table.
const NATIVE: f64 = 50.0;
const PREFILTERED: f64 = 250.0;
/// The background and colour of one pixel.
const PIXEL: f64 = 20.0;
/// One LCM point of a summed-area table (its resolution-1 field, once per plane).
const SAT_POINT: f64 = 400.0;
/// One pixel of one oriented element copy (and its coverage).
const COPY_PIXEL: f64 = 20.0;
/// One LCM point: checking its event and its period when loaded, drawing it when created.
const POINT: f64 = 6.0;
const DRAW_POINT: f64 = 30.0;
/// Fixed work of a load: parsing, the palette table.
const LOAD: f64 = 100_000.0;
/// As `colour`: palette table entries.
const PALETTE_ENTRIES: f64 = 4096.0;

/// What loading `bundle` gives and costs, from its manifest and section bytes.
pub fn plan(bundle: &Bundle) -> Result<Plan> {
    let p: Params = bundle.params()?;
    let c = check(&p, bundle)?;
    let making = if p.mask_coding == MaskCoding::Drawn { Making::LoadDrawing } else { Making::Load };
    Ok(plan_of(&Texture { k: c.k, magnify: p.magnify, planes: c.planes, layers: &p.layers }, c.size, making))
}

/// What `create` gives and costs: the parameters checked, then the LCMs drawn for the period.
#[cfg(feature = "create")]
pub fn plan_create(params: &serde_json::Value, inputs: &Inputs) -> Result<Plan> {
    let p: Params = parse_params(params)?;
    let (k, planes) = element_shape(&p, inputs)?;
    check_derived(&p, k, planes)?;
    if p.magnify > MAX_TOP - k {
        return Err(Error::param("magnify", format!("{}: k + magnify may not exceed {MAX_TOP}", p.magnify)));
    }
    let top = k + p.magnify;
    let background = p.background.clone().unwrap_or_else(|| vec![0.0; planes as usize]);
    colour(planes, &p.palette, &background)?;
    check_layers(&p.layers, top)?;
    let lcms = drawn_lcms(&p)?;
    let period = period(&p.layers, top, |n| {
        Ok(lcms[n].as_deref().expect("`check_layers` lets layers share only an earlier layer's own LCM"))
    })?;
    let size = served_size(period, p.tiles)?;
    Ok(plan_of(&Texture { k, magnify: p.magnify, planes, layers: &p.layers }, size, Making::Create))
}

/// What the cost depends on.
struct Texture<'a> {
    k: u32,
    magnify: u32,
    planes: u32,
    layers: &'a [LayerParams],
}

/// What building the texture does besides loading: `create` draws the LCMs, makes the bundle
/// and loads it; a load of drawn masks draws them.
#[derive(Clone, Copy, PartialEq)]
enum Making {
    #[cfg(feature = "create")]
    Create,
    Load,
    LoadDrawing,
}

fn plan_of(t: &Texture, (width, height): (u64, u64), making: Making) -> Plan {
    let top = t.k + t.magnify;
    let planes = t.planes as f64;
    let levels = level_count(width, height);
    let points = |l: &LayerParams| l.lcm[0] as f64 * l.lcm[1] as f64;
    let sat_points = |l: &LayerParams| (l.lcm[0] as f64 + 1.0) * (l.lcm[1] as f64 + 1.0);
    // A layer renders at resolution top − layer − level; at or below 0 it is prefiltered, and
    // its summed-area tables are built by the first tile that needs them.
    let prefiltered_at = |l: &LayerParams, level: u32| top as i64 - l.layer as i64 - level as i64 <= 0;
    let ever_prefiltered = |l: &&LayerParams| prefiltered_at(l, levels - 1);

    // Resident: per plane, 8 orientations of every resolution up to top (i16 values and u16
    // coverage); per layer its LCM, and per plane a summed-area table (two i64 a point) for
    // layers some level prefilters; the palette table.
    let copies: f64 = (1..=top).map(|r| 8.0 * 4.0 * (1u64 << (2 * r)) as f64).sum::<f64>() * planes;
    let lcms: f64 = t.layers.iter().map(points).sum();
    let sats: f64 = t.layers.iter().filter(ever_prefiltered).map(|l| 16.0 * sat_points(l)).sum::<f64>() * planes;
    let resident = copies + lcms + sats + 3.0 * PALETTE_ENTRIES + 4096.0;
    let resident_why = format!(
        "{} planes × 8 orientations × resolutions 1..={top} (k + magnify) × 4 B + {} layers' LCMs of {lcms} points \
         + summed-area tables of 16 B a point and plane",
        t.planes,
        t.layers.len()
    );

    // A tile at a level: each pixel of each plane takes every layer, natively or prefiltered;
    // a level's first tile also builds the tables of the layers it prefilters.
    let level_work = |level: u32| -> f64 {
        let per_pixel: f64 =
            t.layers.iter().map(|l| if prefiltered_at(l, level) { PREFILTERED } else { NATIVE }).sum::<f64>() * planes;
        let tables: f64 =
            t.layers.iter().filter(|l| prefiltered_at(l, level)).map(|l| SAT_POINT * points(l)).sum::<f64>() * planes;
        TILE * (per_pixel + PIXEL) + tables
    };
    let (tile, worst) = (0..levels).map(|l| (level_work(l), l)).fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
    let tile_why = format!("level {worst} of a 256² tile: 65536 px × {} planes × {} layers", t.planes, t.layers.len());

    // Making it: the element copies, checking every LCM point (its event, its period); `create`
    // draws the points and loads what it made.
    let copy_pixels: f64 = (1..=top).map(|r| 16.0 * (1u64 << (2 * r)) as f64).sum::<f64>() * planes;
    let load = LOAD + COPY_PIXEL * copy_pixels + POINT * lcms;
    let (build, how) = match making {
        #[cfg(feature = "create")]
        Making::Create => (2.0 * load + DRAW_POINT * lcms, " drawn, made and loaded"),
        Making::Load => (load, ""),
        Making::LoadDrawing => (load + DRAW_POINT * lcms, " drawn"),
    };
    let build_why = format!("{} planes × resolutions 1..={top} copied 8 ways + {lcms} LCM points{how}", t.planes);
    Plan {
        width,
        height,
        domain: Domain::Torus,
        animation: None,
        cost: Cost {
            resident_bytes: Measure::new(cost::units(resident), resident_why),
            tile_work: Measure::new(cost::units(tile), tile_why),
            build_work: Measure::new(cost::units(build), build_why),
        },
    }
}
