//! TileJSON 3.0.0 and XYZ tiles, so web-map clients (Leaflet, OpenLayers, MapLibre) take a
//! texture as a raster tile layer.
//!
//! XYZ zoom z is vtex level `levels − 1 − z`: zoom 0 is the whole texture in one tile, the
//! highest zoom full resolution. In a Web Mercator map the texture fills the world from its
//! north-west corner at one texel a map pixel at the highest zoom; the TileJSON `bounds` say
//! where it ends. Map clients draw every tile image stretched to a full square, so a tile the
//! texture's edge cuts is served whole, transparent beyond the texture; every other tile is the
//! tile API's own (same cache entry, bytes and ETag).

use crate::api::error::{echo, ApiError};
use crate::api::extract::{Path, Query};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::origin::Origin;
use crate::api::params::{de, format_value, named, u32_value};
use crate::api::resources::tiles;
use crate::api::state::{lookup, record, App, TextureId};
use crate::encode::Format;
use crate::engine::address::{frame_for, square_shape};
use crate::engine::cache::TileKey;
use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::Response;
use axum::Json;
use serde::Deserialize;
use serde_json::{json, Value};
use std::f64::consts::PI;
use utoipa::IntoParams;

#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct TileJsonQuery {
    /// png (default), webp or jpg
    #[serde(default, deserialize_with = "de::opt_format")]
    #[param(value_type = Option<String>)]
    format: Option<Format>,
    /// frame of an animated texture (reduced modulo its period); ignored for still ones
    #[serde(default, deserialize_with = "de::opt_u32")]
    frame: Option<u32>,
}

/// Latitude (degrees) of the Web Mercator world's row at fraction `t` of its height from the top.
fn latitude(t: f64) -> f64 {
    (PI * (1.0 - 2.0 * t)).sinh().atan().to_degrees()
}

/// `GET /api/v1/textures/{id}/tilejson.json[?format=png|webp|jpg][&frame=N]`
#[utoipa::path(get,
    path = "/api/v1/textures/{id}/tilejson.json",
    tag = "interop",
    params(
        TextureId,
        TileJsonQuery,
    ),
    responses(
        (status = 200, description = "TileJSON 3.0.0", content(("application/json"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
    ))]
pub async fn tilejson(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    Query(q): Query<TileJsonQuery>,
    origin: Origin,
) -> Result<Json<Value>, ApiError> {
    let rec = record(&app, &id).await?;
    let format = q.format.unwrap_or(Format::Png);
    if format == Format::Rgba {
        return Err(ApiError::bad_request("XYZ tiles are images: `format` must be png, webp or jpg"));
    }
    let maxzoom = rec.levels - 1;
    let frame = q.frame.map(|f| format!("?frame={f}")).unwrap_or_default();
    let template = origin.url(&format!("/api/v1/textures/{id}/xyz/{{z}}/{{x}}/{{y}}.{}{frame}", format.ext()));
    // The texture's share of the world: texels over map pixels at the highest zoom.
    let world = (rec.tile_size as u64 * (1u64 << maxzoom)) as f64;
    let (fx, fy) = (rec.plan.width as f64 / world, rec.plan.height as f64 / world);
    let (west, east) = (-180.0, -180.0 + 360.0 * fx);
    let (north, south) = (latitude(0.0), latitude(fy));
    Ok(Json(json!({
        "tilejson": "3.0.0",
        "name": rec.name,
        "description": format!(
            "vtex texture {id} ({} model, {}×{} texels)",
            rec.model, rec.plan.width, rec.plan.height
        ),
        "scheme": "xyz",
        "tiles": [template],
        "minzoom": 0,
        "maxzoom": maxzoom,
        "bounds": [west, south, east, north],
        "center": [(west + east) / 2.0, latitude(fy / 2.0), maxzoom.min(2)],
        "attribution": format!("synthesized by vtex ({} model)", rec.model),
        // Not in TileJSON 3.0.0, read by MapLibre and Mapbox GL, whose default is 512.
        "tileSize": rec.tile_size,
    })))
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct XyzPath {
    id: String,
    #[serde(deserialize_with = "de::u32")]
    z: u32,
    #[serde(deserialize_with = "de::u32")]
    x: u32,
    file: String,
}

#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct XyzQuery {
    /// frame of an animated texture (reduced modulo its period); ignored for still ones
    #[serde(default, deserialize_with = "de::opt_u32")]
    frame: Option<u32>,
}

/// `GET /api/v1/textures/{id}/xyz/{z}/{x}/{y}.{format}[?frame=N]`: every tile a full square
/// (JPEG, without alpha, is black beyond the texture); a zoom or tile outside the texture is a
/// 404, as map clients expect at the edge of a layer.
#[utoipa::path(get,
    path = "/api/v1/textures/{id}/xyz/{z}/{x}/{file}",
    tag = "interop",
    params(
        ("id" = String, Path, description = text::TEXTURE_ID),
        ("z" = u32, Path, description = "zoom, 0 the whole texture in one tile"),
        ("x" = u32, Path),
        ("file" = String, Path, description = "`{y}.{format}`, format png, webp or jpg"),
        XyzQuery,
    ),
    responses(
        (status = 200, description = "the tile of vtex level `levels − 1 − z`, always `tileSize` square: \
            transparent beyond the texture (black in jpg); strong ETag, \
            immutable", content(("image/png"), ("image/webp"), ("image/jpeg"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn xyz(
    State(app): State<App>,
    Path(XyzPath { id, z, x, file }): Path<XyzPath>,
    Query(XyzQuery { frame }): Query<XyzQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(&app, &id).await?;
    let (y, ext) = file.rsplit_once('.').ok_or_else(|| {
        ApiError::bad_request(format!("tile `{}` has no format extension; {}", echo(&file), Format::EXPECTED))
    })?;
    let format = named("format", ext, format_value)?;
    let y = named("y", y, u32_value)?;
    let maxzoom = entry.levels - 1;
    if z > maxzoom {
        return Err(ApiError::not_found(format!("zoom {z} does not exist; this texture has zooms 0..={maxzoom}")));
    }
    let level = maxzoom - z;
    let (cols, rows) = entry.tiles_at(level);
    if x as u64 >= cols || y as u64 >= rows {
        return Err(ApiError::not_found(format!(
            "tile {z}/{x}/{y} is outside the texture, which has {cols}×{rows} tiles at zoom {z}"
        )));
    }
    let shape = square_shape(&entry, level, x, y);
    let key = TileKey { texture: entry.key, level, x, y, frame: frame_for(&entry, frame), format, shape };
    tiles::respond(&app, &entry, key, &headers).await
}
