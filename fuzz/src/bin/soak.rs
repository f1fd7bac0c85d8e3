//! The soak benchmark's load driver (run by `bench/server/soak.sh`): for a fixed time it keeps
//! a fixed number of connections busy against a running `vtex serve`, mixing well-behaved
//! clients (cached tiles, uncached tiles of every stored texture, uploads) with slow readers
//! (reading a large region a few bytes a second) and clients that never read, while sampling
//! the server's resident memory from `/proc/<pid>/status` every 100 ms. Beside them, attackers
//! hold as many sockets again as the server's connection limit, of each of two kinds — silent
//! sockets and idle keep-alives — making each one again as soon as the server closes it, so the
//! server is at its limit throughout. It reports each class's answers, the cached tiles'
//! latency percentiles, how long the attackers' sockets lived, and the largest RSS against the
//! budgets. A slow reader's region refused with 503 (the in-flight budget spent) is the
//! intended answer for that class: it is counted apart and asked again, never as an error.

use clap::Parser;
use rand::rngs::StdRng;
use rand::{Rng, SeedableRng};
use serde_json::Value;
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering::Relaxed};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};

#[derive(Parser)]
struct Args {
    /// Base URL of the server, e.g. http://127.0.0.1:8080.
    #[arg(long)]
    url: String,
    /// The server's process id, for its RSS.
    #[arg(long)]
    pid: u32,
    #[arg(long, default_value_t = 60)]
    seconds: u64,
    #[arg(long, default_value_t = 64)]
    connections: usize,
    /// The memory budgets the server was given, summed (MiB): RSS is held to this + 20 %.
    #[arg(long)]
    budget_mb: f64,
    #[arg(long, default_value_t = 1)]
    seed: u64,
    /// Sockets each kind of attacker holds [default: the server's connection limit].
    #[arg(long)]
    attackers: Option<usize>,
}

/// A stored texture, as `GET /api/v1/textures` lists it.
#[derive(Clone, Debug)]
struct Texture {
    id: String,
    model: String,
    width: u64,
    height: u64,
    levels: u32,
    tile_size: u64,
}

impl Texture {
    fn tiles_at(&self, level: u32) -> (u64, u64) {
        let side = |v: u64| v.div_ceil(1u64 << level.min(63)).max(1).div_ceil(self.tile_size);
        (side(self.width), side(self.height))
    }

    fn tile_url(&self, base: &str, level: u32, x: u64, y: u64, ext: &str) -> String {
        format!("{base}/api/v1/textures/{}/tiles/{level}/{x}/{y}.{ext}", self.id)
    }
}

/// What one class of clients got back.
#[derive(Default, Debug)]
struct Tally {
    ok: u64,
    /// Refusals a loaded server is allowed to give (503 shed, 408 deadline, 507 store full).
    shed: BTreeMap<u16, u64>,
    /// Anything else: other statuses and transport errors, by description.
    errors: BTreeMap<String, u64>,
    /// Requests sent again once because the server closed their connection before answering.
    retried: u64,
    latencies: Vec<Duration>,
}

impl Tally {
    fn status(&mut self, status: u16, ok: &[u16], shed: &[u16]) {
        if ok.contains(&status) {
            self.ok += 1;
        } else if shed.contains(&status) {
            *self.shed.entry(status).or_default() += 1;
        } else {
            *self.errors.entry(format!("HTTP {status}")).or_default() += 1;
        }
    }

    fn error(&mut self, e: &reqwest::Error) {
        let kind = if e.is_timeout() {
            "client timeout"
        } else if e.is_connect() {
            "connect"
        } else {
            "transport"
        };
        // The innermost cause says where the exchange broke (before the head, mid-body, …).
        let mut cause: &dyn std::error::Error = e;
        while let Some(inner) = cause.source() {
            cause = inner;
        }
        *self.errors.entry(format!("{kind}: {cause}")).or_default() += 1;
    }

    fn merge(&mut self, other: Tally) {
        self.ok += other.ok;
        self.retried += other.retried;
        other.shed.into_iter().for_each(|(k, v)| *self.shed.entry(k).or_default() += v);
        other.errors.into_iter().for_each(|(k, v)| *self.errors.entry(k).or_default() += v);
        self.latencies.extend(other.latencies);
    }

    fn line(&self, class: &str, clients: usize) -> String {
        let errors: u64 = self.errors.values().sum();
        format!(
            "{class:<16} {clients:>3} clients  {:>7} ok  shed {:?}  errors {errors} {:?}  retried {}",
            self.ok, self.shed, self.errors, self.retried
        )
    }
}

