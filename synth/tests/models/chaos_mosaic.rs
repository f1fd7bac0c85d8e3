//! The chaos mosaic against the paper and the invariants every model keeps: determinism,
//! seamlessness, the cat map and block constraint, i = 0 as the plain tiling, explicit ≡
//! seed-derived sequences, mip coherence, the storage arithmetic of §3.1, and refusal of bad
//! encodings.

use serde_json::{json, Value};
use vtex_synth::models::chaos_mosaic::{self, ChaosMosaic, RECORD_BYTES};
use vtex_synth::texture::{level_size, render_image};
use vtex_synth::{bundle::Bundle, models, samples, Error, Region, Rgba8Image, Texture};

fn inputs(sample: &Rgba8Image) -> models::Inputs {
    models::Inputs::from([("sample".to_string(), sample.to_png())])
}

fn bundle(sample: &Rgba8Image, params: Value) -> Bundle {
    models::create("chaos-mosaic", "test", &params, &inputs(sample)).unwrap()
}

fn mosaic(sample: &Rgba8Image, params: Value) -> ChaosMosaic {
    chaos_mosaic::load(&bundle(sample, params)).unwrap()
}

fn render(tex: &dyn Texture, level: u32, x: i64, y: i64, w: u32, h: u32) -> Rgba8Image {
    render_image(tex, &Region::new(level, x, y, w, h)).unwrap()
}

fn pebbles64() -> Rgba8Image {
    samples::pebbles(64, 9, 4, true)
}

#[test]
fn output_is_pinned_across_parameter_kinds() {
    // Hashes written by the build before level 0 became bands of spans (8c25bb4): the rewrite,
    // and every later change, must reproduce them bit for bit. Per case: sample w × h, seamless,
    // filter width, blocks per tile, iterations; then five regions (levels 0, 0, 0, 1, 2) and
    // the seam mask.
    let cases = [
        (
            (64, 64, true, 3, 1, 10),
            ["c15a91a99467", "1e0a64a226b0", "f3e05dff3aa9", "c0acd01c5036", "45d8c82c89bb", "55e7773e57b7"],
        ),
        (
            (64, 64, false, 3, 1, 10),
            ["8b35330a8b14", "4798b4b1a2e3", "8372b9a2b2ca", "8248f71cb38c", "c5f8ce44c668", "58456c05911c"],
        ),
        (
            (48, 80, false, 5, 2, 10),
            ["dd40190dd472", "160e63a9d0d4", "c379d1922a46", "155a3a06e1b5", "78391557f341", "0e5c62a128ce"],
        ),
        (
            (64, 64, false, 8, 1, 3),
            ["fbcabfc8f90f", "a8eacd063126", "3c583de32070", "ad11f01bb2ab", "d7cf02515a5a", "c2d757000c1d"],
        ),
        (
            (64, 64, true, 0, 1, 10),
            ["5811d0eecf5b", "6af6d61fd419", "e71c141ebcf1", "4d319c8e5cc4", "5b2ff54d2dc0", "62433c297167"],
        ),
        (
            (33, 47, false, 1, 2, 10),
            ["8746806898e9", "47e62b90f6ae", "95327cc94769", "ac43dfc22425", "414412621255", "f6ae44980f8c"],
        ),
        (
            (64, 64, false, 2, 1, 0),
            ["25a2eea3263c", "ac78dd0ea92c", "f56e2677e1d3", "bc8ce55ada65", "31fbefab382a", "46644e049510"],
        ),
        (
            (100, 60, true, 4, 2, 7),
            ["083e529f4bcb", "a50c9be9780b", "f45f902643b7", "d97399ba93d2", "87ac99d092b4", "7c5d41c5903b"],
        ),
    ];
    let regions = [
        (0, 0i64, 0i64, 500u32, 530u32),
        (0, -37, 1000, 123, 77),
        (0, 5000, -3, 256, 256),
        (1, 3, 9, 200, 190),
        (2, 0, 0, 100, 100),
    ];
    for (k, ((sw, sh, seamless, filter_width, blocks_per_tile, iterations), want)) in cases.into_iter().enumerate() {
        let sample = samples::pebbles(sw.max(sh), 8, 1, seamless).crop(0, 0, sw, sh);
        let params = json!({"tiles_x": 7, "tiles_y": 9, "seed": k, "filter_width": filter_width,
            "blocks_per_tile": blocks_per_tile, "iterations": iterations, "seamless": seamless});
        let tex = mosaic(&sample, params);
        let mut got: Vec<String> = regions
            .iter()
            .map(|&(level, x, y, w, h)| {
                vtex_synth::bundle::id_of(&render(&tex, level, x, y, w, h).data)[..12].to_string()
            })
            .collect();
        let mask: Vec<u8> = tex.seam_mask(-20, 7, 300, 310).into_iter().map(u8::from).collect();
        got.push(vtex_synth::bundle::id_of(&mask)[..12].to_string());
        assert_eq!(got, want, "case {k}");
    }
}

