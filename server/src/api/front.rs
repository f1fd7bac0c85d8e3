//! The service hyper calls for every request: it counts, times and logs each request, bounds
//! it with the request deadline, and hands tile GETs straight to the tile handler; everything
//! else goes through the axum router.
//!
//! Why tiles skip the router: a warm tile is a cache lookup, yet through axum's router and
//! three `from_fn`/CORS layers it cost ~54,000 instructions, mostly boxed futures, service
//! clones, header-map copies and percent-decoding (callgrind, BENCHMARKS.md). The direct path
//! runs the same handler ([`tiles::tile`]) with the same CORS headers; anything it does not
//! recognise exactly (HEAD, other methods, percent-encoded or malformed paths) still takes the
//! router, so answers are the same either way (tests compare both paths).

use super::error::ApiError;
use super::tiles::{self, TilePath};
use super::{router, App, X_VTEX_CACHE, X_VTEX_HEIGHT, X_VTEX_WIDTH};
use crate::metrics::Route;
use axum::body::Body;
use axum::http::{header, HeaderMap, HeaderValue, Method, Request, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Router;
use hyper::body::Incoming;
use std::convert::Infallible;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tower::ServiceExt;
use tower_http::cors::{Any, CorsLayer};

/// Cloned per connection and per request (one reference count); the state is shared.
#[derive(Clone)]
pub struct Front(Arc<Inner>);

struct Inner {
    app: App,
    router: Router,
    cors: CorsHeaders,
}

/// The CORS policy: any origin, the API's methods, any request header, and the response
/// headers the viewer reads exposed.
pub fn cors_layer() -> CorsLayer {
    CorsLayer::new()
        .allow_origin(Any)
        .allow_methods([Method::GET, Method::HEAD, Method::POST, Method::PATCH, Method::OPTIONS])
        .allow_headers(Any)
        .expose_headers([header::ETAG, X_VTEX_CACHE.clone(), X_VTEX_WIDTH.clone(), X_VTEX_HEIGHT.clone()])
}

/// The headers [`cors_layer`] puts on a response to a request that is not a preflight
/// (OPTIONS): they do not depend on the request, so they are taken from the layer once, as
/// static values (cloning one then touches no shared reference count).
struct CorsHeaders(Vec<(header::HeaderName, HeaderValue)>);

impl CorsHeaders {
    fn from_layer(layer: CorsLayer) -> CorsHeaders {
        let svc = tower::ServiceBuilder::new()
            .layer(layer)
            .service_fn(|_: Request<Body>| async { Ok::<_, Infallible>(Response::new(Body::empty())) });
        let req = Request::get("/").body(Body::empty()).expect("a static request");
        let resp = futures_ready(svc.oneshot(req)).expect("the CORS layer answers at once");
        let leak = |v: &HeaderValue| {
            let text: &'static str = v.to_str().expect("CORS header values are ASCII").to_owned().leak();
            HeaderValue::from_static(text)
        };
        CorsHeaders(resp.headers().iter().map(|(k, v)| (k.clone(), leak(v))).collect())
    }

    /// Adds them as the layer would (`Vary` appended, the others replaced).
    fn apply(&self, h: &mut HeaderMap) {
        for (k, v) in &self.0 {
            if k == header::VARY {
                h.append(k, v.clone());
            } else {
                h.insert(k, v.clone());
            }
        }
    }
}

/// Polls a future that needs no waking (the CORS layer over an immediate service) once.
fn futures_ready<F: Future>(f: F) -> F::Output {
    let mut f = std::pin::pin!(f);
    match f.as_mut().poll(&mut std::task::Context::from_waker(std::task::Waker::noop())) {
        std::task::Poll::Ready(v) => v,
        std::task::Poll::Pending => panic!("expected an immediate future"),
    }
}

impl Front {
    pub fn new(app: App) -> Front {
        let cors = CorsHeaders::from_layer(cors_layer());
        Front(Arc::new(Inner { router: router(app.clone()), app, cors }))
    }
}

impl hyper::service::Service<Request<Incoming>> for Front {
    type Response = Response;
    type Error = Infallible;
    type Future = Pin<Box<dyn Future<Output = Result<Response, Infallible>> + Send>>;

    fn call(&self, req: Request<Incoming>) -> Self::Future {
        let start = Instant::now();
        let this = self.0.clone();
        Box::pin(async move {
            let method = req.method().clone();
            let path = tracing::enabled!(tracing::Level::INFO).then(|| req.uri().path().to_owned());
            let limit = this.app.cfg.request_timeout();
            let direct = if method == Method::GET { TilePath::plain(req.uri().path()) } else { None };
            let (route, answer) = match direct {
                Some(tile) => (Route::Tiles, tokio::time::timeout(limit, this.tile(tile, &req)).await),
                None => (Route::of(req.uri().path()), tokio::time::timeout(limit, this.route(req)).await),
            };
            let resp = answer.unwrap_or_else(|_| {
                let mut resp = ApiError::new(
                    StatusCode::REQUEST_TIMEOUT,
                    format!("request not completed within {} s (slow client or overload)", limit.as_secs_f64()),
                )
                .into_response();
                this.cors.apply(resp.headers_mut());
                resp
            });
            observe(&this.app, route, &method, path, start.elapsed(), &resp);
            Ok(resp)
        })
    }
}

impl Inner {
    /// A plain tile GET, answered directly, with the CORS headers the router would add.
    async fn tile(&self, path: TilePath<'_>, req: &Request<Incoming>) -> Response {
        let mut resp = tiles::tile(&self.app, path, req.uri().query(), req.headers()).await.into_response();
        self.cors.apply(resp.headers_mut());
        resp
    }

    /// Everything else, through the router.
    async fn route(&self, req: Request<Incoming>) -> Response {
        match self.router.clone().oneshot(req.map(Body::new)).await {
            Ok(resp) => resp,
            Err(never) => match never {},
        }
    }
}

/// Counts, times and logs one request.
fn observe(app: &App, route: Route, method: &Method, path: Option<String>, elapsed: Duration, resp: &Response) {
    let status = resp.status();
    let bytes = http_body::Body::size_hint(resp.body()).exact().unwrap_or(0);
    app.metrics.request_done(route, method, status, elapsed.as_secs_f64(), bytes);
    if let Some(path) = path {
        tracing::info!(
            target: "vtex::http",
            method = %method,
            path,
            status = status.as_u16(),
            latency_us = elapsed.as_micros() as u64,
            bytes,
            "request"
        );
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn tile_paths_taken_directly() {
        let id = "ab".repeat(32);
        let path = format!("/api/v1/textures/{id}/tiles/3/4/5.png");
        let p = TilePath::plain(&path).unwrap();
        assert_eq!((p.id, p.level, p.x, p.file), (id.as_str(), "3", "4", "5.png"));
        for other in [
            format!("/api/v1/textures/{id}/tiles/3/4/5.png/"),
            format!("/api/v1/textures/{id}/tiles/3/4"),
            format!("/api/v1/textures/{id}/tiles/3//5.png"),
            format!("/api/v1/textures/{id}/tile/3/4/5.png"),
            format!("/api/v1/textures/{id}/tiles/%33/4/5.png"),
            "/api/v1/textures//tiles/3/4/5.png".to_string(),
            format!("/api/v1/textures/{id}"),
            "/healthz".to_string(),
        ] {
            assert!(TilePath::plain(&other).is_none(), "{other}");
        }
    }

    #[test]
    fn cors_headers_are_the_layers() {
        let cors = CorsHeaders::from_layer(cors_layer());
        let mut h = HeaderMap::new();
        cors.apply(&mut h);
        assert_eq!(h["access-control-allow-origin"], "*");
        let exposed = h["access-control-expose-headers"].to_str().unwrap().to_ascii_lowercase();
        for name in ["etag", "x-vtex-cache", "x-vtex-width", "x-vtex-height"] {
            assert!(exposed.contains(name), "{exposed}");
        }
        assert!(h.contains_key(header::VARY));
    }
}
