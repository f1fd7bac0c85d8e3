//! The blocks by the tile that holds their corner (their home tile), which is how a region
//! finds the blocks that meet it.
//!
//! A seed-derived sequence is not drawn when the texture is opened: the blocks of the home
//! tiles a region needs are found on demand ([`Generator::landing_in`]) and kept. Finding a
//! home tile's blocks that way costs a pass over its pixels, far less than drawing and indexing
//! the whole sequence for the first tiles, far more for a whole texture; so once the home tiles
//! found would have cost as much as the whole index, the whole sequence is drawn and indexed
//! ([`TileIndex`]) and the kept tiles dropped. The first tile then costs work in proportion to
//! its neighbourhood, and no session more than about twice the eager index.
//! An explicit sequence comes whole in the encoding and is indexed when opened.

use super::blocks::{Block, Generator, Numbered};
use super::index::{self, TileIndex};
use std::collections::HashMap;
use std::sync::{Arc, Mutex, OnceLock};

/// Points of a home tile [`Generator::landing_in`] visits for the cost of indexing one block
/// of the whole sequence (drawing it, moving it, grouping it and listing it in the tiles it
/// touches, mostly cache misses).
const POINTS_PER_BLOCK: u64 = 32;

/// The whole sequence grouped by home tile, and the index of the blocks touching each tile.
pub(super) struct Indexed {
    /// The blocks grouped by home tile ([`index::by_home_tile`]): the index refers to them by
    /// position in this list.
    pub blocks: Vec<Numbered>,
    pub index: TileIndex,
}

/// The tiling's geometry: `tiles_x × tiles_y` tiles of `tile_w × tile_h` pixels.
#[derive(Clone, Copy)]
pub(super) struct Tiling {
    pub tiles_x: u32,
    pub tiles_y: u32,
    pub tile_w: u32,
    pub tile_h: u32,
}

pub(super) struct Homes {
    tiling: Tiling,
    /// `None` for an explicit sequence, indexed when opened.
    generator: Option<Generator>,
    indexed: OnceLock<Indexed>,
    found: Mutex<Found>,
}

/// The home tiles found on demand, until the whole sequence is indexed.
#[derive(Default)]
struct Found {
    tiles: HashMap<u32, Arc<[Numbered]>>,
    /// Points visited finding them, against [`POINTS_PER_BLOCK`] a block of the sequence.
    points: u64,
}

impl Homes {
    /// A seed-derived sequence: nothing is drawn yet.
    pub fn seeded(generator: Generator, tiling: Tiling) -> Self {
        Self { tiling, generator: Some(generator), indexed: OnceLock::new(), found: Mutex::default() }
    }

    /// An explicit sequence (in sequence order), indexed now.
    pub fn explicit(blocks: &[Block], tiling: Tiling) -> Self {
        let indexed = OnceLock::from(index_all(blocks, tiling));
        Self { tiling, generator: None, indexed, found: Mutex::default() }
    }

    /// The whole sequence indexed, drawn now if it was not yet.
    pub fn indexed(&self) -> &Indexed {
        self.indexed.get_or_init(|| {
            let generator = self.generator.as_ref().expect("an explicit sequence is indexed when opened");
            let indexed = index_all(&generator.all(), self.tiling);
            *self.found.lock().unwrap_or_else(|e| e.into_inner()) = Found::default();
            indexed
        })
    }

