//! Every endpoint of the HTTP API v1 over a real socket.

use crate::support::*;
use serde_json::{json, Value};

#[tokio::test]
async fn healthz_metrics_and_empty_list() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let r = c.get(s.url("/healthz")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.json::<Value>().await.unwrap(), json!({"status": "ok"}));
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    assert_eq!(list, json!({"textures": []}));
    let m = metrics(&c, &s).await;
    for name in [
        "vtex_http_requests_total",
        "vtex_tile_cache_bytes",
        "vtex_tile_cache_budget_bytes",
        "vtex_syntheses_in_flight",
        "vtex_http_response_bytes_total",
    ] {
        assert!(m.contains(name), "{name} missing from /metrics");
    }
    assert_eq!(metric(&m, "vtex_http_requests_total", &[("route", "/healthz"), ("status", "200")]), 1.0);
}

#[tokio::test]
async fn upload_info_list_encoding() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let b = mosaic(64, 16, 1);
    let bytes = b.to_bytes();
    let (status, info) = upload(&c, &s, bytes.clone()).await;
    assert_eq!(status, 201, "{info}");
    let id = info["id"].as_str().unwrap().to_string();
    assert_eq!(id, vtex_synth::bundle::id_of(&bytes));
    assert_eq!(info["model"], "chaos-mosaic");
    assert_eq!(info["width"], 1024);
    assert_eq!(info["height"], 1024);
    assert_eq!(info["levels"], 3, "1024 → 512 → 256: the last level fits one tile");
    assert_eq!(info["tile_size"], 256);
    assert_eq!(info["encoding_bytes"], bytes.len());
    assert_eq!(info["explicit_bytes"], 1024 * 1024 * 3);
    assert_eq!(info["wraps"], true);
    assert_eq!(info["domain"], "torus");
    assert_eq!(info["animated"], false);
    assert_eq!(info["animation"], Value::Null);

    // The same bundle again: 200, nothing new stored.
    let (status, again) = upload(&c, &s, bytes.clone()).await;
    assert_eq!((status, &again), (200, &info));
    assert_eq!(store_files(dir.path()), vec![format!("{id}.vtex")]);

    let got: Value = c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
    assert_eq!(got, info);

    let other = put(&c, &s, &mosaic(32, 8, 2)).await;
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    let names: Vec<&str> = list["textures"].as_array().unwrap().iter().map(|t| t["name"].as_str().unwrap()).collect();
    let mut sorted = names.clone();
    sorted.sort();
    assert_eq!(names, sorted, "list is sorted by name");
    assert_eq!(names.len(), 2);
    assert!(list["textures"].as_array().unwrap().iter().any(|t| t["id"] == other.as_str()));

    let (status, headers, body) = get_bytes(&c, &s.url(&format!("/api/v1/textures/{id}/encoding"))).await;
    assert_eq!(status, 200);
    assert_eq!(body, bytes, "the encoding is served exactly as stored");
    assert_eq!(headers["etag"], format!("\"{id}\""));
    let r = c
        .get(s.url(&format!("/api/v1/textures/{id}/encoding")))
        .header("if-none-match", format!("\"{id}\""))
        .send()
        .await
        .unwrap();
    assert_eq!(r.status(), 304);
}

#[tokio::test]
async fn multipart_upload_creates_a_mosaic() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let form = reqwest::multipart::Form::new()
        .text("model", "chaos-mosaic")
        .text("name", "uploaded pebbles")
        .text("params", r#"{"tiles_x":8,"tiles_y":8,"iterations":10,"seed":1}"#)
        .part("sample", reqwest::multipart::Part::bytes(sample_png(64, 3)).file_name("s.png"));
    let r = c.post(s.url("/api/v1/textures")).multipart(form).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let info: Value = r.json().await.unwrap();
    assert_eq!(info["name"], "uploaded pebbles");
    assert_eq!((info["width"].as_u64(), info["height"].as_u64()), (Some(512), Some(512)));
    let id = info["id"].as_str().unwrap();
    let (status, _, png) = get_bytes(&c, &s.tile_url(id, 0, 1, 1, "png")).await;
    assert_eq!(status, 200);
    assert_eq!(image::load_from_memory(&png).unwrap().width(), 256);
}

