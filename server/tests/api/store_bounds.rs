//! The store under bounds: lazy loading within the texture budget, the limits on uploads, the
//! store's caps (507), and the small defects of the store (one 201, stale temporary files,
//! names on every path) — each over a real socket.

use crate::support::*;
use serde_json::{json, Value};
use std::path::Path;
use vtex_synth::bundle::Bundle;

/// Four textures whose summed resident bytes are over a budget each fits in alone: rendering a
/// tile of each in turn loads and evicts them, the bytes they hold never pass the budget, and
/// every texture still answers.
#[tokio::test]
async fn loaded_textures_stay_within_the_budget() {
    let bundles: Vec<Bundle> = (1..=4).map(|seed| mosaic(64, 8, seed)).collect();
    let largest = bundles.iter().map(resident).max().unwrap();
    let sum: u64 = bundles.iter().map(resident).sum();
    assert!(largest > 0, "the cost model states no resident bytes");
    let budget = largest * 3 / 2;
    assert!(sum > budget);
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--textures-mb", &mib(budget)]);
    let c = client();
    let budget = gauge(&c, &s, "vtex_textures_budget_bytes").await;
    let mut ids = Vec::new();
    for b in &bundles {
        ids.push(put(&c, &s, b).await);
        assert!(gauge(&c, &s, "vtex_textures_loaded_bytes").await <= budget);
    }
    for round in 0..2 {
        for id in &ids {
            let (status, _, _) = get_bytes(&c, &s.tile_url(id, 0, round, 0, "rgba")).await;
            assert_eq!(status, 200, "{id}");
            let held = gauge(&c, &s, "vtex_textures_loaded_bytes").await;
            assert!(held > 0.0 && held <= budget, "{held} bytes held over a budget of {budget}");
        }
    }
    let m = metrics(&c, &s).await;
    assert!(metric(&m, "vtex_texture_evictions_total", &[]) >= 4.0, "{m}");
    assert!(metric(&m, "vtex_textures_loaded", &[]) < 4.0, "{m}");
    assert_eq!(metric(&m, "vtex_textures", &[]), 4.0);
}

/// Textures load on first use, not at start; concurrent first uses share one load.
#[tokio::test]
async fn textures_load_on_first_use_once() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let ids = [put(&c, &s, &mosaic(64, 8, 1)).await, put(&c, &s, &mosaic(64, 8, 2)).await];
    drop(s);
    let s = Server::start(dir.path(), &[]);
    let m = metrics(&c, &s).await;
    assert_eq!(metric(&m, "vtex_textures", &[]), 2.0);
    assert_eq!((metric(&m, "vtex_textures_loaded", &[]), metric(&m, "vtex_texture_loads_total", &[])), (0.0, 0.0));
    // Info, lists and encodings are answered from the index.
    let (status, _, _) = get_bytes(&c, &s.url(&format!("/api/v1/textures/{}", ids[0]))).await;
    assert_eq!(status, 200);
    get_bytes(&c, &s.url("/api/v1/textures")).await;
    assert_eq!(gauge(&c, &s, "vtex_texture_loads_total").await, 0.0);
    let urls: Vec<String> = (0..4).map(|i| s.tile_url(&ids[0], 0, i % 2, i / 2, "png")).collect();
    let answers = futures::future::join_all(urls.iter().map(|u| get_bytes(&c, u))).await;
    assert!(answers.iter().all(|(status, _, _)| *status == 200));
    let m = metrics(&c, &s).await;
    assert_eq!(
        (metric(&m, "vtex_textures_loaded", &[]), metric(&m, "vtex_texture_loads_total", &[])),
        (1.0, 1.0),
        "{m}"
    );
}

/// `--max-textures` and `--store-mb`: an upload past either is a 507 naming the cap; what is
/// already stored is still a 200.
#[tokio::test]
async fn store_caps_answer_507() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--max-textures", "2"]);
    let c = client();
    let first = mosaic(32, 8, 1);
    put(&c, &s, &first).await;
    put(&c, &s, &mosaic(32, 8, 2)).await;
    let (status, body) = upload(&c, &s, mosaic(32, 8, 3).to_bytes()).await;
    assert_eq!(status, 507, "{body}");
    assert!(body["error"].as_str().unwrap().contains("--max-textures"), "{body}");
    assert_eq!(upload(&c, &s, first.to_bytes()).await.0, 200, "a bundle already stored is not refused");
    assert_eq!(store_files(dir.path()).len(), 2);
    drop(s);

    let dir = tempdir();
    let bundles: Vec<Vec<u8>> = (1..=3).map(|seed| mosaic(32, 8, seed).to_bytes()).collect();
    let room = bundles[0].len() + bundles[1].len() + bundles[2].len() / 2;
    let s = Server::start(dir.path(), &["--store-mb", &mib(room as u64)]);
    assert_eq!(upload(&c, &s, bundles[0].clone()).await.0, 201);
    assert_eq!(upload(&c, &s, bundles[1].clone()).await.0, 201);
    let (status, body) = upload(&c, &s, bundles[2].clone()).await;
    assert_eq!(status, 507, "{body}");
    assert!(body["error"].as_str().unwrap().contains("--store-mb"), "{body}");
    assert_eq!(store_files(dir.path()).len(), 2, "nothing written, no temporary file left");
    assert_eq!(gauge(&c, &s, "vtex_store_bytes").await, (bundles[0].len() + bundles[1].len()) as f64);
}

