//! Texture resources: list, info, upload, merge-patch, encoding download.

use crate::api::error::{echo, ApiError};
use crate::api::extract::{NoQuery, Path, Query};
use crate::api::http::{
    declared_length, drain, json_validated, not_modified, not_modified_response, read_body, refuse_oversized,
    CACHE_IMMUTABLE,
};
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::state::{record, App, TextureId};
use crate::store::{StoreError, TextureInfo};
use axum::extract::{FromRequest, Multipart, Request, State};
use axum::http::{header, HeaderMap, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use axum::Json;
use serde_json::Value;
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, Inputs, Limits};

/// `GET /api/v1/textures`: every texture, sorted by name.
#[derive(serde::Serialize, utoipa::ToSchema)]
pub struct TextureList {
    pub textures: Vec<TextureInfo>,
}

/// Most multipart fields an upload may carry (model, name, params and input images).
const MAX_FIELDS: usize = 16;
/// Largest PATCH body: a merge patch of names and parameters.
const MAX_PATCH_BYTES: usize = 1 << 20;

#[utoipa::path(get,
    path = "/api/v1/textures",
    tag = "textures",
    responses(
        (status = 200, description = "every texture, by name (strong ETag, `no-cache`)", body = TextureList),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
    ))]
pub async fn list(State(app): State<App>, _: Query<NoQuery>, headers: HeaderMap) -> Response {
    let textures: Vec<TextureInfo> = app.engine.store.list().iter().map(|e| e.info()).collect();
    json_validated(&headers, &TextureList { textures })
}