#[tokio::test]
async fn tiles_in_every_format_with_headers() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    // 40×40 tiles of a 30² sample: 1200², so edge tiles are clipped (1200 = 4·256 + 176).
    let id = put(&c, &s, &mosaic(30, 40, 4)).await;
    let region = c
        .get(s.url(&format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=1200&h=1200&format=rgba")))
        .send()
        .await
        .unwrap();
    assert_eq!(region.status(), 200);
    let full = region.bytes().await.unwrap().to_vec();
    assert_eq!(full.len(), 1200 * 1200 * 4);
    for (fmt, ctype) in
        [("png", "image/png"), ("webp", "image/webp"), ("jpg", "image/jpeg"), ("rgba", "application/octet-stream")]
    {
        let (status, h, body) = get_bytes(&c, &s.tile_url(&id, 0, 4, 2, fmt)).await;
        assert_eq!(status, 200, "{fmt}");
        assert_eq!(h["content-type"], ctype);
        assert_eq!(h["cache-control"], "public, max-age=31536000, immutable");
        assert_eq!(h["access-control-allow-origin"], "*");
        let exposed = h["access-control-expose-headers"].to_str().unwrap().to_ascii_lowercase();
        for name in ["etag", "x-vtex-cache", "x-vtex-width", "x-vtex-height"] {
            assert!(exposed.contains(name), "{exposed}");
        }
        assert_eq!(h["x-vtex-cache"], "miss");
        assert_eq!((h["x-vtex-width"].to_str().unwrap(), h["x-vtex-height"].to_str().unwrap()), ("176", "256"));
        let etag = h["etag"].to_str().unwrap();
        assert!(etag.starts_with('"') && etag.ends_with('"') && !etag.starts_with("W/"), "strong ETag: {etag}");
        let pixels = match fmt {
            "rgba" => body.clone(),
            _ => image::load_from_memory(&body).unwrap().into_rgba8().into_raw(),
        };
        assert_eq!(pixels.len(), 176 * 256 * 4);
        if fmt != "jpg" {
            // The tile equals the matching crop of the whole level rendered in one call.
            for row in 0..256usize {
                let src = ((512 + row) * 1200 + 1024) * 4;
                assert_eq!(&pixels[row * 176 * 4..(row + 1) * 176 * 4], &full[src..src + 176 * 4], "{fmt} row {row}");
            }
        }
        let (_, h2, body2) = get_bytes(&c, &s.tile_url(&id, 0, 4, 2, fmt)).await;
        assert_eq!(h2["x-vtex-cache"], "hit");
        assert_eq!(h2["etag"], h["etag"]);
        assert_eq!(body2, body);
    }
    // The coarsest level fits one tile.
    let (status, h, _) = get_bytes(&c, &s.tile_url(&id, 3, 0, 0, "png")).await;
    assert_eq!(status, 200);
    assert_eq!((h["x-vtex-width"].to_str().unwrap(), h["x-vtex-height"].to_str().unwrap()), ("150", "150"));
    let _ = expect_error(&c, &s.tile_url(&id, 4, 0, 0, "png"), 400).await;
}

/// Plain tile GETs take the fast path (`Front` answers them without the router); HEAD and
/// percent-encoded paths take the router. All must answer alike: same bytes, same headers
/// (CORS included, as on every other route), counted under the one tile route.
#[tokio::test]
async fn plain_encoded_and_head_tiles_answer_alike() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 16, 9)).await;
    let plain = s.tile_url(&id, 0, 2, 3, "png");
    let encoded = s.url(&format!("/api/v1/textures/{id}/tiles/%30/%32/3.png"));
    let (st1, h1, b1) = get_bytes(&c, &plain).await;
    let (st2, h2, b2) = get_bytes(&c, &encoded).await;
    assert_eq!((st1, st2), (200, 200));
    assert_eq!(b1, b2);
    assert!(!b1.is_empty());
    assert_eq!((h1["x-vtex-cache"].to_str().unwrap(), h2["x-vtex-cache"].to_str().unwrap()), ("miss", "hit"));
    let info = c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap();
    let head = c.head(&plain).send().await.unwrap();
    assert_eq!(head.status(), 200);
    let names = |h: &reqwest::header::HeaderMap| {
        let mut v: Vec<String> = h.keys().map(|k| k.to_string()).filter(|k| k != "date").collect();
        v.sort();
        v
    };
    assert_eq!(names(&h1), names(&h2));
    assert_eq!(names(&h1), names(head.headers()));
    for name in ["content-type", "content-length", "etag", "cache-control", "x-vtex-width", "x-vtex-height"] {
        assert_eq!(h1[name], h2[name], "{name}");
        assert_eq!(h1[name], head.headers()[name], "{name}");
    }
    assert!(h1.get("vary").is_none() && h2.get("vary").is_none(), "a png tile varies with nothing");
    for name in ["access-control-allow-origin", "access-control-expose-headers"] {
        let all = |h: &reqwest::header::HeaderMap| h.get_all(name).iter().cloned().collect::<Vec<_>>();
        assert!(!all(&h1).is_empty(), "{name}");
        assert_eq!(all(&h1), all(&h2), "{name}");
        assert_eq!(all(&h1), all(head.headers()), "{name}");
        assert_eq!(all(&h1), all(info.headers()), "{name}: tiles carry the CORS headers of every route");
    }
    // Errors: JSON, with CORS.
    let r = c.get(s.tile_url(&id, 0, 99, 0, "png")).send().await.unwrap();
    assert_eq!(r.status(), 404);
    assert_eq!(r.headers()["access-control-allow-origin"], "*");
    assert!(r.text().await.unwrap().contains("outside level 0"));
    // Methods other than GET and HEAD still get the router's 405.
    assert_eq!(c.delete(&plain).send().await.unwrap().status(), 405);
    // All are counted under the tile route.
    let m = metrics(&c, &s).await;
    let tiles = ("route", "/api/v1/textures/{id}/tiles/{level}/{x}/{file}");
    assert_eq!(metric(&m, "vtex_http_requests_total", &[tiles, ("method", "GET"), ("status", "200")]), 2.0);
    assert_eq!(metric(&m, "vtex_http_requests_total", &[tiles, ("method", "HEAD"), ("status", "200")]), 1.0);
    assert_eq!(metric(&m, "vtex_http_requests_total", &[tiles, ("method", "GET"), ("status", "404")]), 1.0);
    assert_eq!(metric(&m, "vtex_http_requests_total", &[tiles, ("method", "DELETE"), ("status", "405")]), 1.0);
    assert_eq!(metric(&m, "vtex_tile_cache_misses_total", &[("level", "0")]), 1.0);
    assert_eq!(metric(&m, "vtex_tile_cache_hits_total", &[("level", "0")]), 2.0);
    assert!(metric(&m, "vtex_http_response_bytes_total", &[]) >= 2.0 * b1.len() as f64);
}

