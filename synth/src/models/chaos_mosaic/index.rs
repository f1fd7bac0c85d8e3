//! The per-tile index of §3.2: for each tile of T, the blocks whose pasted rectangle touches
//! it, in sequence order. A region then costs only the blocks near it, whatever the size of
//! the texture.

use super::blocks::{Block, Numbered};

/// Compressed rows: the blocks touching tile `i` are `ids[starts[i]..starts[i + 1]]`, by
/// position in the list of [`by_home_tile`], in sequence order.
pub struct TileIndex {
    tiles_x: u32,
    starts: Vec<u32>,
    ids: Vec<u32>,
    /// The blocks whose corner lies in tile `i` are positions `home[i]..home[i + 1]` (the
    /// list is grouped by [`by_home_tile`]): each block once, for listing a region's blocks.
    home: Vec<u32>,
}

/// The blocks (given in sequence order) reordered by the tile that holds their corner
/// (row-major), in sequence order within a tile, each with its sequence number. The blocks near
/// a region then lie in a few runs of memory (a region's blocks come from its own and the
/// neighbouring tile rows) instead of all over the list, whose sequence order the cat map
/// scatters over the texture.
pub fn by_home_tile(blocks: &[Block], tiles_x: u32, tiles_y: u32, tile_w: u32, tile_h: u32) -> Vec<Numbered> {
    let mut at = home_starts(blocks.iter(), tiles_x, tiles_y, tile_w, tile_h);
    let mut local = vec![Numbered::default(); blocks.len()];
    for (id, b) in blocks.iter().enumerate() {
        let pos = &mut at[home_tile(b, tiles_x, tile_w, tile_h)];
        local[*pos as usize] = Numbered { block: *b, id: id as u32 };
        *pos += 1;
    }
    local
}

/// The tile (row-major) holding a block's corner: its home tile.
fn home_tile(b: &Block, tiles_x: u32, tile_w: u32, tile_h: u32) -> usize {
    (b.t / tile_h) as usize * tiles_x as usize + (b.s / tile_w) as usize
}

/// Where each home tile's blocks start in a list grouped by home tile (one entry per tile, and
/// the total at the end).
fn home_starts<'a>(
    blocks: impl Iterator<Item = &'a Block>,
    tiles_x: u32,
    tiles_y: u32,
    tile_w: u32,
    tile_h: u32,
) -> Vec<u32> {
    let mut at = vec![0u32; tiles_x as usize * tiles_y as usize + 1];
    for b in blocks {
        at[home_tile(b, tiles_x, tile_w, tile_h) + 1] += 1;
    }
    for i in 1..at.len() {
        at[i] += at[i - 1];
    }
    at
}

impl TileIndex {
    /// Indexes `blocks` (listed by position, grouped by home tile as [`by_home_tile`] lists
    /// them): each tile's list holds positions in ascending sequence order. Blocks are never
    /// larger than a tile, so each touches at most 2 × 2 tiles of the torus.
    pub fn build(blocks: &[Numbered], tiles_x: u32, tiles_y: u32, tile_w: u32, tile_h: u32) -> Self {
        let tiles = tiles_x as usize * tiles_y as usize;
        let home = home_starts(blocks.iter().map(|n| &n.block), tiles_x, tiles_y, tile_w, tile_h);
        let touched = |b: &Block| {
            let cols = tile_span(b.s, b.w, tile_w, tiles_x);
            let rows = tile_span(b.t, b.h, tile_h, tiles_y);
            rows.into_iter().flatten().flat_map(move |r| cols.into_iter().flatten().map(move |c| r * tiles_x + c))
        };
        let mut counts = vec![0u32; tiles + 1];
        for n in blocks {
            for t in touched(&n.block) {
                counts[t as usize + 1] += 1;
            }
        }
        for i in 1..=tiles {
            counts[i] += counts[i - 1];
        }
        let starts = counts;
        let mut fill = starts.clone();
        let mut ids = vec![0u32; starts[tiles] as usize];
        let mut in_sequence = vec![0u32; blocks.len()];
        for (pos, n) in blocks.iter().enumerate() {
            in_sequence[n.id as usize] = pos as u32;
        }
        for pos in in_sequence {
            for t in touched(&blocks[pos as usize].block) {
                ids[fill[t as usize] as usize] = pos;
                fill[t as usize] += 1;
            }
        }
        Self { tiles_x, starts, ids, home }
    }

