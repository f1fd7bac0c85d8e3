//! Many tiles in one response: `GET /api/v1/textures/{id}/tiles?tiles=L/x/y,…&format=F[&frame=N]`,
//! or many pages: `…/tiles?pages=L/x/y,…&format=F[&size=S&border=B&layer=L&codec=C&supercompression=Z&frame=N]`
//! (the parameters of a single page, [`pages`](crate::api::resources::pages)).
//!
//! Why: a browser spends a fixed amount of CPU on every request, whatever its size, so a view
//! of a few dozen tiles paid it a few dozen times before a pixel was drawn. One request for the
//! whole view pays it once.
//!
//! The body is a stream of frames ([`vtex_wire::frame`]) sent in completion order: tiles found
//! in the cache at once, the others as each synthesis finishes. Each frame is a header followed
//! by exactly the bytes the single-tile endpoint returns for that tile (the same cache, the same
//! coalescing of concurrent misses, the same synthesis slots:
//! [`Engine::tile`](crate::engine::Engine::tile)).
//!
//! The whole request is validated before anything is sent: a malformed or empty list, a
//! repeated tile, more than [`MAX_TILES`] tiles, a list over [`MAX_LIST_BYTES`], an unknown
//! format or parameter are 400s, a level the texture does not serve a 400 and a tile outside
//! its level a 404, as for single tiles, each naming the problem; a spent in-flight budget
//! ([`crate::api::inflight`]) is a 503. Errors after that (a model failing to render; no synthesis
//! slot, 503) come as error frames. Dropping the response (a
//! client that went away) aborts the tiles not yet done: a synthesis that has not started never
//! starts, and one running stops unless another request waits for the same tile; a body not
//! finished within the request deadline is cut off (the client sees a truncated stream).

use crate::api::error::{echo, ApiError};
use crate::api::extract::{Both, Path, Query, MAX_LIST_BYTES};
use crate::api::http::{not_modified, not_modified_response, CACHE_IMMUTABLE};
use crate::api::inflight::Reservation;
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::params::u32_value;
use crate::api::resources::pages::{self, page_format_value, PageFormat, PageParams};
use crate::api::state::{lookup, App, TextureId};
use crate::encode::Format;
use crate::engine::address::{self, frame_for};
use crate::engine::cache::{Shape, Source, Tile, TileKey};
use axum::body::Body;
use axum::extract::State;
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::Response;
use bytes::{BufMut, Bytes, BytesMut};
use http_body::Frame;
use serde::{Deserialize, Deserializer};
use std::collections::{HashSet, VecDeque};
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Instant;
use tokio::sync::Semaphore;
use tokio::task::JoinSet;
use utoipa::IntoParams;
pub use vtex_wire::frame::{FrameHeader, TileRef, CONTENT_TYPE, HEADER_LEN, MAX_TILES};

/// What a batch reserves from the in-flight budget for each of its tiles: the frame header it
/// builds and, for a tile that fails, room for its error's JSON (one of the synthesis path's
/// fixed messages). The tiles' bytes are the cache's, sent without a copy, and not charged.
const FRAME_RESERVE: u64 = HEADER_LEN as u64 + 256;

/// The `tiles` list: `L/x/y` items separated by commas, at most [`MAX_TILES`] in at most
/// [`MAX_LIST_BYTES`], none repeated. Errors are worded to follow the parameter's name.
pub fn parse_tiles(list: &str) -> Result<Vec<TileRef>, String> {
    if list.is_empty() {
        return Err("is empty; expected a comma-separated list of level/x/y".into());
    }
    if list.len() > MAX_LIST_BYTES {
        return Err(format!("is {} bytes long, longer than the limit of {MAX_LIST_BYTES}", list.len()));
    }
    let n = list.split(',').count();
    if n > MAX_TILES {
        return Err(format!("lists {n} tiles; at most {MAX_TILES} per request"));
    }
    let mut seen = HashSet::with_capacity(n);
    let mut out = Vec::with_capacity(n);
    for (i, item) in list.split(',').enumerate() {
        let parts: Vec<&str> = item.split('/').collect();
        let [level, x, y] = parts[..] else {
            return Err(format!("item {} is `{}`; expected level/x/y", i + 1, echo(item)));
        };
        let coord = |name: &str, s: &str| u32_value(s).map_err(|why| format!("item {}: `{name}` {why}", i + 1));
        let tile = TileRef { level: coord("level", level)?, x: coord("x", x)?, y: coord("y", y)? };
        if !seen.insert(tile) {
            return Err(format!("lists tile {}/{}/{} twice", tile.level, tile.x, tile.y));
        }
        out.push(tile);
    }
    Ok(out)
}

