//! The `lcm` model against the paper and the invariants every model keeps: event codes, the
//! four-replication bound, the order of non-commutative operations, LCM statistics, periods,
//! native mip levels, consistency, seamlessness, encoding size, operation counts and bad input.

use serde_json::json;
use std::collections::BTreeMap;
use vtex_synth::bundle::Bundle;
use vtex_synth::models::lcm::{
    self, demos,
    event::{Event, Sign},
    table::Table,
    LcmTexture, OpCount, Params,
};
use vtex_synth::models::{self, Inputs};
use vtex_synth::texture::render_image;
use vtex_synth::{mip, Region, Rgba8Image, Texture};

/// The encoding of `p` with one byte a mask point (the paper's §6 count).
fn raw_masks(mut p: Params) -> Bundle {
    p.mask_coding = lcm::packing::MaskCoding::Raw;
    demos::make("raw", &p).unwrap()
}

fn demo(name: &str) -> (Bundle, LcmTexture) {
    let (n, p) = demos::all_params().into_iter().find(|(n, _)| *n == name).expect("demo exists");
    let b = demos::make(n, &p).unwrap();
    let t = lcm::load(&b).unwrap();
    (b, t)
}

fn render(t: &LcmTexture, level: u32, x: i64, y: i64, w: u32, h: u32) -> Rgba8Image {
    render_image(t, &Region::new(level, x, y, w, h)).unwrap()
}

/// An element image whose every pixel has grey level `grey` (intensity grey − 128).
fn flat_element(side: u32, grey: u8) -> Inputs {
    let mut img = Rgba8Image::new(side, side);
    for y in 0..side {
        for x in 0..side {
            img.set_pixel(x, y, [grey, grey, grey, 255]);
        }
    }
    BTreeMap::from([("element".to_string(), img.to_png())])
}

/// Grey level = intensity + 128.
const GREY: [[f64; 4]; 2] = [[-128.0, 0.0, 0.0, 0.0], [127.0, 255.0, 255.0, 255.0]];

// ---------------------------------------------------------------- event codes (§5)

#[test]
fn every_seven_bit_event_code_decodes_and_encodes_to_itself() {
    let mut events = 0;
    for code in 0..=255u8 {
        match Event::decode(code) {
            Ok(e) => {
                assert!(code < 128, "an 8-bit code decoded");
                assert_eq!(e.encode(), code, "code {code:#04x}");
                events += 1;
            }
            Err(e) => {
                let sign_bits = code & 3 == 3;
                let op_bits = (code >> 5) & 3 == 3;
                assert!(code >= 128 || sign_bits || op_bits, "valid code {code:#04x} refused: {e}");
                assert!(e.to_string().contains(&format!("{code:#04x}")), "the error names the code: {e}");
            }
        }
    }
    // 3 signs × 4 rotations × 2 mirrorings × 3 operations.
    assert_eq!(events, 72);
}

// ---------------------------------------------------------------- at most four replications (§6)

