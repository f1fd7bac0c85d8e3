//! The fuzz targets: one per parser of untrusted bytes, each with its seeds, its mutations and
//! the bounds its parser documents.

use crate::mutate::{self, Chunk};
use rand::rngs::StdRng;
use rand::seq::IndexedRandom;
use rand::Rng;
use std::time::Duration;
use vtex_server::api::resources::{batch::BatchQuery, tiles};
use vtex_server::api::{extract, params};
use vtex_synth::bundle::{Bundle, MAX_BUNDLE_BYTES};
use vtex_synth::models::{self, Limits};
use vtex_synth::pixels::{decode_png, MAX_IMAGE_ALLOC};
use vtex_synth::texture::{level_count, render_image_until};
use vtex_synth::{Never, Region};
use vtex_wire::urls::TILE;

/// What one input may take.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    /// Largest single allocation.
    pub max_alloc: usize,
    /// Largest growth of the live heap while the input runs.
    pub max_live: usize,
    pub timeout: Duration,
}

/// A parser under test.
pub trait Target: Sync {
    fn name(&self) -> &'static str;
    fn bounds(&self) -> Bounds;
    /// Project-made valid inputs to start from.
    fn seeds(&self) -> Vec<Vec<u8>>;
    fn mutate(&self, rng: &mut StdRng, session: &mut mutatis::Session, input: &mut Vec<u8>);
    /// Parses (and for models loads and renders) one input; true when it was accepted.
    fn run(&self, input: &[u8]) -> bool;
}

/// The bounds the fuzzer loads textures within: the server's, with a texture holding at most
/// 256 MiB so that the fuzzer's heap bound stays tight.
pub const LIMITS: Limits = Limits { max_resident_bytes: 256 << 20, ..Limits::SERVE };

/// Tiles rendered per loaded texture (the finest, a middle and the coarsest level).
const TILES_PER_LOAD: u64 = 3;

pub static TARGETS: [&dyn Target; 7] = [
    &BundleTarget,
    &ManifestTarget { name: "manifest-cascade", model: "cascade" },
    &ManifestTarget { name: "manifest-chaos-mosaic", model: "chaos-mosaic" },
    &ManifestTarget { name: "manifest-lcm", model: "lcm" },
    &ManifestTarget { name: "manifest-patterns", model: "patterns" },
    &PngTarget,
    &QueryTarget,
];

pub fn by_name(name: &str) -> Option<&'static dyn Target> {
    TARGETS.iter().copied().find(|t| t.name() == name)
}

fn demo_bytes(model: Option<&str>) -> Vec<Vec<u8>> {
    models::demos().into_iter().filter(|b| model.is_none_or(|m| b.manifest.model == m)).map(|b| b.to_bytes()).collect()
}

/// The container alone: `Bundle::from_bytes`.
struct BundleTarget;

impl Target for BundleTarget {
    fn name(&self) -> &'static str {
        "bundle"
    }

    /// The input itself, its sections copied out once, and the manifest as a JSON tree.
    fn bounds(&self) -> Bounds {
        Bounds { max_alloc: MAX_BUNDLE_BYTES, max_live: 2 * MAX_BUNDLE_BYTES, timeout: Duration::from_secs(10) }
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        demo_bytes(None)
    }

    fn mutate(&self, rng: &mut StdRng, session: &mut mutatis::Session, input: &mut Vec<u8>) {
        match rng.random_range(0..4) {
            0 => mutate::bundle_field(rng, input),
            1 => mutate_bundle(rng, session, input),
            _ => mutate::bytes(rng, session, input),
        }
    }

    fn run(&self, input: &[u8]) -> bool {
        Bundle::from_bytes(input).is_ok()
    }
}

/// A parsed bundle changed where a model reads it: its params, name, model, sections.
fn mutate_bundle(rng: &mut StdRng, session: &mut mutatis::Session, input: &mut Vec<u8>) {
    let Ok(mut b) = Bundle::from_bytes(input) else {
        return mutate::bytes(rng, session, input);
    };
    match rng.random_range(0..10) {
        0..=5 => mutate::json(rng, session, &mut b.manifest.params),
        6 | 7 if !b.sections.is_empty() => {
            let i = rng.random_range(0..b.sections.len());
            let data = &mut b.sections[i].data;
            if data.starts_with(mutate::PNG_SIGNATURE) {
                mutate::png(rng, session, data);
            } else {
                mutate::bytes(rng, session, data);
            }
        }
        8 if !b.sections.is_empty() => {
            let i = rng.random_range(0..b.sections.len());
            if rng.random_bool(0.5) {
                b.sections.remove(i);
            } else {
                let mut name = b.sections[i].name.clone().into_bytes();
                mutate::bytes(rng, session, &mut name);
                b.sections[i].name = String::from_utf8_lossy(&name).into_owned();
            }
        }
        _ => {
            let mut name = b.manifest.name.clone().into_bytes();
            mutate::bytes(rng, session, &mut name);
            b.manifest.name = String::from_utf8_lossy(&name).into_owned();
        }
    }
    *input = b.to_bytes();
}

