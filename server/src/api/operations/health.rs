//! Liveness (`/healthz`: the process answers) and readiness (`/readyz`: it should be sent
//! traffic). The store is opened before the server listens, so a server that answers has its
//! store loaded; it is not ready while its data directory cannot be read (a shared volume gone)
//! or once it drains for shutdown, so a balancer sends new requests elsewhere. An object store
//! that stops answering leaves it ready (see [`crate::store::Bundles::reachable`]).

use crate::api::extract::{NoQuery, Query};
use crate::api::state::App;
use axum::extract::State;
use axum::http::{header, StatusCode};
use axum::response::{IntoResponse, Response};
use std::sync::atomic::Ordering;

#[utoipa::path(get,
    path = "/healthz",
    tag = "operations",
    responses(
        (status = 200, description = "`{\"status\":\"ok\"}`: the process answers", content(("application/json"))),
    ))]
pub async fn healthz(_: Query<NoQuery>) -> Response {
    ([(header::CONTENT_TYPE, "application/json")], r#"{"status":"ok"}"#).into_response()
}

#[utoipa::path(get,
    path = "/readyz",
    tag = "operations",
    responses(
        (status = 200, description = "`{\"status\":\"ready\",\"textures\":N}`", content(("application/json"))),
        (status = 503, description = "not ready: the data directory cannot be read, or shutting \
            down", content(("application/json"))),
    ))]
pub async fn readyz(State(app): State<App>, _: Query<NoQuery>) -> Response {
    let not_ready = |why: &str| {
        let body = serde_json::json!({ "status": "not ready", "error": why }).to_string();
        (StatusCode::SERVICE_UNAVAILABLE, [(header::CONTENT_TYPE, "application/json")], body).into_response()
    };
    if app.draining.load(Ordering::Relaxed) {
        return not_ready("the server is shutting down");
    }
    let store = app.engine.store.clone();
    let reachable = tokio::task::spawn_blocking(move || store.bundles().reachable()).await.unwrap_or(false);
    if !reachable {
        return not_ready("the data directory cannot be read");
    }
    let body = serde_json::json!({ "status": "ready", "textures": app.engine.store.len() }).to_string();
    ([(header::CONTENT_TYPE, "application/json")], body).into_response()
}
