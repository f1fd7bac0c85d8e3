//! The `patterns` encoding's limits and checks, and its cost model: from the manifest, the
//! section lengths and the reference's PNG header, what a loaded texture holds and what its
//! dearest tile and its making cost, before the reference is decoded or its mip chains built. An animated texture's period comes from
//! its animation maps (small value maps, read as `load` reads them). Constants are work units
//! (≈ 1 ns of one core) per item, calibrated by `examples/cost_calibration.rs`.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::animation::{AnimationBlock, Context};
use super::params::{Choice, LayerKind, LayerParams, Params, ValueParams};
use super::random::LayerRng;
use super::sigma::{self, RangeTable, Sigma};
use super::transform::TransformBlock;
use super::{pixel_map, sprites, MODEL};
use crate::bundle::Bundle;
#[cfg(feature = "create")]
use crate::models::Inputs;
use crate::models::{cost, parse_params, Cost, Measure, Plan};
use crate::pixels::png_dimensions;
use crate::texture::level_count;
use crate::{Animation, Domain, Error, Result};
use std::sync::Arc;

/// Largest side of a texture, in pixels.
pub const MAX_SIDE: u64 = 1 << 24;
pub const MAX_LAYERS: usize = 8;

/// A tile's pixels.
const TILE: f64 = 256.0 * 256.0;
/// Filling a pixel with the background.
const PIXEL: f64 = 1.0;
/// One cell's pattern texel of a tiling layer (choosing the cell's pattern once a run).
const TEXEL: f64 = 100.0;
/// One cell mean of a coarse tiling level (its pattern chosen, its mean read).
const CELL: f64 = 700.0;
/// One bilinear read of a sparse layer's cell, or a sprite's.
const BILINEAR: f64 = 60.0;
/// The expected colour of a coarse sparse pixel, or a sprite's splat.
const EXPECTED: f64 = 200.0;
/// Recording one cell of a moving sprite in a positioning map.
const MAP_CELL: f64 = 100.0;
/// Decoding the reference and building its mip chains, per pixel; encoding it in `create`.
const REFERENCE_PIXEL: f64 = 40.0;
const ENCODE_PIXEL: f64 = 60.0;
/// Reading one byte of a map or table section.
const SECTION_BYTE: f64 = 10.0;
/// Fixed work of a load: parsing, the permutation tables.
const LOAD: f64 = 200_000.0;
/// Cells per pixel side up to which coarse tiling levels combine cell means (`model`).
const OVERSAMPLE: u64 = 4;

/// What loading `bundle` gives and costs, from its manifest, section lengths and the
/// reference's header.
pub fn plan(bundle: &Bundle) -> Result<Plan> {
    let p: Params = bundle.params()?;
    plan_of(&p, bundle, false)
}

