//! Connections are bounded in time, number and request size, over real sockets against a real
//! `vtex serve`: slow readers are dropped after the send timeout and their memory freed, idle
//! connections (HTTP/1.1 keep-alive, HTTP/2, silent) are closed while a long synthesis is not,
//! a connection without a request head is closed at the header deadline from its accept, at the
//! connection limit silent and idle connections make room for a new client (a reader pausing
//! mid-response does not), which gets a clear 503 only when every connection has a request in
//! flight, one address's connections are
//! bounded, long and crowded queries are refused before parsing, and `Host` is checked as
//! RFC 9112 §3.2 asks.

use crate::support::*;
use std::io::{ErrorKind, Read, Write};
use std::net::TcpStream;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use vtex_synth::models::{self, Inputs};

/// Sends `request` on a fresh connection and reads the whole answer (the request should ask
/// for `Connection: close`).
fn exchange(addr: &str, request: &str) -> String {
    raw_request(addr, request.as_bytes())
}

fn get(addr: &str, path: &str) -> String {
    exchange(addr, &format!("GET {path} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n"))
}

fn status(response: &str) -> u16 {
    response.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or_else(|| panic!("no status in {response:?}"))
}

fn body(response: &str) -> &str {
    response.split_once("\r\n\r\n").map_or("", |(_, b)| b)
}

fn metrics_of(s: &Server) -> String {
    body(&get(&s.addr, "/metrics")).to_string()
}

/// Open connections the server counts (the one asking included).
fn open_connections(s: &Server) -> f64 {
    metric(&metrics_of(s), "vtex_http_connections", &[])
}

/// The server's resident memory, from `/proc/<pid>/status`.
fn rss_mib(s: &Server) -> f64 {
    let status = std::fs::read_to_string(format!("/proc/{}/status", s.pid())).unwrap();
    let line = status.lines().find(|l| l.starts_with("VmRSS:")).unwrap();
    line.split_whitespace().nth(1).unwrap().parse::<f64>().unwrap() / 1024.0
}

