//! IIIF Image API 3.0 at compliance level 2: `/iiif/3/{identifier}/info.json` and
//! `/iiif/3/{identifier}/{region}/{size}/{rotation}/{quality}.{format}`, over the same tiles
//! and bounded renders as the rest of the API ([`crate::api::view`]).
//!
//! The identifier is a texture id; `{id};{frame}` names a frame of an animated texture (the
//! meta-identifier form Cantaloupe uses for pages). Errors follow the specification's rules: a
//! request that cannot be parsed or asks for what is not offered (a rotation other than a
//! multiple of 90°, §4.3; a size over the region without `^` or over the limits, §4.2) is a
//! 400, an identifier that names no image a 404. Beyond level 2: mirroring, upscaling (`^`),
//! WebP, `bitonal`, and the profile and canonical `Link` headers.

use crate::api::error::{echo, ApiError};
use crate::api::extract::{NoQuery, Path, Query};
use crate::api::inflight::Reservation;
use crate::api::interop::jsonld;
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::origin::Origin;
use crate::api::resources::tiles;
use crate::api::state::App;
use crate::config::MAX_REGION_SIDE;
use crate::encode::Format;
use crate::engine::address::frame_for;
use crate::engine::cache::{Shape, TileKey};
use crate::engine::view::View;
use crate::engine::{ETag, Mark};
use crate::store::Entry;
use axum::extract::State;
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use serde::Deserialize;
use serde_json::json;
use std::sync::Arc;
use vtex_synth::Rgba8Image;

/// Where the service lives: `{base}/{identifier}/…`.
pub const PREFIX: &str = "/iiif/3";
const PROFILE_LINK: &str = "<http://iiif.io/api/image/3/level2.json>;rel=\"profile\"";

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct IdentPath {
    ident: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ImagePath {
    ident: String,
    region: String,
    size: String,
    rotation: String,
    file: String,
}

/// A texture and the frame an identifier names. An identifier that is not a stored texture's
/// id (with an optional `;frame`) names no image: 404.
async fn image_of(app: &App, ident: &str) -> Result<(Arc<Entry>, u32), ApiError> {
    let none = || ApiError::not_found(format!("no image with identifier `{}`", echo(ident)));
    let (id, frame) = match ident.split_once(';') {
        Some((id, f)) => (id, Some(f.parse::<u32>().map_err(|_| none())?)),
        None => (ident, None),
    };
    if !vtex_synth::bundle::is_valid_id(id) || app.engine.store.record(id).is_none() {
        return Err(none());
    }
    let entry = crate::api::state::lookup(app, id).await?;
    let frame = frame_for(&entry, frame);
    Ok((entry, frame))
}

/// The URL of the image service of `ident`, as the client reached this server.
pub(in crate::api) fn service_url(origin: &Origin, ident: &str) -> String {
    let ident: String = form_urlencoded::byte_serialize(ident.as_bytes()).collect();
    origin.url(&format!("{PREFIX}/{ident}"))
}

/// `GET /iiif/3/{identifier}`: the base URI redirects to its image information.
#[utoipa::path(get, operation_id = "iiif_base",
    path = "/iiif/3/{ident}",
    tag = "interop",
    params(("ident" = String, Path, description = text::ID_AND_FRAME)),
    responses(
        (status = 303, description = "to its `info.json`"),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
    ))]
pub async fn base(Path(IdentPath { ident }): Path<IdentPath>, _: Query<NoQuery>, origin: Origin) -> Response {
    let to = format!("{}/info.json", service_url(&origin, &ident));
    (StatusCode::SEE_OTHER, [(header::LOCATION, to)]).into_response()
}

/// `GET /iiif/3/{identifier}/info.json`: JSON-LD, or plain JSON when the client prefers it
/// ([`jsonld`]); the profile `Link` too, as on images (§6).
#[utoipa::path(get, operation_id = "iiif_info",
    path = "/iiif/3/{ident}/info.json",
    tag = "interop",
    params(("ident" = String, Path, description = text::ID_AND_FRAME)),
    responses(
        (status = 200, description = "IIIF Image API 3 image information: JSON-LD with the image context as its \
            profile unless `Accept` prefers plain JSON", content(("application/ld+json"), ("application/json"))),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 406, description = text::NOT_ACCEPTABLE, body = ErrorBody),
    ))]