/// An element whose intensity e(u, v) = 4·((u + 2v) mod 7) − 12 differs along both axes,
/// added unrotated at weight ¼ with random signs: a pixel's grey is 128 + Σ ±e(u, v)/4 over
/// the replications covering it. The brute force lays the element square of every point
/// (i, j) of the stored LCM at [i·h, i·h + 2h) × [j·h, j·h + 2h) over the periodic plane and
/// sums; no renderer code is involved. At most four replications of a layer meet at a pixel,
/// and when every point replicates, exactly four.
#[test]
fn each_pixel_sums_exactly_the_replications_whose_element_covers_it() {
    let (side, lw, lh) = (8i64, 12i64, 10i64);
    let h = side / 2;
    let e = |u: i64, v: i64| 4 * ((u + 2 * v) % 7) - 12;
    let mut element = Rgba8Image::new(side as u32, side as u32);
    for v in 0..side {
        for u in 0..side {
            let g = (128 + e(u, v)) as u8;
            element.set_pixel(u as u32, v as u32, [g, g, g, 255]);
        }
    }
    let inputs = BTreeMap::from([("element".to_string(), element.to_png())]);
    for (sign, all) in [([0.4, 0.3, 0.3], false), ([1.0, 0.0, 0.0], true)] {
        let cell = json!({"sign": sign, "rotation": [1.0, 0.0, 0.0, 0.0], "mirror": 0.0});
        let params = json!({"palette": GREY, "layers": [{"layer": 0, "weight": 0.25, "lcm": [lw, lh],
            "table": {"width": 1, "height": 1, "cells": [cell]}}]});
        let b = lcm::create("cover", &params, &inputs).unwrap();
        let t = lcm::load(&b).unwrap();
        let codes = b.section("lcm.0").unwrap();
        // Across the torus edge, from negative coordinates.
        let (x0, y0, w, ht) = (-30i64, -17i64, 120u32, 90u32);
        let img = render(&t, 0, x0, y0, w, ht);
        let mut touches = BTreeMap::new();
        for j in 0..ht {
            for i in 0..w {
                let (x, y) = (x0 + i as i64, y0 + j as i64);
                let (mut sum, mut touch) = (0, 0);
                for pj in 0..lh {
                    for pi in 0..lw {
                        let s = match Event::decode(codes[(pj * lw + pi) as usize]).unwrap().sign {
                            Sign::None => 0,
                            Sign::Positive => 1,
                            Sign::Negative => -1,
                        };
                        let (u, v) = ((x - pi * h).rem_euclid(lw * h), (y - pj * h).rem_euclid(lh * h));
                        if s != 0 && u < side && v < side {
                            sum += s * e(u, v) / 4;
                            touch += 1;
                        }
                    }
                }
                *touches.entry(touch).or_insert(0) += 1;
                assert_eq!(img.pixel(i, j)[0] as i64, 128 + sum, "pixel ({x}, {y}): {touch} replications");
            }
        }
        eprintln!("pixels by replications covering them ({}): {touches:?}", if all { "all points" } else { "random" });
        let most = *touches.keys().max().unwrap();
        if all {
            assert_eq!(touches.keys().copied().collect::<Vec<_>>(), vec![4], "every pixel under exactly four");
        } else {
            assert!(most <= 4 && touches.len() == most + 1, "counts 0..={most} all occur: {touches:?}");
        }
    }
}

// ---------------------------------------------------------------- order of application (§2.2)

fn two_layers(op: [f64; 3], order: &str, second_weight: f64, second_sign: [f64; 3]) -> LcmTexture {
    let cell = |sign: [f64; 3]| json!({"sign": sign, "operation": op});
    let params = json!({
        "palette": GREY, "order": order,
        "layers": [
            {"layer": 0, "weight": 1.0, "lcm": [3, 3], "table": {"width": 1, "height": 1, "cells": [cell([1.0, 0.0, 0.0])]}},
            {"layer": 1, "weight": second_weight, "lcm": [5, 5], "table": {"width": 1, "height": 1, "cells": [cell(second_sign)]}}
        ]
    });
    let b = lcm::create("order", &params, &flat_element(4, 228)).unwrap();
    lcm::load(&b).unwrap()
}