/// Uploads `bundle` over a raw connection; returns its id.
fn upload(s: &Server, bundle: &vtex_synth::bundle::Bundle) -> String {
    let bytes = bundle.to_bytes();
    let mut req = format!(
        "POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n\
         Content-Length: {}\r\nConnection: close\r\n\r\n",
        bytes.len()
    )
    .into_bytes();
    req.extend_from_slice(&bytes);
    let resp = raw_request(&s.addr, &req);
    assert!(matches!(status(&resp), 200 | 201), "{resp}");
    let info: serde_json::Value = serde_json::from_str(body(&resp)).unwrap();
    info["id"].as_str().unwrap().to_string()
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

/// Reads until the server closes `s`; returns when, or `None` if it is still open after
/// `limit`. A reset counts as closed.
fn closed_within(s: &mut TcpStream, limit: Duration) -> Option<Instant> {
    s.set_read_timeout(Some(limit)).unwrap();
    let mut buf = [0u8; 65536];
    loop {
        match s.read(&mut buf) {
            Ok(0) => return Some(Instant::now()),
            Ok(_) => continue,
            Err(e) if matches!(e.kind(), ErrorKind::WouldBlock | ErrorKind::TimedOut) => return None,
            Err(_) => return Some(Instant::now()),
        }
    }
}

/// A minimal HTTP/2 client over a raw socket (prior knowledge): the preface, empty SETTINGS,
/// and GETs encoded with HPACK's static table only.
struct H2(TcpStream);

impl H2 {
    fn connect(addr: &str) -> H2 {
        let mut s = TcpStream::connect(addr).unwrap();
        s.write_all(b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n").unwrap();
        s.write_all(&[0, 0, 0, 4, 0, 0, 0, 0, 0]).unwrap();
        H2(s)
    }

    /// GET `path` on stream `id` with `:authority` and no `Host`; returns the status, read
    /// from the response's first header (hyper sends `:status` as a static-table index).
    fn get(&mut self, id: u32, path: &str) -> u16 {
        let mut block = vec![0x82, 0x86, 0x44];
        // The path's length: an HPACK integer with a 7-bit prefix.
        let mut n = path.len();
        if n < 127 {
            block.push(n as u8);
        } else {
            block.push(127);
            n -= 127;
            while n >= 128 {
                block.push((n % 128) as u8 | 0x80);
                n /= 128;
            }
            block.push(n as u8);
        }
        block.extend_from_slice(path.as_bytes());
        block.extend_from_slice(&[0x41, 1, b'x']);
        let mut frame = (block.len() as u32).to_be_bytes()[1..].to_vec();
        frame.extend_from_slice(&[1, 0x05]);
        frame.extend_from_slice(&id.to_be_bytes());
        frame.extend_from_slice(&block);
        self.0.write_all(&frame).unwrap();
        self.0.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
        loop {
            let mut head = [0u8; 9];
            self.0.read_exact(&mut head).unwrap();
            let len = u32::from_be_bytes([0, head[0], head[1], head[2]]) as usize;
            let mut payload = vec![0; len];
            self.0.read_exact(&mut payload).unwrap();
            let (kind, flags, stream) = (head[3], head[4], u32::from_be_bytes(head[5..9].try_into().unwrap()));
            if kind == 4 && flags & 1 == 0 {
                self.0.write_all(&[0, 0, 0, 4, 1, 0, 0, 0, 0]).unwrap();
            }
            if kind == 1 && stream == id {
                return match payload[0] {
                    0x88 => 200,
                    0x8c => 400,
                    0x8d => 404,
                    other => panic!("unexpected first header byte {other:#x}"),
                };
            }
        }
    }
}

/// Clients that send a request for a 16 MiB region and never read it: after the send timeout
/// their connections are closed and the memory their responses held is freed.
#[test]
fn readers_that_stop_are_dropped_after_the_send_timeout_and_their_memory_freed() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--send-timeout-secs", "1"]);
    let id = upload(&s, &mosaic(64, 8, 1));
    let region = format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=2048&h=2048&format=rgba");
    let full = get(&s.addr, &region);
    assert_eq!(status(&full), 200);
    let baseline = rss_mib(&s);

    const READERS: usize = 4;
    let request = format!("GET {region} HTTP/1.1\r\nHost: x\r\n\r\n");
    let mut readers: Vec<TcpStream> = (0..READERS)
        .map(|_| {
            let mut c = TcpStream::connect(&s.addr).unwrap();
            c.write_all(request.as_bytes()).unwrap();
            c
        })
        .collect();
    let rendered = eventually(Duration::from_secs(60), || {
        let m = metrics_of(&s);
        metric(&m, "vtex_syntheses_total", &[]) >= 1.0 + READERS as f64
            && metric(&m, "vtex_syntheses_in_flight", &[]) == 0.0
    });
    assert!(rendered, "the regions were rendered");
    let held = rss_mib(&s);
    assert!(held > baseline + 48.0, "the unread responses are held: {baseline:.0} MiB, then {held:.0} MiB");

    let t0 = Instant::now();
    assert!(
        eventually(Duration::from_secs(30), || open_connections(&s) <= 1.0),
        "the stalled connections are closed after the send timeout ({} open)",
        open_connections(&s)
    );
    let freed = eventually(Duration::from_secs(10), || rss_mib(&s) < baseline + 16.0);
    assert!(freed, "memory returns near its baseline: {baseline:.0} MiB before, {:.0} MiB after", rss_mib(&s));
    eprintln!("RSS {baseline:.0} → {held:.0} → {:.0} MiB; closed {:?} after the regions", rss_mib(&s), t0.elapsed());
    for r in &mut readers {
        let mut got = Vec::new();
        r.set_read_timeout(Some(Duration::from_secs(10))).unwrap();
        let _ = r.read_to_end(&mut got);
        assert!(got.len() < full.len(), "the response was cut short ({} of {} bytes)", got.len(), full.len());
    }
}

/// An HTTP/2 client that reads every byte but never opens its flow-control window stalls its
/// response without filling the socket; hyper has taken the whole body, so no request is in
/// flight and no bytes move: the idle timeout drops the connection and what it buffered.
#[test]
fn an_http2_response_stalled_by_flow_control_is_dropped_when_idle() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--idle-timeout-secs", "1"]);
    let id = upload(&s, &mosaic(64, 8, 1));
    let mut h2 = H2::connect(&s.addr);
    assert_eq!(h2.get(1, &format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=1024&h=1024&format=rgba")), 200);
    let since = Instant::now();
    let closed = closed_within(&mut h2.0, Duration::from_secs(30)).expect("the stalled connection is closed");
    eprintln!("stalled HTTP/2 response dropped {:?} after its head", closed - since);
    assert!(closed - since >= Duration::from_millis(900), "not before the idle timeout");
    assert!(eventually(Duration::from_secs(10), || open_connections(&s) <= 1.0), "and uncounted");
}

/// A connection that never speaks, an HTTP/1.1 keep-alive connection after its answer and an
/// HTTP/2 connection after its answer are closed once idle for the idle timeout, and not before.
#[test]
fn idle_connections_are_closed_whatever_they_speak() {
    let dir = tempdir();
    let idle = Duration::from_millis(500);
    let s = Server::spawn(dir.path(), &["--idle-timeout-secs", "0.5"]);

    let mut silent = TcpStream::connect(&s.addr).unwrap();
    let silent_since = Instant::now();

    let mut kept = TcpStream::connect(&s.addr).unwrap();
    kept.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n").unwrap();
    let mut answer = Vec::new();
    let mut buf = [0u8; 1024];
    while !answer.ends_with(b"}") {
        let n = kept.read(&mut buf).unwrap();
        assert!(n > 0, "the keep-alive answer arrives before any close");
        answer.extend_from_slice(&buf[..n]);
    }
    let kept_since = Instant::now();

    let mut h2 = H2::connect(&s.addr);
    assert_eq!(h2.get(1, "/healthz"), 200);
    let h2_since = Instant::now();

    for (name, conn, since) in
        [("silent", &mut silent, silent_since), ("keep-alive", &mut kept, kept_since), ("HTTP/2", &mut h2.0, h2_since)]
    {
        let closed = closed_within(conn, Duration::from_secs(20)).unwrap_or_else(|| panic!("{name}: never closed"));
        let after = closed - since;
        assert!(after >= idle - Duration::from_millis(100), "{name}: closed after {after:?}, before the idle timeout");
        eprintln!("{name}: closed {after:?} after its last byte");
    }
}

/// A request in flight is not idle: a region whose synthesis outlasts the idle timeout several
/// times over, with no byte moving meanwhile, is answered in full.
#[test]
fn a_long_synthesis_is_not_idle() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--idle-timeout-secs", "0.2"]);
    let params = serde_json::json!({"seed": 11, "stages": [{"kernel": {"size": 5, "preset": "gauss", "sigma": 1.0},
        "map": {"kind": "logistic", "r": 3.9}, "iterations": 5}], "palette": "ocean"});
    let id = upload(&s, &models::create("cascade", "slow ripples", &params, &Inputs::new()).unwrap());
    let t0 = Instant::now();
    let mut c = TcpStream::connect(&s.addr).unwrap();
    let region = format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=4096&h=4096&format=rgba");
    write!(c, "GET {region} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").unwrap();
    let mut resp = Vec::new();
    c.set_read_timeout(Some(Duration::from_secs(120))).unwrap();
    c.read_to_end(&mut resp).unwrap();
    let took = t0.elapsed();
    let end = resp.windows(4).position(|w| w == b"\r\n\r\n").expect("a response head") + 4;
    let head = String::from_utf8_lossy(&resp[..end]);
    assert_eq!(status(&head), 200, "{head}");
    assert_eq!(resp.len() - end, 4096 * 4096 * 4, "the whole region arrives");
    assert!(took > Duration::from_millis(400), "the synthesis outlasted the idle timeout twice ({took:?})");
}

/// With the server's open-file limit at 128, the limit is derived from it; connections that
/// each have a request in flight (uploads whose bodies are still coming) fill it, and a new
/// client is answered a clear 503 at once, then served once they go.
#[test]
fn at_the_connection_limit_with_every_request_in_flight_a_new_client_gets_a_clear_refusal() {
    let dir = tempdir();
    let s = Server::spawn_under(&["prlimit", "--nofile=128:128", "--"], dir.path(), &[], &[]);
    let log = s.log_text();
    let per = if log.contains("send=copy") { 1 } else { 3 };
    let max = metric(&metrics_of(&s), "vtex_http_connections_max", &[]);
    assert_eq!(max, ((128 - 64) / per) as f64, "the limit is (RLIMIT_NOFILE − 64) / descriptors per connection");

    let busy: Vec<TcpStream> = (0..max as usize).map(|_| upload_in_flight(&s.addr)).collect();
    // Time for every upload to start: a connection whose request has not is closed to make room.
    std::thread::sleep(Duration::from_millis(500));
    let t0 = Instant::now();
    let refused = get(&s.addr, "/healthz");
    assert!(t0.elapsed() < Duration::from_secs(1), "the refusal is immediate ({:?})", t0.elapsed());
    assert_eq!(status(&refused), 503, "{refused}");
    let head = refused.to_ascii_lowercase();
    for h in ["retry-after: 1\r\n", "connection: close\r\n", "content-type: application/json\r\n"] {
        assert!(head.contains(h), "{h:?} in {refused}");
    }
    let why: serde_json::Value = serde_json::from_str(body(&refused)).unwrap();
    let says = why["error"].as_str().unwrap();
    assert!(says.contains(&format!("limit of {max} connections")) && says.contains("request in flight"), "{why}");

    drop(busy);
    assert!(eventually(Duration::from_secs(20), || status(&get(&s.addr, "/healthz")) == 200), "served again");
    let m = metrics_of(&s);
    assert!(metric(&m, "vtex_http_connections_refused_total", &[("limit", "max-connections")]) >= 1.0, "{m}");
}

/// A connection on which an upload has started, its body still coming: a request in flight.
fn upload_in_flight(addr: &str) -> TcpStream {
    let mut c = TcpStream::connect(addr).unwrap();
    c.write_all(
        b"POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\n\
          Content-Length: 100000\r\n\r\nVTEX",
    )
    .unwrap();
    c
}

/// A connection that has been answered once and stays open, idle, between requests.
fn idle_keep_alive(addr: &str) -> std::io::Result<TcpStream> {
    let mut c = TcpStream::connect(addr)?;
    c.write_all(b"GET /healthz HTTP/1.1\r\nHost: x\r\n\r\n")?;
    c.set_read_timeout(Some(Duration::from_secs(30)))?;
    let (mut answer, mut buf) = (Vec::new(), [0u8; 1024]);
    while !answer.ends_with(b"}") {
        match c.read(&mut buf)? {
            0 => return Err(ErrorKind::UnexpectedEof.into()),
            n => answer.extend_from_slice(&buf[..n]),
        }
    }
    Ok(c)
}

/// Seconds from `since` until the server closes `c`, which must happen within `limit`.
fn closed_after(c: &mut TcpStream, since: Instant, limit: Duration) -> f64 {
    let closed = closed_within(c, limit).expect("the server closes the connection");
    (closed - since).as_secs_f64()
}

/// With a header deadline of 2 s, each of these is closed 2 ± 1 s after its accept (or after
/// its response, on keep-alive), long before the idle timeout: a socket that never sends a
/// byte, a head sent a byte at a time from 1.5 s on, HTTP/2's preface alone, and an HTTP/1.1
/// keep-alive connection after its answer.
#[test]
fn a_connection_without_a_request_head_is_closed_at_the_header_deadline() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--header-timeout-secs", "2"]);
    let window = 1.0..=3.0;

    let t0 = Instant::now();
    let mut silent = TcpStream::connect(&s.addr).unwrap();
    let mut h2 = TcpStream::connect(&s.addr).unwrap();
    h2.write_all(b"PRI * HTTP/2.0\r\n\r\nSM\r\n\r\n").unwrap();
    let mut trickle = TcpStream::connect(&s.addr).unwrap();
    let trickler = std::thread::spawn({
        let mut c = trickle.try_clone().unwrap();
        move || {
            std::thread::sleep(Duration::from_millis(1500));
            for b in b"GET /healthz HTTP/1.1\r\nHost: x\r\n".iter() {
                if c.write_all(&[*b]).is_err() {
                    return;
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        }
    });
    let mut kept = idle_keep_alive(&s.addr).expect("a keep-alive answer");
    let answered = Instant::now();

    for (name, conn, since) in
        [("silent", &mut silent, t0), ("HTTP/2 preface alone", &mut h2, t0), ("a byte at a time", &mut trickle, t0)]
    {
        let after = closed_after(conn, since, Duration::from_secs(20));
        eprintln!("{name}: closed {after:.2} s after its accept");
        assert!(window.contains(&after), "{name}: closed {after:.2} s after its accept, not at the 2 s deadline");
    }
    let after = closed_after(&mut kept, answered, Duration::from_secs(20));
    eprintln!("keep-alive: closed {after:.2} s after its answer");
    assert!(window.contains(&after), "keep-alive: closed {after:.2} s after its answer, not at the 2 s deadline");
    trickler.join().unwrap();
}

/// Keeps `n` connections made by `open` to `addr` open until `stop`: each one the server closes
/// is made again at once, as an attacker holding slots would. Returns how many were made.
fn hold(addr: &str, n: usize, open: Opener, stop: Arc<AtomicBool>) -> std::thread::JoinHandle<usize> {
    let addr = addr.to_string();
    std::thread::spawn(move || {
        let mut made = 0;
        let mut conns: Vec<Option<TcpStream>> = (0..n).map(|_| None).collect();
        while !stop.load(Ordering::Relaxed) {
            for slot in conns.iter_mut() {
                let closed = slot.as_mut().is_none_or(|c| {
                    c.set_nonblocking(true).unwrap();
                    match c.read(&mut [0u8; 256]) {
                        Ok(0) => true,
                        Ok(_) => false,
                        Err(e) => e.kind() != ErrorKind::WouldBlock,
                    }
                });
                if closed {
                    *slot = open(&addr).ok();
                    made += 1;
                }
            }
            std::thread::sleep(Duration::from_millis(10));
        }
        made
    })
}

/// How an attacker opens a connection it then holds.
type Opener = fn(&str) -> std::io::Result<TcpStream>;

/// At a limit of 8 connections, 16 held by `open` — made again as soon as they are closed —
/// do not keep clients out: a client's request is answered in under a second, every time, and
/// health checks are 200 throughout; the held connections are the ones closed to make room.
fn clients_are_served_past_connections_held_by(open: Opener) {
    let dir = tempdir();
    const MAX: usize = 8;
    let s = Server::spawn(dir.path(), &["--max-connections", &MAX.to_string()]);
    let id = upload(&s, &mosaic(64, 8, 1));
    let stop = Arc::new(AtomicBool::new(false));
    let attacker = hold(&s.addr, 2 * MAX, open, stop.clone());
    std::thread::sleep(Duration::from_millis(500));

    let tile = format!("/api/v1/textures/{id}/tiles/0/0/0.png");
    // A fresh connection chosen to make room before its head arrived is closed unanswered; a
    // client sends the request once more on a new one, as browsers do (RFC 9112 §9.3.1).
    let mut retried = 0;
    let mut get_once_more = |path: &str| {
        let answer = get(&s.addr, path);
        if !answer.is_empty() {
            return answer;
        }
        retried += 1;
        get(&s.addr, path)
    };
    let end = Instant::now() + Duration::from_secs(3);
    let (mut served, mut slowest) = (0, Duration::ZERO);
    while Instant::now() < end {
        let t = Instant::now();
        let health = get_once_more("/healthz");
        assert_eq!(status(&health), 200, "a health check while the connections are held: {health}");
        let resp = get_once_more(&tile);
        assert_eq!(status(&resp), 200, "a client while the connections are held: {}", &resp[..resp.len().min(300)]);
        slowest = slowest.max(t.elapsed());
        served += 1;
        std::thread::sleep(Duration::from_millis(50));
    }
    stop.store(true, Ordering::Relaxed);
    let made = attacker.join().unwrap();
    let m = metrics_of(&s);
    let evicted = metric(&m, "vtex_http_connections_evicted_total", &[]);
    eprintln!(
        "{served} clients served ({retried} sent again), slowest {slowest:?}; {made} held connections made, \
         {evicted} closed to make room"
    );
    assert!(slowest < Duration::from_secs(1), "every client served in under a second (slowest {slowest:?})");
    assert!(evicted >= served as f64, "the held connections made room ({evicted} closed for {served} clients)");
    assert_eq!(metric(&m, "vtex_http_connections_refused_total", &[]), 0.0, "nobody refused: {m}");
}

#[test]
fn silent_connections_at_the_limit_make_room_for_clients() {
    clients_are_served_past_connections_held_by(|addr| TcpStream::connect(addr));
}

#[test]
fn idle_keep_alive_connections_at_the_limit_make_room_for_clients() {
    clients_are_served_past_connections_held_by(idle_keep_alive);
}

/// A response whose body hyper has taken whole but the socket has not (a reader pausing with
/// 16 MiB on its way) still has a request in flight: at the limit, with twice the limit in
/// silent connections made again as fast as they are closed, the reader is not the one closed
/// to make room, and gets every byte once it reads; with either transport (the bytes wait in
/// hyper's buffer, or in the splice pipe).
#[test]
fn a_response_still_on_its_way_is_not_closed_to_make_room() {
    a_paused_reader_gets_its_whole_response("copy");
    #[cfg(target_os = "linux")]
    a_paused_reader_gets_its_whole_response("splice");
}

fn a_paused_reader_gets_its_whole_response(send: &str) {
    let dir = tempdir();
    const MAX: usize = 8;
    let s = Server::spawn(dir.path(), &["--max-connections", &MAX.to_string(), "--send", send]);
    let id = upload(&s, &mosaic(64, 8, 1));
    let region = format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=2048&h=2048&format=rgba");
    assert_eq!(status(&get(&s.addr, &region)), 200);

    let mut reader = TcpStream::connect(&s.addr).unwrap();
    reader.write_all(format!("GET {region} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n").as_bytes()).unwrap();
    std::thread::sleep(Duration::from_millis(500));
    let stop = Arc::new(AtomicBool::new(false));
    let attacker = hold(&s.addr, 2 * MAX, |addr| TcpStream::connect(addr), stop.clone());
    std::thread::sleep(Duration::from_secs(2));
    let evicted = metric(&metrics_of(&s), "vtex_http_connections_evicted_total", &[]);

    let mut got = Vec::new();
    reader.set_read_timeout(Some(Duration::from_secs(20))).unwrap();
    let _ = reader.read_to_end(&mut got);
    stop.store(true, Ordering::Relaxed);
    attacker.join().unwrap();
    assert!(evicted >= MAX as f64, "{send}: the silent connections were closed to make room ({evicted})");
    let head = got.windows(4).position(|w| w == b"\r\n\r\n").expect("a response head") + 4;
    assert_eq!(status(&String::from_utf8_lossy(&got[..head])), 200);
    assert_eq!(got.len() - head, 2048 * 2048 * 4, "{send}: the paused reader got its whole response");
}

/// With `--max-connections-per-client 3`, a fourth connection from the same address is
/// answered a clear 429 naming the limit, whatever room the server has; once one of the three
/// closes, the address is served again.
#[test]
fn one_address_is_held_to_its_connection_limit() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--max-connections-per-client", "3"]);
    let mut three: Vec<TcpStream> = (0..3).map(|_| TcpStream::connect(&s.addr).unwrap()).collect();
    let refused = eventually_answer(&s.addr, 429);
    let head = refused.to_ascii_lowercase();
    for h in ["retry-after: 1\r\n", "connection: close\r\n", "content-type: application/json\r\n"] {
        assert!(head.contains(h), "{h:?} in {refused}");
    }
    let why: serde_json::Value = serde_json::from_str(body(&refused)).unwrap();
    assert!(why["error"].as_str().unwrap().contains("limit of 3 connections"), "{why}");

    three.pop();
    let served = eventually_answer(&s.addr, 200);
    assert!(body(&served).contains("ok"), "{served}");
    drop(three);
    let m = metrics_of(&s);
    assert!(metric(&m, "vtex_http_connections_refused_total", &[("limit", "max-connections-per-client")]) >= 1.0);
}

/// The answer to `/healthz` once it is `want` (the server sees a connection open or close a
/// moment after the client does), within 10 s.
fn eventually_answer(addr: &str, want: u16) -> String {
    let mut last = String::new();
    let seen = eventually(Duration::from_secs(10), || {
        last = get(addr, "/healthz");
        status(&last) == want
    });
    assert!(seen, "never answered {want}; last: {last}");
    last
}

/// Queries over the length bound are 414s and queries with more parameters than any route
/// takes are 400s naming the count, on every route and the tile fast path, before any parsing;
/// the batch route alone takes a longer query. Four clients sending 60 KB queries of 15,000
/// parameters do not slow `/healthz` down.
#[test]
fn long_and_crowded_queries_are_refused_before_parsing() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--tile-size", "16"]);
    let id = upload(&s, &mosaic(64, 8, 1));
    let routes = [
        "/healthz".to_string(),
        "/api/v1/textures".to_string(),
        format!("/api/v1/textures/{id}"),
        format!("/api/v1/textures/{id}/tiles/0/0/0.png"),
        format!("/api/v1/textures/{id}/region"),
        format!("/api/v1/textures/{id}/tiles"),
        "/api/nowhere".to_string(),
        "/index.html".to_string(),
    ];
    let long = format!("a={}", "x".repeat(3000));
    let crowded = "a=1&".repeat(20);
    for r in &routes {
        let batch = r.ends_with("/tiles");
        let resp = get(&s.addr, &format!("{r}?{long}"));
        if batch {
            assert_eq!(status(&resp), 400, "the batch takes longer queries: {r} {resp}");
        } else {
            assert_eq!(status(&resp), 414, "{r} {resp}");
            assert!(body(&resp).contains("at most 2048"), "{resp}");
        }
        let resp = get(&s.addr, &format!("{r}?{crowded}"));
        assert_eq!(status(&resp), 400, "{r} {resp}");
        assert!(body(&resp).contains("has 20 parameters"), "{resp}");
    }
    let resp = get(&s.addr, &format!("{}?a={}", routes[5], "x".repeat(30_000)));
    assert_eq!(status(&resp), 414, "{resp}");

    // The longest valid batch lists are over the usual bound, and served.
    let list: Vec<String> = (0..256).map(|i| format!("0/{}/{}", i % 32, i / 32)).collect();
    let q = format!("format=rgba&tiles={}", list.join("%2C"));
    assert!(q.len() > 2048);
    let resp = raw_request(
        &s.addr,
        format!("GET {}?{q} HTTP/1.1\r\nHost: x\r\nConnection: close\r\n\r\n", routes[5]).as_bytes(),
    );
    assert_eq!(status(&resp), 200, "{}", &resp[..resp.len().min(300)]);

    let hostile = format!("/healthz?{}", (0..15_000).map(|i| format!("k{i}=1")).collect::<Vec<_>>().join("&"));
    let hostile = hostile[..60_000].to_string();
    let stop = std::sync::Arc::new(std::sync::atomic::AtomicBool::new(false));
    let hammers: Vec<_> = (0..4)
        .map(|_| {
            let (addr, path, stop) = (s.addr.clone(), hostile.clone(), stop.clone());
            std::thread::spawn(move || {
                let mut sent = 0;
                while !stop.load(std::sync::atomic::Ordering::Relaxed) {
                    let resp = get(&addr, &path);
                    assert!(matches!(status(&resp), 414 | 431), "{resp}");
                    sent += 1;
                }
                sent
            })
        })
        .collect();
    std::thread::sleep(Duration::from_millis(200));
    let mut latencies: Vec<Duration> = (0..20)
        .map(|_| {
            let t = Instant::now();
            assert_eq!(status(&get(&s.addr, "/healthz")), 200);
            t.elapsed()
        })
        .collect();
    stop.store(true, std::sync::atomic::Ordering::Relaxed);
    let sent: usize = hammers.into_iter().map(|h| h.join().unwrap()).sum();
    latencies.sort();
    eprintln!("/healthz under {sent} hostile queries: median {:?}, max {:?}", latencies[10], latencies[19]);
    assert!(sent >= 4, "the hostile clients ran");
    assert!(latencies[10] < Duration::from_millis(100), "/healthz stays quick: {latencies:?}");
}