#[tokio::test]
async fn etag_gives_304_without_a_body() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 8, 5)).await;
    let url = s.tile_url(&id, 0, 1, 0, "webp");
    let (_, h, _) = get_bytes(&c, &url).await;
    let etag = h["etag"].to_str().unwrap().to_string();
    for inm in [etag.clone(), format!("\"nope\", {etag}"), format!("W/{etag}"), "*".to_string()] {
        let r = c.get(&url).header("if-none-match", &inm).send().await.unwrap();
        assert_eq!(r.status(), 304, "{inm}");
        assert_eq!(r.headers()["etag"], etag.as_str());
        assert_eq!(r.headers()["cache-control"], "public, max-age=31536000, immutable");
        assert!(r.bytes().await.unwrap().is_empty());
    }
    let r = c.get(&url).header("if-none-match", "\"other\"").send().await.unwrap();
    assert_eq!(r.status(), 200);
    // A 304 never needs the tile: a cold tile answers it without synthesis.
    let m0 = metric(&metrics(&c, &s).await, "vtex_syntheses_total", &[]);
    let cold = s.tile_url(&id, 0, 0, 1, "png");
    let cold_tag = {
        let s2 = Server::start(dir.path(), &[]);
        let (_, h, _) = get_bytes(&c, &s2.tile_url(&id, 0, 0, 1, "png")).await;
        h["etag"].to_str().unwrap().to_string()
    };
    let r = c.get(&cold).header("if-none-match", &cold_tag).send().await.unwrap();
    assert_eq!(r.status(), 304);
    assert_eq!(metric(&metrics(&c, &s).await, "vtex_syntheses_total", &[]), m0);
    // ETags differ by tile, format and frame-independence holds for still textures.
    let (_, a, _) = get_bytes(&c, &s.tile_url(&id, 0, 1, 0, "png")).await;
    assert_ne!(a["etag"].to_str().unwrap(), etag);
    let (_, f, _) = get_bytes(&c, &format!("{url}?frame=7")).await;
    assert_eq!(f["etag"].to_str().unwrap(), etag, "frame is normalised to 0 for still textures");
}

