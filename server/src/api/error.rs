//! The API's one error type: every failure a handler, extractor or layer can answer with,
//! sent as a status and `{"error": "message"}`.

use axum::http::{header, HeaderValue, StatusCode};
use axum::response::{IntoResponse, Response};

pub use crate::engine::Cause;

/// Seconds a client is asked to wait before retrying a `503`.
pub const RETRY_AFTER_SECS: u32 = 1;

#[derive(Clone, Debug, thiserror::Error)]
pub enum ApiError {
    #[error("{0}")]
    BadRequest(String),
    #[error("{0}")]
    NotFound(String),
    /// A write without the write token, or with a wrong one: answered with `WWW-Authenticate`.
    #[error("{0}")]
    Unauthorized(String),
    /// A write this server refuses whatever the token: read-only, from an origin not allowed,
    /// or, with no token set, from a client not on loopback. No credential would change the
    /// answer, so 403 (RFC 9110 §15.5.4), not a 401 whose challenge could not be met.
    #[error("{0}")]
    Forbidden(String),
    #[error("{0}")]
    MethodNotAllowed(String),
    #[error("{0}")]
    Timeout(String),
    #[error("{0}")]
    PayloadTooLarge(String),
    #[error("{0}")]
    UriTooLong(String),
    #[error("{0}")]
    UnsupportedMediaType(String),
    /// An `Accept` header that names no representation the resource has.
    #[error("{0}")]
    NotAcceptable(String),
    /// An encoding over a bound of the server: what it would cost (`vtex_synth::Error::TooCostly`).
    #[error("{0}")]
    TooCostly(String),
    /// The store holds its maximum, or its disk is full: the message names which.
    #[error("{0}")]
    InsufficientStorage(String),
    /// Over capacity or shutting down: answered at once with `Retry-After`.
    #[error("{0}")]
    Unavailable(String),
    /// The server failed. `what` (static text, so it cannot carry a path or an OS message) is
    /// all the client learns; `cause` goes to the log.
    #[error("{what}: {cause}")]
    Internal { what: &'static str, cause: Cause },
}

impl ApiError {
    pub fn bad_request(message: impl Into<String>) -> Self {
        ApiError::BadRequest(message.into())
    }

    pub fn not_found(message: impl Into<String>) -> Self {
        ApiError::NotFound(message.into())
    }

    /// A server-side failure: `what` the server was doing, `cause` why it failed.
    pub fn internal(what: &'static str, cause: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> Self {
        ApiError::Internal { what, cause: Cause::from(cause.into()) }
    }

    pub fn status(&self) -> StatusCode {
        match self {
            ApiError::BadRequest(_) => StatusCode::BAD_REQUEST,
            ApiError::NotFound(_) => StatusCode::NOT_FOUND,
            ApiError::Unauthorized(_) => StatusCode::UNAUTHORIZED,
            ApiError::Forbidden(_) => StatusCode::FORBIDDEN,
            ApiError::MethodNotAllowed(_) => StatusCode::METHOD_NOT_ALLOWED,
            ApiError::Timeout(_) => StatusCode::REQUEST_TIMEOUT,
            ApiError::PayloadTooLarge(_) => StatusCode::PAYLOAD_TOO_LARGE,
            ApiError::UriTooLong(_) => StatusCode::URI_TOO_LONG,
            ApiError::UnsupportedMediaType(_) => StatusCode::UNSUPPORTED_MEDIA_TYPE,
            ApiError::NotAcceptable(_) => StatusCode::NOT_ACCEPTABLE,
            ApiError::TooCostly(_) => StatusCode::UNPROCESSABLE_ENTITY,
            ApiError::InsufficientStorage(_) => StatusCode::INSUFFICIENT_STORAGE,
            ApiError::Unavailable(_) => StatusCode::SERVICE_UNAVAILABLE,
            ApiError::Internal { .. } => StatusCode::INTERNAL_SERVER_ERROR,
        }
    }

    /// The status and the message the client receives. An internal error is logged here with
    /// its cause, once per answer it becomes, and answered with its static description only.
    pub fn to_client(&self) -> (StatusCode, String) {
        let message = match self {
            ApiError::Internal { what, cause } => {
                tracing::error!(cause = %cause, "{what}");
                format!("internal server error: {what}")
            }
            other => other.to_string(),
        };
        (self.status(), message)
    }

    /// The JSON body of the answer, `{"error": "…"}`.
    pub fn to_json(&self) -> (StatusCode, String) {
        let (status, message) = self.to_client();
        (status, serde_json::json!({ "error": message }).to_string())
    }
}

pub use crate::engine::echo;

/// The engine's failures by meaning, as statuses.
impl From<crate::engine::Error> for ApiError {
    fn from(e: crate::engine::Error) -> Self {
        use crate::engine::Error;
        match e {
            Error::Invalid(m) => ApiError::BadRequest(m),
            Error::Missing(m) => ApiError::NotFound(m),
            Error::Model(e) => e.into(),
            Error::Busy(m) => ApiError::Unavailable(m),
            Error::Failed { what, cause } => ApiError::Internal { what, cause },
        }
    }
}

/// An encoding the client got wrong is a 400; one that is well formed but over the server's
/// bounds a 422.
impl From<vtex_synth::Error> for ApiError {
    fn from(e: vtex_synth::Error) -> Self {
        match e {
            vtex_synth::Error::TooCostly { .. } => ApiError::TooCostly(e.to_string()),
            e => ApiError::bad_request(e.to_string()),
        }
    }
}

impl IntoResponse for ApiError {
    fn into_response(self) -> Response {
        let (status, body) = self.to_json();
        let mut resp = (status, body).into_response();
        resp.headers_mut().insert(header::CONTENT_TYPE, HeaderValue::from_static("application/json"));
        if status == StatusCode::UNAUTHORIZED {
            resp.headers_mut()
                .insert(header::WWW_AUTHENTICATE, HeaderValue::from_static("Bearer realm=\"vtex writes\""));
        }
        if status == StatusCode::SERVICE_UNAVAILABLE {
            resp.headers_mut().insert(header::RETRY_AFTER, HeaderValue::from(RETRY_AFTER_SECS));
        }
        resp
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn internal_errors_answer_without_their_cause() {
        let cause = std::io::Error::new(std::io::ErrorKind::PermissionDenied, "/secret/dir: permission denied");
        let e = ApiError::internal("storing the bundle failed", cause);
        let (status, body) = e.to_json();
        assert_eq!(status, StatusCode::INTERNAL_SERVER_ERROR);
        assert!(body.contains("storing the bundle failed"), "{body}");
        assert!(!body.contains("secret") && !body.contains("permission"), "{body}");
        assert!(e.to_string().contains("/secret/dir"), "the cause stays available for the log");
    }

    #[test]
    fn costs_over_the_bounds_are_422() {
        let e = vtex_synth::Error::TooCostly {
            model: "cascade".into(),
            what: "work units per tile",
            value: 9,
            why: "3 stages × 3".into(),
            bound: 5,
        };
        let (status, message) = ApiError::from(e).to_client();
        assert_eq!(status, StatusCode::UNPROCESSABLE_ENTITY);
        assert!(message.contains("cascade") && message.contains("3 stages × 3") && message.contains('5'), "{message}");
        let bad = ApiError::from(vtex_synth::Error::param("name", "1 to 200 printable characters"));
        assert_eq!(bad.status(), StatusCode::BAD_REQUEST);
    }
}
