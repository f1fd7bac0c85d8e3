//! The model catalogue of the command line (`vtex models`): the same models, and its example
//! commands create them.

use crate::support::*;
use serde_json::Value;
use std::process::Command;

fn vtex(args: &[&str]) -> String {
    let out = Command::new(BIN).args(args).output().unwrap();
    assert!(out.status.success(), "vtex {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// `vtex models --json` is the server's document; the human listing's example commands, run
/// as printed, make the very textures the multipart upload of the same example makes (same
/// ids: an id is the hash of the bundle); `vtex create --help` names every model.
#[tokio::test]
async fn the_cli_lists_the_same_models_and_its_example_commands_create_them() {
    let dir = tempdir();
    let s = Server::spawn(dir.path(), &[]);
    let c = client();
    let served: Value = c.get(s.url("/api/v1/models")).send().await.unwrap().json().await.unwrap();
    // Over HTTP the example images' links are absolute; the CLI, with no request, prints paths.
    let as_paths: Value = serde_json::from_str(&served.to_string().replace(&s.url(""), "")).unwrap();
    let printed: Value = serde_json::from_str(&vtex(&["models", "--json"])).unwrap();
    assert_eq!(printed, as_paths);
    let one: Value = serde_json::from_str(&vtex(&["models", "--json", "chaos-mosaic"])).unwrap();
    assert_eq!(Some(&one), as_paths["models"].as_array().unwrap().iter().find(|d| d["id"] == "chaos-mosaic"));

    let help = vtex(&["create", "--help"]);
    for id in vtex_synth::models::ids() {
        assert!(help.contains(id), "`vtex create --help` does not name {id}: {help}");
    }
    assert!(help.contains("vtex models"), "{help}");

    let work = tempdir();
    let images = work.path().join("examples");
    let listing = vtex(&["models", "--example-dir", images.to_str().unwrap()]);
    let commands: Vec<&str> = listing.lines().filter_map(|l| l.trim().strip_prefix("example: ")).collect();
    assert_eq!(commands.len(), served["models"].as_array().unwrap().len(), "{listing}");
    let data = work.path().join("data");
    let bin_dir = std::path::Path::new(BIN).parent().unwrap();
    for (command, doc) in commands.iter().zip(served["models"].as_array().unwrap()) {
        let out = Command::new("sh")
            .arg("-c")
            .arg(format!("{command} --data-dir {}", data.display()))
            .env("PATH", format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default()))
            .output()
            .unwrap();
        assert!(out.status.success(), "{command}: {}", String::from_utf8_lossy(&out.stderr));
        let cli_id = String::from_utf8(out.stdout).unwrap().trim().to_string();
        let id = doc["id"].as_str().unwrap();
        let r = post_example(&c, &s, doc, &format!("{id} example")).await;
        let info: Value = r.json().await.unwrap();
        assert_eq!(info["id"], cli_id, "{id}: the CLI's example and the upload's differ");
    }
}
