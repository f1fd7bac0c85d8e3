//! The chaos mosaic of Xu, Guo and Shum (MSR-TR-2000-32) as a virtual texture.
//!
//! A tiling T of the sample S is overlaid with one random block of S per tile, each moved by
//! i iterations of the cat map, pasted in sequence order, and cross-edge filtered over
//! `filter_width` pixels each side of every seam. The encoding V = (S, T_ε, R_ε) keeps the
//! sample, the tiling and either the explicit block sequence (12 bytes a block) or the seed
//! it is derived from. The texture is a torus of `tiles_x·n_w × tiles_y·n_h` pixels.
//!
//! Supported inputs: any sample from 2 × 2 up to 4096 × 4096 (non-square and non-power-of-two
//! included; explicit sequences need sides ≤ 256, as the 12-byte records do) whose size admits
//! a block under the area constraint; alpha is kept and filtered like the colour channels
//! (straight alpha); non-square textures run the cat map on a square torus of side
//! lcm(W, H) scaled onto the texture (see [`catmap::iterate`]).

mod blocks;
pub mod catmap;
mod compose;
mod demos;
mod index;
mod layout;
mod params;
mod prefilter;

pub use blocks::{Block, RECORD_BYTES};
pub use demos::demos;
pub use params::{Params, Sequence};
pub use prefilter::EXACT_LEVELS;

use super::{InputInfo, Inputs, MipGuarantee, Model, ModelInfo};
use crate::{bundle::Bundle, pixels::Rgba8Image, Domain, Error, Region, Result, Texture};
use blocks::SizeRule;
use index::TileIndex;
use prefilter::{BoxTables, PeriodicSums};
use std::sync::Arc;

pub const MODEL: &str = "chaos-mosaic";
const SAMPLE_SECTION: &str = "sample.png";
const BLOCKS_SECTION: &str = "blocks";

/// The chaos mosaic's registry entry.
pub struct ChaosMosaicModel;
pub static CHAOS_MOSAIC: ChaosMosaicModel = ChaosMosaicModel;

impl Model for ChaosMosaicModel {
    fn id(&self) -> &'static str {
        MODEL
    }
    fn describe(&self) -> ModelInfo {
        ModelInfo {
            id: MODEL,
            title: "Chaos mosaic",
            paper: "Xu, Guo, Shum 2000, Chaos Mosaic: Fast and Memory Efficient Texture Synthesis",
            summary: "A tiling of the sample overlaid with random blocks of it, scattered by the cat map and \
                      cross-edge filtered: a seamless torus of any size from one small sample.",
            params_schema: super::params_schema::<Params>(),
            inputs: &[InputInfo {
                name: "sample",
                required: true,
                what: "the example texture, 2 × 2 up to 4096 × 4096 pixels (straight alpha kept)",
            }],
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
        MipGuarantee { min_psnr_db: 30.0, max_mean_error: 2.0 }
    }
}

/// A loaded chaos mosaic: everything needed to evaluate any region, validated.
pub struct ChaosMosaic {
    params: Params,
    sample: Rgba8Image,
    /// The sample's pixels as little-endian `u32`s, for copying a pixel at a time.
    sample_px: Vec<u32>,
    seamless: bool,
    width: u64,
    height: u64,
    /// The blocks grouped by the tile of their corner ([`index::by_home_tile`]) and their
    /// sequence numbers: the index and placements refer to blocks by position in this list.
    blocks: Vec<Block>,
    seq: Vec<u32>,
    index: TileIndex,
    sums: PeriodicSums,
    /// Box sums of the sample at each power-of-two side, built on first use (mid mip levels).
    tables: BoxTables,
}