fn de_tiles<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Vec<TileRef>>, D::Error> {
    parse_tiles(&String::deserialize(d)?).map(Some).map_err(serde::de::Error::custom)
}

fn de_format<'de, D: Deserializer<'de>>(d: D) -> Result<PageFormat, D::Error> {
    page_format_value(&String::deserialize(d)?).map_err(serde::de::Error::custom)
}

/// The query of a batch: `tiles` or `pages`, and its format; the other parameters are a
/// page's ([`PageParams`]), of which tiles take only `frame`.
#[derive(Deserialize, IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Query)]
pub struct BatchList {
    /// `L/x/y,L/x/y,…`, at most 256 tiles
    #[serde(default, deserialize_with = "de_tiles")]
    #[param(value_type = Option<String>)]
    pub tiles: Option<Vec<TileRef>>,
    /// `L/x/y,…` pages instead of tiles, with `size`, `border`, `layer`, `codec`, `supercompression`
    #[serde(default, deserialize_with = "de_tiles")]
    #[param(value_type = Option<String>)]
    pub pages: Option<Vec<TileRef>>,
    /// png, webp, jpg or rgba (ktx2 with `pages`)
    #[serde(deserialize_with = "de_format")]
    #[param(value_type = String)]
    pub format: PageFormat,
}

/// The query of a batch: its list and format, and a page's parameters.
pub type BatchQuery = Both<BatchList, PageParams>;

/// Version of the batch validator scheme, part of every batch ETag.
const BATCH_ETAG_SCHEME: &[u8] = b"vtex-batch/1";

/// A weak validator of a batch: the frames it holds are a pure function of everything hashed
/// here, though their order (and hit or miss) may differ from one response to the next.
fn batch_etag(
    texture: &[u8; 32],
    tile_size: u32,
    frame: u32,
    format: Format,
    shape: Shape,
    tiles: &[TileRef],
) -> HeaderValue {
    let mut h = blake3::Hasher::new();
    h.update(BATCH_ETAG_SCHEME);
    h.update(texture);
    for v in [tile_size, frame] {
        h.update(&v.to_le_bytes());
    }
    // The format with its codec options, and the page shape.
    h.update(format!("{format:?} {shape:?}").as_bytes());
    for t in tiles {
        for v in [t.level, t.x, t.y] {
            h.update(&v.to_le_bytes());
        }
    }
    let hex = h.finalize().to_hex();
    HeaderValue::from_str(&format!("W/\"{}\"", &hex[..32])).expect("hex is a valid header value")
}

/// The list, the format and the shape of a batch: tiles take no page parameter and no ktx2.
fn items(list: BatchList, page: &PageParams) -> Result<(Vec<TileRef>, Format, Shape), ApiError> {
    let BatchList { tiles, pages, format } = list;
    match (tiles, pages) {
        (Some(tiles), None) => {
            let page_params = [
                ("size", page.size.is_some()),
                ("border", page.border.is_some()),
                ("layer", page.layer.is_some()),
                ("codec", page.codec.is_some()),
                ("supercompression", page.supercompression.is_some()),
            ];
            if let Some((name, _)) = page_params.into_iter().find(|(_, given)| *given) {
                return Err(ApiError::bad_request(format!("`{name}` applies to pages only; this batch lists tiles")));
            }
            let PageFormat::Image(format) = format else {
                return Err(ApiError::bad_request(format!(
                    "`format` ktx2 is served for pages only; tiles: {}",
                    Format::EXPECTED
                )));
            };
            Ok((tiles, format, Shape::Tile))
        }
        (None, Some(pages)) => {
            let (format, shape) = pages::page_spec(format, page)?;
            Ok((pages, format, shape))
        }
        _ => Err(ApiError::bad_request("a batch takes exactly one of `tiles` and `pages`")),
    }
}

