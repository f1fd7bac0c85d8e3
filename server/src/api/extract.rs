//! [`Path`] and [`Query`]: axum's extractors of the same names, deserializing a route's path
//! segments or query string into a struct (`#[serde(deny_unknown_fields)]`) and rejecting with
//! [`ApiError`]. Every endpoint thereby names a bad, missing, repeated or unknown parameter in
//! the same words. A query of parameters shared with other routes is a [`Both`] of two structs.
//!
//! [`check_query`] bounds a query before anything parses it: its length (414) and its number
//! of parameters (400). The connection code (`serve/head.rs`) applies it to every request, so
//! a hostile query costs one scan of at most [`MAX_BATCH_QUERY_BYTES`] bytes, whatever the
//! route.

use super::error::{echo, ApiError};
use axum::extract::{FromRequestParts, RawPathParams};
use axum::http::request::Parts;
use serde::de::value::MapDeserializer;
use serde::de::{DeserializeOwned, IntoDeserializer};
use serde::Deserialize;
use std::fmt;

/// Longest query of every route but the tile batch; the others take a few short numbers.
pub const MAX_QUERY_BYTES: usize = 2048;
/// Longest query of a tile batch ([`BATCH`](vtex_wire::urls::BATCH)): its longest list with every byte
/// percent-encoded, and its other parameters.
pub const MAX_BATCH_QUERY_BYTES: usize = 3 * MAX_LIST_BYTES + 256;
/// Longest `tiles` list accepted: 256 tiles of the largest coordinates fit with room to spare.
pub const MAX_LIST_BYTES: usize = 8192;
/// Most parameters any route takes (a page batch's nine); a query with more cannot be valid.
pub const MAX_QUERY_KEYS: usize = 9;

/// Refuses a query over `max_bytes` (414) or with more than [`MAX_QUERY_KEYS`] parameters
/// (400), counting them as the parser would (`&`-separated, empty ones skipped).
pub fn check_query(query: Option<&str>, max_bytes: usize) -> Result<(), ApiError> {
    let Some(q) = query.filter(|q| !q.is_empty()) else { return Ok(()) };
    if q.len() > max_bytes {
        return Err(ApiError::UriTooLong(format!(
            "the query is {} bytes long; this endpoint takes at most {max_bytes}",
            q.len()
        )));
    }
    let keys = q.split('&').filter(|p| !p.is_empty()).count();
    if keys > MAX_QUERY_KEYS {
        return Err(ApiError::bad_request(format!(
            "the query has {keys} parameters; no endpoint takes more than {MAX_QUERY_KEYS}"
        )));
    }
    Ok(())
}

/// The path segments of the matched route template, by name.
pub struct Path<T>(pub T);

/// The query string, by parameter name.
pub struct Query<T>(pub T);

/// The query of the endpoints that take none: any parameter is refused.
#[derive(Debug, Deserialize)]
#[serde(deny_unknown_fields)]
pub struct NoQuery {}

/// A query filled into two parameter structs: `A` the route's own parameters, `B` a set it
/// shares with other routes (serde's `flatten` would lose `deny_unknown_fields` and the names
/// in value errors). Each struct takes its own parameters, and a parameter neither takes is
/// refused naming the parameters of both.
#[derive(Debug)]
pub struct Both<A, B>(pub A, pub B);

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

impl<S: Send + Sync, T: FromQuery> FromRequestParts<S> for Query<T> {
    type Rejection = ApiError;

    async fn from_request_parts(parts: &mut Parts, _: &S) -> Result<Self, ApiError> {
        query_params(parts.uri.query()).map(Query)
    }
}

/// What a query string fills: a parameter struct, or [`Both`] of two.
pub trait FromQuery: Sized {
    fn from_query(query: Option<&str>) -> Result<Self, ApiError>;
}

impl<T: DeserializeOwned> FromQuery for T {
    fn from_query(query: Option<&str>) -> Result<T, ApiError> {
        deserialize(MapDeserializer::new(pairs(query)), Place::Query, &[])
    }
}

