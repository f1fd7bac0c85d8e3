//! Protected writes over real sockets: the write token, read-only mode, DELETE, the CORS
//! policy of writes, and readiness beside liveness.

use crate::support::*;
use serde_json::{json, Value};

const TOKEN: &str = "s3cret-Token_42";

async fn error_of(r: reqwest::Response, status: u16) -> String {
    assert_eq!(r.status().as_u16(), status);
    assert_eq!(r.headers()["content-type"], "application/json");
    let v: Value = r.json().await.unwrap();
    v["error"].as_str().unwrap_or_else(|| panic!("no error message in {v}")).to_string()
}

fn post_bundle(c: &reqwest::Client, s: &Server, bytes: Vec<u8>) -> reqwest::RequestBuilder {
    c.post(s.url("/api/v1/textures")).header("content-type", "application/octet-stream").body(bytes)
}

#[tokio::test]
async fn writes_need_the_token_when_one_is_set() {
    let dir = tempdir();
    let s = Server::spawn_env(dir.path(), &[], &[("VTEX_WRITE_TOKEN", TOKEN)]);
    let c = client();
    let bundle = mosaic(32, 8, 1).to_bytes();

    let r = post_bundle(&c, &s, bundle.clone()).send().await.unwrap();
    assert!(r.headers()["www-authenticate"].to_str().unwrap().starts_with("Bearer"));
    let msg = error_of(r, 401).await;
    assert!(msg.contains("write token") && msg.contains("Bearer"), "{msg}");
    for wrong in ["Bearer nope", "Basic czNjcmV0", &format!("Bearer {TOKEN}x"), TOKEN] {
        let r = post_bundle(&c, &s, bundle.clone()).header("authorization", wrong).send().await.unwrap();
        assert!(error_of(r, 401).await.contains("wrong"), "{wrong}");
    }
    assert!(store_files(dir.path()).is_empty(), "a refused write stored something");

    let r = post_bundle(&c, &s, bundle.clone()).bearer_auth(TOKEN).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let id = r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string();
    // Reads need no token.
    let (status, _, _) = get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "png")).await;
    assert_eq!(status, 200);

    let texture = s.url(&format!("/api/v1/textures/{id}"));
    let r = c.patch(&texture).json(&json!({"name": "renamed"})).send().await.unwrap();
    error_of(r, 401).await;
    let r = c.delete(&texture).send().await.unwrap();
    error_of(r, 401).await;
    let r = c.patch(&texture).bearer_auth(TOKEN).json(&json!({"name": "renamed"})).send().await.unwrap();
    assert_eq!(r.status(), 201);
}

#[tokio::test]
async fn the_token_can_come_from_a_file() {
    let dir = tempdir();
    let file = dir.path().with_extension("token");
    std::fs::write(&file, format!("{TOKEN}\n")).unwrap();
    let s = Server::spawn(dir.path(), &["--write-token-file", file.to_str().unwrap()]);
    let c = client();
    let r = post_bundle(&c, &s, mosaic(32, 8, 1).to_bytes()).send().await.unwrap();
    error_of(r, 401).await;
    let r = post_bundle(&c, &s, mosaic(32, 8, 1).to_bytes()).bearer_auth(TOKEN).send().await.unwrap();
    assert_eq!(r.status(), 201);
    drop(s);
    std::fs::remove_file(&file).unwrap();
}

#[tokio::test]
async fn delete_removes_the_texture_for_good() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(32, 8, 2)).await;
    let keep = put(&c, &s, &mosaic(32, 8, 3)).await;
    let tile = s.tile_url(&id, 0, 0, 0, "png");
    assert_eq!(get_bytes(&c, &tile).await.0, 200, "the texture is loaded and its tile cached");

    let r = c.delete(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(store_files(dir.path()), vec![format!("{keep}.vtex")]);
    for path in
        ["", "/encoding", "/tiles/0/0/0.png", "/tiles?format=png&tiles=0/0/0", "/region?level=0&x=0&y=0&w=8&h=8"]
    {
        let msg = expect_error(&c, &s.url(&format!("/api/v1/textures/{id}{path}")), 404).await;
        assert!(msg.contains(&id), "{path}: {msg}");
    }
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    let ids: Vec<&str> = list["textures"].as_array().unwrap().iter().map(|t| t["id"].as_str().unwrap()).collect();
    assert_eq!(ids, vec![keep.as_str()]);
    let again = c.delete(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap();
    assert!(error_of(again, 404).await.contains(&id));
    let bad = c.delete(s.url("/api/v1/textures/not-an-id")).send().await.unwrap();
    assert!(error_of(bad, 400).await.contains("invalid texture id"));
    // Deleted, then uploaded again: served again.
    assert_eq!(put(&c, &s, &mosaic(32, 8, 2)).await, id);
    assert_eq!(get_bytes(&c, &tile).await.0, 200);
}

#[tokio::test]
async fn read_only_refuses_every_write_naming_the_mode() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
    let id = put(&client(), &s, &mosaic(32, 8, 4)).await;
    drop(s);
    let s = Server::spawn_env(dir.path(), &["--read-only"], &[("VTEX_WRITE_TOKEN", TOKEN)]);
    let c = client();
    let texture = s.url(&format!("/api/v1/textures/{id}"));
    let refused = [
        post_bundle(&c, &s, mosaic(32, 8, 5).to_bytes()).bearer_auth(TOKEN),
        c.patch(&texture).bearer_auth(TOKEN).json(&json!({"name": "x"})),
        c.delete(&texture).bearer_auth(TOKEN),
    ];
    for req in refused {
        let msg = error_of(req.send().await.unwrap(), 403).await;
        assert!(msg.contains("read-only"), "{msg}");
    }
    assert_eq!(store_files(dir.path()), vec![format!("{id}.vtex")]);
    assert_eq!(get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "png")).await.0, 200);
}