pub async fn info(
    State(app): State<App>,
    Path(IdentPath { ident }): Path<IdentPath>,
    _: Query<NoQuery>,
    origin: Origin,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let (entry, _) = image_of(&app, &ident).await?;
    let (w, h) = (entry.texture.width(), entry.texture.height());
    let max_area = app.cfg.max_region_pixels;
    let sizes: Vec<_> = (0..vtex_synth::texture::level_count(w, h))
        .rev()
        .map(|l| vtex_synth::texture::level_size(w, h, l))
        .take_while(|&(lw, lh)| lw <= MAX_REGION_SIDE as u64 && lh <= MAX_REGION_SIDE as u64 && lw * lh <= max_area)
        .map(|(lw, lh)| json!({"width": lw, "height": lh}))
        .collect();
    let body = json!({
        "@context": jsonld::IMAGE.uri,
        "id": service_url(&origin, &ident),
        "type": "ImageService3",
        "protocol": "http://iiif.io/api/image",
        "profile": "level2",
        "width": w,
        "height": h,
        "maxWidth": MAX_REGION_SIDE,
        "maxHeight": MAX_REGION_SIDE,
        "maxArea": max_area,
        "sizes": sizes,
        "tiles": [{"width": entry.tile_size, "scaleFactors": (0..entry.levels).map(|l| 1u64 << l).collect::<Vec<_>>()}],
        "extraQualities": ["gray", "bitonal"],
        "extraFormats": ["webp"],
        // Tiles are lossless by default; clients that honour this (OpenSeadragon) then show
        // the texture's exact pixels.
        "preferredFormats": ["png"],
        "extraFeatures": ["mirroring", "sizeUpscaling", "profileLinkHeader", "canonicalLinkHeader"],
    });
    let mut resp = jsonld::respond(&headers, &jsonld::IMAGE, &body)?;
    resp.headers_mut().insert(header::LINK, HeaderValue::from_static(PROFILE_LINK));
    Ok(resp)
}

/// Any other path under `/iiif`: an image or a service that does not exist.
pub async fn not_found(req: axum::extract::Request) -> ApiError {
    ApiError::not_found(format!("no IIIF image or service at {}", echo(req.uri().path())))
}

/// A parsed image request, resolved against its image.
#[derive(Clone, Copy, Debug, PartialEq)]
struct Request {
    view: View,
    /// Mirrored before rotating (`!` in the rotation).
    mirror: bool,
    /// Clockwise quarter turns.
    turns: u8,
    quality: Quality,
    format: Format,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
enum Quality {
    Default,
    Color,
    Gray,
    Bitonal,
}

impl Quality {
    fn name(self) -> &'static str {
        match self {
            Quality::Default => "default",
            Quality::Color => "color",
            Quality::Gray => "gray",
            Quality::Bitonal => "bitonal",
        }
    }
}

/// The limits a size must respect: `maxWidth`, `maxHeight`, `maxArea`.
#[derive(Clone, Copy)]
struct Limits {
    side: u64,
    area: u64,
}

fn bad(what: &str, value: &str, expected: &str) -> ApiError {
    ApiError::bad_request(format!("IIIF {what} `{}` is not valid; expected {expected}", echo(value)))
}

/// A non-negative decimal number as IIIF writes them (no sign, no exponent).
fn decimal(s: &str) -> Option<f64> {
    let ok = !s.is_empty()
        && s.bytes().all(|b| b.is_ascii_digit() || b == b'.')
        && s.bytes().filter(|&b| b == b'.').count() <= 1;
    ok.then(|| s.parse::<f64>().ok()).flatten().filter(|v| v.is_finite())
}

fn integer(s: &str) -> Option<u64> {
    (!s.is_empty() && s.len() <= 19 && s.bytes().all(|b| b.is_ascii_digit())).then(|| s.parse().ok()).flatten()
}

