//! [`Path`] and [`Query`]: axum's extractors of the same names, deserializing a route's path
//! segments or query string into a struct (`#[serde(deny_unknown_fields)]`) and rejecting with
//! [`ApiError`]. Every endpoint thereby names a bad, missing, repeated or unknown parameter in
//! the same words.

use super::error::{echo, ApiError};
use axum::extract::{FromRequestParts, RawPathParams};
use axum::http::request::Parts;
use serde::de::value::MapDeserializer;
use serde::de::{DeserializeOwned, IntoDeserializer};
use serde::Deserialize;
use std::fmt;

/// The path segments of the matched route template, by name.
pub struct Path<T>(pub T);

/// The query string, by parameter name.
pub struct Query<T>(pub T);

/// The query of the endpoints that take none: any parameter is refused.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoQuery {}

impl<S: Send + Sync, T: DeserializeOwned> FromRequestParts<S> for Path<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, state: &S) -> Result<Self, ApiError> {
        let raw = RawPathParams::from_request_parts(parts, state).await.map_err(|e| {
            if e.status().is_client_error() {
                ApiError::bad_request(e.body_text())
            } else {
                ApiError::internal("the route has no path parameters", e)
            }
        })?;
        path_params(raw.iter()).map(Path)
    }
}

impl<S: Send + Sync, T: DeserializeOwned> FromRequestParts<S> for Query<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        query_params(parts.uri.query()).map(Query)
    }
}

/// What [`Path`] makes of the (decoded) segments a route template matched.
pub fn path_params<'a, T: Deserialize<'a>>(pairs: impl Iterator<Item = (&'a str, &'a str)>) -> Result<T, ApiError> {
    deserialize(MapDeserializer::new(pairs), Place::Path)
}

/// What [`Query`] makes of a query string.
pub fn query_params<T: DeserializeOwned>(query: Option<&str>) -> Result<T, ApiError> {
    deserialize(MapDeserializer::new(form_urlencoded::parse(query.unwrap_or_default().as_bytes())), Place::Query)
}

#[derive(Clone, Copy)]
enum Place {
    Path,
    Query,
}

/// What serde reports while filling a parameter struct, kept apart so that each kind of
/// problem gets its own message.
#[derive(Debug)]
enum ParamError {
    /// A value its parser refused: the words that follow the parameter's name.
    Value(String),
    Unknown {
        name: String,
        expected: &'static [&'static str],
    },
    Missing(&'static str),
    Repeated(&'static str),
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            ParamError::Value(why) => f.write_str(why),
            ParamError::Unknown { name, expected } => {
                let expected = if expected.is_empty() { "none".to_string() } else { expected.join(", ") };
                write!(f, "unknown query parameter `{}`; expected {expected}", echo(name))
            }
            ParamError::Missing(name) => write!(f, "missing query parameter `{name}`"),
            ParamError::Repeated(name) => write!(f, "query parameter `{name}` is repeated"),
        }
    }
}

impl std::error::Error for ParamError {}

impl serde::de::Error for ParamError {
    fn custom<T: fmt::Display>(msg: T) -> Self {
        ParamError::Value(msg.to_string())
    }

    fn unknown_field(field: &str, expected: &'static [&'static str]) -> Self {
        ParamError::Unknown { name: field.to_string(), expected }
    }

    fn missing_field(field: &'static str) -> Self {
        ParamError::Missing(field)
    }

    fn duplicate_field(field: &'static str) -> Self {
        ParamError::Repeated(field)
    }
}

/// Fills `T` from name–value pairs. A value's error is prefixed with its name; a path that
/// does not fit its struct is the server's fault (the route template and the handler
/// disagree), a query that does not fit is the client's.
fn deserialize<'de, T, I, K, V>(pairs: MapDeserializer<'de, I, ParamError>, place: Place) -> Result<T, ApiError>
where
    T: Deserialize<'de>,
    I: Iterator<Item = (K, V)>,
    K: IntoDeserializer<'de, ParamError>,
    V: IntoDeserializer<'de, ParamError>,
{
    serde_path_to_error::deserialize(pairs).map_err(|e| {
        let name = e.path().to_string();
        match (e.into_inner(), place) {
            (ParamError::Value(why), _) => ApiError::bad_request(format!("`{}` {why}", echo(&name))),
            (other, Place::Query) => ApiError::bad_request(other.to_string()),
            (other, Place::Path) => ApiError::internal("the route's path does not fit its handler", other),
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::api::params::de;

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Q {
        #[serde(deserialize_with = "de::u32")]
        level: u32,
        #[serde(default, deserialize_with = "de::opt_u32")]
        frame: Option<u32>,
    }

    fn query<T: DeserializeOwned>(q: &str) -> Result<T, String> {
        query_params(Some(q)).map_err(|e| e.to_string())
    }

    #[test]
    fn each_problem_is_named() {
        let q: Q = query("level=3&frame=%32").unwrap();
        assert_eq!((q.level, q.frame), (3, Some(2)));
        assert_eq!(query::<Q>("level=3").unwrap().frame, None);
        assert_eq!(query::<Q>("level=-3").unwrap_err(), "`level` must not be negative (got -3)");
        assert_eq!(query::<Q>("frame=1").unwrap_err(), "missing query parameter `level`");
        assert_eq!(query::<Q>("level=1&level=2").unwrap_err(), "query parameter `level` is repeated");
        assert_eq!(
            query::<Q>("level=1&border=4").unwrap_err(),
            "unknown query parameter `border`; expected level, frame"
        );
        assert_eq!(query::<NoQuery>("x=1").unwrap_err(), "unknown query parameter `x`; expected none");
        assert!(query::<NoQuery>("").is_ok());
    }
}
