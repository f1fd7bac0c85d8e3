//! The service hyper calls for every request: the [`router`], except for plain GETs of a
//! single tile, which it answers itself.
//!
//! Why: a warm tile is a cache lookup, and the router's per-request machinery (the route's
//! boxed services, its layers, the request extensions) costs more than the rest of such a
//! request. The fast path matches the path against the router's own template ([`TILE`]) with
//! the router's matcher (`matchit`), fills the same extractor types, runs the same handler
//! ([`tiles::answer`]) and gives the answer the same CORS headers, metrics label and
//! deadline. Anything else (HEAD, other methods, percent-encoded paths, other routes)
//! takes the router, so answers are the same either way (tests compare both).
//!
//! Before either, every request's head is checked where it costs least, before any route or
//! parser sees it: its `Host` (RFC 9112 §3.2) and its query's length and number of parameters
//! ([`check_query`]). Each connection has its own [`Connection`] service, which counts its
//! requests in flight for the idle timeout, and writes each request's access line once its
//! body is sent ([`super::access`]), whichever path answered it.

use super::access::AccessLine;
use super::error::{echo, ApiError};
use super::extract::{check_query, path_params, query_params, MAX_BATCH_QUERY_BYTES, MAX_QUERY_BYTES};
use super::{accepts_compression, cors_layer, count, router, tiles, timed_out, App, BATCH, TILE};
use crate::transport::{Activity, InFlight};
use axum::body::Body;
use axum::extract::ConnectInfo;
use axum::http::uri::Authority;
use axum::http::{header, HeaderMap, HeaderValue, Method, Request, Version};
use axum::response::{IntoResponse, Response};
use axum::Router;
use bytes::Bytes;
use hyper::body::Incoming;
use std::convert::Infallible;
use std::future::Future;
use std::net::SocketAddr;
use std::pin::Pin;
use std::sync::Arc;
use std::task::{Context, Poll};
use std::time::Instant;
use tower::ServiceExt;
use tower_http::cors::CorsLayer;

/// Largest request head (request line and headers) hyper reads, in either protocol: the longest
/// query any route takes (a tile batch's) and room for ordinary headers.
pub const MAX_HEAD_BYTES: usize = MAX_BATCH_QUERY_BYTES + 32 * 1024;

/// The `route` label of requests refused before routing (a bad `Host`, an oversized query).
const REFUSED: &str = "refused";

/// Cloned per connection and per request (one reference count); the state is shared.
#[derive(Clone)]
pub struct Front(Arc<Inner>);

struct Inner {
    app: App,
    router: Router,
    /// [`TILE`] alone, in the matcher the router uses.
    tile: matchit::Router<()>,
    /// [`BATCH`] alone, likewise: the route allowed a longer query.
    batch: matchit::Router<()>,
    cors: CorsHeaders,
}

impl Front {
    pub fn new(app: App) -> Front {
        let one = |template: &str| {
            let mut m = matchit::Router::new();
            m.insert(template, ()).expect("route templates are valid");
            m
        };
        let cors = CorsHeaders::from_layer(cors_layer());
        Front(Arc::new(Inner { router: router(app.clone()), app, tile: one(TILE), batch: one(BATCH), cors }))
    }

    /// The service of one connection, counting its requests in flight in `activity`.
    /// The service of one connection from `peer`, which every request of it carries as the
    /// extension [`ConnectInfo`] (who may write, which proxies are trusted).
    pub fn connection(&self, activity: Arc<Activity>, peer: SocketAddr) -> Connection {
        Connection { front: self.clone(), activity, peer }
    }
}

/// [`Front`] serving one connection.
pub struct Connection {
    front: Front,
    activity: Arc<Activity>,
    peer: SocketAddr,
}

impl hyper::service::Service<Request<Incoming>> for Connection {
    type Response = Response<Tracked>;
    type Error = Infallible;
    type Future = Pin<Box<dyn Future<Output = Result<Response<Tracked>, Infallible>> + Send>>;

    fn call(&self, mut req: Request<Incoming>) -> Self::Future {
        req.extensions_mut().insert(ConnectInfo(self.peer));
        let in_flight = self.activity.start();
        let this = self.front.0.clone();
        let start = Instant::now();
        let info = this.app.cfg.access_log;
        let logged = AccessLine::wanted(info).then(|| (req.method().clone(), req.uri().clone()));
        Box::pin(async move {
            let resp = Inner::answer(this, req).await;
            let status = resp.status().as_u16();
            let line = logged.map(|(method, uri)| AccessLine::new(method, uri, status, start, info));
            Ok(resp.map(|body| Tracked { body, _in_flight: in_flight, line }))
        })
    }
}

