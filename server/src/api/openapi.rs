//! The OpenAPI 3.1 description of the whole API, `GET /api/v1/openapi.json`, collected by the
//! route table (`super::routes`) from the handlers' `#[utoipa::path]` annotations and the
//! response types' schemas, so every described route is served and the reverse;
//! `server/tests/api/openapi.rs` validates it and requests every described path.

use super::extract::{NoQuery, Query};
use super::http::json_validated;
use super::origin::Origin;
use axum::http::HeaderMap;
use axum::response::Response;
use axum::Extension;
use serde::Serialize;
use std::sync::Arc;
use utoipa::openapi::{OpenApi as Document, Server};
use utoipa::{OpenApi, ToSchema};

/// Descriptions many operations share, written once.
pub mod text {
    pub const TEXTURE_ID: &str = "texture id: 64 lowercase hex characters, the BLAKE3 of its bundle";
    pub const ID_AND_FRAME: &str = "a texture id, optionally `;frame`";
    pub const BAD_REQUEST: &str = "a malformed path or query, named in the message";
    pub const NOT_FOUND: &str = "no such texture, or a tile outside its level";
    pub const NOT_ACCEPTABLE: &str =
        "`Accept` allows neither JSON-LD (with the document's context as `profile`) nor JSON";
    pub const OVER_BOUND: &str = "over a cost bound of the server";
    pub const UNAVAILABLE: &str =
        "synthesis queue full, in-flight budget spent, object store unreachable or shutting down (`Retry-After`)";
}

/// Every error's body.
#[derive(Serialize, ToSchema)]
pub struct ErrorBody {
    /// What is wrong, naming the parameter, limit or resource.
    pub error: String,
}

#[derive(OpenApi)]
#[openapi(
    info(
        title = "vtex",
        description = "Virtual textures: compact encodings stored, any tile of any mip level synthesized on \
                       demand, identical every time. Errors are JSON `{\"error\": …}` with a 4xx status for \
                       anything the client got wrong."
    ),
    components(schemas(ErrorBody)),
    tags(
        (name = "textures", description = "Texture resources: list, info, upload, edit, delete, encoding"),
        (name = "tiles", description = "Tiles, tile batches and regions of any level"),
        (name = "pages", description = "Virtual-texturing pages with borders, KTX2 mip chains"),
        (name = "interop", description = "Deep Zoom, IIIF Image API 3 and Presentation 3, TileJSON and XYZ over the \
            same tiles"),
        (name = "models", description = "The texture models: parameter schemas and examples"),
        (name = "operations", description = "Liveness, readiness, metrics and this description"),
    )
)]
struct ApiDoc;

/// What the description says beyond its operations: title, tags, shared schemas.
pub(super) fn base() -> Document {
    let mut doc = ApiDoc::openapi();
    doc.info.version = env!("CARGO_PKG_VERSION").into();
    doc
}

/// `GET /api/v1/openapi.json`, its `servers` the one URL this server is reached at.
#[utoipa::path(get, path = "/api/v1/openapi.json", tag = "operations",
    responses(
        (status = 200, description = "This OpenAPI 3.1 document (strong ETag, \
            `no-cache`)", content_type = "application/json"),
    ))]
pub async fn openapi_json(
    _: Query<NoQuery>,
    Extension(document): Extension<Arc<Document>>,
    origin: Origin,
    headers: HeaderMap,
) -> Response {
    let mut doc = Document::clone(&document);
    doc.servers = Some(vec![Server::new(origin.to_string())]);
    json_validated(&headers, &doc)
}