/// Per level 2–9, the hash of the regions `regions(level)` of `tex`, each rendered alone.
fn mid_level_hashes(tex: &dyn Texture, regions: impl Fn(u32) -> Vec<(i64, i64, u32, u32)>) -> Vec<String> {
    (2..=9)
        .map(|level| {
            let data: Vec<u8> =
                regions(level).into_iter().flat_map(|(x, y, w, h)| render(tex, level, x, y, w, h).data).collect();
            vtex_synth::bundle::id_of(&data)[..12].to_string()
        })
        .collect()
}

#[test]
fn mid_levels_are_pinned_across_parameter_kinds() {
    // Hashes of the mid levels as first served (commit c7db1bd): bundles already served must
    // keep their tiles, so every later speed-up must reproduce them bit for bit. Regions
    // wrap the torus and reach the partial last pixels of odd-sized levels.
    let cases = [
        (
            (64, 64, true, 3, 1, 10),
            [
                "99b7a264ac96",
                "52c8f3b113c1",
                "54c4a58ce6e3",
                "04255e3ec4e4",
                "8c66b80bb339",
                "8c66b80bb339",
                "8c66b80bb339",
                "8c66b80bb339",
            ],
        ),
        (
            (64, 64, false, 3, 1, 10),
            [
                "acc34c5f1a4c",
                "dc96b7d7c5d5",
                "2deca6d98e45",
                "34dce99c5391",
                "7fb6b7eba209",
                "7fb6b7eba209",
                "7fb6b7eba209",
                "7fb6b7eba209",
            ],
        ),
        (
            (48, 80, false, 5, 2, 10),
            [
                "77feefe6cf36",
                "6c8228556368",
                "72d2f4150e82",
                "f23c53bcaefe",
                "c65a6f1b87d5",
                "4e05af93e898",
                "6c28cd02e9ae",
                "743d4c939ae8",
            ],
        ),
        (
            (64, 64, false, 8, 1, 3),
            [
                "c326cca70440",
                "a0ca3dc6367c",
                "22e3a1992abf",
                "6d78df6612ae",
                "7fb6b7eba209",
                "7fb6b7eba209",
                "7fb6b7eba209",
                "7fb6b7eba209",
            ],
        ),
        (
            (64, 64, true, 0, 1, 10),
            [
                "e2bd62bb6270",
                "2f7ab8bcd358",
                "e12a4e126c12",
                "1f0c18d4ce14",
                "8c66b80bb339",
                "8c66b80bb339",
                "8c66b80bb339",
                "8c66b80bb339",
            ],
        ),
        (
            (33, 47, false, 1, 2, 10),
            [
                "87a1b2c5e4d9",
                "f7afeba7c9bc",
                "ea366f35306e",
                "d407d2012af9",
                "35e0e176b237",
                "8fabcdbe6fd7",
                "43aa8a2ed1a7",
                "43aa8a2ed1a7",
            ],
        ),
        (
            (100, 60, true, 4, 2, 7),
            [
                "91c9caefcd43",
                "1f01041b5a62",
                "f1a49ef02042",
                "4de41a63c22c",
                "8900d279895c",
                "921717d29305",
                "efe309878855",
                "5d5bbbcb2401",
            ],
        ),
    ];
    for (k, ((sw, sh, seamless, filter_width, blocks_per_tile, iterations), want)) in cases.into_iter().enumerate() {
        let sample = samples::pebbles(sw.max(sh), 8, 1, seamless).crop(0, 0, sw, sh);
        let params = json!({"tiles_x": 7, "tiles_y": 9, "seed": k, "filter_width": filter_width,
            "blocks_per_tile": blocks_per_tile, "iterations": iterations, "seamless": seamless});
        let tex = mosaic(&sample, params);
        let got = mid_level_hashes(&tex, |level| {
            let (lw, lh) = level_size(tex.width(), tex.height(), level);
            vec![(-3, 5, 40, 37), (lw as i64 - 7, lh as i64 - 5, 13, 11), (11, 2, 1, 1)]
        });
        assert_eq!(got, want, "case {k}");
    }
}

