//! The access log: one line per request, written when its response body is finished or
//! dropped, so that it counts the bytes actually sent and the time to the last of them. At
//! `info` with `--access-log`, else at `debug`; the target is `vtex::access` either way.

use axum::http::{Method, Uri};
use std::time::Instant;

const TARGET: &str = "vtex::access";

/// One request's line, logged when dropped.
pub struct AccessLine {
    method: Method,
    uri: Uri,
    status: u16,
    start: Instant,
    bytes: u64,
    info: bool,
}

impl AccessLine {
    /// Whether a line would be written: only then is the request's method and URI kept.
    pub fn wanted(info: bool) -> bool {
        if info {
            tracing::enabled!(target: TARGET, tracing::Level::INFO)
        } else {
            tracing::enabled!(target: TARGET, tracing::Level::DEBUG)
        }
    }

    /// The line of a request received at `start`, answered `status`.
    pub fn new(method: Method, uri: Uri, status: u16, start: Instant, info: bool) -> AccessLine {
        AccessLine { method, uri, status, start, bytes: 0, info }
    }

    /// Counts `n` more body bytes sent.
    pub fn sent(&mut self, n: usize) {
        self.bytes += n as u64;
    }
}

impl Drop for AccessLine {
    fn drop(&mut self) {
        let latency_us = self.start.elapsed().as_micros() as u64;
        // Levels are constants of their call sites: one per level, with the same fields.
        macro_rules! line {
            ($level:ident) => {
                tracing::$level!(
                    target: TARGET,
                    method = %self.method,
                    path = %self.uri.path(),
                    status = self.status,
                    bytes = self.bytes,
                    latency_us,
                    "request"
                )
            };
        }
        if self.info {
            line!(info)
        } else {
            line!(debug)
        }
    }
}
