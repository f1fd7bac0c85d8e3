//! What a client that synthesizes tiles itself needs, in plain Rust: open a bundle within a
//! page's bounds, describe it as the server does, render regions and the server's tiles.
//! [`crate::api`] exports it to JavaScript; the native reference binary (`src/bin/reference.rs`)
//! runs the same code.

use std::sync::Arc;
use vtex_synth::bundle::{id_of, Bundle};
use vtex_synth::models::{self, Limits};
use vtex_synth::texture::{level_size, render_image};
use vtex_synth::{Domain, Region, Texture};
use vtex_wire::info::explicit_bytes;
use vtex_wire::levels::{metatile_tiles, tile_levels};
use vtex_wire::TextureInfo;

/// What one texture may hold and cost in a page: the server's per-tile and build bounds, and
/// at most 1 GiB resident (a wasm32 instance addresses 4 GiB, a tab often less).
pub const LIMITS: Limits = Limits { max_resident_bytes: 1 << 30, ..Limits::SERVE };

/// Largest region one render may ask for: 16 Mpx, 64 MiB of RGBA.
pub const MAX_RENDER_PIXELS: u64 = 1 << 24;

/// Largest tile side: [`crate::api::vtex_render_tile`] answers a tile's width and height in 16
/// bits each.
pub const MAX_TILE_SIZE: u32 = u16::MAX as u32;

/// A texture opened from a bundle and cut into tiles of `info.tile_size`.
pub struct Opened {
    pub texture: Arc<dyn Texture>,
    /// The texture's info exactly as a server with this tile size gives it for the same bytes.
    pub info: TextureInfo,
}

/// Parses, bounds ([`LIMITS`]) and loads bundle `bytes`, to be cut into tiles of `tile_size`;
/// the error names what is wrong.
pub fn open(bytes: &[u8], tile_size: u32) -> Result<Opened, String> {
    if !(1..=MAX_TILE_SIZE).contains(&tile_size) {
        return Err(format!("invalid tile size {tile_size}: from 1 to {MAX_TILE_SIZE}"));
    }
    let bundle = Bundle::from_bytes(bytes).map_err(|e| e.to_string())?;
    let plan = models::plan(&bundle).map_err(|e| e.to_string())?;
    LIMITS.check(&bundle.manifest.model, &plan).map_err(|e| e.to_string())?;
    let texture = models::load(&bundle).map_err(|e| e.to_string())?;
    let (width, height) = (texture.width(), texture.height());
    let manifest = bundle.manifest;
    let info = TextureInfo {
        id: id_of(bytes),
        name: manifest.name,
        model: manifest.model,
        width,
        height,
        levels: tile_levels(width, height, tile_size),
        tile_size,
        metatile: metatile_tiles(tile_size),
        encoding_bytes: bytes.len() as u64,
        explicit_bytes: explicit_bytes(width, height),
        wraps: texture.domain() == Domain::Torus,
        domain: texture.domain(),
        animated: texture.animation().is_some(),
        animation: texture.animation(),
        params: manifest.params,
        derived: manifest.derived,
    };
    Ok(Opened { texture, info })
}

impl Opened {
    /// Renders `region` within [`MAX_RENDER_PIXELS`]: RGBA8 rows, or why not.
    pub fn render(&self, region: &Region) -> Result<Vec<u8>, String> {
        if region.pixel_count() > MAX_RENDER_PIXELS {
            return Err(format!(
                "invalid region: {}×{} is {} pixels; at most {MAX_RENDER_PIXELS} per render here",
                region.width,
                region.height,
                region.pixel_count()
            ));
        }
        render_image(&*self.texture, region).map(|img| img.data).map_err(|e| e.to_string())
    }

    /// The region of tile (`tx`, `ty`) of `level` at `frame`, cut from the origin with edge
    /// tiles clipped to the level, at the levels the info lists: the server's tiles.
    pub fn tile_region(&self, level: u32, tx: u32, ty: u32, frame: u32) -> Result<Region, String> {
        let TextureInfo { width, height, levels, tile_size, .. } = self.info;
        if level >= levels {
            return Err(format!("invalid tile: level {level} does not exist; levels are 0..{levels}"));
        }
        let (lw, lh) = level_size(width, height, level);
        let ts = tile_size as u64;
        let (px, py) = (tx as u64 * ts, ty as u64 * ts);
        if px >= lw || py >= lh {
            let (nx, ny) = (lw.div_ceil(ts), lh.div_ceil(ts));
            return Err(format!("invalid tile: {level}/{tx}/{ty} is outside level {level}'s {nx} × {ny} tiles"));
        }
        let (w, h) = ((lw - px).min(ts) as u32, (lh - py).min(ts) as u32);
        Ok(Region::new(level, px as i64, py as i64, w, h).at_frame(frame))
    }
}
