//! Synthesis under pressure, over real sockets: a texture whose tiles take minutes cannot take
//! every slot from the others, a full queue is refused at once with 503 and `Retry-After`,
//! renders stop when every client waiting for them has gone, and SIGTERM stops them and exits
//! within the drain time.

use crate::support::*;
use std::io::{Read, Write};
use std::net::TcpStream;
use std::time::{Duration, Instant};
use vtex_synth::models::{self, Inputs};

/// Flags every server here starts with: the expensive texture is over the default work bounds,
/// which these servers lift so that it is admitted.
const ADMIT_EXPENSIVE: &[&str] =
    &["--max-tile-work", "18446744073709551615", "--max-build-work", "18446744073709551615"];

fn start(dir: &std::path::Path, flags: &[&str]) -> Server {
    Server::spawn(dir, &[ADMIT_EXPENSIVE, flags].concat())
}

/// A cascade of twelve stages of 40 iterations of a 7 × 7 kernel, none coarser than the next:
/// one level-0 tile depends on a window of about 3100² lattice points through 480 iterations,
/// tens of seconds to minutes of one core. Created instantly (its `range` is given).
fn expensive() -> vtex_synth::bundle::Bundle {
    let stage = |first: bool| {
        let mut s = serde_json::json!({"kernel": {"size": 7, "preset": "box"},
                                       "map": {"kind": "logistic", "r": 3.7}, "iterations": 40});
        if !first {
            s["upsample"] = 1.into();
        }
        s
    };
    let stages: Vec<_> = (0..12).map(|i| stage(i == 0)).collect();
    let params = serde_json::json!({"seed": 1, "width": 65536, "height": 65536, "stages": stages, "range": [0.0, 1.0]});
    models::create("cascade", "expensive cascade", &params, &Inputs::new()).unwrap()
}

/// The synthesis gauges: (running, queued).
async fn syntheses(c: &reqwest::Client, s: &Server) -> (f64, f64) {
    let m = metrics(c, s).await;
    (metric(&m, "vtex_syntheses_in_flight", &[]), metric(&m, "vtex_syntheses_queued", &[]))
}

/// Waits (up to a generous bound) until the server's synthesis gauges satisfy `ok`.
async fn wait_for(c: &reqwest::Client, s: &Server, what: &str, ok: impl Fn(f64, f64) -> bool) {
    let deadline = Instant::now() + Duration::from_secs(30);
    loop {
        let (running, queued) = syntheses(c, s).await;
        if ok(running, queued) {
            return;
        }
        assert!(Instant::now() < deadline, "not reached in 30 s: {what} (running {running}, queued {queued})");
        tokio::time::sleep(Duration::from_millis(50)).await;
    }
}