/// `full`, `square`, `x,y,w,h` or `pct:x,y,w,h`, as a rectangle of level 0 cropped to the image.
fn parse_region(s: &str, width: u64, height: u64) -> Result<(u64, u64, u64, u64), ApiError> {
    const EXPECTED: &str = "full, square, x,y,w,h or pct:x,y,w,h";
    let (x, y, w, h) = match s {
        "full" => (0, 0, width, height),
        "square" => {
            let side = width.min(height);
            ((width - side) / 2, (height - side) / 2, side, side)
        }
        _ => {
            let (pct, list) = match s.strip_prefix("pct:") {
                Some(rest) => (true, rest),
                None => (false, s),
            };
            let parts: Vec<&str> = list.split(',').collect();
            if parts.len() != 4 {
                return Err(bad("region", s, EXPECTED));
            }
            if pct {
                let v: Vec<f64> = parts
                    .iter()
                    .map(|p| decimal(p))
                    .collect::<Option<_>>()
                    .ok_or_else(|| bad("region", s, EXPECTED))?;
                let at = |p: f64, of: u64| (p * of as f64 / 100.0).round().min(u64::MAX as f64) as u64;
                let (x, y) = (at(v[0], width), at(v[1], height));
                (x, y, at(v[0] + v[2], width).saturating_sub(x), at(v[1] + v[3], height).saturating_sub(y))
            } else {
                let v: Vec<u64> = parts
                    .iter()
                    .map(|p| integer(p))
                    .collect::<Option<_>>()
                    .ok_or_else(|| bad("region", s, EXPECTED))?;
                (v[0], v[1], v[2], v[3])
            }
        }
    };
    if w == 0 || h == 0 {
        return Err(ApiError::bad_request(format!("IIIF region `{}` has a zero width or height", echo(s))));
    }
    if x >= width || y >= height {
        return Err(ApiError::bad_request(format!(
            "IIIF region `{}` lies outside the image, which is {width}×{height}",
            echo(s)
        )));
    }
    Ok((x, y, w.min(width - x), h.min(height - y)))
}

/// `round(v × num / den)`, in integers.
fn ratio(v: u64, num: u64, den: u64) -> u64 {
    ((2 * v as u128 * num as u128 + den as u128) / (2 * den as u128)) as u64
}

/// The largest size with the `rw` × `rh` region's aspect ratio within `bw` × `bh` and `area`
/// pixels: the side that binds the box is exact and the other rounded, and an area that binds
/// takes both sides down (§4.2, "maintains the aspect ratio ... as closely as possible").
fn fit(rw: u64, rh: u64, bw: u64, bh: u64, area: u64) -> (u64, u64) {
    let (w, h) = if rw as u128 * bh as u128 >= rh as u128 * bw as u128 {
        (bw, ratio(rh, bw, rw))
    } else {
        (ratio(rw, bh, rh), bh)
    };
    if w as u128 * h as u128 <= area as u128 {
        return (w, h);
    }
    // w² ≤ area × rw / rh and h = w × rh / rw, rounded down, so w × h ≤ area.
    let w = (area as u128 * rw as u128 / rh as u128).isqrt() as u64;
    (w, (w as u128 * rh as u128 / rw as u128) as u64)
}

/// What `max` (`up` false) or `^max` (`up` true) gives for a `rw` × `rh` region (§4.2): the
/// region itself, or scaled to the largest size the limits allow; only `^max` scales up.
fn max_size(rw: u64, rh: u64, up: bool, limits: Limits) -> (u64, u64) {
    let (bw, bh) = if up { (limits.side, limits.side) } else { (rw.min(limits.side), rh.min(limits.side)) };
    fit(rw, rh, bw, bh, limits.area)
}

