//! The offline subcommands: `vtex create`, `vtex render`, `vtex info`.

mod common;
use common::*;
use std::process::Command;

fn vtex(args: &[&str]) -> std::process::Output {
    Command::new(BIN).args(args).env("VTEX_LOG", "warn").output().unwrap()
}

#[tokio::test]
async fn create_info_render_agree_with_the_server() {
    let dir = tempdir();
    let data = dir.path().join("data");
    let sample = dir.path().join("sample.png");
    std::fs::write(&sample, sample_png(64, 21)).unwrap();
    let params = r#"{"tiles_x":8,"tiles_y":8,"iterations":10,"seed":1}"#;
    let out = vtex(&[
        "create",
        "--model",
        "chaos-mosaic",
        "--name",
        "cli pebbles",
        "--params",
        params,
        "--input",
        &format!("sample={}", sample.display()),
        "--data-dir",
        data.to_str().unwrap(),
    ]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let id = String::from_utf8(out.stdout).unwrap().trim().to_string();
    assert!(vtex_synth::bundle::is_valid_id(&id), "{id}");
    assert_eq!(store_files(&data), vec![format!("{id}.vtex")]);

    // --out writes the same bundle to a file.
    let file = dir.path().join("copy.vtex");
    let params_file = dir.path().join("params.json");
    std::fs::write(&params_file, params).unwrap();
    let out = vtex(&[
        "create",
        "--model",
        "chaos-mosaic",
        "--name",
        "cli pebbles",
        "--params",
        &format!("@{}", params_file.display()),
        "--input",
        &format!("sample={}", sample.display()),
        "--out",
        file.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    assert_eq!(String::from_utf8(out.stdout).unwrap().trim(), id);
    assert_eq!(std::fs::read(&file).unwrap(), std::fs::read(data.join(format!("{id}.vtex"))).unwrap());

    let out = vtex(&["info", &id, "--data-dir", data.to_str().unwrap()]);
    let info: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!((info["width"].as_u64(), info["levels"].as_u64()), (Some(512), Some(2)));
    let out = vtex(&["info", "--data-dir", data.to_str().unwrap()]);
    let all: serde_json::Value = serde_json::from_slice(&out.stdout).unwrap();
    assert_eq!(all["textures"][0], info);

    // `render` of one tile's rectangle equals the server's tile, byte for byte.
    let raw = dir.path().join("t.rgba");
    let out = vtex(&["render", file.to_str().unwrap(), "--x", "256", "--y", "0", "--out", raw.to_str().unwrap()]);
    assert!(out.status.success(), "{}", String::from_utf8_lossy(&out.stderr));
    let s = Server::start(&data, &[]);
    let (_, _, tile) = get_bytes(&client(), &s.tile_url(&id, 0, 1, 0, "rgba")).await;
    assert_eq!(std::fs::read(&raw).unwrap(), tile);
    let png = dir.path().join("r.png");
    let out = vtex(&[
        "render",
        &id,
        "--data-dir",
        data.to_str().unwrap(),
        "--level",
        "1",
        "--x",
        "-10",
        "--width",
        "300",
        "--height",
        "20",
        "--out",
        png.to_str().unwrap(),
    ]);
    assert!(out.status.success());
    let img = image::open(&png).unwrap();
    assert_eq!((img.width(), img.height()), (300, 20));
}

#[test]
fn bad_input_fails_with_a_message() {
    let dir = tempdir();
    let sample = dir.path().join("bad.png");
    let png = sample_png(64, 1);
    std::fs::write(&sample, &png[..png.len() / 2]).unwrap();
    let out = vtex(&[
        "create",
        "--model",
        "chaos-mosaic",
        "--name",
        "x",
        "--params",
        r#"{"tiles_x":8,"tiles_y":8}"#,
        "--input",
        &format!("sample={}", sample.display()),
        "--data-dir",
        dir.path().join("d").to_str().unwrap(),
    ]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("sample"), "{}", String::from_utf8_lossy(&out.stderr));
    let d = dir.path().join("d");
    assert!(!d.exists() || store_files(&d).is_empty(), "nothing stored");
    let out = vtex(&["render", "/nonexistent.vtex", "--out", "/tmp/x.gif"]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("gif"));
    let out = vtex(&["create", "--model", "nope", "--name", "x", "--out", "/tmp/never.vtex"]);
    assert!(String::from_utf8_lossy(&out.stderr).contains("unknown model `nope`"));
    let out = vtex(&["serve", "--tile-size", "7", "--bind", "127.0.0.1:0", "--data-dir", dir.path().to_str().unwrap()]);
    assert!(!out.status.success());
    assert!(String::from_utf8_lossy(&out.stderr).contains("tile size 7"));
}
