//! vtex-client over HTTPS with HTTP/2: a real `vtex serve` behind Debian's nginx terminating TLS
//! with a certificate of a CA made for the test (`openssl`), as a game ships its CA. nginx's
//! access log (port, protocol, status of each request) tells what went over the wire.

mod common;

use common::{addrs, nginx, pki, scripted_after, serve, upload, Nginx};
use std::collections::BTreeSet;
use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};
use vtex_client::{Client, Page, PageAddr, PageFormat, PageKey, PageLayer, PageSpec, Retry};

const SPEC: PageSpec =
    PageSpec { size: 64, border: 4, format: PageFormat::Ktx2 { codec: "bc1", zstd: true }, layer: PageLayer::Color };

fn quick() -> Retry {
    Retry { attempts: 3, first_delay: Duration::from_millis(5), max_delay: Duration::from_millis(20) }
}

/// A client of `base` trusting only the test's CA, with a disk cache in `disk` if given.
fn client(base: &str, ca: &[u8], disk: Option<&std::path::Path>) -> Client {
    let mut b = Client::builder(base).root_certificate_pem(ca).unwrap().system_roots(false).retry(quick());
    if let Some(dir) = disk {
        b = b.disk_cache(dir, 64 << 20);
    }
    b.build().unwrap()
}

/// 40 of level 0's 64 pages (one page metatile) and three pages alone.
fn wanted() -> Vec<PageAddr> {
    let alone =
        [PageAddr { level: 1, x: 3, y: 1 }, PageAddr { level: 1, x: 0, y: 0 }, PageAddr { level: 2, x: 1, y: 1 }];
    [&addrs(0, 8)[..40], &alone].concat()
}

/// The same pages over plain HTTP straight from vtex.
async fn plain(base: &str, id: &str, want: &[PageAddr]) -> Vec<Page> {
    Client::new(base, 64 << 20).pages(id, want, &SPEC).await.unwrap().0
}

fn assert_same(got: &[Page], want: &[Page]) {
    assert_eq!(got.len(), want.len());
    for (g, w) in got.iter().zip(want) {
        assert_eq!((g.addr, g.width, g.height), (w.addr, w.width, w.height));
        assert!(g.bytes == w.bytes, "page {:?}: not the plain HTTP bytes", g.addr);
    }
}

struct Setup {
    nginx: Nginx,
    ca: Vec<u8>,
    id: String,
    vtex: common::Server,
    _pki: common::Pki,
    scripted: std::sync::Arc<std::sync::atomic::AtomicUsize>,
}

async fn setup(scripted_failures: usize) -> Setup {
    let vtex = serve();
    let id = upload(&vtex.base).await;
    let (scripted_base, scripted) = scripted_after(scripted_failures, 503, 1);
    let pki = pki();
    let nginx = nginx(&vtex.base, &scripted_base, &pki);
    Setup { nginx, ca: pki.ca_pem(), id, vtex, _pki: pki, scripted }
}

#[tokio::test]
async fn https_over_http2_brings_the_plain_pages_and_refuses_an_untrusted_certificate() {
    let s = setup(0).await;
    let c = client(&s.nginx.pass, &s.ca, None);
    let textures = c.textures().await.unwrap();
    assert!(textures.iter().any(|t| t.id == s.id));
    let want = wanted();
    let (pages, stats) = c.pages(&s.id, &want, &SPEC).await.unwrap();
    assert_eq!((stats.requested, stats.metatiles), (want.len(), 1));
    assert_same(&pages, &plain(&s.vtex.base, &s.id, &want).await);
    let (page, _) = c.revalidate(&s.id, want[41], &SPEC).await.unwrap();
    assert_eq!(page.bytes, pages[41].bytes);
    let log = s.nginx.log_of(&s.nginx.pass);
    assert_eq!(log.len(), 1 + 1 + 3 + 1, "the list, one metatile, three pages, one revalidation: {log:?}");
    assert!(log.iter().all(|l| l.protocol == "HTTP/2.0"), "HTTP/2 negotiated: {log:?}");
    assert_eq!(log.last().unwrap().status, 304);

    // A client that trusts only the system's roots, or another CA, does not connect: nothing
    // reaches nginx's log.
    let other = pki();
    for untrusting in [
        Client::builder(&s.nginx.pass).retry(quick()).build().unwrap(),
        Client::builder(&s.nginx.pass)
            .root_certificate_pem(&other.ca_pem())
            .unwrap()
            .system_roots(false)
            .retry(quick())
            .build()
            .unwrap(),
    ] {
        let err = untrusting.textures().await.unwrap_err();
        assert!(matches!(err, vtex_client::Error::Http(_)), "{err}");
        assert!(format!("{:?}", err).to_lowercase().contains("certificate"), "{err:?}");
    }
    assert_eq!(s.nginx.log_of(&s.nginx.pass).len(), log.len());
    assert!(Client::builder("x").root_certificate_pem(b"not a certificate").is_err());
}

