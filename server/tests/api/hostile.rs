//! Invariant 6: bad input never crashes and never corrupts. Each case gets a 4xx JSON error
//! naming the problem, the server keeps serving, and the store is unchanged.

use crate::support::*;
use serde_json::{json, Value};
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// The server still answers, and the store holds exactly `files`.
async fn still_fine(s: &Server, files: &[String]) {
    let c = client();
    assert_eq!(c.get(s.url("/healthz")).send().await.unwrap().status(), 200);
    assert_eq!(store_files(&s.data_dir), files, "the store changed");
}

async fn refused_upload(s: &Server, bytes: Vec<u8>, needle: &str) {
    let (status, body) = upload(&client(), s, bytes).await;
    assert_eq!(status, 400, "{body}");
    let msg = body["error"].as_str().unwrap();
    assert!(msg.contains(needle), "expected `{needle}` in: {msg}");
}

async fn refused_multipart(s: &Server, form: reqwest::multipart::Form, status: u16, needle: &str) {
    let r = client().post(s.url("/api/v1/textures")).multipart(form).send().await.unwrap();
    assert_eq!(r.status().as_u16(), status);
    let body: Value = r.json().await.unwrap();
    let msg = body["error"].as_str().unwrap();
    assert!(msg.contains(needle), "expected `{needle}` in: {msg}");
}

fn form_with_sample(sample: Vec<u8>, params: &str) -> reqwest::multipart::Form {
    reqwest::multipart::Form::new()
        .text("model", "chaos-mosaic")
        .text("name", "hostile")
        .text("params", params.to_string())
        .part("sample", reqwest::multipart::Part::bytes(sample).file_name("s.png"))
}

const PARAMS: &str = r#"{"tiles_x":8,"tiles_y":8,"iterations":10,"seed":1}"#;

#[tokio::test]
async fn malformed_bundles() {
    let dir = tempdir();
    let (s, _, files) = with_one_texture(Server::start(dir.path(), &[])).await;
    refused_upload(&s, b"definitely not a bundle".to_vec(), "bad magic").await;
    refused_upload(&s, Vec::new(), "truncated").await;
    let good = mosaic(32, 8, 2).to_bytes();
    let mut garbage_tail = good.clone();
    garbage_tail.extend_from_slice(b"xx");
    refused_upload(&s, garbage_tail, "unexpected bytes").await;
    let mut lying = good.clone();
    lying[12..16].copy_from_slice(&u32::MAX.to_le_bytes()); // manifest length
    refused_upload(&s, lying, "manifest").await;
    let mut unknown = mosaic(32, 8, 2);
    unknown.manifest.model = "no-such-model".into();
    refused_upload(&s, unknown.to_bytes(), "unknown model `no-such-model`").await;
    let mut bad_params = mosaic(32, 8, 2);
    bad_params.manifest.params["tiles_x"] = json!(0);
    refused_upload(&s, bad_params.to_bytes(), "tiles_x").await;
    let mut no_sample = mosaic(32, 8, 2);
    no_sample.sections.clear();
    refused_upload(&s, no_sample.to_bytes(), "section").await;
    still_fine(&s, &files).await;
}

#[tokio::test]
async fn truncated_bundles() {
    let dir = tempdir();
    let (s, _, files) = with_one_texture(Server::start(dir.path(), &[])).await;
    let good = mosaic(32, 8, 3).to_bytes();
    for cut in [1, 8, 11, 20, good.len() / 2, good.len() - 1] {
        refused_upload(&s, good[..cut].to_vec(), "truncated").await;
    }
    still_fine(&s, &files).await;
}

/// The PNG with its IHDR width rewritten to 100000 and the chunk CRC fixed, so only the
/// declared size is wrong.
fn lie_about_width(png: &[u8]) -> Vec<u8> {
    let mut out = png.to_vec();
    out[16..20].copy_from_slice(&100_000u32.to_be_bytes());
    let crc = crc32fast::hash(&out[12..29]); // chunk type + 13 bytes of IHDR data
    out[29..33].copy_from_slice(&crc.to_be_bytes());
    out
}

#[tokio::test]
async fn truncated_and_lying_png_samples() {
    let dir = tempdir();
    let (s, _, files) = with_one_texture(Server::start(dir.path(), &[])).await;
    let png = sample_png(64, 4);
    refused_multipart(&s, form_with_sample(png[..png.len() / 2].to_vec(), PARAMS), 400, "sample").await;
    refused_multipart(&s, form_with_sample(png[..30].to_vec(), PARAMS), 400, "sample").await;
    refused_multipart(&s, form_with_sample(b"GIF89a....".to_vec(), PARAMS), 400, "not a PNG").await;
    refused_multipart(&s, form_with_sample(lie_about_width(&png), PARAMS), 400, "100000").await;
    // The same lie inside a bundle's sample section.
    let mut b = mosaic(32, 8, 4);
    let sec = b.sections.iter_mut().find(|s| s.data.starts_with(b"\x89PNG")).expect("a PNG section");
    sec.data = lie_about_width(&sec.data);
    refused_upload(&s, b.to_bytes(), "100000").await;
    // A missing sample.
    let form = reqwest::multipart::Form::new().text("model", "chaos-mosaic").text("params", PARAMS);
    refused_multipart(&s, form, 400, "sample").await;
    still_fine(&s, &files).await;
}