/// One model's encodings, through what the server does with an uploaded or stored bundle:
/// parse, plan, load within [`LIMITS`], then render a tile at a few levels.
struct ManifestTarget {
    name: &'static str,
    model: &'static str,
}

impl Target for ManifestTarget {
    fn name(&self) -> &'static str {
        self.name
    }

    /// What a texture within [`LIMITS`] holds, plus decoding one input image (its pixels at
    /// their widest and as RGBA8) and the bundle's own bytes; time is the work bounds read as
    /// nanoseconds, doubled for a loaded machine.
    fn bounds(&self) -> Bounds {
        let resident = LIMITS.max_resident_bytes as usize;
        let work_ns = LIMITS.max_build_work + TILES_PER_LOAD * LIMITS.max_tile_work;
        Bounds {
            max_alloc: resident.max(MAX_IMAGE_ALLOC as usize),
            max_live: resident + 2 * MAX_IMAGE_ALLOC as usize + MAX_BUNDLE_BYTES,
            timeout: Duration::from_nanos(2 * work_ns),
        }
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        demo_bytes(Some(self.model))
    }

    fn mutate(&self, rng: &mut StdRng, session: &mut mutatis::Session, input: &mut Vec<u8>) {
        if rng.random_ratio(1, 10) {
            mutate::bundle_field(rng, input);
        } else {
            mutate_bundle(rng, session, input);
        }
    }

    fn run(&self, input: &[u8]) -> bool {
        let Ok(bundle) = Bundle::from_bytes(input) else { return false };
        if models::plan(&bundle).is_err() {
            return false;
        }
        let Ok(tex) = models::load_within(&bundle, &LIMITS, &vtex_synth::Resources::default()) else { return false };
        let levels = level_count(tex.width(), tex.height());
        for level in [0, levels / 2, levels - 1] {
            let region = Region::new(level, 0, 0, 64, 64);
            render_image_until(tex.as_ref(), &region, &Never).expect("a 64 × 64 region at an existing level renders");
        }
        true
    }
}

/// `decode_png`, which reads every image a model takes (uploads and bundle sections).
struct PngTarget;

impl Target for PngTarget {
    fn name(&self) -> &'static str {
        "png"
    }

    /// The decoder's documented bound, for the decoded image and again for its RGBA8 copy.
    fn bounds(&self) -> Bounds {
        let one = MAX_IMAGE_ALLOC as usize;
        Bounds { max_alloc: one, max_live: 2 * one, timeout: Duration::from_secs(10) }
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        png_seeds()
    }

    fn mutate(&self, rng: &mut StdRng, session: &mut mutatis::Session, input: &mut Vec<u8>) {
        mutate::png(rng, session, input);
    }

    fn run(&self, input: &[u8]) -> bool {
        decode_png("fuzz", input).is_ok()
    }
}

/// PNGs of every colour type and bit depth, with pixels from the project's own pebbles
/// sample, plain and with each ancillary chunk the decoder reads or skips.
fn png_seeds() -> Vec<Vec<u8>> {
    use png::{BitDepth as D, ColorType as C};
    let kinds: [(C, &[D]); 5] = [
        (C::Grayscale, &[D::One, D::Two, D::Four, D::Eight, D::Sixteen]),
        (C::Rgb, &[D::Eight, D::Sixteen]),
        (C::Indexed, &[D::One, D::Two, D::Four, D::Eight]),
        (C::GrayscaleAlpha, &[D::Eight, D::Sixteen]),
        (C::Rgba, &[D::Eight, D::Sixteen]),
    ];
    let pebbles = vtex_synth::samples::pebbles(32, 5, 3, true).data;
    let (w, h) = (13u32, 7u32);
    let mut out = Vec::new();
    for (colour, depths) in kinds {
        for &depth in depths {
            let bits = colour.samples() * depth as usize;
            let stride = (w as usize * bits).div_ceil(8);
            let data: Vec<u8> = pebbles.iter().copied().cycle().take(stride * h as usize).collect();
            let mut png = Vec::new();
            let mut enc = png::Encoder::new(&mut png, w, h);
            enc.set_color(colour);
            enc.set_depth(depth);
            if colour == C::Indexed {
                let entries = 1usize << depth as usize;
                enc.set_palette(pebbles[..entries * 3].to_vec());
                enc.set_trns(pebbles[..entries].to_vec());
            }
            let mut writer = enc.write_header().expect("a valid header");
            writer.write_image_data(&data).expect("data of the declared size");
            writer.finish().expect("the PNG completes");
            out.push(png);
        }
    }
    let plain = out.clone();
    let text = miniz_oxide::deflate::compress_to_vec_zlib(b"vtex", 6);
    let extras = [
        Chunk::new(b"iCCP", [b"icc\0\0".as_slice(), &text].concat()),
        Chunk::new(b"zTXt", [b"Comment\0\0".as_slice(), &text].concat()),
        Chunk::new(b"iTXt", [b"Comment\0\x01\0en\0Comment\0".as_slice(), &text].concat()),
        Chunk::new(b"tEXt", b"Comment\0vtex".to_vec()),
        Chunk::new(b"gAMA", 45455u32.to_be_bytes().to_vec()),
    ];
    for (png, extra) in plain.iter().zip(extras.iter().cycle()) {
        let mut chunks = mutate::png_chunks(png).expect("the encoder writes chunks");
        chunks.insert(1, extra.clone());
        out.push(mutate::png_bytes(&chunks));
    }
    out.push(vtex_synth::samples::pebbles(256, 24, 9, true).to_png());
    out
}

