//! One warm 256² tile of a demo, rendered inside `measured` alone, so that callgrind counts
//! the instructions of the tile and nothing else (loading, the warm-up render):
//!
//! `valgrind --tool=callgrind --toggle-collect='*measured*' target/release/examples/tile_cost MODEL NAME LEVEL`
//!
//! NAME is a text the demo's name contains (the first of MODEL's demos that does is used); the
//! tile is the one at (x, y) = (3, 5) tiles of LEVEL, rendered twice before it is measured.

use vtex_synth::{models, Never, Region, Texture};

const TILE: u32 = 256;

#[inline(never)]
fn measured(tex: &dyn Texture, region: &Region, out: &mut [u8]) {
    tex.render(region, out, &Never);
}

fn main() {
    let args: Vec<String> = std::env::args().skip(1).collect();
    let [model, name, level] = args.as_slice() else {
        eprintln!("usage: tile_cost MODEL NAME LEVEL");
        std::process::exit(2);
    };
    let level = level.parse().expect("LEVEL is a number");
    let bundle = models::get(model)
        .unwrap()
        .demos()
        .into_iter()
        .find(|b| b.manifest.name.contains(name.as_str()))
        .unwrap_or_else(|| panic!("no demo of {model} is called like `{name}`"));
    let tex = models::load(&bundle).unwrap();
    let region = Region::new(level, 3 * TILE as i64, 5 * TILE as i64, TILE, TILE);
    let mut out = vec![0u8; region.byte_len()];
    for _ in 0..2 {
        tex.render(&region, &mut out, &Never);
    }
    measured(tex.as_ref(), &region, &mut out);
    println!("{}/{} level {level}: {}", bundle.manifest.model, bundle.manifest.name, blake3::hash(&out).to_hex());
}
