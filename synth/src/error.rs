//! One error type for everything a caller can get wrong: each variant names the problem.

/// What was wrong with an encoding, an image, a parameter or a request.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum Error {
    #[error("invalid bundle: {0}")]
    Bundle(String),
    #[error("invalid image `{name}`: {reason}")]
    Image { name: String, reason: String },
    #[error("invalid parameter `{name}`: {reason}")]
    Param { name: String, reason: String },
    #[error("invalid region: {0}")]
    Region(String),
    #[error("unknown model `{model}`; known models: {known}")]
    UnknownModel { model: String, known: String },
    /// A model of vtex that this build was made without (its `model-*` feature is off).
    #[error("model `{model}` is not in this build, which holds only: {built}")]
    NotBuilt { model: String, built: String },
    /// An encoding whose cost is over a bound the caller set (see `models::cost`).
    #[error("{model}: {value} {what} ({why}) exceeds the bound of {bound}")]
    TooCostly { model: String, what: &'static str, value: u64, why: String, bound: u64 },
}

pub type Result<T, E = Error> = std::result::Result<T, E>;

impl Error {
    /// An invalid parameter, named as it appears in the encoding's JSON.
    pub fn param(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::Param { name: name.into(), reason: reason.into() }
    }

    pub fn image(name: impl Into<String>, reason: impl Into<String>) -> Self {
        Error::Image { name: name.into(), reason: reason.into() }
    }

    pub fn bundle(reason: impl Into<String>) -> Self {
        Error::Bundle(reason.into())
    }
}
