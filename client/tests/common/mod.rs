//! What the client's integration tests share: a real `vtex serve`, a texture uploaded to it, a
//! scripted socket for retries, and Debian's nginx terminating TLS (HTTP/2) in front of them
//! with certificates made by the `openssl` command for the test.

#![allow(dead_code)]

use std::io::{BufRead, BufReader, Read, Write};
use std::net::{TcpListener, TcpStream};
use std::path::{Path, PathBuf};
use std::process::{Child, Command, Stdio};
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};
use vtex_client::PageAddr;

/// `vtex serve` on a free port over a fresh data directory, killed when dropped.
pub struct Server {
    child: Child,
    pub base: String,
    _dir: tempfile::TempDir,
}

impl Drop for Server {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// The `vtex` binary beside this test's own directory (`target/<profile>/`).
pub fn vtex_binary() -> PathBuf {
    let exe = std::env::current_exe().unwrap();
    let bin = exe.parent().unwrap().parent().unwrap().join("vtex");
    assert!(bin.exists(), "{} is missing: build it with `cargo build -p vtex-server` (same profile)", bin.display());
    bin
}

pub fn serve() -> Server {
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
pub async fn upload(base: &str) -> String {
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

pub fn addrs(level: u32, n: u32) -> Vec<PageAddr> {
    (0..n * n).map(|i| PageAddr { level, x: i % n, y: i / n }).collect()
}

/// A socket that answers its first `failures` requests with `status` (Retry-After: 0), then a
/// page; counts the requests.
pub fn scripted(failures: usize, status: u16) -> (String, Arc<AtomicUsize>) {
    scripted_after(failures, status, 0)
}

/// [`scripted`] with `Retry-After: retry_after` (seconds).
pub fn scripted_after(failures: usize, status: u16, retry_after: u64) -> (String, Arc<AtomicUsize>) {
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
                    "HTTP/1.1 {status} X\r\nretry-after: {retry_after}\r\ncontent-length: {}\r\nconnection: close\r\n\r\n",
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

/// A certificate authority made for a test (`openssl`), and a server certificate it signed
/// for `127.0.0.1` and `localhost`.
pub struct Pki {
    pub dir: tempfile::TempDir,
}

impl Pki {
    pub fn ca_pem(&self) -> Vec<u8> {
        std::fs::read(self.dir.path().join("ca.pem")).unwrap()
    }
    pub fn cert(&self) -> PathBuf {
        self.dir.path().join("server.pem")
    }
    pub fn key(&self) -> PathBuf {
        self.dir.path().join("server.key")
    }
}

fn openssl(dir: &Path, args: &[&str]) {
    let out =
        Command::new("openssl").args(args).current_dir(dir).output().expect("the openssl command (Debian: openssl)");
    assert!(out.status.success(), "openssl {args:?}: {}", String::from_utf8_lossy(&out.stderr));
}

/// A CA (P-256, a day) and a server certificate it signed (`serverAuth`, not a CA).
pub fn pki() -> Pki {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    let ec = ["-newkey", "ec", "-pkeyopt", "ec_paramgen_curve:prime256v1", "-nodes"];
    let mut ca = vec!["req", "-x509", "-days", "1", "-subj", "/CN=vtex test CA", "-keyout", "ca.key", "-out", "ca.pem"];
    ca.extend(ec);
    ca.extend(["-addext", "basicConstraints=critical,CA:TRUE", "-addext", "keyUsage=critical,keyCertSign,cRLSign"]);
    openssl(d, &ca);
    let mut csr = vec!["req", "-new", "-subj", "/CN=localhost", "-keyout", "server.key", "-out", "server.csr"];
    csr.extend(ec);
    openssl(d, &csr);
    std::fs::write(
        d.join("server.ext"),
        "basicConstraints=critical,CA:FALSE\nkeyUsage=critical,digitalSignature\nextendedKeyUsage=serverAuth\nsubjectAltName=IP:127.0.0.1,DNS:localhost\n",
    )
    .unwrap();
    openssl(
        d,
        &[
            "x509",
            "-req",
            "-in",
            "server.csr",
            "-CA",
            "ca.pem",
            "-CAkey",
            "ca.key",
            "-CAcreateserial",
            "-days",
            "1",
            "-extfile",
            "server.ext",
            "-out",
            "server.pem",
        ],
    );
    Pki { dir }
}

/// Debian's nginx (or `$NGINX`) terminating TLS with HTTP/2 on three ports, each proxying to
/// plain HTTP: `pass` to `vtex` as is; `no_cache` to `vtex` with `Cache-Control: no-cache` in
/// place of the server's (so a client must revalidate what it holds); `scripted` to the
/// `scripted` upstream. Its access log names the port, protocol and status of every request.
pub struct Nginx {
    child: Child,
    pub dir: tempfile::TempDir,
    pub pass: String,
    pub no_cache: String,
    pub scripted: String,
}

impl Drop for Nginx {
    fn drop(&mut self) {
        let _ = self.child.kill();
        let _ = self.child.wait();
    }
}

/// One request of nginx's access log.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Logged {
    pub port: u16,
    pub protocol: String,
    pub status: u16,
    pub uri: String,
    pub bytes: u64,
}

impl Nginx {
    /// The requests logged so far. nginx writes a request's line as it ends, which may be just
    /// after its client has the answer: the log is read until it holds still for 150 ms.
    pub fn log(&self) -> Vec<Logged> {
        let read = || std::fs::read_to_string(self.dir.path().join("access.log")).unwrap_or_default();
        let mut text = read();
        let mut still = Instant::now();
        while still.elapsed() < Duration::from_millis(150) {
            std::thread::sleep(Duration::from_millis(25));
            let now = read();
            if now != text {
                (text, still) = (now, Instant::now());
            }
        }
        text.lines()
            .map(|l| {
                let f: Vec<&str> = l.split(' ').collect();
                Logged {
                    port: f[0].parse().unwrap(),
                    protocol: f[1].to_string(),
                    status: f[2].parse().unwrap(),
                    uri: f[3].to_string(),
                    bytes: f[4].parse().unwrap(),
                }
            })
            .collect()
    }

    /// The requests logged on `base`'s port.
    pub fn log_of(&self, base: &str) -> Vec<Logged> {
        let port: u16 = base.rsplit(':').next().unwrap().parse().unwrap();
        self.log().into_iter().filter(|l| l.port == port).collect()
    }
}

fn free_port() -> u16 {
    TcpListener::bind("127.0.0.1:0").unwrap().local_addr().unwrap().port()
}

/// Whether this nginx has the `http2` directive (1.25.1 on); older ones (Debian 12's 1.22)
/// take `http2` as a parameter of `listen`.
fn http2_directive(nginx: &str) -> bool {
    let out = Command::new(nginx).arg("-v").output().expect("nginx (Debian: nginx)");
    let text = String::from_utf8_lossy(&out.stderr);
    let version = text.split('/').nth(1).unwrap_or("0").split_whitespace().next().unwrap_or("0").to_string();
    let v: Vec<u32> = version.split('.').map(|n| n.parse().unwrap_or(0)).collect();
    (v[0], v.get(1).copied().unwrap_or(0), v.get(2).copied().unwrap_or(0)) >= (1, 25, 1)
}

/// nginx in front of `vtex` and `scripted` (`http://host:port`), with `pki`'s certificate.
pub fn nginx(vtex: &str, scripted: &str, pki: &Pki) -> Nginx {
    let bin = std::env::var("NGINX").unwrap_or_else(|_| "/usr/sbin/nginx".into());
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path().display().to_string();
    let ports = [free_port(), free_port(), free_port()];
    let (listen, directive) = match http2_directive(&bin) {
        true => ("ssl", "http2 on;"),
        false => ("ssl http2", ""),
    };
    let server = |port: u16, upstream: &str, extra: &str| {
        format!(
            "server {{ listen 127.0.0.1:{port} {listen}; {directive}
                ssl_certificate {cert}; ssl_certificate_key {key};
                location / {{ proxy_pass {upstream}; proxy_http_version 1.1; proxy_buffering off; {extra} }} }}\n",
            cert = pki.cert().display(),
            key = pki.key().display(),
        )
    };
    let vtex = vtex.trim_end_matches('/');
    let conf = format!(
        "daemon off; worker_processes 1; pid {d}/nginx.pid; error_log {d}/error.log;
        events {{ worker_connections 256; }}
        http {{
            log_format test '$server_port $server_protocol $status $request_uri $body_bytes_sent';
            access_log {d}/access.log test;
            client_body_temp_path {d}/body; proxy_temp_path {d}/proxy; fastcgi_temp_path {d}/fastcgi;
            uwsgi_temp_path {d}/uwsgi; scgi_temp_path {d}/scgi;
            {}{}{}
        }}\n",
        server(ports[0], vtex, ""),
        server(ports[1], vtex, "proxy_hide_header Cache-Control; add_header Cache-Control no-cache always;"),
        server(ports[2], scripted.trim_end_matches('/'), ""),
    );
    std::fs::write(dir.path().join("nginx.conf"), conf).unwrap();
    let child = Command::new(&bin)
        .args(["-p", &d, "-c"])
        .arg(dir.path().join("nginx.conf"))
        .stdout(Stdio::null())
        .stderr(Stdio::piped())
        .spawn()
        .unwrap();
    let start = Instant::now();
    while !ports.iter().all(|p| TcpStream::connect(("127.0.0.1", *p)).is_ok()) {
        assert!(
            start.elapsed() < Duration::from_secs(10),
            "nginx did not listen: {}",
            std::fs::read_to_string(dir.path().join("error.log")).unwrap_or_default()
        );
        std::thread::sleep(Duration::from_millis(20));
    }
    let base = |p: u16| format!("https://127.0.0.1:{p}");
    Nginx { child, pass: base(ports[0]), no_cache: base(ports[1]), scripted: base(ports[2]), dir }
}