impl<A: DeserializeOwned, B: DeserializeOwned> FromQuery for Both<A, B> {
    fn from_query(query: Option<&str>) -> Result<Both<A, B>, ApiError> {
        let (own, shared) = (fields::<A>(), fields::<B>());
        let is_shared = |key: &str| shared.contains(&key);
        // Unknown parameters go to `A`, whose refusal names `B`'s parameters too. The query is
        // parsed once for each, not collected: a hostile query of many empty pairs costs no
        // memory in proportion.
        let a = pairs(query).filter(|(k, _)| !is_shared(k));
        let b = pairs(query).filter(|(k, _)| is_shared(k));
        let a = deserialize(MapDeserializer::new(a), Place::Query, shared)?;
        let b = deserialize(MapDeserializer::new(b), Place::Query, own)?;
        Ok(Both(a, b))
    }
}

/// What [`Path`] makes of the (decoded) segments a route template matched.
pub fn path_params<'a, T: Deserialize<'a>>(pairs: impl Iterator<Item = (&'a str, &'a str)>) -> Result<T, ApiError> {
    deserialize(MapDeserializer::new(pairs), Place::Path, &[])
}

/// What [`Query`] makes of a query string.
pub fn query_params<T: FromQuery>(query: Option<&str>) -> Result<T, ApiError> {
    T::from_query(query)
}

/// The decoded name–value pairs of a query string.
fn pairs(query: Option<&str>) -> form_urlencoded::Parse<'_> {
    form_urlencoded::parse(query.unwrap_or_default().as_bytes())
}

/// The fields of a parameter struct, as its `Deserialize` declares them: serde hands them to
/// `deserialize_struct`, which this deserializer answers with them at once.
fn fields<'de, T: Deserialize<'de>>() -> &'static [&'static str] {
    struct Probe;
    #[derive(Debug)]
    struct Fields(&'static [&'static str]);
    impl fmt::Display for Fields {
        fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
            write!(f, "fields {:?}", self.0)
        }
    }
    impl std::error::Error for Fields {}
    impl serde::de::Error for Fields {
        fn custom<M: fmt::Display>(msg: M) -> Self {
            unreachable!("a parameter struct deserializes as a struct: {msg}")
        }
    }
    impl<'de> serde::Deserializer<'de> for Probe {
        type Error = Fields;
        fn deserialize_any<V: serde::de::Visitor<'de>>(self, _: V) -> Result<V::Value, Fields> {
            unreachable!("a parameter struct deserializes as a struct")
        }
        fn deserialize_struct<V: serde::de::Visitor<'de>>(
            self,
            _: &'static str,
            fields: &'static [&'static str],
            _: V,
        ) -> Result<V::Value, Fields> {
            Err(Fields(fields))
        }
        serde::forward_to_deserialize_any! {
            bool i8 i16 i32 i64 i128 u8 u16 u32 u64 u128 f32 f64 char str string bytes byte_buf
            option unit unit_struct newtype_struct seq tuple tuple_struct map enum identifier
            ignored_any
        }
    }
    match T::deserialize(Probe) {
        Err(Fields(fields)) => fields,
        Ok(_) => unreachable!("the probe never yields a value"),
    }
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

impl ParamError {
    /// The message, naming `also` besides the struct's own parameters as expected.
    fn message(&self, also: &[&str]) -> String {
        match self {
            ParamError::Value(why) => why.clone(),
            ParamError::Unknown { name, expected } => {
                let expected: Vec<&str> = expected.iter().chain(also).copied().collect();
                let expected = if expected.is_empty() { "none".to_string() } else { expected.join(", ") };
                format!("unknown query parameter `{}`; expected {expected}", echo(name))
            }
            ParamError::Missing(name) => format!("missing query parameter `{name}`"),
            ParamError::Repeated(name) => format!("query parameter `{name}` is repeated"),
        }
    }
}

