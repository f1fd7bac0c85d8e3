//! The loaded texture: the validated sample and the blocks by home tile from which
//! [`compose`](super::compose) and [`prefilter`](super::prefilter) evaluate any region.

use super::blocks::{self, Generator, SizeRule};
use super::homes::{Homes, Tiling};
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
    /// The blocks by home tile, found as regions need them.
    pub(super) homes: Homes,
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
        let tiling = Tiling { tiles_x: params.tiles_x, tiles_y: params.tiles_y, tile_w: sw, tile_h: sh };
        let homes = match (params.sequence, explicit) {
            (Sequence::Seed, None) => Homes::seeded(Generator::new(&params, sw, sh, rule), tiling),
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
                Homes::explicit(&blocks, tiling)
            }
            (Sequence::Seed, Some(_)) => {
                return Err(Error::bundle("section `blocks` present for a seed-derived sequence"))
            }
            (Sequence::Explicit, None) => return Err(Error::bundle("missing section `blocks`")),
        };
        let (sums, sample) = (PeriodicSums::new(&sample), Sample::new(&sample));
        Ok(Self { params, seamless, width, height, homes, sums, sample, tables: BoxTables::default() })
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    /// A copy of the sample (the texture keeps it as packed pixels).
    pub fn sample(&self) -> Rgba8Image {
        self.sample.to_image()
    }

    /// The random block sequence R_ε in paste order (drawing and indexing all of it).
    pub fn blocks(&self) -> Vec<Block> {
        let indexed = self.homes.indexed();
        let mut out = vec![Block::default(); indexed.blocks.len()];
        for n in &indexed.blocks {
            out[n.id as usize] = n.block;
        }
        out
    }

    /// Blocks drawn and held so far: those of the home tiles the rendered regions needed,
    /// or the whole sequence once it is indexed.
    pub fn blocks_held(&self) -> usize {
        self.homes.blocks_held()
    }

    /// Heap bytes of the blocks held and their index.
    pub fn structure_heap_bytes(&self) -> usize {
        self.homes.heap_bytes()
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
