//! The batched tile endpoint over a real socket: every frame carries exactly the single-tile
//! endpoint's bytes, hits come first and misses as they finish, bad requests are 400/404 JSON
//! errors naming the problem, metrics count it, and a client that goes away stops the work.

use crate::support::*;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::Duration;

/// One frame of a batch body, parsed here independently of the server's code.
#[derive(Debug)]
pub(crate) struct Frame {
    pub level: u32,
    pub x: u32,
    pub y: u32,
    pub status: u16,
    pub cache: u8,
    pub width: u32,
    pub height: u32,
    pub body: Vec<u8>,
}

pub(crate) fn frames(mut b: &[u8]) -> Vec<Frame> {
    let mut out = Vec::new();
    let u32_at = |b: &[u8], i: usize| u32::from_le_bytes(b[i..i + 4].try_into().unwrap());
    while !b.is_empty() {
        assert!(b.len() >= 32, "a truncated header");
        assert_eq!(&b[..4], b"vtb\x01", "magic and version");
        assert_eq!(b[19], 0, "reserved byte");
        let len = u32_at(b, 28) as usize;
        out.push(Frame {
            level: u32_at(b, 4),
            x: u32_at(b, 8),
            y: u32_at(b, 12),
            status: u16::from_le_bytes([b[16], b[17]]),
            cache: b[18],
            width: u32_at(b, 20),
            height: u32_at(b, 24),
            body: b[32..32 + len].to_vec(),
        });
        b = &b[32 + len..];
    }
    out
}

fn batch_url(s: &Server, id: &str, query: &str) -> String {
    s.url(&format!("/api/v1/textures/{id}/tiles?{query}"))
}

/// Batches timed to their end with this `outcome`, once the count reaches `want` (a body is
/// timed when the connection drops it, just after its last bytes went out) or 5 s passed.
async fn batches_timed(c: &reqwest::Client, s: &Server, outcome: &str, want: f64) -> f64 {
    let mut seen = 0.0;
    for _ in 0..50 {
        seen = metric(&metrics(c, s).await, "vtex_tile_batch_seconds_count", &[("outcome", outcome)]);
        if seen >= want {
            break;
        }
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
    seen
}

#[tokio::test]
async fn frames_equal_single_tiles_hits_first() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    // 1200² (edge tiles clipped to 176 px), 4 served levels.
    let id = put(&c, &s, &mosaic(30, 40, 4)).await;
    // Warm two tiles through the single-tile endpoint first.
    for (l, x, y) in [(0, 1, 1), (2, 0, 0)] {
        assert_eq!(get_bytes(&c, &s.tile_url(&id, l, x, y, "rgba")).await.0, 200);
    }
    let list = [(0, 4, 2), (0, 1, 1), (1, 2, 2), (3, 0, 0), (2, 0, 0), (0, 4, 4), (1, 0, 1)];
    let q: Vec<String> = list.iter().map(|(l, x, y)| format!("{l}/{x}/{y}")).collect();
    for fmt in ["rgba", "png"] {
        let (status, h, body) =
            get_bytes(&c, &batch_url(&s, &id, &format!("format={fmt}&tiles={}", q.join(",")))).await;
        assert_eq!(status, 200);
        assert_eq!(h["content-type"], "application/x-vtex-tile-batch");
        assert_eq!(h["cache-control"], "no-store", "a batch with misses");
        assert_eq!(h["access-control-allow-origin"], "*");
        let got = frames(&body);
        assert_eq!(got.len(), list.len(), "one frame per tile");
        let mut seen: Vec<(u32, u32, u32)> = got.iter().map(|f| (f.level, f.x, f.y)).collect();
        seen.sort();
        let mut want = list.to_vec();
        want.sort();
        assert_eq!(seen, want, "every tile exactly once");
        if fmt == "rgba" {
            // The two cached tiles come first, in list order; the rest are misses.
            let order: Vec<_> = got.iter().map(|f| ((f.level, f.x, f.y), f.cache)).collect();
            assert_eq!(&order[..2], &[((0, 1, 1), 1), ((2, 0, 0), 1)]);
            assert!(got[2..].iter().all(|f| f.cache == 2), "{order:?}");
        } else {
            assert!(got.iter().all(|f| f.cache == 2), "png tiles were never made");
        }
        for f in &got {
            assert_eq!(f.status, 200);
            let (st, h, single) = get_bytes(&c, &s.tile_url(&id, f.level, f.x, f.y, fmt)).await;
            assert_eq!(st, 200);
            assert_eq!(h["x-vtex-cache"], "hit", "the batch filled the same cache");
            assert_eq!(f.body, single, "{fmt} {}/{}/{} equals the single tile", f.level, f.x, f.y);
            let w: u32 = h["x-vtex-width"].to_str().unwrap().parse().unwrap();
            let hh: u32 = h["x-vtex-height"].to_str().unwrap().parse().unwrap();
            assert_eq!((f.width, f.height), (w, hh));
        }
        let edge = got.iter().find(|f| (f.level, f.x, f.y) == (0, 4, 4)).unwrap();
        assert_eq!((edge.width, edge.height), (176, 176));
        assert_eq!(got.iter().find(|f| f.level == 3).map(|f| (f.width, f.height)), Some((150, 150)));
        // Asked again: every tile is a hit, in list order.
        let (_, _, again) = get_bytes(&c, &batch_url(&s, &id, &format!("tiles={}&format={fmt}", q.join(",")))).await;
        let again = frames(&again);
        let order: Vec<_> = again.iter().map(|f| (f.level, f.x, f.y)).collect();
        assert_eq!(order, list.to_vec());
        assert!(again.iter().all(|f| f.cache == 1));
    }
    let m = metrics(&c, &s).await;
    assert_eq!(
        metric(&m, "vtex_http_requests_total", &[("route", "/api/v1/textures/{id}/tiles"), ("status", "200")]),
        4.0
    );
    assert_eq!(batches_timed(&c, &s, "complete", 4.0).await, 4.0, "each batch timed to its end");
    // 7 tiles × 2 formats × 2 batches + 2 warming + 14 single checks + 2 more per format (= 7 checks each)
    let hits = metric(&m, "vtex_tile_cache_hits_total", &[]);
    let misses = metric(&m, "vtex_tile_cache_misses_total", &[]);
    assert_eq!(misses, 2.0 + 5.0 + 7.0, "misses: 2 warming, 5 rgba, 7 png");
    assert_eq!(hits, 2.0 + 14.0 + 14.0, "hits: 2 in the first rgba batch, 14 single checks, 14 in the repeats");
    // Animated frames are part of the key; a still texture ignores `frame`.
    let (st, _, body) = get_bytes(&c, &batch_url(&s, &id, "tiles=3/0/0&format=rgba&frame=7")).await;
    assert_eq!((st, frames(&body)[0].cache), (200, 1));
}

