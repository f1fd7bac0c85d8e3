//! What both test binaries share: servers to test against (in this process, or the real
//! `vtex` binary as a process) and helpers to talk to them.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, Inputs};

pub const BIN: &str = env!("CARGO_BIN_EXE_vtex");

/// A `vtex serve` on a real socket of 127.0.0.1: in this process ([`Server::start`]) or the
/// real binary ([`Server::spawn`]). Stopped when dropped.
pub struct Server {
    pub base: String,
    pub addr: String,
    pub data_dir: PathBuf,
    run: Run,
}

enum Run {
    /// Served by threads of this process until the sender is dropped.
    InProcess(Option<tokio::sync::oneshot::Sender<()>>),
    Process {
        child: Child,
        log: PathBuf,
    },
}

/// The arguments of `vtex serve` over `data_dir` with `extra` flags: a free port of 127.0.0.1
/// unless `extra` has a `--bind`, no demos unless `--demos` is among them.
fn serve_args(data_dir: &Path, extra: &[&str]) -> Vec<String> {
    let mut args = vec!["serve".to_string(), "--data-dir".into(), data_dir.display().to_string()];
    if !extra.contains(&"--bind") {
        args.extend(["--bind".into(), "127.0.0.1:0".into()]);
    }
    args.extend(extra.iter().filter(|a| **a != "--demos").map(|a| a.to_string()));
    if !extra.contains(&"--demos") {
        args.push("--no-demos".into());
    }
    args
}

