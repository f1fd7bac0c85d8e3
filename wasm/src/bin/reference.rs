//! Writes what the WebAssembly module must reproduce (`tests/wasm/api.test.mjs`) into DIR:
//! every demo's bundle (`NN.vtex`), the native RGBA bytes of its probe regions and of a few of
//! its tiles (`NN-K.rgba`), and `reference.json` listing them (with the error message a region
//! or tile must give instead, where it has no pixels).
//!
//! Usage: `cargo run --release -p vtex-synth-wasm --bin reference -- DIR`

#![forbid(unsafe_code)]

use serde_json::{json, Value};
use std::path::{Path, PathBuf};
use vtex_synth::models;
use vtex_synth::texture::{level_count, level_size, render_image};
use vtex_synth::{Region, Texture};
use vtex_synth_wasm::{client, probe};

/// The server's default tile size: the tiles the viewer asks for, and every demo is opened with.
const TILE_SIZE: u32 = 256;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let dir = PathBuf::from(std::env::args().nth(1).ok_or("usage: reference DIR")?);
    std::fs::create_dir_all(&dir)?;
    let mut demos = Vec::new();
    for (i, bundle) in models::demos().iter().enumerate() {
        let bytes = bundle.to_bytes();
        let file = format!("{i:02}.vtex");
        std::fs::write(dir.join(&file), &bytes)?;
        let opened = client::open(&bytes, TILE_SIZE)?;
        let tex = &*opened.texture;
        let mut cases = Vec::new();
        for region in probe::regions(tex) {
            let case = json!({ "kind": "region", "level": region.level, "x": region.x, "y": region.y,
                "width": region.width, "height": region.height, "frame": region.frame });
            cases.push(expect(&dir, &format!("{i:02}-{}", cases.len()), tex, &region, case)?);
        }
        for (level, tx, ty, frame) in tiles(tex) {
            let region = server_tile(tex, level, tx, ty, frame);
            let case = json!({ "kind": "tile", "level": level, "tx": tx, "ty": ty, "frame": frame,
                "width": region.width, "height": region.height });
            cases.push(expect(&dir, &format!("{i:02}-{}", cases.len()), tex, &region, case)?);
        }
        demos.push(json!({ "bundle": file, "info": opened.info, "cases": cases }));
    }
    std::fs::write(dir.join("reference.json"), serde_json::to_vec_pretty(&json!({ "demos": demos }))?)?;
    Ok(())
}

/// `case` with the file holding the native bytes of `region`, or the error it gives.
fn expect(dir: &Path, stem: &str, tex: &dyn Texture, region: &Region, mut case: Value) -> std::io::Result<Value> {
    match render_image(tex, region) {
        Ok(img) => {
            let file = format!("{stem}.rgba");
            std::fs::write(dir.join(&file), &img.data)?;
            case["rgba"] = json!(file);
        }
        Err(e) => case["error"] = json!(e.to_string()),
    }
    Ok(case)
}

/// Tiles checked beside the probe: the first of level 0, its last (clipped at both edges), one
/// of a middle level at a later frame, and the first of the coarsest level the server serves.
fn tiles(tex: &dyn Texture) -> Vec<(u32, u32, u32, u32)> {
    let count = |level: u32| {
        let (w, h) = level_size(tex.width(), tex.height(), level);
        (w.div_ceil(TILE_SIZE as u64) as u32, h.div_ceil(TILE_SIZE as u64) as u32)
    };
    let served =
        (0..level_count(tex.width(), tex.height())).find(|&l| count(l) == (1, 1)).expect("the 1 × 1 level is one tile");
    let (nx, ny) = count(0);
    let middle = served / 2;
    let (mx, my) = count(middle);
    vec![(0, 0, 0, 0), (0, nx - 1, ny - 1, 0), (middle, mx / 2, my / 2, 41), (served, 0, 0, 0)]
}

/// Tile (`tx`, `ty`) of `level` as the server cuts it (server/src/api/tiles.rs), written here
/// independently of `Opened::tile_region`, which the module uses.
fn server_tile(tex: &dyn Texture, level: u32, tx: u32, ty: u32, frame: u32) -> Region {
    let ts = TILE_SIZE as u64;
    let (lw, lh) = level_size(tex.width(), tex.height(), level);
    let (px, py) = (tx as u64 * ts, ty as u64 * ts);
    Region::new(level, px as i64, py as i64, (lw - px).min(ts) as u32, (lh - py).min(ts) as u32).at_frame(frame)
}
