//! Several `vtex serve` processes on one data directory (replicas on a shared volume): a
//! texture written by any of them, or copied into the directory, is served by all; a deletion
//! reaches all; replicas starting together on an empty directory do not collide.

use crate::support::*;
use serde_json::Value;
use std::time::{Duration, Instant};

async fn listed(c: &reqwest::Client, s: &Server) -> Vec<String> {
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    list["textures"].as_array().unwrap().iter().map(|t| t["id"].as_str().unwrap().to_string()).collect()
}

/// Waits (up to 10 s) until `s` lists `id` (or, with `present` false, no longer does).
async fn until_listed(c: &reqwest::Client, s: &Server, id: &str, present: bool) {
    let deadline = Instant::now() + Duration::from_secs(10);
    while listed(c, s).await.iter().any(|i| i == id) != present {
        assert!(Instant::now() < deadline, "{} did not {} {id}", s.base, if present { "list" } else { "drop" });
        tokio::time::sleep(Duration::from_millis(20)).await;
    }
}

/// Without any watch, a replica finds a texture another one wrote on the first request for
/// it, and serves the very same bytes.
#[tokio::test]
async fn a_miss_looks_in_the_shared_directory() {
    let dir = tempdir();
    let a = Server::spawn(dir.path(), &[]);
    let b = Server::spawn(dir.path(), &["--watch", "off"]);
    let c = client();
    let unknown = "0".repeat(64);
    assert!(expect_error(&c, &b.url(&format!("/api/v1/textures/{unknown}")), 404).await.contains(&unknown));

    let id = put(&c, &a, &mosaic(48, 8, 1)).await;
    for path in ["", "/encoding"] {
        let (status, _, _) = get_bytes(&c, &b.url(&format!("/api/v1/textures/{id}{path}"))).await;
        assert_eq!(status, 200, "{path}");
    }
    for (level, x, y) in [(0, 1, 1), (0, 0, 1), (1, 0, 0)] {
        let (sa, _, ta) = get_bytes(&c, &a.tile_url(&id, level, x, y, "png")).await;
        let (sb, _, tb) = get_bytes(&c, &b.tile_url(&id, level, x, y, "png")).await;
        assert_eq!((sa, sb), (200, 200));
        assert_eq!(ta, tb, "replicas disagree on tile {level}/{x}/{y}");
    }
    assert_eq!(listed(&c, &b).await, vec![id.clone()], "found on a miss, then listed");
    // Deleted through `b`: gone from `b` at once, its cached tile included.
    let r = c.delete(b.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(get_bytes(&c, &b.tile_url(&id, 0, 1, 1, "png")).await.0, 404);
    assert!(listed(&c, &b).await.is_empty());
}

/// With the watch (the default), the texture list of every replica follows uploads, copies
/// and deletions made by others.
#[tokio::test]
async fn the_watch_keeps_every_replica_list_in_step() {
    let dir = tempdir();
    let a = Server::spawn(dir.path(), &[]);
    let b = Server::spawn(dir.path(), &[]);
    let c = client();
    let id = put(&c, &a, &mosaic(48, 8, 2)).await;
    until_listed(&c, &b, &id, true).await;
    let tile = |s: &Server| s.tile_url(&id, 0, 0, 0, "webp");
    assert_eq!(get_bytes(&c, &tile(&b)).await.0, 200, "b loads it");

    // An operator copies a bundle in (under a temporary name, then renamed into place).
    let copied = mosaic(48, 8, 3);
    let copied_id = vtex_synth::bundle::id_of(&copied.to_bytes());
    let tmp = dir.path().join(".tmp-operator-copy");
    std::fs::write(&tmp, copied.to_bytes()).unwrap();
    std::fs::rename(&tmp, dir.path().join(format!("{copied_id}.vtex"))).unwrap();
    until_listed(&c, &a, &copied_id, true).await;
    until_listed(&c, &b, &copied_id, true).await;

    // Deleted through `a`: `b`, which had it loaded, drops it from its list and its tiles.
    let r = c.delete(a.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap();
    assert_eq!(r.status(), 204);
    until_listed(&c, &b, &id, false).await;
    assert_eq!(get_bytes(&c, &tile(&b)).await.0, 404);
    assert_eq!(listed(&c, &a).await, vec![copied_id.clone()]);
    assert_eq!(listed(&c, &b).await, vec![copied_id]);
}

/// Three replicas started at once on an empty directory each write the demos: they do not
/// collide (no failed start, no temporary left, each demo once) and all end up serving all.
#[tokio::test]
async fn replicas_starting_together_seed_the_demos_once() {
    let dir = tempdir();
    let path = dir.path().to_path_buf();
    let starting: Vec<_> = (0..3)
        .map(|_| {
            let path = path.clone();
            std::thread::spawn(move || Server::spawn(&path, &["--demos"]))
        })
        .collect();
    let replicas: Vec<Server> = starting.into_iter().map(|t| t.join().expect("a replica failed to start")).collect();
    let files = store_files(dir.path());
    assert!(files.iter().all(|f| f.ends_with(".vtex") && !f.starts_with(".tmp-")), "{files:?}");
    let demos = vtex_synth::models::demos().len();
    assert_eq!(files.len(), demos, "{files:?}");
    let c = client();
    for s in &replicas {
        let deadline = Instant::now() + Duration::from_secs(10);
        while listed(&c, s).await.len() != demos {
            assert!(Instant::now() < deadline, "{} lists {} of {demos} demos", s.base, listed(&c, s).await.len());
            tokio::time::sleep(Duration::from_millis(20)).await;
        }
    }
}
