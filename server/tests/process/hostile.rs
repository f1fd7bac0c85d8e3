//! Invariant 6 where it takes a process: a SIGKILL mid-upload stores nothing partial, SIGTERM
//! drains requests in flight, and what the store refuses (corrupt files, failed storage) is
//! logged.

use crate::support::*;
use serde_json::Value;
use std::io::Write;
use std::net::TcpStream;
use std::time::Duration;

#[tokio::test]
async fn sigkill_mid_upload_leaves_no_partial_bundle() {
    let dir = tempdir();
    let (s, _, files) = with_one_texture(Server::spawn(dir.path(), &[])).await;
    let bundle = mosaic(64, 8, 9).to_bytes();
    let mut stream = TcpStream::connect(&s.addr).unwrap();
    let head = format!(
        "POST /api/v1/textures HTTP/1.1\r\nHost: x\r\nContent-Type: application/octet-stream\r\nContent-Length: {}\r\n\r\n",
        bundle.len()
    );
    stream.write_all(head.as_bytes()).unwrap();
    stream.write_all(&bundle[..bundle.len() / 2]).unwrap();
    std::thread::sleep(Duration::from_millis(300));
    s.kill9();
    assert_eq!(store_files(dir.path()), files, "no partial bundle after SIGKILL");
    // A crash during a write leaves at most a temporary file: the next start removes it.
    // (It is old: a young one may be another replica's write in progress, and is left alone.)
    let crashed = dir.path().join(".tmp-4242-0-crashed.vtex");
    std::fs::write(&crashed, &bundle[..bundle.len() / 3]).unwrap();
    let long_ago = std::time::SystemTime::now() - vtex_server::store::STALE_TEMP_AGE * 2;
    std::fs::File::options().write(true).open(&crashed).unwrap().set_modified(long_ago).unwrap();
    let s = Server::spawn(dir.path(), &[]);
    assert_eq!(store_files(dir.path()), files, "stale temporary file removed at start");
    assert!(s.log_text().contains("stale_temp_removed=1") || s.log_text().contains("stale_temp_removed"));
    let list: Value = client().get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    assert_eq!(list["textures"].as_array().unwrap().len(), 1);
    // The interrupted upload succeeds when retried.
    let (status, _) = upload(&client(), &s, bundle).await;
    assert_eq!(status, 201);
}

#[tokio::test]
async fn corrupt_files_in_the_data_dir_are_not_served() {
    let dir = tempdir();
    let (s, id, _) = with_one_texture(Server::spawn(dir.path(), &[])).await;
    drop(s);
    // Flip one byte of the stored bundle: its hash no longer matches its name.
    let path = dir.path().join(format!("{id}.vtex"));
    let mut bytes = std::fs::read(&path).unwrap();
    let n = bytes.len();
    bytes[n - 10] ^= 0xff;
    std::fs::write(&path, &bytes).unwrap();
    std::fs::write(dir.path().join("notes.vtex"), b"not a bundle").unwrap();
    let s = Server::spawn(dir.path(), &[]);
    let c = client();
    let msg = expect_error(&c, &s.url(&format!("/api/v1/textures/{id}")), 404).await;
    assert!(msg.contains("no texture"));
    assert!(s.log_text().contains("not serving an invalid bundle"), "{}", s.log_text());
    assert!(path.exists(), "corrupt files are left for an operator, never deleted");
}

#[tokio::test]
async fn sigterm_drains_requests_in_flight() {
    let dir = tempdir();
    let (s, id, _) = with_one_texture(Server::spawn(dir.path(), &[])).await;
    let url = s.url(&format!("/api/v1/textures/{id}/region?level=0&x=0&y=0&w=4096&h=4096&format=png"));
    let pending = tokio::spawn(async move {
        let resp = client().get(url).send().await.unwrap();
        (resp.status(), resp.bytes().await.unwrap())
    });
    tokio::time::sleep(Duration::from_millis(150)).await;
    let status = tokio::task::spawn_blocking(move || s.terminate()).await.unwrap();
    let (code, body) = pending.await.unwrap();
    assert_eq!(code, 200, "the request in flight completed");
    let img = image::load_from_memory(&body).unwrap();
    assert_eq!((img.width(), img.height()), (4096, 4096));
    assert_eq!(status.code(), Some(0), "clean exit after SIGTERM");
}

/// A storage failure is the server's fault: a 500 whose message says what failed and nothing
/// of the cause (no path, no OS error), while the log keeps the cause.
#[tokio::test]
async fn storage_failures_answer_a_generic_500() {
    let root = tempdir();
    let dir = root.path().join("data");
    std::fs::create_dir(&dir).unwrap();
    let s = Server::spawn(&dir, &[]);
    // The data directory vanishes under the server (it runs as root in CI, where permissions
    // would not stop it): storing a bundle now fails in the file system.
    std::fs::remove_dir_all(&dir).unwrap();
    let (status, body) = upload(&client(), &s, mosaic(32, 8, 9).to_bytes()).await;
    assert_eq!(status, 500, "{body}");
    let msg = body["error"].as_str().unwrap();
    assert_eq!(msg, "internal server error: storing the bundle failed");
    let log = s.log_text();
    assert!(log.contains("storing the bundle failed") && log.contains("os error"), "the cause is logged: {log}");
    assert_eq!(client().get(s.url("/healthz")).send().await.unwrap().status(), 200);
}
