//! The `lcm` cost model: from the manifest, the section lengths and the LCM bytes (the
//! encoding's few kilobytes of structure, whose own period sets the texture's size), what a
//! loaded texture holds and what its dearest tile and its making cost — before any element
//! copy, layer or summed-area table is built. `create`'s plan draws the LCMs (the encoding
//! itself, at most `MAX_LCM_POINTS` bytes, checked first) to know that period. Constants are
//! work units (≈ 1 ns of one core) per item, calibrated by `examples/cost_calibration.rs`.

use super::element::MAX_TOP;
use super::encoding::{self, check, check_derived, check_layers, colour, drawn_lcms, element_shape, LayerParams};
use super::params::Params;
use crate::bundle::Bundle;
use crate::models::{cost, parse_params, Cost, Inputs, Measure, Plan};
use crate::texture::level_count;
use crate::{Domain, Error, Result};

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
    Ok(plan_of(&Texture { k: c.k, magnify: p.magnify, planes: c.planes, layers: &p.layers }, c.size, false))
}

/// What `create` gives and costs: the parameters checked, then the LCMs drawn for the period.
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
    let period = encoding::period(&p.layers, top, |n| {
        Ok(lcms[n].as_deref().expect("`check_layers` lets layers share only an earlier layer's own LCM"))
    })?;
    let size = encoding::served_size(period, p.tiles)?;
    Ok(plan_of(&Texture { k, magnify: p.magnify, planes, layers: &p.layers }, size, true))
}

/// What the cost depends on.
struct Texture<'a> {
    k: u32,
    magnify: u32,
    planes: u32,
    layers: &'a [LayerParams],
}

fn plan_of(t: &Texture, (width, height): (u64, u64), create: bool) -> Plan {
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
    let build = if create { 2.0 * load + DRAW_POINT * lcms } else { load };
    let build_why = format!(
        "{} planes × resolutions 1..={top} copied 8 ways + {lcms} LCM points{}",
        t.planes,
        if create { " drawn, made and loaded" } else { "" }
    );
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
