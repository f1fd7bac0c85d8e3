//! The HTTP API v1, the static viewer, and the layers around them. [`routes`] is the one
//! table of routes: requests are matched there and nowhere else ([`router`] wraps it in the
//! layers, and the OpenAPI description is checked against it).

pub mod error;
pub mod extract;
pub mod inflight;
pub mod interop;
pub mod openapi;
pub mod operations;
pub mod origin;
pub mod params;
pub mod resources;

use crate::config::ServeConfig;
use crate::engine::{ETag, Engine};
use crate::metrics::Metrics;
use crate::store::{Entry, Record, Store};
use axum::error_handling::HandleErrorLayer;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{header, HeaderMap, HeaderName, HeaderValue, Method, StatusCode};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::any;
use axum::{BoxError, Router};
use error::ApiError;
use extract::{NoQuery, Query};
use http_body_util::BodyExt;
use inflight::Inflight;
use interop::{dzi, iiif, presentation, tilejson};
use operations::{health, web};
use resources::{batch, deletion, models, pages, textures, tiles, writes};
use serde::Deserialize;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;
use std::time::Instant;
use tower::ServiceBuilder;
use tower_http::compression::predicate::{DefaultPredicate, NotForContentType, Predicate};
use tower_http::compression::{CompressionLayer, CompressionLevel};
use tower_http::cors::{Any, CorsLayer};
use tower_http::services::ServeDir;
use tower_http::trace::{DefaultMakeSpan, TraceLayer};
use utoipa_axum::{router::OpenApiRouter, routes};

pub use error::ApiError as Error;
pub use web::Web;

/// The route of a single tile: [`router`] serves it, and the fast tile path of the connection
/// code (`serve/fast_tile.rs`) answers plain GETs of it directly, matching paths against this
/// same template.
pub const TILE: &str = vtex_wire::urls::TILE;
/// The route of a tile batch, the one route whose query may be longer than
/// [`extract::MAX_QUERY_BYTES`].
pub const BATCH: &str = vtex_wire::urls::BATCH;

pub const CACHE_IMMUTABLE: HeaderValue = HeaderValue::from_static("public, max-age=31536000, immutable");
pub static X_VTEX_CACHE: HeaderName = HeaderName::from_static("x-vtex-cache");
pub static X_VTEX_WIDTH: HeaderName = HeaderName::from_static("x-vtex-width");
pub static X_VTEX_HEIGHT: HeaderName = HeaderName::from_static("x-vtex-height");

/// Everything a request handler needs: the engine, and what only HTTP has.
pub struct AppState {
    pub engine: Arc<Engine>,
    pub metrics: Arc<Metrics>,
    /// The budget of response bodies in flight (`--inflight-mb`).
    pub inflight: Inflight,
    /// Set when shutdown begins: no longer ready (`/readyz`).
    pub draining: AtomicBool,
    /// Who may write (`VTEX_WRITE_TOKEN`, `--read-only`, `--cors-write-origins`).
    pub writes: writes::WritePolicy,
    pub cfg: ServeConfig,
}

pub type App = Arc<AppState>;

impl AppState {
    pub fn new(store: Arc<Store>, cfg: ServeConfig) -> App {
        let metrics = Arc::new(Metrics::new());
        metrics.textures_budget_bytes.set(store.bounds().limits.max_resident_bytes as i64);
        metrics.model_cache_budget_bytes.set(store.resources().cache_budget() as i64);
        let engine = Arc::new(Engine::new(store, &cfg, metrics.clone()));
        let inflight = Inflight::new(cfg.inflight_bytes());
        metrics.inflight_budget_bytes.set(inflight.budget_bytes() as i64);
        let (draining, writes) = (AtomicBool::new(false), writes::WritePolicy::new(&cfg));
        Arc::new(AppState { engine, metrics, inflight, draining, writes, cfg })
    }
}

/// The path of the routes of one texture, `/api/v1/textures/{id}…`.
#[derive(Deserialize, utoipa::IntoParams)]
#[serde(deny_unknown_fields)]
#[into_params(parameter_in = Path)]
pub struct TextureId {
    /// texture id: 64 lowercase hex characters, the BLAKE3 of its bundle
    pub id: String,
}

