//! What the engine can fail with, by meaning; `api` gives each its HTTP status at the edge.

/// The cause of a failure of the server's own: kept for the log, never shown to a client.
/// Shared, so that one synthesis's failure can answer every request that waited for it.
pub type Cause = std::sync::Arc<dyn std::error::Error + Send + Sync>;

#[derive(Clone, Debug, thiserror::Error)]
pub enum Error {
    /// The request names something malformed or absent by definition: an invalid id, a level
    /// the texture does not have, a region outside the limits.
    #[error("{0}")]
    Invalid(String),
    /// What the request names does not exist: no such texture, a tile outside its level.
    #[error("{0}")]
    Missing(String),
    /// A model refused what it was given (a bad encoding, a region it cannot render).
    #[error(transparent)]
    Model(#[from] vtex_synth::Error),
    /// No capacity now (the synthesis queue is full) or any more (shutting down).
    #[error("{0}")]
    Busy(String),
    /// The server failed. `what` (static text, so it cannot carry a path or an OS message) is
    /// all a client may learn; `cause` goes to the log.
    #[error("{what}: {cause}")]
    Failed { what: &'static str, cause: Cause },
}

impl Error {
    /// A failure of the server's own: `what` it was doing, `cause` why it failed.
    pub fn failed(what: &'static str, cause: impl Into<Box<dyn std::error::Error + Send + Sync>>) -> Self {
        Error::Failed { what, cause: Cause::from(cause.into()) }
    }
}

/// Client input echoed in messages is cut short, so an error never amplifies a request.
pub fn echo(s: &str) -> String {
    const MAX: usize = 64;
    if s.chars().count() <= MAX {
        s.to_string()
    } else {
        format!("{}…", s.chars().take(MAX).collect::<String>())
    }
}
