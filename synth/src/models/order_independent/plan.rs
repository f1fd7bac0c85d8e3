//! The cost model: from the parameters and the sample's PNG header alone, what a loaded texture
//! holds and what its dearest tile and its making cost. Work units are about 1 ns of one core.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::params::{ExemplarLevels, Generation0, Params, Search};
use super::prefilter::{source, span, Source, SECTION as CALIBRATION_SECTION};
use super::rect::Rect;
use super::search::{structure, PILOT};
use super::served::{cone_to, CHUNK};
use super::MODEL;
use crate::bundle::Bundle;
#[cfg(feature = "create")]
use crate::models::Inputs;
use crate::models::{cost, parse_params, Cost, Measure, Plan};
use crate::pixels::png_dimensions;
use crate::texture::level_count;
use crate::{Domain, Error, Result};

/// The bundle's sections: the sample as given, and the calibration `create` measured
/// ([`super::prefilter::SECTION`]; absent from bundles stored before it).
pub(super) const SAMPLE_SECTION: &str = "sample.png";

/// Refuses a stored manifest that leaves a default to be filled.
pub(super) fn check_stored(p: &Params) -> Result<()> {
    if p.generation0.is_none() {
        return Err(Error::param("generation0", "must be set in a stored encoding"));
    }
    Ok(())
}

/// Per noise entry (a hash), per upsampled entry, per k-coherence entry (gathering, candidates
/// and about a dozen 96-byte SSDs), and per byte an exhaustive scan compares.
const NOISE: f64 = 12.0;
const UPSAMPLE: f64 = 15.0;
const COHERENT: f64 = 250.0;
const SCAN_BYTE: f64 = 0.12;
/// Per k-coherence-set comparison byte at load (the scan abandons most comparisons early).
const KSET_BYTE: f64 = 0.07;
/// Per output pixel: colouring, and each box filter.
const COLOUR: f64 = 2.0;
const DOWNSAMPLE: f64 = 8.0;
/// Per sample pixel: decoding, the pyramids and vectors; encoding it as PNG in `create`.
const SAMPLE_PIXEL: f64 = 300.0;
const ENCODE_PIXEL: f64 = 60.0;
/// Calibration windows and their side, as in `prefilter`.
const CALIBRATION_WINDOWS: f64 = 64.0;
const CALIBRATION_WINDOW: usize = 64;

/// What loading `bundle` gives and costs, from its manifest and the sample's header.
pub fn plan(bundle: &Bundle) -> Result<Plan> {
    if bundle.manifest.model != MODEL {
        return Err(Error::bundle(format!("model `{}`, expected `{MODEL}`", bundle.manifest.model)));
    }
    if let Some(s) = bundle.sections.iter().find(|s| s.name != SAMPLE_SECTION && s.name != CALIBRATION_SECTION) {
        return Err(Error::bundle(format!("unexpected section `{}`", s.name)));
    }
    let p: Params = bundle.params()?;
    check_stored(&p)?;
    let (w, h) = png_dimensions(SAMPLE_SECTION, bundle.section(SAMPLE_SECTION)?)?;
    let stored = bundle.section(CALIBRATION_SECTION).is_ok();
    plan_params(&p, w, h, if stored { Making::Stored } else { Making::Lazy })
}

/// Where the calibration is measured, which the plan charges.
#[derive(Clone, Copy, PartialEq, Eq)]
enum Making {
    /// By `create`: to build.
    Create,
    /// Stored in the bundle: to build, as checking it where the bundle is accepted measures
    /// it again (opening it measures nothing).
    Stored,
    /// Not stored (a bundle made before the section existed): on the first tile needing it.
    Lazy,
}

/// What `create` gives and costs, from the parameters and the sample's header.
#[cfg(feature = "create")]
pub fn plan_create(params: &serde_json::Value, inputs: &Inputs) -> Result<Plan> {
    if let Some(other) = inputs.keys().find(|k| k.as_str() != "sample") {
        return Err(Error::image(other.as_str(), "not an input of `order-independent` (it takes `sample`)"));
    }
    let p = parse_params::<Params>(params)?.filled();
    let sample = inputs.get("sample").ok_or_else(|| Error::image("sample", "missing; this model needs it"))?;
    let (w, h) = png_dimensions("sample", sample)?;
    plan_params(&p, w, h, Making::Create)
}