/// The routes, the static viewer as the fallback, and the layers every request passes:
/// the log outermost (so it sees every answer, a timeout's too), then compression, metrics
/// (which count bytes before compression), the write policy (it answers write preflights
/// itself), CORS, the request deadline and the body limit.
pub fn router(app: App) -> Router {
    let limit = app.cfg.request_timeout();
    let on_timeout = move |_: BoxError| async move { timed_out(limit) };
    let layers = ServiceBuilder::new()
        .layer(
            // The span gives what handlers log its request; the request's own line is the
            // access log's (`serve/access.rs`), so the layer logs no line per request.
            TraceLayer::new_for_http()
                .make_span_with(DefaultMakeSpan::new().level(tracing::Level::INFO))
                .on_request(())
                .on_response(())
                .on_eos(()),
        )
        .layer(middleware::map_response(weaken_encoded_etag))
        .layer(compression_layer())
        .layer(middleware::from_fn_with_state(app.clone(), observe))
        .layer(middleware::from_fn_with_state(app.clone(), writes::guard))
        .layer(cors_layer())
        .layer(HandleErrorLayer::new(on_timeout))
        .timeout(limit)
        .layer(DefaultBodyLimit::max(app.cfg.max_upload_bytes()));
    let (routes, _) = routes().split_for_parts();
    routes.method_not_allowed_fallback(method_not_allowed).merge(viewer(&app)).layer(layers).with_state(app)
}

/// The route table. A described route is declared once, by its handler: `routes!` takes the
/// path and method from the handler's `#[utoipa::path]`, so the router and the OpenAPI
/// description ([`openapi::document`]) cannot disagree.
pub(crate) fn routes() -> OpenApiRouter<App> {
    OpenApiRouter::with_openapi(openapi::base())
        .routes(routes!(textures::list, textures::upload))
        .routes(routes!(textures::info, textures::patch, deletion::delete))
        .routes(routes!(textures::encoding))
        .routes(routes!(batch::batch))
        .routes(routes!(tiles::tile))
        .routes(routes!(tiles::region))
        // Deployment: liveness and readiness.
        .routes(routes!(health::healthz))
        .routes(routes!(health::readyz))
        // Virtual-texture pages with borders and KTX2 mip chains for game engines (pages.rs).
        .routes(routes!(pages::page))
        .routes(routes!(pages::mip_chain))
        // Deep Zoom and IIIF Image API 3 (dzi.rs, iiif.rs), over the same tiles and renders, and
        // IIIF Presentation 3 documents for viewers (presentation.rs).
        .routes(routes!(dzi::descriptor))
        .routes(routes!(dzi::tile))
        .routes(routes!(iiif::base))
        .routes(routes!(iiif::info))
        .routes(routes!(iiif::image))
        .routes(routes!(presentation::manifest_json))
        .routes(routes!(presentation::collection_json))
        // TileJSON 3 and XYZ tiles (tilejson.rs).
        .routes(routes!(tilejson::tilejson))
        .routes(routes!(tilejson::xyz))
        // The model catalogue: parameter schemas and examples (models.rs).
        .routes(routes!(models::list_models))
        .routes(routes!(models::model))
        .routes(routes!(models::example_image))
        .routes(routes!(metrics))
        // The OpenAPI 3.1 description of this table (openapi.rs).
        .routes(routes!(openapi::openapi_json))
        // Not described: the JSON 404 of unknown IIIF and API paths.
        .route("/iiif", any(iiif::not_found))
        .route("/iiif/{*rest}", any(iiif::not_found))
        .route("/api", any(api_not_found))
        .route("/api/{*rest}", any(api_not_found))
}

/// The viewer at `/` and every path no route takes: from `--web-dir` when given, else the copy
/// built into the binary ([`web`]).
fn viewer(app: &App) -> Router<App> {
    match &app.cfg.web_dir {
        Some(dir) => Router::new().fallback_service(
            ServeDir::new(dir).append_index_html_on_directories(true).precompressed_br().precompressed_gzip(),
        ),
        None => Router::new().fallback(web::serve),
    }
}

/// gzip, Brotli or zstd, as the client accepts (`Vary: Accept-Encoding` on what may be
/// compressed), for everything but images (already compressed), bodies under 32 bytes and the
/// streamed tile batch (compression would hold its frames back). The fastest level: raw tiles
/// are compressed on the fly, per request.
fn compression_layer() -> CompressionLayer<impl Predicate> {
    let predicate = DefaultPredicate::new().and(NotForContentType::const_new(batch::CONTENT_TYPE));
    CompressionLayer::new().quality(CompressionLevel::Fastest).compress_when(predicate)
}

/// Whether `Accept-Encoding` names an encoding [`compression_layer`] might apply.
pub fn accepts_compression(headers: &HeaderMap) -> bool {
    headers.get_all(header::ACCEPT_ENCODING).iter().any(|v| {
        v.to_str().is_ok_and(|v| {
            v.split(',').any(|e| matches!(e.split(';').next().unwrap_or("").trim(), "gzip" | "br" | "zstd" | "*"))
        })
    })
}

