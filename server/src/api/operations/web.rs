//! The viewer, built into the binary (`server/build.rs` embeds `client-web/dist`), served at `/`.
//!
//! Every file is served twice: at `/{path}`, revalidated (`no-cache` and an ETag), and at
//! `/assets/{build}/{path}`, cached for a year (`immutable`), `build` being a hash of every
//! file. The pages (`/` or `/index.html`, the viewer; `/vt.html`, the virtual-texturing demo;
//! `/world.html`, the 3D world), at the build's root, are revalidated and name their stylesheets
//! and scripts (in the build's folders: `viewer/main.js`, `vt/main.js`, …) by their
//! `assets/{build}/` URLs, so a browser fetches those once per build; the modules they import
//! relatively resolve inside the same fingerprinted directory. Those URLs are relative, as every
//! URL of the viewer is: under a proxy's sub-path (`/vtex/`) they stay below it.
//!
//! Files come with the brotli and gzip copies the viewer's build made; a client that accepts
//! one gets it (`Vary: Accept-Encoding`), others the file as it is.

use crate::api::http::not_modified;
use axum::body::Body;
use axum::extract::Request;
use axum::http::{header, HeaderMap, HeaderValue, Method, StatusCode};
use axum::response::{IntoResponse, Response};
use bytes::Bytes;
use std::collections::HashMap;
use std::sync::LazyLock;

mod embedded {
    /// One file of the viewer's build, with its compressed copies (empty when compressing
    /// does not pay, or for the page, which is rewritten at run time).
    pub struct File {
        pub path: &'static str,
        pub bytes: &'static [u8],
        pub br: &'static [u8],
        pub gzip: &'static [u8],
    }

    include!(concat!(env!("OUT_DIR"), "/web_files.rs"));
}
use embedded::File;

/// Where the fingerprinted copies live, below the viewer's root: `assets/{build}/…`.
const ASSETS: &str = "assets/";

struct Asset {
    body: Bytes,
    /// The body as brotli and as gzip; empty when there is no such copy.
    br: Bytes,
    gzip: Bytes,
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

    fn from_files(files: &[File]) -> Option<Web> {
        if !files.iter().any(|f| f.path == "index.html") {
            return None;
        }
        let mut all = blake3::Hasher::new();
        for f in files {
            all.update(f.path.as_bytes()).update(&(f.bytes.len() as u64).to_le_bytes()).update(f.bytes);
        }
        let build = all.finalize().to_hex()[..16].to_string();
        let asset = |path: &str, body: Vec<u8>, br: &'static [u8], gzip: &'static [u8]| {
            let etag = format!("\"{}\"", &blake3::hash(&body).to_hex()[..32]);
            let mime = mime_guess::from_path(path).first_or_octet_stream();
            let content_type = match mime.type_() {
                mime_guess::mime::TEXT | mime_guess::mime::JAVASCRIPT => format!("{mime}; charset=utf-8"),
                _ => mime.to_string(),
            };
            Asset {
                body: Bytes::from(body),
                br: Bytes::from_static(br),
                gzip: Bytes::from_static(gzip),
                content_type: HeaderValue::from_str(&content_type).expect("a media type is a valid header value"),
                etag: HeaderValue::from_str(&etag).expect("hex is a valid header value"),
            }
        };
        let mut out: HashMap<String, Asset> =
            files.iter().map(|f| (f.path.to_string(), asset(f.path, f.bytes.to_vec(), f.br, f.gzip))).collect();
        for page in files.iter().filter(|f| is_page(f.path)) {
            let mut html = String::from_utf8_lossy(page.bytes).into_owned();
            for f in files.iter().filter(|f| !is_page(f.path)) {
                let path = f.path;
                html = html.replace(&format!("=\"{path}\""), &format!("=\"{ASSETS}{build}/{path}\""));
            }
            out.insert(page.path.to_string(), asset(page.path, html.into_bytes(), &[], &[]));
        }
        Some(Web { files: out, build })
    }

