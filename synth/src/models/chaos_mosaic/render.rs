//! The loaded texture: the validated sample, block list and index from which
//! [`compose`](super::compose) and [`prefilter`](super::prefilter) evaluate any region.

use super::blocks::{self, SizeRule};
use super::index::{self, TileIndex};
use super::params::{self, Params, Sequence};
use super::sums::{BoxTables, PeriodicSums, Sample};
use super::{Block, MODEL};
use crate::{pixels::Rgba8Image, Domain, Error, Region, Result, Stop, Texture};

/// A loaded chaos mosaic: everything needed to evaluate any region, validated.
pub struct ChaosMosaic {
    pub(super) params: Params,
    pub(super) sample: Sample,
    pub(super) seamless: bool,
    pub(super) width: u64,
    pub(super) height: u64,
    /// The blocks grouped by the tile of their corner ([`index::by_home_tile`]) and their
    /// sequence numbers: the index and placements refer to blocks by position in this list.
    pub(super) blocks: Vec<Block>,
    pub(super) seq: Vec<u32>,
    pub(super) index: TileIndex,
    pub(super) sums: PeriodicSums,
    /// Box sums of the sample at each power-of-two side, built on first use (mid mip levels).
    pub(super) tables: BoxTables,
}

impl ChaosMosaic {
    /// Builds the texture from validated parts; `blocks` is `None` for a seed-derived sequence.
    pub(super) fn new(params: Params, sample: Rgba8Image, explicit: Option<&[u8]>) -> Result<Self> {
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
                super::plan::check_explicit_sample(sw, sh)?;
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
        let (sums, sample) = (PeriodicSums::new(&sample), Sample::new(&sample));
        Ok(Self { params, seamless, width, height, blocks, seq, index, sums, sample, tables: BoxTables::default() })
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    /// A copy of the sample (the texture keeps it as packed pixels).
    pub fn sample(&self) -> Rgba8Image {
        self.sample.to_image()
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

    /// Heap bytes of the sample and its prefix sums, held from the load on (the box tables
    /// of the prefiltered levels come on top, built on first use).
    pub fn sample_heap_bytes(&self) -> usize {
        self.sample.px.capacity() * 4 + self.sums.heap_bytes()
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
    fn render(&self, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        // `None` when stopped: `out` is then incomplete, and discarded.
        let _ = match region.level {
            0 => self.render_level0(region.x, region.y, region.width, region.height, out, stop),
            _ => self.render_prefiltered(region, out, stop),
        };
    }
}
