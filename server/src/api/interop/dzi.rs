//! Deep Zoom: `/dzi/{id}.dzi` (the descriptor) and `/dzi/{id}_files/{level}/{x}_{y}.{format}`
//! (its tiles), as OpenSeadragon and other Deep Zoom clients read them.
//!
//! Deep Zoom numbers levels from 1 × 1 (level 0) up to full resolution (level N, N = ⌈log₂ of
//! the longer side⌉), so Deep Zoom level k is vtex level N − k, and without overlap its tiles
//! are the tile API's own (the same cache and ETags). The descriptor's query — `overlap`
//! (0..=[`MAX_OVERLAP`] pixels shared with each neighbour), `format` and `frame` — is repeated
//! on every tile URL by Deep Zoom clients, and the tiles take it too.

use crate::api::error::{echo, ApiError};
use crate::api::extract::{Path, Query};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::params::{de, format_value, named, u32_value};
use crate::api::resources::tiles;
use crate::api::state::{lookup, App};
use crate::encode::{self, Format};
use crate::engine::address::frame_for;
use crate::engine::cache::{Shape, TileKey};
use crate::engine::{ETag, Mark};
use crate::store::Entry;
use axum::extract::State;
use axum::http::{header, HeaderMap};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use std::sync::Arc;
use utoipa::IntoParams;
use vtex_synth::layer::Layer;
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::Region;

/// Most pixels a tile may share with each neighbour.
pub const MAX_OVERLAP: u32 = 32;

#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct DziQuery {
    /// tile overlap in pixels
    #[serde(default, deserialize_with = "de::opt_u32")]
    overlap: Option<u32>,
    /// png, webp or jpg
    #[serde(default, deserialize_with = "de::opt_format")]
    #[param(value_type = Option<String>)]
    format: Option<Format>,
    /// frame of an animated texture (reduced modulo its period); ignored for still ones
    #[serde(default, deserialize_with = "de::opt_u32")]
    frame: Option<u32>,
}

