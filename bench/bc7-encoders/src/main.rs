//! BC7 and BC1 encoders from crates.io on the demos' pages: PSNR (R, G, B; check_pages.py's
//! per-demo figure over pages 0/1/1 and 3/0/0 of 128² + 4, and the worst single page of every
//! level and size dumped) and encode time per pixel against PNG as the server writes it, one
//! thread (one run each, so a noisy machine shows in the times). For the ISPC encoder (bc7e),
//! each compiled target is also run alone, for two presets, and its blocks compared with the
//! SSE2 target's. docs/ktx2-quality.md has the figures.
//!
//! ```sh
//! mkdir -p /tmp/pages && python3 bench/bc7-encoders/dump_pages.py target/release/vtex /tmp/pages
//! cd bench/bc7-encoders && cargo run --release -- /tmp/pages [PAGE-PREFIXES] [ENCODER-SUBSTRINGS]
//! ```
//!
//! Prefixes and substrings are comma-separated (`07_3_0_0 'bc7e slowest,bc1'`).

use block_compression::decode::decompress_blocks_as_rgba8;
use block_compression::{encode::compress_rgba8, BC7Settings, CompressionVariant};
use ctt_bc7enc_rdo::bindings::{self as bc7e, bc7e_compress_block_params as Params};
use std::collections::BTreeMap;
use std::time::Instant;

type BlocksFn = unsafe extern "C" fn(u32, *mut u64, *const u32, *const Params);

// The per-target entry points and table initialisers of the multi-target ISPC library, beside
// the dispatching ones that the crate binds.
unsafe extern "C" {
    fn bc7e_compress_blocks_sse2(n: u32, b: *mut u64, p: *const u32, params: *const Params);
    fn bc7e_compress_blocks_sse4(n: u32, b: *mut u64, p: *const u32, params: *const Params);
    fn bc7e_compress_blocks_avx(n: u32, b: *mut u64, p: *const u32, params: *const Params);
    fn bc7e_compress_blocks_avx2(n: u32, b: *mut u64, p: *const u32, params: *const Params);
    fn bc7e_compress_blocks_avx512skx(n: u32, b: *mut u64, p: *const u32, params: *const Params);
    fn bc7e_compress_block_init_sse2();
    fn bc7e_compress_block_init_sse4();
    fn bc7e_compress_block_init_avx();
    fn bc7e_compress_block_init_avx2();
    fn bc7e_compress_block_init_avx512skx();
}

const TARGETS: [(&str, BlocksFn); 5] = [
    ("sse2", bc7e_compress_blocks_sse2),
    ("sse4", bc7e_compress_blocks_sse4),
    ("avx", bc7e_compress_blocks_avx),
    ("avx2", bc7e_compress_blocks_avx2),
    ("avx512skx", bc7e_compress_blocks_avx512skx),
];

struct Page {
    demo: usize,
    key: String,
    side: usize,
    rgba: Vec<u8>,
}

impl Page {
    fn block(&self, bx: usize, by: usize) -> Page {
        let mut rgba = Vec::with_capacity(64);
        for y in 0..4 {
            let i = ((by * 4 + y) * self.side + bx * 4) * 4;
            rgba.extend_from_slice(&self.rgba[i..i + 16]);
        }
        Page { demo: self.demo, key: String::new(), side: 4, rgba }
    }

    /// The pixels as 4×4 blocks of packed RGBA, block after block (bc7e's input).
    fn blocks_u32(&self) -> Vec<u32> {
        let mut out = Vec::with_capacity(self.side * self.side);
        for by in 0..self.side / 4 {
            for bx in 0..self.side / 4 {
                out.extend(
                    self.block(bx, by).rgba.chunks_exact(4).map(|p| u32::from_le_bytes([p[0], p[1], p[2], p[3]])),
                );
            }
        }
        out
    }
}

fn bcc(variant: CompressionVariant, p: &Page) -> Vec<u8> {
    let side = p.side as u32;
    let mut out = vec![0u8; variant.blocks_byte_size(side, side)];
    compress_rgba8(variant, &p.rgba, &mut out, side, side, side * 4);
    out
}

