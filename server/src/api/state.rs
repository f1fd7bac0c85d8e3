//! What a handler is given: the service's state ([`AppState`], shared as [`App`]), the path
//! of one texture's routes, and the texture it names.

use crate::api::error::ApiError;
use crate::api::inflight::Inflight;
use crate::api::origin::{self, Origin};
use crate::api::write_policy::WritePolicy;
use crate::config::ServeConfig;
use crate::engine::Engine;
use crate::metrics::Metrics;
use crate::store::{Entry, Record, Store};
use axum::extract::FromRequestParts;
use axum::http::request::Parts;
use serde::Deserialize;
use std::convert::Infallible;
use std::sync::atomic::AtomicBool;
use std::sync::Arc;

/// Everything a request handler needs: the engine, and what only HTTP has.
pub struct AppState {
    pub engine: Arc<Engine>,
    pub metrics: Arc<Metrics>,
    /// The budget of bodies in flight (`--inflight-mb`).
    pub inflight: Inflight,
    /// Set when shutdown begins: no longer ready (`/readyz`).
    pub draining: AtomicBool,
    /// Who may write (`VTEX_WRITE_TOKEN`, `--read-only`, `--cors-write-origins`).
    pub writes: WritePolicy,
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
        let (draining, writes) = (AtomicBool::new(false), WritePolicy::new(&cfg));
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

/// Texture `id`'s record, without loading it ([`Engine::record`]).
pub async fn record(app: &AppState, id: &str) -> Result<Arc<Record>, ApiError> {
    Ok(app.engine.record(id).await?)
}

/// Texture `id`, loaded ([`Engine::lookup`]).
pub async fn lookup(app: &AppState, id: &str) -> Result<Arc<Entry>, ApiError> {
    Ok(app.engine.lookup(id).await?)
}

impl FromRequestParts<App> for Origin {
    type Rejection = Infallible;

    async fn from_request_parts(parts: &mut Parts, app: &App) -> Result<Origin, Infallible> {
        Ok(origin::origin(&app.cfg, parts))
    }
}