/// A compressed body is another representation of the same resource: its strong ETag becomes
/// weak (as nginx does), so `If-None-Match` still matches and byte ranges never mix them.
async fn weaken_encoded_etag<B>(mut resp: Response<B>) -> Response<B> {
    if resp.headers().contains_key(header::CONTENT_ENCODING) {
        if let Some(tag) = resp.headers().get(header::ETAG).filter(|t| !t.as_bytes().starts_with(b"W/")) {
            let weak = [b"W/".as_slice(), tag.as_bytes()].concat();
            if let Ok(weak) = HeaderValue::from_bytes(&weak) {
                resp.headers_mut().insert(header::ETAG, weak);
            }
        }
    }
    resp
}

/// The answer to a request not done within the deadline `limit`.
pub(crate) fn timed_out(limit: std::time::Duration) -> ApiError {
    ApiError::Timeout(format!("request not completed within {} s (slow client or overload)", limit.as_secs_f64()))
}

/// The CORS policy of reads: any origin, the read methods, any request header, and the
/// response headers the viewer reads exposed. Writes have their own ([`writes::guard`]). The
/// answers do not depend on the request's `Origin` or preflight headers, so they carry no
/// `Vary` for them (caches keep one copy).
pub(crate) fn cors_layer() -> CorsLayer {
    CorsLayer::new()
        .vary([])
        .allow_origin(Any)
        .allow_methods([Method::GET, Method::HEAD, Method::OPTIONS])
        .allow_headers(Any)
        .expose_headers([header::ETAG, X_VTEX_CACHE.clone(), X_VTEX_WIDTH.clone(), X_VTEX_HEIGHT.clone()])
}

/// Counts and times every request under the template of the route that matched it, so the
/// metrics name the same routes as the router, with a bounded set of labels.
async fn observe(State(app): State<App>, req: Request, next: Next) -> Response {
    let start = Instant::now();
    let route = req.extensions().get::<MatchedPath>().cloned();
    let method = req.method().clone();
    let resp = next.run(req).await;
    let route = route.as_ref().map_or(crate::metrics::STATIC, MatchedPath::as_str);
    count(&app, route, &method, start, &resp);
    resp
}

/// Counts one answered request under `route`.
pub(crate) fn count(app: &AppState, route: &str, method: &Method, start: Instant, resp: &Response) {
    let bytes = http_body::Body::size_hint(resp.body()).exact().unwrap_or(0);
    app.metrics.request_done(route, method.as_str(), resp.status().as_str(), start.elapsed().as_secs_f64(), bytes);
}

#[utoipa::path(get,
    path = "/metrics",
    tag = "operations",
    responses((status = 200, description = "Prometheus text format", content(("text/plain")))))]
async fn metrics(State(app): State<App>, _: Query<NoQuery>) -> Response {
    let m = &app.metrics;
    let (cache, store) = (&app.engine.cache, &app.engine.store);
    m.cache_bytes.set(cache.bytes() as i64);
    m.cache_mapped_bytes.set(app.cfg.send.mapped_bytes() as i64);
    m.cache_entries.set(cache.len() as i64);
    m.catch_up(&m.cache_evictions, cache.evictions());
    m.textures.set(store.len() as i64);
    m.store_bytes.set(store.stored_bytes() as i64);
    m.textures_loaded.set(store.loaded() as i64);
    m.textures_loaded_bytes.set(store.loaded_bytes() as i64);
    m.catch_up(&m.texture_loads, store.loads());
    m.catch_up(&m.texture_evictions, store.evictions());
    m.syntheses_queued.set(app.engine.slots.queued() as i64);
    m.inflight_bytes.set(app.inflight.reserved_bytes() as i64);
    m.read_models(store.resources());
    ([(header::CONTENT_TYPE, "text/plain; version=0.0.4")], m.render()).into_response()
}

async fn api_not_found(req: Request) -> ApiError {
    ApiError::not_found(format!("no API route {} {}", req.method(), error::echo(req.uri().path())))
}

async fn method_not_allowed(req: Request) -> ApiError {
    ApiError::MethodNotAllowed(format!("method {} is not allowed on {}", req.method(), error::echo(req.uri().path())))
}