#[tokio::test]
async fn decompression_bombs_and_absurd_dimensions() {
    let dir = tempdir();
    let (s, _, files) = with_one_texture(Server::start(dir.path(), &[])).await;
    // A real bomb: a valid 1-bit PNG of 16384² pixels that is a few tens of KiB on the wire
    // and 1 GiB once decoded to RGBA8. Refused from its header, before any pixel memory.
    let bomb = {
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, 16384, 16384);
        enc.set_color(png::ColorType::Grayscale);
        enc.set_depth(png::BitDepth::One);
        enc.set_compression(png::Compression::Fast);
        let mut w = enc.write_header().unwrap();
        w.write_image_data(&vec![0u8; 16384 * 16384 / 8]).unwrap();
        w.finish().unwrap();
        out
    };
    assert!(bomb.len() < 1 << 20, "bomb is {} bytes", bomb.len());
    refused_multipart(&s, form_with_sample(bomb.clone(), PARAMS), 400, "16384×16384").await;
    let mut b = mosaic(32, 8, 5);
    let sec = b.sections.iter_mut().find(|s| s.data.starts_with(b"\x89PNG")).expect("a PNG section");
    sec.data = bomb;
    refused_upload(&s, b.to_bytes(), "16384×16384").await;
    // Absurd declared sizes in the parameters.
    let absurd = r#"{"tiles_x":100000,"tiles_y":100000,"seed":1}"#;
    refused_multipart(&s, form_with_sample(sample_png(64, 5), absurd), 400, "tiles").await;
    let zero = r#"{"tiles_x":0,"tiles_y":1}"#;
    refused_multipart(&s, form_with_sample(sample_png(64, 5), zero), 400, "tiles_x").await;
    refused_multipart(&s, form_with_sample(sample_png(64, 5), "{not json"), 400, "params").await;
    let form = reqwest::multipart::Form::new().text("name", "x");
    refused_multipart(&s, form, 400, "missing multipart field `model`").await;
    still_fine(&s, &files).await;
}

#[tokio::test]
async fn bad_coordinates_formats_and_levels() {
    let dir = tempdir();
    let (s, id, files) = with_one_texture(Server::start(dir.path(), &[])).await; // 256²: one level, one tile
    let c = client();
    let t = |rest: &str| s.url(&format!("/api/v1/textures/{id}/tiles/{rest}"));
    for (rest, status, needle) in [
        ("0/-1/0.png", 400, "`x` must not be negative"),
        ("0/0/-3.png", 400, "`y` must not be negative"),
        ("-1/0/0.png", 400, "`level` must not be negative"),
        ("0/99999999999999999999/0.png", 400, "`x` 99999999999999999999 is too large"),
        ("0/4294967296/0.png", 400, "too large"),
        ("abc/0/0.png", 400, "`level` must be an integer"),
        ("0/1.5/0.png", 400, "`x` must be an integer"),
        ("0/0/zz.png", 400, "`y` must be an integer"),
        ("0/0/0.gif", 400, "unknown format `gif`"),
        ("0/0/0", 400, "no format extension"),
        ("0/0/0.", 400, "unknown format ``"),
        ("1/0/0.png", 400, "level 1 does not exist"),
        ("4294967295/0/0.png", 400, "does not exist"),
        ("0/1/0.png", 404, "outside level 0"),
        ("0/0/4294967295.png", 404, "outside level 0"),
        ("0/0/0.png?frame=-1", 400, "`frame` must not be negative"),
        ("0/0/0.png?frame=x", 400, "`frame` must be an integer"),
    ] {
        let msg = expect_error(&c, &t(rest), status).await;
        assert!(msg.contains(needle), "{rest}: expected `{needle}` in `{msg}`");
    }
    still_fine(&s, &files).await;
}

#[tokio::test]
async fn path_traversal_and_malformed_ids() {
    let dir = tempdir();
    let (s, id, files) = with_one_texture(Server::start(dir.path(), &[])).await;
    let c = client();
    // (`..` and `%2e%2e` as whole segments are normalised away by URL clients; they are
    // sent raw below.)
    for bad in [
        "..%2F..%2F..%2Fetc%2Fpasswd",
        "..%5C..%5Cwindows",
        "a%00b",
        &id.to_uppercase(),
        &id[..63],
        &format!("{id}0"),
        &format!("{}.vtex", &id),
    ] {
        for path in [
            format!("/api/v1/textures/{bad}"),
            format!("/api/v1/textures/{bad}/tiles/0/0/0.png"),
            format!("/api/v1/textures/{bad}/encoding"),
        ] {
            let msg = expect_error(&c, &s.url(&path), 400).await;
            assert!(msg.contains("invalid texture id"), "{path}: {msg}");
        }
    }
    let unknown = "0".repeat(64);
    let msg = expect_error(&c, &s.url(&format!("/api/v1/textures/{unknown}/tiles/0/0/0.png")), 404).await;
    assert!(msg.contains("no texture"), "{msg}");
    // Unnormalised dot segments sent raw: never a file outside the API.
    for raw_path in ["/api/v1/textures/../../../etc/passwd", "/api/v1/textures/%2e%2e/encoding"] {
        let req = format!("GET {raw_path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n");
        let resp = raw_request(&s.addr, req.as_bytes());
        assert!(resp.starts_with("HTTP/1.1 4"), "{raw_path}: {resp}");
        assert!(resp.contains("\"error\""), "{raw_path}: {resp}");
        assert!(!resp.contains("root:"), "{raw_path}");
    }
    still_fine(&s, &files).await;
}