#[test]
fn mid_levels_of_the_100k_mosaics_are_pinned() {
    // The bench's mosaic (one block a tile) and the served demo (two): 256² tiles mid-level and
    // across the wrap, where the fast paths (merged cells, rasterized and indexed layers) run.
    const BENCH: [&str; 8] = [
        "265597ea9b3a",
        "67fd435c4d8d",
        "7a6ee24e544a",
        "f1405c61fe18",
        "5c4e20d22f59",
        "b23b6b4e8326",
        "2ecea3b21730",
        "565c4c604823",
    ];
    const DEMO: [&str; 8] = [
        "27b3b93e4b35",
        "e52d4c99d36c",
        "307b5c8cb46d",
        "90cd54ae4c89",
        "57f7c72bddb2",
        "80b9f508bdaf",
        "32c67a8b37d6",
        "565c4c604823",
    ];
    let bench = bundle(&samples::pebbles(160, 24, 11, true), json!({"tiles_x": 625, "tiles_y": 625, "seed": 1}));
    for (name, b, want) in [("bench", bench, BENCH), ("demo", chaos_mosaic::demos().swap_remove(0), DEMO)] {
        let tex = chaos_mosaic::load(&b).unwrap();
        let got = mid_level_hashes(&tex, |level| {
            let (lw, _) = level_size(tex.width(), tex.height(), level);
            let at = (lw as i64 / 2 / 256) * 256;
            vec![(at, at, 256, 256), (-128, -77, 256, 256), (at + 256, 768, 256, 256)]
        });
        assert_eq!(got, want, "{name}");
    }
}

#[test]
fn opening_the_100k_demo_and_rendering_a_tile_draws_only_the_blocks_near_it() {
    let demo = chaos_mosaic::demos().swap_remove(0);
    let (tex, eager) = (chaos_mosaic::load(&demo).unwrap(), chaos_mosaic::load(&demo).unwrap());
    let all = eager.blocks();
    assert_eq!(tex.blocks_held(), 0, "nothing is drawn when the texture is opened");
    let (x0, y0, size) = (51_200i64, 76_800i64, 256u32);
    let tile = render(&tex, 0, x0, y0, size, size);
    // The blocks meeting the tile and its filter margin have their corner in the tiles under it
    // or one tile left of or above it: those home tiles' blocks, and no others, are drawn.
    let (side, margin) = (160i64, tex.params().filter_width as i64);
    let homes = |a: i64| (a - margin).div_euclid(side) - 1..=(a + size as i64 + margin - 1).div_euclid(side);
    let near =
        all.iter().filter(|b| homes(x0).contains(&(b.s as i64 / side)) && homes(y0).contains(&(b.t as i64 / side)));
    assert_eq!(tex.blocks_held(), near.count());
    assert!(tex.blocks_held() < 100, "{} of {} blocks drawn", tex.blocks_held(), all.len());
    assert_eq!(tile, render(&eager, 0, x0, y0, size, size), "the same pixels as from the whole index");
}

/// Renders `tiles × tiles` tiles of `size` and one region covering them, and compares.
fn assert_tiles_match_region(tex: &dyn Texture, level: u32, x0: i64, y0: i64, size: u32, tiles: u32) {
    let whole = render(tex, level, x0, y0, size * tiles, size * tiles);
    for ty in 0..tiles {
        for tx in 0..tiles {
            let tile = render(tex, level, x0 + (tx * size) as i64, y0 + (ty * size) as i64, size, size);
            assert_eq!(
                tile,
                whole.crop(tx * size, ty * size, size, size),
                "level {level} tile ({tx},{ty}) from ({x0},{y0})"
            );
        }
    }
}