#[tokio::test]
async fn region_endpoint_and_its_bound() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 80, 6)).await; // 5120²
    let base = s.url(&format!("/api/v1/textures/{id}/region"));
    let r = c.get(format!("{base}?level=0&x=-100&y=5000&w=300&h=200")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "image/png");
    let img = image::load_from_memory(&r.bytes().await.unwrap()).unwrap();
    assert_eq!((img.width(), img.height()), (300, 200));
    // Torus: x = -100 is x = 5020.
    let a =
        c.get(format!("{base}?level=0&x=-100&y=0&w=100&h=10&format=rgba")).send().await.unwrap().bytes().await.unwrap();
    let b =
        c.get(format!("{base}?level=0&x=5020&y=0&w=100&h=10&format=rgba")).send().await.unwrap().bytes().await.unwrap();
    assert_eq!(a, b);
    // 4096 × 4096 is allowed.
    let r = c.get(format!("{base}?level=0&x=0&y=0&w=4096&h=4096&format=rgba")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.bytes().await.unwrap().len(), 4096 * 4096 * 4);
    // Beyond the bound: a 4xx naming the limit.
    let msg = expect_error(&c, &format!("{base}?level=0&x=0&y=0&w=4097&h=4096"), 400).await;
    assert!(msg.contains("16777216"), "{msg}");
    let msg = expect_error(&c, &format!("{base}?level=0&x=0&y=0&w=0&h=10"), 400).await;
    assert!(msg.contains("0×10"), "{msg}");
    let msg = expect_error(&c, &format!("{base}?level=0&x=0&y=0&w=10"), 400).await;
    assert!(msg.contains("missing query parameter `h`"), "{msg}");
    let msg = expect_error(&c, &format!("{base}?level=0&x=0&y=0&w=10&h=10&format=gif"), 400).await;
    assert!(msg.contains("unknown format `gif`"), "{msg}");
    let msg = expect_error(&c, &format!("{base}?level=0&x=0&y=0&w=10&h=10&zoom=2"), 400).await;
    assert!(msg.contains("unknown query parameter `zoom`"), "{msg}");
    let msg = expect_error(&c, &format!("{base}?level=40&x=0&y=0&w=10&h=10"), 400).await;
    assert!(msg.contains("level 40 does not exist"), "{msg}");
    let msg = expect_error(&c, &format!("{base}?level=0&x=9223372036854775800&y=0&w=100&h=10"), 400).await;
    assert!(msg.contains("overflow"), "{msg}");
}

#[tokio::test]
async fn patch_makes_a_new_texture() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let b = mosaic(64, 8, 7);
    let id = put(&c, &s, &b).await;
    let url = s.url(&format!("/api/v1/textures/{id}"));
    let r = c.patch(&url).json(&json!({"name": "renamed", "params": {"seed": 99}})).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let info: Value = r.json().await.unwrap();
    let new_id = info["id"].as_str().unwrap();
    assert_ne!(new_id, id);
    assert_eq!(info["name"], "renamed");
    // The stored bundle carries the merged params; the original is untouched.
    let (_, _, bytes) = get_bytes(&c, &s.url(&format!("/api/v1/textures/{new_id}/encoding"))).await;
    let patched = vtex_synth::bundle::Bundle::from_bytes(&bytes).unwrap();
    assert_eq!(patched.manifest.params["seed"], 99);
    assert_eq!(patched.manifest.params["tiles_x"], b.manifest.params["tiles_x"]);
    assert_eq!(patched.sections, b.sections);
    let (status, _, old) = get_bytes(&c, &s.url(&format!("/api/v1/textures/{id}/encoding"))).await;
    assert_eq!((status, old), (200, b.to_bytes()));
    // A new seed is a different texture.
    let (_, _, t0) = get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "rgba")).await;
    let (_, _, t1) = get_bytes(&c, &s.tile_url(new_id, 0, 0, 0, "rgba")).await;
    assert_ne!(t0, t1);

    // Invalid patches: 4xx naming the problem, nothing stored.
    let before = store_files(dir.path());
    for (patch, needle) in [
        (json!({"model": "lcm"}), "`model` cannot be patched"),
        (json!({"params": {"tiles_x": 0}}), "tiles_x"),
        (json!({"params": {"bogus": 1}}), "bogus"),
        (json!({"name": 5}), "`name` must remain a string"),
        (json!([1, 2]), "JSON object"),
    ] {
        let r = c.patch(&url).json(&patch).send().await.unwrap();
        assert_eq!(r.status(), 400, "{patch}");
        let e: Value = r.json().await.unwrap();
        assert!(e["error"].as_str().unwrap().contains(needle), "{patch}: {e}");
    }
    let r = c.patch(&url).body("{not json").send().await.unwrap();
    assert_eq!(r.status(), 400);
    assert_eq!(store_files(dir.path()), before);
}

