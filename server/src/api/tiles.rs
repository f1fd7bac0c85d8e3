//! Tiles and regions: validation, ETags, the cache, synthesis.

use super::error::{echo, ApiError};
use super::params::{parse_i64, parse_u32, query_pairs};
use super::{
    lookup, not_modified, not_modified_response, App, CACHE_IMMUTABLE, X_VTEX_CACHE, X_VTEX_HEIGHT, X_VTEX_WIDTH,
};
use crate::cache::{Source, Tile, TileKey};
use crate::config::MAX_REGION_SIDE;
use crate::encode::Format;
use crate::store::Entry;
use axum::body::Body;
use axum::extract::rejection::PathRejection;
use axum::extract::{Path, RawQuery, State};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::Response;
use bytes::Bytes;
use std::sync::Arc;
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::Region;

/// Headers on a tile response, CORS included: reserved at once rather than grown.
const RESPONSE_HEADERS: usize = 12;

/// Version of the tile encoding scheme, part of every ETag: bump it when encoders change.
const ETAG_SCHEME: &[u8] = b"vtex-tile/1";

/// The frame a request renders: animated textures reduce it modulo their period (frames
/// one period apart are identical), still textures ignore it.
pub(super) fn frame_for(entry: &Entry, raw: Option<&str>) -> Result<u32, ApiError> {
    let frame = raw.map(|s| parse_u32("frame", s)).transpose()?.unwrap_or(0);
    Ok(match entry.texture.animation() {
        None => 0,
        Some(a) if a.period_frames > 0 => frame % a.period_frames,
        Some(_) => frame,
    })
}

