//! IIIF Presentation API 3: a Manifest per texture and a Collection of them all, so that a IIIF
//! viewer (Mirador, the Universal Viewer) opens a texture from a URL alone. Each Manifest has one
//! Canvas the texture's size, painted by one Image whose service is the texture's Image API 3
//! service ([`crate::api::interop::iiif`]), which viewers then tile.

use crate::api::error::ApiError;
use crate::api::extract::{NoQuery, Path, Query};
use crate::api::interop::iiif;
use crate::api::interop::jsonld;
use crate::api::openapi::text;
use crate::api::openapi::ErrorBody;
use crate::api::origin::Origin;
use crate::api::state::{App, TextureId};
use crate::store::Record;
use axum::extract::State;
use axum::http::HeaderMap;
use axum::response::Response;
use serde_json::{json, Value};

/// Where the documents live: `{PREFIX}/{id}/manifest.json` and `{PREFIX}/collection.json`.
pub const PREFIX: &str = "/iiif/presentation/3";

/// Longest side of the thumbnails the documents name.
const THUMBNAIL_SIDE: u32 = 256;

/// The absolute URL of `path` under [`PREFIX`], as the client reached this server.
fn url(origin: &Origin, path: &str) -> String {
    origin.url(&format!("{PREFIX}/{path}"))
}

/// A label in no particular language (Presentation 3 §4.4: the `none` key).
fn label(record: &Record) -> Value {
    json!({ "none": [record.name] })
}

/// A small image of the whole texture, from its image service.
fn thumbnail(service: &str) -> Value {
    json!([{
        "id": format!("{service}/full/!{THUMBNAIL_SIDE},{THUMBNAIL_SIDE}/0/default.png"),
        "type": "Image",
        "format": "image/png",
        "service": [image_service(service)],
    }])
}

fn image_service(service: &str) -> Value {
    json!({ "id": service, "type": "ImageService3", "profile": "level2" })
}

/// The Manifest of `record`: one Canvas the texture's size, one AnnotationPage with one
/// painting Annotation whose body is the whole texture as an Image with its image service.
fn manifest(origin: &Origin, record: &Record) -> Value {
    let (w, h) = (record.plan.width, record.plan.height);
    let id = url(origin, &format!("{}/manifest.json", record.id));
    let base = url(origin, &record.id);
    let canvas = format!("{base}/canvas/0");
    let service = iiif::service_url(origin, &record.id);
    json!({
        "@context": jsonld::PRESENTATION.uri,
        "id": id,
        "type": "Manifest",
        "label": label(record),
        "thumbnail": thumbnail(&service),
        "items": [{
            "id": canvas,
            "type": "Canvas",
            "label": label(record),
            "width": w,
            "height": h,
            "items": [{
                "id": format!("{base}/page/0"),
                "type": "AnnotationPage",
                "items": [{
                    "id": format!("{base}/annotation/0"),
                    "type": "Annotation",
                    "motivation": "painting",
                    "body": {
                        "id": format!("{service}/full/max/0/default.png"),
                        "type": "Image",
                        "format": "image/png",
                        "width": w,
                        "height": h,
                        "service": [image_service(&service)],
                    },
                    "target": canvas,
                }],
            }],
        }],
    })
}

/// `GET /iiif/presentation/3/{id}/manifest.json`
#[utoipa::path(get, operation_id = "iiif_manifest",
    path = "/iiif/presentation/3/{id}/manifest.json",
    tag = "interop",
    params(TextureId),
    responses(
        (status = 200, description = "IIIF Presentation API 3 Manifest of the texture: one Canvas painted by its \
            Image API 3 service. JSON-LD with the presentation context as its profile unless `Accept` prefers plain \
            JSON", content(("application/ld+json"), ("application/json"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 404, description = text::NOT_FOUND, body = ErrorBody),
        (status = 406, description = text::NOT_ACCEPTABLE, body = ErrorBody),
    ))]
pub async fn manifest_json(
    State(app): State<App>,
    Path(TextureId { id }): Path<TextureId>,
    _: Query<NoQuery>,
    headers: HeaderMap,
    origin: Origin,
) -> Result<Response, ApiError> {
    let record = crate::api::state::record(&app, &id).await?;
    jsonld::respond(&headers, &jsonld::PRESENTATION, &manifest(&origin, &record))
}

/// `GET /iiif/presentation/3/collection.json`
#[utoipa::path(get, operation_id = "iiif_collection",
    path = "/iiif/presentation/3/collection.json",
    tag = "interop",
    responses(
        (status = 200, description = "IIIF Presentation API 3 Collection of every texture's Manifest, by name. \
            JSON-LD with the presentation context as its profile unless `Accept` prefers plain \
            JSON", content(("application/ld+json"), ("application/json"))),
        (status = 400, description = text::BAD_REQUEST, body = ErrorBody),
        (status = 406, description = text::NOT_ACCEPTABLE, body = ErrorBody),
    ))]
pub async fn collection_json(
    State(app): State<App>,
    _: Query<NoQuery>,
    headers: HeaderMap,
    origin: Origin,
) -> Result<Response, ApiError> {
    let items: Vec<Value> = app
        .engine
        .store
        .list()
        .iter()
        .map(|r| {
            json!({
                "id": url(&origin, &format!("{}/manifest.json", r.id)),
                "type": "Manifest",
                "label": label(r),
                "thumbnail": thumbnail(&iiif::service_url(&origin, &r.id)),
            })
        })
        .collect();
    let body = json!({
        "@context": jsonld::PRESENTATION.uri,
        "id": url(&origin, "collection.json"),
        "type": "Collection",
        "label": { "none": ["vtex textures"] },
        "items": items,
    });
    jsonld::respond(&headers, &jsonld::PRESENTATION, &body)
}
