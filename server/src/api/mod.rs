//! The HTTP API v1, the static viewer, and the layers around them. [`routes`] is the one
//! table of routes: requests are matched there and nowhere else ([`router`] wraps it in the
//! layers, and the OpenAPI description is checked against it).

pub mod error;
pub mod extract;
pub mod http;
pub mod inflight;
pub mod interop;
pub mod openapi;
pub mod operations;
pub mod origin;
pub mod params;
pub mod resources;
pub mod state;
pub mod write_policy;

use axum::error_handling::HandleErrorLayer;
use axum::extract::{DefaultBodyLimit, MatchedPath, Request, State};
use axum::http::{header, HeaderValue, Method};
use axum::middleware::{self, Next};
use axum::response::{IntoResponse, Response};
use axum::routing::any;
use axum::{BoxError, Extension, Router};
use error::ApiError;
use extract::{NoQuery, Query};
use http::{timed_out, X_VTEX_CACHE, X_VTEX_HEIGHT, X_VTEX_WIDTH};
use interop::{dzi, iiif, presentation, tilejson};
use operations::{health, web};
use resources::{batch, deletion, metatiles, models, pages, textures, tiles};
use state::{App, AppState};
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
        .layer(middleware::from_fn_with_state(app.clone(), screen_writes))
        .layer(cors_layer())
        .layer(HandleErrorLayer::new(on_timeout))
        .timeout(limit)
        .layer(DefaultBodyLimit::max(app.cfg.max_upload_bytes()));
    // The description the routes were declared with, for `GET /api/v1/openapi.json`.
    let (routes, document) = routes().split_for_parts();
    routes
        .method_not_allowed_fallback(method_not_allowed)
        .merge(viewer(&app))
        .layer(Extension(Arc::new(document)))
        .layer(layers)
        .with_state(app)
}

/// The route table. A described route is declared once, by its handler: `routes!` takes the
/// path and method from the handler's `#[utoipa::path]`, so the router and the OpenAPI
/// description cannot disagree.
pub(crate) fn routes() -> OpenApiRouter<App> {
    OpenApiRouter::with_openapi(openapi::base())
        .routes(routes!(textures::list, textures::upload))
        .routes(routes!(textures::info, textures::patch, deletion::delete))
        .routes(routes!(textures::encoding))
        .routes(routes!(batch::batch))
        .routes(routes!(tiles::tile))
        .routes(routes!(metatiles::metatile))
        .routes(routes!(tiles::region))
        // Deployment: liveness and readiness.
        .routes(routes!(health::healthz))
        .routes(routes!(health::readyz))
        // Virtual-texture pages with borders and KTX2 mip chains for game engines (pages.rs).
        .routes(routes!(pages::page))
        .routes(routes!(pages::page_metatile))
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

/// The CORS policy of reads: any origin, the read methods, any request header, and the
/// response headers the viewer reads exposed. Writes have their own ([`write_policy`]). The
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

/// The write policy ([`write_policy`]) in front of every route.
async fn screen_writes(State(app): State<App>, req: Request, next: Next) -> Response {
    match app.writes.screen(&app.cfg, req).await {
        Ok(req) => next.run(req).await,
        Err(answer) => answer,
    }
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
    m.cache_outside_bytes.set(cache.outside() as i64);
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
