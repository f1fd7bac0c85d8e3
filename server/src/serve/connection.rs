//! The service hyper calls for every request of a connection: the request's head is checked
//! first ([`head`](super::head)), where it costs least, then a plain GET of a single tile takes
//! the fast path ([`fast_tile`](super::fast_tile)) and anything else the router
//! ([`api::router`]). Each connection has its own [`Connection`] service, which counts its
//! requests in flight for the idle timeout, and writes each request's access line once its
//! body is sent ([`access`](super::access)), whichever path answered it.

use super::access::AccessLine;
use super::cors::CorsHeaders;
use super::fast_tile::FastTile;
use super::head::Head;
use crate::api::error::ApiError;
use crate::api::state::App;
use crate::api::{self};
use crate::transport::{Activity, InFlight};
use axum::body::Body;
use axum::extract::ConnectInfo;
use axum::http::Request;
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

/// The `route` label of requests refused before routing (a bad `Host`, an oversized query).
const REFUSED: &str = "refused";

/// Cloned per connection and per request (one reference count); the state is shared.
#[derive(Clone)]
pub struct Front(Arc<Inner>);

struct Inner {
    app: App,
    router: Router,
    head: Head,
    fast: FastTile,
    cors: CorsHeaders,
}

impl Front {
    pub fn new(app: App) -> Front {
        let cors = CorsHeaders::from_layer(api::cors_layer());
        let (head, fast) = (Head::new(), FastTile::new(app.clone()));
        Front(Arc::new(Inner { router: api::router(app.clone()), app, head, fast, cors }))
    }

    /// The service of one connection from `peer`, counting its requests in flight in
    /// `activity`; every request of it carries `peer` as the extension [`ConnectInfo`] (who
    /// may write, which proxies are trusted).
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
        if let Err(e) = this.head.check(&req) {
            return this.refuse(&req, e);
        }
        if let Some(resp) = this.fast.answer(&req, &this.cors).await {
            return resp;
        }
        match this.router.clone().oneshot(req.map(Body::new)).await {
            Ok(resp) => resp,
            Err(never) => match never {},
        }
    }

    /// The answer to a request [`Head::check`] refused: counted like any other.
    fn refuse(&self, req: &Request<Incoming>, e: ApiError) -> Response {
        let start = Instant::now();
        let mut resp = e.into_response();
        self.cors.apply(resp.headers_mut());
        api::count(&self.app, REFUSED, req.method(), start, &resp);
        resp
    }
}