#[test]
fn non_commutative_operations_honour_the_order() {
    // A flat element of intensity 100 on layer 0, and on layer 1 its negative at weight ½.
    let grey = |t: &LcmTexture| render(t, 0, 0, 0, 8, 8).pixel(3, 5)[0] as i32;
    // Grey level = intensity + 128.
    let top_down = two_layers([0.0, 1.0, 0.0], "top_down", 0.5, [0.0, 1.0, 0.0]);
    let bottom_up = two_layers([0.0, 1.0, 0.0], "bottom_up", 0.5, [0.0, 1.0, 0.0]);
    assert_eq!(grey(&top_down), 128 - 50, "non-zero: layer 1 applied last wins");
    assert_eq!(grey(&bottom_up), 128 + 100, "non-zero: layer 0 applied last wins");
    // Maximum application, §2.2: a stays where |a| > |b|, else b — so of equal magnitudes
    // the replication applied last wins.
    let top_down = two_layers([0.0, 0.0, 1.0], "top_down", 1.0, [0.0, 1.0, 0.0]);
    let bottom_up = two_layers([0.0, 0.0, 1.0], "bottom_up", 1.0, [0.0, 1.0, 0.0]);
    assert_eq!(grey(&top_down), 128 - 100);
    assert_eq!(grey(&bottom_up), 128 + 100);
    // Larger magnitude wins whatever the order.
    let a = two_layers([0.0, 0.0, 1.0], "top_down", 0.5, [0.0, 1.0, 0.0]);
    let b = two_layers([0.0, 0.0, 1.0], "bottom_up", 0.5, [0.0, 1.0, 0.0]);
    assert_eq!((grey(&a), grey(&b)), (228, 228));
    // Addition commutes: both orders give 100 + 4 × (−50) replications meeting... the same image.
    let a = two_layers([1.0, 0.0, 0.0], "top_down", 0.5, [0.0, 1.0, 0.0]);
    let b = two_layers([1.0, 0.0, 0.0], "bottom_up", 0.5, [0.0, 1.0, 0.0]);
    assert_eq!(render(&a, 0, 0, 0, 40, 40), render(&b, 0, 0, 0, 40, 40));
}

// ---------------------------------------------------------------- LCM statistics (chi-square)

/// Upper 0.1 % point of the chi-square distribution (Wilson–Hilferty).
fn chi_square_critical(df: f64) -> f64 {
    let z = 3.090_232;
    let a = 2.0 / (9.0 * df);
    df * (1.0 - a + z * a.sqrt()).powi(3)
}

/// Chi-square of the codes of the points governed by table cell (ci, cj) against that cell.
fn chi_square(codes: &[u8], w: usize, table: &Table, ci: usize, cj: usize, against: &Table) -> (f64, f64) {
    let (tw, th) = (table.width as usize, table.height as usize);
    let mut counts = [0u64; 128];
    let mut n = 0u64;
    for (at, &c) in codes.iter().enumerate() {
        if at % w % tw == ci && at / w % th == cj {
            counts[c as usize] += 1;
            n += 1;
        }
    }
    let cell = &against.cells[cj * tw + ci];
    let (mut chi, mut df) = (0.0, -1.0);
    for code in 0..128u8 {
        let p = cell.probability_of(code);
        let o = counts[code as usize] as f64;
        if p > 0.0 {
            let e = p * n as f64;
            chi += (o - e) * (o - e) / e;
            df += 1.0;
        } else if o > 0.0 {
            // An event the cell forbids.
            chi = f64::INFINITY;
        }
    }
    (chi, df)
}

#[test]
fn event_frequencies_match_their_tables() {
    // Tab. 2 (17 events) over 240 × 240 points, and each cell of Tab. 3 over 4 × 2 tables.
    for (table, size) in [(demos::table_noise(), 240u32), (demos::table_brick(), 300)] {
        table.check([size, size], "t").unwrap();
        let codes = table.generate([size, size], 42, 0);
        for cj in 0..table.height as usize {
            for ci in 0..table.width as usize {
                let (chi, df) = chi_square(&codes, size as usize, &table, ci, cj, &table);
                let crit = chi_square_critical(df.max(1.0));
                eprintln!("cell ({ci},{cj}): chi² = {chi:.1} with {df} df (0.1% critical {crit:.1})");
                assert!(chi < crit, "cell ({ci},{cj}): chi² {chi} ≥ {crit}");
            }
        }
    }
    // The test can fail: the brick cells of a row swapped do not fit.
    let t = demos::table_brick();
    let mut swapped = t.clone();
    swapped.cells.swap(0, 2);
    let codes = t.generate([300, 300], 42, 0);
    let (chi, df) = chi_square(&codes, 300, &t, 0, 0, &swapped);
    assert!(chi > chi_square_critical(df), "swapped cells fit: {chi}");
    // The demo's stored LCM is the one its table gives, its zeros coded (§6).
    let (b, _) = demo("LCM brick wall");
    let drawn = t.generate([40, 40], 3, 0);
    assert_eq!(b.section("lcm.0").unwrap(), lcm::packing::pack(&drawn, &t, 40).as_slice());
    assert_eq!(drawn.iter().filter(|&&c| c == 0).count(), 40 * 40 / 2, "the staggered zeros");
}

