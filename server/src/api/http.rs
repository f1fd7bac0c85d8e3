//! What every route's answer is made with: the cache and validator headers, conditional
//! requests (`If-None-Match` → 304), bodies read within a limit or drained before a refusal,
//! and the answer to a request past its deadline.

use crate::api::error::ApiError;
use crate::engine::ETag;
use axum::extract::Request;
use axum::http::{header, HeaderMap, HeaderName, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};
use http_body_util::BodyExt;

pub const CACHE_IMMUTABLE: HeaderValue = HeaderValue::from_static("public, max-age=31536000, immutable");
pub static X_VTEX_CACHE: HeaderName = HeaderName::from_static("x-vtex-cache");
pub static X_VTEX_WIDTH: HeaderName = HeaderName::from_static("x-vtex-width");
pub static X_VTEX_HEIGHT: HeaderName = HeaderName::from_static("x-vtex-height");

/// Whether `Accept-Encoding` names an encoding [`compression_layer`] might apply.
pub fn accepts_compression(headers: &HeaderMap) -> bool {
    headers.get_all(header::ACCEPT_ENCODING).iter().any(|v| {
        v.to_str().is_ok_and(|v| {
            v.split(',').any(|e| matches!(e.split(';').next().unwrap_or("").trim(), "gzip" | "br" | "zstd" | "*"))
        })
    })
}

/// The answer to a request not done within the deadline `limit`.
pub(crate) fn timed_out(limit: std::time::Duration) -> ApiError {
    ApiError::Timeout(format!("request not completed within {} s (slow client or overload)", limit.as_secs_f64()))
}

/// True when `If-None-Match` names `etag` (weak comparison, as RFC 9110 requires) or is `*`.
pub fn not_modified(headers: &HeaderMap, etag: &str) -> bool {
    let bare = |t: &str| t.trim().trim_start_matches("W/").to_string();
    headers
        .get_all(header::IF_NONE_MATCH)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .any(|v| v.trim() == "*" || v.split(',').any(|t| bare(t) == bare(etag)))
}

/// A 304 carrying the validators a 200 would have carried.
pub fn not_modified_response(etag: HeaderValue) -> Response {
    let mut resp = StatusCode::NOT_MODIFIED.into_response();
    resp.headers_mut().insert(header::ETAG, etag);
    resp.headers_mut().insert(header::CACHE_CONTROL, CACHE_IMMUTABLE);
    resp
}

/// How much more of an oversized body is read and thrown away, and for how long (in all, and
/// waiting for each piece), so that a client still sending it receives the 413 rather than a
/// reset connection; past any bound the connection is cut.
const DRAIN_BYTES: usize = 16 << 20;
const DRAIN_TIME: std::time::Duration = std::time::Duration::from_secs(5);
const DRAIN_IDLE: std::time::Duration = std::time::Duration::from_millis(500);

/// Reads a request body of at most `limit` bytes; larger is 413 naming the limit.
pub async fn read_body(req: Request, limit: usize) -> Result<bytes::Bytes, ApiError> {
    let declared = declared_length(req.headers());
    if declared.is_some_and(|n| n > limit as u64) {
        return Err(refuse_oversized(req, limit).await);
    }
    let (parts, mut body) = req.into_parts();
    // Sized once when the length is known, so the buffer holds the body and no more.
    let mut bytes = bytes::BytesMut::with_capacity(declared.map_or(0, |n| n as usize));
    while let Some(frame) = body.frame().await {
        let frame = frame.map_err(|e| ApiError::bad_request(format!("could not read the request body: {e}")))?;
        if let Some(data) = frame.data_ref() {
            if bytes.len() + data.len() > limit {
                return Err(refuse_oversized(Request::from_parts(parts, body), limit).await);
            }
            bytes.extend_from_slice(data);
        }
    }
    Ok(bytes.freeze())
}

/// The request's `Content-Length`, when it has a valid one.
pub fn declared_length(headers: &HeaderMap) -> Option<u64> {
    headers.get(header::CONTENT_LENGTH).and_then(|v| v.to_str().ok()?.parse::<u64>().ok())
}

/// The 413 for a body over `limit`, given after [`drain`]ing the rest of the body.
pub async fn refuse_oversized(req: Request, limit: usize) -> ApiError {
    drain(req).await;
    ApiError::PayloadTooLarge(format!("request body larger than the limit of {limit} bytes"))
}

/// Reads and throws away the body of a request about to be refused, within [`DRAIN_BYTES`]
/// and [`DRAIN_TIME`] — unless the client waits for `100 Continue` before sending it, or
/// sends nothing for [`DRAIN_IDLE`] — so that a client (or a proxy) still sending it receives
/// the refusal rather than a reset connection.
pub async fn drain(req: Request) {
    let waits_to_send =
        req.headers().get(header::EXPECT).is_some_and(|v| v.as_bytes().eq_ignore_ascii_case(b"100-continue"));
    let mut body = req.into_body();
    let drain = async {
        let mut left = DRAIN_BYTES;
        while let Ok(Some(Ok(frame))) = tokio::time::timeout(DRAIN_IDLE, body.frame()).await {
            match frame.data_ref() {
                Some(data) if data.len() >= left => return,
                Some(data) => left -= data.len(),
                None => {}
            }
        }
    };
    if !waits_to_send {
        let _ = tokio::time::timeout(DRAIN_TIME, drain).await;
    }
}

/// An ETag as a header value (its bytes shared, not copied).
pub fn etag_header(tag: &ETag) -> HeaderValue {
    HeaderValue::from_maybe_shared(tag.bytes()).expect("quotes and hex digits are a valid header value")
}

/// `value` as JSON with a strong ETag (a hash of the body), revalidated on every use
/// (`no-cache`): a 304 when `If-None-Match` names it. The list changes with the store, so it is
/// never cached unchecked.
pub fn json_validated(headers: &HeaderMap, value: &impl serde::Serialize) -> Response {
    let body = serde_json::to_vec(value).expect("plain data serializes");
    validated(headers, "application/json", body.into())
}

/// `body` of `content_type` with a strong ETag (a hash of the body), revalidated on every use
/// (`no-cache`): a 304 when `If-None-Match` names it.
pub fn validated(headers: &HeaderMap, content_type: &'static str, body: bytes::Bytes) -> Response {
    let tag = format!("\"{}\"", &blake3::hash(&body).to_hex()[..32]);
    let tag = HeaderValue::from_str(&tag).expect("hex is a valid header value");
    let no_cache = HeaderValue::from_static("no-cache");
    if not_modified(headers, tag.to_str().unwrap_or_default()) {
        return (StatusCode::NOT_MODIFIED, [(header::ETAG, tag), (header::CACHE_CONTROL, no_cache)]).into_response();
    }
    let content_type = HeaderValue::from_static(content_type);
    ([(header::CONTENT_TYPE, content_type), (header::ETAG, tag), (header::CACHE_CONTROL, no_cache)], body)
        .into_response()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn if_none_match_forms() {
        let mut h = HeaderMap::new();
        h.insert(header::IF_NONE_MATCH, HeaderValue::from_static("\"a\", W/\"b\""));
        assert!(not_modified(&h, "\"a\""));
        assert!(not_modified(&h, "\"b\""));
        assert!(!not_modified(&h, "\"c\""));
        h.insert(header::IF_NONE_MATCH, HeaderValue::from_static("*"));
        assert!(not_modified(&h, "\"c\""));
        assert!(!not_modified(&HeaderMap::new(), "\"a\""));
    }
}
