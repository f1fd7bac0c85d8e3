//! Parsing of path segments and query values, with errors that name the parameter and say
//! what was wrong (empty, negative, not a number, too large).

use super::error::{echo, ApiError};

fn check_integer(name: &str, s: &str, allow_negative: bool) -> Result<(), ApiError> {
    if s.is_empty() {
        return Err(ApiError::bad_request(format!("`{name}` is empty; expected an integer")));
    }
    let digits = s.strip_prefix('-').filter(|_| allow_negative).unwrap_or(s);
    if !digits.is_empty() && digits.bytes().all(|b| b.is_ascii_digit()) {
        return Ok(());
    }
    if let Some(rest) = s.strip_prefix('-') {
        if !rest.is_empty() && rest.bytes().all(|b| b.is_ascii_digit()) {
            return Err(ApiError::bad_request(format!("`{name}` must not be negative (got {})", echo(s))));
        }
    }
    Err(ApiError::bad_request(format!("`{name}` must be an integer (got `{}`)", echo(s))))
}

/// A non-negative integer that fits in u32.
pub fn parse_u32(name: &str, s: &str) -> Result<u32, ApiError> {
    check_integer(name, s, false)?;
    s.parse::<u32>()
        .map_err(|_| ApiError::bad_request(format!("`{name}` {} is too large (at most {})", echo(s), u32::MAX)))
}

/// A signed integer that fits in i64.
pub fn parse_i64(name: &str, s: &str) -> Result<i64, ApiError> {
    check_integer(name, s, true)?;
    s.parse::<i64>().map_err(|_| {
        ApiError::bad_request(format!("`{name}` {} is out of range ({}..={})", echo(s), i64::MIN, i64::MAX))
    })
}

/// Query pairs of a raw query string, refusing repeated keys (which would be ambiguous).
pub fn query_pairs(raw: Option<&str>) -> Result<Vec<(String, String)>, ApiError> {
    let mut out: Vec<(String, String)> = Vec::new();
    for (k, v) in form_urlencoded::parse(raw.unwrap_or("").as_bytes()) {
        if out.iter().any(|(seen, _)| *seen == k) {
            return Err(ApiError::bad_request(format!("query parameter `{}` is repeated", echo(&k))));
        }
        out.push((k.into_owned(), v.into_owned()));
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn msg<T: std::fmt::Debug>(r: Result<T, ApiError>) -> String {
        r.unwrap_err().message
    }

    #[test]
    fn integers_and_their_errors() {
        assert_eq!(parse_u32("x", "0").unwrap(), 0);
        assert_eq!(parse_u32("x", "4294967295").unwrap(), u32::MAX);
        assert!(msg(parse_u32("x", "4294967296")).contains("too large"));
        assert!(msg(parse_u32("x", "99999999999999999999999")).contains("too large"));
        assert!(msg(parse_u32("x", "-1")).contains("negative"));
        assert!(msg(parse_u32("level", "abc")).contains("`level` must be an integer"));
        assert!(msg(parse_u32("x", "")).contains("empty"));
        assert!(msg(parse_u32("x", "+1")).contains("integer"));
        assert!(msg(parse_u32("x", "1e3")).contains("integer"));
        assert_eq!(parse_i64("x", "-5").unwrap(), -5);
        assert!(msg(parse_i64("x", "-")).contains("integer"));
        assert!(msg(parse_i64("x", "9223372036854775808")).contains("out of range"));
    }

    #[test]
    fn long_input_is_not_echoed_in_full() {
        let long = "a".repeat(10_000);
        assert!(msg(parse_u32("x", &long)).len() < 200);
    }

    #[test]
    fn repeated_query_keys_are_refused() {
        assert_eq!(query_pairs(Some("a=1&b=2")).unwrap().len(), 2);
        assert!(msg(query_pairs(Some("a=1&a=2"))).contains("repeated"));
    }
}
