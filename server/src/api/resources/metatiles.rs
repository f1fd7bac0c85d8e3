//! Metatiles: `GET /api/v1/textures/{id}/metatiles/{level}/{x}/{y}.{format}[?frame=N]`, the
//! aligned block of `metatile` × `metatile` tiles (the texture info's `metatile`) whose top
//! left tile is (`x`·metatile, `y`·metatile), clipped at the level's edges.
//!
//! Why: a tile server that renders on demand wants a unit larger than a tile that is the same
//! for every client (mod_tile's metatiles). A viewer asking for the blocks under its view,
//! rather than for its view as one batch, asks for what another viewer over the same area asks
//! for: a cache in front (nginx, a CDN) answers the second from the first, and a consistent
//! hash on the URL spreads one view's blocks over the replicas.
//!
//! The body is the tiles' [`vtex_wire::frame`]s, row by row, each exactly the single tile's
//! bytes, with no cache state in them (`X-Vtex-Cache` tells it for the whole): the bytes are a
//! pure function of the URL, so the response is `immutable` with a strong ETag. It is rendered
//! in one call, cached as one entry, and the tile route and batches serve its tiles from it.

use crate::api::error::ApiError;
use crate::api::extract::{Path, Query};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::params::{format_value, row_and_format};
use crate::api::resources::tiles::{respond, TilePath, TileQuery};
use crate::api::state::{lookup, App};
use crate::encode::Format;
use crate::engine::address;
use crate::engine::cache::{Shape, TileKey};
use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::Response;

/// `GET /api/v1/textures/{id}/metatiles/{level}/{x}/{y}.{format}[?frame=N]`: one metatile.
#[utoipa::path(get,
    path = vtex_wire::urls::METATILE,
    tag = "tiles",
    params(
        ("id" = String, Path, description = text::TEXTURE_ID),
        ("level" = u32, Path, description = "mip level, 0 full resolution"),
        ("x" = u32, Path, description = "metatile column: tiles x·metatile … x·metatile + metatile − 1"),
        ("file" = String, Path, description = "`{y}.{format}`, format png, webp, jpg or rgba (raw RGBA8)"),
        TileQuery,
    ),
    responses(
        (status = 200, description = "the block's tiles as frames, row by row: a 32-byte header then the tile's \
            bytes (strong ETag, immutable)", content(("application/x-vtex-tile-batch"))),
        (status = 304, description = "`If-None-Match` names its ETag"),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn metatile(
    State(app): State<App>,
    Path(TilePath { id, level, x, file }): Path<TilePath>,
    Query(TileQuery { frame }): Query<TileQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(&app, &id).await?;
    let (y, format) = row_and_format("metatile", &file, format_value, Format::EXPECTED)?;
    let side = entry.metatile;
    address::check_metatile(&entry, level, x, y, Shape::Tile, side)?;
    let frame = address::frame_for(&entry, frame);
    let key = TileKey { texture: entry.key, level, x, y, frame, format, shape: Shape::Metatile { side } };
    respond(&app, &entry, key, &headers).await
}