/// The query strings (and tile paths) of the API: `extract::query_params` into each endpoint's
/// query type, as the `Query` extractor and the tile fast path call it, and `path_params` of
/// the tile route.
struct QueryTarget;

/// Longest query the target makes: beyond what HTTP servers accept in a request line.
const MAX_QUERY: usize = 64 << 10;

impl Target for QueryTarget {
    fn name(&self) -> &'static str {
        "query"
    }

    /// A query of [`MAX_QUERY`] bytes decoded a few times over.
    fn bounds(&self) -> Bounds {
        Bounds { max_alloc: 4 * MAX_QUERY, max_live: 16 * MAX_QUERY, timeout: Duration::from_secs(2) }
    }

    fn seeds(&self) -> Vec<Vec<u8>> {
        let id = "a".repeat(64);
        [
            String::new(),
            "frame=3".into(),
            "frame=%33".into(),
            "level=2&x=-5&y=7&w=256&h=256&format=png&frame=1".into(),
            "level=0&x=9223372036854775807&y=-9223372036854775808&w=4096&h=4096&format=webp".into(),
            "tiles=0/0/0,1/0/1,2/3/1&format=webp&frame=0".into(),
            "tiles=0%2F0%2F0&format=rgba".into(),
            format!("/api/v1/textures/{id}/tiles/3/2/1.png?frame=2"),
            format!("/api/v1/textures/{id}/tiles/0/0/0.jpg"),
        ]
        .into_iter()
        .map(String::into_bytes)
        .collect()
    }

    fn mutate(&self, rng: &mut StdRng, session: &mut mutatis::Session, input: &mut Vec<u8>) {
        match rng.random_range(0..6) {
            0 => {
                // Many keys, as a hostile client sends them.
                let pair =
                    *[b"frame=1&".as_slice(), b"x=1&", b"&", b"=&", b"%zz&", b"tiles=0/0/0&"].choose(rng).unwrap();
                let n = rng.random_range(1..=20_000);
                for _ in 0..n {
                    if input.len() + pair.len() > MAX_QUERY {
                        break;
                    }
                    input.extend_from_slice(pair);
                }
            }
            1 => {
                let piece = *[b"&".as_slice(), b"=", b"%", b"%2", b"%00", b"%ff", b"+", b"/", b",", b"?", b"#"]
                    .choose(rng)
                    .unwrap();
                let at = rng.random_range(0..=input.len());
                input.splice(at..at, piece.iter().copied());
            }
            _ => mutate::bytes(rng, session, input),
        }
        input.truncate(MAX_QUERY);
    }

    fn run(&self, input: &[u8]) -> bool {
        let text = String::from_utf8_lossy(input);
        let (path, query) = match text.split_once('?') {
            Some((p, q)) if p.starts_with('/') => (Some(p), Some(q)),
            _ if text.starts_with('/') => (Some(&*text), None),
            _ => (None, Some(&*text)),
        };
        let mut accepted = false;
        accepted |= extract::query_params::<tiles::TileQuery>(query).is_ok();
        accepted |= extract::query_params::<tiles::RegionQuery>(query).is_ok();
        accepted |= extract::query_params::<BatchQuery>(query).is_ok();
        accepted |= extract::query_params::<extract::NoQuery>(query).is_ok();
        if let Some(path) = path {
            let mut router = matchit::Router::new();
            router.insert(TILE, ()).expect("the tile route is a valid template");
            if let Ok(m) = router.at(path) {
                if let Ok(p) = extract::path_params::<tiles::TilePath>(m.params.iter()) {
                    let (y, ext) = p.file.rsplit_once('.').unwrap_or((&p.file, ""));
                    accepted |= params::u32_value(y).is_ok() && params::format_value(ext).is_ok();
                }
            }
        }
        accepted
    }
}
