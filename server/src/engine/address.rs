//! Where a tile or page is, what it renders, and its ETag: the addressing every route that
//! serves tiles, pages or renders shares.

use super::cache::{Shape, TileKey};
use super::Error;
use crate::encode::Format;
use crate::store::Entry;
use bytes::Bytes;
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::Region;

/// Version of the tile encoding scheme, part of every ETag: bump it when encoders change.
const ETAG_SCHEME: &[u8] = b"vtex-tile/2";

/// What an ETag names, its first hashed field: it sets the resources apart that could
/// otherwise hash the same fields (a tile is unmarked: its fields are its own).
#[derive(Clone, Copy, Debug)]
pub enum Mark {
    /// A region of `GET …/region`.
    Region,
    /// A page of the page grid.
    Page,
    /// A KTX2 mip chain.
    Chain,
    /// An edge tile drawn on the whole square ([`Shape::Square`]).
    Square,
    /// A Deep Zoom tile with its overlap.
    Dzi,
    /// A IIIF Image API image.
    Iiif,
    /// A metatile.
    Metatile,
    /// A page metatile.
    PageMetatile,
}

impl Mark {
    /// The hashed value. ETags are compared per URL, so the region's and Deep Zoom's sharing
    /// one is harmless.
    fn value(self) -> u64 {
        match self {
            Mark::Region | Mark::Dzi => 1 << 63,
            Mark::Page => 2 << 61,
            Mark::Chain => 3 << 61,
            Mark::Square => 5 << 61,
            Mark::Iiif => 3 << 62,
            Mark::Metatile => 7 << 61,
            Mark::PageMetatile => 1 << 61,
        }
    }
}

/// A strong validator, `"…"` with 32 hex digits: the bytes it names are a pure function of
/// everything hashed into it.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct ETag(Bytes);

impl ETag {
    /// The ETag of texture `texture`'s resource `what` (after its [`Mark`], if any) in `format`.
    pub fn new(texture: &[u8; 32], mark: Option<Mark>, what: &[u64], format: Format) -> ETag {
        let mut h = blake3::Hasher::new();
        h.update(ETAG_SCHEME);
        h.update(texture);
        for v in mark.map(Mark::value).iter().chain(what) {
            h.update(&v.to_le_bytes());
        }
        h.update(format.ext().as_bytes());
        let hex = h.finalize().to_hex();
        ETag(Bytes::from(format!("\"{}\"", &hex[..32])))
    }

    pub fn as_str(&self) -> &str {
        std::str::from_utf8(&self.0).expect("quotes and hex digits")
    }

    /// Its bytes, shared (for a header value without a copy).
    pub fn bytes(&self) -> Bytes {
        self.0.clone()
    }
}

/// The frame a request renders: animated textures reduce it modulo their period (frames one
/// period apart are identical), still textures ignore it.
pub fn frame_for(entry: &Entry, frame: Option<u32>) -> u32 {
    let frame = frame.unwrap_or(0);
    match entry.texture.animation() {
        None => 0,
        Some(a) if a.period_frames > 0 => frame % a.period_frames,
        Some(_) => frame,
    }
}

/// Whether `entry` serves tile (`level`, `x`, `y`): a level it does not serve is invalid, a
/// tile outside its level missing (a client may probe the pyramid's edge).
pub fn check_tile(entry: &Entry, level: u32, x: u32, y: u32) -> Result<(), Error> {
    if level >= entry.levels {
        return Err(Error::Invalid(format!(
            "tile {level}/{x}/{y}: level {level} does not exist; this texture serves levels 0..={}",
            entry.levels - 1
        )));
    }
    let (cols, rows) = entry.tiles_at(level);
    if x as u64 >= cols || y as u64 >= rows {
        return Err(Error::Missing(format!(
            "tile {level}/{x}/{y} is outside level {level}, which has {cols}×{rows} tiles"
        )));
    }
    Ok(())
}