#[utoipa::path(get,
    path = "/api/v1/textures/{id}",
    tag = "textures",
    params(TextureId),
    responses(
        (status = 200, description = "the texture's info (strong ETag, `no-cache`)", body = TextureInfo),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn info(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    _: Query<NoQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    Ok(json_validated(&headers, &record(&app, &id).await?.info()))
}

/// The bundle bytes exactly as stored, read whole once their length is reserved from the
/// in-flight budget. The id is the content hash: a perfect strong ETag.
#[utoipa::path(get,
    path = "/api/v1/textures/{id}/encoding",
    tag = "textures",
    params(TextureId),
    responses(
        (status = 200, description = "the bundle bytes exactly as stored (ETag: the \
            id)", content(("application/octet-stream"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn encoding(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    _: Query<NoQuery>,
    headers: HeaderMap,
) -> Result<Response, ApiError> {
    let entry = record(&app, &id).await?;
    let tag = HeaderValue::from_str(&format!("\"{}\"", entry.id)).expect("hex id");
    if not_modified(&headers, tag.to_str().unwrap_or_default()) {
        return Ok(not_modified_response(tag));
    }
    let reservation = app.inflight.reserve(entry.encoding_bytes)?;
    let bytes = reservation.hold(stored_bytes(&app, &entry.id).await?);
    let disposition = format!("attachment; filename=\"{}.vtex\"", entry.id);
    Ok((
        [
            (header::CONTENT_TYPE, HeaderValue::from_static("application/octet-stream")),
            (header::ETAG, tag),
            (header::CACHE_CONTROL, CACHE_IMMUTABLE),
            (header::CONTENT_DISPOSITION, HeaderValue::from_str(&disposition).expect("ascii")),
        ],
        bytes,
    )
        .into_response())
}

/// The bytes of stored bundle `id`, read off the runtime.
async fn stored_bytes(app: &App, id: &str) -> Result<Vec<u8>, ApiError> {
    let (store, id) = (app.engine.store.clone(), id.to_string());
    tokio::task::spawn_blocking(move || store.bytes_of(&id))
        .await
        .map_err(|e| ApiError::internal("reading the stored bundle failed", e))?
        .map_err(|e| ApiError::from(crate::engine::store_failure(e)))
}

/// Where bundle bytes come from: uploaded as they are (verified by their model once, here), or
/// made by this server's model `create` (a multipart upload, a PATCH).
#[derive(Clone, Copy)]
enum Origin {
    Uploaded,
    Made,
}

/// Validates and stores bundle bytes off the runtime: 201 when new, 200 when already stored.
/// Over the server's bounds is 422; past a cap of the store or on a full disk, 507.
async fn store_bundle(app: &App, bytes: Vec<u8>, origin: Origin) -> Result<(StatusCode, Json<TextureInfo>), ApiError> {
    let store = app.engine.store.clone();
    let put = move || match origin {
        Origin::Uploaded => store.put(bytes),
        Origin::Made => store.put_made(bytes),
    };
    let (entry, created) = tokio::task::spawn_blocking(put)
        .await
        .map_err(|e| ApiError::internal("validating the bundle failed inside the model", e))?
        .map_err(|e| match e {
            StoreError::Invalid(e) => ApiError::from(e),
            StoreError::Full(why) => ApiError::InsufficientStorage(why),
            StoreError::Unavailable(_) => ApiError::Unavailable(crate::engine::STORE_UNAVAILABLE.into()),
            StoreError::Io(e) => ApiError::internal("storing the bundle failed", e),
        })?;
    if created {
        tracing::info!(id = %entry.id, name = %entry.name, model = %entry.model, "texture stored");
    }
    Ok((if created { StatusCode::CREATED } else { StatusCode::OK }, Json(entry.info())))
}

/// `POST /api/v1/textures`: a raw bundle, or multipart `model`, `name`, `params` + input images.
#[utoipa::path(post,
    path = "/api/v1/textures",
    tag = "textures",
    request_body(description = "a bundle (`application/octet-stream`), or multipart fields `model`, `name`, `params` \
        (JSON text) and one per input image (see `GET \
        /api/v1/models`)", content(("application/octet-stream"), ("multipart/form-data"))),
    responses(
        (status = 201, description = "stored", body = TextureInfo),
        (status = 200, description = "the identical bundle was already stored", body = TextureInfo),
        (status = 400, description = "invalid bundle, model, parameters or input image, named", body = ErrorBody),
        (status = 413, description = "body over `--max-upload-mb`", body = ErrorBody),
        (status = 415, description = "neither a bundle nor multipart", body = ErrorBody),
        (status = 422, description = text::OVER_BOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
        (status = 507, description = "the store is full", body = ErrorBody),
    ))]
pub async fn upload(
    State(app): State<App>,
    _: Query<NoQuery>,
    req: Request,
) -> Result<(StatusCode, Json<TextureInfo>), ApiError> {
    let content_type = req
        .headers()
        .get(header::CONTENT_TYPE)
        .and_then(|v| v.to_str().ok())
        .unwrap_or("application/octet-stream")
        .to_ascii_lowercase();
    let multipart = match content_type.as_str() {
        t if t.starts_with("multipart/form-data") => true,
        t if t.starts_with("application/octet-stream") => false,
        _ => {
            return Err(ApiError::UnsupportedMediaType(format!(
                "content type `{}`; expected application/octet-stream (a bundle) or multipart/form-data",
                echo(&content_type)
            )))
        }
    };
    let limit = app.cfg.max_upload_bytes();
    let declared = declared_length(req.headers());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(refuse_oversized(req, limit).await);
    }
    // What reading the body holds, reserved before a byte of it is read and kept until the
    // texture is stored (a body of unknown length may reach the limit).
    let _body = match app.inflight.reserve(declared.unwrap_or(limit as u64)) {
        Ok(reservation) => reservation,
        Err(spent) => {
            drain(req).await;
            return Err(spent);
        }
    };
    let (bytes, origin) = if multipart {
        (bundle_from_multipart(req, limit, app.engine.store.bounds().limits).await?, Origin::Made)
    } else {
        (read_body(req, limit).await?.into(), Origin::Uploaded)
    };
    store_bundle(&app, bytes, origin).await
}

/// The bundle a multipart upload describes, created only when its plan is within `bounds`.
async fn bundle_from_multipart(req: Request, limit: usize, bounds: Limits) -> Result<Vec<u8>, ApiError> {
    let multipart_error = |status: StatusCode, text: String| {
        if status == StatusCode::PAYLOAD_TOO_LARGE {
            ApiError::PayloadTooLarge(format!("request body larger than the limit of {limit} bytes"))
        } else {
            ApiError::bad_request(format!("malformed multipart body: {text}"))
        }
    };
    let mut form = Multipart::from_request(req, &()).await.map_err(|e| multipart_error(e.status(), e.body_text()))?;
    let (mut model, mut name, mut params) = (None, None, None);
    let mut inputs = Inputs::new();
    let mut fields = 0;
    while let Some(field) = form.next_field().await.map_err(|e| multipart_error(e.status(), e.body_text()))? {
        fields += 1;
        if fields > MAX_FIELDS {
            return Err(ApiError::bad_request(format!("more than {MAX_FIELDS} multipart fields")));
        }
        let field_name = field.name().unwrap_or_default().to_string();
        let data = field.bytes().await.map_err(|e| multipart_error(e.status(), e.body_text()))?;
        let text = || {
            String::from_utf8(data.to_vec())
                .map_err(|_| ApiError::bad_request(format!("multipart field `{field_name}` is not UTF-8 text")))
        };
        match field_name.as_str() {
            "model" => model = Some(text()?),
            "name" => name = Some(text()?),
            "params" => {
                let v: Value = serde_json::from_slice(&data)
                    .map_err(|e| ApiError::bad_request(format!("multipart field `params` is not JSON: {e}")))?;
                params = Some(v)
            }
            "" => return Err(ApiError::bad_request("a multipart field has no name")),
            _ => {
                inputs.insert(field_name.clone(), data.to_vec());
            }
        }
    }
    let model = model.ok_or_else(|| ApiError::bad_request("missing multipart field `model`"))?;
    let name = name.unwrap_or_else(|| model.clone());
    let params = params.unwrap_or_else(|| serde_json::json!({}));
    let bundle = tokio::task::spawn_blocking(move || models::create_within(&model, &name, &params, &inputs, &bounds))
        .await
        .map_err(|e| ApiError::internal("creating the encoding failed inside the model", e))??;
    Ok(bundle.to_bytes())
}

/// `PATCH /api/v1/textures/{id}`: merge-patch `name` and `params` of the manifest (the params
/// as given, not those the model derived); the texture is made again by its model from the
/// patched params — exactly what creating it from them makes — or refused naming the field it
/// cannot remake; the result is stored as a new texture (bundles are immutable).
#[utoipa::path(patch,
    path = "/api/v1/textures/{id}",
    tag = "textures",
    params(TextureId),
    request_body(description = "JSON merge patch (RFC 7396) of `name` and `params` (the params as given; `derived` \
        is made again from them)", content(("application/json"))),
    responses(
        (status = 201, description = "the new texture: what creating it from the patched name and params with the \
            same input images makes", body = TextureInfo),
        (status = 400, description = "not a patch of `name` and `params`, or params its model cannot remake, \
            named", body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 422, description = text::OVER_BOUND, body = ErrorBody),
        (status = 503, description = text::UNAVAILABLE, body = ErrorBody),
    ))]
pub async fn patch(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    _: Query<NoQuery>,
    req: Request,
) -> Result<(StatusCode, Json<TextureInfo>), ApiError> {
    let entry = record(&app, &id).await?;
    let body = read_body(req, MAX_PATCH_BYTES).await?;
    let patch: Value =
        serde_json::from_slice(&body).map_err(|e| ApiError::bad_request(format!("patch is not JSON: {e}")))?;
    let Value::Object(fields) = &patch else {
        return Err(ApiError::bad_request("patch must be a JSON object with `name` and/or `params`"));
    };
    if let Some(k) = fields.keys().find(|k| *k != "name" && *k != "params") {
        return Err(ApiError::bad_request(format!("`{}` cannot be patched; only `name` and `params`", echo(k))));
    }
    let old = Bundle::from_bytes(&stored_bytes(&app, &entry.id).await?)?;
    let mut doc = serde_json::json!({ "name": old.manifest.name, "params": old.manifest.params });
    models::merge_patch(&mut doc, &patch);
    let name = match doc.get("name") {
        Some(Value::String(s)) => s.clone(),
        _ => return Err(ApiError::bad_request("`name` must remain a string")),
    };
    let params = doc.get("params").cloned().unwrap_or(Value::Null);
    let limits = app.engine.store.bounds().limits;
    let new = tokio::task::spawn_blocking(move || models::remake_within(&old, &name, &params, &limits))
        .await
        .map_err(|e| ApiError::internal("remaking the encoding failed inside the model", e))??;
    store_bundle(&app, new.to_bytes(), Origin::Made).await
}
