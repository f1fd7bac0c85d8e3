//! `vtex export-web`: a folder any static file server can host — the viewer, the synthesis
//! module and one texture's encoding — in which the viewer runs in client mode, with no vtex
//! (the Chaos Mosaic paper's §3.3 use case: ship the encoding, synthesize on the client).
//!
//! Layout: the viewer's files as built (`client-web/dist`, with `vtex_synth.wasm`),
//! `textures/<id>.vtex` (the bundle bytes, unchanged), `vtex-export.json` (the texture's info
//! as the server gives it, and where its bundle is), and `index.html` naming that file in a
//! `<meta name="vtex-export">`, which switches the viewer to its static mode.

use crate::store::{Entry, TextureInfo};
use anyhow::{bail, Context};
use serde::Serialize;
use std::collections::BTreeMap;
use std::path::{Path, PathBuf};

/// The description file the viewer reads (`client-web/src/viewer/client-synth.js` staticExport).
pub const DESCRIPTION: &str = "vtex-export.json";
/// The synthesis module the viewer loads in client mode (`client-synth.js` WASM_URL).
pub const MODULE: &str = "vtex_synth.wasm";

#[derive(Serialize)]
struct Description {
    textures: Vec<TextureInfo>,
    /// Texture id → the URL of its bundle, relative to the page.
    encodings: BTreeMap<String, String>,
}

/// What an export wrote.
pub struct Exported {
    pub files: usize,
    pub bytes: u64,
}

/// Writes the export of `entry` (whose bundle is `bundle`) into `out`, which must not exist or
/// be empty, from the viewer built in `web_dir`.
pub fn export_web(entry: &Entry, bundle: &[u8], web_dir: &Path, out: &Path) -> anyhow::Result<Exported> {
    for needed in ["index.html", MODULE] {
        if !web_dir.join(needed).is_file() {
            bail!(
                "{} has no {needed}: build the viewer with the synthesis module first \
                 (cargo build -p vtex-synth-wasm --lib --target wasm32-unknown-unknown --profile wasm; \
                 cd client-web && npm ci && npm run build)",
                web_dir.display()
            );
        }
    }
    if out.exists() && std::fs::read_dir(out).with_context(|| format!("reading {}", out.display()))?.next().is_some() {
        bail!("{} is not empty: export into a new or empty directory", out.display());
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut written = Exported { files: 0, bytes: 0 };
    copy_tree(web_dir, out, &web_dir.join("index.html"), &mut written)?;

    let index = std::fs::read_to_string(web_dir.join("index.html")).context("reading the viewer's index.html")?;
    let anchor = "<meta charset=\"utf-8\">";
    if !index.contains(anchor) {
        bail!("the viewer's index.html has no `{anchor}` to put the export's description after");
    }
    let meta = format!("{anchor}\n  <meta name=\"vtex-export\" content=\"{DESCRIPTION}\">");
    write(out, "index.html", index.replacen(anchor, &meta, 1).as_bytes(), &mut written)?;

    let info = entry.info();
    let bundle_path = format!("textures/{}.vtex", info.id);
    write(out, &bundle_path, bundle, &mut written)?;
    let description = Description { encodings: BTreeMap::from([(info.id.clone(), bundle_path)]), textures: vec![info] };
    write(out, DESCRIPTION, &serde_json::to_vec_pretty(&description)?, &mut written)?;
    Ok(written)
}

/// Writes `bytes` to `out/relative`, creating folders.
fn write(out: &Path, relative: &str, bytes: &[u8], written: &mut Exported) -> anyhow::Result<()> {
    let path = out.join(relative);
    if let Some(parent) = path.parent() {
        std::fs::create_dir_all(parent)?;
    }
    std::fs::write(&path, bytes).with_context(|| format!("writing {}", path.display()))?;
    written.files += 1;
    written.bytes += bytes.len() as u64;
    Ok(())
}

/// Copies the files under `from` into `to`, but `skip`; symbolic links are not followed.
fn copy_tree(from: &Path, to: &Path, skip: &Path, written: &mut Exported) -> anyhow::Result<()> {
    let mut dirs: Vec<(PathBuf, PathBuf)> = vec![(from.to_path_buf(), to.to_path_buf())];
    while let Some((src, dst)) = dirs.pop() {
        std::fs::create_dir_all(&dst)?;
        for item in std::fs::read_dir(&src).with_context(|| format!("reading {}", src.display()))? {
            let item = item?;
            let kind = item.file_type()?;
            let target = dst.join(item.file_name());
            if kind.is_dir() {
                dirs.push((item.path(), target));
            } else if kind.is_file() && item.path() != skip {
                let n = std::fs::copy(item.path(), &target)
                    .with_context(|| format!("copying {}", item.path().display()))?;
                written.files += 1;
                written.bytes += n;
            }
        }
    }
    Ok(())
}
