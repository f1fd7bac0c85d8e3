//! Who may write: the write token (`VTEX_WRITE_TOKEN`, a bearer token), read-only mode
//! (`--read-only`) and the origins whose pages may write (`--cors-write-origins`), enforced by
//! [`WritePolicy::screen`] in front of every route, before CORS answers anything.
//!
//! A write is any method but GET, HEAD and OPTIONS. Reads stay open to every origin. With no
//! token set, only loopback clients may write (a server reachable from elsewhere is not open
//! to writes by accident), unless the operator opens writes to all (`--open-writes`). A write
//! preflight (`OPTIONS` asking for a write method) is answered here: allowed for the configured
//! origins only, so a browser on any other page never sends the write. Browsers send some
//! writes without a preflight (a multipart form POST), so the write itself is checked too: an
//! `Origin` that is neither configured nor the server's own (its `Host`) is refused. Requests
//! without an `Origin` (curl, scripts, other servers) are not browsers' and pass that check.
//! Behind trusted proxies (`--trusted-proxies`), the client is the address they forward for.

use crate::api::error::{echo, ApiError};
use crate::api::http::drain;
use crate::api::origin;
use crate::config::{ServeConfig, WriteToken};
use axum::extract::Request;
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode};
use axum::response::{IntoResponse, Response};
use std::net::IpAddr;

/// How long a browser may keep a write preflight's answer.
const PREFLIGHT_MAX_AGE_SECS: u32 = 600;

/// The write policy of one server.
pub struct WritePolicy {
    token: Option<WriteToken>,
    read_only: bool,
    /// Without a token, writes from every client, not only loopback ones (`--open-writes`).
    open: bool,
    /// Lowercase origins allowed to write across origins; `*` allows every origin.
    origins: Vec<String>,
}

impl WritePolicy {
    pub fn new(cfg: &ServeConfig) -> WritePolicy {
        WritePolicy {
            token: cfg.write_token.clone(),
            read_only: cfg.read_only,
            open: cfg.open_writes,
            origins: cfg.cors_write_origins.iter().map(|o| o.trim_end_matches('/').to_ascii_lowercase()).collect(),
        }
    }

    fn origin_listed(&self, origin: &str) -> bool {
        self.origins.iter().any(|o| o == "*" || o.eq_ignore_ascii_case(origin))
    }

    /// Logs at start-up who may write, warning when anyone may.
    pub fn announce(&self) {
        if self.read_only {
            tracing::info!("writes: refused (--read-only)");
        } else if self.token.is_some() {
            tracing::info!("writes: with the write token");
        } else if self.open {
            tracing::warn!(
                "writes: OPEN to every client that reaches the port (--open-writes): anyone can upload, rename \
                 and delete textures; set VTEX_WRITE_TOKEN instead unless a proxy in front authenticates writes"
            );
        } else {
            tracing::info!("writes: from loopback clients only (no write token set; see VTEX_WRITE_TOKEN)");
        }
    }

    /// Whether a write from `client` carrying `headers` may proceed: read-only first, then the
    /// origin, then the token, or without one the client's address.
    fn admit(&self, headers: &HeaderMap, client: IpAddr) -> Result<(), ApiError> {
        if self.read_only {
            return Err(ApiError::Forbidden("this server is read-only (--read-only): writes are refused".into()));
        }
        if let Some(origin) = headers.get(header::ORIGIN) {
            let origin = origin.to_str().unwrap_or("");
            if !self.origin_listed(origin) && !same_origin(origin, headers) {
                return Err(ApiError::Forbidden(format!(
                    "writes from pages of origin `{}` are not allowed (--cors-write-origins)",
                    echo(origin)
                )));
            }
        }
        let Some(token) = &self.token else {
            return if self.open || client.to_canonical().is_loopback() {
                Ok(())
            } else {
                Err(ApiError::Forbidden(format!(
                    "writes from {client} are refused: with no write token set, only loopback clients may write. \
                     Set a token (VTEX_WRITE_TOKEN, --write-token or --write-token-file) and send \
                     `Authorization: Bearer <token>`, or start the server with --open-writes to accept writes \
                     from anyone"
                )))
            };
        };
        let presented = headers.get(header::AUTHORIZATION).and_then(|v| v.to_str().ok());
        match presented.map(|v| v.split_once(' ')) {
            None => Err(ApiError::Unauthorized(
                "writes need the write token: send `Authorization: Bearer <token>` (VTEX_WRITE_TOKEN)".into(),
            )),
            Some(Some((scheme, value))) if scheme.eq_ignore_ascii_case("bearer") && token.matches(value.trim()) => {
                Ok(())
            }
            Some(_) => Err(ApiError::Unauthorized(
                "the write token is wrong (expected `Authorization: Bearer <token>`)".into(),
            )),
        }
    }