/// Sends `req`, and once more when the server closed the connection before answering: what a
/// browser does when a keep-alive it reused was closed as idle meanwhile (RFC 9112 §9.3.1
/// allows it; every upload here is a new bundle, and the same one again would be answered 200).
async fn send(req: reqwest::RequestBuilder, t: &mut Tally) -> reqwest::Result<reqwest::Response> {
    let again = req.try_clone();
    match (req.send().await, again) {
        (Err(e), Some(again)) if !e.is_timeout() && !e.is_connect() => {
            t.retried += 1;
            again.send().await
        }
        (sent, _) => sent,
    }
}

fn client() -> reqwest::Client {
    // One connection per client task: the connection count is the task count.
    reqwest::Client::builder()
        .pool_max_idle_per_host(1)
        .timeout(Duration::from_secs(90))
        .build()
        .expect("a client builds")
}

async fn textures(base: &str) -> Vec<Texture> {
    let list: Value = reqwest::get(format!("{base}/api/v1/textures")).await.unwrap().json().await.unwrap();
    let items = list.get("textures").unwrap_or(&list).as_array().expect("a list of textures").clone();
    items
        .iter()
        .map(|t| Texture {
            id: t["id"].as_str().unwrap().into(),
            model: t["model"].as_str().unwrap().into(),
            width: t["width"].as_u64().unwrap(),
            height: t["height"].as_u64().unwrap(),
            levels: t["levels"].as_u64().unwrap() as u32,
            tile_size: t["tile_size"].as_u64().unwrap(),
        })
        .collect()
}

/// Fetches tiles of a warm set in a loop, timing each.
async fn cached(urls: Arc<Vec<String>>, stop: Arc<AtomicBool>, seed: u64) -> Tally {
    let (http, mut rng, mut t) = (client(), StdRng::seed_from_u64(seed), Tally::default());
    while !stop.load(Relaxed) {
        let url = &urls[rng.random_range(0..urls.len())];
        let start = Instant::now();
        match send(http.get(url), &mut t).await {
            Ok(r) => {
                let status = r.status().as_u16();
                let body = r.bytes().await;
                if body.is_ok() {
                    t.latencies.push(start.elapsed());
                    t.status(status, &[200], &[]);
                } else {
                    *t.errors.entry("body".into()).or_default() += 1;
                }
            }
            Err(e) => t.error(&e),
        }
    }
    t
}

/// Asks for tiles never asked before, of every texture in turn, in every format.
async fn uncached(base: String, texs: Arc<Vec<Texture>>, stop: Arc<AtomicBool>, seed: u64, first: usize) -> Tally {
    let (http, mut rng, mut t) = (client(), StdRng::seed_from_u64(seed), Tally::default());
    let mut i = first;
    while !stop.load(Relaxed) {
        let tex = &texs[i % texs.len()];
        i += 1;
        let level = rng.random_range(0..tex.levels);
        let (cols, rows) = tex.tiles_at(level);
        let ext = ["png", "webp", "jpg", "rgba"][rng.random_range(0..4)];
        let url = tex.tile_url(&base, level, rng.random_range(0..cols), rng.random_range(0..rows), ext);
        match send(http.get(url), &mut t).await {
            Ok(r) => {
                let status = r.status().as_u16();
                match r.bytes().await {
                    Ok(_) => t.status(status, &[200], &[503, 408]),
                    Err(e) => t.error(&e),
                }
            }
            Err(e) => t.error(&e),
        }
    }
    t
}

/// Uploads new textures: a stored bundle renamed, so each upload is a new encoding.
async fn uploads(base: String, bundle: Arc<Vec<u8>>, stop: Arc<AtomicBool>, who: usize) -> Tally {
    let (http, mut t) = (client(), Tally::default());
    let mut b = vtex_synth::bundle::Bundle::from_bytes(&bundle).expect("the server's encoding parses");
    let mut n = 0u64;
    while !stop.load(Relaxed) {
        n += 1;
        b.manifest.name = format!("soak {who}.{n}");
        let req = http
            .post(format!("{base}/api/v1/textures"))
            .header("content-type", "application/octet-stream")
            .body(b.to_bytes());
        match send(req, &mut t).await {
            Ok(r) => {
                let status = r.status().as_u16();
                let _ = r.bytes().await;
                t.status(status, &[201, 200], &[503, 507]);
            }
            Err(e) => t.error(&e),
        }
    }
    t
}