/// Whether `entry` serves metatile (`level`, `x`, `y`) of `side` × `side` parts (tiles or pages
/// of shape `part`): as [`check_tile`] and [`check_page`] for its grid of blocks.
pub fn check_metatile(entry: &Entry, level: u32, x: u32, y: u32, part: Shape, side: u32) -> Result<(), Error> {
    let (levels, what) = match part {
        Shape::Page { size, .. } => {
            (level_count(entry.texture.width(), entry.texture.height()), format!("pages of {size}²"))
        }
        _ => (entry.levels, "tiles".to_string()),
    };
    if level >= levels {
        return Err(Error::Invalid(format!(
            "metatile {level}/{x}/{y}: level {level} does not exist; this texture serves levels 0..={}",
            levels - 1
        )));
    }
    let (cols, rows) = grid(entry, level, part);
    let (cols, rows) = (cols.div_ceil(side as u64), rows.div_ceil(side as u64));
    if x as u64 >= cols || y as u64 >= rows {
        return Err(Error::Missing(format!(
            "metatile {level}/{x}/{y} is outside level {level}, which has {cols}×{rows} metatiles of {side}×{side} {what}"
        )));
    }
    Ok(())
}

/// Columns and rows of `level`'s grid of tiles, or of pages.
fn grid(entry: &Entry, level: u32, part: Shape) -> (u64, u64) {
    match part {
        Shape::Page { size, .. } => page_grid(entry.texture.width(), entry.texture.height(), level, size),
        _ => entry.tiles_at(level),
    }
}

/// The metatile holding tile or page `key` of `entry` (a [`Shape::Tile`] or [`Shape::Page`]),
/// and where it is in it (its frame's index, row by row); `None` for other shapes.
pub fn metatile_of(entry: &Entry, key: &TileKey) -> Option<(TileKey, usize)> {
    let (side, block) = match key.shape {
        Shape::Tile => (entry.metatile, Shape::Metatile { side: entry.metatile }),
        Shape::Page { size, border, layer } => {
            let side = page_metatile_pages(size);
            (side, Shape::PageMetatile { size, border, side, layer })
        }
        _ => return None,
    };
    let (cols, _) = grid(entry, key.level, key.shape);
    let (mx, my) = (key.x / side, key.y / side);
    let width = (cols - (mx * side) as u64).min(side as u64) as usize;
    let index = (key.y - my * side) as usize * width + (key.x - mx * side) as usize;
    Some((TileKey { x: mx, y: my, shape: block, ..*key }, index))
}

/// Pages a side of a page metatile, for pages of side `size`: as many as make the metatile's
/// level pixels.
pub fn page_metatile_pages(size: u32) -> u32 {
    vtex_wire::levels::metatile_tiles(size)
}

/// The parts of metatile `key` of `entry` (tiles or pages), row by row, each with its region.
pub fn metatile_parts(entry: &Entry, key: &TileKey) -> Vec<(TileKey, Region)> {
    let (side, part) = match key.shape {
        Shape::Metatile { side } => (side, Shape::Tile),
        Shape::PageMetatile { size, border, side, layer } => (side, Shape::Page { size, border, layer }),
        _ => panic!("not a metatile: {key:?}"),
    };
    let (cols, rows) = grid(entry, key.level, part);
    let (x0, y0) = (key.x * side, key.y * side);
    let (x1, y1) = (((x0 + side) as u64).min(cols) as u32, ((y0 + side) as u64).min(rows) as u32);
    (y0..y1)
        .flat_map(|y| (x0..x1).map(move |x| (x, y)))
        .map(|(x, y)| {
            let part = TileKey { x, y, shape: part, ..*key };
            (part, key_region(entry, &part).0)
        })
        .collect()
}

/// Whether `entry` serves page (`level`, `x`, `y`) of side `size`: a level it does not have is
/// invalid, a page outside the level's grid missing.
pub fn check_page(entry: &Entry, level: u32, x: u32, y: u32, size: u32) -> Result<(), Error> {
    let (w, h) = (entry.texture.width(), entry.texture.height());
    let levels = level_count(w, h);
    if level >= levels {
        return Err(Error::Invalid(format!(
            "page {level}/{x}/{y}: level {level} does not exist; pages are served at levels 0..={} (down to 1×1)",
            levels - 1
        )));
    }
    let (cols, rows) = page_grid(w, h, level, size);
    if x as u64 >= cols || y as u64 >= rows {
        return Err(Error::Missing(format!(
            "page {level}/{x}/{y} is outside level {level}, which has {cols}×{rows} pages of {size}²"
        )));
    }
    Ok(())
}