    /// The answer to a write preflight from `origin`.
    fn preflight(&self, origin: Option<&str>) -> Response {
        let Some(origin) = origin.filter(|o| self.origin_listed(o)) else {
            let shown = origin.map_or("(none)".to_string(), echo);
            return refusal(ApiError::Forbidden(format!(
                "writes from pages of origin `{shown}` are not allowed (--cors-write-origins)"
            )));
        };
        let mut resp = StatusCode::NO_CONTENT.into_response();
        let h = resp.headers_mut();
        let origin = HeaderValue::from_str(origin).unwrap_or(HeaderValue::from_static("null"));
        h.insert(header::ACCESS_CONTROL_ALLOW_ORIGIN, origin);
        h.insert(header::ACCESS_CONTROL_ALLOW_METHODS, HeaderValue::from_static("POST, PATCH, DELETE"));
        h.insert(header::ACCESS_CONTROL_ALLOW_HEADERS, HeaderValue::from_static("authorization, content-type"));
        h.insert(header::ACCESS_CONTROL_MAX_AGE, HeaderValue::from(PREFLIGHT_MAX_AGE_SECS));
        h.insert(header::VARY, HeaderValue::from_static("origin"));
        resp
    }
}

/// True for methods that change the store.
pub fn is_write(method: &Method) -> bool {
    !matches!(*method, Method::GET | Method::HEAD | Method::OPTIONS)
}

/// True when `origin` (`scheme://host[:port]`) names the host the request was sent to: the
/// server's own pages. The scheme is not compared: behind a TLS-terminating proxy the server
/// cannot know it.
fn same_origin(origin: &str, headers: &HeaderMap) -> bool {
    let authority = origin.split_once("://").map_or("", |(_, rest)| rest);
    let host = headers.get(header::HOST).and_then(|v| v.to_str().ok()).unwrap_or("");
    !authority.is_empty() && authority.eq_ignore_ascii_case(host)
}

/// A refused write: the JSON error, readable by any page like every other answer.
fn refusal(e: ApiError) -> Response {
    let mut resp = e.into_response();
    resp.headers_mut().insert(header::ACCESS_CONTROL_ALLOW_ORIGIN, HeaderValue::from_static("*"));
    resp
}

impl WritePolicy {
    /// `req` if the policy lets it through (see the module docs); otherwise the answer: a
    /// write preflight's, or a refused write's after its body is drained.
    pub async fn screen(&self, cfg: &ServeConfig, req: Request) -> Result<Request, Response> {
        if req.method() == Method::OPTIONS {
            let headers = req.headers();
            let asks_to_write = headers
                .get(header::ACCESS_CONTROL_REQUEST_METHOD)
                .and_then(|v| Method::from_bytes(v.as_bytes()).ok())
                .is_some_and(|m| is_write(&m));
            if asks_to_write {
                return Err(self.preflight(headers.get(header::ORIGIN).and_then(|v| v.to_str().ok())));
            }
        } else if is_write(req.method()) {
            let (parts, body) = req.into_parts();
            let client = origin::client_addr(cfg, &parts);
            let req = Request::from_parts(parts, body);
            if let Err(e) = self.admit(req.headers(), client) {
                tracing::info!(method = %req.method(), path = %echo(req.uri().path()), reason = %e, "write refused");
                drain(req).await;
                return Err(refusal(e));
            }
            return Ok(req);
        }
        Ok(req)
    }
}