/// A file system of `size` mounted on a new directory, unmounted when dropped.
struct Tmpfs(tempfile::TempDir);

impl Tmpfs {
    fn mount(size: &str) -> Result<Tmpfs, String> {
        let dir = tempdir();
        let out = std::process::Command::new("mount")
            .args(["-t", "tmpfs", "-o", &format!("size={size}"), "tmpfs"])
            .arg(dir.path())
            .output()
            .map_err(|e| e.to_string())?;
        match out.status.success() {
            true => Ok(Tmpfs(dir)),
            false => Err(String::from_utf8_lossy(&out.stderr).into_owned()),
        }
    }

    fn path(&self) -> &Path {
        self.0.path()
    }
}

impl Drop for Tmpfs {
    fn drop(&mut self) {
        let _ = std::process::Command::new("umount").arg("-l").arg(self.0.path()).status();
    }
}

/// A full disk is a 507, never a 500, and leaves no temporary file. Needs to mount a tmpfs
/// (root, as in CI); elsewhere it says so and stops (the mapping of `StorageFull` to a full
/// store also has a unit test in `store.rs`).
#[tokio::test]
async fn a_full_disk_answers_507() {
    let disk = match Tmpfs::mount("1m") {
        Ok(disk) => disk,
        Err(why) => {
            eprintln!("a_full_disk_answers_507: cannot mount a tmpfs here ({why}); not run");
            return;
        }
    };
    // The mount is the data directory itself, so that the server's log (beside it) is not on it.
    let data = disk.path();
    let s = Server::start(data, &[]);
    let c = client();
    let bundle = mosaic(64, 8, 1).to_bytes();
    // Fill the disk but for less than the bundle.
    let _ = std::fs::write(data.join("filler"), vec![7u8; 1024 * 1024 - bundle.len() / 2]);
    let (status, body) = upload(&c, &s, bundle).await;
    assert_eq!(status, 507, "{body}");
    assert!(body["error"].as_str().unwrap().contains("disk"), "{body}");
    assert!(store_files(data).is_empty(), "{:?}", store_files(data));
    assert_eq!(c.get(s.url("/healthz")).send().await.unwrap().status(), 200);
}

/// Of ten identical uploads at once exactly one is new (201); the others find it (200).
#[tokio::test]
async fn concurrent_identical_uploads_make_one_201() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let bytes = mosaic(64, 8, 4).to_bytes();
    let answers = futures::future::join_all((0..10).map(|_| upload(&c, &s, bytes.clone()))).await;
    let mut statuses: Vec<u16> = answers.iter().map(|(status, _)| *status).collect();
    statuses.sort();
    assert_eq!(statuses, [vec![200; 9], vec![201]].concat(), "{answers:?}");
    assert_eq!(store_files(dir.path()).len(), 1);
}

/// Empty names and names with control characters are refused on every path that names a
/// texture: raw bundles, multipart creation, PATCH — a 400 naming `name`, nothing stored.
#[tokio::test]
async fn bad_names_are_refused_on_every_path() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let good = mosaic(32, 8, 1);
    let id = put(&c, &s, &good).await;
    let files = store_files(dir.path());
    let named = |name: &str| {
        let mut b = good.clone();
        b.manifest.name = name.to_string();
        b.to_bytes()
    };
    let bad = ["", "bell\u{7}", "two\nlines"];
    for name in bad {
        let (status, body) = upload(&c, &s, named(name)).await;
        assert_eq!(status, 400, "{name:?}: {body}");
        assert!(body["error"].as_str().unwrap().contains("`name`"), "{name:?}: {body}");

        let form = reqwest::multipart::Form::new()
            .text("model", "chaos-mosaic")
            .text("name", name.to_string())
            .text("params", r#"{"tiles_x":8,"tiles_y":8,"iterations":10,"seed":1}"#)
            .part("sample", reqwest::multipart::Part::bytes(sample_png(32, 3)).file_name("s.png"));
        let r = c.post(s.url("/api/v1/textures")).multipart(form).send().await.unwrap();
        assert_eq!(r.status(), 400, "{name:?}");
        let body: Value = r.json().await.unwrap();
        assert!(body["error"].as_str().unwrap().contains("`name`"), "{name:?}: {body}");

        let r = c.patch(s.url(&format!("/api/v1/textures/{id}"))).json(&json!({ "name": name })).send().await.unwrap();
        assert_eq!(r.status(), 400, "{name:?}");
        let body: Value = r.json().await.unwrap();
        assert!(body["error"].as_str().unwrap().contains("`name`"), "{name:?}: {body}");
    }
    assert_eq!(store_files(dir.path()), files);
}