/// RFC 9112 §3.2: an HTTP/1.1 request without `Host`, with two, or with one that is not
/// `host[:port]` is a 400; HTTP/1.0 may omit it; HTTP/2 carries `:authority` instead.
#[test]
fn host_is_required_once_in_http_1_1() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
    let cases = [
        ("GET /healthz HTTP/1.1\r\nConnection: close\r\n\r\n", 400, "needs a Host header"),
        ("GET /healthz HTTP/1.1\r\nHost: a\r\nHost: b\r\nConnection: close\r\n\r\n", 400, "more than one Host"),
        ("GET /healthz HTTP/1.1\r\nHost: me@a\r\nConnection: close\r\n\r\n", 400, "not host[:port]"),
        ("GET /healthz HTTP/1.0\r\nHost: a\r\nHost: a\r\n\r\n", 400, "more than one Host"),
        ("GET /healthz HTTP/1.1\r\nHost: 127.0.0.1:8080\r\nConnection: close\r\n\r\n", 200, "ok"),
        ("GET /healthz HTTP/1.0\r\n\r\n", 200, "ok"),
    ];
    for (request, want, says) in cases {
        let resp = exchange(&s.addr, request);
        assert_eq!(status(&resp), want, "{request:?}: {resp}");
        assert!(body(&resp).contains(says), "{request:?}: {resp}");
        if want == 400 {
            assert!(resp.to_ascii_lowercase().contains("content-type: application/json"), "{resp}");
        }
    }
    let mut h2 = H2::connect(&s.addr);
    assert_eq!(h2.get(1, "/healthz"), 200, "HTTP/2 without a Host header");
}