impl DziQuery {
    fn overlap(&self) -> Result<u32, ApiError> {
        match self.overlap.unwrap_or(0) {
            o if o <= MAX_OVERLAP => Ok(o),
            o => Err(ApiError::bad_request(format!("`overlap` must be at most {MAX_OVERLAP} (got {o})"))),
        }
    }
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct DescriptorPath {
    file: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct TilePath {
    dir: String,
    #[serde(deserialize_with = "de::u32")]
    level: u32,
    file: String,
}

/// `GET /dzi/{id}.dzi[?overlap=&format=&frame=]`
#[utoipa::path(get, operation_id = "dzi_descriptor",
    path = "/dzi/{file}",
    tag = "interop",
    params(
        ("file" = String, Path, description = "`{id}.dzi`"),
        DziQuery,
    ),
    responses(
        (status = 200, description = "the Deep Zoom descriptor", content(("application/xml"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
    ))]
pub async fn descriptor(
    State(app): State<App>,
    Path(DescriptorPath { file }): Path<DescriptorPath>,
    Query(q): Query<DziQuery>,
) -> Result<Response, ApiError> {
    let id = file.strip_suffix(".dzi").ok_or_else(|| {
        ApiError::not_found(format!("`{}` is not a Deep Zoom descriptor (`{{id}}.dzi`)", echo(&file)))
    })?;
    let record = crate::api::state::record(&app, id).await?;
    let overlap = q.overlap()?;
    let format = q.format.unwrap_or(Format::Png);
    if format == Format::Rgba {
        return Err(ApiError::bad_request("Deep Zoom tiles are images: `format` must be png, webp or jpg"));
    }
    let xml = format!(
        "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<Image xmlns=\"http://schemas.microsoft.com/deepzoom/2008\" \
         Format=\"{}\" Overlap=\"{overlap}\" TileSize=\"{}\"><Size Width=\"{}\" Height=\"{}\"/></Image>\n",
        format.ext(),
        record.tile_size,
        record.plan.width,
        record.plan.height
    );
    Ok(([(header::CONTENT_TYPE, "application/xml")], xml).into_response())
}

/// `GET /dzi/{id}_files/{level}/{x}_{y}.{format}[?overlap=&format=&frame=]`
#[utoipa::path(get, operation_id = "dzi_tile",
    path = "/dzi/{dir}/{level}/{file}",
    tag = "interop",
    params(
        ("dir" = String, Path, description = "`{id}_files`"),
        ("level" = u32, Path, description = "Deep Zoom level, 0 the 1×1"),
        ("file" = String, Path, description = "`{x}_{y}.{format}`"),
        DziQuery,
    ),
    responses(
        (status = 200, description = "the Deep Zoom tile", content(("image/png"), ("image/webp"), ("image/jpeg"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn tile(
    State(app): State<App>,
    Path(TilePath { dir, level, file }): Path<TilePath>,
    Query(q): Query<DziQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let id = dir.strip_suffix("_files").ok_or_else(|| {
        ApiError::not_found(format!("`{}` is not a Deep Zoom tile folder (`{{id}}_files`)", echo(&dir)))
    })?;
    let entry = lookup(&app, id).await?;
    let overlap = q.overlap()?;
    let (xy, ext) = file.rsplit_once('.').ok_or_else(|| {
        ApiError::bad_request(format!("tile `{}` has no format extension; {}", echo(&file), Format::EXPECTED))
    })?;
    let format = named("format", ext, format_value)?;
    if q.format.is_some_and(|f| f != format) {
        return Err(ApiError::bad_request(format!("the tile's extension `{ext}` differs from its `format` parameter")));
    }
    let (x, y) = xy.split_once('_').ok_or_else(|| {
        ApiError::bad_request(format!("tile `{}` is not named `{{x}}_{{y}}.{{format}}`", echo(&file)))
    })?;
    let (x, y) = (named("x", x, u32_value)?, named("y", y, u32_value)?);
    let (w, h) = (entry.texture.width(), entry.texture.height());
    let top = level_count(w, h) - 1;
    if level > top {
        return Err(ApiError::not_found(format!("Deep Zoom level {level} does not exist; levels are 0..={top}")));
    }
    let vtex_level = top - level;
    let frame = frame_for(&entry, q.frame);
    let ts = entry.tile_size as u64;
    let (lw, lh) = level_size(w, h, vtex_level);
    if x as u64 >= lw.div_ceil(ts) || y as u64 >= lh.div_ceil(ts) {
        return Err(ApiError::not_found(format!(
            "tile {x}_{y} is outside Deep Zoom level {level}, which has {}×{} tiles",
            lw.div_ceil(ts),
            lh.div_ceil(ts)
        )));
    }
    if overlap == 0 && vtex_level < entry.levels {
        let key = TileKey { texture: entry.key, level: vtex_level, x, y, frame, format, shape: Shape::Tile };
        return tiles::respond(&app, &entry, key, &headers).await;
    }
    rendered(&app, entry, DziTile { level: vtex_level, x, y, overlap, frame, format }, &headers).await
}

struct DziTile {
    level: u32,
    x: u32,
    y: u32,
    overlap: u32,
    frame: u32,
    format: Format,
}

/// A tile with overlap, or of a level coarser than the tile pyramid: rendered, not cached.
async fn rendered(app: &App, entry: Arc<Entry>, t: DziTile, headers: &HeaderMap) -> Result<Response, ApiError> {
    let (ts, ov) = (entry.tile_size as u64, t.overlap as u64);
    let (lw, lh) = level_size(entry.texture.width(), entry.texture.height(), t.level);
    let span = |i: u32, size: u64| {
        let start = (i as u64 * ts).saturating_sub(ov);
        (start, ((i as u64 + 1) * ts + ov).min(size) - start)
    };
    let ((x0, w), (y0, h)) = (span(t.x, lw), span(t.y, lh));
    let what = [t.level as u64, t.x as u64, t.y as u64, ov, t.frame as u64, ts];
    let tag = ETag::new(&entry.key, Some(Mark::Dzi), &what, t.format);
    if crate::api::http::not_modified(headers, tag.as_str()) {
        return Ok(crate::api::http::not_modified_response(crate::api::http::etag_header(&tag)));
    }
    let (w, h) = (w as u32, h as u32);
    let mut reservation = app.inflight.reserve(encode::peak_bytes(t.format, w, h))?;
    let region = Region::new(t.level, x0 as i64, y0 as i64, w, h).at_frame(t.frame);
    let body = app.engine.synthesize(entry, region, Layer::Color, t.format).await?;
    app.inflight.resize(&mut reservation, body.len() as u64)?;
    Ok(tiles::image_response(reservation.hold(body), t.format, &tag, w, h))
}
