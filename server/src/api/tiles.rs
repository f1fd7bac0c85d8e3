//! Tiles and regions: validation, ETags, the cache, synthesis.

use super::error::{echo, ApiError};
use super::extract::{Path, Query};
use super::openapi::text;
use super::openapi::ErrorBody;
use super::pages;
use super::params::{de, format_value, named, u32_value};
use super::{
    lookup, not_modified, not_modified_response, App, TextureId, CACHE_IMMUTABLE, X_VTEX_CACHE, X_VTEX_HEIGHT,
    X_VTEX_WIDTH,
};
use crate::cache::{Shape, Source, Tile, TileKey};
use crate::config::MAX_REGION_SIDE;
use crate::encode::{self, Format};
use crate::store::Entry;
use axum::body::Body;
use axum::extract::State;
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::Response;
use bytes::Bytes;
use serde::Deserialize;
use std::sync::Arc;
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::Region;

/// Headers on a tile response, CORS included: reserved at once rather than grown.
const RESPONSE_HEADERS: usize = 12;

/// Version of the tile encoding scheme, part of every ETag: bump it when encoders change.
const ETAG_SCHEME: &[u8] = b"vtex-tile/2";
/// ETag field that sets square edge tiles apart from the clipped tiles at the same address
/// (regions are marked 4 << 61, pages 2 and 3 << 61).
const SQUARE_MARK: u64 = 5 << 61;

/// The frame a request renders: animated textures reduce it modulo their period (frames
/// one period apart are identical), still textures ignore it.
pub(super) fn frame_for(entry: &Entry, frame: Option<u32>) -> u32 {
    let frame = frame.unwrap_or(0);
    match entry.texture.animation() {
        None => 0,
        Some(a) if a.period_frames > 0 => frame % a.period_frames,
        Some(_) => frame,
    }
}

/// A strong validator: the bytes are a pure function of everything hashed here.
pub(super) fn etag(texture: &[u8; 32], what: &[u64], format: Format) -> HeaderValue {
    let mut h = blake3::Hasher::new();
    h.update(ETAG_SCHEME);
    h.update(texture);
    for v in what {
        h.update(&v.to_le_bytes());
    }
    h.update(format.ext().as_bytes());
    let hex = h.finalize().to_hex();
    HeaderValue::from_str(&format!("\"{}\"", &hex[..32])).expect("hex is a valid header value")
}

pub(super) fn image_response(body: Bytes, format: Format, etag: HeaderValue, width: u32, height: u32) -> Response {
    let mut resp = Response::new(Body::from(body));
    let h = resp.headers_mut();
    h.reserve(RESPONSE_HEADERS);
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(format.content_type()));
    h.insert(header::ETAG, etag);
    h.insert(header::CACHE_CONTROL, CACHE_IMMUTABLE);
    h.insert(X_VTEX_WIDTH.clone(), HeaderValue::from(width));
    h.insert(X_VTEX_HEIGHT.clone(), HeaderValue::from(height));
    resp
}

/// The path of a tile: `/api/v1/textures/{id}/tiles/{level}/{x}/{file}`, `file` being
/// `{y}.{format}`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TilePath {
    pub id: String,
    #[serde(deserialize_with = "de::u32")]
    pub level: u32,
    #[serde(deserialize_with = "de::u32")]
    pub x: u32,
    pub file: String,
}

/// The query of a tile: `[?frame=N]`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TileQuery {
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub frame: Option<u32>,
}

/// Whether `entry` serves tile (`level`, `x`, `y`): a level it does not serve is a 400, a tile
/// outside its level a 404 (a client may probe the pyramid's edge).
pub(super) fn check_tile(entry: &Entry, level: u32, x: u32, y: u32) -> Result<(), ApiError> {
    if level >= entry.levels {
        return Err(ApiError::bad_request(format!(
            "tile {level}/{x}/{y}: level {level} does not exist; this texture serves levels 0..={}",
            entry.levels - 1
        )));
    }
    let (cols, rows) = entry.tiles_at(level);
    if x as u64 >= cols || y as u64 >= rows {
        return Err(ApiError::not_found(format!(
            "tile {level}/{x}/{y} is outside level {level}, which has {cols}×{rows} tiles"
        )));
    }
    Ok(())
}