#[tokio::test]
async fn bad_batches_are_refused_naming_the_problem() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(30, 40, 4)).await; // 5×5 tiles at level 0, levels 0..=3
    let many = (0..257).map(|i| format!("0/{}/{}", i % 5, i / 5)).collect::<Vec<_>>().join(",");
    let long = format!("format=rgba&tiles={}", "0/0/0,".repeat(1500));
    let cases: Vec<(String, u16, &str)> = vec![
        ("format=rgba".into(), 400, "a batch takes exactly one of `tiles` and `pages`"),
        ("tiles=0/0/0".into(), 400, "missing query parameter `format`"),
        ("tiles=0/0/0&format=gif".into(), 400, "unknown format `gif`"),
        ("tiles=&format=rgba".into(), 400, "`tiles` is empty"),
        ("tiles=0/0&format=rgba".into(), 400, "`tiles` item 1 is `0/0`"),
        ("tiles=0/0/0,,1/0/0&format=rgba".into(), 400, "`tiles` item 2"),
        ("tiles=0/a/0&format=rgba".into(), 400, "item 1: `x` must be an integer"),
        ("tiles=0/0/0,1/1/1,0/0/0&format=rgba".into(), 400, "lists tile 0/0/0 twice"),
        (format!("tiles={many}&format=rgba"), 400, "at most 256"),
        (long, 400, "longer than the limit"),
        ("tiles=0/0/0&format=rgba&level=2".into(), 400, "unknown query parameter `level`"),
        ("tiles=0/0/0&tiles=0/1/0&format=rgba".into(), 400, "query parameter `tiles` is repeated"),
        ("tiles=0/0/0&format=rgba&frame=-1".into(), 400, "negative"),
        ("tiles=0/0/0,4/0/0&format=rgba".into(), 400, "level 4 does not exist"),
        ("tiles=0/0/0,1/3/0&format=rgba".into(), 404, "tile 1/3/0 is outside level 1"),
    ];
    for (query, status, needle) in cases {
        let msg = expect_error(&c, &batch_url(&s, &id, &query), status).await;
        assert!(msg.contains(needle), "{query}: expected `{needle}` in: {msg}");
        assert!(msg.len() < 300, "the error does not echo the request: {}", msg.len());
    }
    let unknown = "ab".repeat(32);
    assert!(expect_error(&c, &batch_url(&s, &unknown, "tiles=0/0/0&format=rgba"), 404).await.contains("no texture"));
    assert!(expect_error(&c, &batch_url(&s, "nope", "tiles=0/0/0&format=rgba"), 400)
        .await
        .contains("invalid texture id"));
    // Nothing was synthesized for a refused batch.
    let m = metrics(&c, &s).await;
    assert_eq!(metric(&m, "vtex_syntheses_total", &[]), 0.0);
    assert_eq!(
        metric(&m, "vtex_http_requests_total", &[("route", "/api/v1/textures/{id}/tiles"), ("status", "400")]),
        15.0
    );
}