    /// Calls `f` with the blocks of each home tile (tx, ty) of `tiles`, in sequence order.
    pub fn with_homed<R>(&self, tiles: &[(u32, u32)], f: impl FnOnce(&[&[Numbered]]) -> R) -> R {
        if let Some(indexed) = self.indexed.get() {
            return f(&self.lists(indexed, tiles));
        }
        let generator = self.generator.as_ref().expect("an explicit sequence is indexed when opened");
        let mut found = self.found.lock().unwrap_or_else(|e| e.into_inner());
        let Tiling { tiles_x, tile_w, tile_h, .. } = self.tiling;
        let key = |&(tx, ty): &(u32, u32)| ty * tiles_x + tx;
        let mut missing: Vec<(u32, u32)> =
            tiles.iter().copied().filter(|t| !found.tiles.contains_key(&key(t))).collect();
        missing.sort_unstable();
        missing.dedup();
        let points = found.points + missing.len() as u64 * generator.points_for(tile_w as u64, tile_h as u64);
        if points > generator.len() * POINTS_PER_BLOCK {
            drop(found);
            return f(&self.lists(self.indexed(), tiles));
        }
        for &(tx, ty) in &missing {
            let corner = (tx as u64 * tile_w as u64, ty as u64 * tile_h as u64);
            let blocks = generator.landing_in(corner, (tile_w as u64, tile_h as u64));
            found.tiles.insert(key(&(tx, ty)), blocks.into());
        }
        found.points = points;
        let kept: Vec<Arc<[Numbered]>> = tiles.iter().map(|t| found.tiles[&key(t)].clone()).collect();
        drop(found);
        f(&kept.iter().map(|b| &b[..]).collect::<Vec<_>>())
    }

    fn lists<'a>(&self, indexed: &'a Indexed, tiles: &[(u32, u32)]) -> Vec<&'a [Numbered]> {
        tiles.iter().map(|&(tx, ty)| &indexed.blocks[indexed.index.homed(tx, ty)]).collect()
    }

    /// Blocks held: the whole sequence once indexed, else those of the home tiles found.
    pub fn blocks_held(&self) -> usize {
        match self.indexed.get() {
            Some(indexed) => indexed.blocks.len(),
            None => self.found.lock().unwrap_or_else(|e| e.into_inner()).tiles.values().map(|b| b.len()).sum(),
        }
    }

    /// Heap bytes of the blocks held and their index.
    pub fn heap_bytes(&self) -> usize {
        let block = std::mem::size_of::<Numbered>();
        match self.indexed.get() {
            Some(indexed) => indexed.blocks.capacity() * block + indexed.index.heap_bytes(),
            None => {
                let found = self.found.lock().unwrap_or_else(|e| e.into_inner());
                let entry = std::mem::size_of::<(u32, Arc<[Numbered]>)>();
                found.tiles.capacity() * entry + found.tiles.values().map(|b| b.len() * block).sum::<usize>()
            }
        }
    }
}

/// Groups `blocks` (in sequence order) by home tile and indexes them.
fn index_all(blocks: &[Block], t: Tiling) -> Indexed {
    let blocks = index::by_home_tile(blocks, t.tiles_x, t.tiles_y, t.tile_w, t.tile_h);
    let index = TileIndex::build(&blocks, t.tiles_x, t.tiles_y, t.tile_w, t.tile_h);
    Indexed { blocks, index }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::chaos_mosaic::blocks::SizeRule;
    use crate::models::chaos_mosaic::Params;

    #[test]
    fn every_home_tile_found_on_demand_lists_what_the_whole_index_lists() {
        // Square and non-square tori, several blocks a tile, no and many cat map iterations.
        for (sample, tiles, per_tile, iterations) in [
            ((16, 16), (12, 12), 1, 10),
            ((12, 20), (10, 6), 3, 10),
            ((9, 7), (14, 20), 2, 1000),
            ((10, 10), (9, 9), 8, 0),
        ] {
            let params: Params = serde_json::from_value(serde_json::json!({
                "tiles_x": tiles.0, "tiles_y": tiles.1, "blocks_per_tile": per_tile,
                "iterations": iterations, "seed": 17,
            }))
            .unwrap();
            let generator =
                Generator::new(&params, sample.0, sample.1, SizeRule::new(sample.0, sample.1, &params).unwrap());
            let tiling = Tiling { tiles_x: tiles.0, tiles_y: tiles.1, tile_w: sample.0, tile_h: sample.1 };
            let indexed = index_all(&generator.all(), tiling);
            for ty in 0..tiles.1 {
                for tx in 0..tiles.0 {
                    let corner = (tx as u64 * sample.0 as u64, ty as u64 * sample.1 as u64);
                    let found = generator.landing_in(corner, (sample.0 as u64, sample.1 as u64));
                    assert_eq!(
                        found,
                        indexed.blocks[indexed.index.homed(tx, ty)],
                        "{sample:?} {tiles:?}: tile ({tx}, {ty})"
                    );
                }
            }
        }
    }
}