#[test]
fn every_block_obeys_the_area_constraint_and_lies_in_the_sample() {
    for (n, cl, cu, per_tile) in [(64u32, 0.5, 0.75, 1), (100, 0.3, 0.4, 1), (37, 0.5, 0.75, 1), (64, 0.5, 0.75, 3)] {
        let sample = samples::lichen(n, 1);
        let params =
            json!({"tiles_x": 30, "tiles_y": 30, "seed": n, "c_lambda": cl, "c_mu": cu, "blocks_per_tile": per_tile});
        let tex = mosaic(&sample, params);
        assert_eq!(tex.blocks().len(), 900 * per_tile, "{per_tile} blocks per tile");
        for b in tex.blocks() {
            let ratio = b.w as f64 * b.h as f64 / (n * n) as f64;
            assert!((cl..=cu).contains(&ratio), "{b:?}: wh/n² = {ratio}");
            assert!(b.x as u32 + b.w as u32 <= n && b.y as u32 + b.h as u32 <= n, "{b:?}");
            assert!((b.s as u64) < tex.width() && (b.t as u64) < tex.height());
        }
    }
}

#[test]
fn block_corners_follow_the_cat_map_from_their_tile() {
    let n = 64u64;
    let tex = mosaic(&pebbles64(), json!({"tiles_x": 10, "tiles_y": 10, "seed": 2, "iterations": 10}));
    let m = 10 * n;
    for (i, b) in tex.blocks().iter().enumerate() {
        let (k1, k2) = (i as u64 % 10, i as u64 / 10);
        let (mut x, mut y) = (b.x as u64 + k1 * n, b.y as u64 + k2 * n);
        for _ in 0..10 {
            (x, y) = ((x + y) % m, (x + 2 * y) % m);
        }
        assert_eq!((b.s as u64, b.t as u64), (x, y), "block {i}");
    }
}

#[test]
fn zero_iterations_reproduce_the_plain_tiling_exactly() {
    let sample = pebbles64();
    let tex = mosaic(&sample, json!({"tiles_x": 6, "tiles_y": 4, "iterations": 0, "seamless": true, "seed": 8}));
    let img = render(&tex, 0, -50, 20, 500, 300);
    for y in 0..300 {
        for x in 0..500 {
            let (sx, sy) = ((x as i64 - 50).rem_euclid(64) as u32, (y + 20) % 64);
            assert_eq!(img.pixel(x, y), sample.pixel(sx, sy), "({x},{y})");
        }
    }
}

#[test]
fn ten_iterations_are_not_the_tiling() {
    let sample = pebbles64();
    let tex = mosaic(&sample, json!({"tiles_x": 6, "tiles_y": 4, "seed": 8}));
    let img = render(&tex, 0, 0, 0, 384, 256);
    let differing = (0..256)
        .flat_map(|y| (0..384).map(move |x| (x, y)))
        .filter(|&(x, y)| img.pixel(x, y) != sample.pixel(x % 64, y % 64))
        .count();
    assert!(differing > 384 * 256 / 2, "only {differing} pixels differ from the tiling");
}

#[test]
fn explicit_and_seed_derived_sequences_render_identically() {
    let sample = samples::lichen(128, 3);
    let seeded = bundle(&sample, json!({"tiles_x": 12, "tiles_y": 9, "seed": 77}));
    let explicit = bundle(&sample, json!({"tiles_x": 12, "tiles_y": 9, "seed": 77, "sequence": "explicit"}));
    assert_eq!(explicit.section("blocks").unwrap().len(), 12 * 9 * RECORD_BYTES);
    let (a, b) = (models::load(&seeded).unwrap(), models::load(&explicit).unwrap());
    for level in [0, 1, 3, 6] {
        assert_eq!(render(&*a, level, 0, 0, 200, 150), render(&*b, level, 0, 0, 200, 150), "level {level}");
    }
}