/// What the slow or silent readers of one kind saw.
#[derive(Debug, Default)]
struct Slow {
    bytes: u64,
    /// Answers by status: 200, or 503 when the server's in-flight budget is spent (the
    /// intended answer for this class, never counted as an error).
    answers: BTreeMap<u16, u64>,
    /// Seconds after each request at which the server closed the connection.
    closed_after: Vec<f64>,
}

impl Slow {
    fn merge(&mut self, other: Slow) {
        self.bytes += other.bytes;
        other.answers.into_iter().for_each(|(k, v)| *self.answers.entry(k).or_default() += v);
        self.closed_after.extend(other.closed_after);
    }
}

/// Length of `HTTP/1.1 NNN`: what a reader takes to learn the status.
const STATUS_LINE: usize = 12;

/// Requests a large region and reads it `per_second` bytes a second (0: only its status), until
/// the end of the run; asks again on a new connection when the region is refused or the server
/// closes the connection.
async fn slow_reader(addr: String, path: String, per_second: usize, stop: Arc<AtomicBool>) -> Slow {
    let mut s = Slow::default();
    while !stop.load(Relaxed) {
        slow_request(&addr, &path, per_second, &stop, &mut s).await;
    }
    s
}

/// One request of [`slow_reader`]: until the answer is a refusal, the server closes the
/// connection, or the run ends.
async fn slow_request(addr: &str, path: &str, per_second: usize, stop: &AtomicBool, s: &mut Slow) {
    let Ok(mut sock) = tokio::net::TcpStream::connect(addr).await else {
        return tokio::time::sleep(Duration::from_secs(1)).await;
    };
    let req = format!("GET {path} HTTP/1.1\r\nHost: {addr}\r\n\r\n");
    if sock.write_all(req.as_bytes()).await.is_err() {
        return;
    }
    let start = Instant::now();
    let mut head = Vec::new();
    let mut buf = vec![0u8; per_second.max(STATUS_LINE)];
    while !stop.load(Relaxed) {
        tokio::time::sleep(Duration::from_secs(1)).await;
        // A reset shows here at once; a read would first return what the socket still holds,
        // for a long time at a few bytes a second.
        if sock.take_error().is_ok_and(|e| e.is_some()) {
            s.closed_after.push(start.elapsed().as_secs_f64());
            return;
        }
        let want = match STATUS_LINE.saturating_sub(head.len()) {
            0 if per_second == 0 => continue,
            0 => per_second,
            missing => missing,
        };
        match tokio::time::timeout(Duration::from_millis(100), sock.read(&mut buf[..want])).await {
            Ok(Ok(0)) | Ok(Err(_)) => {
                s.closed_after.push(start.elapsed().as_secs_f64());
                return;
            }
            Ok(Ok(n)) => {
                s.bytes += n as u64;
                if head.len() < STATUS_LINE {
                    head.extend_from_slice(&buf[..n]);
                    if let Some(status) = head.get(9..STATUS_LINE).and_then(|c| std::str::from_utf8(c).ok()) {
                        let status = status.parse().unwrap_or(0);
                        *s.answers.entry(status).or_default() += 1;
                        if status == 503 {
                            return;
                        }
                    }
                }
            }
            Err(_) => {}
        }
    }
    if per_second == 0 {
        // Whether the server is still holding the response for it: drain what is buffered.
        let mut big = vec![0u8; 1 << 20];
        loop {
            match tokio::time::timeout(Duration::from_millis(200), sock.read(&mut big)).await {
                Ok(Ok(0)) | Ok(Err(_)) => {
                    s.closed_after.push(start.elapsed().as_secs_f64());
                    break;
                }
                Ok(Ok(n)) => s.bytes += n as u64,
                Err(_) => break,
            }
        }
    }
}

/// What the attackers of one kind saw.
#[derive(Debug, Default)]
struct Attack {
    /// Connections made.
    made: u64,
    /// Seconds each lived, from its accept (silent) or its answer (keep-alive) until the server
    /// closed it.
    lived: Vec<f64>,
    /// Connections answered 503 (the server full of requests in flight) instead of admitted.
    refused: u64,
}

impl Attack {
    fn merge(&mut self, other: Attack) {
        self.made += other.made;
        self.lived.extend(other.lived);
        self.refused += other.refused;
    }
}

/// How long an attacker waits after the server closes one of its sockets before making the
/// next: enough to keep a slot's worth of pressure without spinning the machine's two cores.
const ATTACKER_PAUSE: Duration = Duration::from_millis(250);