/// A response body that keeps its request counted in flight until it is finished or dropped,
/// and then writes its access line.
pub struct Tracked {
    body: Body,
    _in_flight: InFlight,
    line: Option<AccessLine>,
}

impl http_body::Body for Tracked {
    type Data = Bytes;
    type Error = axum::Error;

    fn poll_frame(
        mut self: Pin<&mut Self>,
        cx: &mut Context<'_>,
    ) -> Poll<Option<Result<http_body::Frame<Bytes>, axum::Error>>> {
        let polled = Pin::new(&mut self.body).poll_frame(cx);
        if let (Poll::Ready(Some(Ok(frame))), Some(line)) = (&polled, &mut self.line) {
            line.sent(frame.data_ref().map_or(0, Bytes::len));
        }
        polled
    }

    fn is_end_stream(&self) -> bool {
        self.body.is_end_stream()
    }

    fn size_hint(&self) -> http_body::SizeHint {
        self.body.size_hint()
    }
}

impl Inner {
    /// The answer to `req`: refused, or from the fast path, or from the router.
    async fn answer(this: Arc<Inner>, req: Request<Incoming>) -> Response {
        if let Err(e) = this.check_head(&req) {
            return this.refuse(&req, e);
        }
        // Percent-encoded segments need decoding, which the router's extractor does; raw tiles
        // for a client that accepts compression, the router's compression layer.
        let path = req.uri().path();
        let compressible = path.ends_with(".rgba") && accepts_compression(req.headers());
        let plain = req.method() == Method::GET && !path.contains('%') && !compressible;
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
            return resp;
        }
        match this.router.clone().oneshot(req.map(Body::new)).await {
            Ok(resp) => resp,
            Err(never) => match never {},
        }
    }

    /// What every request must satisfy before routing: a valid `Host`, a bounded query. The
    /// query's bound is looked up by route only for a query longer than the usual one.
    fn check_head(&self, req: &Request<Incoming>) -> Result<(), ApiError> {
        check_host(req.version(), req.headers())?;
        let query = req.uri().query();
        let long = query.is_some_and(|q| q.len() > MAX_QUERY_BYTES) && self.batch.at(req.uri().path()).is_ok();
        check_query(query, if long { MAX_BATCH_QUERY_BYTES } else { MAX_QUERY_BYTES })
    }

    /// The answer to a request [`Self::check_head`] refused: counted like any other.
    fn refuse(&self, req: &Request<Incoming>, e: ApiError) -> Response {
        let start = Instant::now();
        let mut resp = e.into_response();
        self.cors.apply(resp.headers_mut());
        count(&self.app, REFUSED, req.method(), start, &resp);
        resp
    }
}

/// RFC 9112 §3.2: an HTTP/1.1 request without `Host`, and an HTTP/1 request with more than one
/// or with one that is not `host[:port]`, are 400s. HTTP/2 carries `:authority` instead.
fn check_host(version: Version, headers: &HeaderMap) -> Result<(), ApiError> {
    if version != Version::HTTP_11 && version != Version::HTTP_10 {
        return Ok(());
    }
    let mut hosts = headers.get_all(header::HOST).iter();
    match (hosts.next(), hosts.next()) {
        (None, _) if version == Version::HTTP_11 => {
            Err(ApiError::bad_request("an HTTP/1.1 request needs a Host header (RFC 9112 §3.2)"))
        }
        (None, _) => Ok(()),
        (Some(_), Some(_)) => Err(ApiError::bad_request("more than one Host header (RFC 9112 §3.2)")),
        (Some(host), None) => {
            let valid = !host.as_bytes().contains(&b'@') && Authority::try_from(host.as_bytes()).is_ok();
            match valid {
                true => Ok(()),
                false => Err(ApiError::bad_request(format!(
                    "the Host header `{}` is not host[:port]",
                    echo(&String::from_utf8_lossy(host.as_bytes()))
                ))),
            }
        }
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
        assert!(!h.contains_key(header::VARY), "answers do not depend on the origin");
    }
}