#[tokio::test]
async fn static_viewer_and_unknown_routes() {
    let dir = tempdir();
    let web = tempdir();
    std::fs::write(web.path().join("index.html"), "<html>vtex viewer</html>").unwrap();
    std::fs::write(web.path().join("app.js"), "console.log(1)").unwrap();
    std::fs::write(dir.path().with_extension("secret"), "secret").unwrap();
    let s = Server::start(dir.path(), &["--web-dir", web.path().to_str().unwrap()]);
    let c = client();
    let r = c.get(s.url("/")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert!(r.text().await.unwrap().contains("vtex viewer"));
    assert_eq!(c.get(s.url("/app.js")).send().await.unwrap().status(), 200);
    let raw = raw_request(&s.addr, b"GET /../secret HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    assert!(!raw.contains("secret\n") && !raw.starts_with("HTTP/1.1 200"), "{raw}");
    let msg = expect_error(&c, &s.url("/api/v2/whatever"), 404).await;
    assert!(msg.contains("no API route"), "{msg}");
    let r = c.delete(s.url("/api/v1/textures")).send().await.unwrap();
    assert_eq!(r.status(), 405);
    assert!(r.text().await.unwrap().contains("not allowed"));
    let _ = std::fs::remove_file(dir.path().with_extension("secret"));
}

/// Open connections per I/O runtime, from `/metrics` read over a connection that closes.
fn connections_per_runtime(s: &Server, runtimes: usize) -> Vec<f64> {
    let m = raw_request(&s.addr, b"GET /metrics HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
    let (head, m) = m.split_once("\r\n\r\n").expect("a whole response");
    assert!(head.starts_with("HTTP/1.1 200") && head.to_ascii_lowercase().contains("content-length"), "{head}");
    (0..runtimes).map(|i| metric(m, "vtex_http_connections", &[("runtime", &i.to_string())])).collect()
}

/// Keeps `conns` open and answered once each (so each has been handed to its runtime).
fn open_answered(s: &Server, n: usize) -> Vec<std::net::TcpStream> {
    use std::io::{BufRead, BufReader, Read, Write};
    (0..n)
        .map(|_| {
            let mut c = std::net::TcpStream::connect(&s.addr).unwrap();
            c.set_read_timeout(Some(std::time::Duration::from_secs(30))).unwrap();
            c.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
            let mut r = BufReader::new(c.try_clone().unwrap());
            let mut len = 0;
            loop {
                let mut line = String::new();
                r.read_line(&mut line).unwrap();
                if let Some(v) = line.to_ascii_lowercase().strip_prefix("content-length:") {
                    len = v.trim().parse().unwrap();
                }
                if line == "\r\n" {
                    break;
                }
            }
            r.read_exact(&mut vec![0; len]).unwrap();
            c
        })
        .collect()
}

/// The acceptor hands each connection to the runtime serving the fewest: the counts never
/// differ by more than one, also after connections close unevenly.
#[tokio::test]
async fn connections_are_spread_over_the_runtimes() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--io-threads", "3"]);
    let spread = |v: &[f64]| v.iter().cloned().fold(f64::MIN, f64::max) - v.iter().cloned().fold(f64::MAX, f64::min);
    let mut open = open_answered(&s, 10);
    // The metrics request's own connection makes 11.
    let v = connections_per_runtime(&s, 3);
    assert_eq!(v.iter().sum::<f64>(), 11.0, "{v:?}");
    assert!(spread(&v) <= 1.0, "{v:?}");
    open.truncate(4); // closes 6 connections, however they were spread
    let deadline = std::time::Instant::now() + std::time::Duration::from_secs(10);
    while connections_per_runtime(&s, 3).iter().sum::<f64>() != 5.0 {
        assert!(std::time::Instant::now() < deadline, "closed connections still counted");
        std::thread::sleep(std::time::Duration::from_millis(20));
    }
    open.extend(open_answered(&s, 8)); // 12 open, refilling the emptiest runtimes first
    let v = connections_per_runtime(&s, 3);
    assert_eq!(v.iter().sum::<f64>(), 13.0, "{v:?}");
    assert!(spread(&v) <= 1.0, "{v:?}");
    drop(open);
}

/// Every route refuses a query parameter it does not know with the same 400 naming it — the
/// single tile included — while the same request without it succeeds.
#[tokio::test]
async fn unknown_query_parameters_are_refused_on_every_route() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let b = mosaic(32, 8, 3);
    let id = put(&c, &s, &b).await;
    let t = format!("/api/v1/textures/{id}");
    let routes: Vec<(reqwest::Method, String, &str)> = vec![
        (reqwest::Method::GET, "/api/v1/textures".into(), ""),
        (reqwest::Method::POST, "/api/v1/textures".into(), ""),
        (reqwest::Method::GET, t.clone(), ""),
        (reqwest::Method::PATCH, t.clone(), ""),
        (reqwest::Method::GET, format!("{t}/encoding"), ""),
        (reqwest::Method::GET, format!("{t}/tiles"), "tiles=0/0/0&format=png&"),
        (reqwest::Method::GET, format!("{t}/tiles/0/0/0.png"), "frame=1&"),
        (reqwest::Method::GET, format!("{t}/region"), "level=0&x=0&y=0&w=8&h=8&"),
        (reqwest::Method::GET, format!("{t}/pages/0/0/0.ktx2"), "size=64&"),
        (reqwest::Method::GET, format!("{t}/mips.ktx2"), "level=2&"),
        (reqwest::Method::GET, "/healthz".into(), ""),
        (reqwest::Method::GET, "/readyz".into(), ""),
        (reqwest::Method::GET, "/metrics".into(), ""),
        (reqwest::Method::DELETE, t.clone(), ""),
    ];
    let send = |method: &reqwest::Method, url: String| {
        let req = c.request(method.clone(), url);
        match *method {
            reqwest::Method::POST => req.header("content-type", "application/octet-stream").body(b.to_bytes()),
            reqwest::Method::PATCH => req.json(&json!({"name": "renamed"})),
            _ => req,
        }
        .send()
    };
    for (method, path, known) in &routes {
        let r = send(method, s.url(&format!("{path}?{known}gutter=4"))).await.unwrap();
        assert_eq!(r.status(), 400, "{method} {path}");
        assert_eq!(r.headers()["content-type"], "application/json", "{method} {path}");
        let msg = r.json::<Value>().await.unwrap()["error"].as_str().unwrap().to_string();
        assert!(msg.starts_with("unknown query parameter `gutter`"), "{method} {path}: {msg}");
        let ok = send(method, s.url(&format!("{path}?{}", known.trim_end_matches('&')))).await.unwrap();
        assert!(ok.status().is_success(), "{method} {path} without the parameter: {}", ok.status());
    }
}

/// Requests are counted under the template of the route that matched; paths no route matches
/// share fixed labels, so a garbage path adds no series.
#[tokio::test]
async fn metrics_are_labelled_by_route_template() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(32, 8, 2)).await;
    let routes = |text: &str| {
        let mut set: Vec<String> = text
            .lines()
            .filter(|l| l.starts_with("vtex_http_requests_total{"))
            .filter_map(|l| l.split("route=\"").nth(1)?.split('"').next().map(str::to_string))
            .collect();
        set.sort();
        set.dedup();
        set
    };
    get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "png")).await;
    get_bytes(&c, &s.url(&format!("/api/v1/textures/{id}"))).await;
    get_bytes(&c, &s.url(&format!("/api/v1/textures/{id}/tiles?tiles=0/0/0&format=png"))).await;
    get_bytes(&c, &s.url("/no/such/file")).await;
    get_bytes(&c, &s.url("/api/v1/textures/a/b/c/d/e/f/g")).await;
    let before = metrics(&c, &s).await;
    assert_eq!(
        routes(&before),
        [
            "/api/v1/textures",
            "/api/v1/textures/{id}",
            "/api/v1/textures/{id}/tiles",
            "/api/v1/textures/{id}/tiles/{level}/{x}/{file}",
            "/api/{*rest}",
            "static",
        ]
    );
    let tile = ("route", "/api/v1/textures/{id}/tiles/{level}/{x}/{file}");
    assert_eq!(metric(&before, "vtex_http_requests_total", &[tile, ("status", "200")]), 1.0);
    assert_eq!(metric(&before, "vtex_http_request_duration_seconds_count", &[tile]), 1.0);
    for garbage in ["/other/garbage", "/api/v1/textures/x/y/z/1/2/3/4", "/api/v9", "/%ff%fe"] {
        get_bytes(&c, &s.url(garbage)).await;
    }
    let after = metrics(&c, &s).await;
    let mut want = routes(&before);
    want.push("/metrics".into());
    want.sort();
    assert_eq!(routes(&after), want, "garbage paths added no label");
}

