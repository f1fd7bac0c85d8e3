//! The fast path of a single tile: plain GETs of the tile route answered without the router.
//!
//! Why: a warm tile is a cache lookup, and the router's per-request machinery (the route's
//! boxed services, its layers, the request extensions) costs more than the rest of such a
//! request. The fast path matches the path against the router's own template
//! ([`TILE`]) with the router's matcher (`matchit`), fills the same extractor types,
//! runs the same answer ([`tiles::answer`]: the engine's lookup, addressing and cache) and
//! gives it the same CORS headers, metrics label and deadline. Anything else (HEAD, other
//! methods, percent-encoded paths, other routes) takes the router, so answers are the same
//! either way (tests compare both).

use super::cors::CorsHeaders;
use crate::api::extract::{path_params, query_params};
use crate::api::resources::tiles;
use crate::api::state::App;
use crate::api::{self};
use axum::http::{Method, Request};
use axum::response::{IntoResponse, Response};
use hyper::body::Incoming;
use std::time::Instant;
use vtex_wire::urls::TILE;

pub(super) struct FastTile {
    app: App,
    /// [`TILE`] alone, in the matcher the router uses.
    tile: matchit::Router<()>,
}

impl FastTile {
    pub(super) fn new(app: App) -> FastTile {
        FastTile { app, tile: super::head::matcher(TILE) }
    }

    /// The answer to `req` when it is a plain GET of a single tile, with the headers of `cors`;
    /// `None` for the router to answer.
    pub(super) async fn answer(&self, req: &Request<Incoming>, cors: &CorsHeaders) -> Option<Response> {
        // Percent-encoded segments need decoding, which the router's extractor does; raw tiles
        // for a client that accepts compression, the router's compression layer.
        let path = req.uri().path();
        let compressible = path.ends_with(".rgba") && api::http::accepts_compression(req.headers());
        let plain = req.method() == Method::GET && !path.contains('%') && !compressible;
        let m = plain.then(|| self.tile.at(path).ok()).flatten()?;
        let start = Instant::now();
        let limit = self.app.cfg.request_timeout();
        let work = async {
            let (path, query) = (path_params(m.params.iter())?, query_params(req.uri().query())?);
            tiles::answer(&self.app, path, query, req.headers()).await
        };
        let mut resp = match tokio::time::timeout(limit, work).await {
            Ok(answer) => answer.into_response(),
            Err(_) => api::http::timed_out(limit).into_response(),
        };
        cors.apply(resp.headers_mut());
        api::count(&self.app, TILE, &Method::GET, start, &resp);
        Some(resp)
    }
}