impl fmt::Display for ParamError {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.message(&[]))
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
/// disagree), a query that does not fit is the client's, told the parameters `T` and `also`
/// take.
fn deserialize<'de, T, I, K, V>(
    pairs: MapDeserializer<'de, I, ParamError>,
    place: Place,
    also: &[&str],
) -> Result<T, ApiError>
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
            (other, Place::Query) => ApiError::bad_request(other.message(also)),
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

    fn query<T: FromQuery>(q: &str) -> Result<T, String> {
        query_params(Some(q)).map_err(|e| e.to_string())
    }

    /// [`MAX_QUERY_KEYS`] refuses no valid query: it is the largest count of parameters of any
    /// route's query.
    #[test]
    fn the_key_bound_is_the_largest_query() {
        use crate::api::pages::{ChainQuery, PageParams};
        use crate::api::{batch::BatchList, tiles::RegionQuery, tiles::TileQuery};
        // A batch names `tiles` or `pages`, never both.
        let batch = fields::<BatchList>().len() - 1 + fields::<PageParams>().len();
        let counts = [
            fields::<NoQuery>().len(),
            fields::<TileQuery>().len(),
            batch,
            fields::<RegionQuery>().len(),
            fields::<PageParams>().len(),
            fields::<ChainQuery>().len(),
        ];
        assert_eq!(counts, [0, 1, 9, 7, 7, 6]);
        assert_eq!(counts.iter().max(), Some(&MAX_QUERY_KEYS));
    }

    #[test]
    fn long_and_crowded_queries_are_refused_before_parsing() {
        let status = |q: &str, max| check_query(Some(q), max).map_err(|e| e.status().as_u16());
        assert_eq!(status("level=0&x=0&y=0&w=1&h=1&format=png&frame=0", MAX_QUERY_BYTES), Ok(()));
        assert_eq!(status("a&&&&&&&&b&c&d&e&f&g", MAX_QUERY_BYTES), Ok(()), "empty pairs are skipped");
        assert_eq!(status("a&b&c&d&e&f&g&h&i", MAX_QUERY_BYTES), Ok(()));
        assert_eq!(status("a&b&c&d&e&f&g&h&i&j", MAX_QUERY_BYTES), Err(400));
        assert_eq!(status(&"x".repeat(MAX_QUERY_BYTES), MAX_QUERY_BYTES), Ok(()));
        assert_eq!(status(&"x".repeat(MAX_QUERY_BYTES + 1), MAX_QUERY_BYTES), Err(414));
        let e = check_query(Some(&"k=1&".repeat(15_000)), MAX_BATCH_QUERY_BYTES).unwrap_err();
        assert_eq!(e.to_string(), "the query is 60000 bytes long; this endpoint takes at most 24832");
        let e = check_query(Some(&"k=1&".repeat(100)), MAX_QUERY_BYTES).unwrap_err();
        assert_eq!(e.to_string(), "the query has 100 parameters; no endpoint takes more than 9");
        assert!(check_query(None, 0).is_ok() && check_query(Some(""), 0).is_ok());
    }

    /// The longest batch list, every byte percent-encoded, fits the batch's bound.
    #[test]
    fn the_longest_batch_query_fits() {
        let list = "%2C".repeat(MAX_LIST_BYTES);
        let q = format!("format=rgba&frame=4294967295&tiles={list}");
        assert!(check_query(Some(&q), MAX_BATCH_QUERY_BYTES).is_ok());
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

    #[derive(Debug, Deserialize)]
    #[serde(deny_unknown_fields)]
    struct Shared {
        #[serde(default, deserialize_with = "de::opt_u32")]
        size: Option<u32>,
    }

    #[test]
    fn both_structs_share_one_query_and_its_words() {
        let both = |q: &str| query::<Both<Q, Shared>>(q);
        let Both(q, shared) = both("size=64&level=3").unwrap();
        assert_eq!((q.level, q.frame, shared.size), (3, None, Some(64)));
        assert_eq!(both("level=1&size=-1").unwrap_err(), "`size` must not be negative (got -1)");
        assert_eq!(both("level=1&size=1&size=2").unwrap_err(), "query parameter `size` is repeated");
        assert_eq!(both("size=1").unwrap_err(), "missing query parameter `level`");
        assert_eq!(
            both("level=1&gutter=4").unwrap_err(),
            "unknown query parameter `gutter`; expected level, frame, size"
        );
    }
}
