//! Embeds the viewer's build (`client-web/dist`) in the binary, so `vtex serve` runs from any
//! directory. Without a build (a fresh clone before `npm run build`) the binary is built
//! without the viewer and says so at `/`; `scripts/test` builds the viewer first.
//!
//! `client-web/build.mjs` writes brotli and gzip copies beside the files (`X.br`, `X.gz`);
//! they are embedded with the file they compress.

use std::fmt::Write as _;
use std::path::{Path, PathBuf};

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
        } else if !matches!(path.extension().and_then(|e| e.to_str()), Some("br" | "gz")) {
            out.push(path);
        }
    }
}

fn main() {
    let client = Path::new(env!("CARGO_MANIFEST_DIR")).join("..").join("client-web");
    let dist = client.join("dist");
    // The client directory, not dist alone: a dist that appears later must be noticed, and a
    // path that does not exist would rerun this script (and rebuild the crate) every time.
    println!("cargo:rerun-if-changed={}", client.display());
    let mut found = Vec::new();
    if dist.join("index.html").is_file() {
        files(&dist, &mut found);
    } else {
        println!("cargo:warning=client-web/dist is not built: this vtex serves no viewer (run `npm ci && npm run build` in client-web/, then build again)");
    }
    found.sort();
    let mut code = String::from("/// The viewer's files, below `client-web/dist`.\npub static FILES: &[File] = &[\n");
    for path in &found {
        let rel = path.strip_prefix(&dist).unwrap().to_string_lossy().replace('\\', "/");
        let copy = |ext: &str| {
            let copy = PathBuf::from(format!("{}.{ext}", path.display()));
            if copy.is_file() {
                format!("include_bytes!({:?})", copy.display().to_string())
            } else {
                "&[]".to_string()
            }
        };
        let _ = writeln!(
            code,
            "    File {{ path: {rel:?}, bytes: include_bytes!({:?}), br: {}, gzip: {} }},",
            path.display().to_string(),
            copy("br"),
            copy("gz")
        );
    }
    code.push_str("];\n");
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap()).join("web_files.rs");
    std::fs::write(out, code).unwrap();
}