/// A strong validator: the bytes are a pure function of everything hashed here.
fn etag(texture: &[u8; 32], what: &[u64], format: Format) -> HeaderValue {
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

fn image_response(body: Bytes, format: Format, etag: HeaderValue, width: u32, height: u32) -> Response {
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

pub(super) fn parse_format(s: &str) -> Result<Format, ApiError> {
    Format::parse(s).ok_or_else(|| ApiError::bad_request(format!("unknown format `{}`; {}", echo(s), Format::EXPECTED)))
}

/// `GET /api/v1/textures/{id}/tiles/{level}/{x}/{y}.{format}[?frame=N]` through the router
/// (HEAD, percent-encoded paths); plain GETs take [`tile`] directly (`front`).
pub async fn tile_route(
    State(app): State<App>,
    path: Result<Path<(String, String, String, String)>, PathRejection>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Path((id, level, x, file)) = path.map_err(|e| ApiError::bad_request(e.body_text()))?;
    tile(&app, TilePath { id: &id, level: &level, x: &x, file: &file }, query.as_deref(), &headers).await
}

/// The path segments of a tile request, percent-decoded.
#[derive(Clone, Copy, Debug)]
pub struct TilePath<'a> {
    pub id: &'a str,
    pub level: &'a str,
    pub x: &'a str,
    /// `{y}.{format}`
    pub file: &'a str,
}

impl<'a> TilePath<'a> {
    /// The segments of `/api/v1/textures/{id}/tiles/{level}/{x}/{file}` when no segment is
    /// empty or percent-encoded (then they need no decoding); `None` for anything else.
    pub fn plain(path: &'a str) -> Option<TilePath<'a>> {
        let rest = path.strip_prefix("/api/v1/textures/")?;
        if rest.contains('%') {
            return None;
        }
        let mut it = rest.split('/');
        let (id, tiles, level, x, file) = (it.next()?, it.next()?, it.next()?, it.next()?, it.next()?);
        let plain = tiles == "tiles" && it.next().is_none() && [id, level, x, file].iter().all(|s| !s.is_empty());
        plain.then_some(TilePath { id, level, x, file })
    }
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

/// A tile: validation, 304, the cache, synthesis on a miss.
pub async fn tile(
    app: &App,
    path: TilePath<'_>,
    query: Option<&str>,
    headers: &HeaderMap,
) -> Result<Response, ApiError> {
    let TilePath { id, level, x, file } = path;
    let entry = lookup(app, id)?;
    let level = parse_u32("level", level)?;
    let x = parse_u32("x", x)?;
    let (y, ext) = file.rsplit_once('.').ok_or_else(|| {
        ApiError::bad_request(format!("tile `{}` has no format extension; {}", echo(file), Format::EXPECTED))
    })?;
    let format = parse_format(ext)?;
    let y = parse_u32("y", y)?;
    check_tile(&entry, level, x, y)?;
    let mut frame = None;
    for (k, v) in query_pairs(query)? {
        if k == "frame" {
            frame = Some(v);
        }
    }
    let frame = frame_for(&entry, frame.as_deref())?;
    let key = TileKey { texture: entry.key, level, x, y, frame, format };
    // A cached tile carries its ETag; only a tile not in the cache needs it hashed.
    let cached = app.cache.get(&key);
    let tag = match &cached {
        Some(tile) => tile.etag.clone(),
        None => tile_etag(&entry, &key),
    };
    if not_modified(headers, tag.to_str().unwrap_or_default()) {
        return Ok(not_modified_response(tag));
    }
    let (tile, source) = obtain(app, &entry, key, cached, tag).await?;
    let mut resp = image_response(tile.body.clone(), format, tile.etag.clone(), tile.width, tile.height);
    let cache_state = if source == Source::Hit { "hit" } else { "miss" };
    resp.headers_mut().insert(X_VTEX_CACHE.clone(), HeaderValue::from_static(cache_state));
    Ok(resp)
}

/// The strong ETag of tile `key` of `entry`.
pub(super) fn tile_etag(entry: &Entry, key: &TileKey) -> HeaderValue {
    let what = [key.level as u64, key.x as u64, key.y as u64, key.frame as u64, entry.tile_size as u64];
    etag(&entry.key, &what, key.format)
}

/// Tile `key` (inside `entry`'s pyramid): `cached` when the caller found it in the cache, else
/// from the cache or synthesized, one computation shared by every concurrent request for it,
/// holding a synthesis permit. Counted as a hit or a miss. Single tiles and batches
/// (`batch.rs`) both come through here, so they share the cache, coalescing and bounds.
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
            app.cache
                .get_or_compute(key, || async {
                    let TileKey { level, x, y, frame, format, .. } = key;
                    let ts = entry.tile_size as u64;
                    let (lw, lh) = level_size(entry.texture.width(), entry.texture.height(), level);
                    let (px, py) = (x as u64 * ts, y as u64 * ts);
                    let (w, h) = ((lw - px).min(ts) as u32, (lh - py).min(ts) as u32);
                    let region = Region::new(level, px as i64, py as i64, w, h).at_frame(frame);
                    let send = app.cfg.send;
                    let body = app.synthesize_then(entry.clone(), region, format, move |b| send.seal(b)).await?;
                    Ok::<_, ApiError>(Tile { body, etag: tag, width: w, height: h })
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

/// `GET /api/v1/textures/{id}/region?level=&x=&y=&w=&h=[&format=png][&frame=]`
///
/// Any integer coordinates are allowed (a torus wraps, a plane is defined everywhere);
/// the area is bounded by `--max-region-pixels`. Regions are rendered, not cached.
pub async fn region(
    State(app): State<App>,
    path: Result<Path<String>, PathRejection>,
    RawQuery(query): RawQuery,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let Path(id) = path.map_err(|e| ApiError::bad_request(e.body_text()))?;
    let entry = lookup(&app, &id)?;
    let (mut level, mut x, mut y, mut w, mut h, mut format, mut frame) = (None, None, None, None, None, None, None);
    for (k, v) in query_pairs(query.as_deref())? {
        match k.as_str() {
            "level" => level = Some(parse_u32("level", &v)?),
            "x" => x = Some(parse_i64("x", &v)?),
            "y" => y = Some(parse_i64("y", &v)?),
            "w" => w = Some(parse_u32("w", &v)?),
            "h" => h = Some(parse_u32("h", &v)?),
            "format" => format = Some(parse_format(&v)?),
            "frame" => frame = Some(v),
            other => {
                return Err(ApiError::bad_request(format!(
                    "unknown query parameter `{}`; expected level, x, y, w, h, format, frame",
                    echo(other)
                )))
            }
        }
    }
    fn need<T>(v: Option<T>, name: &str) -> Result<T, ApiError> {
        v.ok_or_else(|| ApiError::bad_request(format!("missing query parameter `{name}`")))
    }
    let (level, x, y, w, h) = (need(level, "level")?, need(x, "x")?, need(y, "y")?, need(w, "w")?, need(h, "h")?);
    let format = format.unwrap_or(Format::Png);
    let frame = frame_for(&entry, frame.as_deref())?;
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
    let body = app.synthesize(entry, region, format).await?;
    Ok(image_response(Bytes::from(body), format, tag, w, h))
}