/// What `create` gives and costs: the bundle it would make, less the pixels — the reference
/// kept as given (only its header is read) and the animation maps among the inputs, as
/// `create` stores them.
#[cfg(feature = "create")]
pub fn plan_create(params: &serde_json::Value, inputs: &Inputs) -> Result<Plan> {
    let p: Params = parse_params(params)?;
    let reference = inputs.get("reference").ok_or_else(|| Error::image("reference", "missing; this model needs it"))?;
    let bundle = Bundle::new(MODEL, "plan", params.clone())
        .with_section("reference.png", reference.clone())
        .with_section("sigma", sigma::to_bytes(&tables(&p)));
    let mut bundle = with_range_tables(bundle, &p);
    let maps = p
        .layers
        .iter()
        .filter_map(|l| l.animation.as_ref())
        .flat_map(|a| a.values().filter_map(|v: &ValueParams| v.map.as_ref()));
    for section in maps.filter_map(|m| m.section.as_deref()) {
        if let Some(bytes) = inputs.get(section) {
            let data = map_section(section, bytes, &[])?;
            bundle = bundle.with_section(section, data);
        }
    }
    plan_of(&p, &bundle, true)
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

/// The permutation tables `create` generates for `p`.
pub(super) fn tables(p: &Params) -> Vec<Sigma> {
    sigma::generate_all(p.reference[0].clamp(1, 256), p.reference[1].clamp(1, 256), p.seed)
}

/// The range tables `create` stores for `p`: one per range its probability maps and random
/// values draw from that does not divide the random tables (none for most encodings).
pub(super) fn range_tables(p: &Params) -> Vec<RangeTable> {
    let mut ranges: Vec<u32> = Vec::new();
    for l in &p.layers {
        if let Some(Choice::Materials { materials, .. }) = &l.choice {
            ranges.extend(materials.iter().map(|m| m.patterns.len() as u32));
        }
        if let Some(a) = &l.animation {
            ranges.extend(a.ranges());
        }
    }
    ranges.retain(|&m| sigma::needs_range_table(m) && m <= sigma::MAX_RANGE);
    super::animation::distinct(ranges.into_iter()).into_iter().map(|m| RangeTable::generate(m, p.seed)).collect()
}

/// `bundle` with the range tables `p` needs, when it needs any.
pub(super) fn with_range_tables(bundle: Bundle, p: &Params) -> Bundle {
    let ranges = range_tables(p);
    if ranges.is_empty() {
        bundle
    } else {
        bundle.with_section(sigma::RANGES_SECTION, sigma::ranges_to_bytes(&ranges))
    }
}

/// Checks the reference's shape: `tx × ty` patterns of side `size` (a power of two up to
/// 1024) packed in a `width × height` image.
pub(super) fn check_reference(width: u32, height: u32, size: u32, tx: u32, ty: u32) -> Result<()> {
    if size == 0 || !size.is_power_of_two() || size > 1024 {
        return Err(Error::param(
            "pattern_size",
            format!("{size}: must be a power of two up to 1024 (each pattern has its own mip chain)"),
        ));
    }
    if tx == 0 || ty == 0 || tx > 256 || ty > 256 {
        return Err(Error::param("reference", format!("{tx}×{ty} patterns: each side must be 1..=256")));
    }
    if width != tx * size || height != ty * size {
        return Err(Error::image(
            "reference",
            format!("{width}×{height} pixels; {tx}×{ty} patterns of {size}² need {}×{}", tx * size, ty * size),
        ));
    }
    Ok(())
}

/// How the texture moves: the periods of its animated layers and moving sprites combined
/// (0 when one never repeats or the least common multiple passes `u32`), at `fps` frames a
/// second.
pub(super) fn animation(periods: &[u64], fps: Option<f32>) -> Result<Option<Animation>> {
    match (periods.is_empty(), fps) {
        (true, _) => Ok(None),
        (false, Some(fps)) if fps > 0.0 && fps <= 240.0 => {
            let mut period = 1u64;
            for &q in periods {
                period = if q == 0 || period == 0 { 0 } else { period / gcd(period, q) * q };
                if period > u32::MAX as u64 {
                    period = 0;
                }
            }
            Ok(Some(Animation { fps, period_frames: period as u32 }))
        }
        (false, _) => Err(Error::param("fps", "animated layers and moving sprites need fps in (0, 240]")),
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// `e` as an error of layer `i`'s parameters.
pub(super) fn in_layer(i: usize, e: Error) -> Error {
    match e {
        Error::Param { name, reason } => Error::param(format!("layers[{i}].{name}"), reason),
        other => other,
    }
}

fn plan_of(p: &Params, bundle: &Bundle, create: bool) -> Result<Plan> {
    if p.width == 0 || p.height == 0 || p.width > MAX_SIDE || p.height > MAX_SIDE {
        return Err(Error::param(
            "width/height",
            format!("{}×{}: each side must be 1..={MAX_SIDE}", p.width, p.height),
        ));
    }
    let (rw, rh) = png_dimensions("reference", bundle.section("reference.png")?)?;
    check_reference(rw, rh, p.pattern_size, p.reference[0], p.reference[1])?;
    let sigma_bytes = bundle.section("sigma")?;
    let tables: Arc<[Sigma]> = sigma::from_bytes(sigma_bytes)?.into();
    let ranges = sigma::ranges_of(bundle)?;
    if p.layers.is_empty() || p.layers.len() > MAX_LAYERS {
        return Err(Error::param("layers", format!("{} layers; 1..={MAX_LAYERS}", p.layers.len())));
    }
    sprites::check_layers(&p.sprites, &p.layers)?;
    let count = p.reference[0] * p.reference[1];
    let mut animated = Vec::new();
    let mut transforms = Vec::new();
    for (i, lp) in p.layers.iter().enumerate() {
        let c = lp.cell as u64;
        if c == 0 || p.width % c != 0 || p.height % c != 0 {
            let e = Error::param(
                "cell",
                format!(
                    "{c} px cells do not divide the {}×{} texture (the virtual tile map must tile it)",
                    p.width, p.height
                ),
            );
            return Err(in_layer(i, e));
        }
        let grid = (p.width / c, p.height / c);
        if let Some(a) = &lp.animation {
            let rng = LayerRng::new(tables.clone(), i, grid).with_ranges(ranges.clone());
            let cx = Context {
                params: p,
                bundle,
                cell: lp.cell,
                grid,
                patterns: count,
                allow_blank: lp.kind == LayerKind::Sparse,
            };
            animated.push(AnimationBlock::load(a, &cx, &rng).map_err(|e| in_layer(i, e))?);
        }
        let load = if lp.kind == LayerKind::Sprites { TransformBlock::for_sprites } else { TransformBlock::load };
        transforms.push(lp.transform.as_ref().map(load).transpose().map_err(|e| in_layer(i, e))?);
    }
    let mut periods: Vec<u64> = animated.iter().filter_map(AnimationBlock::period).collect();
    periods.extend(sprites::moving_periods(&p.sprites, (p.width, p.height)));
    let animation = animation(&periods, p.fps)?;

    let ref_px = rw as f64 * rh as f64;
    let log2 = p.pattern_size.trailing_zeros();
    let levels = level_count(p.width, p.height);
    // Resident: the reference's mip chains (a third more than its pixels) and pattern means,
    // the permutation tables, every map section as 16-bit values, what the parameters list
    // (materials, sequences, inline maps, sprites: bounded by the manifest's own bytes), and a
    // little per layer.
    let maps: f64 = bundle
        .sections
        .iter()
        .filter(|s| s.name != "reference.png" && s.name != "sigma")
        .map(|s| s.data.len() as f64)
        .sum();
    // Every use of a map in an animation holds its own 16-bit copy (a ramp reads one Z map
    // in several segments).
    let value_maps: f64 = p
        .layers
        .iter()
        .filter_map(|l| l.animation.as_ref())
        .flat_map(|a| a.values().filter_map(|v| v.map.as_ref()))
        .map(|m| 2.0 * m.size[0] as f64 * m.size[1] as f64)
        .sum();
    // The parameters' JSON as the manifest holds them (given and derived), not `p` written
    // again: a render-only build then serializes no parameter type.
    let manifest = serde_json::to_vec(&bundle.manifest.full_params()?).map_or(0, |m| m.len()) as f64;
    let resident = 4.0 * ref_px * 4.0 / 3.0
        + value_maps
        + 16.0 * count as f64
        + 2.0 * sigma_bytes.len() as f64
        + 2.0 * maps
        + 8.0 * manifest
        + 128.0 * p.sprites.len() as f64
        + 1024.0 * p.layers.len() as f64
        + 4096.0;
    let resident_why =
        format!(
        "reference {rw}×{rh} × 4 B × 4/3 (mip chains) + {maps} B of maps × 2 + {value_maps} B of animation maps + {} layers",
        p.layers.len()
    );

    // A tile: per pixel and layer, a tiling layer reads one texel (its transition overlays
    // too) while a pattern covers pixels, then up to 4 × 4 cell means; a sparse layer reads
    // every neighbour cell a pattern may overflow from, then up to 4 × 4 cell means; sprites
    // read one pattern, then splat each sprite.
    let layer_work = |lp: &LayerParams, t: &Option<TransformBlock>, level: u32| -> f64 {
        match lp.kind {
            LayerKind::Tiling => {
                let overlays = if lp.transitions.is_some() { 4.0 } else { 1.0 };
                if level <= log2 {
                    TILE * TEXEL * overlays
                } else {
                    let k = 1u64 << (level - log2).min(32);
                    let cells = if k <= OVERSAMPLE { (k * k) as f64 * 4.0 / 3.0 } else { 16.0 };
                    TILE * CELL * cells * overlays
                }
            }
            LayerKind::Sparse => {
                let f = (1u64 << level.min(62)) as f64;
                if f * 4.0 > lp.cell as f64 {
                    // Up to 4 × 4 cells are read, then a static layer's expected colour.
                    let expected = if lp.animation.is_some() { 0.0 } else { 1.0 };
                    TILE * EXPECTED * ((OVERSAMPLE * OVERSAMPLE) as f64 + expected)
                } else {
                    let reach = t.as_ref().map_or(1, |t| t.left + t.right + 1) as f64;
                    TILE * BILINEAR * reach * reach
                }
            }
            LayerKind::Sprites => {
                // A sprite's box is at most 4 √2 patterns wide once transformed; a positioning
                // map is rebuilt a tile when sprites move.
                let side = |unit: f64| 4.0 * std::f64::consts::SQRT_2 * p.pattern_size as f64 / unit + 2.0;
                let n = p.sprites.len() as f64;
                let moving = p.sprites.values().any(|s| s.velocity != [0, 0]);
                let rebuild = if moving { MAP_CELL * n * side(lp.cell as f64).powi(2) } else { 0.0 };
                let draw = if level <= log2 {
                    TILE * BILINEAR
                } else {
                    EXPECTED * n * side((1u64 << level.min(62)) as f64).powi(2)
                };
                draw + rebuild
            }
        }
    };
    let level_work = |level: u32| -> f64 {
        TILE * PIXEL + p.layers.iter().zip(&transforms).map(|(lp, t)| layer_work(lp, t, level)).sum::<f64>()
    };
    let (tile, worst) = (0..levels).map(|l| (level_work(l), l)).fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
    let tile_why = format!("level {worst} of a 256² tile: 65536 px × {} layers", p.layers.len());

    // Making it: decoding the reference and building its mip chains, reading the tables and
    // maps; `create` also encodes the reference and the maps and loads what it made.
    let load = LOAD + REFERENCE_PIXEL * ref_px + SECTION_BYTE * (sigma_bytes.len() as f64 + maps);
    let build = if create { 2.0 * load + ENCODE_PIXEL * ref_px } else { load };
    let build_why = format!(
        "reference {rw}×{rh} decoded and mip-mapped + {maps} B of maps{}",
        if create { ", made and loaded" } else { "" }
    );
    Ok(Plan {
        width: p.width,
        height: p.height,
        domain: Domain::Torus,
        animation,
        cost: Cost {
            resident_bytes: Measure::new(cost::units(resident), resident_why),
            tile_work: Measure::new(cost::units(tile), tile_why),
            build_work: Measure::new(cost::units(build), build_why),
        },
    })
}
