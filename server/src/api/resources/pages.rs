//! Pages for virtual texturing in game engines, and whole mip chains of small textures.
//!
//! A page is the `S`² square (`x`·S, `y`·S) of a level's page grid with `B` pixels of its
//! neighbours on every side, so a GPU atlas of bordered pages filters (bilinear, anisotropic)
//! without bleeding. Every pixel of a page, border included, is the texture's pixel at its
//! level coordinates — wrapped on a torus, the plane's own beyond the served extent — so a
//! border is bit for bit the neighbouring page's pixels, across a torus's wrap too, and pages
//! are always (S + 2B)² even where the grid runs past the level's edge (every texture vtex
//! serves is a torus or a plane: none has an edge where pixels would stop). Pages exist at
//! every level down to 1×1. They share the tile cache, its coalescing and the synthesis slots
//! with tiles (`Engine::tile`), carry strong ETags and are immutable.
//!
//! A page is of one layer (`vtex_synth::layer`): the colour, or its tangent-space normals,
//! derived at the page's level from a region one pixel wider than the page, so normal pages'
//! borders match their neighbours as colour pages' do. KTX2 normal pages are linear (`_UNORM`).

use crate::api::error::{echo, ApiError};
use crate::api::extract::{Path, Query};
use crate::api::http::{not_modified, not_modified_response};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::params::{de, row_and_format};
use crate::api::resources::tiles;
use crate::api::state::{lookup, App, TextureId};
use crate::encode::Format;
use crate::engine::address;
use crate::engine::cache::{Shape, TileKey};
use crate::engine::{ETag, Mark};
use crate::ktx2::{self, Codec, Ktx2, Rdo, Supercompression, Transfer};
use crate::store::Entry;
use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::Response;
use serde::de::Error as _;
use serde::{Deserialize, Deserializer};
use utoipa::IntoParams;
use vtex_synth::layer::Layer;
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::{Region, Rgba8Image};

/// Page sides served: the sizes engines' virtual texturing uses.
pub const PAGE_SIZES: [u32; 4] = [64, 128, 256, 512];
/// Defaults: Unreal's virtual texture page, 128 pixels with a 4-pixel border.
pub const DEFAULT_SIZE: u32 = 128;
pub const DEFAULT_BORDER: u32 = 4;
/// Largest side of a mip chain's first level.
pub const MAX_CHAIN_SIDE: u64 = 2048;
/// Largest side of a Basis Universal (uastc, etc1s) chain's first level: basisu takes some
/// 20 µs a pixel for UASTC on one thread (docs/ktx2-quality.md), so a 512² chain is seconds of
/// a synthesis slot and a 2048² one would be minutes.
pub const MAX_BASIS_CHAIN_SIDE: u64 = 512;

const FORMATS_EXPECTED: &str = "expected png, webp, jpg, rgba or ktx2";

/// The path of a page: `/api/v1/textures/{id}/pages/{level}/{x}/{file}`, `file` being
/// `{y}.{format}`.
#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct PagePath {
    pub id: String,
    #[serde(deserialize_with = "de::u32")]
    pub level: u32,
    #[serde(deserialize_with = "de::u32")]
    pub x: u32,
    pub file: String,
}

/// The parameters of a page, for one page and for a batch of pages alike:
/// `[?size=S][&border=B][&layer=L][&codec=C][&supercompression=Z][&rdo=λ][&frame=N]`.
#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct PageParams {
    /// 64, 128 (default), 256 or 512
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub size: Option<u32>,
    /// 0..=size/8 (default 4)
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub border: Option<u32>,
    /// color (default) or normal: tangent-space normals (glTF convention, linear RGB) of the
    /// level's luminance height
    #[serde(default, deserialize_with = "de_layer")]
    #[param(value_type = Option<String>)]
    pub layer: Option<Layer>,
    /// ktx2: bc7 (default), bc1, bc5 (normals only), rgba8, uastc or etc1s (Basis Universal)
    #[serde(default, deserialize_with = "de_codec")]
    #[param(value_type = Option<String>)]
    pub codec: Option<Codec>,
    /// ktx2: none (default) or zstd; basislz, the default and only one, for etc1s
    #[serde(default, deserialize_with = "de_supercompression")]
    #[param(value_type = Option<String>)]
    pub supercompression: Option<Supercompression>,
    /// ktx2, codec uastc: rate-distortion optimisation λ, 0.1 to 10 (none by default): blocks
    /// chosen so that zstd compresses them better, at up to about λ times more error
    #[serde(default, deserialize_with = "de_rdo")]
    #[param(value_type = Option<f32>)]
    pub rdo: Option<Rdo>,
    /// frame of an animated texture (reduced modulo its period); ignored for still ones
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub frame: Option<u32>,
}

