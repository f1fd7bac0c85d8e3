//! Flies a camera low over a 100,000² texture laid on a ground plane and streams the pages each
//! frame needs through `vtex-client`, printing per-frame figures.
//!
//! The pages a frame needs come from a feedback-like rule: rays through a grid of screen
//! points (every 8th pixel of a 1280×720 view, 60° vertical field of view) meet the ground;
//! at each hit, the texels one screen pixel spans there (distance and incidence) give the mip
//! level, and the hit's texel coordinates at that level give the page — as a GPU feedback pass
//! would write them. The texture is a torus, so pages wrap.
//!
//! ```sh
//! cargo run --release -p vtex-client --example flythrough -- http://127.0.0.1:8080 [frames] [name]
//! ```

use std::collections::BTreeSet;
use std::time::Instant;
use vtex_client::{Client, PageAddr, PageFormat, PageSpec, TextureInfo};

const WIDTH: f64 = 1280.0;
const HEIGHT: f64 = 720.0;
const FOV_Y: f64 = std::f64::consts::FRAC_PI_3;
const STEP: usize = 8;

/// A camera at `pos` (texels; z is the height over the ground) looking along `yaw`, pitched
/// down by `pitch`.
struct Camera {
    pos: [f64; 3],
    yaw: f64,
    pitch: f64,
}

/// The pages the visible ground needs, by the rule in the module docs.
fn needed_pages(cam: &Camera, tex: &TextureInfo, size: u32) -> Vec<PageAddr> {
    let (sy, cy) = cam.yaw.sin_cos();
    let (sp, cp) = cam.pitch.sin_cos();
    let forward = [cy * cp, sy * cp, -sp];
    let right = [-sy, cy, 0.0];
    let up = [cy * sp, sy * sp, cp];
    let tan = (FOV_Y / 2.0).tan();
    let pixel_angle = FOV_Y / HEIGHT;
    let levels = vtex_client::page_levels(tex);
    let mut pages = BTreeSet::new();
    for py in (0..HEIGHT as usize).step_by(STEP) {
        for px in (0..WIDTH as usize).step_by(STEP) {
            let sx = (2.0 * (px as f64 + 0.5) / WIDTH - 1.0) * tan * WIDTH / HEIGHT;
            let sy = (1.0 - 2.0 * (py as f64 + 0.5) / HEIGHT) * tan;
            let d: Vec<f64> = (0..3).map(|i| forward[i] + sx * right[i] + sy * up[i]).collect();
            if d[2] >= -1e-6 {
                continue; // above the horizon
            }
            let len = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
            let t = -cam.pos[2] / d[2];
            let (u, v) = (cam.pos[0] + t * d[0], cam.pos[1] + t * d[1]);
            let distance = t * len;
            let incidence = (-d[2] / len).max(0.05);
            // Texels one screen pixel covers along its longer axis on the ground.
            let footprint = distance * pixel_angle / incidence;
            let level = (footprint.max(1.0).log2().floor() as u32).min(levels - 1);
            let (cols, rows) = vtex_client::page_grid(tex, level, size);
            let scale = (1u64 << level) as f64 * size as f64;
            let x = (u / scale).floor().rem_euclid(cols as f64) as u32;
            let y = (v / scale).floor().rem_euclid(rows as f64) as u32;
            pages.insert(PageAddr { level, x, y });
        }
    }
    pages.into_iter().collect()
}

fn percentile(sorted: &[f64], p: f64) -> f64 {
    sorted[((sorted.len() - 1) as f64 * p).round() as usize]
}

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let base = args.get(1).map_or("http://127.0.0.1:8080", String::as_str);
    let frames: usize = args.get(2).map_or(Ok(120), |s| s.parse())?;
    let name = args.get(3).map_or("Pebbles — chaos mosaic 100k", String::as_str);
    let client = Client::new(base, 256 << 20);
    let textures = client.textures().await?;
    let tex = textures.iter().find(|t| t.name == name).ok_or_else(|| format!("no texture named {name}"))?;
    let spec = PageSpec { size: 128, border: 4, format: PageFormat::Ktx2 { codec: "bc7", zstd: true } };
    println!(
        "{} ({}×{}, {}), pages 128² + 4 px borders, BC7 + zstd, view 1280×720",
        tex.name, tex.width, tex.height, tex.model
    );
    println!("frame  needed  requested  metatiles  hit rate  latency ms  bytes  not asked for");
    let mut latencies = Vec::new();
    let (mut total_bytes, mut total_unused, mut total_requested, mut total_needed, mut total_hits) =
        (0u64, 0, 0usize, 0usize, 0usize);
    let mut total_metatiles = 0;
    let start = Instant::now();
    for f in 0..frames {
        let t = f as f64;
        let cam = Camera { pos: [50_000.0 + 24.0 * t, 50_000.0 + 6.0 * t, 220.0], yaw: 0.25 + 0.004 * t, pitch: 0.35 };
        let need = needed_pages(&cam, tex, spec.size);
        let t0 = Instant::now();
        let (_, stats) = client.pages(&tex.id, &need, &spec).await?;
        let ms = t0.elapsed().as_secs_f64() * 1e3;
        latencies.push(ms);
        total_bytes += stats.bytes;
        total_unused += stats.unused;
        total_metatiles += stats.metatiles;
        total_requested += stats.requested;
        total_needed += need.len();
        total_hits += stats.hits;
        let hit_rate = 100.0 * stats.hits as f64 / need.len().max(1) as f64;
        println!(
            "{f:5}  {:6}  {:9}  {:9}  {hit_rate:7.1}%  {ms:10.1}  {}  {}",
            need.len(),
            stats.requested,
            stats.metatiles,
            stats.bytes,
            stats.unused
        );
    }
    let secs = start.elapsed().as_secs_f64();
    latencies.sort_by(f64::total_cmp);
    println!(
        "{frames} frames in {secs:.1} s: frame latency p50 {:.1} ms, p95 {:.1} ms; {} pages requested ({:.0} pages/s) \
         in {total_metatiles} metatiles, hit rate {:.1}%, {:.1} MB received ({:.1} MB of pages not asked for); \
         client cache {} pages, {:.1} MB",
        percentile(&latencies, 0.5),
        percentile(&latencies, 0.95),
        total_requested,
        total_requested as f64 / secs,
        100.0 * total_hits as f64 / total_needed.max(1) as f64,
        total_bytes as f64 / 1e6,
        total_unused as f64 / 1e6,
        client.cached_pages(),
        client.cached_bytes() as f64 / 1e6,
    );
    Ok(())
}
