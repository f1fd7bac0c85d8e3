//! The model catalogue over HTTP (`GET /api/v1/models[/{id}]`, the example's input images):
//! [`crate::catalogue`] with absolute URLs.

use crate::api::error::{echo, ApiError};
use crate::api::extract::{NoQuery, Path, Query};
use crate::api::http::{json_validated, validated};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::origin::Origin;
use crate::catalogue::{example_input, list, one, ModelDoc, ModelList, EXAMPLE_INPUT};
use axum::http::HeaderMap;
use axum::response::Response;
use serde::Deserialize;

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ModelId {
    id: String,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
pub struct ExampleFile {
    id: String,
    file: String,
}

/// `GET /api/v1/models`
#[utoipa::path(get,
    path = "/api/v1/models",
    tag = "models",
    responses(
        (status = 200, description = "every model (strong ETag, `no-cache`)", body = ModelList),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
    ))]
pub async fn list_models(_: Query<NoQuery>, origin: Origin, headers: HeaderMap) -> Response {
    let mut list = list();
    list.models.iter_mut().for_each(|doc| absolute(doc, &origin));
    json_validated(&headers, &list)
}

/// `doc` with the URLs of its example's images made absolute.
fn absolute(doc: &mut ModelDoc, origin: &Origin) {
    for input in doc.example.inputs.values_mut() {
        input.href = origin.url(&input.href);
    }
}

/// `GET /api/v1/models/{id}`
#[utoipa::path(get,
    path = "/api/v1/models/{id}",
    tag = "models",
    params(("id" = String, Path, description = "model id, e.g. `chaos-mosaic`")),
    responses(
        (status = 200, description = "the model", body = ModelDoc),
        (status = 404, description = "no such model; the message names the models", body = ErrorBody),
    ))]
pub async fn model(
    Path(ModelId { id }): Path<ModelId>,
    _: Query<NoQuery>,
    origin: Origin,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let mut doc = one(&id)?;
    absolute(&mut doc, &origin);
    Ok(json_validated(&headers, &doc))
}

/// `GET /api/v1/models/{id}/example/{input}.png`: revalidated like the JSON (another build may
/// draw another example).
#[utoipa::path(get,
    path = EXAMPLE_INPUT,
    tag = "models",
    params(
        ("id" = String, Path, description = "model id"),
        ("file" = String, Path, description = "`{input}.png`, an input of the model's example"),
    ),
    responses(
        (status = 200, description = "the example's input image", content(("image/png"))),
        (status = 404, description = "no such model or example input", body = ErrorBody),
    ))]
pub async fn example_image(
    Path(ExampleFile { id, file }): Path<ExampleFile>,
    _: Query<NoQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let name = file
        .strip_suffix(".png")
        .ok_or_else(|| ApiError::not_found(format!("`{}`: example inputs are `<input>.png`", echo(&file))))?;
    Ok(validated(&headers, "image/png", bytes::Bytes::from_static(example_input(&id, name)?)))
}