impl Server {
    /// `vtex serve` over `data_dir` with `extra` flags (see [`serve_args`]), served by threads
    /// of this process, without the viewer unless `extra` names a `--web-dir`. Its transport is
    /// `VTEX_SEND`'s, as the binary's would be.
    pub fn start(data_dir: &Path, extra: &[&str]) -> Server {
        use vtex_server::cli::{Cli, Command};
        let mut args = vec!["vtex".to_string()];
        args.extend(serve_args(data_dir, extra));
        if !extra.contains(&"--web-dir") {
            args.extend(["--web-dir".into(), data_dir.join("no-web-dir").display().to_string()]);
        }
        let Command::Serve(cfg) = <Cli as clap::Parser>::try_parse_from(&args).unwrap().command else {
            unreachable!("a serve command line")
        };
        if let Ok(send) = std::env::var("VTEX_SEND") {
            assert!(extra.contains(&"--send") || cfg.send.to_string() == send, "VTEX_SEND={send}, not {}", cfg.send);
        }
        let (stop, stopped) = tokio::sync::oneshot::channel::<()>();
        let (tx, rx) = std::sync::mpsc::channel();
        let failed = tx.clone();
        std::thread::spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread().enable_all().build().unwrap();
            let listening = move |addr| Ok(tx.send(Ok(addr))?);
            let result = rt.block_on(vtex_server::serve::run(*cfg, async { _ = stopped.await }, listening));
            rt.shutdown_background();
            if let Err(e) = result {
                let _ = failed.send(Err(format!("{e:#}")));
            }
        });
        let addr = match rx.recv_timeout(Duration::from_secs(120)) {
            Ok(Ok(addr)) => addr.to_string(),
            Ok(Err(e)) => panic!("server did not start: {e}"),
            Err(e) => panic!("server did not start: {e}"),
        };
        let run = Run::InProcess(Some(stop));
        Server { base: format!("http://{addr}"), addr, data_dir: data_dir.to_path_buf(), run }
    }

    /// The real `vtex serve` as a process over `data_dir` with `extra` flags (see
    /// [`serve_args`]), once it prints its `vtex listening on` line.
    ///
    /// The server inherits the test's environment, so `VTEX_SEND=copy|splice` picks the
    /// transport (`scripts/test` runs this binary under both); this checks that the server runs
    /// the one asked for.
    pub fn spawn(data_dir: &Path, extra: &[&str]) -> Server {
        Self::spawn_env(data_dir, extra, &[])
    }

    /// [`Server::spawn`] with extra environment variables.
    pub fn spawn_env(data_dir: &Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        Self::spawn_under(&[], data_dir, extra, env)
    }

    /// [`Server::spawn_env`] run through a `wrapper` command that executes it in its own
    /// process (e.g. `prlimit --nofile=128:128 --`), so the pid stays the server's.
    pub fn spawn_under(wrapper: &[&str], data_dir: &Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        let log = data_dir.with_extension(format!("log-{}", std::process::id()));
        let mut cmd = match wrapper.split_first() {
            Some((program, rest)) => {
                let mut c = Command::new(program);
                c.args(rest).arg(BIN);
                c
            }
            None => Command::new(BIN),
        };
        let mut child = cmd
            .args(serve_args(data_dir, extra))
            .env_remove("VTEX_BIND")
            .env("VTEX_WEB_DIR", data_dir.join("no-web-dir"))
            .env("VTEX_LOG", "info")
            .envs(env.iter().copied())
            .stdout(Stdio::piped())
            .stderr(std::fs::File::create(&log).unwrap())
            .spawn()
            .expect("spawn vtex");
        let stdout = child.stdout.take().unwrap();
        let (tx, rx) = std::sync::mpsc::channel();
        std::thread::spawn(move || {
            let mut line = String::new();
            let _ = BufReader::new(stdout).read_line(&mut line);
            let _ = tx.send(line);
        });
        let line = rx.recv_timeout(Duration::from_secs(120)).unwrap_or_default();
        let Some(base) = line.trim().strip_prefix("vtex listening on ") else {
            let _ = child.kill();
            panic!("server did not start: {:?}\n{}", line, std::fs::read_to_string(&log).unwrap_or_default());
        };
        // The `serving` line, logged before the address is printed, names the transport.
        let asked = env.iter().find(|(k, _)| *k == "VTEX_SEND").map(|(_, v)| v.to_string());
        if let Some(send) = asked.or_else(|| std::env::var("VTEX_SEND").ok()).filter(|_| !extra.contains(&"--send")) {
            let log = std::fs::read_to_string(&log).unwrap_or_default();
            assert!(log.contains(&format!("send={send}")), "the server does not run VTEX_SEND={send}:\n{log}");
        }
        let base = base.to_string();
        let addr = base.trim_start_matches("http://").to_string();
        Server { base, addr, data_dir: data_dir.to_path_buf(), run: Run::Process { child, log } }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    pub fn tile_url(&self, id: &str, level: u32, x: u32, y: u32, fmt: &str) -> String {
        self.url(&format!("/api/v1/textures/{id}/tiles/{level}/{x}/{y}.{fmt}"))
    }

    /// The process of a [`Server::spawn`]ed server.
    pub fn child(&mut self) -> &mut Child {
        match &mut self.run {
            Run::Process { child, .. } => child,
            Run::InProcess(_) => panic!("a server in this process has no child process: spawn it"),
        }
    }

    /// The process id of a [`Server::spawn`]ed server.
    pub fn pid(&self) -> u32 {
        match &self.run {
            Run::Process { child, .. } => child.id(),
            Run::InProcess(_) => panic!("a server in this process has no process of its own: spawn it"),
        }
    }

    /// Sends SIGTERM and waits for the exit status.
    pub fn terminate(mut self) -> std::process::ExitStatus {
        let pid = self.pid().to_string();
        Command::new("kill").args(["-TERM", &pid]).status().unwrap();
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            if let Some(s) = self.child().try_wait().unwrap() {
                return s;
            }
            assert!(Instant::now() < deadline, "server did not exit after SIGTERM");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    pub fn kill9(mut self) {
        self.child().kill().unwrap();
        self.child().wait().unwrap();
    }

    pub fn is_running(&mut self) -> bool {
        self.child().try_wait().unwrap().is_none()
    }

    /// The log so far of a [`Server::spawn`]ed server (plain text: not a terminal, so no
    /// colours).
    pub fn log_text(&self) -> String {
        match &self.run {
            Run::Process { log, .. } => std::fs::read_to_string(log).unwrap_or_default(),
            Run::InProcess(_) => panic!("a server in this process logs nowhere a test reads: spawn it"),
        }
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        match &mut self.run {
            // Shutdown starts; requests still in flight finish on the server's own threads.
            Run::InProcess(stop) => drop(stop.take()),
            Run::Process { child, log } => {
                let _ = child.kill();
                let _ = child.wait();
                let _ = std::fs::remove_file(log);
            }
        }
    }
}

pub fn tempdir() -> tempfile::TempDir {
    tempfile::Builder::new().prefix("vtex-test-").tempdir().unwrap()
}

/// A client that asks for no compression and decodes none (the suites compare exact bytes).
pub fn client() -> reqwest::Client {
    reqwest::Client::builder().timeout(Duration::from_secs(120)).no_gzip().no_brotli().no_zstd().build().unwrap()
}

/// A chaos mosaic bundle from a project-made sample: `tiles`² tiles of a `side`² sample.
pub fn mosaic(side: u32, tiles: u32, seed: u64) -> Bundle {
    let sample = vtex_synth::samples::pebbles(side, 12, seed, true);
    let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
    let params = serde_json::json!({"tiles_x": tiles, "tiles_y": tiles, "iterations": 10, "seed": seed});
    models::create("chaos-mosaic", &format!("test mosaic {side}×{tiles} #{seed}"), &params, &inputs).unwrap()
}

pub fn sample_png(side: u32, seed: u64) -> Vec<u8> {
    vtex_synth::samples::pebbles(side, 12, seed, true).to_png()
}

/// `s` with one small chaos mosaic uploaded: the server, the texture's id, and the store's files.
pub async fn with_one_texture(s: Server) -> (Server, String, Vec<String>) {
    let id = put(&client(), &s, &mosaic(32, 8, 1)).await;
    let files = store_files(&s.data_dir);
    (s, id, files)
}

/// Uploads raw bundle bytes; returns (status, JSON body).
pub async fn upload(c: &reqwest::Client, s: &Server, bytes: Vec<u8>) -> (u16, serde_json::Value) {
    let r = c
        .post(s.url("/api/v1/textures"))
        .header("content-type", "application/octet-stream")
        .body(bytes)
        .send()
        .await
        .unwrap();
    let status = r.status().as_u16();
    (status, r.json().await.unwrap())
}

/// Uploads a bundle and returns its id (asserting success).
pub async fn put(c: &reqwest::Client, s: &Server, b: &Bundle) -> String {
    let (status, body) = upload(c, s, b.to_bytes()).await;
    assert!(status == 201 || status == 200, "{status} {body}");
    body["id"].as_str().unwrap().to_string()
}

/// GET with extra request `headers`: (status, headers, body).
pub async fn get_with(
    c: &reqwest::Client,
    url: &str,
    headers: &[(&str, &str)],
) -> (u16, reqwest::header::HeaderMap, Vec<u8>) {
    let mut req = c.get(url);
    for (k, v) in headers {
        req = req.header(*k, *v);
    }
    let r = req.send().await.unwrap();
    let (status, h) = (r.status().as_u16(), r.headers().clone());
    (status, h, r.bytes().await.unwrap().to_vec())
}

pub async fn get_bytes(c: &reqwest::Client, url: &str) -> (u16, reqwest::header::HeaderMap, Vec<u8>) {
    let r = c.get(url).send().await.unwrap();
    let status = r.status().as_u16();
    let headers = r.headers().clone();
    (status, headers, r.bytes().await.unwrap().to_vec())
}

/// GET expecting a JSON error with `status`; returns the message.
pub async fn expect_error(c: &reqwest::Client, url: &str, status: u16) -> String {
    let r = c.get(url).send().await.unwrap();
    assert_eq!(r.status().as_u16(), status, "{url}");
    assert_eq!(r.headers()["content-type"], "application/json", "{url}");
    let v: serde_json::Value = r.json().await.unwrap();
    v["error"].as_str().unwrap_or_else(|| panic!("no error message in {v}")).to_string()
}

/// The value of one Prometheus series, e.g. `metric(&text, "vtex_syntheses_total", &[])`, summed
/// over the series matching `labels`; 0 when none does. The family must be exposed (a `# TYPE`
/// line), so that a misspelt or renamed metric fails rather than reads as 0.
pub fn metric(text: &str, name: &str, labels: &[(&str, &str)]) -> f64 {
    let family = ["_bucket", "_sum", "_count"].iter().find_map(|s| name.strip_suffix(s));
    let typed =
        |n: &str| text.lines().any(|l| l.strip_prefix("# TYPE ").is_some_and(|t| t.split(' ').next() == Some(n)));
    assert!(typed(name) || family.is_some_and(typed), "no metric {name} in the exposition:\n{text}");
    let mut total = 0.0;
    let mut found = false;
    for line in text.lines().filter(|l| !l.starts_with('#')) {
        let (series, value) = line.rsplit_once(' ').unwrap();
        let (n, rest) = series.split_once('{').unwrap_or((series, ""));
        if n != name {
            continue;
        }
        if labels.iter().all(|(k, v)| rest.contains(&format!("{k}=\"{v}\""))) {
            total += value.parse::<f64>().unwrap();
            found = true;
        }
    }
    if found {
        total
    } else {
        0.0
    }
}

/// The exposition of a server that has served an upload, tiles (hits and misses) and an
/// error: most series carry values.
pub async fn busy_exposition(s: &Server) -> String {
    let c = client();
    let id = put(&c, s, &mosaic(64, 16, 1)).await;
    for (x, y) in [(0, 0), (1, 0), (0, 0)] {
        assert_eq!(get_bytes(&c, &s.tile_url(&id, 0, x, y, "png")).await.0, 200);
    }
    assert_eq!(get_bytes(&c, &s.url("/api/v1/textures/nope")).await.0, 400);
    let r = c.get(s.url("/metrics")).send().await.unwrap();
    assert_eq!(r.headers()["content-type"], "text/plain; version=0.0.4");
    r.text().await.unwrap()
}

/// `(name, type)` of every family, from its `# TYPE` line.
pub fn families(text: &str) -> Vec<(&str, &str)> {
    text.lines().filter_map(|l| l.strip_prefix("# TYPE ")?.split_once(' ')).collect()
}

pub async fn metrics(c: &reqwest::Client, s: &Server) -> String {
    c.get(s.url("/metrics")).send().await.unwrap().text().await.unwrap()
}

/// The multipart upload of a model's example (from its document), named `name`, with the
/// input images fetched from the server.
pub async fn post_example(c: &reqwest::Client, s: &Server, doc: &serde_json::Value, name: &str) -> reqwest::Response {
    let mut form = reqwest::multipart::Form::new()
        .text("model", doc["id"].as_str().unwrap().to_string())
        .text("name", name.to_string())
        .text("params", doc["example"]["params"].to_string());
    for (input, how) in doc["example"]["inputs"].as_object().unwrap() {
        let href = how["href"].as_str().unwrap();
        assert!(href.starts_with(&s.url("/api/v1/models/")), "an absolute URL on this server: {href}");
        let (status, headers, png) = get_bytes(c, href).await;
        assert_eq!(status, 200, "{input} of {}", doc["id"]);
        assert_eq!(headers["content-type"], "image/png");
        assert!(!how["what"].as_str().unwrap().is_empty());
        form = form.part(input.clone(), reqwest::multipart::Part::bytes(png).file_name(format!("{input}.png")));
    }
    c.post(s.url("/api/v1/textures")).multipart(form).send().await.unwrap()
}
/// Bytes a loaded `bundle` is charged against the texture budget: what its plan states.
pub fn resident(bundle: &Bundle) -> u64 {
    models::plan(bundle).unwrap().cost.resident_bytes.value
}
/// `--textures-mb` for a budget of `bytes`.
pub fn mib(bytes: u64) -> String {
    format!("{}", bytes as f64 / (1024.0 * 1024.0))
}

/// The value of the unlabelled series `name` in `s`'s exposition now.
pub async fn gauge(c: &reqwest::Client, s: &Server, name: &str) -> f64 {
    metric(&metrics(c, s).await, name, &[])
}

/// Every `*.vtex` and temporary file in the data directory, sorted: the store's state.
pub fn store_files(dir: &Path) -> Vec<String> {
    let mut names: Vec<String> = std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().file_name().to_string_lossy().into_owned())
        .filter(|n| n.ends_with(".vtex") || n.starts_with(".tmp-"))
        .collect();
    names.sort();
    names
}

/// One raw HTTP/1.1 exchange on a fresh connection; returns the whole response text.
pub fn raw_request(addr: &str, request: &[u8]) -> String {
    let mut s = TcpStream::connect(addr).unwrap();
    s.set_read_timeout(Some(Duration::from_secs(30))).unwrap();
    // A connection the server closed before the request was written answers nothing.
    let _ = s.write_all(request);
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    String::from_utf8_lossy(&out).into_owned()
}