/// A client that reads one frame and hangs up: the tiles not yet started are never made.
#[tokio::test]
async fn a_client_going_away_stops_the_batch() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--max-syntheses", "1"]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 100, 5)).await; // 6400²: 25×25 tiles at level 0
    let list = (0..256).map(|i| format!("0/{}/{}", i % 25, i / 25)).collect::<Vec<_>>().join(",");
    let mut sock = TcpStream::connect(&s.addr).unwrap();
    sock.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    write!(sock, "GET /api/v1/textures/{id}/tiles?format=png&tiles={list} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let mut got = Vec::new();
    let mut buf = [0u8; 4096];
    // Headers, then at least one frame's header (chunked: the magic appears in the body).
    while !got.windows(4).any(|w| w == b"vtb\x01") {
        let n = sock.read(&mut buf).unwrap();
        assert!(n > 0, "connection closed early: {}", String::from_utf8_lossy(&got));
        got.extend_from_slice(&buf[..n]);
    }
    assert!(got.starts_with(b"HTTP/1.1 200"));
    drop(sock);
    // Let the server notice (its next write fails), then the count must stand still.
    let count = || async { metric(&metrics(&c, &s).await, "vtex_syntheses_total", &[]) };
    tokio::time::sleep(Duration::from_millis(1500)).await;
    let a = count().await;
    tokio::time::sleep(Duration::from_millis(1000)).await;
    let b = count().await;
    assert_eq!(a, b, "syntheses stopped");
    assert!(a < 64.0, "{a} of 256 tiles were made after the client left");
    assert_eq!(metric(&metrics(&c, &s).await, "vtex_syntheses_in_flight", &[]), 0.0);
    assert_eq!(batches_timed(&c, &s, "dropped", 1.0).await, 1.0, "the batch is timed as dropped");
    assert_eq!(batches_timed(&c, &s, "complete", 0.0).await, 0.0);
}

/// Batches dropped while their tiles render never let more syntheses run than permits: a
/// permit is held by the render itself, not by the request that asked for it.
#[tokio::test]
async fn aborted_batches_keep_the_synthesis_bound() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--max-syntheses", "1"]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 100, 6)).await;
    let most = std::sync::Arc::new(std::sync::atomic::AtomicU64::new(0));
    let watch = {
        let (c, url, most) = (c.clone(), s.url("/metrics"), most.clone());
        tokio::spawn(async move {
            loop {
                let text = c.get(&url).send().await.unwrap().text().await.unwrap();
                let n = metric(&text, "vtex_syntheses_in_flight", &[]) as u64;
                most.fetch_max(n, std::sync::atomic::Ordering::SeqCst);
            }
        })
    };
    for round in 0..12u32 {
        // Each batch is dropped while a tile of it renders (PNG: render + encode, several ms).
        let list = (0..8).map(|i| format!("0/{}/{}", (round * 8 + i) % 25, (round * 8 + i) / 25)).collect::<Vec<_>>();
        let url = s.url(&format!("/api/v1/textures/{id}/tiles?format=png&tiles={}", list.join(",")));
        let _ = tokio::time::timeout(Duration::from_millis(3), c.get(&url).send()).await;
    }
    tokio::time::sleep(Duration::from_millis(500)).await;
    watch.abort();
    assert!(metric(&metrics(&c, &s).await, "vtex_syntheses_total", &[]) >= 1.0);
    // (Before permits were held by the render, this saw 4 with one permit.)
    let most = most.load(std::sync::atomic::Ordering::SeqCst);
    assert!(most <= 1, "{most} renders at once with --max-syntheses 1");
}

