//! `vtex export-web`: a folder any static file server can host — the viewer, the synthesis
//! module of the texture's model and one texture's encoding — in which the viewer runs in client mode, with no vtex
//! (the Chaos Mosaic paper's §3.3 use case: ship the encoding, synthesize on the client).
//!
//! Layout: the viewer's files as built (`client-web/dist`), of its synthesis modules only the
//! texture's model's ([`module_file`], with its brotli and gzip copies),
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
/// The synthesis module that renders textures of `model`, as `scripts/build-wasm` names it
/// (`moduleFile` in `client-web/src/shared/vtex-synth.js`, which the viewer loads).
pub fn module_file(model: &str) -> String {
    format!("vtex_synth_{model}.wasm")
}

/// Whether `name` is a synthesis module or one of its compressed copies (`X.br`, `X.gz`).
fn is_module(name: &str) -> bool {
    name.starts_with("vtex_synth_") && [".wasm", ".wasm.br", ".wasm.gz"].iter().any(|end| name.ends_with(end))
}

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
    let info = entry.info();
    let module = module_file(&info.model);
    for needed in ["index.html", &module] {
        if !web_dir.join(needed).is_file() {
            bail!(
                "{} has no {needed}: build the viewer with the synthesis modules first \
                 (scripts/build-wasm; cd client-web && npm ci && npm run build)",
                web_dir.display()
            );
        }
    }
    if out.exists() && std::fs::read_dir(out).with_context(|| format!("reading {}", out.display()))?.next().is_some() {
        bail!("{} is not empty: export into a new or empty directory", out.display());
    }
    std::fs::create_dir_all(out).with_context(|| format!("creating {}", out.display()))?;
    let mut written = Exported { files: 0, bytes: 0 };
    // The page is rewritten below; other models' modules are of no use to this texture.
    let index = web_dir.join("index.html");
    let skip = |path: &Path| {
        let name = path.file_name().and_then(|n| n.to_str()).unwrap_or_default();
        path == index || (path.parent() == Some(web_dir) && is_module(name) && !name.starts_with(&module))
    };
    copy_tree(web_dir, out, &skip, &mut written)?;

    let index = std::fs::read_to_string(web_dir.join("index.html")).context("reading the viewer's index.html")?;
    let anchor = "<meta charset=\"utf-8\">";
    if !index.contains(anchor) {
        bail!("the viewer's index.html has no `{anchor}` to put the export's description after");
    }
    let meta = format!("{anchor}\n  <meta name=\"vtex-export\" content=\"{DESCRIPTION}\">");
    write(out, "index.html", index.replacen(anchor, &meta, 1).as_bytes(), &mut written)?;

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

/// Copies the files under `from` into `to`, but those `skip` names; symbolic links are not
/// followed.
fn copy_tree(from: &Path, to: &Path, skip: &dyn Fn(&Path) -> bool, written: &mut Exported) -> anyhow::Result<()> {
    let mut dirs: Vec<(PathBuf, PathBuf)> = vec![(from.to_path_buf(), to.to_path_buf())];
    while let Some((src, dst)) = dirs.pop() {
        std::fs::create_dir_all(&dst)?;
        for item in std::fs::read_dir(&src).with_context(|| format!("reading {}", src.display()))? {
            let item = item?;
            let kind = item.file_type()?;
            let target = dst.join(item.file_name());
            if kind.is_dir() {
                dirs.push((item.path(), target));
            } else if kind.is_file() && !skip(&item.path()) {
                let n = std::fs::copy(item.path(), &target)
                    .with_context(|| format!("copying {}", item.path().display()))?;
                written.files += 1;
                written.bytes += n;
            }
        }
    }
    Ok(())
}
