//! The media type of a IIIF JSON-LD document, negotiated from `Accept` as Image API 3 §5.1 and
//! Presentation API 3 §6.3 ask: with no `Accept`, JSON-LD with the document's context as its
//! `profile`; otherwise whichever of JSON-LD and plain JSON the client weighs higher (RFC 9110
//! §12.5.1, the most specific media range deciding each one's weight), JSON-LD on a tie.

use crate::api::error::{echo, ApiError};
use axum::http::{header, HeaderMap, HeaderValue};
use axum::response::{IntoResponse, Response};

/// A kind of IIIF document: its JSON-LD context and the media type naming it as the profile.
pub struct Context {
    pub uri: &'static str,
    media_type: &'static str,
}

pub const IMAGE: Context = Context {
    uri: "http://iiif.io/api/image/3/context.json",
    media_type: "application/ld+json;profile=\"http://iiif.io/api/image/3/context.json\"",
};

pub const PRESENTATION: Context = Context {
    uri: "http://iiif.io/api/presentation/3/context.json",
    media_type: "application/ld+json;profile=\"http://iiif.io/api/presentation/3/context.json\"",
};

const JSON: &str = "application/json";

/// `body` as the media type the request negotiates (`Vary: Accept`, since it depends on it).
pub fn respond(headers: &HeaderMap, context: &Context, body: &serde_json::Value) -> Result<Response, ApiError> {
    let content_type = negotiate(headers, context)?;
    let vary = [(header::VARY, HeaderValue::from_static("accept"))];
    Ok(([(header::CONTENT_TYPE, content_type)], vary, body.to_string()).into_response())
}

/// The media type to answer with, or a 406 when `Accept` rules out both.
fn negotiate(headers: &HeaderMap, context: &Context) -> Result<&'static str, ApiError> {
    let ranges: Vec<mime::Mime> = headers
        .get_all(header::ACCEPT)
        .iter()
        .filter_map(|v| v.to_str().ok())
        .flat_map(|v| v.split(','))
        .filter_map(|r| r.trim().parse().ok())
        .collect();
    if ranges.is_empty() {
        return Ok(context.media_type);
    }
    let (ld, json) = (weight(&ranges, "application/ld+json", Some(context.uri)), weight(&ranges, JSON, None));
    if ld == 0.0 && json == 0.0 {
        let accept: Vec<_> = headers.get_all(header::ACCEPT).iter().filter_map(|v| v.to_str().ok()).collect();
        return Err(ApiError::NotAcceptable(format!(
            "Accept `{}` allows neither {} nor {JSON}",
            echo(&accept.join(", ")),
            context.media_type
        )));
    }
    Ok(if ld >= json { context.media_type } else { JSON })
}

/// The weight `ranges` give `media_type` (with `profile`, for JSON-LD): that of the most
/// specific range that matches it, 0 when none does.
fn weight(ranges: &[mime::Mime], media_type: &str, profile: Option<&str>) -> f32 {
    ranges
        .iter()
        .filter_map(|r| {
            let specificity = match r.essence_str() {
                "*/*" => 0,
                "application/*" => 1,
                essence if essence == media_type => match (r.get_param("profile"), profile) {
                    // A profile parameter is a space-separated list of URIs (RFC 6906).
                    (Some(asked), Some(ours)) if asked.as_str().split_whitespace().any(|p| p == ours) => 3,
                    (Some(_), _) => return None,
                    (None, _) => 2,
                },
                _ => return None,
            };
            let q = r.get_param("q").map_or(Some(1.0), |q| q.as_str().parse::<f32>().ok())?;
            Some((specificity, q.clamp(0.0, 1.0)))
        })
        .max_by_key(|&(specificity, _)| specificity)
        .map_or(0.0, |(_, q)| q)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn negotiated(accept: Option<&str>) -> Result<&'static str, u16> {
        let mut headers = HeaderMap::new();
        if let Some(a) = accept {
            headers.insert(header::ACCEPT, HeaderValue::from_str(a).unwrap());
        }
        negotiate(&headers, &IMAGE).map_err(|e| e.status().as_u16())
    }

    #[test]
    fn accept_chooses_the_media_type() {
        let ld = Ok(IMAGE.media_type);
        let json = Ok(JSON);
        // §5.1: "If the request does not include an Accept header", JSON-LD with the profile.
        assert_eq!(negotiated(None), ld);
        // §5.1: otherwise "following the rules of content negotiation".
        for (accept, expected) in [
            ("application/ld+json", ld),
            ("application/json", json),
            ("*/*", ld),
            ("application/*", ld),
            ("application/json, application/ld+json;q=0.5", json),
            ("application/ld+json;q=0.9, application/json;q=0.8", ld),
            ("application/json;q=0.8, */*;q=0.9", ld),
            // The Accept header "MAY include parameters, for example profile or charset".
            ("application/ld+json;profile=\"http://iiif.io/api/image/3/context.json\"", ld),
            ("application/ld+json;profile=\"http://iiif.io/api/image/2/context.json\", application/json", json),
            ("application/json;charset=utf-8", json),
            ("text/html,application/xhtml+xml,*/*;q=0.8", ld),
            ("application/ld+json;q=0, */*", json),
            ("text/html", Err(406)),
            ("application/ld+json;profile=\"http://iiif.io/api/image/2/context.json\"", Err(406)),
            ("application/json;q=0, application/ld+json;q=0", Err(406)),
        ] {
            assert_eq!(negotiated(Some(accept)), expected, "{accept}");
        }
    }
}
