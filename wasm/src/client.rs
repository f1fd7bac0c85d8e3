//! What a client that synthesizes tiles itself needs, in plain Rust: open a bundle within a
//! page's bounds, describe it, render regions and the server's tiles. [`crate::api`] exports
//! it to JavaScript; the native reference binary (`src/bin/reference.rs`) runs the same code.

use serde::Serialize;
use std::sync::Arc;
use vtex_synth::bundle::{id_of, Bundle};
use vtex_synth::models::{self, Limits};
use vtex_synth::texture::{level_count, level_size, render_image};
use vtex_synth::{Animation, Domain, Region, Texture};

/// What one texture may hold and cost in a page: the server's per-tile and build bounds, and
/// at most 1 GiB resident (a wasm32 instance addresses 4 GiB, a tab often less).
pub const LIMITS: Limits = Limits { max_resident_bytes: 1 << 30, ..Limits::SERVE };

/// Largest region one render may ask for: 16 Mpx, 64 MiB of RGBA.
pub const MAX_RENDER_PIXELS: u64 = 1 << 24;

/// A texture opened from a bundle, and what a client shows of it.
pub struct Opened {
    pub texture: Arc<dyn Texture>,
    pub info: Info,
}

/// An opened texture's description, as JSON for JavaScript; the field names are the server's
/// texture info's, except `levels`, which counts every level down to 1 × 1 here (the server
/// stops at the first level that fits in one tile).
#[derive(Clone, Debug, Serialize)]
pub struct Info {
    /// The bundle's content id: the server's texture id when the bytes are the server's.
    pub id: String,
    pub name: String,
    pub model: String,
    pub width: u64,
    pub height: u64,
    pub levels: u32,
    pub domain: Domain,
    pub wraps: bool,
    pub animated: bool,
    pub animation: Option<Animation>,
    pub encoding_bytes: u64,
}

/// Parses, bounds ([`LIMITS`]) and loads bundle `bytes`; the error names what is wrong.
pub fn open(bytes: &[u8]) -> Result<Opened, String> {
    let bundle = Bundle::from_bytes(bytes).map_err(|e| e.to_string())?;
    let plan = models::plan(&bundle).map_err(|e| e.to_string())?;
    LIMITS.check(&bundle.manifest.model, &plan).map_err(|e| e.to_string())?;
    let texture = models::load(&bundle).map_err(|e| e.to_string())?;
    let info = Info {
        id: id_of(bytes),
        name: bundle.manifest.name.clone(),
        model: texture.model().to_string(),
        width: texture.width(),
        height: texture.height(),
        levels: level_count(texture.width(), texture.height()),
        domain: texture.domain(),
        wraps: texture.domain() == Domain::Torus,
        animated: texture.animation().is_some(),
        animation: texture.animation(),
        encoding_bytes: bytes.len() as u64,
    };
    Ok(Opened { texture, info })
}

/// Renders `region` within [`MAX_RENDER_PIXELS`]: RGBA8 rows, or why not.
pub fn render(texture: &dyn Texture, region: &Region) -> Result<Vec<u8>, String> {
    if region.pixel_count() > MAX_RENDER_PIXELS {
        return Err(format!(
            "invalid region: {}×{} is {} pixels; at most {MAX_RENDER_PIXELS} per render here",
            region.width,
            region.height,
            region.pixel_count()
        ));
    }
    render_image(texture, region).map(|img| img.data).map_err(|e| e.to_string())
}

/// The region of tile (`tx`, `ty`) of `level` at `frame` when the texture is cut into tiles of
/// `tile_size` from the origin, edge tiles clipped to the level: the server's tiles.
pub fn tile_region(
    texture: &dyn Texture,
    tile_size: u32,
    level: u32,
    tx: u32,
    ty: u32,
    frame: u32,
) -> Result<Region, String> {
    if tile_size == 0 {
        return Err("invalid tile: the tile size is 0".into());
    }
    let levels = level_count(texture.width(), texture.height());
    if level >= levels {
        return Err(format!("invalid tile: level {level} does not exist; levels are 0..{levels}"));
    }
    let (lw, lh) = level_size(texture.width(), texture.height(), level);
    let ts = tile_size as u64;
    let (px, py) = (tx as u64 * ts, ty as u64 * ts);
    if px >= lw || py >= lh {
        let (nx, ny) = (lw.div_ceil(ts), lh.div_ceil(ts));
        return Err(format!("invalid tile: {level}/{tx}/{ty} is outside level {level}'s {nx} × {ny} tiles"));
    }
    let (w, h) = ((lw - px).min(ts) as u32, (lh - py).min(ts) as u32);
    Ok(Region::new(level, px as i64, py as i64, w, h).at_frame(frame))
}