// ---------------------------------------------------------------- periods (§5)

#[test]
fn paper_lcm_sizes_50x60_and_75x45_give_their_period() {
    let single =
        json!({"width": 1, "height": 1, "cells": [{"sign": [0.5, 0.2, 0.3], "rotation": [0.25, 0.25, 0.25, 0.25]}]});
    let params = json!({
        "element": {"builtin": "stroke", "k": 5}, "palette": GREY,
        "layers": [
            {"layer": 0, "lcm": [50, 60], "table": single},
            {"layer": 1, "lcm": [75, 45], "table": single}
        ]
    });
    let t = lcm::load(&lcm::create("p", &params, &Inputs::new()).unwrap()).unwrap();
    // Layer 0: 50·16 × 60·16 px; layer 1: 75·8 × 45·8 px.
    assert_eq!(t.period(), (2400, 2880));
    assert_eq!((t.width(), t.height()), (2400, 2880));
    eprintln!("50×60 and 75×45 LCMs at spacing 16 and 8: period {:?} (layers alone: 800×960, 600×360)", t.period());
}

/// Distinct prime factors.
fn primes(mut n: u64) -> Vec<u64> {
    let mut out = Vec::new();
    let mut p = 2;
    while p * p <= n {
        if n % p == 0 {
            out.push(p);
            while n % p == 0 {
                n /= p;
            }
        }
        p += 1;
    }
    if n > 1 {
        out.push(n);
    }
    out
}

/// The tile one period away is the same and no shorter period exists (a shorter one would
/// divide the period by a prime); `t` must span at least two periods along each axis.
/// Tiles are 256 × 256: smaller ones can lie wholly under one large occluding replication.
fn check_period(t: &LcmTexture, level: u32, x: i64, y: i64) {
    let (px, py) = t.period();
    let (px, py) = ((px >> level) as i64, (py >> level) as i64);
    let at = |x: i64, y: i64| render(t, level, x, y, 256, 256);
    let tile = at(x, y);
    assert_eq!(tile, at(x + px, y), "one period to the right");
    assert_eq!(tile, at(x, y + py), "one period down");
    for p in primes(px as u64) {
        assert_ne!(tile, at(x + px / p as i64, y), "period {px}/{p} along x");
    }
    for p in primes(py as u64) {
        assert_ne!(tile, at(x, y + py / p as i64), "period {py}/{p} along y");
    }
}

#[test]
fn reported_periods_are_the_true_ones() {
    let (_, brick) = demo("LCM brick wall");
    assert_eq!(brick.period(), (640, 640), "the paper's 640 × 640");
    check_period(&brick, 0, 100, 37);
    check_period(&brick, 2, 5, 9);
    for (name, mut p) in [("pebbles", demos::pebbles()), ("rotation", demos::random_rotation())] {
        p.tiles = [2, 2];
        let t = lcm::load(&demos::make(name, &p).unwrap()).unwrap();
        if name == "pebbles" {
            assert_eq!(t.period(), (100_352, 100_352));
        }
        eprintln!("{name}: period {:?}", t.period());
        check_period(&t, 0, 12_345, 678);
    }
}

// ---------------------------------------------------------------- mip levels (§2.4)

// ---------------------------------------------------------------- invariants every model keeps

// ---------------------------------------------------------------- representation, colour, scaling