#[tokio::test]
async fn oversized_uploads_get_413() {
    let dir = tempdir();
    let (s, _, files) = with_one_texture(Server::start(dir.path(), &["--max-upload-mb", "1"])).await;
    // Declared too large: refused from the header alone.
    let resp = raw_request(
        &s.addr,
        b"POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\nContent-Length: 2000000\r\nConnection: close\r\n\r\n",
    );
    assert!(resp.starts_with("HTTP/1.1 413"), "{resp}");
    assert!(resp.contains("limit of 1048576 bytes"), "{resp}");
    // A client waiting for `100 Continue` is refused without being asked for the body.
    let resp = raw_request(
        &s.addr,
        b"POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\nContent-Length: 2000000\r\nExpect: 100-continue\r\nConnection: close\r\n\r\n",
    );
    assert!(resp.starts_with("HTTP/1.1 413"), "{resp}");
    // Chunked, no length: refused once the limit is crossed.
    let mut stream = TcpStream::connect(&s.addr).unwrap();
    stream.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    stream
        .write_all(b"POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\nTransfer-Encoding: chunked\r\nConnection: close\r\n\r\n")
        .unwrap();
    let chunk = vec![b'a'; 64 * 1024];
    for _ in 0..20 {
        let head = format!("{:x}\r\n", chunk.len());
        if stream
            .write_all(head.as_bytes())
            .and_then(|_| stream.write_all(&chunk))
            .and_then(|_| stream.write_all(b"\r\n"))
            .is_err()
        {
            break;
        }
    }
    let _ = stream.write_all(b"0\r\n\r\n");
    let mut out = Vec::new();
    let _ = stream.read_to_end(&mut out);
    let resp = String::from_utf8_lossy(&out);
    assert!(resp.starts_with("HTTP/1.1 413"), "{resp}");
    assert!(resp.contains("\"error\""), "{resp}");
    // Multipart over the limit, from a client that sends all of it before reading the
    // response: it gets the 413, not a broken pipe (the server drains what it refuses).
    let big = vec![0u8; 1_200_000];
    refused_multipart(&s, form_with_sample(big, PARAMS), 413, "limit of 1048576 bytes").await;
    still_fine(&s, &files).await;
}

#[tokio::test]
async fn wrong_content_type_is_415() {
    let dir = tempdir();
    let (s, _, files) = with_one_texture(Server::start(dir.path(), &[])).await;
    let r =
        client().post(s.url("/api/v1/textures")).header("content-type", "text/plain").body("hi").send().await.unwrap();
    assert_eq!(r.status(), 415);
    let v: Value = r.json().await.unwrap();
    assert!(v["error"].as_str().unwrap().contains("multipart/form-data"));
    still_fine(&s, &files).await;
}

#[tokio::test]
async fn slow_clients_are_cut_off() {
    let dir = tempdir();
    let (s, _, files) =
        with_one_texture(Server::start(dir.path(), &["--header-timeout-secs", "1", "--request-timeout-secs", "1"]))
            .await;
    // Headers that never finish: the connection is closed after the header timeout.
    let mut slow_headers = TcpStream::connect(&s.addr).unwrap();
    slow_headers.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    slow_headers.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\nX-Slow: ").unwrap();
    // A body that never finishes: 408 with a JSON error after the request timeout.
    let mut slow_body = TcpStream::connect(&s.addr).unwrap();
    slow_body.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    slow_body
        .write_all(b"POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\nContent-Length: 1000\r\n\r\nVTEXBNDL")
        .unwrap();
    // Meanwhile other clients are served.
    still_fine(&s, &files).await;
    let t0 = std::time::Instant::now();
    let mut buf = Vec::new();
    let _ = slow_headers.read_to_end(&mut buf);
    assert!(t0.elapsed() < Duration::from_secs(15), "slow header connection was not closed");
    assert!(!String::from_utf8_lossy(&buf).contains("200 OK"));
    let mut buf = Vec::new();
    let _ = slow_body.read_to_end(&mut buf);
    let resp = String::from_utf8_lossy(&buf);
    assert!(resp.starts_with("HTTP/1.1 408"), "{resp}");
    assert!(resp.contains("slow client"), "{resp}");
    still_fine(&s, &files).await;
}
