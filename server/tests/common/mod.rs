//! Test harness: the real `vtex` binary on a real socket, and helpers to talk to it.
#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::TcpStream;
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::time::{Duration, Instant};
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, Inputs};

pub const BIN: &str = env!("CARGO_BIN_EXE_vtex");

/// A running `vtex serve`, killed when dropped.
///
/// The server inherits the test's environment, so `VTEX_SEND=copy|splice` picks the transport
/// of every server the suites start (`scripts/test` runs them under both); [`Server::start`]
/// checks that the server runs the one asked for.
pub struct Server {
    pub child: Child,
    pub base: String,
    pub addr: String,
    pub data_dir: PathBuf,
    pub log: PathBuf,
}

impl Server {
    /// Starts `vtex serve` on a free port of 127.0.0.1 (unless `extra` has a `--bind`) over
    /// `data_dir` with `extra` flags (no demos unless `--demos` is among them), and waits for
    /// its `vtex listening on` line.
    pub fn start(data_dir: &Path, extra: &[&str]) -> Server {
        Self::start_env(data_dir, extra, &[])
    }

    /// [`Server::start`] with extra environment variables.
    pub fn start_env(data_dir: &Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        Self::start_under(&[], data_dir, extra, env)
    }

    /// [`Server::start_env`] run through a `wrapper` command that executes it in its own
    /// process (e.g. `prlimit --nofile=128:128 --`), so the pid stays the server's.
    pub fn start_under(wrapper: &[&str], data_dir: &Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        let log = data_dir.with_extension(format!("log-{}", std::process::id()));
        let mut args = vec!["serve", "--data-dir", data_dir.to_str().unwrap()];
        if !extra.contains(&"--bind") {
            args.extend(["--bind", "127.0.0.1:0"]);
        }
        let demos = extra.contains(&"--demos");
        args.extend(extra.iter().filter(|a| **a != "--demos"));
        if !demos {
            args.push("--no-demos");
        }
        let mut cmd = match wrapper.split_first() {
            Some((program, rest)) => {
                let mut c = Command::new(program);
                c.args(rest).arg(BIN);
                c
            }
            None => Command::new(BIN),
        };
        let mut child = cmd
            .args(&args)
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
        Server { child, base, addr, data_dir: data_dir.to_path_buf(), log }
    }

    pub fn url(&self, path: &str) -> String {
        format!("{}{}", self.base, path)
    }

    pub fn tile_url(&self, id: &str, level: u32, x: u32, y: u32, fmt: &str) -> String {
        self.url(&format!("/api/v1/textures/{id}/tiles/{level}/{x}/{y}.{fmt}"))
    }

    /// Sends SIGTERM and waits for the exit status.
    pub fn terminate(mut self) -> std::process::ExitStatus {
        let pid = self.child.id().to_string();
        Command::new("kill").args(["-TERM", &pid]).status().unwrap();
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            if let Some(s) = self.child.try_wait().unwrap() {
                return s;
            }
            assert!(Instant::now() < deadline, "server did not exit after SIGTERM");
            std::thread::sleep(Duration::from_millis(20));
        }
    }

    pub fn kill9(mut self) {
        self.child.kill().unwrap();
        self.child.wait().unwrap();
    }

    pub fn is_running(&mut self) -> bool {
        self.child.try_wait().unwrap().is_none()
    }

    /// The server's log so far (plain text: not a terminal, so no colours).
    pub fn log_text(&self) -> String {
        std::fs::read_to_string(&self.log).unwrap_or_default()
    }
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
        let _ = std::fs::remove_file(&self.log);
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

pub async fn metrics(c: &reqwest::Client, s: &Server) -> String {
    c.get(s.url("/metrics")).send().await.unwrap().text().await.unwrap()
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
    s.write_all(request).unwrap();
    let mut out = Vec::new();
    let _ = s.read_to_end(&mut out);
    String::from_utf8_lossy(&out).into_owned()
}