/// The models' own work and caches reach `/metrics`: one cold tile of an order-independent
/// texture counts its pixels and every entry of its dependency cone, noise included (the paper's
/// computation ratio for an isolated 256² tile of the default five generations in four
/// subpasses: 2.92 through the synthesis cache, 3.10 without it, which computes the cone's
/// bounding rectangles; the noise is 0.03 of it); `--synth-cache-mb 0` keeps no cache and
/// serves the same bytes.
#[tokio::test]
async fn model_work_and_synthesis_cache_are_exported() {
    let bundle = vtex_synth::models::order_independent::demos().remove(0);
    let mut tiles = Vec::new();
    for budget in ["64", "0"] {
        let dir = tempdir();
        let s = Server::start(dir.path(), &["--synth-cache-mb", budget]);
        let c = client();
        let id = put(&c, &s, &bundle).await;
        let (status, _, body) = get_bytes(&c, &s.tile_url(&id, 0, 3, 5, "rgba")).await;
        assert_eq!(status, 200);
        tiles.push(body);
        let m = metrics(&c, &s).await;
        let oi = [("model", "order-independent")];
        let work = |kind: &str| metric(&m, "vtex_model_work_total", &[oi[0], ("kind", kind)]);
        assert_eq!(work("pixels_requested"), 65536.0, "{m}");
        let ratio = work("entries_computed") / work("pixels_requested");
        assert!((2.85..3.2).contains(&ratio), "computation ratio {ratio}");
        let noise = work("noise_entries") / work("pixels_requested");
        assert!(noise > 0.0 && noise < 0.05, "noise entries a pixel {noise}, part of the ratio");
        let held = metric(&m, "vtex_model_cache_bytes", &oi);
        assert_eq!(metric(&m, "vtex_model_cache_budget_bytes", &[]), budget.parse::<f64>().unwrap() * 1048576.0);
        if budget == "0" {
            assert_eq!(held, 0.0);
        } else {
            assert!(held > 0.0, "a cold tile fills the synthesis cache");
        }
    }
    assert_eq!(tiles[0], tiles[1], "the synthesis cache never changes a tile");
}