#[test]
fn storage_matches_the_papers_arithmetic() {
    // §3.1: the block sequence of an m × m texture from an n × n sample takes 12 m²/n² bytes
    // (one 12-byte record per tile); with b blocks a tile, b times that. Everything else in
    // the bundle (manifest, sample) does not grow with the texture.
    let size_of = |sample: &Rgba8Image, tiles: (u32, u32), per_tile: u32| {
        let b = bundle(
            sample,
            json!({"tiles_x": tiles.0, "tiles_y": tiles.1, "blocks_per_tile": per_tile, "sequence": "explicit"}),
        );
        let tex = models::load(&b).unwrap();
        let (m2, n2) = (tex.width() * tex.height(), (sample.width * sample.height) as u64);
        let blocks = b.section("blocks").unwrap().len() as u64;
        assert_eq!(blocks, 12 * per_tile as u64 * m2 / n2, "{tiles:?} tiles of {}×{}", sample.width, sample.height);
        (b.to_bytes().len() as u64, m2, n2)
    };
    for (sample, per_tile) in [
        (samples::lichen(128, 3), 1),
        (samples::pebbles(64, 9, 4, true), 2),
        (samples::lichen(48, 1).crop(0, 0, 48, 30), 3),
    ] {
        let (small, m2_small, n2) = size_of(&sample, (10, 20), per_tile);
        let (large, m2_large, _) = size_of(&sample, (30, 60), per_tile);
        // Same digit count in the manifest: the whole difference is the sequence.
        assert_eq!(large - small, 12 * per_tile as u64 * (m2_large - m2_small) / n2, "{per_tile} blocks a tile");
    }
    // §3.3: a 5000² texture from a 128² 24-bit sample, about 67 KB. 5000 is not a multiple of
    // 128, so the nearest mosaic is 40×40 tiles (5120²); the sample is stored as PNG.
    let sample = samples::lichen(128, 3);
    let (stored, m2, n2) = size_of(&sample, (40, 40), 1);
    let paper = 12 * 5000u64.pow(2) / 128u64.pow(2) + 3 * 128 * 128;
    let ours = 12 * m2 / n2 + 3 * 128 * 128;
    let png = sample.to_png().len();
    println!("5120² chaos mosaic: bundle {stored} B (sample PNG {png} B, blocks {} B); the paper's formula gives {paper} B at 5000², {ours} B at 5120²; explicit texture {} B", 12 * m2 / n2, m2 * 3);
    assert!(stored <= ours + 1024, "bundle of {stored} B, the paper's arithmetic gives {ours} B");
    // Seed-derived: the structure is the seed, whatever the size ("781" is one digit longer
    // than "40" in each of two places).
    let seeded = |t: u32| bundle(&sample, json!({"tiles_x": t, "tiles_y": t})).to_bytes().len();
    assert_eq!(seeded(781) - seeded(40), 2);
}

#[test]
fn non_square_textures_and_samples_work() {
    let sample = Rgba8Image::from_raw(48, 30, samples::lichen(48, 1).crop(0, 0, 48, 30).data).unwrap();
    let tex = mosaic(&sample, json!({"tiles_x": 7, "tiles_y": 3, "seed": 1}));
    assert_eq!((tex.width(), tex.height()), (336, 90));
    assert_tiles_match_region(&tex, 0, 300, 60, 32, 3);
    assert_tiles_match_region(&tex, 1, 0, 0, 32, 2);
}

#[test]
fn alpha_is_carried_through() {
    let mut sample = pebbles64();
    for (i, px) in sample.data.chunks_exact_mut(4).enumerate() {
        px[3] = (i % 200) as u8 + 50;
    }
    let tex = mosaic(&sample, json!({"tiles_x": 4, "tiles_y": 4, "seed": 1, "iterations": 0, "seamless": true}));
    assert_eq!(render(&tex, 0, 0, 0, 64, 64), sample);
}

fn create_err(sample: &Rgba8Image, params: Value) -> String {
    match models::create("chaos-mosaic", "bad", &params, &inputs(sample)) {
        Ok(_) => panic!("{params} was accepted"),
        Err(e) => e.to_string(),
    }
}

