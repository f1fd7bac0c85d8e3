//! Flies a camera low over a 100,000² texture laid on a ground plane and streams the pages each
//! frame needs through `vtex-client`, printing per-frame figures.
//!
//! The pages a frame needs come from the page-residency planner (`vtex_client::planner`): rays
//! through every 8th pixel of a 1280×720 view (60° vertical field of view) meet the ground, a
//! plane on which the texture repeats (it is a torus); the texels one pixel spans there give the
//! level, the hit the page — as a GPU feedback pass would write them. The plan asks for those
//! pages and their coarser ancestors not held yet, coarsest first, at most 256 a frame.
//!
//! ```sh
//! cargo run --release -p vtex-client --example flythrough -- http://127.0.0.1:8080 [frames] [name]
//! ```

use std::time::Instant;
use vtex_client::planner::{self, Surface, View};
use vtex_client::{Client, PageAddr, PageFormat, PageLayer, PageSpec, TextureInfo};

const WIDTH: u32 = 1280;
const HEIGHT: u32 = 720;
const FOV_Y: f64 = std::f64::consts::FRAC_PI_3;
const STEP: u32 = 8;
/// Pages asked for a frame at most.
const BUDGET: usize = 256;

/// A camera at `pos` (texels; z is the height over the ground) looking along `yaw`, pitched
/// down by `pitch`.
struct Camera {
    pos: [f64; 3],
    yaw: f64,
    pitch: f64,
}

/// The planner's view of the ground from `cam`, and the ground: one texel a unit.
fn view(cam: &Camera, tex: &TextureInfo) -> (View, Surface) {
    let (sy, cy) = cam.yaw.sin_cos();
    let (sp, cp) = cam.pitch.sin_cos();
    let forward = [cy * cp, sy * cp, -sp];
    let target = [cam.pos[0] + forward[0], cam.pos[1] + forward[1], cam.pos[2] + forward[2]];
    let eye = planner::look_at(cam.pos, target, [0.0, 0.0, 1.0]);
    let proj = planner::perspective(FOV_Y, WIDTH as f64 / HEIGHT as f64, 1.0, 1e7);
    let view = View { view_proj: planner::mul(&proj, &eye), width: WIDTH, height: HEIGHT, step: STEP, lod_bias: 0.0 };
    let (w, h) = (tex.width as f64, tex.height as f64);
    (view, Surface { origin: [0.0; 3], u_axis: [w, 0.0, 0.0], v_axis: [0.0, h, 0.0], repeat: true })
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
    let spec = PageSpec {
        size: 128,
        border: 4,
        format: PageFormat::Ktx2 { codec: "bc7", zstd: true },
        layer: PageLayer::Color,
    };
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
        let (view, ground) = view(&cam, tex);
        let feedback = planner::from_camera(&view, &ground, tex, spec.size);
        let plan = planner::plan(&feedback, tex, spec.size, |a| client.is_cached(&tex.id, a, &spec), BUDGET);
        // The planned pages (coarsest first), then those the view samples that are held.
        let mut seen = std::collections::BTreeSet::new();
        let need: Vec<PageAddr> =
            plan.iter().map(|r| r.addr).chain(feedback.keys().copied()).filter(|&a| seen.insert(a)).collect();
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
