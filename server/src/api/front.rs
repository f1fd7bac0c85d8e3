//! The service hyper calls for every request: the [`router`], except for plain GETs of a
//! single tile, which it answers itself.
//!
//! Why: a warm tile is a cache lookup, and the router's per-request machinery (the route's
//! boxed services, its layers, the request extensions) costs more than the rest of such a
//! request. The fast path matches the path against the router's own template ([`TILE`]) with
//! the router's matcher (`matchit`), fills the same extractor types, runs the same handler
//! ([`tiles::answer`]) and gives the answer the same CORS headers, metrics label, log line
//! and deadline. Anything else (HEAD, other methods, percent-encoded paths, other routes)
//! takes the router, so answers are the same either way (tests compare both).

use super::extract::{path_params, query_params};
use super::{cors_layer, count, router, tiles, timed_out, App, TILE};
use axum::body::Body;
use axum::http::{header, HeaderMap, HeaderValue, Method, Request};
use axum::response::{IntoResponse, Response};
use axum::Router;
use hyper::body::Incoming;
use std::convert::Infallible;
use std::future::Future;
use std::pin::Pin;
use std::sync::Arc;
use std::time::Instant;
use tower::ServiceExt;
use tower_http::cors::CorsLayer;

/// Cloned per connection and per request (one reference count); the state is shared.
#[derive(Clone)]
pub struct Front(Arc<Inner>);

struct Inner {
    app: App,
    router: Router,
    /// [`TILE`] alone, in the matcher the router uses.
    tile: matchit::Router<()>,
    cors: CorsHeaders,
}

impl Front {
    pub fn new(app: App) -> Front {
        let mut tile = matchit::Router::new();
        tile.insert(TILE, ()).expect("the tile route is a valid template");
        let cors = CorsHeaders::from_layer(cors_layer());
        Front(Arc::new(Inner { router: router(app.clone()), app, tile, cors }))
    }
}

impl hyper::service::Service<Request<Incoming>> for Front {
    type Response = Response;
    type Error = Infallible;
    type Future = Pin<Box<dyn Future<Output = Result<Response, Infallible>> + Send>>;

    fn call(&self, req: Request<Incoming>) -> Self::Future {
        let this = self.0.clone();
        Box::pin(async move {
            // Percent-encoded segments need decoding, which the router's extractor does.
            let plain = req.method() == Method::GET && !req.uri().path().contains('%');
            if let Some(m) = plain.then(|| this.tile.at(req.uri().path()).ok()).flatten() {
                let start = Instant::now();
                let limit = this.app.cfg.request_timeout();
                let work = async {
                    let (path, query) = (path_params(m.params.iter())?, query_params(req.uri().query())?);
                    tiles::answer(&this.app, path, query, req.headers()).await
                };
                let mut resp = match tokio::time::timeout(limit, work).await {
                    Ok(answer) => answer.into_response(),
                    Err(_) => timed_out(limit).into_response(),
                };
                this.cors.apply(resp.headers_mut());
                count(&this.app, TILE, &Method::GET, start, &resp);
                tracing::info!(
                    target: "vtex::http",
                    method = "GET",
                    uri = %req.uri(),
                    status = resp.status().as_u16(),
                    latency_us = start.elapsed().as_micros() as u64,
                    "finished processing request"
                );
                return Ok(resp);
            }
            match this.router.clone().oneshot(req.map(Body::new)).await {
                Ok(resp) => Ok(resp),
                Err(never) => match never {},
            }
        })
    }
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
        let resp = ready(svc.oneshot(req)).expect("the CORS layer answers at once");
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
fn ready<F: Future>(f: F) -> F::Output {
    let mut f = std::pin::pin!(f);
    match f.as_mut().poll(&mut std::task::Context::from_waker(std::task::Waker::noop())) {
        std::task::Poll::Ready(v) => v,
        std::task::Poll::Pending => panic!("expected an immediate future"),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

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
