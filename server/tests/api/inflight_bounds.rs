//! Response bodies in flight are bounded, over real sockets: past
//! the in-flight budget a region is a clear 503 while cached tiles are still served, and a
//! reader slower than the minimum send rate is dropped; either way the reservations return
//! (the `vtex_inflight_bytes` gauge).

use crate::support::*;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

const MIB: f64 = 1024.0 * 1024.0;

/// One GET on a fresh connection; the whole response, bytes as sent.
fn get(addr: &str, path: &str) -> Vec<u8> {
    let mut c = TcpStream::connect(addr).unwrap();
    c.set_read_timeout(Some(Duration::from_secs(60))).unwrap();
    write!(c, "GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
    let mut out = Vec::new();
    c.read_to_end(&mut out).unwrap();
    out
}

/// The head and the body of a raw response.
fn split(resp: &[u8]) -> (String, &[u8]) {
    let end = resp.windows(4).position(|w| w == b"\r\n\r\n").expect("a response head") + 4;
    (String::from_utf8_lossy(&resp[..end]).to_ascii_lowercase(), &resp[end..])
}

fn status(head: &str) -> u16 {
    head.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or_else(|| panic!("no status in {head:?}"))
}

fn gauge(s: &Server, name: &str) -> f64 {
    let resp = get(&s.addr, "/metrics");
    metric(&String::from_utf8_lossy(split(&resp).1), name, &[])
}

/// Waits up to `limit` for `done`, polling; returns whether it happened.
fn eventually(limit: Duration, mut done: impl FnMut() -> bool) -> bool {
    let end = Instant::now() + limit;
    while Instant::now() < end {
        if done() {
            return true;
        }
        std::thread::sleep(Duration::from_millis(50));
    }
    done()
}

/// Uploads a small chaos mosaic over a raw connection; returns its id.
fn upload_mosaic(s: &Server) -> String {
    let bytes = mosaic(64, 8, 1).to_bytes();
    let mut req = format!(
        "POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n",
        bytes.len()
    )
    .into_bytes();
    req.extend_from_slice(&bytes);
    let resp = raw_request(&s.addr, &req);
    let (head, body) = split(resp.as_bytes());
    assert!(matches!(status(&head), 200 | 201), "{resp}");
    let info: serde_json::Value = serde_json::from_slice(body).unwrap();
    info["id"].as_str().unwrap().to_string()
}

/// A 2048² raw RGBA region: 16 MiB, which is what it reserves.
fn region_path(id: &str) -> String {
    format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=2048&h=2048&format=rgba")
}
const REGION_BYTES: usize = 2048 * 2048 * 4;

/// With a budget of 72 MiB, four clients that ask for a 16 MiB region and never read it hold
/// 64 MiB: the next region is a 503 with `Retry-After` and a JSON error naming the budget, while
/// a cached tile is still a 200. Once those clients are gone the gauge returns to 0 and regions
/// are served again.
#[test]
fn past_the_budget_regions_are_refused_while_cached_tiles_are_served() {
    let dir = tempdir();
    // A send timeout far longer than the test: only the budget can refuse the fifth region.
    let flags = ["--inflight-mb", "72", "--max-region-pixels", "4194304", "--send-timeout-secs", "600"];
    let s = Server::start(dir.path(), &flags);
    let id = upload_mosaic(&s);
    let tile = format!("/api/v1/textures/{id}/tiles/0/0/0.png");
    assert_eq!(status(&split(&get(&s.addr, &tile)).0), 200);
    assert_eq!(gauge(&s, "vtex_inflight_budget_bytes"), 72.0 * MIB);
    // Lossless WebP holds six times the pixels at its peak: 96 MiB, more than the whole budget.
    let webp = get(&s.addr, &region_path(&id).replace("format=rgba", "format=webp"));
    let (head, body) = split(&webp);
    assert_eq!(status(&head), 400, "{head}");
    let why: serde_json::Value = serde_json::from_slice(body).unwrap();
    assert!(why["error"].as_str().unwrap().contains("more than the whole budget"), "{why}");

    const HOLDERS: usize = 4;
    let request = format!("GET {} HTTP/1.1\r\nHost: x\r\n\r\n", region_path(&id));
    let holders: Vec<TcpStream> = (0..HOLDERS)
        .map(|_| {
            let mut c = TcpStream::connect(&s.addr).unwrap();
            c.write_all(request.as_bytes()).unwrap();
            c
        })
        .collect();
    let held = (HOLDERS * REGION_BYTES) as f64;
    let rendered = eventually(Duration::from_secs(120), || {
        gauge(&s, "vtex_inflight_bytes") == held && gauge(&s, "vtex_syntheses_in_flight") == 0.0
    });
    assert!(rendered, "the unread regions hold their bytes: {} MiB", gauge(&s, "vtex_inflight_bytes") / MIB);

    let refused = get(&s.addr, &region_path(&id));
    let (head, body) = split(&refused);
    assert_eq!(status(&head), 503, "{head}");
    assert!(head.contains("retry-after: 1\r\n") && head.contains("content-type: application/json\r\n"), "{head}");
    let why: serde_json::Value = serde_json::from_slice(body).unwrap();
    let why = why["error"].as_str().unwrap();
    assert!(why.contains("in flight") && why.contains("--inflight-mb, 72 MiB"), "{why}");

    let (head, _) = split(&get(&s.addr, &tile));
    assert_eq!(status(&head), 200, "a cached tile is served: {head}");
    assert!(head.contains("x-vtex-cache: hit"), "{head}");

    drop(holders);
    let freed = eventually(Duration::from_secs(20), || gauge(&s, "vtex_inflight_bytes") == 0.0);
    assert!(freed, "the reservations return: {} MiB still reserved", gauge(&s, "vtex_inflight_bytes") / MIB);
    let served = get(&s.addr, &region_path(&id));
    let (head, body) = split(&served);
    assert_eq!((status(&head), body.len()), (200, REGION_BYTES), "regions are served again");
    assert!(eventually(Duration::from_secs(10), || gauge(&s, "vtex_inflight_bytes") == 0.0), "a sent body frees it");
}

/// A client that reads a 64 MiB region at about 1 MiB/s is below a minimum rate of 4 MiB/s,
/// though the server's writes make progress every second or so (each time the reader has
/// drained a third of the kernel's send buffer), well within the send timeout of 4 s. The server
/// resets it within a few windows of 4 s, long before the body could arrive, and its
/// reservation returns.
#[tokio::test(flavor = "multi_thread", worker_threads = 2)]
async fn a_reader_below_the_minimum_send_rate_is_dropped_and_its_reservation_freed() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--send-timeout-secs", "4", "--min-send-rate", "4194304"]);
    let id = tokio::task::block_in_place(|| upload_mosaic(&s));
    let path = format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=4096&h=4096&format=rgba");
    const BODY: usize = 4096 * 4096 * 4;

    // A small receive buffer: what the reader has not taken stays in the server's socket.
    let socket = tokio::net::TcpSocket::new_v4().unwrap();
    socket.set_recv_buffer_size(256 * 1024).unwrap();
    let mut c = socket.connect(s.addr.parse().unwrap()).await.unwrap();
    c.write_all(format!("GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").as_bytes()).await.unwrap();
    // 128 KiB every 125 ms: 1 MiB/s.
    let mut step = vec![0u8; 128 * 1024];
    let mut got = 0;
    let mut first = None;
    let closed = loop {
        let read = tokio::time::timeout(Duration::from_secs(120), c.read_exact(&mut step)).await;
        match read.expect("the reader gets bytes or a close") {
            Ok(_) => got += step.len(),
            Err(_) => break first.map(|t: Instant| t.elapsed()),
        }
        let since = *first.get_or_insert_with(Instant::now);
        if since.elapsed() > Duration::from_secs(30) {
            break None;
        }
        tokio::time::sleep(Duration::from_millis(125)).await;
    };
    let closed =
        closed.unwrap_or_else(|| panic!("a reader at a quarter of the minimum rate is still served ({got} B)"));
    eprintln!("a reader at ~1 MiB/s was dropped {closed:?} after its first bytes, having read {got} of {BODY} B");
    assert!(got < BODY / 2, "dropped long before the body could arrive ({got} B)");
    let freed =
        tokio::task::block_in_place(|| eventually(Duration::from_secs(10), || gauge(&s, "vtex_inflight_bytes") == 0.0));
    assert!(freed, "its reservation returns");
}