#[test]
fn haar_representation_renders_like_the_explicit_copies() {
    let mut p = demos::brick_wall();
    p.representation = lcm::params::Representation::Haar;
    let b = demos::make("haar", &p).unwrap();
    assert_eq!(b.section("haar.0").unwrap().len(), 2 * 32 * 32);
    let haar = lcm::load(&b).unwrap();
    let (_, explicit) = demo("LCM brick wall");
    for level in [0u32, 2, 4] {
        let (a, e) = (render(&haar, level, 0, 0, 160, 160), render(&explicit, level, 0, 0, 160, 160));
        let db = mip::psnr(&a, &e);
        eprintln!("Haar vs explicit copies, level {level}: {db:.1} dB");
        // Resolution K is lossless; lower ones differ by the Haar low-pass rounding.
        assert!(db > 35.0, "level {level}: {db}");
    }
}

#[test]
fn magnification_stretches_the_element() {
    let base = demos::brick_wall();
    let mut big = base.clone();
    big.magnify = 1;
    let (tb, tm) =
        (lcm::load(&demos::make("b", &base).unwrap()).unwrap(), lcm::load(&demos::make("m", &big).unwrap()).unwrap());
    assert_eq!(tm.period(), (1280, 1280));
    let db = mip::psnr(&render(&tm, 1, 0, 0, 256, 256), &render(&tb, 0, 0, 0, 256, 256));
    eprintln!("magnified ×2 then level 1 vs the original level 0: {db:.1} dB");
    assert!(db > 30.0, "{db}");
}

#[test]
fn element_images_give_one_plane_with_a_palette_or_three_without() {
    let table = json!({"width": 1, "height": 1, "cells": [{"sign": [0.5, 0.5, 0.0]}]});
    let mut img = Rgba8Image::new(8, 8);
    img.set_pixel(2, 3, [228, 128, 28, 255]); // intensities +100, 0, −100
    let inputs: Inputs = BTreeMap::from([("element".to_string(), img.to_png())]);
    let rgb = json!({"background": [128.0, 128.0, 128.0], "layers": [{"layer": 0, "lcm": [4, 4], "table": table}]});
    let b = lcm::create("rgb", &rgb, &inputs).unwrap();
    assert_eq!(b.manifest.derived["planes"], 3);
    let t = lcm::load(&b).unwrap();
    let img = render(&t, 0, 0, 0, 16, 16);
    // Transparent pixels (alpha 0 in the image) leave the background.
    assert_eq!(img.pixel(15, 15), [128, 128, 128, 255]);
    assert!(img.data.chunks_exact(4).any(|p| p[0] != p[2]), "channels differ");
    let grey = json!({"palette": GREY, "layers": [{"layer": 0, "lcm": [4, 4], "table": table}]});
    assert_eq!(lcm::create("g", &grey, &inputs).unwrap().manifest.derived["planes"], 1);
}

#[test]
fn an_uploaded_element_is_recovered_from_the_sections_and_makes_the_bundle_again() {
    let table = json!({"width": 1, "height": 1, "cells": [{"sign": [0.4, 0.3, 0.3]}]});
    let mut img = Rgba8Image::new(16, 16);
    for (i, px) in img.data.chunks_exact_mut(4).enumerate() {
        let v = (i * 37 % 256) as u8;
        px.copy_from_slice(&[v, v.wrapping_mul(3), v / 2, if i % 7 == 0 { 0 } else { 255 }]);
    }
    let inputs: Inputs = BTreeMap::from([("element".to_string(), img.to_png())]);
    for (palette, representation) in [(json!(GREY), "explicit"), (json!([]), "explicit"), (json!(GREY), "haar")] {
        let params = json!({"palette": palette, "representation": representation, "mask_coding": "zeros",
                            "layers": [{"layer": 0, "lcm": [6, 4], "table": table}, {"layer": 2, "lcm": [5, 5], "table": table}]});
        let b = lcm::create("uploaded", &params, &inputs).unwrap();
        let model = models::get(lcm::MODEL).unwrap();
        let recovered = model.inputs_of(&b).unwrap();
        assert_ne!(recovered, inputs, "the element comes back as intensities, not as the PNG uploaded");
        let again = model.create("uploaded", &b.manifest.params, &recovered).unwrap();
        assert!(again == b, "{palette} {representation}: the recovered element made another bundle");
    }
}