#[tokio::test]
async fn cors_allows_writes_only_from_configured_origins() {
    let dir = tempdir();
    let good = "https://editor.example";
    let s = Server::spawn(dir.path(), &["--cors-write-origins", &format!("{good},https://other.example")]);
    let c = client();
    let preflight = |origin: &str, method: &str| {
        c.request(reqwest::Method::OPTIONS, s.url("/api/v1/textures"))
            .header("origin", origin)
            .header("access-control-request-method", method)
            .header("access-control-request-headers", "authorization, content-type")
            .send()
    };
    // A write preflight from a page of another origin is refused: the browser never writes.
    for method in ["POST", "PATCH", "DELETE"] {
        let r = preflight("https://evil.example", method).await.unwrap();
        let allowed = r.headers().get("access-control-allow-methods").map(|v| v.to_str().unwrap().to_string());
        assert!(allowed.as_ref().is_none_or(|m| !m.contains(method)), "{method}: {allowed:?}");
        assert!(error_of(r, 403).await.contains("https://evil.example"));
    }
    let r = preflight(good, "POST").await.unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(r.headers()["access-control-allow-origin"], good);
    assert!(r.headers()["access-control-allow-methods"].to_str().unwrap().contains("POST"));
    assert!(r.headers()["access-control-allow-headers"].to_str().unwrap().contains("authorization"));
    // Reads stay open to every origin.
    let r = preflight("https://evil.example", "GET").await.unwrap();
    assert!(r.status().is_success());
    assert_eq!(r.headers()["access-control-allow-origin"], "*");

    // A write sent without a preflight (a form POST) from another origin is refused too;
    // from a configured origin, the server's own pages or a client without Origin it passes.
    let bundle = |seed| mosaic(32, 8, seed).to_bytes();
    let r = post_bundle(&c, &s, bundle(6)).header("origin", "https://evil.example").send().await.unwrap();
    assert!(error_of(r, 403).await.contains("--cors-write-origins"));
    assert!(store_files(dir.path()).is_empty());
    let own = format!("http://{}", s.addr);
    for (seed, origin) in [(6, Some(good)), (7, Some(own.as_str())), (8, None)] {
        let mut req = post_bundle(&c, &s, bundle(seed));
        if let Some(origin) = origin {
            req = req.header("origin", origin);
        }
        assert_eq!(req.send().await.unwrap().status(), 201, "{origin:?}");
    }
}

#[tokio::test]
async fn without_configured_origins_no_cross_origin_write_is_allowed() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
    let c = client();
    let r = c
        .request(reqwest::Method::OPTIONS, s.url("/api/v1/textures"))
        .header("origin", "https://anywhere.example")
        .header("access-control-request-method", "POST")
        .send()
        .await
        .unwrap();
    error_of(r, 403).await;
    let r = post_bundle(&c, &s, mosaic(32, 8, 9).to_bytes()).header("origin", "null").send().await.unwrap();
    error_of(r, 403).await;
}

#[tokio::test]
async fn readiness_follows_the_data_directory_and_liveness_does_not() {
    let dir = tempdir();
    let data = dir.path().join("data");
    let s = Server::spawn(&data, &[]);
    let c = client();
    put(&c, &s, &mosaic(32, 8, 10)).await;
    let ready: Value = c.get(s.url("/readyz")).send().await.unwrap().json().await.unwrap();
    assert_eq!(ready, json!({"status": "ready", "textures": 1}));
    std::fs::rename(&data, dir.path().join("moved")).unwrap();
    let msg = error_of(c.get(s.url("/readyz")).send().await.unwrap(), 503).await;
    assert!(msg.contains("data directory"), "{msg}");
    assert_eq!(c.get(s.url("/healthz")).send().await.unwrap().status(), 200, "alive all the same");
    std::fs::rename(dir.path().join("moved"), &data).unwrap();
    assert_eq!(c.get(s.url("/readyz")).send().await.unwrap().status(), 200);
}

