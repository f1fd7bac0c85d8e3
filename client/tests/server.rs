//! vtex-client against a real `vtex serve` (the workspace's release or debug build of
//! `vtex-server`, built by the same `cargo test --workspace`), and against a scripted socket for
//! retries.

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpListener;
use std::path::PathBuf;
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::Duration;
use vtex_client::{Client, PageAddr, PageFormat, PageSpec, Retry};

/// `vtex serve` on a free port over a fresh data directory, killed when dropped.
struct Server {
    child: Child,
    base: String,
    _dir: tempfile::TempDir,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The `vtex` binary beside this test's own directory (`target/<profile>/`).
fn vtex_binary() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let bin = exe.parent().unwrap().parent().unwrap().join("vtex");
    assert!(bin.exists(), "{} is missing: build it with `cargo build -p vtex-server` (same profile)", bin.display());
    bin
}

fn serve() -> Server {
    let dir = tempfile::tempdir().unwrap();
    let mut child = Command::new(vtex_binary())
        .args(["serve", "--bind", "127.0.0.1:0", "--no-demos", "--data-dir"])
        .arg(dir.path())
        .stdout(Stdio::piped())
        .stderr(Stdio::null())
        .spawn()
        .unwrap();
    let mut line = String::new();
    BufReader::new(child.stdout.take().unwrap()).read_line(&mut line).unwrap();
    let base = line.trim().strip_prefix("vtex listening on ").expect("the listening line").to_string();
    Server { child, base, _dir: dir }
}

/// Uploads a 256² chaos mosaic torus; returns its id.
async fn upload(base: &str) -> String {
    let sample = vtex_synth::samples::pebbles(32, 12, 3, true);
    let inputs = vtex_synth::models::Inputs::from([("sample".to_string(), sample.to_png())]);
    let params = serde_json::json!({"tiles_x": 16, "tiles_y": 16, "iterations": 10, "seed": 3});
    let bundle = vtex_synth::models::create("chaos-mosaic", "client test", &params, &inputs).unwrap();
    let r = reqwest::Client::new()
        .post(format!("{base}/api/v1/textures"))
        .header("content-type", "application/octet-stream")
        .body(bundle.to_bytes())
        .send()
        .await
        .unwrap();
    assert!(r.status().is_success());
    r.json::<serde_json::Value>().await.unwrap()["id"].as_str().unwrap().to_string()
}

fn addrs(level: u32, n: u32) -> Vec<PageAddr> {
    (0..n * n).map(|i| PageAddr { level, x: i % n, y: i / n }).collect()
}

#[tokio::test]
async fn discovery_pages_alone_or_from_their_metatiles_and_the_cache() {
    let s = serve();
    let id = upload(&s.base).await;
    let client = Client::new(&s.base, 1 << 20);
    let textures = client.textures().await.unwrap();
    let t = textures.iter().find(|t| t.id == id).unwrap();
    assert_eq!((t.width, t.domain, vtex_client::page_levels(t)), (512, vtex_client::Domain::Torus, 10));
    assert_eq!(vtex_client::page_grid(t, 0, 64), (8, 8));
    let spec = PageSpec { size: 64, border: 4, format: PageFormat::Ktx2 { codec: "bc1", zstd: true } };
    // Pages of 64 come 8 × 8 a metatile: level 0 is one, and 40 of its 64 pages asked for
    // fetch it; 2 of level 1's pages and level 9's one page come alone.
    let level0 = addrs(0, 8);
    let (asked0, others) = level0.split_at(40);
    let alone =
        [PageAddr { level: 1, x: 3, y: 1 }, PageAddr { level: 1, x: 0, y: 0 }, PageAddr { level: 9, x: 0, y: 0 }];
    let want = [asked0, &alone].concat();
    let (pages, stats) = client.pages(&id, &want, &spec).await.unwrap();
    assert_eq!((stats.hits, stats.requested, stats.metatiles), (0, want.len(), 1));
    let http = reqwest::Client::new();
    let single = |a: PageAddr| {
        let url = client.page_url(&id, a, &spec);
        let http = http.clone();
        async move { http.get(url).send().await.unwrap().bytes().await.unwrap() }
    };
    for (a, p) in want.iter().zip(&pages) {
        assert_eq!(p.addr, *a, "pages come in the order asked");
        assert_eq!((p.width, p.height), (72, 72));
        assert_eq!(p.bytes, single(*a).await, "page {a:?}: the single page's bytes");
        assert_eq!(p.etag.is_some(), a.level > 0, "page {a:?}: a validator where it came alone");
    }
    let mut unused = 0;
    for &a in others {
        unused += single(a).await.len() as u64;
    }
    assert_eq!(stats.unused, unused, "level 0's pages not asked for");
    assert_eq!(stats.bytes, pages.iter().map(|p| p.bytes.len() as u64).sum::<u64>() + unused);
    assert_eq!(client.cached_pages(), want.len() + others.len());
    let (again, stats) = client.pages(&id, &[want.clone(), others.to_vec()].concat(), &spec).await.unwrap();
    assert_eq!(
        (stats.hits, stats.requested, stats.bytes),
        (want.len() + others.len(), 0, 0),
        "all from the client's cache"
    );
    assert!(again.iter().zip(&pages).all(|(a, b)| a.bytes == b.bytes));
    let m = client.page_metatile_url(&id, vtex_client::page_metatile(PageAddr { level: 2, x: 9, y: 17 }, 64), &spec);
    let path =
        format!("/api/v1/textures/{id}/page-metatiles/2/1/2.ktx2?size=64&border=4&codec=bc1&supercompression=zstd");
    assert!(m.ends_with(&path), "{m}");
    assert!(client.tile_url(&id, 0, 1, 2, "png").ends_with(&format!("/api/v1/textures/{id}/tiles/0/1/2.png")));
}