// ---------------------------------------------------------------- §6: size and operations

#[test]
fn brick_wall_encoding_size_beside_the_paper() {
    let (coded, t) = demo("LCM brick wall");
    let b = raw_masks(demos::brick_wall());
    let payload: usize = b.sections.iter().map(|s| s.data.len()).sum();
    // 40² + 20² + 32² + 8² + 4² (layers 2 and 3 share one LCM).
    assert_eq!(payload, 3104);
    // §6: the zeros of Tab. 3 and Tab. 2 coded, "approximately twice" smaller LCMs.
    let lcm_bytes = |b: &Bundle| b.sections.iter().filter(|s| s.name.starts_with("lcm.")).map(|s| s.data.len()).sum();
    let (raw_lcms, coded_lcms): (usize, usize) = (lcm_bytes(&b), lcm_bytes(&coded));
    eprintln!("brick wall LCMs: {raw_lcms} B raw, {coded_lcms} B zero-coded");
    assert!(coded_lcms * 10 <= raw_lcms * 6, "{coded_lcms} of {raw_lcms}");
    let total = b.to_bytes().len();
    let (pw, ph) = t.period();
    eprintln!(
        "brick wall: LCMs + element copies {payload} B (paper: 3,104 B), whole bundle {total} B \
         (manifest JSON with the event tables); one {pw}×{ph} period at 8 bits = {} B ({:.0}× the payload)",
        pw * ph,
        (pw * ph) as f64 / payload as f64
    );
    for (name, p) in demos::all_params() {
        let b = demos::make(name, &p).unwrap();
        let t = lcm::load(&b).unwrap();
        let explicit = t.width() as f64 * t.height() as f64 * 3.0;
        let bytes = b.to_bytes().len();
        eprintln!("{name}: bundle {bytes} B for {}×{} px ({explicit:.3e} B at 24 bits)", t.width(), t.height());
    }
}

#[test]
fn drawn_masks_are_not_stored_and_render_as_stored_ones() {
    use lcm::packing::MaskCoding;
    let with = |coding: MaskCoding| {
        let mut p = demos::brick_wall();
        p.mask_coding = coding;
        demos::make("coded", &p).unwrap()
    };
    let (zeros, drawn) = (with(MaskCoding::Zeros), with(MaskCoding::Drawn));
    assert!(drawn.sections.iter().all(|s| !s.name.starts_with("lcm.")), "a drawn mask has no section");
    assert!(drawn.to_bytes().len() < zeros.to_bytes().len());
    let (a, b) = (lcm::load(&zeros).unwrap(), lcm::load(&drawn).unwrap());
    for level in [0, 2, 5] {
        assert!(render(&a, level, -300, 40, 200, 150) == render(&b, level, -300, 40, 200, 150), "level {level}");
    }
    // A mask section beside drawn masks is refused, as is a drawn mask with no table to draw it.
    let mut stray = drawn.clone();
    stray.sections.push(zeros.sections.iter().find(|s| s.name == "lcm.0").unwrap().clone());
    let Err(e) = lcm::load(&stray) else { panic!("a stray mask section was accepted") };
    let e = e.to_string();
    assert!(e.contains("unexpected section `lcm.0`"), "{e}");
    let mut p: serde_json::Value = drawn.manifest.params.clone();
    p["layers"][0]["table"] = serde_json::Value::Null;
    let mut tableless = drawn.clone();
    tableless.manifest.params = p;
    let Err(e) = lcm::load(&tableless) else { panic!("a drawn mask with no table was accepted") };
    let e = e.to_string();
    assert!(e.contains("layers[0].table"), "{e}");
}

