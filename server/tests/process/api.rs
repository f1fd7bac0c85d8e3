//! The API's settings and demos as the real binary takes them: flags beat the environment
//! beat defaults, and the demos written at the first start survive a SIGTERM and a restart.

use crate::support::*;
use serde_json::Value;

#[tokio::test]
async fn settings_flags_beat_env_beat_defaults() {
    let dir = tempdir();
    let c = client();
    let b = mosaic(64, 16, 8);
    {
        let s = Server::spawn_env(dir.path(), &[], &[("VTEX_TILE_SIZE", "128")]);
        let id = put(&c, &s, &b).await;
        let info: Value = c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
        assert_eq!((info["tile_size"].as_u64(), info["levels"].as_u64()), (Some(128), Some(4)));
    }
    let s = Server::spawn_env(dir.path(), &["--tile-size", "512"], &[("VTEX_TILE_SIZE", "128")]);
    let id = vtex_synth::bundle::id_of(&b.to_bytes());
    let info: Value = c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
    assert_eq!((info["tile_size"].as_u64(), info["levels"].as_u64()), (Some(512), Some(2)));
    let (_, h, _) = get_bytes(&c, &s.tile_url(&id, 0, 1, 1, "rgba")).await;
    assert_eq!(h["x-vtex-width"], "512");
    drop(s);
    let s = Server::spawn(dir.path(), &[]);
    let info: Value = c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["tile_size"], 256, "default");
}

#[tokio::test]
async fn demos_are_written_into_an_empty_data_dir() {
    let dir = tempdir();
    let c = client();
    let s = Server::spawn(dir.path(), &["--demos"]);
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    let all = list["textures"].as_array().unwrap();
    assert_eq!(all.len(), vtex_synth::models::demos().len());
    let big =
        all.iter().find(|t| t["width"] == 100_000 && t["model"] == "chaos-mosaic").expect("a 100k chaos mosaic demo");
    assert_eq!(big["height"], 100_000);
    assert_eq!(big["levels"], 10);
    assert!(big["encoding_bytes"].as_u64().unwrap() < 1 << 20);
    let id = big["id"].as_str().unwrap();
    let (status, _, _) = get_bytes(&c, &s.tile_url(id, 0, 390, 390, "png")).await;
    assert_eq!(status, 200);
    let (status, _, _) = get_bytes(&c, &s.tile_url(id, 9, 0, 0, "png")).await;
    assert_eq!(status, 200);
    assert_eq!(s.terminate().code(), Some(0));
    // A second start does not rewrite them, and serves the same set.
    let files = store_files(dir.path());
    let s = Server::spawn(dir.path(), &["--demos"]);
    assert_eq!(store_files(dir.path()), files);
    let again: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    assert_eq!(again, list);
}