/// An uploaded order-independent bundle's stored calibration is measured again where the
/// server accepts it (once, not on every open): a well-formed one that is not what the params
/// and sample give is a JSON 400 naming the section and the part, and nothing is stored; the
/// genuine one is stored, and so is a bundle stored before the section existed.
#[tokio::test]
async fn an_upload_with_a_crafted_calibration_is_refused() {
    use vtex_synth::models::{self, order_independent};
    let ex = models::get(order_independent::MODEL).unwrap().example();
    let bundle = models::create(order_independent::MODEL, "oi", &ex.params, &ex.inputs()).unwrap();
    let section = |b: &vtex_synth::bundle::Bundle| b.section("calibration.bin").unwrap().to_vec();
    let mut crafted = bundle.clone();
    crafted.sections.retain(|s| s.name != "calibration.bin");
    let old = crafted.clone();
    let mut cal = section(&bundle);
    cal[1] ^= 0x20; // the mean's red: well-formed, so every open would take it
    crafted = crafted.with_section("calibration.bin", cal);
    vtex_synth::models::load(&crafted).expect("well-formed");

    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (status, body) = upload(&c, &s, crafted.to_bytes()).await;
    assert_eq!(status, 400, "{body}");
    let why = body["error"].as_str().unwrap();
    assert!(why.contains("section `calibration.bin`: the mean is not what the params and sample give"), "{why}");
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    assert_eq!(list["textures"].as_array().unwrap().len(), 0, "{list}");
    let (status, body) = upload(&c, &s, bundle.to_bytes()).await;
    assert_eq!(status, 201, "{body}");
    let (status, body) = upload(&c, &s, old.to_bytes()).await;
    assert_eq!(status, 201, "{body}");
}
