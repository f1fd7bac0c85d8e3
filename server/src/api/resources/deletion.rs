//! `DELETE /api/v1/textures/{id}`: removes a texture's bundle from the store.

use crate::api::error::ApiError;
use crate::api::extract::{NoQuery, Path, Query};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::state::{App, TextureId};
use crate::store::StoreError;
use axum::extract::State;
use axum::http::StatusCode;

/// 204 once the bundle is gone from the store (durably) and from this server's index; other
/// servers sharing the store stop serving it when their watch or poll sees it go, or on their
/// next miss. Requests in flight finish with the texture they hold. Tiles cached by
/// proxies in front are not recalled: tile URLs are immutable.
#[utoipa::path(delete,
    path = "/api/v1/textures/{id}",
    tag = "textures",
    params(TextureId),
    responses(
        (status = 204, description = "deleted"),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn delete(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    _: Query<NoQuery>,
) -> Result<StatusCode, ApiError> {
    crate::engine::check_id(&id)?;
    let store = app.engine.store.clone();
    let target = id.clone();
    let removed = tokio::task::spawn_blocking(move || store.remove(&target))
        .await
        .map_err(|e| ApiError::internal("deleting the bundle failed", e))?
        .map_err(|e| match e {
            StoreError::Unavailable(_) => ApiError::Unavailable(crate::engine::STORE_UNAVAILABLE.into()),
            e => ApiError::internal("deleting the bundle failed", e),
        })?;
    if !removed {
        return Err(ApiError::not_found(format!("no texture with id {id}")));
    }
    tracing::info!(%id, "texture deleted");
    Ok(StatusCode::NO_CONTENT)
}
