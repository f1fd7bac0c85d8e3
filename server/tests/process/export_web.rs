//! `vtex export-web`: what the folder holds, and what it refuses. (The folder served by a static
//! server and opened in Chromium: tests/browser/export.test.mjs.)

use crate::support::*;
use std::path::Path;
use std::process::{Command, Output};

fn vtex(args: &[&str]) -> Output {
    Command::new(BIN).args(args).env("VTEX_LOG", "warn").env_remove("RUST_BACKTRACE").output().unwrap()
}

fn text(out: &Output) -> String {
    format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr))
}

/// A stand-in for the built viewer: an index.html, two models' modules with compressed copies,
/// a nested folder.
fn web_dir(root: &Path) -> std::path::PathBuf {
    let web = root.join("web");
    std::fs::create_dir_all(web.join("osd/images")).unwrap();
    std::fs::write(web.join("index.html"), "<!doctype html>\n<head>\n  <meta charset=\"utf-8\">\n</head>\n").unwrap();
    for model in ["chaos-mosaic", "lcm"] {
        for ext in ["", ".br", ".gz"] {
            std::fs::write(web.join(format!("vtex_synth_{model}.wasm{ext}")), format!("\0asm {model}{ext}")).unwrap();
        }
    }
    std::fs::write(web.join("osd/images/home.png"), b"png").unwrap();
    web
}

/// Files under `dir` and their bytes.
fn tree(dir: &Path) -> (usize, u64) {
    let mut total = (0, 0);
    for item in std::fs::read_dir(dir).unwrap() {
        let item = item.unwrap();
        if item.file_type().unwrap().is_dir() {
            let (f, b) = tree(&item.path());
            total = (total.0 + f, total.1 + b);
        } else {
            total = (total.0 + 1, total.1 + item.metadata().unwrap().len());
        }
    }
    total
}

#[test]
fn the_folder_holds_the_viewer_its_models_module_the_bundle_and_its_description() {
    let dir = tempdir();
    let bundle = mosaic(64, 4, 3).to_bytes();
    let file = dir.path().join("m.vtex");
    std::fs::write(&file, &bundle).unwrap();
    let id = vtex_synth::bundle::id_of(&bundle);
    let out_dir = dir.path().join("site");
    let web = web_dir(dir.path());
    let out =
        vtex(&["export-web", file.to_str().unwrap(), out_dir.to_str().unwrap(), "--web-dir", web.to_str().unwrap()]);
    assert!(out.status.success(), "{}", text(&out));
    let (files, bytes) = tree(&out_dir);
    assert_eq!(
        files, 7,
        "index.html, the chaos mosaic's module and its 2 copies, home.png, the bundle, the description"
    );
    assert!(
        text(&out).contains(&format!("{files} files, {bytes} bytes ({} the encoding)", bundle.len())),
        "{}",
        text(&out)
    );
    assert_eq!(std::fs::read(out_dir.join(format!("textures/{id}.vtex"))).unwrap(), bundle);
    for ext in ["", ".br", ".gz"] {
        let module = format!("vtex_synth_chaos-mosaic.wasm{ext}");
        assert_eq!(std::fs::read_to_string(out_dir.join(&module)).unwrap(), format!("\0asm chaos-mosaic{ext}"));
        assert!(!out_dir.join(format!("vtex_synth_lcm.wasm{ext}")).exists(), "another model's module");
    }
    assert_eq!(std::fs::read(out_dir.join("osd/images/home.png")).unwrap(), b"png");
    let index = std::fs::read_to_string(out_dir.join("index.html")).unwrap();
    assert!(
        index.contains("<meta charset=\"utf-8\">\n  <meta name=\"vtex-export\" content=\"vtex-export.json\">"),
        "{index}"
    );
    let description: serde_json::Value =
        serde_json::from_slice(&std::fs::read(out_dir.join("vtex-export.json")).unwrap()).unwrap();
    assert_eq!(description["encodings"][&id], format!("textures/{id}.vtex"));
    let info = &description["textures"][0];
    assert_eq!((info["id"].as_str(), info["model"].as_str()), (Some(id.as_str()), Some("chaos-mosaic")));
    assert_eq!((info["tile_size"].as_u64(), info["encoding_bytes"].as_u64()), (Some(256), Some(bundle.len() as u64)));
}

#[test]
fn a_folder_in_use_a_viewer_without_the_module_and_a_bad_bundle_are_refused_with_a_message() {
    let dir = tempdir();
    let file = dir.path().join("m.vtex");
    let bundle = mosaic(64, 4, 3).to_bytes();
    std::fs::write(&file, &bundle).unwrap();
    let web = web_dir(dir.path());
    let (file, web_arg) = (file.to_str().unwrap(), web.to_str().unwrap());

    let used = dir.path().join("used");
    std::fs::create_dir_all(&used).unwrap();
    std::fs::write(used.join("notes.txt"), "mine").unwrap();
    let out = vtex(&["export-web", file, used.to_str().unwrap(), "--web-dir", web_arg]);
    assert!(!out.status.success());
    assert!(text(&out).contains("is not empty: export into a new or empty directory"), "{}", text(&out));
    assert_eq!(std::fs::read_to_string(used.join("notes.txt")).unwrap(), "mine");

    std::fs::remove_file(web.join("vtex_synth_chaos-mosaic.wasm")).unwrap();
    let out = vtex(&["export-web", file, dir.path().join("a").to_str().unwrap(), "--web-dir", web_arg]);
    assert!(
        text(&out).contains("has no vtex_synth_chaos-mosaic.wasm: build the viewer with the synthesis modules first"),
        "{}",
        text(&out)
    );
    assert!(!dir.path().join("a").exists());

    let cut = dir.path().join("cut.vtex");
    std::fs::write(&cut, &bundle[..bundle.len() / 2]).unwrap();
    let out =
        vtex(&["export-web", cut.to_str().unwrap(), dir.path().join("b").to_str().unwrap(), "--web-dir", web_arg]);
    assert!(text(&out).contains("invalid bundle: truncated"), "{}", text(&out));
    assert!(!dir.path().join("b").exists());
}