/// Holds one socket open until the end of the run, making it again whenever the server closes
/// it: a silent one (connects, never sends a byte) or, with `keep_alive`, one that is answered
/// once and then sends nothing more.
async fn attacker(addr: String, keep_alive: bool, stop: Arc<AtomicBool>) -> Attack {
    let mut h = Attack::default();
    while !stop.load(Relaxed) {
        let Ok(mut sock) = tokio::net::TcpStream::connect(&addr).await else {
            tokio::time::sleep(ATTACKER_PAUSE).await;
            continue;
        };
        h.made += 1;
        let mut got = Vec::new();
        let mut buf = [0u8; 4096];
        if keep_alive {
            let req = format!("GET /healthz HTTP/1.1\r\nHost: {addr}\r\n\r\n");
            if sock.write_all(req.as_bytes()).await.is_err() {
                continue;
            }
        }
        let mut since = Instant::now();
        // Reads until the server closes the socket or the run ends; a keep-alive's answer
        // (a `/healthz` body ends with `}`) restarts the clock.
        loop {
            let read = tokio::select! {
                r = sock.read(&mut buf) => r,
                () = until(&stop) => break,
            };
            match read {
                Ok(0) | Err(_) => {
                    h.lived.push(since.elapsed().as_secs_f64());
                    break;
                }
                Ok(n) => {
                    got.extend_from_slice(&buf[..n]);
                    if got.starts_with(b"HTTP/1.1 503") {
                        h.refused += 1;
                    } else if keep_alive && got.ends_with(b"}") {
                        since = Instant::now();
                    }
                }
            }
        }
        tokio::time::sleep(ATTACKER_PAUSE).await;
    }
    h
}

/// Resolves once `stop` is set (checked every 100 ms).
async fn until(stop: &AtomicBool) {
    while !stop.load(Relaxed) {
        tokio::time::sleep(Duration::from_millis(100)).await;
    }
}

/// Sums the series of gauge `name` in a metrics exposition (MiB, or a count with `count`).
fn gauge_sum(text: &str, name: &str) -> f64 {
    text.lines()
        .filter(|l| l.split(['{', ' ']).next() == Some(name))
        .filter_map(|l| l.rsplit(' ').next()?.parse::<f64>().ok())
        .sum()
}

/// The server's RSS and its metrics, sampled together.
struct Peak {
    rss_mib: f64,
    metrics: String,
}

/// Samples the server's metrics with its RSS every second until `stop`; returns the sample of
/// the largest RSS.
async fn budgets_at_peak(base: String, pid: u32, stop: Arc<AtomicBool>) -> Option<Peak> {
    let http = client();
    let mut peak: Option<Peak> = None;
    while !stop.load(Relaxed) {
        tokio::time::sleep(Duration::from_secs(1)).await;
        let Ok(r) = http.get(format!("{base}/metrics")).send().await else { continue };
        let (Ok(metrics), Some((rss, _))) = (r.text().await, rss_kb(pid)) else { continue };
        let rss_mib = rss as f64 / 1024.0;
        if peak.as_ref().is_none_or(|p| rss_mib > p.rss_mib) {
            peak = Some(Peak { rss_mib, metrics });
        }
    }
    peak
}

/// The server's connection limit, from its metrics.
async fn connection_limit(base: &str) -> usize {
    let text = reqwest::get(format!("{base}/metrics")).await.unwrap().text().await.unwrap();
    let line = text.lines().find(|l| l.starts_with("vtex_http_connections_max ")).expect("the connection limit");
    line.split_whitespace().nth(1).and_then(|v| v.parse().ok()).expect("a number")
}

/// RSS and its high-water mark (kB) from `/proc/<pid>/status`.
fn rss_kb(pid: u32) -> Option<(u64, u64)> {
    let status = std::fs::read_to_string(format!("/proc/{pid}/status")).ok()?;
    let field =
        |name: &str| status.lines().find(|l| l.starts_with(name))?.split_whitespace().nth(1)?.parse::<u64>().ok();
    Some((field("VmRSS:")?, field("VmHWM:")?))
}

fn percentile(sorted: &[Duration], p: f64) -> f64 {
    if sorted.is_empty() {
        return f64::NAN;
    }
    let i = ((sorted.len() as f64 * p).ceil() as usize).clamp(1, sorted.len()) - 1;
    sorted[i].as_secs_f64() * 1e3
}