/// An upload reserves its declared length in the budget before its body is read, and keeps it
/// until it is stored or abandoned: with 72 MiB, an upload of 40 MiB still arriving leaves no
/// room for a second one, which is a 503 naming the budget, while a small upload is stored; the
/// reservation returns when the first client goes.
#[test]
fn an_upload_reserves_its_body_in_the_budget_until_it_is_done() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--inflight-mb", "72", "--max-region-pixels", "4194304"]);
    let large = |addr: &str| {
        let mut c = TcpStream::connect(addr).unwrap();
        let head = "POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n\
                    Content-Length: 41943040\r\n\r\nVTEX";
        c.write_all(head.as_bytes()).unwrap();
        c
    };
    let first = large(&s.addr);
    let reserved = eventually(Duration::from_secs(10), || gauge(&s, "vtex_inflight_bytes") == 40.0 * MIB);
    assert!(reserved, "the upload reserves its length: {} MiB", gauge(&s, "vtex_inflight_bytes") / MIB);

    let mut second = large(&s.addr);
    second.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    let mut refused = Vec::new();
    let _ = second.read_to_end(&mut refused);
    let (head, body) = split(&refused);
    assert_eq!(status(&head), 503, "{head}");
    let why: serde_json::Value = serde_json::from_slice(body).unwrap();
    assert!(why["error"].as_str().unwrap().contains("--inflight-mb, 72 MiB"), "{why}");

    upload_mosaic(&s);
    drop(first);
    let freed = eventually(Duration::from_secs(10), || gauge(&s, "vtex_inflight_bytes") == 0.0);
    assert!(freed, "the reservation returns: {} MiB still reserved", gauge(&s, "vtex_inflight_bytes") / MIB);
}
