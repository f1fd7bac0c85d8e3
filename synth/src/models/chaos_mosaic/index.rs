//! The per-tile index of §3.2: for each tile of T, the blocks whose pasted rectangle touches
//! it, in sequence order. A region then costs only the blocks near it, whatever the size of
//! the texture.

use super::blocks::Block;

/// Compressed rows: the blocks touching tile `i` are `ids[starts[i]..starts[i + 1]]`, ascending.
pub struct TileIndex {
    tiles_x: u32,
    starts: Vec<u32>,
    ids: Vec<u32>,
}

impl TileIndex {
    /// Blocks are never larger than a tile, so each touches at most 2 × 2 tiles of the torus.
    pub fn build(blocks: &[Block], tiles_x: u32, tiles_y: u32, tile_w: u32, tile_h: u32) -> Self {
        let tiles = tiles_x as usize * tiles_y as usize;
        let touched = |b: &Block| {
            let cols = tile_span(b.s, b.w, tile_w, tiles_x);
            let rows = tile_span(b.t, b.h, tile_h, tiles_y);
            rows.into_iter().flatten().flat_map(move |r| cols.into_iter().flatten().map(move |c| r * tiles_x + c))
        };
        let mut counts = vec![0u32; tiles + 1];
        for b in blocks {
            for t in touched(b) {
                counts[t as usize + 1] += 1;
            }
        }
        for i in 1..=tiles {
            counts[i] += counts[i - 1];
        }
        let starts = counts;
        let mut fill = starts.clone();
        let mut ids = vec![0u32; starts[tiles] as usize];
        for (id, b) in blocks.iter().enumerate() {
            for t in touched(b) {
                ids[fill[t as usize] as usize] = id as u32;
                fill[t as usize] += 1;
            }
        }
        Self { tiles_x, starts, ids }
    }

    /// Blocks touching tile (tx, ty), in sequence order.
    #[inline]
    pub fn blocks(&self, tx: u32, ty: u32) -> &[u32] {
        let i = (ty * self.tiles_x + tx) as usize;
        &self.ids[self.starts[i] as usize..self.starts[i + 1] as usize]
    }

    /// The mean number of blocks listed a tile, as a fraction `(entries, tiles)`.
    pub fn blocks_per_tile(&self) -> (u64, u64) {
        (self.ids.len() as u64, self.starts.len() as u64 - 1)
    }

    /// Heap bytes held by the index.
    pub fn heap_bytes(&self) -> usize {
        (self.starts.capacity() + self.ids.capacity()) * 4
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
        let b = Block { x: 0, y: 0, w: 10, h: 10, s: 95, t: 35 };
        let idx = TileIndex::build(&[b], 10, 4, 10, 10);
        for (tx, ty) in [(9, 3), (0, 3), (9, 0), (0, 0)] {
            assert_eq!(idx.blocks(tx, ty), &[0], "tile ({tx},{ty})");
        }
        assert!(idx.blocks(1, 1).is_empty());
        let inside = Block { x: 0, y: 0, w: 10, h: 10, s: 20, t: 10 };
        let idx = TileIndex::build(&[inside], 10, 4, 10, 10);
        assert_eq!(idx.blocks(2, 1), &[0]);
        assert!(idx.blocks(3, 1).is_empty());
    }
}