/// A client that sends `GET path` and waits: drop it to hang up.
fn ask(s: &Server, path: &str) -> TcpStream {
    let mut sock = TcpStream::connect(&s.addr).unwrap();
    write!(sock, "GET {path} HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    sock
}

/// Everything the server sends on `sock` until it closes it (or `limit` passes).
fn answer(mut sock: TcpStream, limit: Duration) -> String {
    sock.set_read_timeout(Some(limit)).unwrap();
    let mut out = Vec::new();
    let _ = sock.read_to_end(&mut out);
    String::from_utf8_lossy(&out).into_owned()
}

fn tile_path(id: &str, x: u32) -> String {
    format!("/api/v1/textures/{id}/tiles/0/{x}/0.png")
}

/// Two clients ask for tiles of the expensive texture on a server of two slots; an ordinary
/// tile of another texture, not cached, is still answered at once.
#[tokio::test]
async fn one_texture_cannot_take_every_slot() {
    let dir = tempdir();
    let s = start(dir.path(), &["--max-syntheses", "2"]);
    let c = client();
    let slow = put(&c, &s, &expensive()).await;
    let ordinary = put(&c, &s, &mosaic(64, 8, 3)).await;
    let _clients = [ask(&s, &tile_path(&slow, 0)), ask(&s, &tile_path(&slow, 1))];
    wait_for(&c, &s, "both expensive tiles admitted", |running, queued| running >= 1.0 && running + queued >= 2.0)
        .await;
    let t0 = Instant::now();
    let quick = reqwest::Client::builder().timeout(Duration::from_secs(20)).build().unwrap();
    let resp = quick.get(s.tile_url(&ordinary, 0, 1, 1, "png")).send().await;
    let resp = resp.unwrap_or_else(|e| panic!("the ordinary tile was not answered: {e}"));
    assert_eq!(resp.status(), 200);
    assert_eq!(resp.headers()["x-vtex-cache"], "miss");
    assert!(t0.elapsed() < Duration::from_secs(10), "answered after {:?}", t0.elapsed());
    // The expensive texture holds one slot, its other tile waits.
    assert_eq!(syntheses(&c, &s).await, (1.0, 1.0));
}

/// Past the queue bound a miss is answered 503 at once, with `Retry-After` and a JSON error;
/// misses already queued keep their place.
#[tokio::test]
async fn a_full_queue_answers_503_at_once() {
    let dir = tempdir();
    let s = start(dir.path(), &["--max-syntheses", "1", "--max-queued", "1"]);
    let c = client();
    let slow = put(&c, &s, &expensive()).await;
    let _clients = [ask(&s, &tile_path(&slow, 0)), ask(&s, &tile_path(&slow, 1))];
    wait_for(&c, &s, "one tile running, one queued", |running, queued| running == 1.0 && queued == 1.0).await;
    let t0 = Instant::now();
    let quick = reqwest::Client::builder().timeout(Duration::from_secs(20)).build().unwrap();
    let resp = quick.get(s.url(&tile_path(&slow, 2))).send().await.expect("answered");
    assert!(t0.elapsed() < Duration::from_secs(5), "answered after {:?}", t0.elapsed());
    assert_eq!(resp.status(), 503);
    assert_eq!(resp.headers()["retry-after"], "1");
    assert_eq!(resp.headers()["content-type"], "application/json");
    let body: serde_json::Value = resp.json().await.unwrap();
    assert!(body["error"].as_str().unwrap().contains("wait for synthesis"), "{body}");
    let m = metrics(&c, &s).await;
    assert_eq!(metric(&m, "vtex_syntheses_shed_total", &[]), 1.0);
    assert_eq!(syntheses(&c, &s).await, (1.0, 1.0), "the queued miss keeps its place");
}

/// SIGTERM with renders in flight and misses queued: the process exits 0 within the drain
/// time (10 s; asserted with a margin).
#[tokio::test]
async fn sigterm_exits_within_the_drain_time_with_renders_in_flight() {
    let dir = tempdir();
    let s = start(dir.path(), &["--max-syntheses", "2"]);
    let c = client();
    let slow = put(&c, &s, &expensive()).await;
    let clients: Vec<_> = (0..3).map(|x| ask(&s, &tile_path(&slow, x))).collect();
    wait_for(&c, &s, "renders in flight", |running, queued| running >= 1.0 && running + queued >= 3.0).await;
    let t0 = Instant::now();
    let answers: Vec<_> = clients
        .into_iter()
        .map(|sock| tokio::task::spawn_blocking(move || (answer(sock, Duration::from_secs(30)), t0.elapsed())))
        .collect();
    let status = tokio::task::spawn_blocking(move || s.terminate()).await.unwrap();
    let took = t0.elapsed();
    assert!(status.success(), "{status}");
    assert!(took < Duration::from_secs(15), "exited {took:?} after SIGTERM");
    // Every client waiting was answered before the exit: its render stopped, or its miss
    // refused, rather than its connection cut.
    for a in answers {
        let (text, when) = a.await.unwrap();
        assert!(text.starts_with("HTTP/1.1 503") && text.contains("shutting down"), "{when:?}: {text}");
        assert!(when <= took, "answered {when:?} after SIGTERM, after the exit at {took:?}");
    }
}

/// Renders stop once every client waiting for them has hung up — tiles, batches, regions,
/// and queued misses — but not while one of several clients of one tile still waits.
#[tokio::test]
async fn renders_stop_when_their_clients_are_gone() {
    let dir = tempdir();
    let s = start(dir.path(), &["--max-syntheses", "3", "--max-syntheses-per-texture", "3"]);
    let c = client();
    let slow = put(&c, &s, &expensive()).await;
    let tile = [ask(&s, &tile_path(&slow, 0)), ask(&s, &tile_path(&slow, 0))];
    let batch = ask(&s, &format!("/api/v1/textures/{slow}/tiles?format=png&tiles=0/1/0"));
    let region = ask(&s, &format!("/api/v1/textures/{slow}/region?level=0&x=0&y=512&w=256&h=256"));
    wait_for(&c, &s, "three renders", |running, _| running == 3.0).await;
    let queued = ask(&s, &tile_path(&slow, 2));
    wait_for(&c, &s, "a miss queued", |running, queued| running == 3.0 && queued == 1.0).await;
    drop(queued);
    wait_for(&c, &s, "the queued miss gone", |running, queued| running == 3.0 && queued == 0.0).await;
    let [first, second] = tile;
    drop(first);
    // The other client of that tile still waits: its render goes on.
    tokio::time::sleep(Duration::from_millis(1500)).await;
    assert_eq!(syntheses(&c, &s).await, (3.0, 0.0));
    assert_eq!(metric(&metrics(&c, &s).await, "vtex_syntheses_stopped_total", &[]), 0.0);
    drop((second, batch, region));
    wait_for(&c, &s, "every render stopped", |running, queued| running == 0.0 && queued == 0.0).await;
    let m = metrics(&c, &s).await;
    assert_eq!(metric(&m, "vtex_syntheses_stopped_total", &[]), 3.0);
    assert_eq!(metric(&m, "vtex_syntheses_total", &[]), 3.0, "the queued miss never started");
}