fn decode(variant: CompressionVariant, side: usize, blocks: &[u8]) -> Vec<u8> {
    let mut rgba = vec![0u8; side * side * 4];
    decompress_blocks_as_rgba8(variant, side as u32, side as u32, blocks, &mut rgba);
    rgba
}

const BC7: CompressionVariant = CompressionVariant::BC7(BC7Settings::opaque_ultra_fast());

fn squared_error(a: &[u8], b: &[u8], channels: usize) -> u64 {
    let d = |x: &[u8], y: &[u8]| (0..channels).map(|c| (x[c] as i64 - y[c] as i64).pow(2) as u64).sum::<u64>();
    a.chunks_exact(4).zip(b.chunks_exact(4)).map(|(x, y)| d(x, y)).sum()
}

/// The server's BC7 (server/src/ktx2.rs `encode_bc7`): the first search for every block, then
/// each later one for blocks whose error (four channels) is still over its threshold.
fn passes(p: &Page, first: BC7Settings, retries: &[(u64, BC7Settings)]) -> Vec<u8> {
    let mut blocks = bcc(CompressionVariant::BC7(first), p);
    let cols = p.side / 4;
    for (i, block) in blocks.chunks_exact_mut(16).enumerate() {
        let src = p.block(i % cols, i / cols);
        let mut err = squared_error(&decode(BC7, 4, block), &src.rgba, 4);
        for &(threshold, settings) in retries {
            if err <= threshold {
                break;
            }
            let again = bcc(CompressionVariant::BC7(settings), &src);
            let again_err = squared_error(&decode(BC7, 4, &again), &src.rgba, 4);
            if again_err < err {
                block.copy_from_slice(&again);
                err = again_err;
            }
        }
    }
    blocks
}

fn bc7e(p: &Page, params: &Params, target: Option<BlocksFn>) -> Vec<u8> {
    let pixels = p.blocks_u32();
    let n = pixels.len() / 16;
    let mut out = vec![0u64; n * 2];
    match target {
        None => ctt_bc7enc_rdo::compress_blocks(&mut out, &pixels, params),
        Some(f) => unsafe { f(n as u32, out.as_mut_ptr(), pixels.as_ptr(), params) },
    }
    out.iter().flat_map(|x| x.to_le_bytes()).collect()
}

fn png_ms(p: &Page) -> f64 {
    let t = Instant::now();
    let mut out = Vec::new();
    let mut e = png::Encoder::new(&mut out, p.side as u32, p.side as u32);
    e.set_color(png::ColorType::Rgba);
    e.set_depth(png::BitDepth::Eight);
    e.set_compression(png::Compression::Fast);
    e.set_filter(png::Filter::Adaptive);
    e.write_header().unwrap().write_image_data(&p.rgba).unwrap();
    std::hint::black_box(out);
    t.elapsed().as_secs_f64() * 1e3
}

fn median3(f: impl Fn() -> f64) -> f64 {
    let mut v = [f(), f(), f()];
    v.sort_by(f64::total_cmp);
    v[1]
}

fn db(se: u64, n: u64) -> f64 {
    10.0 * (65025.0 * n as f64 / se.max(1) as f64).log10()
}

type Encoder = Box<dyn Fn(&Page) -> Vec<u8>>;

