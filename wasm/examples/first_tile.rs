//! Open + first tile natively, through the same code the WebAssembly module runs
//! ([`vtex_synth_wasm::client`]): writes every demo's bundle into DIR (`NN.vtex`) and prints, a
//! JSON line a demo, the median milliseconds from the bundle's bytes to an opened texture and to
//! the RGBA of a first tile, each run on a freshly opened texture. `bench/wasm/first-tile.mjs` times the module on
//! the same bundles and tiles.
//!
//! Usage: `cargo run --release -p vtex-synth-wasm --example first_tile -- DIR [RUNS]`

#![forbid(unsafe_code)]

use serde_json::json;
use std::path::PathBuf;
use std::time::Instant;
use vtex_synth::models;
use vtex_synth_wasm::client;

/// The server's default tile size, which the viewer asks for.
const TILE_SIZE: u32 = 256;

fn main() -> Result<(), Box<dyn std::error::Error>> {
    let mut args = std::env::args().skip(1);
    let dir = PathBuf::from(args.next().ok_or("usage: first_tile DIR [RUNS]")?);
    let runs: usize = args.next().map(|r| r.parse()).transpose()?.unwrap_or(3);
    std::fs::create_dir_all(&dir)?;
    for (i, bundle) in models::demos().iter().enumerate() {
        let bytes = bundle.to_bytes();
        let file = format!("{i:02}.vtex");
        std::fs::write(dir.join(&file), &bytes)?;
        let opened = client::open(&bytes, TILE_SIZE)?;
        let tiles: Vec<_> = first_tiles(opened.info.width, opened.info.height)
            .into_iter()
            .map(|(level, tx, ty)| {
                let (mut open, mut total): (Vec<f64>, Vec<f64>) = (0..runs)
                    .map(|_| {
                        let start = Instant::now();
                        let opened = client::open(&bytes, TILE_SIZE).expect("the demo opens");
                        let open = start.elapsed().as_secs_f64() * 1e3;
                        let region = opened.tile_region(level, tx, ty, 0).expect("the tile exists");
                        opened.render(&region).expect("the tile renders");
                        (open, start.elapsed().as_secs_f64() * 1e3)
                    })
                    .unzip();
                let median = |ms: &mut Vec<f64>| {
                    ms.sort_by(f64::total_cmp);
                    ms[runs / 2]
                };
                json!({ "level": level, "tx": tx, "ty": ty, "open_ms": median(&mut open), "ms": median(&mut total) })
            })
            .collect();
        let info = &opened.info;
        let line = json!({ "bundle": file, "model": info.model, "name": info.name, "tiles": tiles });
        println!("{line}");
    }
    Ok(())
}

/// The first tile timed: the centre tile of level 0, a close-up where the texture's own
/// structure is rendered (coarse levels cost what their footprint does, whatever was opened).
fn first_tiles(width: u64, height: u64) -> Vec<(u32, u32, u32)> {
    let (nx, ny) = (width.div_ceil(TILE_SIZE as u64) as u32, height.div_ceil(TILE_SIZE as u64) as u32);
    vec![(0, nx / 2, ny / 2)]
}