/// True when `If-None-Match` names `etag` (weak comparison, as RFC 9110 requires) or is `*`.
pub fn not_modified(headers: &HeaderMap, etag: &str) -> bool {
    let bare = |t: &str| t.trim().trim_start_matches("W/").to_string();
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.trim() == "*" || v.split(',').any(|t| bare(t) == bare(etag)))
}

/// A 304 carrying the validators a 200 would have carried.
pub fn not_modified_response(etag: HeaderValue) -> Response {
    let mut resp = StatusCode::NOT_MODIFIED.into_response();
    resp.headers_mut().insert(header::ETAG, etag);
    resp.headers_mut().insert(header::CACHE_CONTROL, CACHE_IMMUTABLE);
    resp
}

/// How much more of an oversized body is read and thrown away, and for how long (in all, and
/// waiting for each piece), so that a client still sending it receives the 413 rather than a
/// reset connection; past any bound the connection is cut.
const DRAIN_BYTES: usize = 16 << 20;
const DRAIN_TIME: std::time::Duration = std::time::Duration::from_secs(5);
const DRAIN_IDLE: std::time::Duration = std::time::Duration::from_millis(500);

/// Reads a request body of at most `limit` bytes; larger is 413 naming the limit.
pub async fn read_body(req: Request, limit: usize) -> Result<bytes::Bytes, ApiError> {
    if declared_length(req.headers()).is_some_and(|n| n > limit as u64) {
        return Err(refuse_oversized(req, limit).await);
    }
    let (parts, mut body) = req.into_parts();
    let mut bytes = bytes::BytesMut::new();
    while let Some(frame) = body.frame().await {
        let frame = frame.map_err(|e| ApiError::bad_request(format!("could not read the request body: {e}")))?;
        if let Some(data) = frame.data_ref() {
            if bytes.len() + data.len() > limit {
                return Err(refuse_oversized(Request::from_parts(parts, body), limit).await);
            }
            bytes.extend_from_slice(data);
        }
    }
    Ok(bytes.freeze())
}

/// The request's `Content-Length`, when it has a valid one.
pub fn declared_length(headers: &HeaderMap) -> Option<u64> {
    headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()?.parse::<u64>().ok())
}

/// The 413 for a body over `limit`, given after [`drain`]ing the rest of the body.
pub async fn refuse_oversized(req: Request, limit: usize) -> ApiError {
    drain(req).await;
    ApiError::PayloadTooLarge(format!("request body larger than the limit of {limit} bytes"))
}

/// Reads and throws away the body of a request about to be refused, within [`DRAIN_BYTES`]
/// and [`DRAIN_TIME`] — unless the client waits for `100 Continue` before sending it, or
/// sends nothing for [`DRAIN_IDLE`] — so that a client (or a proxy) still sending it receives
/// the refusal rather than a reset connection.
pub async fn drain(req: Request) {
    let waits_to_send =
        req.headers().get(header::EXPECT).is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"100-continue"));
    let mut body = req.into_body();
    let drain = async {
        let mut left = DRAIN_BYTES;
        while let Ok(Some(Ok(frame))) = tokio::time::timeout(DRAIN_IDLE, body.frame()).await {
            match frame.data_ref() {
                Some(data) if data.len() >= left => return,
                Some(data) => left -= data.len(),
                None => {}
            }
        }
    };
    if !waits_to_send {
        let _ = tokio::time::timeout(DRAIN_TIME, drain).await;
    }
}

/// Texture `id`'s record, without loading it ([`Engine::record`]).
pub async fn record(app: &AppState, id: &str) -> Result<Arc<Record>, ApiError> {
    Ok(app.engine.record(id).await?)
}

/// Texture `id`, loaded ([`Engine::lookup`]).
pub async fn lookup(app: &AppState, id: &str) -> Result<Arc<Entry>, ApiError> {
    Ok(app.engine.lookup(id).await?)
}

/// An ETag as a header value (its bytes shared, not copied).
pub fn etag_header(tag: &ETag) -> HeaderValue {
    HeaderValue::from_maybe_shared(tag.bytes()).expect("quotes and hex digits are a valid header value")
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn if_none_match_forms() {
        let mut h = HeaderMap::new();
        h.insert(header::IF_NONE_MATCH, HeaderValue::from_static("\"a\", W/\"b\""));
        assert!(not_modified(&h, "\"a\""));
        assert!(not_modified(&h, "\"b\""));
        assert!(!not_modified(&h, "\"c\""));
        h.insert(header::IF_NONE_MATCH, HeaderValue::from_static("*"));
        assert!(not_modified(&h, "\"c\""));
        assert!(!not_modified(&HeaderMap::new(), "\"a\""));
    }
}