/// The handler. Tiles in the cache are framed at once; each other tile is a task of its own
/// (they wait for synthesis slots like single tiles do), framed as it finishes.
///
/// A batch whose every tile is in the cache when it starts cannot hold an error frame, so it is
/// marked cacheable like a single tile (`public, immutable`, with a weak ETag: a shared cache
/// may answer the same URL with it for ever); a batch with misses is `no-store`, since a render
/// may still fail or be shed into an error frame.
#[utoipa::path(get,
    path = vtex_wire::urls::BATCH,
    tag = "tiles",
    params(
        TextureId,
        BatchList,
        PageParams,
    ),
    responses(
        (status = 200, description = "a stream of frames, one per tile in completion order: a 32-byte header then \
            the tile's bytes", content(("application/x-vtex-tile-batch"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn batch(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    Query(Both(list, page)): Query<BatchQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let started = Instant::now();
    let frame = page.frame;
    let (tiles, format, shape) = items(list, &page)?;
    let entry = lookup(&app, &id).await?;
    for t in &tiles {
        match shape {
            Shape::Page { size, .. } => address::check_page(&entry, t.level, t.x, t.y, size)?,
            _ => address::check_tile(&entry, t.level, t.x, t.y)?,
        }
    }
    let frame = frame_for(&entry, frame);
    let etag = batch_etag(&entry.key, entry.tile_size, frame, format, shape, &tiles);
    if not_modified(&headers, etag.to_str().unwrap_or_default()) {
        return Ok(not_modified_response(etag));
    }
    let reservation = app.inflight.reserve(tiles.len() as u64 * FRAME_RESERVE)?;
    let mut ready = VecDeque::new();
    let mut pending = JoinSet::new();
    // No more of a batch's misses in flight than its texture may render at once: the rest
    // wait inside the batch, so a view of a hundred misses neither floods the shared queue
    // (to be shed tile by tile) nor asks for more than its texture's share of the slots.
    let turns = Arc::new(Semaphore::new(app.cfg.syntheses_per_texture()));
    for tile in tiles {
        let key = TileKey { texture: entry.key, level: tile.level, x: tile.x, y: tile.y, frame, format, shape };
        match app.engine.cached(&entry, &key) {
            Some(hit) => {
                app.metrics.cache_hit(tile.level);
                push_tile(&mut ready, tile, &hit, Source::Hit);
            }
            None => {
                let (app, entry, turns) = (app.clone(), entry.clone(), turns.clone());
                pending.spawn(async move {
                    let _turn = turns.acquire().await.expect("the semaphore is never closed");
                    let tag = address::key_etag(&entry, &key);
                    (tile, app.engine.tile(&entry, key, None, tag).await.map_err(ApiError::from))
                });
            }
        }
    }
    let deadline = Box::pin(tokio::time::sleep(app.cfg.request_timeout()));
    let body =
        BatchBody { ready, pending, deadline, app: app.clone(), started, timed_out: false, _reservation: reservation };
    let every_tile_cached = body.pending.is_empty();
    let mut resp = Response::new(Body::new(body));
    let h = resp.headers_mut();
    h.insert(header::CONTENT_TYPE, HeaderValue::from_static(CONTENT_TYPE));
    if every_tile_cached {
        h.insert(header::CACHE_CONTROL, CACHE_IMMUTABLE);
        h.insert(header::ETAG, etag);
    } else {
        h.insert(header::CACHE_CONTROL, HeaderValue::from_static("no-store"));
    }
    Ok(resp)
}

fn push_tile(out: &mut VecDeque<Bytes>, tile: TileRef, t: &Tile, source: Source) {
    let cache = if source == Source::Hit { 1 } else { 2 };
    let header = FrameHeader { tile, status: 200, cache, width: t.width, height: t.height, len: t.body.len() as u32 };
    out.push_back(Bytes::copy_from_slice(&header.encode()));
    // The cached bytes themselves (sealed tiles keep their zero-copy send).
    out.push_back(t.body.clone());
}

fn push_error(out: &mut VecDeque<Bytes>, tile: TileRef, e: &ApiError) {
    let (status, json) = e.to_json();
    let header = FrameHeader { tile, status: status.as_u16(), cache: 0, width: 0, height: 0, len: json.len() as u32 };
    let mut b = BytesMut::with_capacity(HEADER_LEN + json.len());
    b.put_slice(&header.encode());
    b.put_slice(json.as_bytes());
    out.push_back(b.freeze());
}

/// A tile as [`Engine::tile`](crate::engine::Engine::tile) answers it.
type Obtained = Result<(Arc<Tile>, Source), ApiError>;

/// The response body: queued chunks first, then tiles as their tasks finish. Dropping it
/// drops the [`JoinSet`], which aborts the tasks still running, and times the whole batch
/// (the request histogram only sees the headers go out).
struct BatchBody {
    ready: VecDeque<Bytes>,
    pending: JoinSet<(TileRef, Obtained)>,
    deadline: Pin<Box<tokio::time::Sleep>>,
    app: App,
    started: Instant,
    timed_out: bool,
    _reservation: Reservation,
}

impl Drop for BatchBody {
    fn drop(&mut self) {
        // `outcome`: every frame handed to the connection, cut off at the deadline, or dropped
        // before its end (the client went away).
        let outcome = if self.timed_out {
            "timeout"
        } else if http_body::Body::is_end_stream(self) {
            "complete"
        } else {
            "dropped"
        };
        self.app.metrics.batch_seconds.with_label_values(&[outcome]).observe(self.started.elapsed().as_secs_f64());
    }
}

impl http_body::Body for BatchBody {
    type Data = Bytes;
    type Error = std::io::Error;

    fn poll_frame(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<Option<Result<Frame<Bytes>, Self::Error>>> {
        let this = self.get_mut();
        loop {
            if let Some(chunk) = this.ready.pop_front() {
                this.app.metrics.bytes_out.inc_by(chunk.len() as u64);
                return Poll::Ready(Some(Ok(Frame::data(chunk))));
            }
            match this.pending.poll_join_next(cx) {
                Poll::Ready(None) => return Poll::Ready(None),
                Poll::Ready(Some(Ok((tile, Ok((t, source)))))) => push_tile(&mut this.ready, tile, &t, source),
                Poll::Ready(Some(Ok((tile, Err(e))))) => push_error(&mut this.ready, tile, &e),
                Poll::Ready(Some(Err(join))) => {
                    // Tasks are only aborted by dropping the body; a panic is a bug, logged.
                    tracing::error!(error = %join, "tile batch task failed");
                    return Poll::Ready(Some(Err(std::io::Error::other("a tile of the batch failed"))));
                }
                Poll::Pending => {
                    if this.deadline.as_mut().poll(cx).is_ready() {
                        this.timed_out = true;
                        return Poll::Ready(Some(Err(std::io::Error::other("tile batch not completed in time"))));
                    }
                    return Poll::Pending;
                }
            }
        }
    }

    fn is_end_stream(&self) -> bool {
        self.ready.is_empty() && self.pending.is_empty()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn headers_round_trip() {
        let h = FrameHeader {
            tile: TileRef { level: 3, x: 70_000, y: u32::MAX },
            status: 404,
            cache: 2,
            width: 256,
            height: 17,
            len: 262_144,
        };
        let b = h.encode();
        assert_eq!(&b[..4], b"vtb\x01");
        assert_eq!(FrameHeader::decode(&b), Some(h));
        assert_eq!(FrameHeader::decode(&b[..31]), None);
        let mut bad = b;
        bad[3] = 2;
        assert_eq!(FrameHeader::decode(&bad), None, "another version is refused");
    }

    #[test]
    fn tile_lists_and_their_errors() {
        let t = |level, x, y| TileRef { level, x, y };
        assert_eq!(parse_tiles("0/1/2,3/4/5").unwrap(), vec![t(0, 1, 2), t(3, 4, 5)]);
        let msg = |s: &str| parse_tiles(s).unwrap_err();
        assert!(msg("").contains("empty"));
        assert!(msg("1/2").contains("item 1 is `1/2`"));
        assert!(msg("1/2/3,4/5/6/7").contains("item 2"));
        assert!(msg("1/2/3,").contains("item 2"));
        assert!(msg("1/x/3").contains("item 1: `x` must be an integer"));
        assert!(msg("1/-2/3").contains("negative"));
        assert!(msg("1/2/3,0/0/0,1/2/3").contains("lists tile 1/2/3 twice"));
        assert!(msg(&"0/0/0,".repeat(2000)).contains("longer than the limit of 8192"));
        let many = (0..=MAX_TILES).map(|i| format!("0/{i}/0")).collect::<Vec<_>>().join(",");
        assert!(msg(&many).contains("at most 256"));
        let most = (0..MAX_TILES).map(|i| format!("0/{i}/0")).collect::<Vec<_>>().join(",");
        assert_eq!(parse_tiles(&most).unwrap().len(), MAX_TILES);
        assert!(msg(&format!("{},0/0/0", "9".repeat(500))).len() < 300, "long input is not echoed");
    }
}
