//! What every request's head must satisfy, checked before any route or parser sees it: its
//! `Host` (RFC 9112 §3.2) and its query's length and number of parameters
//! ([`check_query`]), so a hostile query costs one scan of at most
//! [`MAX_BATCH_QUERY_BYTES`] bytes, whatever the route.

use crate::api::error::{echo, ApiError};
use crate::api::extract::{check_query, MAX_BATCH_QUERY_BYTES, MAX_QUERY_BYTES};
use axum::http::uri::Authority;
use axum::http::{header, HeaderMap, Request, Version};
use vtex_wire::urls::BATCH;

/// Largest request head (request line and headers) hyper reads, in either protocol: the longest
/// query any route takes (a tile batch's) and room for ordinary headers.
pub const MAX_HEAD_BYTES: usize = MAX_BATCH_QUERY_BYTES + 32 * 1024;

/// A matcher of `template` alone, the router's own (`matchit`).
pub(super) fn matcher(template: &str) -> matchit::Router<()> {
    let mut m = matchit::Router::new();
    m.insert(template, ()).expect("route templates are valid");
    m
}

pub(super) struct Head {
    /// [`BATCH`] alone: the route allowed a longer query.
    batch: matchit::Router<()>,
}

impl Head {
    pub(super) fn new() -> Head {
        Head { batch: matcher(BATCH) }
    }

    /// A valid `Host`, a bounded query. The query's bound is looked up by route only for a
    /// query longer than the usual one.
    pub(super) fn check<B>(&self, req: &Request<B>) -> Result<(), ApiError> {
        check_host(req.version(), req.headers())?;
        let query = req.uri().query();
        let long = query.is_some_and(|q| q.len() > MAX_QUERY_BYTES) && self.batch.at(req.uri().path()).is_ok();
        check_query(query, if long { MAX_BATCH_QUERY_BYTES } else { MAX_QUERY_BYTES })
    }
}

/// RFC 9112 §3.2: an HTTP/1.1 request without `Host`, and an HTTP/1 request with more than one
/// or with one that is not `host[:port]`, are 400s. HTTP/2 carries `:authority` instead.
fn check_host(version: Version, headers: &HeaderMap) -> Result<(), ApiError> {
    if version != Version::HTTP_11 && version != Version::HTTP_10 {
        return Ok(());
    }
    let mut hosts = headers.get_all(header::HOST).iter();
    match (hosts.next(), hosts.next()) {
        (None, _) if version == Version::HTTP_11 => {
            Err(ApiError::bad_request("an HTTP/1.1 request needs a Host header (RFC 9112 §3.2)"))
        }
        (None, _) => Ok(()),
        (Some(_), Some(_)) => Err(ApiError::bad_request("more than one Host header (RFC 9112 §3.2)")),
        (Some(host), None) => {
            let valid = !host.as_bytes().contains(&b'@') && Authority::try_from(host.as_bytes()).is_ok();
            match valid {
                true => Ok(()),
                false => Err(ApiError::bad_request(format!(
                    "the Host header `{}` is not host[:port]",
                    echo(&String::from_utf8_lossy(host.as_bytes()))
                ))),
            }
        }
    }
}