fn encoders() -> Vec<(String, bool, Encoder)> {
    let mut e: Vec<(String, bool, Encoder)> = Vec::new();
    let t = |mse: u64| mse * 16 * 4;
    use BC7Settings as S;
    let vtex_before = [(t(6), S::opaque_very_fast())];
    let vtex = [(t(6), S::opaque_very_fast()), (t(24), S::opaque_basic())];
    e.push((
        "bc7 vtex before (uf, vf>6)".into(),
        true,
        Box::new(move |p| passes(p, S::opaque_ultra_fast(), &vtex_before)),
    ));
    e.push(("bc7 vtex (uf, vf>6, basic>24)".into(), true, Box::new(move |p| passes(p, S::opaque_ultra_fast(), &vtex))));
    for (name, s) in [
        ("ultra_fast", S::opaque_ultra_fast()),
        ("very_fast", S::opaque_very_fast()),
        ("fast", S::opaque_fast()),
        ("basic", S::opaque_basic()),
        ("slow", S::opaque_slow()),
    ] {
        e.push((format!("bc7 block_compression {name}"), true, Box::new(move |p| bcc(CompressionVariant::BC7(s), p))));
    }
    let presets: [(&str, unsafe extern "C" fn(*mut Params, bool)); 7] = [
        ("ultrafast", bc7e::bc7e_compress_block_params_init_ultrafast),
        ("veryfast", bc7e::bc7e_compress_block_params_init_veryfast),
        ("fast", bc7e::bc7e_compress_block_params_init_fast),
        ("basic", bc7e::bc7e_compress_block_params_init_basic),
        ("slow", bc7e::bc7e_compress_block_params_init_slow),
        ("veryslow", bc7e::bc7e_compress_block_params_init_veryslow),
        ("slowest", bc7e::bc7e_compress_block_params_init_slowest),
    ];
    for (name, init) in presets {
        let mut params = ctt_bc7enc_rdo::params_init(false);
        unsafe { init(&mut params, false) };
        e.push((format!("bc7 bc7e {name}"), true, Box::new(move |p| bc7e(p, &params, None))));
        // Each target alone, for two presets: the dispatching library's bytes on other CPUs.
        for (target, f) in TARGETS.into_iter().filter(|_| name == "fast" || name == "slowest") {
            e.push((format!("bc7 bc7e {name} @{target}"), true, Box::new(move |p| bc7e(p, &params, Some(f)))));
        }
    }
    e.push(("bc1 block_compression".into(), false, Box::new(|p| bcc(CompressionVariant::BC1, p))));
    for (name, algorithm) in [
        ("range fit", texpresso::Algorithm::RangeFit),
        ("cluster fit", texpresso::Algorithm::ClusterFit),
        ("iterative cluster fit", texpresso::Algorithm::IterativeClusterFit),
    ] {
        e.push((
            format!("bc1 texpresso {name}"),
            false,
            Box::new(move |p| {
                let params = texpresso::Params {
                    algorithm,
                    weights: texpresso::COLOUR_WEIGHTS_UNIFORM,
                    weigh_colour_by_alpha: false,
                };
                let mut out = vec![0u8; texpresso::Format::Bc1.compressed_size(p.side, p.side)];
                texpresso::Format::Bc1.compress(&p.rgba, p.side, p.side, params, &mut out);
                out
            }),
        ));
    }
    for level in [10u32, 18] {
        e.push((
            format!("bc1 rgbcx level {level}"),
            false,
            Box::new(move |p| {
                let cols = p.side / 4;
                let mut out = vec![0u8; cols * cols * 8];
                for (i, dst) in out.chunks_exact_mut(8).enumerate() {
                    let src = p.block(i % cols, i / cols);
                    let (dst, src) = (dst.as_mut_ptr().cast(), src.rgba.as_ptr());
                    unsafe { rgbcx_sys::root::rgbcx::encode_bc1(level, dst, src, true, false, std::ptr::null()) };
                }
                out
            }),
        ));
    }
    e
}