fn plan_params(p: &Params, sw: u32, sh: u32, making: Making) -> Result<Plan> {
    let create = making == Making::Create;
    let lazy = making == Making::Lazy;
    p.validate(sw, sh)?;
    let st = structure(p);
    let fin = p.levels - 1;
    let shift = |s: u8| if p.exemplar() == ExemplarLevels::Stack { 0 } else { fin - s };
    let pixels = |s: u8| ((sw >> shift(s)) as f64) * ((sh >> shift(s)) as f64);
    let vector = |s: u8| {
        let taps = st.same.len() + if s > 0 { st.lower.len() } else { 0 };
        (3 * taps).div_ceil(32) as f64 * 32.0
    };
    let searched = |s: u8| s > 0 || p.coarsest_generations > 1;
    let k = if p.search == Search::Kcoherence { p.k as f64 } else { 0.0 };

    // With four subpasses a generation searches one pixel in four and copies the others.
    let subpass = |search: f64| if p.subpasses() == 4 { search / 4.0 + 0.75 * UPSAMPLE } else { search };
    // The work of every entry of the cone of an s-level rectangle.
    let entry = |s: u8, m: u8| -> f64 {
        match (s, m) {
            (0, 0) => NOISE,
            (_, 0) if p.generation0() == Generation0::Upsample => UPSAMPLE,
            (_, 0) => pixels(s) * 3.0 * st.lower.len() as f64 * SCAN_BYTE,
            _ if p.search == Search::Kcoherence => {
                subpass(COHERENT * (st.same.len() + st.lower.len()) as f64 / 30.0 * k / 2.0)
            }
            _ => subpass(pixels(s) * vector(s) * SCAN_BYTE),
        }
    };
    // The work of generation m of an s-level rectangle, and of its latest generation.
    let work_to = |s: u8, m: u8, side: usize| -> f64 {
        let rects = cone_to(&st, s, m, Rect { x: 0, y: 0, w: side, h: side });
        rects
            .iter()
            .enumerate()
            .flat_map(|(l, gens)| gens.iter().enumerate().map(move |(m, r)| (l, m, r)))
            .map(|(l, m, r)| r.area() as f64 * entry(l as u8, m as u8))
            .sum()
    };
    let work = |s: u8, side: usize| work_to(s, st.last(s), side);
    let tile = (CHUNK * CHUNK) as f64;
    let calibration = CALIBRATION_WINDOWS * work(fin, CALIBRATION_WINDOW.max(2 << fin));
    let levels = level_count(p.width, p.height);
    let level_work = |l: u32| -> f64 {
        if l == 0 {
            return work(fin, CHUNK as usize) + tile * COLOUR;
        }
        let d = span(p, l);
        let chunks = (1u64 << (2 * d)) as f64;
        match source(p, l) {
            Source::Exact => chunks * (work(fin, CHUNK as usize) + tile * COLOUR) + chunks * tile * DOWNSAMPLE,
            Source::Pyramid { r, m } => {
                let s = fin - r as u8;
                let cal = if lazy && (r > 0 || m < st.last(s)) { calibration } else { 0.0 };
                chunks * (work_to(s, m, CHUNK as usize) + tile * (COLOUR + DOWNSAMPLE)) + cal
            }
            Source::Mean => (if lazy { calibration } else { 0.0 }) + tile * COLOUR,
        }
    };
    let (tile_work, worst) =
        (0..levels).map(|l| (level_work(l), l)).fold((0.0, 0), |a, b| if b.0 > a.0 { b } else { a });
    let search = match p.search {
        Search::Kcoherence => format!("k-coherence, k = {}, κ = {}%, jitter {}", p.k, p.kappa(), p.jitter()),
        Search::Exhaustive => format!("exhaustive over {sw}×{sh}"),
    };
    let tile_why = format!(
        "the dependency cone of {} levels × {} generations ({search}) under level {worst} of a 256² tile",
        p.levels,
        p.generations()
    );

    // Resident: per exemplar pixel of each level, colours and box colours, its balance, the
    // valid masks, and where searched its vector, its k-coherence set and the set shifted 9
    // ways (with whether each shifted set starts with the coherent continuation); the
    // calibration's colours (g, and g_s of each synthesis level read before its latest
    // generation), 3 bytes a coordinate, and the bins they are expanded from and stored as, at
    // most 4 a coordinate; the empty cache and counters of a texture loaded alone.
    let measured: f64 = (1..levels)
        .filter_map(|l| match source(p, l) {
            Source::Pyramid { r, m } if m < st.last(fin - r as u8) && r < fin as u32 => Some(fin - r as u8),
            _ => None,
        })
        .collect::<std::collections::BTreeSet<u8>>()
        .into_iter()
        .map(|s| pixels(s) * 7.0)
        .sum();
    let resident: f64 = (0..p.levels)
        .map(|s| {
            let n = pixels(s);
            let ksets = if k > 0.0 { 2.0 * k + 1.0 + 9.0 * (2.0 * k + 2.0) } else { 0.0 };
            let searched = if searched(s) { n * (vector(s) + 5.0 + ksets) } else { 0.0 };
            n * 8.0 + searched
        })
        .sum::<f64>()
        + pixels(0) * 7.0
        + measured
        + 8192.0;
    let resident_why = format!("a {sw}×{sh} sample in {} levels: colours, vectors, k-coherence sets", p.levels);

    let ksets: f64 =
        (0..p.levels).filter(|&s| searched(s) && k > 0.0).map(|s| pixels(s) * pixels(s) * vector(s) * KSET_BYTE).sum();
    // The histogram balance synthesises a pilot window of each searched level.
    let pilots: f64 =
        if p.balance() > 0 { (0..p.levels).filter(|&s| searched(s)).map(|s| work(s, PILOT)).sum() } else { 0.0 };
    let load = SAMPLE_PIXEL * pixels(fin) + ksets + pilots;
    let measuring = if lazy { 0.0 } else { calibration };
    let build = if create { 2.0 * load + ENCODE_PIXEL * pixels(fin) } else { load } + measuring;
    let build_why = format!(
        "k-coherence sets of {sw}×{sh} pixels{}{}{}",
        if p.balance() > 0 { " and the balance's pilot windows" } else { "" },
        if create { ", made and loaded" } else { "" },
        match making {
            Making::Create => ", and the calibration's 64 level-0 windows",
            Making::Stored => ", and the calibration's 64 level-0 windows, measured again where the bundle is accepted",
            Making::Lazy => "",
        }
    );
    Ok(Plan {
        width: p.width,
        height: p.height,
        domain: match p.domain {
            super::params::DomainSpec::Plane => Domain::Plane,
            super::params::DomainSpec::Torus => Domain::Torus,
        },
        animation: None,
        cost: Cost {
            resident_bytes: Measure::new(cost::units(resident), resident_why),
            tile_work: Measure::new(cost::units(tile_work), tile_why),
            build_work: Measure::new(cost::units(build), build_why),
        },
    })
}