#[tokio::test]
async fn the_cache_is_bounded_in_bytes() {
    let s = serve();
    let id = upload(&s.base).await;
    let spec = PageSpec { size: 64, border: 0, format: PageFormat::Rgba };
    let budget = 3 * 64 * 64 * 4;
    let client = Client::new(&s.base, budget);
    let want = addrs(0, 4);
    let (_, stats) = client.pages(&id, &want, &spec).await.unwrap();
    assert_eq!(stats.requested, 16);
    assert_eq!((client.cached_pages(), client.cached_bytes()), (3, budget));
    let (_, stats) = client.pages(&id, &want[13..], &spec).await.unwrap();
    assert_eq!(stats.hits, 3, "the last three pages stayed");
}

#[tokio::test]
async fn revalidation_keeps_the_held_page_on_304() {
    let s = serve();
    let id = upload(&s.base).await;
    let client = Client::new(&s.base, 1 << 20);
    let spec = PageSpec::default();
    let a = PageAddr { level: 1, x: 0, y: 0 };
    let (first, not_modified) = client.revalidate(&id, a, &spec).await.unwrap();
    assert!(!not_modified);
    assert!(first.etag.is_some());
    assert_eq!(&first.bytes[..12], &[0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A]);
    let (second, not_modified) = client.revalidate(&id, a, &spec).await.unwrap();
    assert!(not_modified, "the server answered 304");
    assert_eq!(second.bytes, first.bytes);
}

/// A socket that answers its first `failures` requests with `status` (Retry-After: 0), then a
/// page; counts the requests.
fn scripted(failures: usize, status: u16) -> (String, Arc<AtomicUsize>) {
    let listener = TcpListener::bind("127.0.0.1:0").unwrap();
    let base = format!("http://{}", listener.local_addr().unwrap());
    let count = Arc::new(AtomicUsize::new(0));
    let seen = count.clone();
    std::thread::spawn(move || {
        for stream in listener.incoming() {
            let mut stream = stream.unwrap();
            let mut head = Vec::new();
            let mut byte = [0u8];
            while !head.ends_with(b"\r\n\r\n") && stream.read(&mut byte).unwrap() == 1 {
                head.push(byte[0]);
            }
            let n = seen.fetch_add(1, Ordering::SeqCst);
            let response = if n < failures {
                let body = br#"{"error":"try later"}"#;
                let mut r = format!(
                    "HTTP/1.1 {status} X\r\nretry-after: 0\r\ncontent-length: {}\r\nconnection: close\r\n\r\n",
                    body.len()
                )
                .into_bytes();
                r.extend_from_slice(body);
                r
            } else {
                let page = [1u8, 2, 3, 4];
                let head = "HTTP/1.1 200 OK\r\nx-vtex-width: 1\r\nx-vtex-height: 1\r\ncontent-length: 4\r\nconnection: close\r\n\r\n";
                [head.as_bytes(), &page].concat()
            };
            let _ = stream.write_all(&response);
        }
    });
    (base, count)
}

#[tokio::test]
async fn retries_back_off_on_503_and_never_on_404() {
    let retry = Retry { attempts: 4, first_delay: Duration::from_millis(5), max_delay: Duration::from_millis(20) };
    let spec = PageSpec { size: 64, border: 0, format: PageFormat::Rgba };
    let one = [PageAddr { level: 0, x: 0, y: 0 }];
    let (base, count) = scripted(2, 503);
    let (pages, _) = Client::new(&base, 1 << 20).with_retry(retry).pages("t", &one, &spec).await.unwrap();
    assert_eq!((count.load(Ordering::SeqCst), &pages[0].bytes[..]), (3, &[1u8, 2, 3, 4][..]));
    let (base, count) = scripted(10, 503);
    let err = Client::new(&base, 1 << 20).with_retry(retry).pages("t", &one, &spec).await.unwrap_err();
    assert_eq!(count.load(Ordering::SeqCst), 4, "attempts run out: {err}");
    let (base, count) = scripted(10, 404);
    let err = Client::new(&base, 1 << 20).with_retry(retry).pages("t", &one, &spec).await.unwrap_err();
    assert_eq!(count.load(Ordering::SeqCst), 1, "a 404 is not retried: {err}");
    assert!(err.to_string().contains("404: try later"), "{err}");
}
