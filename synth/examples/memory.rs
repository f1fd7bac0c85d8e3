//! What a loaded texture holds: for every demo of every model, and for a chaos mosaic of a
//! 4096² sample (the largest a model takes), the heap bytes a fresh load holds, then after a
//! cold 256² tile (the whole level below 256²) of frame 0 at every level, in order — the
//! tables a level builds on first use count — beside the sample's RGBA8 bytes, the encoding's
//! bytes and the plan's resident bytes (what the server charges against its budget).
//!
//! `cargo run -p vtex-synth --release --example memory [NAME]`
//!
//! NAME keeps the textures whose label (`model/name`) contains it. Prints a markdown table.

use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicI64, Ordering::Relaxed};
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, Inputs};
use vtex_synth::pixels::png_dimensions;
use vtex_synth::texture::{level_count, level_size, Region};
use vtex_synth::{samples, Never};

/// Counts the heap bytes live in the process: allocated less freed.
struct Counting;

static LIVE: AtomicI64 = AtomicI64::new(0);

unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        LIVE.fetch_add(layout.size() as i64, Relaxed);
        System.alloc(layout)
    }
    unsafe fn dealloc(&self, ptr: *mut u8, layout: Layout) {
        LIVE.fetch_sub(layout.size() as i64, Relaxed);
        System.dealloc(ptr, layout)
    }
    unsafe fn realloc(&self, ptr: *mut u8, layout: Layout, new_size: usize) -> *mut u8 {
        LIVE.fetch_add(new_size as i64 - layout.size() as i64, Relaxed);
        System.realloc(ptr, layout, new_size)
    }
}

#[global_allocator]
static COUNTING: Counting = Counting;

const TILE: u64 = 256;

/// A chaos mosaic of 2 × 2 tiles of a 4096² sample stored as a 1-bit PNG: a few megabytes
/// that decode to 64 MiB of RGBA8 (issue 34's example), the sample thresholded from pebbles.
fn chaos_mosaic_4096() -> Bundle {
    let pebbles = samples::pebbles(4096, 400, 34, true);
    let mut bits = vec![0u8; 4096 / 8 * 4096];
    for (i, p) in pebbles.data.chunks_exact(4).enumerate() {
        if p[0] as u32 + p[1] as u32 + p[2] as u32 > 3 * 110 {
            bits[i / 8] |= 0x80 >> (i % 8);
        }
    }
    let mut png = Vec::new();
    let mut encoder = png::Encoder::new(&mut png, 4096, 4096);
    encoder.set_color(png::ColorType::Grayscale);
    encoder.set_depth(png::BitDepth::One);
    let mut writer = encoder.write_header().unwrap();
    writer.write_image_data(&bits).unwrap();
    writer.finish().unwrap();
    let inputs = Inputs::from([("sample".to_string(), png)]);
    let params = serde_json::json!({"tiles_x": 2, "tiles_y": 2, "seed": 34});
    models::create("chaos-mosaic", "Chaos mosaic of a 4096² 1-bit sample", &params, &inputs).unwrap()
}

fn mib(b: i64) -> String {
    format!("{:.2}", b as f64 / (1 << 20) as f64)
}

fn main() {
    let filter = std::env::args().nth(1).unwrap_or_default();
    let mut bundles = models::demos();
    bundles.push(chaos_mosaic_4096());
    bundles.sort_by(|a, b| (&a.manifest.model, &a.manifest.name).cmp(&(&b.manifest.model, &b.manifest.name)));
    println!(
        "| texture | sample RGBA8 MiB | encoding MiB | held after load MiB | after a cold tile at every level MiB \
         | held ÷ (sample RGBA8 + encoding) | plan MiB |"
    );
    println!("|---|---|---|---|---|---|---|");
    for bundle in bundles {
        let label = format!("{}/{}", bundle.manifest.model, bundle.manifest.name);
        if !label.contains(&filter) {
            continue;
        }
        let model = models::get(&bundle.manifest.model).unwrap();
        let inputs = model.inputs_of(&bundle).unwrap();
        let rgba: i64 = inputs
            .iter()
            .map(|(name, png)| png_dimensions(name, png).unwrap())
            .map(|(w, h)| 4 * w as i64 * h as i64)
            .sum();
        let encoding = bundle.to_bytes().len() as i64;
        let plan = models::plan(&bundle).unwrap().cost.resident_bytes.value as i64;
        let mut out = vec![0u8; (TILE * TILE * 4) as usize];

        let before = LIVE.load(Relaxed);
        let tex = models::load(&bundle).unwrap();
        let loaded = LIVE.load(Relaxed) - before;
        for level in 0..level_count(tex.width(), tex.height()) {
            let (w, h) = level_size(tex.width(), tex.height(), level);
            let (x, y) = ((w / 2 / TILE * TILE) as i64, (h / 2 / TILE * TILE) as i64);
            let region = Region::new(level, x, y, w.min(TILE) as u32, h.min(TILE) as u32);
            tex.render(&region, &mut out[..region.byte_len()], &Never);
        }
        let held = LIVE.load(Relaxed) - before;
        drop(tex);
        let ratio = match rgba + encoding {
            0 => "—".to_string(),
            d => format!("{:.2}", held as f64 / d as f64),
        };
        let rgba = if rgba == 0 { "—".to_string() } else { mib(rgba) };
        println!(
            "| {label} | {rgba} | {} | {} | {} | {ratio} | {} |",
            mib(encoding),
            mib(loaded),
            mib(held),
            mib(plan)
        );
    }
}