    /// The answer to a GET or HEAD of `path`.
    fn answer(&self, path: &str, req: &Request) -> Response {
        let path = path.trim_start_matches('/');
        let (key, immutable) = match path.strip_prefix(ASSETS).and_then(|p| p.split_once('/')) {
            Some((build, rest)) if build == self.build => (rest, true),
            Some(_) => return not_found(),
            None => match path {
                "" => ("index.html", false),
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
        let (encoding, bytes) = asset.representation(req.headers());
        let length = bytes.len();
        let body = if req.method() == Method::HEAD { Body::empty() } else { Body::from(bytes) };
        let mut resp = (headers, body).into_response();
        let h = resp.headers_mut();
        h.insert(header::CONTENT_LENGTH, HeaderValue::from(length));
        if !asset.br.is_empty() || !asset.gzip.is_empty() {
            h.insert(header::VARY, HeaderValue::from_static("accept-encoding"));
        }
        if let Some(encoding) = encoding {
            h.insert(header::CONTENT_ENCODING, HeaderValue::from_static(encoding));
        }
        resp
    }
}

impl Asset {
    /// The copy to send to a client with `headers`: brotli, else gzip, when accepted and made;
    /// else the file itself (and the compression layer may still compress it, e.g. as zstd).
    fn representation(&self, headers: &HeaderMap) -> (Option<&'static str>, Bytes) {
        for (encoding, bytes) in [("br", &self.br), ("gzip", &self.gzip)] {
            if !bytes.is_empty() && accepts(headers, encoding) {
                return (Some(encoding), bytes.clone());
            }
        }
        (None, self.body.clone())
    }
}

/// Whether `Accept-Encoding` accepts `encoding`: named, or `*`, with a quality above 0.
fn accepts(headers: &HeaderMap, encoding: &str) -> bool {
    let mut named = None;
    let mut any = None;
    for value in headers.get_all(header::ACCEPT_ENCODING).iter().filter_map(|v| v.to_str().ok()) {
        for item in value.split(',') {
            let mut parts = item.split(';');
            let name = parts.next().unwrap_or("").trim();
            let q = parts
                .filter_map(|p| p.trim().strip_prefix("q="))
                .find_map(|q| q.trim().parse::<f32>().ok())
                .unwrap_or(1.0);
            if name.eq_ignore_ascii_case(encoding) {
                named = Some(q > 0.0);
            } else if name == "*" {
                any = Some(q > 0.0);
            }
        }
    }
    named.or(any).unwrap_or(false)
}

/// A page of the build: its references to the other files are rewritten to their fingerprinted
/// URLs (so it is never sent as a compressed copy the build made).
fn is_page(path: &str) -> bool {
    path.ends_with(".html") && !path.contains('/')
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

    fn file(path: &'static str, bytes: &'static [u8]) -> File {
        File { path, bytes, br: &[], gzip: &[] }
    }

    #[test]
    fn the_page_names_fingerprinted_assets() {
        let files = &[
            file(
                "index.html",
                b"<link href=\"viewer/style.css\"><script src=\"viewer/main.js\"></script><a href=\"x\">",
            ),
            file("viewer/main.js", b"import '../shared/lib.js';"),
            file("viewer/style.css", b"body{}"),
        ];
        let web = Web::from_files(files).unwrap();
        let page = String::from_utf8(web.files["index.html"].body.to_vec()).unwrap();
        let b = &web.build;
        assert_eq!(
            page,
            format!(
                "<link href=\"assets/{b}/viewer/style.css\"><script src=\"assets/{b}/viewer/main.js\"></script>\
                 <a href=\"x\">"
            )
        );
        let r = get(&web, &format!("/assets/{b}/viewer/main.js"));
        assert_eq!(r.status(), StatusCode::OK);
        assert!(r.headers()[header::CACHE_CONTROL].to_str().unwrap().contains("immutable"));
        assert_eq!(r.headers()[header::CONTENT_TYPE], "text/javascript; charset=utf-8");
        let r = get(&web, "/viewer/main.js");
        assert_eq!(r.headers()[header::CACHE_CONTROL], "no-cache");
        assert_eq!(get(&web, "/assets/0000000000000000/viewer/main.js").status(), StatusCode::NOT_FOUND);
        assert_eq!(get(&web, "/nothing.js").status(), StatusCode::NOT_FOUND);
        let other = Web::from_files(&[
            file("index.html", files[0].bytes),
            file("viewer/main.js", b"changed"),
            file("viewer/style.css", files[2].bytes),
        ])
        .unwrap();
        assert_ne!(other.build, web.build, "another build, another fingerprint");
        assert!(Web::from_files(&files[1..]).is_none(), "no page, no viewer");
    }

    #[test]
    fn every_page_names_fingerprinted_assets_and_the_root_is_the_viewer() {
        let web = Web::from_files(&[
            file("index.html", b"<script src=\"viewer/main.js\"></script>"),
            File { path: "vt.html", bytes: b"<script src=\"vt/main.js\"></script>", br: b"stale", gzip: b"stale" },
            file("viewer/main.js", b""),
            file("vt/main.js", b""),
        ])
        .unwrap();
        let b = &web.build;
        let body = |path: &str| web.files[path].body.clone();
        assert_eq!(body("index.html"), format!("<script src=\"assets/{b}/viewer/main.js\"></script>"));
        assert_eq!(body("vt.html"), format!("<script src=\"assets/{b}/vt/main.js\"></script>"));
        assert!(web.files["vt.html"].br.is_empty(), "a rewritten page has no copy the build compressed");
        let r = web.answer("/", &Request::get("/").header(header::ACCEPT_ENCODING, "br").body(Body::empty()).unwrap());
        assert_eq!(r.headers()[header::ETAG], web.files["index.html"].etag);
        assert_eq!(r.headers()[header::CACHE_CONTROL], "no-cache");
    }

    #[test]
    fn compressed_copies_are_sent_to_clients_that_accept_them() {
        let web = Web::from_files(&[
            file("index.html", b"<script src=\"main.js\"></script>"),
            File { path: "main.js", bytes: b"raw", br: b"BR", gzip: b"GZ" },
            File { path: "only-gzip.js", bytes: b"raw", br: &[], gzip: b"GZ" },
        ])
        .unwrap();
        let ask = |path: &str, accept: &str| {
            let r = web
                .answer(path, &Request::get(path).header(header::ACCEPT_ENCODING, accept).body(Body::empty()).unwrap());
            let encoding = r.headers().get(header::CONTENT_ENCODING).map(|v| v.to_str().unwrap().to_string());
            let vary = r.headers().get(header::VARY).map(|v| v.to_str().unwrap().to_string());
            let length: usize = r.headers()[header::CONTENT_LENGTH].to_str().unwrap().parse().unwrap();
            (encoding, vary, length)
        };
        let br = (Some("br".to_string()), Some("accept-encoding".to_string()), 2);
        let gz = (Some("gzip".to_string()), Some("accept-encoding".to_string()), 2);
        let raw = (None, Some("accept-encoding".to_string()), 3);
        assert_eq!(ask("/main.js", "gzip, deflate, br, zstd"), br);
        assert_eq!(ask("/main.js", "gzip"), gz);
        assert_eq!(ask("/main.js", "br;q=0, gzip;q=0.5"), gz);
        assert_eq!(ask("/main.js", "*"), br);
        assert_eq!(ask("/main.js", "*;q=0, identity"), raw);
        assert_eq!(ask("/main.js", "zstd"), raw, "no zstd copy: the compression layer's business");
        assert_eq!(ask("/only-gzip.js", "br, gzip"), gz);
        let (encoding, vary, _) = ask("/", "br, gzip");
        assert_eq!((encoding, vary), (None, None), "the page is rewritten, never precompressed");
    }
}