pub(in crate::api) fn de_rdo<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Rdo>, D::Error> {
    let s = String::deserialize(d)?;
    Rdo::parse(&s).map(Some).ok_or_else(|| D::Error::custom(format!("must be {} (got `{}`)", Rdo::EXPECTED, echo(&s))))
}

pub(in crate::api) fn de_codec<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Codec>, D::Error> {
    let s = String::deserialize(d)?;
    Codec::parse(&s)
        .map(Some)
        .ok_or_else(|| D::Error::custom(format!("names unknown codec `{}`; {}", echo(&s), Codec::EXPECTED)))
}

pub(in crate::api) fn de_layer<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Layer>, D::Error> {
    let s = String::deserialize(d)?;
    Layer::parse(&s)
        .map(Some)
        .ok_or_else(|| D::Error::custom(format!("names unknown layer `{}`; {}", echo(&s), Layer::EXPECTED)))
}

pub(in crate::api) fn de_supercompression<'de, D: Deserializer<'de>>(
    d: D,
) -> Result<Option<Supercompression>, D::Error> {
    let s = String::deserialize(d)?;
    Supercompression::parse(&s)
        .map(Some)
        .ok_or_else(|| D::Error::custom(format!("names unknown scheme `{}`; {}", echo(&s), Supercompression::EXPECTED)))
}

/// A page format by its extension: the tile formats and `ktx2`.
pub fn page_format_value(s: &str) -> Result<PageFormat, String> {
    match s {
        "ktx2" => Ok(PageFormat::Ktx2),
        _ => Format::parse(s)
            .map(PageFormat::Image)
            .ok_or_else(|| format!("names unknown format `{}`; {FORMATS_EXPECTED}", echo(s))),
    }
}

/// A page format before its KTX2 options are known.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum PageFormat {
    Image(Format),
    Ktx2,
}

/// What a page request asks for, checked: its format and its shape.
pub fn page_spec(format: PageFormat, page: &PageParams) -> Result<(Format, Shape), ApiError> {
    let size = page.size.unwrap_or(DEFAULT_SIZE);
    if !PAGE_SIZES.contains(&size) {
        return Err(ApiError::bad_request(format!("`size` must be one of 64, 128, 256 or 512 (got {size})")));
    }
    let border = page.border.unwrap_or(DEFAULT_BORDER);
    let layer = page.layer.unwrap_or_default();
    if border > size / 8 {
        return Err(ApiError::bad_request(format!(
            "`border` must be at most size / 8 = {} for size {size} (got {border})",
            size / 8
        )));
    }
    let format = match format {
        PageFormat::Image(f) => {
            let ktx2_params = [
                ("codec", page.codec.is_some()),
                ("supercompression", page.supercompression.is_some()),
                ("rdo", page.rdo.is_some()),
            ];
            if let Some((name, _)) = ktx2_params.into_iter().find(|(_, given)| *given) {
                return Err(ApiError::bad_request(format!(
                    "`{name}` applies to ktx2 pages only; this page is {}",
                    f.ext()
                )));
            }
            f
        }
        PageFormat::Ktx2 => {
            let k = ktx2_options(page.codec, page.supercompression, page.rdo, layer)?;
            if k.codec.is_block_compressed() && border % 2 == 1 {
                return Err(ApiError::bad_request(format!(
                    "`border` must be even for {} pages (got {border}): a block-compressed page's side, \
                     size + 2 × border, must be a multiple of 4",
                    k.codec.name()
                )));
            }
            Format::Ktx2(k)
        }
    };
    Ok((format, Shape::Page { size, border, layer }))
}

/// The KTX2 options: `codec` (default bc7), `supercompression` (default none; basislz, the
/// only one it takes, for etc1s) and `rdo` (uastc only), for `layer`'s pixels (sRGB colour or
/// linear data).
fn ktx2_options(
    codec: Option<Codec>,
    supercompression: Option<Supercompression>,
    rdo: Option<Rdo>,
    layer: Layer,
) -> Result<Ktx2, ApiError> {
    let codec = codec.unwrap_or(Codec::Bc7);
    let supercompression = supercompression.unwrap_or(codec.default_supercompression());
    let transfer = if layer.is_linear() { Transfer::Linear } else { Transfer::Srgb };
    let k = Ktx2 { codec, supercompression, transfer, rdo };
    if codec == Codec::Bc5 && layer != Layer::Normal {
        return Err(ApiError::bad_request(format!(
            "`codec` bc5 holds two channels, a normal's X and Y: it serves layer normal only (got layer {})",
            layer.name()
        )));
    }
    k.check().map_err(ApiError::bad_request)?;
    if layer == Layer::Normal && codec == Codec::Etc1s {
        // One colour line per block from a small codebook: a normal map comes out barely
        // nearer than a flat one (docs/ktx2-quality.md).
        return Err(ApiError::bad_request(
            "etc1s cannot hold normals (it keeps little more than a flat normal map); \
             for layer normal use bc5, uastc, bc7, bc1 or rgba8",
        ));
    }
    Ok(k)
}