/// Columns and rows of pages of side `size` covering `level`.
pub fn page_grid(width: u64, height: u64, level: u32, size: u32) -> (u64, u64) {
    let (lw, lh) = level_size(width, height, level);
    (lw.div_ceil(size as u64), lh.div_ceil(size as u64))
}

/// The shape of tile (`level`, `x`, `y`) of `entry` for clients that draw every tile as a full
/// square: a whole tile is the tile API's own (same cache entry, bytes and ETag), a tile the
/// level's edge cuts is a [`Shape::Square`].
pub fn square_shape(entry: &Entry, level: u32, x: u32, y: u32) -> Shape {
    let ts = entry.tile_size as u64;
    let (lw, lh) = level_size(entry.texture.width(), entry.texture.height(), level);
    if (x as u64 + 1) * ts <= lw && (y as u64 + 1) * ts <= lh {
        Shape::Tile
    } else {
        Shape::Square
    }
}

/// The strong ETag of tile or page `key` of `entry`.
pub fn key_etag(entry: &Entry, key: &TileKey) -> ETag {
    let (level, x, y, frame) = (key.level as u64, key.x as u64, key.y as u64, key.frame as u64);
    match key.shape {
        Shape::Tile => ETag::new(&entry.key, None, &[level, x, y, frame, entry.tile_size as u64], key.format),
        Shape::Square => {
            ETag::new(&entry.key, Some(Mark::Square), &[level, x, y, frame, entry.tile_size as u64], key.format)
        }
        Shape::Metatile { side } => ETag::new(
            &entry.key,
            Some(Mark::Metatile),
            &[level, x, y, frame, entry.tile_size as u64, side as u64],
            key.format,
        ),
        Shape::Page { size, border, layer } => {
            let (codec, sc) = ktx2_ids(key.format);
            let what = [level, x, y, frame, size as u64, border as u64, codec, sc, layer as u64];
            ETag::new(&entry.key, Some(Mark::Page), &what, key.format)
        }
        Shape::PageMetatile { size, border, side, layer } => {
            let (codec, sc) = ktx2_ids(key.format);
            let what = [level, x, y, frame, size as u64, border as u64, codec, sc, side as u64, layer as u64];
            ETag::new(&entry.key, Some(Mark::PageMetatile), &what, key.format)
        }
    }
}

/// A page format's KTX2 codec and supercompression as hashed into ETags: 0 for image formats.
pub fn ktx2_ids(format: Format) -> (u64, u64) {
    match format {
        Format::Ktx2(k) => (1 + k.codec as u64, 1 + k.supercompression as u64),
        _ => (0, 0),
    }
}

/// The region tile or page `key` of `entry` renders, and the canvas it is drawn on (at its top
/// left, transparent beyond).
pub fn key_region(entry: &Entry, key: &TileKey) -> (Region, (u32, u32)) {
    match key.shape {
        Shape::Tile | Shape::Square => {
            let ts = entry.tile_size as u64;
            let (lw, lh) = level_size(entry.texture.width(), entry.texture.height(), key.level);
            let (px, py) = (key.x as u64 * ts, key.y as u64 * ts);
            let (w, h) = ((lw - px).min(ts) as u32, (lh - py).min(ts) as u32);
            let canvas = if key.shape == Shape::Square { (ts as u32, ts as u32) } else { (w, h) };
            (Region::new(key.level, px as i64, py as i64, w, h).at_frame(key.frame), canvas)
        }
        Shape::Metatile { .. } | Shape::PageMetatile { .. } => {
            let parts = metatile_parts(entry, key);
            let (first, last) = (parts[0].1, parts[parts.len() - 1].1);
            let (w, h) = ((last.x - first.x) as u32 + last.width, (last.y - first.y) as u32 + last.height);
            (Region::new(key.level, first.x, first.y, w, h).at_frame(key.frame), (w, h))
        }
        Shape::Page { size, border, .. } => {
            let at = |v: u32| v as i64 * size as i64 - border as i64;
            let side = size + 2 * border;
            (Region::new(key.level, at(key.x), at(key.y), side, side).at_frame(key.frame), (side, side))
        }
    }
}