#[test]
fn operations_per_pixel_within_the_paper_bound() {
    for name in ["LCM random rotation", "LCM brick wall", "LCM cheese", "LCM pebbles 100k"] {
        let (_, t) = demo(name);
        let n = t.layer_count() as u32;
        let mut c = OpCount::default();
        let region = Region::new(0, 0, 0, 512, 512);
        let mut out = vec![0u8; region.byte_len()];
        t.render_counted(&region, &mut out, &mut c);
        // Counts cover every intensity plane; the paper's bound is for one.
        let planes = t.planes() as f64;
        eprintln!(
            "{name}: N = {n}, {planes} plane(s): per plane additions mean {:.2} max {:.1} (4N = {}), \
             multiplications mean {:.2} max {:.1} (N = {n})",
            c.mean_adds() / planes,
            c.max_adds as f64 / planes,
            4 * n,
            c.mean_muls() / planes,
            c.max_muls as f64 / planes
        );
        if name == "LCM random rotation" {
            // Addition only: exactly the paper's bound.
            assert!(c.max_adds <= 4 * n && c.max_muls <= n, "{c:?}");
        }
        assert!(c.max_touch <= 4);
    }
}

// ---------------------------------------------------------------- bad input

fn create_err(params: serde_json::Value, inputs: &Inputs) -> String {
    lcm::create("bad", &params, inputs).unwrap_err().to_string()
}

#[test]
fn bad_tables_sizes_and_elements_are_named() {
    let stroke = json!({"builtin": "stroke", "k": 5});
    let with_cell = |cell: serde_json::Value, lcm: [u32; 2]| {
        json!({"element": stroke, "palette": GREY,
               "layers": [{"layer": 0, "lcm": lcm, "table": {"width": 2, "height": 2, "cells": [cell, {}, {}, {}]}}]})
    };
    let none = Inputs::new();
    let e = create_err(with_cell(json!({"sign": [0.5, 0.4, 0.0]}), [4, 4]), &none);
    assert!(e.contains("layers[0].table.cells[0].sign") && e.contains("not 1"), "{e}");
    let e = create_err(with_cell(json!({"rotation": [1.5, -0.5, 0.0, 0.0]}), [4, 4]), &none);
    assert!(e.contains("negative"), "{e}");
    let e = create_err(with_cell(json!({"mirror": 2.0}), [4, 4]), &none);
    assert!(e.contains("mirror"), "{e}");
    let e = create_err(with_cell(json!({}), [5, 4]), &none);
    assert!(e.contains("not a whole number of 2×2 event tables"), "{e}");
    let e = create_err(with_cell(json!({}), [0, 4]), &none);
    assert!(e.contains("LCM size"), "{e}");
    let e = create_err(json!({"palette": GREY, "layers": [{"layer": 0, "lcm": [2, 2]}]}), &flat_element(8, 200));
    assert!(e.contains("needed to draw the LCM"), "{e}");
    // Base elements that are not 2^K squares.
    let good_layers = json!([{"layer": 0, "lcm": [2, 2], "table": {"width": 1, "height": 1, "cells": [{}]}}]);
    let e = create_err(json!({"palette": GREY, "layers": good_layers}), &flat_element(48, 200));
    assert!(e.contains("power of two"), "{e}");
    let mut wide = Rgba8Image::new(16, 8);
    wide.data.fill(255);
    let e = create_err(
        json!({"palette": GREY, "layers": good_layers}),
        &BTreeMap::from([("element".into(), wide.to_png())]),
    );
    assert!(e.contains("not square"), "{e}");
    let e = create_err(json!({"palette": GREY, "layers": good_layers}), &none);
    assert!(e.contains("element") && e.contains("missing"), "{e}");
    let e =
        create_err(json!({"element": {"builtin": "teapot", "k": 5}, "palette": GREY, "layers": good_layers}), &none);
    assert!(e.contains("teapot"), "{e}");
    let e =
        create_err(json!({"element": {"builtin": "stroke", "k": 12}, "palette": GREY, "layers": good_layers}), &none);
    assert!(e.contains("power of two"), "{e}");
    // A layer below resolution 1, a palette missing, too many planes.
    let e = create_err(
        json!({"element": stroke, "palette": GREY, "layers": [{"layer": 5, "lcm": [2, 2], "table": {"width": 1, "height": 1, "cells": [{}]}}]}),
        &none,
    );
    assert!(e.contains("below resolution 1"), "{e}");
    let e = create_err(json!({"element": stroke, "layers": good_layers}), &none);
    assert!(e.contains("palette"), "{e}");
    let e = create_err(json!({"element": stroke, "palette": GREY, "layers": good_layers, "colour": 3}), &none);
    assert!(e.contains("colour"), "unknown fields are refused: {e}");
}