impl ChaosMosaic {
    /// Builds the texture from validated parts; `blocks` is `None` for a seed-derived sequence.
    fn new(params: Params, sample: Rgba8Image, explicit: Option<&[u8]>) -> Result<Self> {
        params.validate()?;
        let seamless = params.seamless.ok_or_else(|| Error::param("seamless", "must be set in a stored encoding"))?;
        let (sw, sh) = (sample.width, sample.height);
        let width = params.tiles_x as u64 * sw as u64;
        let height = params.tiles_y as u64 * sh as u64;
        if width > params::MAX_SIDE || height > params::MAX_SIDE {
            return Err(Error::param(
                "tiles_x/tiles_y",
                format!("texture {width}×{height} exceeds {}", params::MAX_SIDE),
            ));
        }
        let rule = SizeRule::new(sw, sh, &params)?;
        let blocks = match (params.sequence, explicit) {
            (Sequence::Seed, None) => blocks::generate(&params, sw, sh, &rule),
            (Sequence::Explicit, Some(bytes)) => {
                check_explicit_sample(&sample)?;
                let blocks = blocks::unpack(bytes, sw, sh, width, height, &rule)?;
                let expected = params.tiles_x as usize * params.tiles_y as usize * params.blocks_per_tile as usize;
                if blocks.len() != expected {
                    return Err(Error::bundle(format!(
                        "section `blocks` holds {} blocks; tiles_x × tiles_y × blocks_per_tile is {expected}",
                        blocks.len()
                    )));
                }
                blocks
            }
            (Sequence::Seed, Some(_)) => {
                return Err(Error::bundle("section `blocks` present for a seed-derived sequence"))
            }
            (Sequence::Explicit, None) => return Err(Error::bundle("missing section `blocks`")),
        };
        let (blocks, seq) = index::by_home_tile(blocks, params.tiles_x, params.tiles_y, sw, sh);
        let index = TileIndex::build(&blocks, &seq, params.tiles_x, params.tiles_y, sw, sh);
        let sample_px = sample.data.chunks_exact(4).map(|p| u32::from_le_bytes(p.try_into().unwrap())).collect();
        let sums = PeriodicSums::new(&sample);
        Ok(Self {
            params,
            sample_px,
            seamless,
            width,
            height,
            blocks,
            seq,
            index,
            sums,
            sample,
            tables: BoxTables::default(),
        })
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    pub fn sample(&self) -> &Rgba8Image {
        &self.sample
    }

    /// The random block sequence R_ε in paste order.
    pub fn blocks(&self) -> Vec<Block> {
        let mut out = self.blocks.clone();
        for (b, &id) in self.blocks.iter().zip(&self.seq) {
            out[id as usize] = *b;
        }
        out
    }

    /// Heap bytes of the block list and the per-tile index.
    pub fn structure_heap_bytes(&self) -> usize {
        self.blocks.capacity() * std::mem::size_of::<Block>() + self.seq.capacity() * 4 + self.index.heap_bytes()
    }
}

impl Texture for ChaosMosaic {
    fn model(&self) -> &'static str {
        MODEL
    }
    fn width(&self) -> u64 {
        self.width
    }
    fn height(&self) -> u64 {
        self.height
    }
    fn domain(&self) -> Domain {
        Domain::Torus
    }
    fn render(&self, region: &Region, out: &mut [u8]) {
        if region.level == 0 {
            self.render_level0(region.x, region.y, region.width, region.height, out);
        } else {
            self.render_prefiltered(region, out);
        }
    }
}

/// Makes an encoding from `params` (JSON, see [`Params`]) and the input image `sample`.
/// When `seamless` is not given it is measured from the sample.
pub fn create(name: &str, params: &serde_json::Value, inputs: &Inputs) -> Result<Bundle> {
    let mut p: Params = serde_json::from_value(params.clone()).map_err(|e| Error::param("params", e.to_string()))?;
    p.validate()?;
    let sample = super::input_image(inputs, "sample")?;
    if p.sequence == Sequence::Explicit {
        check_explicit_sample(&sample)?;
    }
    p.seamless.get_or_insert_with(|| is_seamless(&sample));
    let rule = SizeRule::new(sample.width, sample.height, &p)?;
    let mut bundle = Bundle::new(MODEL, name, serde_json::to_value(&p).expect("params serialize"))
        .with_section(SAMPLE_SECTION, sample.to_png());
    if p.sequence == Sequence::Explicit {
        bundle = bundle
            .with_section(BLOCKS_SECTION, blocks::pack(&blocks::generate(&p, sample.width, sample.height, &rule)));
    }
    load(&bundle)?;
    Ok(bundle)
}

/// Validates a stored encoding completely and builds the texture.
pub fn load(bundle: &Bundle) -> Result<ChaosMosaic> {
    if let Some(s) = bundle.sections.iter().find(|s| s.name != SAMPLE_SECTION && s.name != BLOCKS_SECTION) {
        return Err(Error::bundle(format!("unexpected section `{}`", s.name)));
    }
    let params: Params = bundle.params()?;
    let sample = crate::pixels::decode_png(SAMPLE_SECTION, bundle.section(SAMPLE_SECTION)?)?;
    let explicit = bundle.sections.iter().find(|s| s.name == BLOCKS_SECTION).map(|s| s.data.as_slice());
    ChaosMosaic::new(params, sample, explicit)
}

fn check_explicit_sample(sample: &Rgba8Image) -> Result<()> {
    let max = params::MAX_EXPLICIT_SAMPLE_SIDE;
    if sample.width > max || sample.height > max {
        return Err(Error::param(
            "sequence",
            format!(
                "explicit 12-byte blocks need a sample of at most {max}×{max}; use \"seed\" for {}×{}",
                sample.width, sample.height
            ),
        ));
    }
    Ok(())
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