/// `GET /api/v1/textures/{id}/tiles/{level}/{x}/{y}.{format}[?frame=N]` (the route
/// [`TILE`](super::TILE)).
#[utoipa::path(get,
    path = super::TILE,
    tag = "tiles",
    params(
        ("id" = String, Path, description = text::TEXTURE_ID),
        ("level" = u32, Path, description = "mip level, 0 full resolution"),
        ("x" = u32, Path, description = "tile column"),
        ("file" = String, Path, description = "`{y}.{format}`, format png, webp, jpg or rgba (raw RGBA8)"),
        ("frame" = Option<u32>, Query, description = text::FRAME),
    ),
    responses(
        (status = 200, description = "the tile (edge tiles clipped; strong ETag, \
            immutable)", content(("image/png"), ("image/webp"), ("image/jpeg"), ("application/octet-stream"))),
        (status = 304, description = "`If-None-Match` names its ETag"),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn tile(
    State(app): State<App>,
    Path(path): Path<TilePath>,
    Query(query): Query<TileQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    answer(&app, path, query, &headers).await
}

/// A tile: validation, 304, the cache, synthesis on a miss — for the router and for the
/// fast path of [`Front`](super::Front) alike.
pub(super) async fn answer(
    app: &App,
    TilePath { id, level, x, file }: TilePath,
    TileQuery { frame }: TileQuery,
    headers: &HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(app, &id).await?;
    let (y, ext) = file.rsplit_once('.').ok_or_else(|| {
        ApiError::bad_request(format!("tile `{}` has no format extension; {}", echo(&file), Format::EXPECTED))
    })?;
    let format = named("format", ext, format_value)?;
    let y = named("y", y, u32_value)?;
    check_tile(&entry, level, x, y)?;
    let frame = frame_for(&entry, frame);
    let key = TileKey { texture: entry.key, level, x, y, frame, format, shape: Shape::Tile };
    respond(app, &entry, key, headers).await
}

/// The response for tile `key` of `entry` (inside its pyramid): 304, or the tile from the
/// cache or synthesized — for every route that serves tiles (tiles, Deep Zoom, IIIF, XYZ).
pub(super) async fn respond(
    app: &App,
    entry: &Arc<Entry>,
    key: TileKey,
    headers: &HeaderMap,
) -> Result<Response, ApiError> {
    // A cached tile carries its ETag; only a tile not in the cache needs it hashed.
    let cached = app.cache.get(&key);
    let tag = match &cached {
        Some(tile) => tile.etag.clone(),
        None => key_etag(entry, &key),
    };
    if not_modified(headers, tag.to_str().unwrap_or_default()) {
        return Ok(not_modified_response(tag));
    }
    let (tile, source) = obtain(app, entry, key, cached, tag).await?;
    let mut resp = image_response(tile.body.clone(), key.format, tile.etag.clone(), tile.width, tile.height);
    let cache_state = if source == Source::Hit { "hit" } else { "miss" };
    resp.headers_mut().insert(X_VTEX_CACHE.clone(), HeaderValue::from_static(cache_state));
    Ok(resp)
}

/// The strong ETag of tile or page `key` of `entry`.
pub(super) fn key_etag(entry: &Entry, key: &TileKey) -> HeaderValue {
    let tile = [key.level as u64, key.x as u64, key.y as u64, key.frame as u64, entry.tile_size as u64];
    match key.shape {
        Shape::Tile => etag(&entry.key, &tile, key.format),
        Shape::Square => etag(&entry.key, &[SQUARE_MARK, tile[0], tile[1], tile[2], tile[3], tile[4]], key.format),
        Shape::Page { size, border } => pages::page_etag(entry, key, size, border),
    }
}

/// The shape of tile (`level`, `x`, `y`) of `entry` for clients that draw every tile as a full
/// square: a whole tile is the tile API's own (same cache entry, bytes and ETag), a tile the
/// level's edge cuts is a [`Shape::Square`].
pub(super) fn square_shape(entry: &Entry, level: u32, x: u32, y: u32) -> Shape {
    let ts = entry.tile_size as u64;
    let (lw, lh) = level_size(entry.texture.width(), entry.texture.height(), level);
    if (x as u64 + 1) * ts <= lw && (y as u64 + 1) * ts <= lh {
        Shape::Tile
    } else {
        Shape::Square
    }
}

/// The region tile or page `key` of `entry` renders, and the canvas it is drawn on (at its top
/// left, transparent beyond).
fn key_region(entry: &Entry, key: &TileKey) -> (Region, (u32, u32)) {
    match key.shape {
        Shape::Tile | Shape::Square => {
            let ts = entry.tile_size as u64;
            let (lw, lh) = level_size(entry.texture.width(), entry.texture.height(), key.level);
            let (px, py) = (key.x as u64 * ts, key.y as u64 * ts);
            let (w, h) = ((lw - px).min(ts) as u32, (lh - py).min(ts) as u32);
            let canvas = if key.shape == Shape::Square { (ts as u32, ts as u32) } else { (w, h) };
            (Region::new(key.level, px as i64, py as i64, w, h).at_frame(key.frame), canvas)
        }
        Shape::Page { size, border } => {
            let region = pages::page_region(key, size, border);
            let canvas = (region.width, region.height);
            (region, canvas)
        }
    }
}

/// Tile or page `key` (inside `entry`'s pyramid or page grid): `cached` when the caller found it
/// in the cache, else from the cache or synthesized, one computation shared by every concurrent
/// request for it (holding a synthesis slot, and stopped once none of them waits any more).
/// Counted as a hit or a miss. Single tiles and batches (`batch.rs`) both come through here, so
/// they share the cache, coalescing and bounds.
pub(super) async fn obtain(
    app: &App,
    entry: &Arc<Entry>,
    key: TileKey,
    cached: Option<Arc<Tile>>,
    tag: HeaderValue,
) -> Result<(Arc<Tile>, Source), ApiError> {
    let (tile, source) = match cached {
        Some(tile) => (tile, Source::Hit),
        None => {
            let (owner, entry) = (app.clone(), entry.clone());
            app.cache
                .get_or_compute(key, move || async move {
                    let (region, (width, height)) = key_region(&entry, &key);
                    let send = owner.cfg.send;
                    let body = owner
                        .synthesize_then(entry, region, (width, height), key.format, move |b| send.seal(b))
                        .await?;
                    Ok(Tile { body, etag: tag, width, height })
                })
                .await?
        }
    };
    match source {
        Source::Hit => app.metrics.cache_hit(key.level),
        Source::Miss => app.metrics.cache_miss(key.level),
    }
    Ok((tile, source))
}

/// The query of a region.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct RegionQuery {
    #[serde(deserialize_with = "de::u32")]
    pub level: u32,
    #[serde(deserialize_with = "de::i64")]
    pub x: i64,
    #[serde(deserialize_with = "de::i64")]
    pub y: i64,
    #[serde(deserialize_with = "de::u32")]
    pub w: u32,
    #[serde(deserialize_with = "de::u32")]
    pub h: u32,
    #[serde(default, deserialize_with = "de::opt_format")]
    pub format: Option<Format>,
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub frame: Option<u32>,
}

