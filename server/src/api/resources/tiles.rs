//! Tiles and regions: validation, ETags, the cache, synthesis.

use crate::api::error::ApiError;
use crate::api::extract::{Path, Query};
use crate::api::http::{
    not_modified, not_modified_response, CACHE_IMMUTABLE, X_VTEX_CACHE, X_VTEX_HEIGHT, X_VTEX_WIDTH,
};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::params::{de, format_value, row_and_format};
use crate::api::state::{lookup, App, TextureId};
use crate::config::MAX_REGION_SIDE;
use crate::encode::{self, Format};
use crate::engine::address;
use crate::engine::cache::{Shape, Source, TileKey};
use crate::engine::{ETag, Mark};
use crate::store::Entry;
use axum::body::Body;
use axum::extract::State;
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::Response;
use bytes::Bytes;
use serde::Deserialize;
use std::sync::Arc;
use utoipa::IntoParams;
use vtex_synth::layer::Layer;
use vtex_synth::texture::level_count;
use vtex_synth::Region;

/// Headers on a tile response, CORS included: reserved at once rather than grown.
const RESPONSE_HEADERS: usize = 12;

pub(in crate::api) fn image_response(body: Bytes, format: Format, etag: &ETag, width: u32, height: u32) -> Response {
    let mut resp = Response::new(Body::from(body));
    let h = resp.headers_mut();
    h.reserve(RESPONSE_HEADERS);
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(format.content_type()));
    h.insert(header::ETAG, crate::api::http::etag_header(etag));
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
#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct TileQuery {
    /// frame of an animated texture (reduced modulo its period); ignored for still ones
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub frame: Option<u32>,
}

/// `GET /api/v1/textures/{id}/tiles/{level}/{x}/{y}.{format}[?frame=N]`: one tile of the
/// pyramid.
#[utoipa::path(get,
    path = vtex_wire::urls::TILE,
    tag = "tiles",
    params(
        ("id" = String, Path, description = text::TEXTURE_ID),
        ("level" = u32, Path, description = "mip level, 0 full resolution"),
        ("x" = u32, Path, description = "tile column"),
        ("file" = String, Path, description = "`{y}.{format}`, format png, webp, jpg or rgba (raw RGBA8)"),
        TileQuery,
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
/// fast tile path of the connection code (`serve/fast_tile.rs`) alike.
pub(crate) async fn answer(
    app: &App,
    TilePath { id, level, x, file }: TilePath,
    TileQuery { frame }: TileQuery,
    headers: &HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(app, &id).await?;
    let (y, format) = row_and_format("tile", &file, format_value, Format::EXPECTED)?;
    address::check_tile(&entry, level, x, y)?;
    let frame = address::frame_for(&entry, frame);
    let key = TileKey { texture: entry.key, level, x, y, frame, format, shape: Shape::Tile };
    respond(app, &entry, key, headers).await
}

/// The response for tile or metatile `key` of `entry` (inside its pyramid): 304, or the tile
/// from the cache or synthesized — for every route that serves tiles (tiles, metatiles, Deep
/// Zoom, IIIF, XYZ).
pub(in crate::api) async fn respond(
    app: &App,
    entry: &Arc<Entry>,
    key: TileKey,
    headers: &HeaderMap,
) -> Result<Response, ApiError> {
    // A cached tile carries its ETag; only a tile not in the cache needs it hashed.
    let cached = app.engine.cached(entry, &key);
    let tag = match &cached {
        Some(tile) => tile.etag.clone(),
        None => address::key_etag(entry, &key),
    };
    if not_modified(headers, tag.as_str()) {
        return Ok(not_modified_response(crate::api::http::etag_header(&tag)));
    }
    let (tile, source) = app.engine.tile(entry, key, cached, tag).await?;
    let mut resp = image_response(tile.body.clone(), key.format, &tile.etag, tile.width, tile.height);
    if key.shape.is_metatile() {
        resp.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static(vtex_wire::frame::CONTENT_TYPE));
    }
    let cache_state = if source == Source::Hit { "hit" } else { "miss" };
    resp.headers_mut().insert(X_VTEX_CACHE.clone(), HeaderValue::from_static(cache_state));
    Ok(resp)
}

/// The query of a region.
#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct RegionQuery {
    #[serde(deserialize_with = "de::u32")]
    pub level: u32,
    /// any integer: a torus wraps, a plane is defined everywhere
    #[serde(deserialize_with = "de::i64")]
    pub x: i64,
    #[serde(deserialize_with = "de::i64")]
    pub y: i64,
    #[serde(deserialize_with = "de::u32")]
    pub w: u32,
    /// w × h at most `--max-region-pixels`, 16383 a side
    #[serde(deserialize_with = "de::u32")]
    pub h: u32,
    /// png (default), webp, jpg or rgba
    #[serde(default, deserialize_with = "de::opt_format")]
    #[param(value_type = Option<String>)]
    pub format: Option<Format>,
    /// frame of an animated texture (reduced modulo its period); ignored for still ones
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
        TextureId,
        RegionQuery,
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
    let frame = address::frame_for(&entry, frame);
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
    let what = [level as u64, x as u64, y as u64, w as u64, h as u64, frame as u64];
    let tag = ETag::new(&entry.key, Some(Mark::Region), &what, format);
    if not_modified(&headers, tag.as_str()) {
        return Ok(not_modified_response(crate::api::http::etag_header(&tag)));
    }
    let region = Region::new(level, x, y, w, h).at_frame(frame);
    vtex_synth::texture::check_region(&*entry.texture, &region)?;
    let mut reservation = app.inflight.reserve(encode::peak_bytes(format, w, h))?;
    let body = app.engine.synthesize(entry, region, Layer::Color, format).await?;
    app.inflight.resize(&mut reservation, body.len() as u64)?;
    Ok(image_response(reservation.hold(body), format, &tag, w, h))
}
