//! HTTP as operators expect: compression when the client accepts it (bytes identical once
//! decoded), `Vary` only where an answer depends on a request header, validators on the list
//! and texture info.

use crate::support::*;
use std::time::Duration;

/// A client that asks for every encoding vtex offers and decodes what it gets.
fn decoding_client() -> reqwest::Client {
    reqwest::Client::builder().timeout(Duration::from_secs(120)).build().unwrap()
}

#[tokio::test]
async fn compression_is_negotiated_and_decodes_to_the_same_bytes() {
    let dir = tempdir();
    let web = tempdir();
    let script: String = (0..4000).map(|i| format!("export const v{i} = {i};\n")).collect();
    std::fs::write(web.path().join("big.js"), &script).unwrap();
    let s = Server::start(dir.path(), &["--web-dir", web.path().to_str().unwrap()]);
    let (plain, decoding) = (client(), decoding_client());
    let id = put(&plain, &s, &mosaic(64, 16, 1)).await;
    for _ in 0..3 {
        put(&plain, &s, &mosaic(64, 4, rand::random())).await;
    }

    let rgba = s.tile_url(&id, 0, 1, 1, "rgba");
    let list = s.url("/api/v1/textures");
    let static_file = s.url("/big.js");
    for url in [&rgba, &list, &static_file] {
        let (st, ih, identity) = get_with(&plain, url, &[]).await;
        assert_eq!(st, 200, "{url}");
        assert!(ih.get("content-encoding").is_none(), "{url}: nothing compressed unasked");
        for encoding in ["gzip", "br", "zstd"] {
            let (st, h, compressed) = get_with(&plain, url, &[("accept-encoding", encoding)]).await;
            assert_eq!(st, 200);
            assert_eq!(h["content-encoding"], encoding, "{url}");
            assert_eq!(h["vary"], "accept-encoding", "{url}");
            assert!(compressed.len() < identity.len(), "{url}: {encoding} {} ≥ {}", compressed.len(), identity.len());
            let (_, _, decoded) = get_with(&decoding, url, &[("accept-encoding", encoding)]).await;
            assert!(decoded == identity, "{url}: {encoding} decodes to the identity bytes");
        }
    }

    // A compressed tile is another representation: its ETag is the weak form of the tile's, and
    // revalidates either way.
    let (_, strong, _) = get_with(&plain, &rgba, &[]).await;
    let (_, weak, _) = get_with(&plain, &rgba, &[("accept-encoding", "gzip")]).await;
    let strong = strong["etag"].to_str().unwrap();
    assert_eq!(weak["etag"].to_str().unwrap(), format!("W/{strong}"));
    let (st, _, _) = get_with(&plain, &rgba, &[("accept-encoding", "gzip"), ("if-none-match", strong)]).await;
    assert_eq!(st, 304);

    // Images are compressed already; the streamed batch is never held back by a compressor.
    let png = s.tile_url(&id, 0, 1, 1, "png");
    let batch = s.url(&format!("/api/v1/textures/{id}/tiles?format=rgba&tiles=0/0/0,0/1/0"));
    for url in [&png, &batch] {
        let (st, h, _) = get_with(&plain, url, &[("accept-encoding", "gzip, br, zstd")]).await;
        assert_eq!(st, 200);
        assert!(h.get("content-encoding").is_none(), "{url}");
        assert!(h.get("vary").is_none(), "{url}: nothing varies");
    }
}

#[tokio::test]
async fn the_viewer_builds_compressed_copies_are_sent_as_they_are() {
    use std::io::Write as _;
    let dir = tempdir();
    let web = tempdir();
    let script: String = (0..4000).map(|i| format!("export const w{i} = {i};\n")).collect();
    std::fs::write(web.path().join("pre.js"), &script).unwrap();
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(script.as_bytes()).unwrap();
    let gz = gz.finish().unwrap();
    std::fs::write(web.path().join("pre.js.gz"), &gz).unwrap();
    let s = Server::start(dir.path(), &["--web-dir", web.path().to_str().unwrap()]);
    let url = s.url("/pre.js");
    let (st, h, body) = get_with(&client(), &url, &[("accept-encoding", "gzip")]).await;
    assert_eq!(st, 200);
    assert_eq!(h["content-encoding"], "gzip");
    assert!(body == gz, "the build's copy, not one compressed on the fly");
    let (_, _, decoded) = get_with(&decoding_client(), &url, &[("accept-encoding", "gzip")]).await;
    assert!(decoded == script.as_bytes());
}

#[tokio::test]
async fn no_vary_on_origin_any_origin_is_allowed() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 16, 1)).await;
    for path in [format!("/api/v1/textures/{id}/tiles/0/0/0.png"), format!("/api/v1/textures/{id}"), "/healthz".into()]
    {
        let (st, h, _) = get_with(&c, &s.url(&path), &[("origin", "http://example.test")]).await;
        assert_eq!(st, 200);
        assert_eq!(h["access-control-allow-origin"], "*");
        let vary = h.get("vary").map(|v| v.to_str().unwrap().to_ascii_lowercase()).unwrap_or_default();
        assert!(!vary.contains("origin") && !vary.contains("access-control"), "{path}: {vary}");
    }
}

#[tokio::test]
async fn the_list_and_texture_info_carry_validators() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 16, 1)).await;
    for path in ["/api/v1/textures".to_string(), format!("/api/v1/textures/{id}")] {
        let (st, h, body) = get_with(&c, &s.url(&path), &[]).await;
        assert_eq!(st, 200);
        assert_eq!(h["cache-control"], "no-cache");
        let tag = h["etag"].to_str().unwrap().to_string();
        let (st, h, empty) = get_with(&c, &s.url(&path), &[("if-none-match", &tag)]).await;
        assert_eq!((st, empty.len()), (304, 0), "{path}");
        assert_eq!(h["etag"], tag.as_str());
        let (_, again, same) = get_with(&c, &s.url(&path), &[]).await;
        assert_eq!((again["etag"].to_str().unwrap(), same), (tag.as_str(), body));
    }
    // The list's validator changes with the store.
    let (_, before, _) = get_with(&c, &s.url("/api/v1/textures"), &[]).await;
    put(&c, &s, &mosaic(64, 4, 2)).await;
    let (st, _, _) =
        get_with(&c, &s.url("/api/v1/textures"), &[("if-none-match", before["etag"].to_str().unwrap())]).await;
    assert_eq!(st, 200, "a new texture is a new list");
}
