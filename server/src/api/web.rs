//! The viewer, built into the binary (`server/build.rs` embeds `client-web/dist`), served at `/`.
//!
//! Every file is served twice: at `/{path}`, revalidated (`no-cache` and an ETag), and at
//! `/assets/{build}/{path}`, cached for a year (`immutable`), `build` being a hash of every
//! file. The page itself (`/`, `/index.html`) is revalidated and names its stylesheet and
//! scripts by their `/assets/{build}/` URLs, so a browser fetches them once per build; the
//! modules they import relatively resolve inside the same fingerprinted directory.

use super::not_modified;
use axum::body::Body;
use axum::extract::Request;
use axum::http::{header, HeaderValue, Method, StatusCode};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use std::collections::HashMap;
use std::sync::LazyLock;

mod embedded {
    include!(concat!(env!("OUT_DIR"), "/web_files.rs"));
}

/// Where the fingerprinted copies live: `/assets/{build}/…`.
const ASSETS: &str = "/assets/";

struct Asset {
    body: Bytes,
    content_type: HeaderValue,
    etag: HeaderValue,
}

/// The viewer's files, by path below the build directory.
pub struct Web {
    files: HashMap<String, Asset>,
    /// A hash of every file: the fingerprint in `/assets/{build}/`.
    build: String,
}

static EMBEDDED: LazyLock<Option<Web>> = LazyLock::new(|| Web::from_files(embedded::FILES));

impl Web {
    /// The viewer this binary was built with, if it was built with one.
    pub fn embedded() -> Option<&'static Web> {
        EMBEDDED.as_ref()
    }

    fn from_files(files: &[(&str, &[u8])]) -> Option<Web> {
        if !files.iter().any(|(p, _)| *p == "index.html") {
            return None;
        }
        let mut all = blake3::Hasher::new();
        for (path, bytes) in files {
            all.update(path.as_bytes()).update(&(bytes.len() as u64).to_le_bytes()).update(bytes);
        }
        let build = all.finalize().to_hex()[..16].to_string();
        let asset = |path: &str, body: Vec<u8>| {
            let etag = format!("\"{}\"", &blake3::hash(&body).to_hex()[..32]);
            let mime = mime_guess::from_path(path).first_or_octet_stream();
            let content_type = match mime.type_() {
                mime_guess::mime::TEXT | mime_guess::mime::JAVASCRIPT => format!("{mime}; charset=utf-8"),
                _ => mime.to_string(),
            };
            Asset {
                body: Bytes::from(body),
                content_type: HeaderValue::from_str(&content_type).expect("a media type is a valid header value"),
                etag: HeaderValue::from_str(&etag).expect("hex is a valid header value"),
            }
        };
        let mut out: HashMap<String, Asset> =
            files.iter().map(|(path, bytes)| (path.to_string(), asset(path, bytes.to_vec()))).collect();
        let index = files.iter().find(|(p, _)| *p == "index.html").expect("checked above").1;
        let mut page = String::from_utf8_lossy(index).into_owned();
        for (path, _) in files.iter().filter(|(p, _)| *p != "index.html") {
            page = page.replace(&format!("=\"{path}\""), &format!("=\"{ASSETS}{build}/{path}\""));
        }
        out.insert(String::new(), asset("index.html", page.into_bytes()));
        Some(Web { files: out, build })
    }

    /// The answer to a GET or HEAD of `path`.
    fn answer(&self, path: &str, req: &Request) -> Response {
        let (key, immutable) = match path.strip_prefix(ASSETS).and_then(|p| p.split_once('/')) {
            Some((build, rest)) if build == self.build => (rest, true),
            Some(_) => return not_found(),
            None => match path.trim_start_matches('/') {
                "index.html" => ("", false),
                p => (p, false),
            },
        };
        let Some(asset) = self.files.get(key) else { return not_found() };
        let cache =
            HeaderValue::from_static(if immutable { "public, max-age=31536000, immutable" } else { "no-cache" });
        if not_modified(req.headers(), asset.etag.to_str().unwrap_or_default()) {
            return (StatusCode::NOT_MODIFIED, [(header::ETAG, asset.etag.clone()), (header::CACHE_CONTROL, cache)])
                .into_response();
        }
        let headers = [
            (header::CONTENT_TYPE, asset.content_type.clone()),
            (header::ETAG, asset.etag.clone()),
            (header::CACHE_CONTROL, cache),
        ];
        let body = if req.method() == Method::HEAD { Body::empty() } else { Body::from(asset.body.clone()) };
        let mut resp = (headers, body).into_response();
        resp.headers_mut().insert(header::CONTENT_LENGTH, HeaderValue::from(asset.body.len()));
        resp
    }
}

fn not_found() -> Response {
    (StatusCode::NOT_FOUND, [(header::CONTENT_TYPE, "text/plain; charset=utf-8")], "not found\n").into_response()
}

/// The static fallback of the router when the viewer is served from the binary: the viewer,
/// or, in a binary built without it, a page that says how to build it.
pub async fn serve(req: Request) -> Response {
    if req.method() != Method::GET && req.method() != Method::HEAD {
        return StatusCode::METHOD_NOT_ALLOWED.into_response();
    }
    match Web::embedded() {
        Some(web) => web.answer(req.uri().path(), &req),
        None => (
            StatusCode::NOT_FOUND,
            [(header::CONTENT_TYPE, "text/plain; charset=utf-8")],
            "This vtex was built without its viewer. Run `npm ci && npm run build` in client-web/, then build \
             vtex again (or serve a viewer build with --web-dir). The API is at /api/v1/textures.\n",
        )
            .into_response(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn get(web: &Web, path: &str) -> Response {
        web.answer(path, &Request::get(path).body(Body::empty()).unwrap())
    }

    #[test]
    fn the_page_names_fingerprinted_assets() {
        let files: &[(&str, &[u8])] = &[
            ("index.html", b"<link href=\"viewer.css\"><script src=\"main.js\"></script><a href=\"other\">"),
            ("main.js", b"import './lib.js';"),
            ("viewer.css", b"body{}"),
        ];
        let web = Web::from_files(files).unwrap();
        let page = String::from_utf8(web.files[""].body.to_vec()).unwrap();
        let b = &web.build;
        assert_eq!(
            page,
            format!(
                "<link href=\"/assets/{b}/viewer.css\"><script src=\"/assets/{b}/main.js\"></script><a href=\"other\">"
            )
        );
        let r = get(&web, &format!("/assets/{b}/main.js"));
        assert_eq!(r.status(), StatusCode::OK);
        assert!(r.headers()[header::CACHE_CONTROL].to_str().unwrap().contains("immutable"));
        assert_eq!(r.headers()[header::CONTENT_TYPE], "text/javascript; charset=utf-8");
        let r = get(&web, "/main.js");
        assert_eq!(r.headers()[header::CACHE_CONTROL], "no-cache");
        assert_eq!(get(&web, "/assets/0000000000000000/main.js").status(), StatusCode::NOT_FOUND);
        assert_eq!(get(&web, "/nothing.js").status(), StatusCode::NOT_FOUND);
        let other = Web::from_files(&[files[0], ("main.js", b"changed"), files[2]]).unwrap();
        assert_ne!(other.build, web.build, "another build, another fingerprint");
        assert!(Web::from_files(&files[1..]).is_none(), "no page, no viewer");
    }
}