/// `GET /api/v1/textures/{id}/region?level=&x=&y=&w=&h=[&format=png][&frame=]`
///
/// Any integer coordinates are allowed (a torus wraps, a plane is defined everywhere);
/// the area is bounded by `--max-region-pixels`. Regions are rendered, not cached: each one
/// reserves its peak bytes from the in-flight budget before it waits for a slot, keeps its
/// body's length reserved until the body is sent or dropped, and is a 503 when the budget is
/// spent.
#[utoipa::path(get,
    path = "/api/v1/textures/{id}/region",
    tag = "tiles",
    params(
        ("id" = String, Path, description = text::TEXTURE_ID),
        ("level" = u32, Query),
        ("x" = i64, Query, description = "any integer: a torus wraps, a plane is defined everywhere"),
        ("y" = i64, Query),
        ("w" = u32, Query),
        ("h" = u32, Query, description = "w × h at most `--max-region-pixels`, 16383 a side"),
        ("format" = Option<String>, Query, description = "png (default), webp, jpg or rgba"),
        ("frame" = Option<u32>, Query, description = text::FRAME),
    ),
    responses(
        (status = 200, description = "the region, rendered", content(("image/png"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn region(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    Query(q): Query<RegionQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(&app, &id).await?;
    let RegionQuery { level, x, y, w, h, format, frame } = q;
    let format = format.unwrap_or(Format::Png);
    let frame = frame_for(&entry, frame);
    let levels = level_count(entry.texture.width(), entry.texture.height());
    if level >= levels {
        return Err(ApiError::bad_request(format!("level {level} does not exist; levels are 0..={}", levels - 1)));
    }
    let max = app.cfg.max_region_pixels;
    if w == 0 || h == 0 || w > MAX_REGION_SIDE || h > MAX_REGION_SIDE || w as u64 * h as u64 > max {
        return Err(ApiError::bad_request(format!(
            "region {w}×{h} is outside the limits: 1..={MAX_REGION_SIDE} pixels a side and at most {max} pixels in all"
        )));
    }
    let tag = etag(&entry.key, &[1 << 63, level as u64, x as u64, y as u64, w as u64, h as u64, frame as u64], format);
    if not_modified(&headers, tag.to_str().unwrap_or_default()) {
        return Ok(not_modified_response(tag));
    }
    let region = Region::new(level, x, y, w, h).at_frame(frame);
    vtex_synth::texture::check_region(&*entry.texture, &region)?;
    let mut reservation = app.inflight.reserve(encode::peak_bytes(format, w, h))?;
    let body = app.synthesize(entry, region, format).await?;
    app.inflight.resize(&mut reservation, body.len() as u64)?;
    Ok(image_response(reservation.hold(body), format, tag, w, h))
}
