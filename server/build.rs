//! Embeds the viewer's build (`client-web/dist`) in the binary, so `vtex serve` runs from any
//! directory. Without a build (a fresh clone before `npm run build`) the binary is built
//! without the viewer and says so at `/`; `scripts/test` builds the viewer first.
//!
//! Each file is also compressed here, once, at the best brotli and gzip levels (the viewer's
//! code and the synthesis module are most of what a first visit downloads), so the server
//! sends those copies instead of compressing at its fastest level on every request.

use std::fmt::Write as _;
use std::io::Write as _;
use std::path::{Path, PathBuf};

/// Files the page rewrites at run time (its asset URLs) or that are compressed already are
/// served as they are; the compression layer handles the page.
fn compressible(rel: &str) -> bool {
    let ext = rel.rsplit_once('.').map_or("", |(_, e)| e);
    rel != "index.html" && matches!(ext, "js" | "mjs" | "css" | "wasm" | "json" | "svg" | "html" | "map" | "txt")
}

/// `bytes` compressed as brotli (quality 11) and gzip (level 9); each empty when it saves
/// less than a tenth.
fn precompress(bytes: &[u8]) -> (Vec<u8>, Vec<u8>) {
    let params = brotli::enc::BrotliEncoderParams { quality: 11, lgwin: 24, ..Default::default() };
    let mut br = Vec::new();
    brotli::BrotliCompress(&mut &bytes[..], &mut br, &params).expect("compressing to memory");
    let mut gz = flate2::write::GzEncoder::new(Vec::new(), flate2::Compression::best());
    gz.write_all(bytes).expect("compressing to memory");
    let gz = gz.finish().expect("compressing to memory");
    let worth = |c: Vec<u8>| if c.len() * 10 < bytes.len() * 9 { c } else { Vec::new() };
    (worth(br), worth(gz))
}

fn files(dir: &Path, out: &mut Vec<PathBuf>) {
    let Ok(entries) = std::fs::read_dir(dir) else { return };
    for entry in entries.flatten() {
        let path = entry.path();
        if path.is_dir() {
            files(&path, out);
        } else {
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
    let out = PathBuf::from(std::env::var("OUT_DIR").unwrap());
    let packed = out.join("web");
    let _ = std::fs::remove_dir_all(&packed);
    let mut code = String::from("/// The viewer's files, below `client-web/dist`.\npub static FILES: &[File] = &[\n");
    for (i, path) in found.iter().enumerate() {
        let rel = path.strip_prefix(&dist).unwrap().to_string_lossy().replace('\\', "/");
        let bytes = std::fs::read(path).unwrap();
        let (br, gzip) = if compressible(&rel) { precompress(&bytes) } else { Default::default() };
        let include = |ext: &str, data: &[u8]| {
            if data.is_empty() {
                return "&[]".to_string();
            }
            let file = packed.join(format!("{i}.{ext}"));
            std::fs::create_dir_all(&packed).unwrap();
            std::fs::write(&file, data).unwrap();
            format!("include_bytes!({:?})", file.display().to_string())
        };
        let (br, gzip) = (include("br", &br), include("gz", &gzip));
        let _ = writeln!(
            code,
            "    File {{ path: {rel:?}, bytes: include_bytes!({:?}), br: {br}, gzip: {gzip} }},",
            path.display().to_string()
        );
    }
    code.push_str("];\n");
    std::fs::write(out.join("web_files.rs"), code).unwrap();
}