    /// Positions of the blocks touching tile (tx, ty), in sequence order.
    #[inline]
    pub fn blocks(&self, tx: u32, ty: u32) -> &[u32] {
        let i = (ty * self.tiles_x + tx) as usize;
        &self.ids[self.starts[i] as usize..self.starts[i + 1] as usize]
    }

    /// Positions of the blocks whose corner lies in tile (tx, ty), in sequence order.
    #[inline]
    pub fn homed(&self, tx: u32, ty: u32) -> std::ops::Range<usize> {
        let i = (ty * self.tiles_x + tx) as usize;
        self.home[i] as usize..self.home[i + 1] as usize
    }

    /// The mean number of blocks listed a tile, as a fraction `(entries, tiles)`.
    pub fn blocks_per_tile(&self) -> (u64, u64) {
        (self.ids.len() as u64, self.starts.len() as u64 - 1)
    }

    /// Heap bytes held by the index.
    pub fn heap_bytes(&self) -> usize {
        (self.starts.capacity() + self.ids.capacity() + self.home.capacity()) * 4
    }
}

/// The (at most two) tiles along one axis that `[start, start + len)` touches on a torus
/// of `tiles` tiles of `size`.
fn tile_span(start: u32, len: u16, size: u32, tiles: u32) -> [Option<u32>; 2] {
    let first = start / size;
    let last = ((start as u64 + len as u64 - 1) / size as u64 % tiles as u64) as u32;
    [Some(first), (last != first).then_some(last)]
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn wrapping_block_is_found_in_all_four_tiles() {
        let one = |block| [Numbered { block, id: 0 }];
        let b = Block { x: 0, y: 0, w: 10, h: 10, s: 95, t: 35 };
        let idx = TileIndex::build(&one(b), 10, 4, 10, 10);
        for (tx, ty) in [(9, 3), (0, 3), (9, 0), (0, 0)] {
            assert_eq!(idx.blocks(tx, ty), &[0], "tile ({tx},{ty})");
        }
        assert!(idx.blocks(1, 1).is_empty());
        let inside = Block { x: 0, y: 0, w: 10, h: 10, s: 20, t: 10 };
        let idx = TileIndex::build(&one(inside), 10, 4, 10, 10);
        assert_eq!(idx.blocks(2, 1), &[0]);
        assert!(idx.blocks(3, 1).is_empty());
    }

    #[test]
    fn blocks_are_grouped_by_home_tile_and_listed_in_sequence_order() {
        let at = |s, t| Block { x: 0, y: 0, w: 6, h: 6, s, t };
        let blocks = vec![at(15, 15), at(2, 3), at(18, 11), at(5, 5), at(12, 0)];
        let local = by_home_tile(&blocks, 2, 2, 10, 10);
        let seq: Vec<u32> = local.iter().map(|n| n.id).collect();
        assert_eq!(seq, [1, 3, 4, 0, 2]);
        assert!(local.iter().all(|n| blocks[n.id as usize] == n.block));
        let idx = TileIndex::build(&local, 2, 2, 10, 10);
        // Tile (1, 1) meets blocks 0 and 2 (its own) and 3 (from tile (0, 0)): sequence order.
        assert_eq!(idx.blocks(1, 1), &[3, 4, 1]);
        assert_eq!(idx.blocks(0, 0).iter().map(|&p| seq[p as usize]).collect::<Vec<_>>(), [0, 1, 3]);
        // Homes: tile (0, 0) holds the corners of blocks 1 and 3, (1, 0) of 4, (1, 1) of 0 and 2.
        assert_eq!([idx.homed(0, 0), idx.homed(1, 0), idx.homed(0, 1), idx.homed(1, 1)], [0..2, 2..3, 3..3, 3..5]);
    }
}