#[tokio::main]
async fn main() {
    let args = Args::parse();
    let base = args.url.trim_end_matches('/').to_string();
    let base_ref = base.as_str();
    let addr = base.trim_start_matches("http://").to_string();
    let texs = textures(&base).await;
    assert!(!texs.is_empty(), "the server stores no texture");
    let models: std::collections::BTreeSet<String> = texs.iter().map(|t| t.model.clone()).collect();

    // The warm set: the two coarsest levels' first tile of every texture, all asked at once;
    // the ones that answered (an expensive texture's may run past the deadline) are kept.
    let candidates: Vec<String> = texs
        .iter()
        .flat_map(|t| (t.levels.saturating_sub(2)..t.levels).map(move |l| t.tile_url(base_ref, l, 0, 0, "png")))
        .collect();
    let http = client();
    let asked = candidates.into_iter().map(|url| {
        let http = http.clone();
        tokio::spawn(async move {
            let r = http.get(&url).send().await.ok()?;
            (r.status().as_u16() == 200 && r.bytes().await.is_ok()).then_some(url)
        })
    });
    let warm: Vec<String> = join_all(asked.collect()).await.into_iter().flatten().collect();
    assert!(!warm.is_empty(), "no tile could be warmed");
    let smallest = texs.iter().min_by_key(|t| t.width * t.height).unwrap();
    let bundle = http.get(format!("{base}/api/v1/textures/{}/encoding", smallest.id)).send().await.unwrap();
    let bundle = Arc::new(bundle.bytes().await.unwrap().to_vec());
    let region = format!(
        "/api/v1/textures/{}/region?level=0&x=0&y=0&w=2048&h=2048&format=rgba",
        texs.iter().find(|t| t.model == "chaos-mosaic").unwrap_or(&texs[0]).id
    );

    // The mix, out of `connections`: 1/16 slow readers, 1/16 never-readers, 1/16 uploaders,
    // 3/16 uncached, the rest cached.
    let n = args.connections;
    let (slow, silent, up) = ((n / 16).max(1), (n / 16).max(1), (n / 16).max(1));
    let limit = connection_limit(&base).await;
    let attackers = args.attackers.unwrap_or(limit);
    let cold = (3 * n / 16).max(1);
    let warm_clients = n.saturating_sub(slow + silent + up + cold).max(1);

    let stop = Arc::new(AtomicBool::new(false));
    let samples: Arc<Mutex<Vec<(f64, u64)>>> = Arc::default();
    let sampler = {
        let (stop, samples, pid) = (stop.clone(), samples.clone(), args.pid);
        std::thread::spawn(move || {
            let start = Instant::now();
            while !stop.load(Relaxed) {
                if let Some((rss, _)) = rss_kb(pid) {
                    samples.lock().unwrap().push((start.elapsed().as_secs_f64(), rss));
                }
                std::thread::sleep(Duration::from_millis(100));
            }
        })
    };
    let urls = Arc::new(warm);
    let texs = Arc::new(texs);
    let mut seed = args.seed * 1000;
    let mut next = || {
        seed += 1;
        seed
    };
    let warm_tasks: Vec<_> =
        (0..warm_clients).map(|_| tokio::spawn(cached(urls.clone(), stop.clone(), next()))).collect();
    let cold_tasks: Vec<_> =
        (0..cold).map(|i| tokio::spawn(uncached(base.clone(), texs.clone(), stop.clone(), next(), i))).collect();
    let up_tasks: Vec<_> =
        (0..up).map(|i| tokio::spawn(uploads(base.clone(), bundle.clone(), stop.clone(), i))).collect();
    let slow_tasks: Vec<_> = (0..slow)
        .map(|_| tokio::spawn(slow_reader(addr.clone(), region.clone(), 16, stop.clone())))
        .chain((0..silent).map(|_| tokio::spawn(slow_reader(addr.clone(), region.clone(), 0, stop.clone()))))
        .collect();
    let attack_tasks: Vec<_> = [false, true]
        .iter()
        .flat_map(|&keep_alive| (0..attackers).map(move |_| keep_alive))
        .map(|keep_alive| tokio::spawn(attacker(addr.clone(), keep_alive, stop.clone())))
        .collect();
    let peak_task = tokio::spawn(budgets_at_peak(base.clone(), args.pid, stop.clone()));

    tokio::time::sleep(Duration::from_secs(args.seconds)).await;
    stop.store(true, Relaxed);
    let mut classes = Vec::new();
    for (name, tasks) in [("cached tiles", warm_tasks), ("uncached tiles", cold_tasks), ("uploads", up_tasks)] {
        let clients = tasks.len();
        let mut t = Tally::default();
        join_all(tasks).await.into_iter().for_each(|one| t.merge(one));
        classes.push((name, clients, t));
    }
    let slow_seen: Vec<Slow> = join_all(slow_tasks).await;
    let held: Vec<Attack> = join_all(attack_tasks).await;
    let peak = peak_task.await.unwrap();
    sampler.join().unwrap();

    let samples = samples.lock().unwrap();
    let max_rss = samples.iter().map(|s| s.1).max().unwrap_or(0) as f64 / 1024.0;
    let hwm = rss_kb(args.pid).map(|r| r.1 as f64 / 1024.0).unwrap_or(f64::NAN);
    let bound = args.budget_mb * 1.2;
    println!(
        "{} s at {n} connections and {} attackers' sockets (connection limit {limit}); {} textures of models {:?}; {} \
         cached tiles in the warm set",
        args.seconds,
        2 * attackers,
        texs.len(),
        models,
        urls.len()
    );
    for (name, clients, t) in &classes {
        println!("{}", t.line(name, *clients));
    }
    let mut lat = classes[0].2.latencies.clone();
    lat.sort();
    println!(
        "cached tiles: {} requests, p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms",
        lat.len(),
        percentile(&lat, 0.50),
        percentile(&lat, 0.99),
        percentile(&lat, 1.0)
    );
    let mut slow_seen = slow_seen.into_iter();
    for (kind, clients) in [("slow readers (16 B/s)", slow), ("never-readers", silent)] {
        let mut seen = Slow::default();
        slow_seen.by_ref().take(clients).for_each(|one| seen.merge(one));
        let closed: Vec<String> = seen.closed_after.iter().map(|c| format!("{c:.0} s")).collect();
        println!(
            "{kind}: {clients} clients, {} bytes read in all; answers {:?} (503: the in-flight budget spent, \
             as intended); connections closed by the server: {} (after {})",
            seen.bytes,
            seen.answers,
            closed.len(),
            closed.join(", ")
        );
    }
    let mut held = held.into_iter();
    for kind in ["silent sockets", "idle keep-alives"] {
        let mut seen = Attack::default();
        held.by_ref().take(attackers).for_each(|one| seen.merge(one));
        let mut lived = seen.lived.clone();
        lived.sort_by(f64::total_cmp);
        let at = |p: f64| lived.get(((lived.len() as f64 * p) as usize).min(lived.len().saturating_sub(1)));
        println!(
            "attackers, {kind}: {attackers} held, {} connections made, {} closed by the server \
             (after p50 {:.3} s, p99 {:.3} s, max {:.3} s), {} answered 503",
            seen.made,
            lived.len(),
            at(0.5).copied().unwrap_or(f64::NAN),
            at(0.99).copied().unwrap_or(f64::NAN),
            lived.last().copied().unwrap_or(f64::NAN),
            seen.refused
        );
    }
    println!(
        "RSS: {} samples every 100 ms, max {max_rss:.1} MiB (VmHWM {hwm:.1} MiB); budgets {:.1} MiB + 20 % = {bound:.1} MiB: {}",
        samples.len(),
        args.budget_mb,
        if max_rss <= bound { "within" } else { "OVER" }
    );
    if let Some(p) = peak {
        let mib = |name: &str| gauge_sum(&p.metrics, name) / (1024.0 * 1024.0);
        println!(
            "at the largest RSS sampled with the metrics (every second), {:.1} MiB: tile cache {:.1} MiB (+{:.1} \
             still sent outside it; {:.1} mapped), textures loaded {:.1} MiB, bodies in flight {:.1} MiB, model caches {:.1} MiB; {} connections",
            p.rss_mib,
            mib("vtex_tile_cache_bytes"),
            mib("vtex_tile_cache_outside_bytes"),
            mib("vtex_tile_cache_mapped_bytes"),
            mib("vtex_textures_loaded_bytes"),
            mib("vtex_inflight_bytes"),
            mib("vtex_model_cache_bytes"),
            gauge_sum(&p.metrics, "vtex_http_connections")
        );
    }
    let well_behaved_errors: u64 = classes.iter().map(|c| c.2.errors.values().sum::<u64>()).sum();
    println!("well-behaved clients' errors: {well_behaved_errors}");
}

async fn join_all<T>(tasks: Vec<tokio::task::JoinHandle<T>>) -> Vec<T> {
    let mut out = Vec::with_capacity(tasks.len());
    for t in tasks {
        out.push(t.await.unwrap());
    }
    out
}
