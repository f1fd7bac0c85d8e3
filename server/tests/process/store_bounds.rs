//! The store's bounds where a test reads the server's log: a texture over the budget, a
//! bundle invalid at first use, a stale temporary file start-up cannot remove.

use crate::support::*;

/// A texture that alone holds more than the budget is refused at upload (422 naming it), and a
/// stored one is not served by a server whose budget it passes.
#[tokio::test]
async fn a_texture_alone_over_the_budget_is_refused() {
    let big = mosaic(64, 8, 5);
    let small_budget = mib(resident(&big) / 2);
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &["--textures-mb", &small_budget]);
    let (status, body) = upload(&client(), &s, big.to_bytes()).await;
    assert_eq!(status, 422, "{body}");
    let msg = body["error"].as_str().unwrap();
    assert!(msg.contains("chaos-mosaic") && msg.contains("resident bytes") && msg.contains("bound"), "{msg}");
    assert!(store_files(dir.path()).is_empty());
    drop(s);

    let s = Server::spawn(dir.path(), &[]);
    let id = put(&client(), &s, &big).await;
    drop(s);
    let s = Server::spawn(dir.path(), &["--textures-mb", &small_budget]);
    expect_error(&client(), &s.url(&format!("/api/v1/textures/{id}")), 404).await;
    let log = s.log_text();
    assert!(log.contains("not serving an invalid bundle") && log.contains("resident bytes"), "{log}");
}

/// A bundle that fails validation when it is first loaded is logged, dropped from the index, and
/// its request answered with a JSON error; the server goes on serving the others.
#[tokio::test]
async fn a_bundle_invalid_at_first_use_is_dropped() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
    let c = client();
    let (bad, good) = (put(&c, &s, &mosaic(64, 8, 1)).await, put(&c, &s, &mosaic(64, 8, 2)).await);
    drop(s);
    let s = Server::spawn(dir.path(), &[]);
    // Changed on disk after it was indexed: it no longer matches its id.
    let path = dir.path().join(format!("{bad}.vtex"));
    let mut bytes = std::fs::read(&path).unwrap();
    let n = bytes.len();
    bytes[n - 10] ^= 0xff;
    std::fs::write(&path, &bytes).unwrap();
    let msg = expect_error(&c, &s.tile_url(&bad, 0, 0, 0, "png"), 500).await;
    assert!(msg.contains("failed validation") && msg.contains("no longer served"), "{msg}");
    assert!(s.log_text().contains("no longer serving it"), "{}", s.log_text());
    expect_error(&c, &s.url(&format!("/api/v1/textures/{bad}")), 404).await;
    let (status, _, _) = get_bytes(&c, &s.tile_url(&good, 0, 0, 0, "png")).await;
    assert_eq!(status, 200);
    assert_eq!(gauge(&c, &s, "vtex_textures").await, 1.0);
    assert!(path.exists(), "invalid files are left for an operator, never deleted");
}

/// A stale temporary entry that cannot be removed (a non-empty directory: `remove_file` fails
/// on it even as root) is logged and left; the server starts and serves.
#[tokio::test]
async fn start_up_survives_a_stale_temp_it_cannot_remove() {
    let dir = tempdir();
    let stuck = dir.path().join(".tmp-4242-0-stuck.vtex");
    std::fs::create_dir(&stuck).unwrap();
    std::fs::write(stuck.join("inside"), b"x").unwrap();
    let long_ago = std::time::SystemTime::now() - vtex_server::store::STALE_TEMP_AGE * 2;
    std::fs::File::open(&stuck).unwrap().set_modified(long_ago).unwrap();
    let s = Server::spawn(dir.path(), &[]);
    let id = put(&client(), &s, &mosaic(32, 8, 1)).await;
    let (status, _, _) = get_bytes(&client(), &s.tile_url(&id, 0, 0, 0, "png")).await;
    assert_eq!(status, 200);
    let log = s.log_text();
    assert!(log.contains("could not remove a stale temporary file") && log.contains(".tmp-4242-0-stuck"), "{log}");
}
