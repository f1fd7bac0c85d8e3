//! The chaos mosaic's encoding: the sample as `sample.png`, the parameters in the manifest,
//! and, for an explicit sequence, the 12-byte block records in `blocks`.

// Loading and creation share this file; a build without `create` (render-only) leaves the
// creation half and what only it uses unused.
#![cfg_attr(not(feature = "create"), allow(unused_imports, dead_code))]

use super::blocks::{self, SizeRule};
use super::params::{Params, Sequence};
use super::plan::{BLOCKS_SECTION, SAMPLE_SECTION};
use super::render::ChaosMosaic;
use super::MODEL;
use crate::models::parse_params;
#[cfg(feature = "create")]
use crate::models::{input_image, Inputs};
use crate::{bundle::Bundle, pixels::Rgba8Image, Result};

/// Makes an encoding from `params` (JSON, see [`Params`]) and the input image `sample`.
/// When `seamless` is not given it is measured from the sample.
#[cfg(feature = "create")]
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    super::plan::plan_create(params, inputs)?;
    let mut p: Params = parse_params(params)?;
    let given = serde_json::to_value(&p).expect("params serialize");
    let sample = input_image(inputs, "sample")?;
    p.seamless.get_or_insert_with(|| is_seamless(&sample));
    let rule = SizeRule::new(sample.width, sample.height, &p)?;
    let mut bundle = Bundle::created(MODEL, name, given, serde_json::to_value(&p).expect("params serialize"))
        .with_section(SAMPLE_SECTION, sample.to_png());
    if p.sequence == Sequence::Explicit {
        let generator = blocks::Generator::new(&p, sample.width, sample.height, rule);
        bundle = bundle.with_section(BLOCKS_SECTION, blocks::pack(&generator.all()));
    }
    load(&bundle)?;
    Ok(bundle)
}

/// Validates a stored encoding completely and builds the texture.
pub fn load(bundle: &Bundle) -> Result<ChaosMosaic> {
    super::plan::plan(bundle)?;
    let params: Params = bundle.params()?;
    let sample = crate::pixels::decode_png(SAMPLE_SECTION, bundle.section(SAMPLE_SECTION)?)?;
    let explicit = bundle.sections.iter().find(|s| s.name == BLOCKS_SECTION).map(|s| s.data.as_slice());
    ChaosMosaic::new(params, sample, explicit)
}

/// Whether a sample tiles without a visible seam: the mean colour step across its wrap edges
/// is no larger than 1.5 times the mean step between interior neighbours (plus one level).
pub fn is_seamless(sample: &Rgba8Image) -> bool {
    let step = |a: [u8; 4], b: [u8; 4]| (0..4).map(|c| (a[c] as i32 - b[c] as i32).unsigned_abs() as u64).sum::<u64>();
    let (w, h) = (sample.width, sample.height);
    let (mut inner, mut inner_n, mut wrap, mut wrap_n) = (0u64, 0u64, 0u64, 0u64);
    for y in 0..h {
        for x in 0..w {
            let p = sample.pixel(x, y);
            let (right, down) = (sample.pixel((x + 1) % w, y), sample.pixel(x, (y + 1) % h));
            for (q, across) in [(right, x + 1 == w), (down, y + 1 == h)] {
                if across {
                    wrap += step(p, q);
                    wrap_n += 1;
                } else {
                    inner += step(p, q);
                    inner_n += 1;
                }
            }
        }
    }
    let mean = |s: u64, n: u64| s as f64 / n.max(1) as f64;
    mean(wrap, wrap_n) <= 1.5 * mean(inner, inner_n) + 4.0
}