/// Without a token, loopback clients write: over IPv4, over IPv6, and as IPv4 clients of a
/// dual-stack listener (whose peer is `::ffff:127.0.0.1`).
#[tokio::test]
async fn without_a_token_loopback_clients_write() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--bind", "[::]:0"]);
    let port = s.addr.rsplit_once(':').unwrap().1;
    let c = client();
    for (seed, host) in [(11, "127.0.0.1"), (12, "[::1]")] {
        let r = c
            .post(format!("http://{host}:{port}/api/v1/textures"))
            .header("content-type", "application/octet-stream")
            .body(mosaic(32, 8, seed).to_bytes())
            .send()
            .await
            .unwrap();
        assert_eq!(r.status(), 201, "{host}");
    }
    assert!(s.log_text().contains("writes: from loopback clients only"), "{}", s.log_text());
}

/// A network namespace of this test's own, whose loopback device also carries [`OUTSIDE`]:
/// a client there connecting from that address is a peer that is not loopback, on one machine
/// and without touching the host's network. Removed when dropped.
struct NetNs(String);

/// The namespace's address that is not loopback (TEST-NET-1, RFC 5737: never routed).
const OUTSIDE: &str = "192.0.2.1";

impl NetNs {
    /// The namespace, or `None` where it cannot be made (not root, no `ip`): then the tests
    /// that need one say so, and fail under CI, where `scripts/test` runs as root with iproute2.
    fn new() -> Option<NetNs> {
        static MADE: std::sync::atomic::AtomicU32 = std::sync::atomic::AtomicU32::new(0);
        let n = MADE.fetch_add(1, std::sync::atomic::Ordering::Relaxed);
        let ns = NetNs(format!("vtex-writes-{}-{n}", std::process::id()));
        let ip = |args: &[&str]| std::process::Command::new("ip").args(args).output().is_ok_and(|o| o.status.success());
        let made = ip(&["netns", "add", &ns.0])
            && ip(&["-n", &ns.0, "link", "set", "lo", "up"])
            && ip(&["-n", &ns.0, "addr", "add", &format!("{OUTSIDE}/32"), "dev", "lo"]);
        if !made {
            assert!(std::env::var_os("CI").is_none(), "CI must test non-loopback peers: run as root with iproute2");
            eprintln!("cannot make a network namespace (root and iproute2 needed): non-loopback writes NOT tested");
            return None;
        }
        Some(ns)
    }

    /// Starts vtex inside the namespace, on every address of it.
    fn serve(&self, data_dir: &std::path::Path, extra: &[&str], env: &[(&str, &str)]) -> Server {
        let mut args = vec!["--bind", "0.0.0.0:0"];
        args.extend(extra);
        Server::spawn_under(&["ip", "netns", "exec", &self.0], data_dir, &args, env)
    }

    /// One raw HTTP/1.1 exchange with `s` from inside the namespace, from `from` (an address of
    /// the namespace); returns the status and the whole response.
    fn send(
        &self,
        s: &Server,
        from: &str,
        method: &str,
        path: &str,
        headers: &[(&str, &str)],
        body: &[u8],
    ) -> (u16, String) {
        let port = s.addr.rsplit_once(':').unwrap().1;
        let mut req = format!("{method} {path} HTTP/1.1\r\nhost: {from}:{port}\r\nconnection: close\r\n");
        for (k, v) in headers {
            req.push_str(&format!("{k}: {v}\r\n"));
        }
        let mut req = format!("{req}content-length: {}\r\n\r\n", body.len()).into_bytes();
        req.extend_from_slice(body);
        let netns = std::fs::File::open(format!("/run/netns/{}", self.0)).unwrap();
        // A thread of its own enters the namespace: its sockets are the namespace's, the other
        // threads' are not.
        let resp = std::thread::scope(|scope| {
            scope
                .spawn(|| {
                    use std::os::fd::AsRawFd;
                    // SAFETY: `setns` on a descriptor this function holds open; it changes the
                    // network namespace of the calling thread only.
                    let entered = unsafe { libc::setns(netns.as_raw_fd(), libc::CLONE_NEWNET) };
                    assert_eq!(entered, 0, "setns: {}", std::io::Error::last_os_error());
                    raw_request(&format!("{from}:{port}"), &req)
                })
                .join()
                .unwrap()
        });
        let status = resp.split(' ').nth(1).and_then(|s| s.parse().ok()).unwrap_or_else(|| panic!("{resp:?}"));
        (status, resp)
    }
}

