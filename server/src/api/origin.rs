//! The URL of this server as the client reached it, for documents that must hold absolute
//! URLs (IIIF `info.json` ids, TileJSON tile templates).

use axum::http::{header, HeaderMap, Uri};

/// `scheme://host[:port]` of the request: its `Host` (HTTP/1.1) or authority (HTTP/2), and
/// `https` when a proxy in front says so (`X-Forwarded-Proto`).
pub fn origin(headers: &HeaderMap, uri: &Uri) -> String {
    let host = headers
        .get(header::HOST)
        .and_then(|h| h.to_str().ok())
        .map(str::to_string)
        .or_else(|| uri.authority().map(|a| a.to_string()))
        .unwrap_or_else(|| "localhost".into());
    let https = headers.get("x-forwarded-proto").is_some_and(|p| p.as_bytes().eq_ignore_ascii_case(b"https"));
    format!("{}://{host}", if https { "https" } else { "http" })
}
