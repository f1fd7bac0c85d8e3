//! The CORS headers of reads as static values, for the answers that do not pass the router's
//! CORS layer (the fast tile path, refusals before routing).

use axum::body::Body;
use axum::http::{header, HeaderMap, HeaderValue, Request};
use axum::response::Response;
use std::convert::Infallible;
use std::future::Future;
use tower::ServiceExt;
use tower_http::cors::CorsLayer;

/// The headers a [`CorsLayer`] puts on a response to a request that is not a preflight
/// (OPTIONS): they do not depend on the request, so they are taken from the layer once, as
/// static values (cloning one then touches no shared reference count).
pub(super) struct CorsHeaders(Vec<(header::HeaderName, HeaderValue)>);

impl CorsHeaders {
    pub(super) fn from_layer(layer: CorsLayer) -> CorsHeaders {
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
    pub(super) fn apply(&self, h: &mut HeaderMap) {
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
        let cors = CorsHeaders::from_layer(crate::api::cors_layer());
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
