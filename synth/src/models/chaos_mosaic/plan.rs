//! The chaos mosaic's cost model: from the parameters and the sample's PNG header, what a
//! loaded mosaic holds and what its dearest tile and its making cost, before anything is
//! decoded, generated or indexed. Constants are work units (≈ 1 ns of one core) per item,
//! calibrated by `examples/cost_calibration.rs`.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::blocks::SizeRule;
use super::params::{self, Params, Sequence};
use super::sums::PeriodicSums;
use crate::bundle::Bundle;
#[cfg(feature = "create")]
use crate::models::Inputs;
use crate::models::{cost, parse_params, Cost, Measure, Plan};
use crate::pixels::png_dimensions;
use crate::texture::level_count;
use crate::{Domain, Error, Result};

/// The bundle's sections: the sample as given, and the explicit block sequence when there is one.
pub(super) const SAMPLE_SECTION: &str = "sample.png";
pub(super) const BLOCKS_SECTION: &str = "blocks";

/// Refuses a `width × height` sample for an explicit sequence when its records cannot hold it.
pub(super) fn check_explicit_sample(width: u32, height: u32) -> Result<()> {
    let max = params::MAX_EXPLICIT_SAMPLE_SIDE;
    if width > max || height > max {
        return Err(Error::param(
            "sequence",
            format!("explicit 12-byte blocks need a sample of at most {max}×{max}; use \"seed\" for {width}×{height}"),
        ));
    }
    Ok(())
}

/// Pixels of one tile.
const TILE: f64 = 256.0 * 256.0;
/// Level 0, per pixel: the plain tiling, each block a tile pastes over it, and per filtered
/// pixel on each side of a seam.
const PIXEL: f64 = 4.0;
const BLOCK_PIXEL: f64 = 6.0;
const FILTER_PIXEL: f64 = 2.0;
/// Level 1 renders 2 × 2 level-0 tiles and box-filters them.
const DOWNSAMPLE_PIXEL: f64 = 2.0;
/// Prefiltered levels, per pixel: the footprint's cells (at most 4 × 4), each a box sum per
/// layer over it.
const CELL: f64 = 100.0;
const FOOTPRINT_CELLS: f64 = 16.0;
/// Building one box table, per sample pixel (they are filled on a level's first tile).
const TABLE_PIXEL: f64 = 40.0;
/// Decoding, summing and copying the sample, per pixel; encoding it as PNG in `create`.
const SAMPLE_PIXEL: f64 = 30.0;
const ENCODE_PIXEL: f64 = 60.0;
/// One block: drawing it, moving it by the cat map's matrix power, grouping and indexing it;
/// blocks beyond what the caches hold (about `CACHED_BLOCKS`) add a miss at each of those steps.
const BLOCK: f64 = 300.0;
const BLOCK_MISS: f64 = 4000.0;
const CACHED_BLOCKS: f64 = 131_072.0;

/// The texture's parts of fixed size (its parameters, the table slots, the allocations' rounding).
const FIXED: f64 = 65536.0;
/// The size of box table the prefiltered levels use at most, as in `prefilter::BoxTables`.
const TABLE_SIDES: u32 = 13;
/// Samples up to this many pixels get box tables, as `prefilter::BoxTable` decides.
const TABLE_MAX_PIXELS: u64 = 1 << 18;

/// What loading `bundle` gives and costs, from its manifest and the sample's header.
pub fn plan(bundle: &Bundle) -> Result<Plan> {
    if let Some(s) = bundle.sections.iter().find(|s| s.name != SAMPLE_SECTION && s.name != BLOCKS_SECTION) {
        return Err(Error::bundle(format!("unexpected section `{}`", s.name)));
    }
    let p: Params = bundle.params()?;
    if p.seamless.is_none() {
        return Err(Error::param("seamless", "must be set in a stored encoding"));
    }
    let (sw, sh) = png_dimensions(SAMPLE_SECTION, bundle.section(SAMPLE_SECTION)?)?;
    let plan = plan_params(&p, sw, sh, false)?;
    let explicit = bundle.sections.iter().find(|s| s.name == BLOCKS_SECTION);
    match (p.sequence, explicit) {
        (Sequence::Seed, Some(_)) => Err(Error::bundle("section `blocks` present for a seed-derived sequence")),
        (Sequence::Explicit, None) => Err(Error::bundle("missing section `blocks`")),
        _ => Ok(plan),
    }
}

/// What `create` gives and costs, from the parameters and the sample's header.
#[cfg(feature = "create")]
pub fn plan_create(params: &serde_json::Value, inputs: &Inputs) -> Result<Plan> {
    let p: Params = parse_params(params)?;
    p.validate()?;
    let sample = inputs.get("sample").ok_or_else(|| Error::image("sample", "missing; this model needs it"))?;
    let (sw, sh) = png_dimensions("sample", sample)?;
    plan_params(&p, sw, sh, true)
}