impl Drop for NetNs {
    fn drop(&mut self) {
        let _ = std::process::Command::new("ip").args(["netns", "del", &self.0]).status();
    }
}

const BUNDLE: (&str, &str) = ("content-type", "application/octet-stream");

/// Without a token, a client that is not on loopback is refused every write with a 403 that
/// says how to set a token; reads stay open to it, and loopback clients of the same server
/// still write.
#[test]
fn without_a_token_other_clients_are_refused_writes() {
    let Some(ns) = NetNs::new() else { return };
    let dir = tempdir();
    let s = ns.serve(dir.path(), &[], &[]);
    let bundle = mosaic(32, 8, 13).to_bytes();
    let (status, resp) = ns.send(&s, OUTSIDE, "POST", "/api/v1/textures", &[BUNDLE], &bundle);
    assert_eq!(status, 403, "{resp}");
    assert!(resp.to_ascii_lowercase().contains("content-type: application/json"), "{resp}");
    let error: Value = serde_json::from_str(resp.split_once("\r\n\r\n").unwrap().1).unwrap();
    let msg = error["error"].as_str().unwrap();
    for needed in [OUTSIDE, "loopback", "VTEX_WRITE_TOKEN", "--write-token-file", "Bearer", "--open-writes"] {
        assert!(msg.contains(needed), "{needed}: {msg}");
    }
    assert!(store_files(dir.path()).is_empty(), "a refused write stored something");

    let (status, resp) = ns.send(&s, "127.0.0.1", "POST", "/api/v1/textures", &[BUNDLE], &bundle);
    assert_eq!(status, 201, "{resp}");
    let id = vtex_synth::bundle::id_of(&bundle);
    let texture = format!("/api/v1/textures/{id}");
    assert_eq!(ns.send(&s, OUTSIDE, "GET", &format!("{texture}/tiles/0/0/0.png"), &[], b"").0, 200);
    let rename = br#"{"name": "x"}"#;
    assert_eq!(ns.send(&s, OUTSIDE, "PATCH", &texture, &[("content-type", "application/json")], rename).0, 403);
    assert_eq!(ns.send(&s, OUTSIDE, "DELETE", &texture, &[], b"").0, 403);
    assert_eq!(store_files(dir.path()), vec![format!("{id}.vtex")]);
    assert!(s.log_text().contains("write refused"), "{}", s.log_text());
}

/// With a token, every client writes with it, and none without it, wherever it connects from.
#[test]
fn the_token_lets_any_client_write() {
    let Some(ns) = NetNs::new() else { return };
    let dir = tempdir();
    let s = ns.serve(dir.path(), &[], &[("VTEX_WRITE_TOKEN", TOKEN)]);
    let bundle = mosaic(32, 8, 14).to_bytes();
    let bearer = format!("Bearer {TOKEN}");
    for from in [OUTSIDE, "127.0.0.1"] {
        let (status, resp) = ns.send(&s, from, "POST", "/api/v1/textures", &[BUNDLE], &bundle);
        assert_eq!(status, 401, "{from}: {resp}");
        assert!(resp.contains("write token"), "{resp}");
    }
    let (status, resp) =
        ns.send(&s, OUTSIDE, "POST", "/api/v1/textures", &[BUNDLE, ("authorization", &bearer)], &bundle);
    assert_eq!(status, 201, "{resp}");
    assert!(s.log_text().contains("writes: with the write token"), "{}", s.log_text());
}

/// `--open-writes` accepts writes from every client without a token, and says so at start-up
/// as a warning; it cannot be combined with a token.
#[test]
fn open_writes_accept_every_client_and_warn() {
    let Some(ns) = NetNs::new() else { return };
    let dir = tempdir();
    let s = ns.serve(dir.path(), &["--open-writes"], &[]);
    let (status, resp) = ns.send(&s, OUTSIDE, "POST", "/api/v1/textures", &[BUNDLE], &mosaic(32, 8, 15).to_bytes());
    assert_eq!(status, 201, "{resp}");
    let log = s.log_text();
    let warning = log.lines().find(|l| l.contains("--open-writes")).unwrap_or_else(|| panic!("{log}"));
    assert!(warning.contains("WARN") && warning.contains("OPEN"), "{warning}");

    // Under `timeout`: a server that accepted the pair would run on.
    let out = std::process::Command::new("timeout")
        .args(["60", BIN, "serve", "--open-writes", "--bind", "127.0.0.1:0", "--no-demos", "--data-dir"])
        .arg(dir.path())
        .env("VTEX_WRITE_TOKEN", TOKEN)
        .output()
        .unwrap();
    assert!(!out.status.success());
    let said = String::from_utf8_lossy(&out.stderr);
    assert!(said.contains("--open-writes") && said.contains("cannot be used with"), "{said}");
}