fn main() {
    let args: Vec<String> = std::env::args().collect();
    let dir = args.get(1).expect("usage: bc7-encoders PAGES-DIR [PAGE-PREFIXES] [ENCODER-SUBSTRINGS]");
    let any = |list: Option<&String>, s: &str, f: fn(&str, &str) -> bool| {
        list.is_none_or(|l| l.is_empty() || l.split(',').any(|x| f(s, x)))
    };
    let mut paths: Vec<_> = std::fs::read_dir(dir).unwrap().map(|e| e.unwrap().path()).collect();
    paths.retain(|p| p.extension().is_some_and(|e| e == "rgba"));
    paths.sort();
    let mut names = BTreeMap::new();
    let mut pages = Vec::new();
    for path in paths {
        let key = path.file_stem().unwrap().to_str().unwrap().to_string();
        if !any(args.get(2), &key, |k, x| k.starts_with(x)) {
            continue;
        }
        let f: Vec<usize> = key.split('_').map(|n| n.parse().unwrap()).collect();
        let name = std::fs::read_to_string(format!("{dir}/{:02}.name", f[0])).unwrap();
        names.insert(f[0], name);
        pages.push(Page { demo: f[0], key, side: f[4], rgba: std::fs::read(&path).unwrap() });
    }
    unsafe {
        rgbcx_sys::root::rgbcx::init(rgbcx_sys::root::rgbcx::bc1_approx_mode::cBC1Ideal);
        bc7e_compress_block_init_sse2();
        bc7e_compress_block_init_sse4();
        bc7e_compress_block_init_avx();
        bc7e_compress_block_init_avx2();
        bc7e_compress_block_init_avx512skx();
    }
    let pixels: usize = pages.iter().map(|p| p.side * p.side).sum();
    let png: f64 = pages.iter().map(|p| median3(|| png_ms(p))).sum();
    println!(
        "{} pages, {pixels} pixels; PNG (fast deflate, adaptive filters): {:.1} ns/px\n",
        pages.len(),
        png * 1e6 / pixels as f64
    );
    println!("| encoder | ns/px | × PNG | demo min | demo median | worst page (dB) | lowest demos | blocks ≠ SSE2 |");
    println!("|---|---|---|---|---|---|---|---|");
    let mut sse2: BTreeMap<String, Vec<Vec<u8>>> = BTreeMap::new();
    for (name, is_bc7, encode) in encoders() {
        let (base, target) = name.split_once(" @").map_or((name.as_str(), None), |(b, t)| (b, Some(t)));
        if !any(args.get(3), &name, |n, x| n.contains(x)) && target != Some("sse2") {
            continue;
        }
        let mut ms = 0.0;
        let mut outs = Vec::new();
        let mut per_demo: BTreeMap<usize, (u64, u64)> = BTreeMap::new();
        let mut worst = (f64::INFINITY, String::new());
        for p in &pages {
            let t = Instant::now();
            outs.push(encode(p));
            ms += t.elapsed().as_secs_f64() * 1e3;
            let texels = decode(if is_bc7 { BC7 } else { CompressionVariant::BC1 }, p.side, outs.last().unwrap());
            let (se, n) = (squared_error(&texels, &p.rgba, 3), (p.side * p.side * 3) as u64);
            if db(se, n) < worst.0 {
                worst = (db(se, n), p.key.clone());
            }
            if p.key.ends_with("_0_1_1_136") || p.key.ends_with("_3_0_0_136") {
                let d = per_demo.entry(p.demo).or_default();
                *d = (d.0 + se, d.1 + n);
            }
        }
        let differing = match target {
            None => String::new(),
            Some("sse2") => {
                sse2.insert(base.to_string(), outs);
                if !any(args.get(3), &name, |n, x| n.contains(x)) {
                    continue;
                }
                "0".into()
            }
            Some(_) => {
                let reference = &sse2[base];
                let d: usize = reference
                    .iter()
                    .zip(&outs)
                    .map(|(a, b)| a.chunks(16).zip(b.chunks(16)).filter(|(x, y)| x != y).count())
                    .sum();
                d.to_string()
            }
        };
        let mut demos: Vec<(f64, usize)> = per_demo.iter().map(|(&d, &(se, n))| (db(se, n), d)).collect();
        demos.sort_by(|a, b| a.0.total_cmp(&b.0));
        let lowest: Vec<String> =
            demos.iter().take(2).map(|(v, d)| format!("{} {v:.2}", names[d].split(" — ").next().unwrap())).collect();
        let (min, med) =
            demos.first().zip(demos.get(demos.len() / 2)).map_or((f64::NAN, f64::NAN), |(a, b)| (a.0, b.0));
        println!(
            "| {name} | {:.0} | {:.1} | {min:.2} | {med:.2} | {:.2} ({}) | {} | {differing} |",
            ms * 1e6 / pixels as f64,
            ms / png,
            worst.0,
            worst.1,
            lowest.join(", ")
        );
    }
}