/// The output size a size parameter asks for a `rw` × `rh` region, by the rules of §4.2:
/// `max`, `w,`, `,h`, `pct:n`, `w,h` or `!w,h`, each optionally after `^`, which alone may
/// scale the region up. `max` and `!w,h` are confined to the limits; any other form over them,
/// or under one pixel, is a 400.
fn parse_size(s: &str, rw: u64, rh: u64, limits: Limits) -> Result<(u64, u64), ApiError> {
    const EXPECTED: &str = "max, w,, ,h, pct:n, w,h or !w,h, each optionally prefixed by ^";
    let (up, rest) = match s.strip_prefix('^') {
        Some(r) => (true, r),
        None => (false, s),
    };
    let (w, h) = if rest == "max" {
        max_size(rw, rh, up, limits)
    } else if let Some(p) = rest.strip_prefix("pct:") {
        let n = decimal(p).ok_or_else(|| bad("size", s, EXPECTED))?;
        if n > 100.0 && !up {
            return Err(ApiError::bad_request(format!(
                "IIIF size `{}` is over 100%; upscaling needs the ^ prefix",
                echo(s)
            )));
        }
        let pct = |v: u64| (v as f64 * n / 100.0).round().min(u64::MAX as f64) as u64;
        (pct(rw), pct(rh))
    } else {
        let (confined, list) = match rest.strip_prefix('!') {
            Some(r) => (true, r),
            None => (false, rest),
        };
        let (a, b) = list.split_once(',').ok_or_else(|| bad("size", s, EXPECTED))?;
        let number = |v: &str| integer(v).ok_or_else(|| bad("size", s, EXPECTED));
        let (a, b) =
            (if a.is_empty() { None } else { Some(number(a)?) }, if b.is_empty() { None } else { Some(number(b)?) });
        match (confined, a, b) {
            (false, Some(w), None) => (w, ratio(rh, w, rw)),
            (false, None, Some(h)) => (ratio(rw, h, rh), h),
            (false, Some(w), Some(h)) => (w, h),
            (true, Some(w), Some(h)) => {
                let (bw, bh) = (w.min(limits.side), h.min(limits.side));
                let (bw, bh) = if up { (bw, bh) } else { (bw.min(rw), bh.min(rh)) };
                fit(rw, rh, bw, bh, limits.area)
            }
            _ => return Err(bad("size", s, EXPECTED)),
        }
    };
    if w == 0 || h == 0 {
        return Err(ApiError::bad_request(format!(
            "IIIF size `{}` of the {rw}×{rh} region is {w}×{h}, under one pixel",
            echo(s)
        )));
    }
    if !up && (w > rw || h > rh) {
        return Err(ApiError::bad_request(format!(
            "IIIF size `{}` is {w}×{h}, larger than the {rw}×{rh} region; upscaling needs the ^ prefix",
            echo(s)
        )));
    }
    if w > limits.side || h > limits.side || w.saturating_mul(h) > limits.area {
        return Err(ApiError::bad_request(format!(
            "IIIF size `{}` is {w}×{h}, over this service's maxWidth/maxHeight {} or maxArea {}",
            echo(s),
            limits.side,
            limits.area
        )));
    }
    Ok((w, h))
}

/// `n` or `!n` (mirrored first), `n` a multiple of 90 in 0..=360: (mirror, quarter turns).
fn parse_rotation(s: &str) -> Result<(bool, u8), ApiError> {
    let (mirror, deg) = match s.strip_prefix('!') {
        Some(r) => (true, r),
        None => (false, s),
    };
    let deg = decimal(deg)
        .filter(|d| *d <= 360.0)
        .ok_or_else(|| bad("rotation", s, "a number of degrees 0..=360, optionally prefixed by !"))?;
    // §4.3: an unsupported rotation is a 400, like one out of range.
    if deg % 90.0 != 0.0 {
        return Err(bad("rotation", s, "a multiple of 90 (this service rotates by quarter turns only)"));
    }
    Ok((mirror, ((deg / 90.0) as u8) % 4))
}

fn parse_file(s: &str) -> Result<(Quality, Format), ApiError> {
    let (q, f) = s.rsplit_once('.').ok_or_else(|| bad("quality and format", s, "{quality}.{format}"))?;
    let quality = match q {
        "default" => Quality::Default,
        "color" => Quality::Color,
        "gray" => Quality::Gray,
        "bitonal" => Quality::Bitonal,
        _ => return Err(bad("quality", q, "default, color, gray or bitonal")),
    };
    let format = match f {
        "png" => Format::Png,
        "jpg" => Format::Jpg,
        "webp" => Format::Webp,
        _ => return Err(bad("format", f, "png, jpg or webp")),
    };
    Ok((quality, format))
}

impl Request {
    fn parse(path: &ImagePath, width: u64, height: u64, limits: Limits, frame: u32) -> Result<Request, ApiError> {
        let (x, y, w, h) = parse_region(&path.region, width, height)?;
        let (out_w, out_h) = parse_size(&path.size, w, h, limits)?;
        let (mirror, turns) = parse_rotation(&path.rotation)?;
        let (quality, format) = parse_file(&path.file)?;
        let view = View { x, y, w, h, out_w: out_w as u32, out_h: out_h as u32, frame };
        Ok(Request { view, mirror, turns, quality, format })
    }

    /// Whether the pixels are the view's own (no mirroring, rotation or change of colour).
    fn untransformed(&self) -> bool {
        !self.mirror && self.turns == 0 && matches!(self.quality, Quality::Default | Quality::Color)
    }