fn blocks(p: &Params) -> u64 {
    p.tiles_x as u64 * p.tiles_y as u64 * p.blocks_per_tile as u64
}

/// Checks what `create` and `load` check before building, then counts the cost; `create`
/// adds measuring the seams, encoding the sample and the load it ends with.
fn plan_params(p: &Params, sw: u32, sh: u32, create: bool) -> Result<Plan> {
    p.validate()?;
    if p.sequence == Sequence::Explicit {
        check_explicit_sample(sw, sh)?;
    }
    let (width, height) = (p.tiles_x as u64 * sw as u64, p.tiles_y as u64 * sh as u64);
    if width > params::MAX_SIDE || height > params::MAX_SIDE {
        return Err(Error::param("tiles_x/tiles_y", format!("texture {width}×{height} exceeds {}", params::MAX_SIDE)));
    }
    SizeRule::new(sw, sh, p)?;
    let n = blocks(p) as f64;
    let tiles = p.tiles_x as f64 * p.tiles_y as f64;
    let px = sw as f64 * sh as f64;
    let levels = level_count(width, height);

    // Resident: the sample (RGBA8) and its prefix sums, the blocks with their sequence
    // numbers, the index (each block lists in at most 4 tiles), and the box tables of the
    // prefiltered levels (one per power-of-two side a level uses).
    let sums = PeriodicSums::bytes_for(sw as u64, sh as u64) as f64;
    let structure = 20.0 * n + 16.0 * n + 8.0 * (tiles + 1.0);
    let table_sides = TABLE_SIDES.min(levels);
    let tables = match sw as u64 * sh as u64 <= TABLE_MAX_PIXELS {
        true => (0..table_sides).map(|k| table_bytes(sw, sh, k)).sum(),
        false => 0.0,
    };
    let resident = 4.0 * px + sums + structure + tables + FIXED;
    let resident_why = format!(
        "sample {sw}×{sh} × (4 + 10) B + {n} blocks (tiles_x {} × tiles_y {} × blocks_per_tile {}) × 36 B \
         + {table_sides} box tables of the sample",
        p.tiles_x, p.tiles_y, p.blocks_per_tile
    );

    // A tile: level 0 pastes every block over its pixels (blocks_per_tile of at most a tile's
    // area each) and filters 2·filter_width pixels a seam; level 1 is four level-0 tiles
    // box-filtered; the prefiltered levels sum each pixel's footprint cell by cell, one box
    // sum a layer (the plain tiling and the blocks over the cell), and the first tile of a
    // level fills its box table.
    let bpt = p.blocks_per_tile as f64;
    let fw = p.filter_width as f64;
    let level0 = TILE * (PIXEL + BLOCK_PIXEL * bpt + FILTER_PIXEL * fw * (1.0 + bpt));
    let level1 = 4.0 * level0 + 4.0 * TILE * DOWNSAMPLE_PIXEL;
    let table = if tables > 0.0 { TABLE_PIXEL * px } else { 0.0 };
    let prefiltered = TILE * CELL * FOOTPRINT_CELLS * (1.0 + bpt) + table;
    let (tile, worst) = [(level0, 0), (level1, 1), (prefiltered, 2)]
        .into_iter()
        .filter(|&(_, l)| l < levels)
        .fold((0.0, 0), |a, (w, l)| if w > a.0 { (w, l) } else { a });
    let tile_why = format!(
        "level {worst} of a 256² tile: 65536 px × (1 + blocks_per_tile {}) layers, filter_width {}",
        p.blocks_per_tile, p.filter_width
    );

    // Making it: decoding and summing the sample, drawing and moving the blocks, grouping and
    // indexing them; `create` also measures the seams and encodes
    // the sample, then loads what it made, and the caller loads it once more.
    let per_block = BLOCK + BLOCK_MISS * n / (n + CACHED_BLOCKS);
    let load = SAMPLE_PIXEL * px + n * per_block;
    let build = match create {
        true => 3.0 * load + ENCODE_PIXEL * px,
        false => load,
    };
    let build_why = format!("sample {sw}×{sh} + {n} blocks{}", if create { ", made and loaded" } else { "" });
    Ok(Plan {
        width,
        height,
        domain: Domain::Torus,
        animation: None,
        cost: Cost {
            resident_bytes: Measure::new(cost::units(resident), resident_why),
            tile_work: Measure::new(cost::units(tile), tile_why),
            build_work: Measure::new(cost::units(build), build_why),
        },
    })
}

/// Bytes of the box table of side 2^k: column and row maps, sums in 16 bits a channel up to
/// side 16 and 32 above, and a packed mean a box.
fn table_bytes(sw: u32, sh: u32, k: u32) -> f64 {
    let px = sw as f64 * sh as f64;
    let lanes = if (1u64 << (2 * k)) * 255 <= u16::MAX as u64 { 8.0 } else { 16.0 };
    4.0 * (sw as f64 + sh as f64) + (lanes + 4.0) * px
}
