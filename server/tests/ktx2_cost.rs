//! What a KTX2 page costs to encode, per codec, against PNG and BC7 in the same run: pages of
//! 256² and 512² (level 0 of a few demos, at (512, 512)), each encoded `RUNS` times on one thread
//! as the server does on a cache miss (`encode::encode`), the median reported. Ignored by
//! default (it is a measurement, not a check); docs/ktx2-quality.md has its figures:
//!
//! `cargo test -p vtex-server --test ktx2_cost -- --ignored --nocapture` (the test profile: opt-level 2)

use std::time::Instant;
use vtex_server::encode::{encode, Format};
use vtex_server::ktx2::{Codec, Ktx2, Supercompression, Transfer};
use vtex_server::store::Entry;
use vtex_synth::texture::render_image;
use vtex_synth::Region;

const RUNS: usize = 3;
const DEMOS: [&str; 3] = ["Pebbles — chaos mosaic 100k", "LCM brick wall", "Cascade H — fire clouds"];

#[test]
#[ignore = "a measurement: run with --ignored --nocapture"]
fn encode_time_per_page() {
    let demos = vtex_synth::models::demos();
    let ktx2 = |codec: Codec, sc| Format::Ktx2(Ktx2 { codec, supercompression: sc, transfer: Transfer::Srgb });
    let formats = [
        ("png", Format::Png),
        ("jpg", Format::Jpg),
        ("bc1", ktx2(Codec::Bc1, Supercompression::None)),
        ("bc7", ktx2(Codec::Bc7, Supercompression::None)),
        ("uastc", ktx2(Codec::Uastc, Supercompression::None)),
        ("uastc+zstd", ktx2(Codec::Uastc, Supercompression::Zstd)),
        ("etc1s", ktx2(Codec::Etc1s, Supercompression::BasisLz)),
    ];
    println!("| demo | side | {} |", formats.map(|f| f.0).join(" | "));
    println!("|---|---|{}", "---|".repeat(formats.len()));
    for name in DEMOS {
        let demo = demos.iter().find(|d| d.manifest.name == name).unwrap_or_else(|| panic!("demo {name}"));
        let entry = Entry::from_bytes(&demo.to_bytes(), 256).expect("demo loads");
        for side in [256u32, 512] {
            let img = render_image(&*entry.texture, &Region::new(0, 512, 512, side, side)).unwrap();
            let mut cells = Vec::new();
            for (_, format) in formats {
                let mut ms: Vec<f64> = (0..RUNS)
                    .map(|_| {
                        let copy = img.clone();
                        let t = Instant::now();
                        let out = encode(copy, format).unwrap();
                        std::hint::black_box(out);
                        t.elapsed().as_secs_f64() * 1e3
                    })
                    .collect();
                ms.sort_by(f64::total_cmp);
                cells.push(format!("{:.1}", ms[RUNS / 2]));
            }
            println!("| {name} | {side}² | {} |", cells.join(" | "));
        }
    }
    println!("\nmilliseconds per page, median of {RUNS}, one thread");
}