    /// The canonical form of this request's path after the identifier (§4.8): the size is
    /// `max` or `^max` when it is what those give for the region, else `w,h` or `^w,h`.
    fn canonical(&self, width: u64, height: u64, limits: Limits) -> String {
        let v = &self.view;
        let region = if (v.x, v.y, v.w, v.h) == (0, 0, width, height) {
            "full".into()
        } else {
            format!("{},{},{},{}", v.x, v.y, v.w, v.h)
        };
        let out = (v.out_w as u64, v.out_h as u64);
        let size = if out == max_size(v.w, v.h, false, limits) {
            "max".into()
        } else if out == max_size(v.w, v.h, true, limits) {
            "^max".into()
        } else if out.0 > v.w || out.1 > v.h {
            format!("^{},{}", out.0, out.1)
        } else {
            format!("{},{}", out.0, out.1)
        };
        let rotation = format!("{}{}", if self.mirror { "!" } else { "" }, self.turns as u32 * 90);
        // `color` is this server's default quality.
        let quality = if self.quality == Quality::Color { Quality::Default } else { self.quality };
        format!("{region}/{size}/{rotation}/{}.{}", quality.name(), self.format.ext())
    }
}

/// `GET /iiif/3/{identifier}/{region}/{size}/{rotation}/{quality}.{format}`
#[utoipa::path(get, operation_id = "iiif_image",
    path = "/iiif/3/{ident}/{region}/{size}/{rotation}/{file}",
    tag = "interop",
    params(
        ("ident" = String, Path, description = text::ID_AND_FRAME),
        ("region" = String, Path, description = "full, square, x,y,w,h or pct:x,y,w,h"),
        ("size" = String, Path, description = "max, ^max, w,, ,h, pct:n, w,h, !w,h (and ^ forms)"),
        ("rotation" = String, Path, description = "0, 90, 180, 270 or 360, optionally mirrored (!); other angles are \
            a 400"),
        ("file" = String, Path, description = "`{quality}.{format}`: default, color, gray or bitonal; png, jpg or \
            webp"),
    ),
    responses(
        (status = 200, description = "the image", content(("image/png"), ("image/webp"), ("image/jpeg"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn image(
    State(app): State<App>,
    Path(path): Path<ImagePath>,
    _: Query<NoQuery>,
    origin: Origin,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let (entry, frame) = image_of(&app, &path.ident).await?;
    let (width, height) = (entry.texture.width(), entry.texture.height());
    let limits = Limits { side: MAX_REGION_SIDE as u64, area: app.cfg.max_region_pixels };
    let req = Request::parse(&path, width, height, limits, frame)?;
    req.view.check(app.cfg.max_region_pixels)?;
    // One header with both links: some clients read only the first `Link` header.
    let links = format!(
        "{PROFILE_LINK}, <{}/{}>;rel=\"canonical\"",
        service_url(&origin, &path.ident),
        req.canonical(width, height, limits)
    );
    let mut resp = answer(&app, entry, req, &headers).await?;
    if let Ok(v) = HeaderValue::from_str(&links) {
        resp.headers_mut().insert(header::LINK, v);
    }
    Ok(resp)
}

/// The image of `req`: the cached tile when the request is exactly one, else rendered.
async fn answer(app: &App, entry: Arc<Entry>, req: Request, headers: &HeaderMap) -> Result<Response, ApiError> {
    let v = req.view;
    let max_pixels = app.cfg.max_region_pixels;
    if let Some((level, x, y)) = req.view.as_tile(&entry, max_pixels).filter(|_| req.untransformed()) {
        let key = TileKey { texture: entry.key, level, x, y, frame: v.frame, format: req.format, shape: Shape::Tile };
        return tiles::respond(app, &entry, key, headers).await;
    }
    let what = [
        v.x,
        v.y,
        v.w,
        v.h,
        v.out_w as u64,
        v.out_h as u64,
        v.frame as u64,
        req.mirror as u64,
        req.turns as u64,
        req.quality as u64,
    ];
    let tag = ETag::new(&entry.key, Some(Mark::Iiif), &what, req.format);
    if crate::api::http::not_modified(headers, tag.as_str()) {
        return Ok(crate::api::http::not_modified_response(crate::api::http::etag_header(&tag)));
    }
    let reservation = app
        .inflight
        .reserve(v.peak_bytes(&entry, max_pixels) + crate::encode::peak_bytes(req.format, v.out_w, v.out_h))?;
    let img = app.engine.view(entry, v, max_pixels).await?;
    let img = tokio::task::spawn_blocking(move || transform(img, req.mirror, req.turns, req.quality))
        .await
        .map_err(|e| ApiError::internal("transforming the image failed", e))?;
    let (w, h) = (img.width, img.height);
    let body = encode_held(app, img, req.format, reservation).await?;
    Ok(tiles::image_response(body, req.format, &tag, w, h))
}

/// Encodes `img` off the I/O threads and keeps its body's length reserved in `reservation`.
pub async fn encode_held(
    app: &App,
    img: Rgba8Image,
    format: Format,
    mut reservation: Reservation,
) -> Result<bytes::Bytes, ApiError> {
    let body = tokio::task::spawn_blocking(move || crate::encode::encode(img, format))
        .await
        .map_err(|e| ApiError::internal("encoding failed", e))?
        .map_err(|e| ApiError::internal("encoding failed", e))?;
    app.inflight.resize(&mut reservation, body.len() as u64)?;
    Ok(reservation.hold(body))
}

/// Mirrors (left–right), then rotates clockwise by quarter turns, then maps the colours.
fn transform(img: Rgba8Image, mirror: bool, turns: u8, quality: Quality) -> Rgba8Image {
    let (w, h) = (img.width, img.height);
    let mut out = if mirror || turns != 0 {
        let (ow, oh) = if turns % 2 == 1 { (h, w) } else { (w, h) };
        let mut out = Rgba8Image::new(ow, oh);
        for y in 0..oh {
            for x in 0..ow {
                // The source pixel that lands at (x, y) after mirroring then turning.
                let (sx, sy) = match turns {
                    0 => (x, y),
                    1 => (y, h - 1 - x),
                    2 => (w - 1 - x, h - 1 - y),
                    _ => (w - 1 - y, x),
                };
                let sx = if mirror { w - 1 - sx } else { sx };
                out.set_pixel(x, y, img.pixel(sx, sy));
            }
        }
        out
    } else {
        img
    };
    if matches!(quality, Quality::Gray | Quality::Bitonal) {
        for p in out.data.chunks_exact_mut(4) {
            // Rec. 601 luma, in integers.
            let luma = ((p[0] as u32 * 299 + p[1] as u32 * 587 + p[2] as u32 * 114 + 500) / 1000) as u8;
            let v = if quality == Quality::Bitonal {
                if luma >= 128 {
                    255
                } else {
                    0
                }
            } else {
                luma
            };
            p[..3].fill(v);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    const LIMITS: Limits = Limits { side: 16383, area: 4096 * 4096 };

    #[test]
    fn regions() {
        assert_eq!(parse_region("full", 1000, 600).unwrap(), (0, 0, 1000, 600));
        assert_eq!(parse_region("square", 1000, 600).unwrap(), (200, 0, 600, 600));
        assert_eq!(parse_region("square", 600, 1000).unwrap(), (0, 200, 600, 600));
        assert_eq!(parse_region("10,20,30,40", 1000, 600).unwrap(), (10, 20, 30, 40));
        assert_eq!(parse_region("900,500,300,300", 1000, 600).unwrap(), (900, 500, 100, 100), "cropped to the image");
        assert_eq!(parse_region("pct:10,50,20,50", 1000, 600).unwrap(), (100, 300, 200, 300));
        for bad in ["", "a,b,c,d", "1,2,3", "1,2,3,4,5", "-1,0,5,5", "pct:1,2,3", "1.5,0,4,4", "pct:-1,0,4,4"] {
            assert_eq!(parse_region(bad, 1000, 600).unwrap_err().status(), StatusCode::BAD_REQUEST, "{bad}");
        }
        assert!(parse_region("0,0,0,5", 1000, 600).is_err(), "zero width");
        assert!(parse_region("1000,0,5,5", 1000, 600).is_err(), "outside");
    }

    /// Small limits, so that rows reach them: maxWidth = maxHeight = 1000, maxArea = 360,000.
    const SMALL: Limits = Limits { side: 1000, area: 360_000 };

    /// Every size form of §4.2 against a 4:3 region larger than (400 × 300), equal to
    /// (200 × 150) and smaller than (100 × 75) the size asked for; `None` is a 400.
    #[test]
    fn sizes_follow_the_specification() {
        const L: (u64, u64) = (400, 300);
        const E: (u64, u64) = (200, 150);
        const S: (u64, u64) = (100, 75);
        let err = None;
        /// A size form, and the size it gives against the larger, equal and smaller region.
        type Row = (&'static str, [Option<(u64, u64)>; 3]);
        #[rustfmt::skip]
        let table: &[Row] = &[
            // `w,`: "the width of the returned image is exactly equal to w", the height keeping
            // the aspect ratio; "w MUST NOT be greater than the width of the extracted region".
            ("200,", [Some(E), Some(E), err]),
            // `^w,`: the same, and "if w is greater than the pixel width of the extracted region,
            // the extracted region is upscaled".
            ("^200,", [Some(E), Some(E), Some(E)]),
            // `,h` and `^,h`: the same rules for the height.
            (",150", [Some(E), Some(E), err]),
            ("^,150", [Some(E), Some(E), Some(E)]),
            // `pct:n`: "n percent of the width and height of the extracted region"; "n MUST NOT be
            // greater than 100". `^pct:n`: "for values of n greater than 100, ... upscaled", and
            // 800 × 600 is over maxArea.
            ("pct:50", [Some(E), Some(S), Some((50, 38))]),
            ("pct:200", [err, err, err]),
            ("^pct:200", [err, Some(L), Some(E)]),
            // `w,h`: "exactly w and h", the aspect ratio may change; "w and h MUST NOT be greater
            // than the corresponding pixel dimensions of the extracted region". `^w,h`: upscaled.
            ("200,150", [Some(E), Some(E), err]),
            ("200,50", [Some((200, 50)), Some((200, 50)), err]),
            ("^200,150", [Some(E), Some(E), Some(E)]),
            ("^200,50", [Some((200, 50)), Some((200, 50)), Some((200, 50))]),
            // `!w,h`: "not greater than w and h, while maintaining the aspect ratio ... as large as
            // possible but not larger than the extracted region, w or h".
            ("!200,200", [Some(E), Some(E), Some(S)]),
            ("!200,100", [Some((133, 100)), Some((133, 100)), Some(S)]),
            // `^!w,h`: "as large as possible but not larger than w, h, or server-imposed limits".
            ("^!200,200", [Some(E), Some(E), Some(E)]),
            ("^!200,100", [Some((133, 100)), Some((133, 100)), Some((133, 100))]),
            // `max`: "the pixel dimensions of the extracted region", never upscaled.
            ("max", [Some(L), Some(E), Some(S)]),
            // `^max`: "the maximum size permitted by maxWidth, maxHeight, or maxArea": here the
            // area binds, 692 × 519 ≤ 360,000 pixels.
            ("^max", [Some((692, 519)), Some((692, 519)), Some((692, 519))]),
        ];
        for (size, expected) in table {
            for (region, expected) in [L, E, S].into_iter().zip(expected) {
                let got = parse_size(size, region.0, region.1, SMALL);
                match expected {
                    Some(wh) => assert_eq!(got.unwrap(), *wh, "{size} of {region:?}"),
                    None => assert_eq!(got.unwrap_err().status(), StatusCode::BAD_REQUEST, "{size} of {region:?}"),
                }
            }
        }
    }

    /// The rules that do not depend on how the region compares with the request.
    #[test]
    fn size_limits_and_syntax() {
        let size = |s: &str, rw: u64, rh: u64| parse_size(s, rw, rh, SMALL).map_err(|e| e.status());
        // The case: `!w,h` is confined to the region, never a 400 for a small region.
        assert_eq!(size("!200,200", 100, 100), Ok((100, 100)));
        // `max` is "constrained to a smaller size by maxWidth, maxHeight, or maxArea".
        assert_eq!(size("max", 2000, 500), Ok((1000, 250)), "maxWidth binds");
        assert_eq!(size("max", 1200, 900), Ok((692, 519)), "maxArea binds");
        // `!w,h` is "not larger than ... server-imposed limits" either.
        assert_eq!(size("!1500,1500", 2000, 2000), Ok((600, 600)));
        assert_eq!(size("^!5000,5000", 10, 10), Ok((600, 600)));
        // "the pixel dimensions of the scaled region MUST NOT be less than 1 pixel or greater
        // than the server-imposed limits ... 400 (Bad Request)".
        for (s, rw, rh) in [("^1200,", 400, 300), ("^700,700", 400, 300), ("pct:100", 2000, 500), ("1,", 1000, 2)] {
            assert_eq!(size(s, rw, rh), Err(StatusCode::BAD_REQUEST), "{s} of {rw}×{rh}");
        }
        for bad in [
            "full", "0,", ",0", "0,0", "pct:0", "!0,10", "!10,", "!,10", "^", "^!", "pct:", "pct:-5", "10", "a,",
            "1,2,3", "^^max",
        ] {
            assert_eq!(size(bad, 400, 300), Err(StatusCode::BAD_REQUEST), "{bad}");
        }
        let huge = parse_size("max", 100_000, 100_000, LIMITS).unwrap();
        assert_eq!(huge, (4096, 4096), "max is confined to maxArea");
    }

    #[test]
    fn canonical_forms() {
        let canonical = |region: &str, size: &str, rotation: &str, file: &str| {
            let path = ImagePath {
                ident: "i".into(),
                region: region.into(),
                size: size.into(),
                rotation: rotation.into(),
                file: file.into(),
            };
            Request::parse(&path, 1000, 600, SMALL, 0).unwrap().canonical(1000, 600, SMALL)
        };
        // §4.8: region `full` if the full image is requested, otherwise `x,y,w,h`; size `max`
        // if the maximum size without upscaling is requested, `^max` if the maximum upscaled
        // size, otherwise `w,h`, or `^w,h` when upscaling; `!` then an integer rotation; the
        // quality `default` if the server's default is requested.
        for (req, expected) in [
            (("full", "max", "0", "default.png"), "full/max/0/default.png"),
            (("0,0,1000,600", "max", "0", "default.png"), "full/max/0/default.png"),
            (("full", "!5000,5000", "0", "default.png"), "full/max/0/default.png"),
            (("0,0,100,100", "!200,200", "0", "default.png"), "0,0,100,100/max/0/default.png"),
            (("0,0,100,100", "100,", "0", "default.png"), "0,0,100,100/max/0/default.png"),
            (("0,0,100,100", "^max", "0", "default.png"), "0,0,100,100/^max/0/default.png"),
            (("0,0,100,100", "^600,600", "0", "default.png"), "0,0,100,100/^max/0/default.png"),
            (("0,0,100,100", "^200,", "0", "default.png"), "0,0,100,100/^200,200/0/default.png"),
            (("0,0,100,100", "pct:50", "0", "default.png"), "0,0,100,100/50,50/0/default.png"),
            (("pct:10,10,10,10", "50,", "!90", "gray.jpg"), "100,60,100,60/50,30/!90/gray.jpg"),
            (("square", "^!700,700", "360.0", "color.webp"), "200,0,600,600/max/0/default.webp"),
            (("square", "^601,500", "0", "default.png"), "200,0,600,600/^601,500/0/default.png"),
        ] {
            assert_eq!(canonical(req.0, req.1, req.2, req.3), expected, "{req:?}");
        }
    }

    #[test]
    fn rotations() {
        assert_eq!(parse_rotation("0").unwrap(), (false, 0));
        assert_eq!(parse_rotation("!90").unwrap(), (true, 1));
        assert_eq!(parse_rotation("270.0").unwrap(), (false, 3));
        assert_eq!(parse_rotation("360").unwrap(), (false, 0));
        // §4.3: "A rotation value that is out of range or unsupported SHOULD result in a 400".
        for bad in ["", "-90", "abc", "400", "!!90", "22.5", "45", "!180.5"] {
            assert_eq!(parse_rotation(bad).unwrap_err().status(), StatusCode::BAD_REQUEST, "{bad}");
        }
    }

    #[test]
    fn transforms_move_the_corners() {
        let mut img = Rgba8Image::new(3, 2);
        img.set_pixel(0, 0, [1, 1, 1, 255]); // top left
        img.set_pixel(2, 0, [2, 2, 2, 255]); // top right
        let r = transform(img.clone(), false, 1, Quality::Default);
        assert_eq!((r.width, r.height), (2, 3));
        assert_eq!(r.pixel(1, 0)[0], 1, "a clockwise turn takes the top left to the top right");
        assert_eq!(r.pixel(1, 2)[0], 2);
        let m = transform(img.clone(), true, 0, Quality::Default);
        assert_eq!(m.pixel(2, 0)[0], 1);
        let m180 = transform(img, true, 2, Quality::Default);
        assert_eq!(m180.pixel(0, 1)[0], 1, "mirrored then turned twice: top left to bottom left");
    }
}