/// A batch not finished by the request deadline is cut off: the client sees a truncated body
/// (never a complete-looking one), the metrics time it as a timeout, and the server serves on.
#[tokio::test]
async fn a_batch_past_the_deadline_is_cut_off() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--max-syntheses", "1", "--request-timeout-secs", "0.1"]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 100, 5)).await; // 6400²: 25×25 tiles at level 0
    let list = (0..256).map(|i| format!("0/{}/{}", i % 25, i / 25)).collect::<Vec<_>>().join(",");
    let resp = c.get(batch_url(&s, &id, &format!("tiles={list}&format=png"))).send().await.unwrap();
    assert_eq!(resp.status(), 200);
    assert!(resp.bytes().await.is_err(), "the body ends in an error, not a short but well-formed stream");
    assert_eq!(batches_timed(&c, &s, "timeout", 1.0).await, 1.0);
    let (st, _, body) = get_bytes(&c, &batch_url(&s, &id, "tiles=0/0/0&format=rgba")).await;
    assert_eq!((st, frames(&body).len()), (200, 1), "the server serves on");
}

/// A batch of tiles all in the cache is as immutable as its tiles: cacheable by a proxy, with
/// a weak ETag naming its texture, list, format and frame, answered 304 on revalidation. A
/// batch with a miss is not (a render may still fail into an error frame).
#[tokio::test]
async fn batches_of_cached_tiles_are_cacheable() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(30, 40, 5)).await;
    let url = batch_url(&s, &id, "format=png&tiles=0/1/1,1/0/1,2/0/0");
    let (status, cold, _) = get_bytes(&c, &url).await;
    assert_eq!(status, 200);
    assert_eq!(cold["cache-control"], "no-store", "a batch with misses");
    assert!(cold.get("etag").is_none());
    let (status, warm, body) = get_bytes(&c, &url).await;
    assert_eq!(status, 200);
    assert_eq!(warm["cache-control"], "public, max-age=31536000, immutable");
    let etag = warm["etag"].to_str().unwrap().to_string();
    assert!(etag.starts_with("W/\""), "{etag}");
    assert!(frames(&body).iter().all(|f| f.status == 200 && f.cache == 1));
    let r = c.get(&url).header("if-none-match", &etag).send().await.unwrap();
    assert_eq!(r.status(), 304);
    assert_eq!(r.headers()["etag"].to_str().unwrap(), etag);
    // Another list, format or order is another batch.
    for other in ["format=png&tiles=1/0/1,0/1/1,2/0/0", "format=rgba&tiles=0/1/1,1/0/1,2/0/0"] {
        let r = c.get(batch_url(&s, &id, other)).header("if-none-match", &etag).send().await.unwrap();
        assert_eq!(r.status(), 200, "{other}");
    }
}

/// The golden files of `wire/fixtures`, which the Rust client's and the viewer's tests read: a
/// real batch body (two hits, then a miss: a deterministic order) with the frames it holds, and
/// the info of its texture. A change of the frame format or the info fails here first;
/// `VTEX_BLESS=1` writes the files again, and then the readers' tests must agree with them.
#[tokio::test]
async fn the_golden_batch_and_info_are_what_the_server_sends() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--tile-size", "16"]);
    let c = client();
    let id = put(&c, &s, &mosaic(16, 4, 7)).await;
    for (x, y) in [(0, 0), (3, 2)] {
        assert_eq!(get_bytes(&c, &s.tile_url(&id, 0, x, y, "rgba")).await.0, 200);
    }
    let (status, headers, batch) = get_bytes(&c, &batch_url(&s, &id, "format=rgba&tiles=0/0/0,0/1/1,0/3/2")).await;
    assert_eq!((status, &headers["content-type"]), (200, &"application/x-vtex-tile-batch".parse().unwrap()));
    let expected: Vec<serde_json::Value> = {
        let mut at = 0;
        frames(&batch)
            .iter()
            .map(|f| {
                at += 32;
                let entry = serde_json::json!({
                    "level": f.level, "x": f.x, "y": f.y, "status": f.status, "cache": f.cache,
                    "width": f.width, "height": f.height, "body_offset": at, "body_length": f.body.len(),
                });
                at += f.body.len();
                entry
            })
            .collect()
    };
    let caches: Vec<u64> = expected.iter().map(|f| f["cache"].as_u64().unwrap()).collect();
    assert_eq!(caches, [1, 1, 2], "two hits in the order asked, then the miss");
    let info: serde_json::Value =
        c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
    let fixtures = std::path::Path::new(env!("CARGO_MANIFEST_DIR")).join("../wire/fixtures");
    let golden = [
        ("batch.bin", batch),
        ("batch.json", serde_json::to_vec_pretty(&expected).unwrap()),
        ("texture-info.json", serde_json::to_vec_pretty(&info).unwrap()),
    ];
    for (name, bytes) in golden {
        let path = fixtures.join(name);
        if std::env::var_os("VTEX_BLESS").is_some() {
            std::fs::write(&path, &bytes).unwrap();
        }
        assert!(std::fs::read(&path).unwrap() == bytes, "{name} differs from what the server sends");
    }
}