/// `GET /api/v1/textures/{id}/pages/{level}/{x}/{y}.{format}[?size=S&border=B&layer=L&codec=C&supercompression=Z&rdo=λ&frame=N]`
#[utoipa::path(get,
    path = vtex_wire::urls::PAGE,
    tag = "pages",
    params(
        ("id" = String, Path, description = text::TEXTURE_ID),
        ("level" = u32, Path),
        ("x" = u32, Path, description = "page column"),
        ("file" = String, Path, description = "`{y}.{format}`, format png, webp, jpg, rgba or ktx2"),
        PageParams,
    ),
    responses(
        (status = 200, description = "the (size + 2·border)² page, its border bit-identical to its \
            neighbours", content(("application/octet-stream"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn page(
    State(app): State<App>,
    Path(PagePath { id, level, x, file }): Path<PagePath>,
    Query(q): Query<PageParams>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(&app, &id).await?;
    let key = page_key(&entry, level, x, &file, &q, false)?;
    tiles::respond(&app, &entry, key, &headers).await
}

/// `GET /api/v1/textures/{id}/page-metatiles/{level}/{x}/{y}.{format}[?size=S&border=B&layer=L&codec=C&supercompression=Z&rdo=λ&frame=N]`:
/// the aligned block of pages (512 level pixels a side: 4 × 4 pages of 128, 1 of 512) whose top
/// left page is (`x`·n, `y`·n), clipped at the page grid's edges, as frames row by row — each
/// exactly the page's bytes. The unit a virtual-texturing client fetches so that a cache in
/// front shares it between clients (see `metatiles.rs`); the page route and batches serve its
/// pages from it.
#[utoipa::path(get,
    path = vtex_wire::urls::PAGE_METATILE,
    tag = "pages",
    params(
        ("id" = String, Path, description = text::TEXTURE_ID),
        ("level" = u32, Path),
        ("x" = u32, Path, description = "page metatile column: pages x·n … x·n + n − 1, n = 512 / size (at least 1)"),
        ("file" = String, Path, description = "`{y}.{format}`, format png, webp, jpg, rgba or ktx2"),
        PageParams,
    ),
    responses(
        (status = 200, description = "the block's pages as frames, row by row: a 32-byte header then the page's \
            bytes (strong ETag, immutable)", content(("application/x-vtex-tile-batch"))),
        (status = 304, description = "`If-None-Match` names its ETag"),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn page_metatile(
    State(app): State<App>,
    Path(PagePath { id, level, x, file }): Path<PagePath>,
    Query(q): Query<PageParams>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(&app, &id).await?;
    let key = page_key(&entry, level, x, &file, &q, true)?;
    tiles::respond(&app, &entry, key, &headers).await
}

/// The key of page (`level`, `x`, `file`) of `entry` — of the page metatile there when
/// `metatile` — checked against the level's page grid.
fn page_key(
    entry: &Entry,
    level: u32,
    x: u32,
    file: &str,
    q: &PageParams,
    metatile: bool,
) -> Result<TileKey, ApiError> {
    let what = if metatile { "page metatile" } else { "page" };
    let (y, format) = row_and_format(what, file, page_format_value, FORMATS_EXPECTED)?;
    let (format, page) = page_spec(format, q)?;
    let Shape::Page { size, border, layer } = page else { unreachable!("page_spec gives pages") };
    let shape = if metatile {
        let side = address::page_metatile_pages(size);
        address::check_metatile(entry, level, x, y, page, side)?;
        Shape::PageMetatile { size, border, side, layer }
    } else {
        address::check_page(entry, level, x, y, size)?;
        page
    };
    Ok(TileKey { texture: entry.key, level, x, y, frame: address::frame_for(entry, q.frame), format, shape })
}

/// The query of a mip chain: `[?level=L][&layer=Y][&codec=C][&supercompression=Z][&rdo=λ][&frame=N]`.
#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct ChainQuery {
    /// finest level of the chain
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub level: Option<u32>,
    /// color (default) or normal: each level's normals from its own luminance height
    #[serde(default, deserialize_with = "de_layer")]
    #[param(value_type = Option<String>)]
    pub layer: Option<Layer>,
    /// bc7 (default), bc1, bc5 (normals only), rgba8, uastc or etc1s (Basis Universal)
    #[serde(default, deserialize_with = "de_codec")]
    #[param(value_type = Option<String>)]
    pub codec: Option<Codec>,
    /// none (default) or zstd; basislz, the default and only one, for etc1s
    #[serde(default, deserialize_with = "de_supercompression")]
    #[param(value_type = Option<String>)]
    pub supercompression: Option<Supercompression>,
    /// codec uastc: rate-distortion optimisation λ, 0.1 to 10 (none by default)
    #[serde(default, deserialize_with = "de_rdo")]
    #[param(value_type = Option<f32>)]
    pub rdo: Option<Rdo>,
    /// frame of an animated texture (reduced modulo its period); ignored for still ones
    #[serde(default, deserialize_with = "de::opt_u32")]
    pub frame: Option<u32>,
}

/// `GET /api/v1/textures/{id}/mips.ktx2[?level=L&layer=Y&codec=C&supercompression=Z&rdo=λ&frame=N]`: one KTX2
/// holding level `L` (by default the finest of at most [`MAX_CHAIN_SIDE`] a side) and every
/// coarser level to 1×1, for textures small enough to upload whole (or the tail of a large
/// one's pyramid, kept resident under its pages).
///
/// The file's level `i` is sized as a GPU's mip chain is, `max(1, ⌊w / 2^i⌋)`, and holds the
/// top-left of vtex level `L + i` — that whole level when the sides are powers of two. Chains
/// are rendered, not cached; each reserves its bytes from the in-flight budget first, and is
/// encoded holding a synthesis slot.
#[utoipa::path(get,
    path = "/api/v1/textures/{id}/mips.ktx2",
    tag = "pages",
    params(
        TextureId,
        ChainQuery,
    ),
    responses(
        (status = 200, description = "a KTX2 mip chain from `level` to 1×1", content(("image/ktx2"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn mip_chain(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    Query(q): Query<ChainQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let entry = lookup(&app, &id).await?;
    let layer = q.layer.unwrap_or_default();
    let k = ktx2_options(q.codec, q.supercompression, q.rdo, layer)?;
    let (w, h) = (entry.texture.width(), entry.texture.height());
    let levels = level_count(w, h);
    let max_side = if k.codec.is_basis() { MAX_BASIS_CHAIN_SIDE } else { MAX_CHAIN_SIDE };
    let fits = |l: u32| {
        let (lw, lh) = level_size(w, h, l);
        lw.max(lh) <= max_side
    };
    let first_fit = (0..levels).find(|&l| fits(l)).expect("the last level is 1×1");
    let level = q.level.unwrap_or(first_fit);
    if level >= levels {
        return Err(ApiError::bad_request(format!("level {level} does not exist; levels are 0..={}", levels - 1)));
    }
    if !fits(level) {
        let (lw, lh) = level_size(w, h, level);
        return Err(ApiError::bad_request(format!(
            "level {level} is {lw}×{lh}; a {} mip chain starts at a level of at most {max_side} a side \
             (level {first_fit} or coarser)",
            k.codec.name()
        )));
    }
    let frame = address::frame_for(&entry, q.frame);
    let [codec, sc, rdo] = address::ktx2_ids(Format::Ktx2(k));
    let what = [level as u64, frame as u64, codec, sc, layer as u64, rdo];
    let tag = ETag::new(&entry.key, Some(Mark::Chain), &what, Format::Ktx2(k));
    if not_modified(&headers, tag.as_str()) {
        return Ok(not_modified_response(crate::api::http::etag_header(&tag)));
    }
    let (bw, bh) = level_size(w, h, level);
    let (bw, bh) = (bw as u32, bh as u32);
    let sizes: Vec<(u32, u32)> = (0..chain_len(bw, bh)).map(|i| ((bw >> i).max(1), (bh >> i).max(1))).collect();
    let pixels: u64 = sizes.iter().map(|&(a, b)| a as u64 * b as u64).sum();
    // The levels' pixels, held until the encoder has returned, and what it holds besides.
    let mut reservation = app.inflight.reserve(pixels * 4 + ktx2::working_bytes(k, pixels))?;
    let mut images = Vec::with_capacity(sizes.len());
    for (i, &(lw, lh)) in sizes.iter().enumerate() {
        let region = Region::new(level + i as u32, 0, 0, lw, lh).at_frame(frame);
        let data = app.engine.synthesize(entry.clone(), region, layer, Format::Rgba).await?;
        images.push(Rgba8Image::from_raw(lw, lh, data).map_err(|e| ApiError::internal("a chain level", e))?);
    }
    // Encoded holding a synthesis slot: a Basis Universal chain of 2048² takes seconds.
    let body = app
        .engine
        .in_slot(&entry, move || ktx2::encode(&images, k))
        .await?
        .map_err(|e| ApiError::internal("encoding the mip chain failed", e))?;
    app.inflight.resize(&mut reservation, body.len() as u64)?;
    Ok(tiles::image_response(reservation.hold(body), Format::Ktx2(k), &tag, bw, bh))
}

/// Levels of a GPU mip chain whose first level is `w` × `h`: down to 1×1.
fn chain_len(w: u32, h: u32) -> usize {
    (32 - w.max(h).leading_zeros()) as usize
}