#[test]
fn bad_parameters_are_refused_with_a_reason() {
    let s = pebbles64();
    let cases = [
        (json!({"tiles_x": 0, "tiles_y": 4}), "tiles_x"),
        (json!({"tiles_x": 100000, "tiles_y": 100000}), "tiles"),
        (json!({"tiles_x": 4, "tiles_y": 4, "iterations": 1_000_000}), "iterations"),
        (json!({"tiles_x": 4, "tiles_y": 4, "c_lambda": 0.9, "c_mu": 0.5}), "c_lambda"),
        (json!({"tiles_x": 4, "tiles_y": 4, "c_mu": 1.5}), "c_mu"),
        (json!({"tiles_x": 4, "tiles_y": 4, "filter_width": 99}), "filter_width"),
        (json!({"tiles_x": 4, "tiles_y": 4, "blocks_per_tile": 0}), "blocks_per_tile"),
        (json!({"tiles_x": 4, "tiles_y": 4, "blocks_per_tile": 9}), "blocks_per_tile"),
        (json!({"tiles_x": 4}), "tiles_y"),
        (json!({"tiles_x": -3, "tiles_y": 4}), "tiles_x"),
    ];
    for (params, needle) in cases {
        let e = create_err(&s, params.clone());
        assert!(e.contains(needle), "{params} → {e}");
    }
    // A sample too small for the block constraint.
    let tiny = samples::lichen(1, 1);
    assert!(create_err(&tiny, json!({"tiles_x": 4, "tiles_y": 4, "c_lambda": 0.6, "c_mu": 0.7})).contains("too small"));
    // Explicit 12-byte records need a sample of at most 256².
    let big = samples::lichen(300, 1);
    assert!(create_err(&big, json!({"tiles_x": 2, "tiles_y": 2, "sequence": "explicit"})).contains("256"));
    // Missing or broken sample.
    let e = models::create("chaos-mosaic", "bad", &json!({"tiles_x": 2, "tiles_y": 2}), &models::Inputs::new())
        .unwrap_err();
    assert!(e.to_string().contains("sample"), "{e}");
    let junk = models::Inputs::from([("sample".to_string(), b"\x89PNG\r\n\x1a\nnot really".to_vec())]);
    assert!(matches!(
        models::create("chaos-mosaic", "bad", &json!({"tiles_x": 2, "tiles_y": 2}), &junk),
        Err(Error::Image { .. })
    ));
}

fn explicit_bundle() -> Bundle {
    bundle(&pebbles64(), json!({"tiles_x": 4, "tiles_y": 4, "seed": 1, "sequence": "explicit"}))
}

fn load_err(b: &Bundle) -> String {
    match models::load(b) {
        Ok(_) => panic!("accepted"),
        Err(e) => e.to_string(),
    }
}

fn with_blocks(mut b: Bundle, edit: impl FnOnce(&mut Vec<u8>)) -> Bundle {
    let s = b.sections.iter_mut().find(|s| s.name == "blocks").unwrap();
    edit(&mut s.data);
    b
}

#[test]
fn hostile_block_sequences_are_refused() {
    // Truncated record.
    assert!(load_err(&with_blocks(explicit_bundle(), |d| d.truncate(d.len() - 5))).contains("multiple of 12"));
    // Block reaching outside the sample: x = 60 with w ≥ 32 in a 64² sample.
    assert!(load_err(&with_blocks(explicit_bundle(), |d| d[0] = 60)).contains("outside the 64×64 sample"));
    // Pasted outside the texture (s = 10^6 on a 256-wide torus).
    assert!(load_err(&with_blocks(explicit_bundle(), |d| d[4..8].copy_from_slice(&1_000_000u32.to_le_bytes())))
        .contains("outside the 256×256 texture"));
    // A 1×1 block breaks the area constraint.
    assert!(load_err(&with_blocks(explicit_bundle(), |d| {
        d[2] = 0;
        d[3] = 0;
    }))
    .contains("area constraint"));
    // Sections that do not belong.
    let mut b = explicit_bundle();
    b.sections.retain(|s| s.name != "blocks");
    assert!(load_err(&b).contains("blocks"));
    let b = explicit_bundle().with_section("extra", vec![1]);
    assert!(load_err(&b).contains("unexpected section"));
    let mut b = explicit_bundle();
    b.manifest.derived.remove("seamless").expect("derived by create");
    assert!(load_err(&b).contains("seamless"));
}