#[test]
fn bad_encodings_are_refused_with_the_reason() {
    let good = raw_masks(demos::brick_wall());
    let edit = |f: &dyn Fn(&mut Bundle)| {
        let mut b = good.clone();
        f(&mut b);
        lcm::load(&b).unwrap_err().to_string()
    };
    let set = |b: &mut Bundle, name: &str, data: Vec<u8>| {
        b.sections.iter_mut().find(|s| s.name == name).unwrap().data = data;
    };
    // An LCM of the wrong size.
    let e = edit(&|b| set(b, "lcm.0", vec![0; 40 * 39]));
    assert!(e.contains("lcm.0") && e.contains("1560 bytes for an LCM of 40×40"), "{e}");
    // A byte that is no event.
    let e = edit(&|b| {
        let mut d = b.section("lcm.1").unwrap().to_vec();
        d[2 * 20 + 7] = 0x03;
        set(b, "lcm.1", d)
    });
    assert!(e.contains("point (7, 2)") && e.contains("0x03"), "{e}");
    let e = edit(&|b| set(b, "element.0.3", vec![0; 63]));
    assert!(e.contains("element.0.3"), "{e}");
    let e = edit(&|b| b.sections.retain(|s| s.name != "element.0.2"));
    assert!(e.contains("missing section `element.0.2`"), "{e}");
    let e = edit(&|b| b.sections.push(vtex_synth::bundle::Section { name: "extra".into(), data: vec![1] }));
    assert!(e.contains("unexpected section `extra`"), "{e}");
    let e = edit(&|b| b.manifest.derived["k"] = json!(6));
    assert!(e.contains("element.0.6") || e.contains("stored_resolutions"), "{e}");
    let e = edit(&|b| b.manifest.params["layers"][2]["share"] = json!(2));
    assert!(e.contains("share"), "{e}");
    let e = edit(&|b| b.manifest.params["layers"][0]["weight"] = json!(1e9));
    assert!(e.contains("weight"), "{e}");
    let e = edit(&|b| b.manifest.params["tiles"] = json!([0, 1]));
    assert!(e.contains("tiles"), "{e}");
    let e = edit(&|b| b.manifest.params["layers"][0]["table"]["cells"][0]["sign"] = json!([-1.0, 1.0, 1.0]));
    assert!(e.contains("negative"), "{e}");
    let e = edit(&|b| b.manifest.params["magnify"] = json!(u32::MAX));
    assert!(e.contains("magnify"), "{e}");
    let e = edit(&|b| b.manifest.params["layers"][0]["lcm"] = json!([5000, 40]));
    assert!(e.contains("LCM size"), "{e}");
    let e = edit(&|b| b.manifest.derived["planes"] = json!(2));
    assert!(e.contains("planes") || e.contains("palette"), "{e}");
    // Through the registry too, from raw bytes.
    let mut bytes = good.to_bytes();
    let n = bytes.len();
    bytes[n - 1] = 0xff; // last LCM byte (layer 1's LCM is the last section) — bit 7 set
    let b = Bundle::from_bytes(&bytes).unwrap();
    assert!(models::load(&b).err().unwrap().to_string().contains("bit 7"));
}

#[test]
fn demo_parameters_round_trip_through_json() {
    for (_, p) in demos::all_params() {
        let v = serde_json::to_value(&p).unwrap();
        let back: Params = serde_json::from_value(v).unwrap();
        assert_eq!(back, p);
    }
}