/// nginx passes the upstream's 503 and `Retry-After: 1` over HTTP/2; the client waits the
/// second it asks, though its own back-off is 5 ms, then gets the page.
#[tokio::test]
async fn a_503_through_nginx_is_retried_after_its_retry_after() {
    let s = setup(1).await;
    let c = client(&s.nginx.scripted, &s.ca, None);
    let start = Instant::now();
    let spec = PageSpec { size: 64, border: 0, format: PageFormat::Rgba, layer: PageLayer::Color };
    let (pages, _) = c.pages("t", &[PageAddr { level: 0, x: 0, y: 0 }], &spec).await.unwrap();
    let waited = start.elapsed();
    assert_eq!(&pages[0].bytes[..], &[1, 2, 3, 4]);
    assert_eq!(s.scripted.load(Ordering::SeqCst), 2, "one 503, then the page");
    assert!(waited >= Duration::from_millis(950), "Retry-After: 1 honoured, waited {waited:?}");
    let log = s.nginx.log_of(&s.nginx.scripted);
    let statuses: Vec<(u16, &str)> = log.iter().map(|l| (l.status, l.protocol.as_str())).collect();
    assert_eq!(statuses, [(503, "HTTP/2.0"), (200, "HTTP/2.0")]);
}

/// Pages kept on disk serve a new client (a game's next run) without a request while the
/// server's `immutable` freshness holds; damaged files are fetched again, not served; with
/// `Cache-Control: no-cache` in front, the held pages are revalidated (304, no body).
#[tokio::test]
async fn the_disk_cache_outlives_the_client_checks_its_files_and_revalidates() {
    let s = setup(0).await;
    let dir = tempfile::tempdir().unwrap();
    let want = wanted();
    let reference = plain(&s.vtex.base, &s.id, &want).await;
    let first = client(&s.nginx.pass, &s.ca, Some(dir.path()));
    let (pages, stats) = first.pages(&s.id, &want, &SPEC).await.unwrap();
    assert_same(&pages, &reference);
    assert_eq!((stats.requested, stats.disk_hits), (want.len(), 0));
    let (held, bytes) = first.disk_cached().unwrap();
    assert_eq!(held, 64 + 3, "the whole metatile and the pages alone");
    assert!(bytes > 0);
    drop(first);
    let before = s.nginx.log_of(&s.nginx.pass).len();

    // The next run: everything from the disk, nothing over the network.
    let second = client(&s.nginx.pass, &s.ca, Some(dir.path()));
    let (pages, stats) = second.pages(&s.id, &want, &SPEC).await.unwrap();
    assert_same(&pages, &reference);
    assert_eq!((stats.disk_hits, stats.requested, stats.bytes), (want.len(), 0, 0));
    assert_eq!(s.nginx.log_of(&s.nginx.pass).len(), before, "no request");
    drop(second);

    // A byte flipped in one page's file, another's cut short: both fetched again (each alone),
    // the others still from the disk, every page the server's bytes.
    let key = |addr| PageKey { texture: s.id.clone(), addr, spec: SPEC };
    let disk = vtex_client::disk::DiskCache::open(dir.path(), 64 << 20).unwrap();
    let (flipped, cut) = (want[41], want[7]);
    let path = disk.path_of(&key(flipped));
    let mut bytes = std::fs::read(&path).unwrap();
    let mid = bytes.len() / 2;
    bytes[mid] ^= 1;
    std::fs::write(&path, bytes).unwrap();
    let path = disk.path_of(&key(cut));
    let len = std::fs::metadata(&path).unwrap().len();
    std::fs::OpenOptions::new().write(true).open(&path).unwrap().set_len(len - 100).unwrap();
    drop(disk);
    let third = client(&s.nginx.pass, &s.ca, Some(dir.path()));
    let (pages, stats) = third.pages(&s.id, &want, &SPEC).await.unwrap();
    assert_same(&pages, &reference);
    assert_eq!((stats.disk_hits, stats.requested, stats.metatiles), (want.len() - 2, 2, 0));
    let log = s.nginx.log_of(&s.nginx.pass);
    let refetched: BTreeSet<String> =
        log[before..].iter().map(|l| l.uri.split('?').next().unwrap().to_string()).collect();
    let expect: BTreeSet<String> = [flipped, cut]
        .iter()
        .map(|&a| format!("/api/v1/textures/{}/pages/{}/{}/{}.ktx2", s.id, a.level, a.x, a.y))
        .collect();
    assert_eq!(refetched, expect, "the two damaged pages, and only them");
    drop(third);

    // Behind a cache that says `no-cache`: what the disk holds is revalidated, not fetched.
    let dir = tempfile::tempdir().unwrap();
    let alone = &want[40..];
    let first = client(&s.nginx.no_cache, &s.ca, Some(dir.path()));
    first.pages(&s.id, alone, &SPEC).await.unwrap();
    drop(first);
    let second = client(&s.nginx.no_cache, &s.ca, Some(dir.path()));
    let (pages, stats) = second.pages(&s.id, alone, &SPEC).await.unwrap();
    assert_same(&pages, &reference[40..]);
    assert_eq!((stats.disk_hits, stats.revalidated, stats.bytes), (0, 3, 0));
    let log = s.nginx.log_of(&s.nginx.no_cache);
    let statuses: Vec<u16> = log.iter().map(|l| l.status).collect();
    assert_eq!(statuses, [200, 200, 200, 304, 304, 304], "{log:?}");
    assert!(log[3..].iter().all(|l| l.bytes == 0 && l.protocol == "HTTP/2.0"));
}
