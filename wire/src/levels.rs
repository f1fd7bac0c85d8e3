//! Mip levels: level L of a `width × height` texture is `⌈width / 2^L⌉ × ⌈height / 2^L⌉`, down
//! to 1 × 1.

/// Size of `level` for a texture of `width × height` at level 0.
pub fn level_size(width: u64, height: u64, level: u32) -> (u64, u64) {
    let d = |v: u64| if level >= 64 { 1 } else { v.div_ceil(1u64 << level).max(1) };
    (d(width), d(height))
}

/// Number of levels down to 1 × 1 inclusive.
pub fn level_count(width: u64, height: u64) -> u32 {
    let side = width.max(height).max(1);
    // ceil(log2(side)) + 1
    (64 - (side - 1).leading_zeros()) + 1
}

/// Number of levels served as tiles of side `tile_size` (at least 1): down to the first level
/// that fits in one tile, the `levels` of [`TextureInfo`](crate::TextureInfo).
pub fn tile_levels(width: u64, height: u64, tile_size: u32) -> u32 {
    // Level L fits in one tile when ⌈side / 2^L⌉ ≤ tile_size, i.e. when 2^L ≥ ⌈side / tile_size⌉.
    let ts = tile_size as u64;
    level_count(width.div_ceil(ts), height.div_ceil(ts))
}

/// Columns and rows of squares of side `size` (tiles, pages) covering `level`.
pub fn grid(width: u64, height: u64, level: u32, size: u32) -> (u64, u64) {
    let (lw, lh) = level_size(width, height, level);
    (lw.div_ceil(size as u64), lh.div_ceil(size as u64))
}

/// Level pixels a side of a metatile: the unit a viewer fetches and a cache in front shares.
/// Larger blocks render no cheaper a tile for any model (`synth/examples/metatile_costs.rs`),
/// while a view at a block's edge fetches more of it the larger it is.
pub const METATILE_PIXELS: u32 = 512;

/// Tiles a side of a metatile, for tiles of side `tile_size`: at least 1.
pub fn metatile_tiles(tile_size: u32) -> u32 {
    (METATILE_PIXELS / tile_size.max(1)).max(1)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn levels_halve_rounding_up_down_to_one_pixel() {
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(100_000, 100_000), 18);
        assert_eq!(level_size(100_000, 3, 1), (50_000, 2));
        assert_eq!(level_size(100_000, 3, 17), (1, 1));
        assert_eq!(level_size(5, 5, 200), (1, 1));
        assert_eq!(grid(1000, 300, 0, 256), (4, 2));
        assert_eq!(grid(1000, 300, 2, 128), (2, 1));
    }

    #[test]
    fn tile_levels_end_at_the_first_level_in_one_tile() {
        for (w, h) in [(1, 1), (256, 256), (257, 3), (100_000, 100_000), (3, 70_001), (512, 511)] {
            for ts in [1, 16, 255, 256, 2048] {
                let levels = tile_levels(w, h, ts);
                assert_eq!(grid(w, h, levels - 1, ts), (1, 1), "{w}×{h}, tiles of {ts}");
                assert!(levels == 1 || grid(w, h, levels - 2, ts) != (1, 1), "{w}×{h}, tiles of {ts}");
            }
        }
        assert_eq!(tile_levels(100_000, 100_000, 256), 10);
    }

    #[test]
    fn metatiles_are_512_pixels_a_side_or_one_tile() {
        assert_eq!(metatile_tiles(256), 2);
        assert_eq!(metatile_tiles(128), 4);
        assert_eq!(metatile_tiles(300), 1);
        assert_eq!(metatile_tiles(4096), 1);
        assert_eq!(metatile_tiles(0), 512);
    }
}
