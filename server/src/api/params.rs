//! Values of path segments and query parameters. Each parser says what is wrong with a value
//! (empty, negative, not a number, too large) in words that follow the parameter's name:
//! [`extract`](super::extract) puts the name in front (`` `x` must not be negative (got -1) ``).

use super::error::{echo, ApiError};
use crate::encode::Format;
use serde::{de::Error as _, Deserialize, Deserializer};

fn check_integer(s: &str, allow_negative: bool) -> Result<(), String> {
    if s.is_empty() {
        return Err("is empty; expected an integer".into());
    }
    let digits = s.strip_prefix('-').filter(|_| allow_negative).unwrap_or(s);
    if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
        return Ok(());
    }
    if let Some(rest) = s.strip_prefix('-') {
        if !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit()) {
            return Err(format!("must not be negative (got {})", echo(s)));
        }
    }
    Err(format!("must be an integer (got `{}`)", echo(s)))
}

/// A non-negative integer that fits in u32.
pub fn u32_value(s: &str) -> Result<u32, String> {
    check_integer(s, false)?;
    s.parse::<u32>().map_err(|_| format!("{} is too large (at most {})", echo(s), u32::MAX))
}

/// A signed integer that fits in i64.
pub fn i64_value(s: &str) -> Result<i64, String> {
    check_integer(s, true)?;
    s.parse::<i64>().map_err(|_| format!("{} is out of range ({}..={})", echo(s), i64::MIN, i64::MAX))
}

/// A tile or region format by its extension.
pub fn format_value(s: &str) -> Result<Format, String> {
    Format::parse(s).ok_or_else(|| format!("names unknown format `{}`; {}", echo(s), Format::EXPECTED))
}

/// Applies a value parser to the value called `name`, for values taken apart by hand (the
/// `y` and format of a tile's file name, the items of a batch's list).
pub fn named<T>(name: &str, s: &str, parse: fn(&str) -> Result<T, String>) -> Result<T, ApiError> {
    parse(s).map_err(|why| ApiError::bad_request(format!("`{name}` {why}")))
}

/// The row and format of a tile's, page's or metatile's file name, `{y}.{format}` (`what` names
/// it in errors, `expected` lists the formats `format` parses).
pub fn row_and_format<T>(
    what: &str,
    file: &str,
    format: fn(&str) -> Result<T, String>,
    expected: &str,
) -> Result<(u32, T), ApiError> {
    let (y, ext) = file
        .rsplit_once('.')
        .ok_or_else(|| ApiError::bad_request(format!("{what} `{}` has no format extension; {expected}", echo(file))))?;
    Ok((named("y", y, u32_value)?, named("format", ext, format)?))
}

/// The parsers above as serde field deserializers (`#[serde(deserialize_with = "…")]`).
pub mod de {
    use super::*;

    fn with<'de, D: Deserializer<'de>, T>(d: D, parse: fn(&str) -> Result<T, String>) -> Result<T, D::Error> {
        parse(&String::deserialize(d)?).map_err(D::Error::custom)
    }

    pub fn u32<'de, D: Deserializer<'de>>(d: D) -> Result<u32, D::Error> {
        with(d, u32_value)
    }

    pub fn opt_u32<'de, D: Deserializer<'de>>(d: D) -> Result<Option<u32>, D::Error> {
        with(d, u32_value).map(Some)
    }

    pub fn i64<'de, D: Deserializer<'de>>(d: D) -> Result<i64, D::Error> {
        with(d, i64_value)
    }

    pub fn format<'de, D: Deserializer<'de>>(d: D) -> Result<Format, D::Error> {
        with(d, format_value)
    }

    pub fn opt_format<'de, D: Deserializer<'de>>(d: D) -> Result<Option<Format>, D::Error> {
        with(d, format_value).map(Some)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg<T: std::fmt::Debug>(r: Result<T, String>) -> String {
        r.unwrap_err()
    }

    #[test]
    fn integers_and_their_errors() {
        assert_eq!(u32_value("0").unwrap(), 0);
        assert_eq!(u32_value("4294967295").unwrap(), u32::MAX);
        assert!(msg(u32_value("4294967296")).contains("too large"));
        assert!(msg(u32_value("99999999999999999999999")).contains("too large"));
        assert!(msg(u32_value("-1")).contains("negative"));
        assert!(msg(u32_value("abc")).contains("must be an integer"));
        assert!(msg(u32_value("")).contains("empty"));
        assert!(msg(u32_value("+1")).contains("integer"));
        assert!(msg(u32_value("1e3")).contains("integer"));
        assert_eq!(i64_value("-5").unwrap(), -5);
        assert!(msg(i64_value("-")).contains("integer"));
        assert!(msg(i64_value("9223372036854775808")).contains("out of range"));
        let e = named("level", "abc", u32_value).unwrap_err().to_string();
        assert_eq!(e, "`level` must be an integer (got `abc`)");
    }

    #[test]
    fn long_input_is_not_echoed_in_full() {
        let long = "a".repeat(10_000);
        assert!(msg(u32_value(&long)).len() < 200);
        assert!(msg(format_value(&long)).len() < 200);
    }
}
