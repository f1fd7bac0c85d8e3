//! The `patterns` model: each §3 block's stated behaviour, the invariants every model keeps and
//! bad input.

use std::collections::BTreeMap;
use std::sync::Arc;
use vtex_synth::bundle::Bundle;
use vtex_synth::models::patterns::animation::{frame, transition_frame};
use vtex_synth::models::patterns::demos;
use vtex_synth::models::patterns::params::*;
use vtex_synth::models::patterns::random::LayerRng;
use vtex_synth::models::patterns::sigma::{self, Sigma, RANDOM_SIZE};
use vtex_synth::models::patterns::transform::TransformBlock;
use vtex_synth::models::patterns::{self as pat, art, pixel_map, PatternTexture};
use vtex_synth::texture::{level_count, render_image};
use vtex_synth::{mip, models, Region, Rgba8Image, Texture};

/// A reference of `tx × ty` flat patterns of side `s`, pattern i coloured (i·16, 255 − i·16, i).
fn flat_reference(tx: u32, ty: u32, s: u32) -> Rgba8Image {
    let pats: Vec<Rgba8Image> = (0..tx * ty)
        .map(|i| {
            let mut img = Rgba8Image::new(s, s);
            for y in 0..s {
                for x in 0..s {
                    // A little texture inside so mip levels are not trivially flat.
                    let v = ((x * 7 + y * 3 + i * 11) % 17) as u8;
                    img.set_pixel(x, y, [(i * 15) as u8 + v, 255 - (i * 15) as u8 - v, (i * 9) as u8 + v, 255]);
                }
            }
            img
        })
        .collect();
    art::pack(&pats, tx, ty)
}

fn params(w: u64, h: u64, s: u32, reference: [u32; 2], layers: Vec<LayerParams>) -> Params {
    Params {
        width: w,
        height: h,
        pattern_size: s,
        reference,
        seed: 7,
        background: [0; 4],
        layers,
        sprites: BTreeMap::new(),
        fps: None,
    }
}

fn tiling(cell: u32, choice: Choice) -> LayerParams {
    LayerParams {
        kind: LayerKind::Tiling,
        cell,
        choice: Some(choice),
        transform: None,
        transitions: None,
        animation: None,
    }
}

fn inline(w: u32, h: u32, values: Vec<u16>) -> MapRef {
    MapRef { size: [w, h], values: Some(values), section: None, depth: 1 }
}

fn build(p: &Params, reference: &Rgba8Image) -> Bundle {
    demos::bundle("test", p, reference, vec![])
}

fn load(b: &Bundle) -> PatternTexture {
    pat::load(b).unwrap()
}

fn err(b: &Bundle) -> String {
    match pat::load(b) {
        Ok(_) => panic!("loaded an invalid encoding"),
        Err(e) => e.to_string(),
    }
}

fn chi_square(counts: &[u64]) -> f64 {
    let n: u64 = counts.iter().sum();
    let e = n as f64 / counts.len() as f64;
    counts.iter().map(|&c| (c as f64 - e).powi(2) / e).sum()
}

// ---------------------------------------------------------------- virtual indirection (σ)

#[test]
fn sigma_hash_is_the_papers_series() {
    // 1D reading of σ(g/T² + σ(g/T + σ(g))) with T = 4, vectorial per §3.5.
    let s = Sigma::generate(4, 4, 9, 0);
    let lookup = |x: u64, y: u64| s.hash(x % 4, y % 4, 1);
    for (gx, gy) in [(0u64, 0u64), (5, 9), (63, 17), (40, 61)] {
        let s0 = lookup(gx, gy);
        let s1 = lookup(gx / 4 + s0.0 as u64, gy / 4 + s0.1 as u64);
        let s2 = lookup(gx / 16 + s1.0 as u64, gy / 16 + s1.1 as u64);
        assert_eq!(s.hash(gx, gy, 3), s2, "cell ({gx}, {gy})");
    }
    assert_eq!(s.steps_for(64, 64), Some(3), "4³ = 64 cells need three steps");
    assert_eq!(Sigma::generate(4, 1, 9, 0).steps_for(64, 64), None, "a 1-wide table cannot hash y");
}

#[test]
fn virtual_choice_is_uniform_and_aperiodic() {
    let b = build(&params(64 * 8, 64 * 8, 8, [4, 4], vec![tiling(8, Choice::Virtual)]), &flat_reference(4, 4, 8));
    let t = load(&b);
    let n = 64u64;
    let grid: Vec<u32> = (0..n * n).map(|i| t.pick(0, i % n, i / n, 0).base.unwrap()).collect();
    // Uniform over all 16 patterns: chi-square with 15 dof, p = 0.001 → 37.7. Also on an
    // unaligned window, where the digit structure does not make it exact.
    let mut counts = [0u64; 16];
    grid.iter().for_each(|&p| counts[p as usize] += 1);
    assert!(chi_square(&counts) < 37.7, "{counts:?}");
    let mut win = [0u64; 16];
    for y in 5..42 {
        for x in 3..56 {
            win[grid[(y * n + x) as usize] as usize] += 1;
        }
    }
    assert!(chi_square(&win) < 37.7, "window {win:?}");
    // Neighbours: every step of the σ chain is a bijection, so two cells whose base-T digits
    // differ in one place never get the same pattern; equal neighbours only occur across a
    // carry. Neighbour repeats are therefore rarer than the 1/16 of independent choices.
    for (dx, dy) in [(1, 0), (0, 1), (1, 1)] {
        let same = (0..n * n)
            .filter(|&i| grid[i as usize] == grid[(((i / n + dy) % n) * n + (i % n + dx) % n) as usize])
            .count();
        let share = same as f64 / (n * n) as f64;
        println!("neighbour ({dx}, {dy}) equal in {share:.4} of cells");
        assert!(share < 1.0 / 16.0, "neighbour ({dx}, {dy}) equal in {share:.3} of cells");
    }
    let mut pairs = vec![0u64; 256];
    for y in 0..n {
        for x in 0..n - 1 {
            pairs[(grid[(y * n + x) as usize] * 16 + grid[(y * n + x + 1) as usize]) as usize] += 1;
        }
    }
    println!("horizontal pair chi-square {:.1} on 255 dof", chi_square(&pairs));
    // Aperiodic: for every translation within the grid, the share of cells equal to their
    // translate stays near 1/16 (a period would give 1).
    let mut worst = 0.0f64;
    let mut at = (0, 0);
    for dy in 0..n {
        for dx in 0..n {
            if dx == 0 && dy == 0 {
                continue;
            }
            let same = (0..n * n)
                .filter(|&i| grid[i as usize] == grid[(((i / n + dy) % n) * n + (i % n + dx) % n) as usize])
                .count();
            if same as f64 / (n * n) as f64 > worst {
                worst = same as f64 / (n * n) as f64;
                at = (dx, dy);
            }
        }
    }
    println!("most repeating translation {at:?}: {worst:.3} of cells");
    assert!(worst < 0.25, "translation {at:?} repeats {worst:.3} of the cells");
}

#[test]
fn aliasing_of_fig_2_2_is_refused_and_power_of_two_ranges_are_exact() {
    // A σ of 256 entries maps onto 16 values exactly: each appears 16 times.
    let s = Sigma::generate(16, 16, 1, 3);
    let mut counts = [0u32; 16];
    for y in 0..16 {
        for x in 0..16 {
            counts[s.below(x, y, 1, 16) as usize] += 1;
        }
    }
    assert!(counts.iter().all(|&c| c == 16), "{counts:?}");
    // A probability map of 12 entries cannot be indexed without bias by a 256-entry σ: an
    // encoding without a range table of 12 is refused...
    let m = vec![MaterialParams { patterns: (0..12).collect(), family: 0 }];
    let p =
        params(96, 96, 8, [4, 4], vec![tiling(8, Choice::Materials { materials: m, areas: None, pixel_map: None })]);
    let mut without = build(&p, &flat_reference(4, 4, 8));
    without.sections.retain(|s| s.name != sigma::RANGES_SECTION);
    let e = err(&without);
    assert!(e.contains("aliasing") && e.contains("12"), "{e}");
    assert_eq!(RANDOM_SIZE, 256);
    // ...while `create` stores a permutation of 0..12 (a σ adapted to the range), and every
    // aligned run of 12 cells then shows each of the 12 entries exactly once.
    let t = load(&build(&p, &flat_reference(4, 4, 8)));
    for gy in 0..12 {
        let mut seen = [0u32; 12];
        for gx in 0..12 {
            seen[t.pick(0, gx, gy, 0).base.unwrap() as usize] += 1;
        }
        assert!(seen.iter().all(|&c| c == 1), "row {gy}: {seen:?}");
    }
}

#[test]
fn probability_maps_of_any_size_give_their_proportions() {
    // 7 entries: pattern 3 five times, pattern 5 twice → 5/7 and 2/7, unbiased.
    let m = vec![MaterialParams { patterns: vec![3, 3, 5, 3, 3, 5, 3], family: 0 }];
    let p = params(
        4 * 7 * 20,
        4 * 7 * 20,
        4,
        [4, 4],
        vec![tiling(4, Choice::Materials { materials: m, areas: None, pixel_map: None })],
    );
    let b = build(&p, &flat_reference(4, 4, 4));
    assert!(b.sections.iter().any(|s| s.name == sigma::RANGES_SECTION));
    let t = load(&b);
    let n = 7 * 20;
    let threes = (0..n).flat_map(|y| (0..n).map(move |x| (x, y))).filter(|&(x, y)| t.pick(0, x, y, 0).base == Some(3));
    let share = threes.count() as f64 / (n * n) as f64;
    assert!((share - 5.0 / 7.0).abs() < 1e-9, "pattern 3 in {share} of cells, exactly 5/7 expected");
    // The encoding made through the registry stores the same table.
    let inputs = models::Inputs::from([("reference".to_string(), flat_reference(4, 4, 4).to_png())]);
    let made = models::create("patterns", "t", &serde_json::to_value(&p).unwrap(), &inputs).unwrap();
    assert_eq!(made.section(sigma::RANGES_SECTION).unwrap(), b.section(sigma::RANGES_SECTION).unwrap());
}

// ---------------------------------------------------------------- probability, areas, dithering

#[test]
fn probability_map_gives_its_proportions() {
    // Material: pattern 3 three times, pattern 5 once → 75 % / 25 %.
    let m = vec![MaterialParams { patterns: vec![3, 3, 5, 3], family: 0 }];
    let p = params(
        128 * 4,
        128 * 4,
        4,
        [4, 4],
        vec![tiling(4, Choice::Materials { materials: m, areas: None, pixel_map: None })],
    );
    let t = load(&build(&p, &flat_reference(4, 4, 4)));
    let mut c3 = 0;
    for y in 0..128 {
        for x in 0..128 {
            match t.pick(0, x, y, 0).base {
                Some(3) => c3 += 1,
                Some(5) => {}
                other => panic!("pattern {other:?} is not in the probability map"),
            }
        }
    }
    let share = c3 as f64 / (128.0 * 128.0);
    assert!((share - 0.75).abs() < 0.015, "pattern 3 in {share:.3} of cells, expected 0.75");
}

#[test]
fn dithering_gives_the_barycentric_proportion() {
    // Areas map 2 × 1: material 0 then 1. The grid is 64 cells wide, so area centres sit at
    // cells 16 and 48: between them the share of material 1 rises linearly (b), and it
    // falls back from 48 to 16 + 64 across the wrap.
    let mats = vec![MaterialParams { patterns: vec![0], family: 0 }, MaterialParams { patterns: vec![1], family: 0 }];
    let areas = AreasParams { map: inline(2, 1, vec![0, 1]), dithered: true };
    let p = params(
        64 * 2,
        2048 * 2,
        2,
        [2, 2],
        vec![tiling(2, Choice::Materials { materials: mats, areas: Some(areas), pixel_map: None })],
    );
    let t = load(&build(&p, &flat_reference(2, 2, 2)));
    for gx in 0..64u64 {
        let ones = (0..2048u64).filter(|&gy| t.material(0, gx, gy) == 1).count() as f64 / 2048.0;
        let a = (gx as f64 + 0.5) * 2.0 / 64.0 - 0.5; // area coordinate of the cell centre
        let b = a - a.floor();
        let expected = if a.floor() as i64 % 2 == 0 { b } else { 1.0 - b };
        assert!((ones - expected).abs() < 0.045, "column {gx}: {ones:.3} of material 1, barycentric {expected:.3}");
    }
    // Without dithering the areas are sharp.
    let mats = vec![MaterialParams { patterns: vec![0], family: 0 }, MaterialParams { patterns: vec![1], family: 0 }];
    let areas = AreasParams { map: inline(2, 1, vec![0, 1]), dithered: false };
    let p = params(
        64 * 2,
        64 * 2,
        2,
        [2, 2],
        vec![tiling(2, Choice::Materials { materials: mats, areas: Some(areas), pixel_map: None })],
    );
    let t = load(&build(&p, &flat_reference(2, 2, 2)));
    for gx in 0..64 {
        assert_eq!(t.material(0, gx, 5), (gx >= 32) as u16);
    }
}

#[test]
fn transition_tiles_come_from_the_four_neighbouring_materials() {
    let b = demos::two_materials();
    let t = load(&b);
    let (nx, ny) = t.grid(0);
    let family = |m: u16| m; // materials 0 and 1 are families 0 and 1 in this demo
    let (mut plain, mut transitions) = (0, 0);
    for gy in 0..ny {
        for gx in 0..nx {
            let corners = [(gx, gy), ((gx + 1) % nx, gy), (gx, (gy + 1) % ny), ((gx + 1) % nx, (gy + 1) % ny)];
            let f = corners.map(|(x, y)| family(t.material(0, x, y)));
            let pick = t.pick(0, gx, gy, 0);
            if f.iter().all(|&v| v == f[0]) {
                plain += 1;
                assert_eq!(pick.n_overlays, 0);
                let base = pick.base.unwrap();
                assert_eq!(base / 16, f[0] as u32, "plain cell ({gx}, {gy}) takes its family's pattern");
            } else {
                transitions += 1;
                let mask: u32 = f.iter().enumerate().map(|(i, &v)| (v as u32) << i).sum();
                assert_eq!(pick.n_overlays, 1);
                assert_eq!(pick.overlays[0], 32 + mask - 1, "cell ({gx}, {gy}) corners {f:?}");
                assert!(pick.base.unwrap() < 16, "the base under a grass border is ground");
            }
        }
    }
    assert!(plain > 1000 && transitions > 100, "{plain} plain, {transitions} transition cells");
}

// ---------------------------------------------------------------- tile transform

/// A square pattern whose red/green channels encode its texel coordinates.
fn gradient_reference(s: u32) -> Rgba8Image {
    let mut img = Rgba8Image::new(s, s);
    for y in 0..s {
        for x in 0..s {
            img.set_pixel(x, y, [(x * 255 / (s - 1)) as u8, (y * 255 / (s - 1)) as u8, 128, 255]);
        }
    }
    img
}

fn sparse(cell: u32, scale: [f32; 2], rotate: bool, overflow: bool) -> LayerParams {
    LayerParams {
        kind: LayerKind::Sparse,
        cell,
        choice: Some(Choice::Materials {
            materials: vec![MaterialParams { patterns: vec![0], family: 0 }],
            areas: None,
            pixel_map: None,
        }),
        transform: Some(TransformParams { scale, rotate, overflow }),
        transitions: None,
        animation: None,
    }
}

#[test]
fn overflowing_patterns_are_continuous_across_cells() {
    // One cell in four holds a pattern (probability map [0, -1, -1, -1]), so most patterns
    // are alone in their neighbourhood and a border pixel belongs to exactly one of them.
    let mut layer = sparse(32, [0.9, 0.9], false, true);
    layer.choice = Some(Choice::Materials {
        materials: vec![MaterialParams { patterns: vec![0, -1, -1, -1], family: 0 }],
        areas: None,
        pixel_map: None,
    });
    let n = 64u32;
    let p = params(32 * n as u64, 32 * n as u64, 32, [1, 1], vec![layer]);
    let t = load(&build(&p, &gradient_reference(32)));
    let img = render_image(&t, &Region::new(0, 0, 0, 32 * n, 32 * n)).unwrap();
    let filled =
        |x: i64, y: i64| t.pick(0, x.rem_euclid(n as i64) as u64, y.rem_euclid(n as i64) as u64, 0).base.is_some();
    let step = 255.0 / 31.0 / 0.9; // red per pixel inside a pattern drawn at scale 0.9
    let mut crossings = 0;
    for y in 0..img.height {
        let gy = (y / 32) as i64;
        for k in 1..n as i64 {
            // Patterns touching pixels x = 32k − 1 and 32k come from cells k−2..=k, rows gy−1..=gy.
            let owners = (k - 2..=k)
                .flat_map(|cx| (gy - 1..=gy).map(move |cy| (cx, cy)))
                .filter(|&(cx, cy)| filled(cx, cy))
                .count();
            if owners != 1 {
                continue;
            }
            let x = (k * 32) as u32;
            let (l, r) = (img.pixel(x - 1, y), img.pixel(x, y));
            if l[3] == 255 && (l[0] as f32) < 255.0 - 2.0 * step {
                // Inside the pattern, not at its right edge: it must go on in the next cell.
                assert_eq!(r[3], 255, "pattern clipped at the cell border x = {x}, y = {y}");
                let d = r[0] as f32 - l[0] as f32;
                assert!(d > 0.0 && d < step + 2.0, "gradient jumps by {d} across x = {x}, y = {y}");
                crossings += 1;
            }
        }
    }
    assert!(crossings > 300, "only {crossings} border pixels checked");
    // Without overflow every pattern stays inside its cell: coverage never crosses a border
    // with a continuing gradient.
    let p = params(32 * 20, 32 * 20, 32, [1, 1], vec![sparse(32, [0.9, 0.9], false, false)]);
    let t = load(&build(&p, &gradient_reference(32)));
    let img = render_image(&t, &Region::new(0, 0, 0, 32 * 20, 32 * 20)).unwrap();
    for y in 0..img.height {
        for k in 1..20 {
            let x = k * 32;
            assert!(
                img.pixel(x - 1, y)[3] == 0 || img.pixel(x, y)[3] == 0 || img.pixel(x, y)[0] < img.pixel(x - 1, y)[0]
            );
        }
    }
}

#[test]
fn rotated_sparse_patterns_reach_two_cells_away_when_needed() {
    // Rotated patterns of scale up to 0.95 have a bounding box of 1.34 cells and may start
    // anywhere in their cell: a pixel can be reached from two cells to its left or above. The
    // render must show exactly the union of every placed pattern, which a brute force over
    // all cells within four of the pixel gives with the model's own placement. One cell in
    // four holds a pattern, so many pixels are reached by a single, distant one.
    let n = 32u64;
    let mut layer = sparse(16, [0.9, 0.95], true, true);
    layer.choice = Some(Choice::Materials {
        materials: vec![MaterialParams { patterns: vec![0, -1, -1, -1], family: 0 }],
        areas: None,
        pixel_map: None,
    });
    let p = params(16 * n, 16 * n, 32, [1, 1], vec![layer.clone()]);
    let b = build(&p, &gradient_reference(32));
    let t = load(&b);
    let tables: Arc<[Sigma]> = sigma::from_bytes(b.section("sigma").unwrap()).unwrap().into();
    let rng = LayerRng::new(tables, 0, (n, n));
    let transform = TransformBlock::load(layer.transform.as_ref().unwrap()).unwrap();
    let cells: Vec<_> = (0..n * n)
        .map(|i| {
            let (gx, gy) = (i % n, i / n);
            t.pick(0, gx, gy, 0).base.map(|p| transform.place(&rng, gx, gy, p, 32))
        })
        .collect();
    let place =
        |ux: i64, uy: i64| cells[(uy.rem_euclid(n as i64) as u64 * n + ux.rem_euclid(n as i64) as u64) as usize];
    // Across the torus edge, from negative coordinates.
    let (x0, y0, side) = (-50i64, -37i64, 16 * n as u32);
    let img = render_image(&t, &Region::new(0, x0, y0, side, side)).unwrap();
    let (mut mismatches, mut reached_from) = (0, [0u32; 5]);
    for j in 0..side {
        let y = (y0 + j as i64) as f64 + 0.5;
        let uy = (y / 16.0).floor() as i64;
        let ry = ((y - uy as f64 * 16.0) / 16.0) as f32;
        for i in 0..side {
            let x = (x0 + i as i64) as f64 + 0.5;
            let ux = (x / 16.0).floor() as i64;
            let rx = ((x - ux as f64 * 16.0) / 16.0) as f32;
            let mut nearest = None;
            for dy in -4..=4i64 {
                for dx in -4..=4i64 {
                    if place(ux + dx, uy + dy)
                        .is_some_and(|pl| pl.local(rx - dx as f32, ry - dy as f32, 32.0).is_some())
                    {
                        let d = dx.abs().max(dy.abs()) as usize;
                        nearest = Some(nearest.map_or(d, |m: usize| m.min(d)));
                    }
                }
            }
            if let Some(d) = nearest {
                reached_from[d] += 1;
            }
            if nearest.is_some() != (img.pixel(i, j)[3] > 0) {
                mismatches += 1;
            }
        }
    }
    println!("pixels by the nearest cell covering them (0..=4 cells away): {reached_from:?}");
    assert_eq!(mismatches, 0, "pixels whose coverage differs from the union of placed patterns");
    assert!(reached_from[2] >= 10, "too few pixels only reached from two cells away: {reached_from:?}");
    assert_eq!(reached_from[3] + reached_from[4], 0, "a pattern reached three cells away");
}

// ---------------------------------------------------------------- animation

#[test]
fn animation_formula_holds() {
    // Fig. 12: φ = 3, Z = 2, n = 4 (a = 1): p = max(0, (t + 3) mod 6 − 2).
    let seq: Vec<i64> = (0..12).map(|t| frame(t, 3, 4, 2)).collect();
    // t = 0: (0 + 3) mod 6 − 2 = 1; the rest lasts Z + 1 frames (frame 0 is the rest state).
    assert_eq!(seq, vec![1, 2, 3, 0, 0, 0, 1, 2, 3, 0, 0, 0]);
    // Through the model: explicit φ and Z maps, a = 2.
    let (w, h) = (8u32, 4u32);
    let phi: Vec<u16> = (0..w * h).map(|i| (i * 5 % 13) as u16).collect();
    let z: Vec<u16> = (0..w * h).map(|i| (i % 4) as u16).collect();
    let anim = AnimationParams {
        sequence: vec![3, 1, 2, 0, 5],
        a: 2.0,
        phi: ValueParams { map: Some(inline(w, h, phi.clone())), random: 0 },
        z: ValueParams { map: Some(inline(w, h, z.clone())), random: 0 },
        ..Default::default()
    };
    let layer = LayerParams {
        kind: LayerKind::Tiling,
        cell: 4,
        choice: None,
        transform: None,
        transitions: None,
        animation: Some(anim),
    };
    let mut p = params(w as u64 * 4, h as u64 * 4, 4, [2, 4], vec![layer]);
    p.fps = Some(10.0);
    let t = load(&build(&p, &flat_reference(2, 4, 4)));
    let seq = [3, 1, 2, 0, 5];
    for frame_t in 0..40u32 {
        for i in 0..(w * h) as u64 {
            let (gx, gy) = (i % w as u64, i / w as u64);
            let (f, r) = (phi[i as usize] as i64, 2 * z[i as usize] as i64);
            let expected = ((frame_t as i64 + f).rem_euclid(5 + r) - r).max(0);
            assert_eq!(t.pick(0, gx, gy, frame_t).base, Some(seq[expected as usize]), "cell {i} at t = {frame_t}");
        }
    }
    let a = t.animation().unwrap();
    // Cycle lengths 5 + 2Z for Z in 0..4: 5, 7, 9, 11 → lcm 3465.
    assert_eq!(a.period_frames, 3465);
    // The texture at frame t + period equals frame t.
    let r = Region::new(0, 0, 0, 32, 16);
    assert_eq!(render_image(&t, &r.at_frame(17)).unwrap(), render_image(&t, &r.at_frame(17 + 3465)).unwrap());
}

#[test]
fn temporal_transitions_never_jump_to_a_mid_cycle_frame() {
    let n = 6i64;
    for phi in 0..14 {
        for old in [0i64, 1, 3, 7, 12] {
            for new in [0i64, 2, 5, 9] {
                for t0 in 0..20 {
                    let mut prev = transition_frame(t0 - 2 * n - 1, phi, n, old, new, t0);
                    for t in t0 - 2 * n..t0 + 4 * n {
                        let p = transition_frame(t, phi, n, old, new, t0);
                        // A frame either continues its cycle, starts one (1 after rest or after
                        // the end of the previous cycle), or rests after a completed cycle.
                        assert!(
                            p == 0 && (prev == 0 || prev == n - 1) || p == prev + 1 || p == 1 && prev == n - 1,
                            "φ={phi} old={old} new={new} t0={t0}: {prev} → {p} at t={t}"
                        );
                        if t < t0 {
                            assert_eq!(p, frame(t, phi, n, old), "before t0 the old cycling runs");
                        }
                        if t >= t0 + 2 * n {
                            assert_eq!(p, frame(t, phi, n, new), "after t0 + 2n the new cycling runs");
                        }
                        prev = p;
                    }
                }
            }
        }
    }
}

fn animated(kind: LayerKind, cell: u32, anim: AnimationParams) -> LayerParams {
    LayerParams { kind, cell, choice: None, transform: None, transitions: None, animation: Some(anim) }
}

#[test]
fn a_cell_plays_one_of_several_animated_patterns() {
    // Fig. 20: the virtual random map picks the animated pattern of each cell; a probability
    // map of 3 entries (sequence 0 twice, 1 once) makes sequence 0 exactly twice as likely
    // in every aligned run of 3 cells.
    let anim = AnimationParams {
        sequences: vec![vec![0, 1, 2], vec![3, 4, 5, 6]],
        probabilities: vec![0, 1, 0],
        ..Default::default()
    };
    let mut p = params(4 * 48, 4 * 48, 4, [4, 2], vec![animated(LayerKind::Tiling, 4, anim)]);
    p.fps = Some(10.0);
    let t = load(&build(&p, &flat_reference(4, 2, 4)));
    assert_eq!(t.animation().unwrap().period_frames, 12, "lcm of the lengths 3 and 4");
    let mut first = 0;
    for gy in 0..48 {
        for gx in 0..48 {
            let shown: Vec<u32> = (0..12).map(|f| t.pick(0, gx, gy, f).base.unwrap()).collect();
            let expected: Vec<u32> =
                if shown[0] == 0 { (0..12).map(|f| f % 3).collect() } else { (0..12).map(|f| 3 + f % 4).collect() };
            assert_eq!(shown, expected, "cell ({gx}, {gy}) plays one sequence");
            first += (shown[0] == 0) as u32;
        }
    }
    assert_eq!(first, 48 * 48 * 2 / 3);
    // Sequences of a tiling layer cannot rest on a blank; an unknown sequence is named.
    for (anim, needle) in [
        (AnimationParams { sequences: vec![vec![-1, 1]], ..Default::default() }, "cannot be blank"),
        (
            AnimationParams { sequences: vec![vec![1]], probabilities: vec![0, 1], ..Default::default() },
            "sequence 1 is missing",
        ),
        (AnimationParams { sequence: vec![1], sequences: vec![vec![1]], ..Default::default() }, "exactly one of"),
    ] {
        let mut p = params(64, 64, 4, [4, 2], vec![animated(LayerKind::Tiling, 4, anim)]);
        p.fps = Some(10.0);
        let e = err(&build(&p, &flat_reference(4, 2, 4)));
        assert!(e.contains(needle), "{e}");
    }
}

#[test]
fn animated_sparse_layers_blink_in_and_out() {
    // Rest on a blank, then the pattern twice: a third of the cells are empty at any frame.
    let anim =
        AnimationParams { sequence: vec![-1, 0, 0], phi: ValueParams { map: None, random: 256 }, ..Default::default() };
    let mut l = animated(LayerKind::Sparse, 8, anim);
    l.transform = Some(TransformParams { scale: [1.0, 1.0], rotate: false, overflow: false });
    let mut p = params(512, 512, 8, [1, 1], vec![l]);
    p.background = [0, 0, 0, 255];
    p.fps = Some(10.0);
    let mut white = Rgba8Image::new(8, 8);
    for y in 0..8 {
        for x in 0..8 {
            white.set_pixel(x, y, [255, 255, 255, 255]);
        }
    }
    let t = load(&build(&p, &white));
    assert_eq!(t.animation().unwrap().period_frames, 3);
    let level0 = |f: u32| render_image(&t, &Region::new(0, 0, 0, 512, 512).at_frame(f)).unwrap();
    let (f0, f1) = (level0(0), level0(1));
    assert_ne!(f0, f1);
    assert_eq!(level0(3), f0);
    let empty =
        (0..64).flat_map(|y| (0..64).map(move |x| (x, y))).filter(|&(x, y)| f0.pixel(x * 8 + 4, y * 8 + 4)[0] == 0);
    let share = empty.count() as f64 / 4096.0;
    assert!((share - 1.0 / 3.0).abs() < 0.03, "{share} of the cells are empty");
    // Coarse levels read the cells under each pixel at the same frame: the mean matches level 0.
    let mean = |img: &Rgba8Image| img.data.chunks(4).map(|p| p[0] as f64).sum::<f64>() / (img.data.len() / 4) as f64;
    let coarse = render_image(&t, &Region::new(4, 0, 0, 32, 32)).unwrap();
    assert!((mean(&coarse) - mean(&f0)).abs() < 2.0, "{} against {}", mean(&coarse), mean(&f0));
}

#[test]
fn a_density_ramp_is_a_series_of_temporal_transitions() {
    // The (a, Z) change at t0 = 20, 40 and 60; n = 4, so they are 2n apart as §3.4 asks.
    let (w, h, n) = (8u32, 8u32, 4i64);
    let phi: Vec<u16> = (0..w * h).map(|i| (i * 7 % 11) as u16).collect();
    let z: Vec<u16> = (0..w * h).map(|i| 1 + (i % 3) as u16).collect();
    let zmap = || ValueParams { map: Some(inline(w, h, z.clone())), random: 0 };
    let ramp = [4.0, 2.0, 1.0, 0.0];
    let t0s = [20u32, 40, 60];
    let anim = AnimationParams {
        sequence: vec![0, 1, 2, 3],
        a: ramp[3],
        phi: ValueParams { map: Some(inline(w, h, phi.clone())), random: 0 },
        z: zmap(),
        previous: Some(Previous::Many((0..3).map(|k| PreviousParams { a: ramp[k], z: zmap(), t0: t0s[k] }).collect())),
        ..Default::default()
    };
    let mut p = params(w as u64 * 4, h as u64 * 4, 4, [2, 2], vec![animated(LayerKind::Tiling, 4, anim.clone())]);
    p.fps = Some(10.0);
    let t = load(&build(&p, &flat_reference(2, 2, 4)));
    assert_eq!(t.animation().unwrap().period_frames, 0, "transitions make it aperiodic");
    for i in 0..(w * h) as u64 {
        let (gx, gy) = (i % w as u64, i / w as u64);
        let (f, zi) = (phi[i as usize] as i64, z[i as usize] as i64);
        let mut prev = t.pick(0, gx, gy, 0).base.unwrap() as i64;
        for time in 1..100u32 {
            let q = t.pick(0, gx, gy, time).base.unwrap() as i64;
            assert!(
                q == 0 && (prev == 0 || prev == n - 1) || q == prev + 1 || q == 1 && prev == n - 1,
                "cell {i}: {prev} → {q} at t = {time}"
            );
            // Between transitions, once 2n frames have passed, the segment's own cycling runs.
            let k = t0s.iter().filter(|&&t0| t0 <= time).count();
            let settled = k == 0 || time >= t0s[k - 1] + 2 * n as u32;
            if settled {
                let r = (ramp[k] * zi as f64).floor() as i64;
                assert_eq!(q, frame(time as i64, f, n, r), "cell {i} at t = {time}, segment {k}");
            }
            prev = q;
        }
    }
    // Transitions closer than 2n frames are refused.
    let mut close = anim;
    close.previous = Some(Previous::Many(vec![
        PreviousParams { a: 1.0, z: zmap(), t0: 20 },
        PreviousParams { a: 2.0, z: zmap(), t0: 25 },
    ]));
    let mut p = params(w as u64 * 4, h as u64 * 4, 4, [2, 2], vec![animated(LayerKind::Tiling, 4, close)]);
    p.fps = Some(10.0);
    let e = err(&build(&p, &flat_reference(2, 2, 4)));
    assert!(e.contains("previous[1].t0") && e.contains("2n"), "{e}");
}

#[test]
fn sequences_can_follow_the_distance_to_moving_targets() {
    // Fig. 21a: a ball (a sprite no layer draws) moves 16 px a frame; cells open as it nears.
    let anim = AnimationParams {
        sequence: vec![0, 1, 2, 3],
        distance: Some(DistanceParams { targets: vec!["ball".into()], radius: 48.0 }),
        ..Default::default()
    };
    let mut p = params(256, 256, 16, [4, 2], vec![animated(LayerKind::Tiling, 16, anim)]);
    let mut ball = SpriteParams::at(4, 100, 100);
    ball.velocity = [16, 0];
    p.sprites.insert("ball".into(), ball);
    p.fps = Some(10.0);
    let t = load(&build(&p, &flat_reference(4, 2, 16)));
    assert_eq!(t.animation().unwrap().period_frames, 16, "the ball's period");
    for time in 0..5u32 {
        let (bx, by) = ((108 + 16 * time) % 256, 108);
        let mut open = 0;
        for gy in 0..16u64 {
            for gx in 0..16u64 {
                let (cx, cy) = ((gx * 16 + 8) as f64, (gy * 16 + 8) as f64);
                let dx = (cx - bx as f64).abs().min(256.0 - (cx - bx as f64).abs());
                let d = (dx * dx + (cy - by as f64).powi(2)).sqrt();
                let want = if d >= 48.0 { 0 } else { ((4.0 * (1.0 - d / 48.0)).floor() as u32).min(3) };
                assert_eq!(t.pick(0, gx, gy, time).base, Some(want), "cell ({gx}, {gy}) at t = {time}");
                open += (want == 3) as u32;
            }
        }
        assert!(open >= 1, "the cell under the ball is open");
    }
    let mut p2 = p.clone();
    p2.layers[0].animation.as_mut().unwrap().distance.as_mut().unwrap().targets = vec!["nobody".into()];
    let e = err(&build(&p2, &flat_reference(4, 2, 16)));
    assert!(e.contains("`nobody` is not in `sprites`"), "{e}");
}

#[test]
fn a_period_over_too_many_rest_values_is_not_searched() {
    // Z from a 512 × 256 map of 65536 distinct values plus a random 0..4096: 2.7 · 10^8
    // possible rests. The period is not searched over them (that list alone would hold a
    // gigabyte): the animation counts as aperiodic, period 0.
    let (w, h) = (512u32, 256u32);
    let z = ValueParams {
        map: Some(MapRef {
            size: [w, h],
            values: Some((0..w * h).map(|i| i as u16).collect()),
            section: None,
            depth: 1,
        }),
        random: 4096,
    };
    let anim = AnimationParams { sequence: vec![0, 1], a: 1.0, z, ..Default::default() };
    let mut p = params(w as u64 * 4, h as u64 * 4, 4, [2, 2], vec![animated(LayerKind::Tiling, 4, anim)]);
    p.fps = Some(10.0);
    assert_eq!(load(&build(&p, &flat_reference(2, 2, 4))).animation().unwrap().period_frames, 0);
}

#[test]
fn led_board_is_animated_and_frames_differ() {
    let t = models::load(&demos::led_board(false)).unwrap();
    assert_eq!((t.width(), t.height()), (12288, 1536));
    let a = t.animation().expect("the LED board moves");
    assert!(a.fps > 0.0);
    // Level 2: 8 px per LED, the first 64 columns of LEDs (the first letters) and all rows.
    let r = Region::new(2, 0, 0, 512, 384);
    let f0 = render_image(&*t, &r.at_frame(0)).unwrap();
    let f1 = render_image(&*t, &r.at_frame(1)).unwrap();
    assert_ne!(f0, f1, "LEDs blink");
    assert_eq!(f1, render_image(&*t, &r.at_frame(1)).unwrap());
}

// ---------------------------------------------------------------- sprites and pixel map

#[test]
fn sprites_move_by_a_merge_patch_of_their_params() {
    let b = demos::sprites();
    let t = load(&b);
    let mut moved = b.clone();
    let sprites = moved.manifest.params.get_mut("sprites").unwrap().as_object_mut().unwrap();
    sprites.insert("maple".into(), serde_json::json!({"pattern": 16, "x": 1000, "y": 1900}));
    let t2 = load(&moved);
    assert_ne!(vtex_synth::bundle::id_of(&b.to_bytes()), vtex_synth::bundle::id_of(&moved.to_bytes()));
    let mut gone = b.clone();
    gone.manifest.params.get_mut("sprites").unwrap().as_object_mut().unwrap().remove("maple");
    let ground = load(&gone);
    let at = |tex: &PatternTexture, x, y| render_image(tex, &Region::new(0, x, y, 64, 64)).unwrap();
    assert_ne!(at(&t, 700, 400), at(&ground, 700, 400), "the sprite is drawn at its place");
    assert_eq!(at(&t2, 700, 400), at(&ground, 700, 400), "after the move the old place shows the ground");
    // The moved sprite is the same picture over a different ground: compare where the leaf is opaque.
    let (a, b2) = (at(&t, 700, 400), at(&t2, 1000, 1900));
    let leaf = art::leaf(2003, 0, 64);
    let mut same = 0;
    for y in 0..64 {
        for x in 0..64 {
            if leaf.pixel(x, y)[3] == 255 {
                assert_eq!(a.pixel(x, y), b2.pixel(x, y));
                same += 1;
            }
        }
    }
    assert!(same > 500);
}

#[test]
fn colliding_sprites_are_an_error() {
    let mut b = demos::sprites();
    let s = b.manifest.params.get_mut("sprites").unwrap().as_object_mut().unwrap();
    s.insert("clash".into(), serde_json::json!({"pattern": 17, "x": 720, "y": 410}));
    let e = err(&b);
    assert!(e.contains("positioning cell") && e.contains("maple"), "{e}");
}

#[test]
fn following_the_collision_advice_draws_both_sprites() {
    let mut b = demos::sprites();
    let clash = serde_json::json!({"pattern": 17, "x": 720, "y": 410});
    b.manifest.params["sprites"].as_object_mut().unwrap().insert("clash".into(), clash.clone());
    let e = err(&b);
    assert!(e.contains("\"layer\"") && e.contains("sprites layer"), "the advice names the way out: {e}");
    // The advice: a second sprites layer, and the clashing sprite on it.
    let layers = b.manifest.params["layers"].as_array_mut().unwrap();
    layers.push(layers[1].clone());
    b.manifest.params["sprites"]["clash"]["layer"] = 2.into();
    let both = load(&b);
    let mut alone = b.clone();
    alone.manifest.params["sprites"].as_object_mut().unwrap().remove("clash");
    let at = |tex: &PatternTexture| render_image(tex, &Region::new(0, 700, 400, 96, 96)).unwrap();
    let (both, maple) = (at(&both), at(&load(&alone)));
    assert_ne!(both, maple, "the clashing sprite is drawn");
    // Maple (700, 400) alone where the clash (720, 410) does not reach.
    assert_eq!(both.pixel(5, 5), maple.pixel(5, 5));
}

/// Pattern 0: the gradient; pattern 1: half-transparent blue. 16-pixel patterns.
fn sprite_reference() -> Rgba8Image {
    let mut blue = Rgba8Image::new(16, 16);
    for y in 0..16 {
        for x in 0..16 {
            blue.set_pixel(x, y, [0, 0, 255, 128]);
        }
    }
    art::pack(&[gradient_reference(16), blue], 2, 1)
}

fn sprites_layer(cell: u32, transform: Option<TransformParams>) -> LayerParams {
    LayerParams { kind: LayerKind::Sprites, cell, choice: None, transform, transitions: None, animation: None }
}

/// A 256² torus of sprites layers with cell 32 over a grey background.
fn sprites_texture(layers: Vec<LayerParams>, sprites: Vec<(&str, SpriteParams)>) -> Bundle {
    let mut p = params(256, 256, 16, [2, 1], layers);
    p.background = [40, 40, 40, 255];
    p.sprites = sprites.into_iter().map(|(n, s)| (n.to_string(), s)).collect();
    if p.sprites.values().any(|s| s.velocity != [0, 0]) {
        p.fps = Some(10.0);
    }
    build(&p, &sprite_reference())
}

fn on_layer(mut s: SpriteParams, layer: usize) -> SpriteParams {
    s.layer = Some(layer);
    s
}

#[test]
fn every_sprites_layer_draws_only_its_own_sprites() {
    let level0 = |b: &Bundle| render_image(&load(b), &Region::new(0, 0, 0, 128, 128)).unwrap();
    // n grids for n patterns in a cell: two sprites in positioning cell (1, 1), one a layer.
    let (a, blue) = (SpriteParams::at(0, 40, 40), SpriteParams::at(1, 48, 48));
    let two = level0(&sprites_texture(
        vec![sprites_layer(32, None), sprites_layer(32, None)],
        vec![("a", a.clone()), ("b", on_layer(blue.clone(), 1))],
    ));
    let only = |s: SpriteParams| level0(&sprites_texture(vec![sprites_layer(32, None)], vec![("s", s)]));
    let (alone_a, alone_b) = (only(a.clone()), only(blue.clone()));
    assert_eq!(two.pixel(44, 44), alone_a.pixel(44, 44), "only the gradient");
    assert_eq!(two.pixel(60, 60), alone_b.pixel(60, 60), "only the blue");
    assert_eq!(two.pixel(70, 70), [40, 40, 40, 255], "neither");
    let mixed = two.pixel(52, 52);
    assert!(mixed != alone_a.pixel(52, 52) && mixed != alone_b.pixel(52, 52), "blue over the gradient: {mixed:?}");
    // A sprites layer without sprites of its own draws nothing: the half-transparent blue is
    // drawn once however many sprites layers there are.
    let twice =
        level0(&sprites_texture(vec![sprites_layer(32, None), sprites_layer(32, None)], vec![("b", blue.clone())]));
    assert_eq!(twice, alone_b);
    // A layer index that is not a sprites layer is named.
    let mut p = params(256, 256, 16, [2, 1], vec![tiling(16, Choice::Virtual), sprites_layer(32, None)]);
    p.sprites.insert("b".into(), on_layer(blue, 0));
    let e = err(&build(&p, &sprite_reference()));
    assert!(e.contains("sprites.b.layer") && e.contains("Tiling"), "{e}");
}

#[test]
fn the_tile_transform_is_plugged_after_the_positioning() {
    let level0 = |b: &Bundle| render_image(&load(b), &Region::new(0, 0, 0, 160, 160)).unwrap();
    let grad = |u: f32, v: f32| [(u.floor() * 17.0) as i32, (v.floor() * 17.0) as i32];
    let close = |got: [u8; 4], want: [i32; 2], at: (u32, u32)| {
        assert!(
            (got[0] as i32 - want[0]).abs() <= 17 && (got[1] as i32 - want[1]).abs() <= 17,
            "pixel {at:?}: {got:?} against texel colour {want:?}"
        );
    };
    // Explicit: a quarter turn clockwise about the centre (72, 72).
    let mut turned = SpriteParams::at(0, 64, 64);
    turned.rotation = 90.0;
    let img = level0(&sprites_texture(vec![sprites_layer(32, None)], vec![("t", turned)]));
    for y in 65..79 {
        for x in 65..79 {
            let (dx, dy) = (x as f32 + 0.5 - 72.0, y as f32 + 0.5 - 72.0);
            close(img.pixel(x, y), grad(dy + 8.0, -dx + 8.0), (x, y));
        }
    }
    // Explicit: twice the size, so 32 px about the same centre, over more than four cells.
    let mut big = SpriteParams::at(0, 64, 64);
    big.scale = 2.0;
    let img = level0(&sprites_texture(vec![sprites_layer(32, None)], vec![("t", big)]));
    let bg = [40, 40, 40, 255];
    assert_ne!(img.pixel(57, 57), bg);
    assert_ne!(img.pixel(86, 86), bg);
    assert_eq!(img.pixel(55, 55), bg);
    assert_eq!(img.pixel(89, 89), bg);
    close(img.pixel(81, 61), grad((81.5 - 72.0) / 2.0 + 8.0, (61.5 - 72.0) / 2.0 + 8.0), (81, 61));
    // Procedural: the layer's transform halves every sprite.
    let half = Some(TransformParams { scale: [0.5, 0.5], rotate: false, overflow: false });
    let img = level0(&sprites_texture(vec![sprites_layer(32, half)], vec![("t", SpriteParams::at(0, 64, 64))]));
    assert_eq!(img.pixel(66, 66), bg);
    assert_ne!(img.pixel(69, 69), bg);
    assert_eq!(img.pixel(77, 77), bg);
    // Too large once transformed is named.
    let mut huge = SpriteParams::at(0, 64, 64);
    huge.scale = 3.0;
    let twice = Some(TransformParams { scale: [2.0, 2.0], rotate: false, overflow: false });
    let e = err(&sprites_texture(vec![sprites_layer(32, twice)], vec![("h", huge)]));
    assert!(e.contains("sprites.h.scale"), "{e}");
}

#[test]
fn moving_sprites_move_with_the_frame_and_never_collide() {
    let mut m = SpriteParams::at(0, 40, 40);
    m.velocity = [8, 4];
    let b = sprites_texture(vec![sprites_layer(32, None)], vec![("m", m.clone())]);
    let t = load(&b);
    let a = t.animation().expect("a moving sprite animates the texture");
    assert_eq!(a.period_frames, 64, "256/8 = 32 and 256/4 = 64 frames");
    let whole = |f: u32| render_image(&t, &Region::new(0, 0, 0, 256, 256).at_frame(f)).unwrap();
    let (f0, f5) = (whole(0), whole(5));
    assert_ne!(f0, f5);
    for y in 0..256 {
        for x in 0..256 {
            assert_eq!(f5.pixel((x + 40) % 256, (y + 20) % 256), f0.pixel(x, y));
        }
    }
    assert_eq!(whole(64), f0);
    // Two sprites on one layer that meet at some frame are refused, naming the frame...
    let mut n = SpriteParams::at(0, 200, 40);
    n.velocity = [-8, 4];
    let e = err(&sprites_texture(vec![sprites_layer(32, None)], vec![("m", m.clone()), ("n", n.clone())]));
    assert!(e.contains("at frame"), "{e}");
    // ...and drawn when each has its own grid.
    load(&sprites_texture(
        vec![sprites_layer(32, None), sprites_layer(32, None)],
        vec![("m", m), ("n", on_layer(n, 1))],
    ));
}

#[test]
fn pixel_map_is_sharp_and_compressed() {
    let (w, h, block) = (256u32, 128u32, 16u32);
    let mask: Vec<u8> =
        (0..w * h).map(|i| (((i % w) as i64 - 100).pow(2) + ((i / w) as i64 - 60).pow(2) < 40 * 40) as u8).collect();
    let data = pixel_map::encode(w, h, block, &mask);
    assert!(data.len() < mask.len() / 3, "{} bytes for a {}-byte mask", data.len(), mask.len());
    let mats =
        vec![MaterialParams { patterns: vec![0, 1], family: 0 }, MaterialParams { patterns: vec![2, 3], family: 1 }];
    let pm = PixelMapParams { section: "mask".into(), size: [w, h], scale: 2, block };
    let p = params(
        512,
        256,
        8,
        [2, 2],
        vec![tiling(8, Choice::Materials { materials: mats, areas: None, pixel_map: Some(pm) })],
    );
    let b = demos::bundle("pm", &p, &flat_reference(2, 2, 8), vec![("mask", data)]);
    let t = load(&b);
    let img = render_image(&t, &Region::new(0, 0, 0, 512, 256)).unwrap();
    let reference = flat_reference(2, 2, 8);
    for y in 0..256u32 {
        for x in 0..512u32 {
            let m = mask[((y / 2) * w + x / 2) as usize];
            assert_eq!(t.pixel_material(0, x as u64, y as u64), Some(m as u16));
            // The pixel comes from a pattern of its own material, at pixel precision.
            let px = img.pixel(x, y);
            let candidates: Vec<[u8; 4]> = [0u32, 1]
                .iter()
                .map(|k| m as u32 * 2 + k)
                .map(|p| reference.pixel((p % 2) * 8 + x % 8, (p / 2) * 8 + y % 8))
                .collect();
            assert!(candidates.contains(&px), "pixel ({x}, {y}) of material {m}");
        }
    }
}

// ---------------------------------------------------------------- invariants every model keeps

#[test]
fn demos_are_reproducible_and_compact() {
    let a: Vec<Vec<u8>> = demos::demos().iter().map(|b| b.to_bytes()).collect();
    let b: Vec<Vec<u8>> = demos::demos().iter().map(|b| b.to_bytes()).collect();
    assert_eq!(a, b, "demo encodings are pure functions of the code");
    for (bytes, d) in a.iter().zip(demos::demos()) {
        let t = models::load(&d).unwrap();
        let explicit = t.width() * t.height() * 3;
        let sections: Vec<String> = d.sections.iter().map(|s| format!("{} {}", s.name, s.data.len())).collect();
        println!(
            "| {} | {}×{} | {} ({}) | {} | {:.0}× |",
            d.manifest.name,
            t.width(),
            t.height(),
            bytes.len(),
            sections.join(", "),
            explicit,
            explicit as f64 / bytes.len() as f64
        );
        assert!((bytes.len() as u64) * 100 < explicit, "{}: {} bytes for {explicit}", d.manifest.name, bytes.len());
    }
}

#[test]
fn create_from_inputs_matches_the_registry() {
    let p = params(256, 256, 16, [2, 2], vec![tiling(16, Choice::Virtual)]);
    let mut inputs = models::Inputs::new();
    inputs.insert("reference".into(), flat_reference(2, 2, 16).to_png());
    let b = models::create("patterns", "made", &serde_json::to_value(&p).unwrap(), &inputs).unwrap();
    let t = models::load(&b).unwrap();
    assert_eq!(t.model(), "patterns");
    assert!(models::MODELS.contains(&"patterns"));
    inputs.clear();
    assert!(models::create("patterns", "made", &serde_json::to_value(&p).unwrap(), &inputs)
        .unwrap_err()
        .to_string()
        .contains("reference"));
}

// ---------------------------------------------------------------- mip coherence

/// PSNR of each level of `t` against the exact 2×2 box chain of its level 0.
fn psnr_per_level(t: &dyn Texture) -> Vec<(u32, f64)> {
    let (w, h) = (t.width() as u32, t.height() as u32);
    let mut exact = render_image(t, &Region::new(0, 0, 0, w, h)).unwrap();
    let mut out = Vec::new();
    for level in 1..level_count(w as u64, h as u64) {
        exact = mip::downsample(&exact);
        let got = render_image(t, &Region::new(level, 0, 0, exact.width, exact.height)).unwrap();
        out.push((level, mip::psnr(&got, &exact)));
    }
    out
}

#[test]
fn tiling_levels_are_the_exact_downsample_up_to_four_cells_per_pixel() {
    // 40 × 24 cells of 16 px (sizes that are not powers of two, so odd levels appear).
    let p = params(40 * 16, 24 * 16, 16, [4, 4], vec![tiling(16, Choice::Virtual)]);
    let t = load(&build(&p, &flat_reference(4, 4, 16)));
    let levels = psnr_per_level(&t);
    for &(level, db) in &levels {
        if level <= 4 + 2 {
            assert!(db.is_infinite(), "level {level}: {db:.1} dB; per-pattern mips and 4×4 oversampling are exact");
        } else {
            assert!(db > 30.0, "level {level}: {db:.1} dB with filtered indirection");
        }
    }
    // The coarsest level's colour is the texture's true mean.
    let full = render_image(&t, &Region::new(0, 0, 0, 640, 384)).unwrap();
    let last = level_count(640, 384) - 1;
    let top = render_image(&t, &Region::new(last, 0, 0, 1, 1)).unwrap();
    let (m, g) = (mip::mean_rgba(&full), top.pixel(0, 0));
    for c in 0..3 {
        assert!((m[c] - g[c] as f64).abs() < 3.0, "channel {c}: mean {:.1}, top level {}", m[c], g[c]);
    }
}

#[test]
fn per_pattern_mips_do_not_bleed() {
    // Two packed patterns, black and white: the 1×1 level of each is its own colour.
    let mut img = Rgba8Image::new(32, 16);
    for y in 0..16 {
        for x in 16..32 {
            img.set_pixel(x, y, [255, 255, 255, 255]);
        }
        for x in 0..16 {
            img.set_pixel(x, y, [0, 0, 0, 255]);
        }
    }
    let r = pat::reference::Reference::new(&img, 16, 2, 1).unwrap();
    for l in 0..=4 {
        let side = 16 >> l;
        for y in 0..side {
            for x in 0..side {
                assert_eq!(r.texel(0, l, x, y), [0, 0, 0, 255]);
                assert_eq!(r.texel(1, l, x, y), [255, 255, 255, 255]);
            }
        }
    }
}

// ---------------------------------------------------------------- bad input

#[test]
fn bad_encodings_are_clear_errors() {
    let r = flat_reference(4, 4, 8);
    let ok = params(64, 64, 8, [4, 4], vec![tiling(8, Choice::Virtual)]);
    pat::load(&build(&ok, &r)).unwrap();
    let cases: Vec<(Params, &str)> = vec![
        (params(64, 64, 12, [4, 4], vec![tiling(12, Choice::Virtual)]), "power of two"),
        (params(60, 64, 8, [4, 4], vec![tiling(8, Choice::Virtual)]), "do not divide"),
        (
            params(64, 64, 8, [4, 4], vec![tiling(8, Choice::Explicit { map: inline(3, 3, vec![0; 9]) })]),
            "does not divide",
        ),
        (
            params(64, 64, 8, [4, 4], vec![tiling(8, Choice::Explicit { map: inline(2, 2, vec![0, 1, 2, 99]) })]),
            "out of range",
        ),
        (params(64, 64, 8, [4, 4], vec![tiling(8, Choice::Explicit { map: inline(2, 2, vec![0, 1, 2]) })]), "3 values"),
        (
            params(
                64,
                64,
                8,
                [4, 4],
                vec![tiling(
                    8,
                    Choice::Materials {
                        materials: vec![MaterialParams { patterns: vec![0, 40], family: 0 }],
                        areas: None,
                        pixel_map: None,
                    },
                )],
            ),
            "pattern 40 is missing",
        ),
        (
            params(
                64,
                64,
                8,
                [4, 4],
                vec![tiling(
                    8,
                    Choice::Materials {
                        materials: vec![MaterialParams { patterns: vec![0, -1], family: 0 }],
                        areas: None,
                        pixel_map: None,
                    },
                )],
            ),
            "cannot be blank",
        ),
        (
            params(
                64,
                64,
                8,
                [4, 4],
                vec![tiling(
                    8,
                    Choice::Materials {
                        materials: vec![MaterialParams { patterns: vec![0], family: 0 }],
                        areas: Some(AreasParams { map: inline(2, 2, vec![0, 0, 1, 0]), dithered: true }),
                        pixel_map: None,
                    },
                )],
            ),
            "below 1",
        ),
        (params(64, 64, 8, [4, 4], vec![]), "layers"),
        (params(64, 64, 8, [4, 4], vec![sparse(8, [0.5, 2.0], true, false)]), "does not fit"),
    ];
    for (p, needle) in cases {
        let e = err(&build(&p, &r));
        assert!(e.contains(needle), "expected `{needle}` in: {e}");
    }
    // Reference image of the wrong size, transitions with the wrong count, animation
    // without fps, corrupted σ, missing sections.
    let e = err(&build(&ok, &flat_reference(4, 3, 8)));
    assert!(e.contains("reference"), "{e}");
    let mut tr = demos::two_materials();
    let l = &mut tr.manifest.params["layers"][0]["transitions"]["tiles"][0];
    l.as_array_mut().unwrap().pop();
    assert!(err(&tr).contains("corner mask"));
    let mut led = demos::led_board(false);
    led.manifest.params.as_object_mut().unwrap().remove("fps");
    assert!(err(&led).contains("fps"));
    let mut bad_sigma = build(&ok, &r);
    let s = bad_sigma.sections.iter_mut().find(|s| s.name == "sigma").unwrap();
    // Entries start at byte 5: make the second entry of the first table repeat the first.
    s.data[7] = s.data[5];
    s.data[8] = s.data[6];
    assert!(err(&bad_sigma).contains("sigma"));
    let mut missing = build(&ok, &r);
    missing.sections.retain(|s| s.name != "reference.png");
    assert!(err(&missing).contains("reference.png"));
    let mut truncated = build(&ok, &r);
    truncated.sections.iter_mut().find(|s| s.name == "sigma").unwrap().data.truncate(100);
    assert!(err(&truncated).contains("truncated"));
    // A virtual choice over a 16 × 1 reference cannot hash the y axis (§3.5).
    let flat = params(64, 64, 8, [16, 1], vec![tiling(8, Choice::Virtual)]);
    assert!(err(&build(&flat, &flat_reference(16, 1, 8))).contains("2D"));
    // Garbage params never panic.
    let mut garbage = build(&ok, &r);
    garbage.manifest.params = serde_json::json!({"width": "wide"});
    assert!(err(&garbage).contains("params"));
}

#[test]
fn explicit_indirection_map_places_its_patterns_and_repeats() {
    // A 2 × 3 map over a 6 × 6 grid repeats (maps wrap, §3.1).
    let values = vec![5, 0, 9, 3, 15, 7];
    let p = params(6 * 8, 6 * 8, 8, [4, 4], vec![tiling(8, Choice::Explicit { map: inline(2, 3, values.clone()) })]);
    let r = flat_reference(4, 4, 8);
    let t = load(&build(&p, &r));
    let img = render_image(&t, &Region::new(0, 0, 0, 48, 48)).unwrap();
    for gy in 0..6u32 {
        for gx in 0..6u32 {
            let want = values[((gy % 3) * 2 + gx % 2) as usize] as u32;
            assert_eq!(t.pick(0, gx as u64, gy as u64, 0).base, Some(want));
            let src = r.crop((want % 4) * 8, (want / 4) * 8, 8, 8);
            assert_eq!(img.crop(gx * 8, gy * 8, 8, 8), src, "cell ({gx}, {gy}) shows pattern {want} exactly");
        }
    }
}

/// Every number and string in a demo's params replaced by hostile values: loading gives a
/// result (usually an error naming the field) and rendering what loads never panics.
#[test]
fn hostile_params_never_panic() {
    fn leaves(v: &serde_json::Value, path: &mut Vec<String>, out: &mut Vec<Vec<String>>) {
        match v {
            serde_json::Value::Object(m) => m.iter().for_each(|(k, x)| {
                path.push(k.clone());
                leaves(x, path, out);
                path.pop();
            }),
            serde_json::Value::Array(a) => a.iter().enumerate().take(3).for_each(|(i, x)| {
                path.push(i.to_string());
                leaves(x, path, out);
                path.pop();
            }),
            _ => out.push(path.clone()),
        }
    }
    fn at<'a>(v: &'a mut serde_json::Value, path: &[String]) -> &'a mut serde_json::Value {
        path.iter().fold(v, |v, k| match v {
            serde_json::Value::Array(a) => &mut a[k.parse::<usize>().unwrap()],
            other => &mut other[k.as_str()],
        })
    }
    let hostile = [
        serde_json::json!(0),
        serde_json::json!(-1),
        serde_json::json!(1u64 << 40),
        serde_json::json!(3),
        serde_json::json!("x"),
    ];
    let mut loaded = 0;
    for b in [demos::two_materials(), demos::leaves(), demos::sprites(), demos::led_board(true)] {
        let mut paths = Vec::new();
        leaves(&b.manifest.params, &mut Vec::new(), &mut paths);
        for path in &paths {
            for h in &hostile {
                let mut m = b.clone();
                *at(&mut m.manifest.params, path) = h.clone();
                if let Ok(t) = pat::load(&m) {
                    loaded += 1;
                    let l = (level_count(t.width(), t.height()) - 1).min(3);
                    render_image(&t, &Region::new(l, -5, -5, 40, 40).at_frame(7)).unwrap();
                }
            }
        }
    }
    assert!(loaded > 0);
}

#[test]
fn basic_sparse_convolution_of_one_pattern() {
    // T = 1 (Fig. 18): a virtual choice over a single pattern, random place, scale, rotation.
    let mut layer = sparse(32, [0.4, 0.7], true, true);
    layer.choice = Some(Choice::Virtual);
    let p = params(32 * 32, 32 * 32, 32, [1, 1], vec![layer]);
    let t = load(&build(&p, &gradient_reference(32)));
    let img = render_image(&t, &Region::new(0, 0, 0, 1024, 1024)).unwrap();
    let covered = img.data.chunks_exact(4).filter(|p| p[3] > 0).count() as f64 / (1024.0 * 1024.0);
    // Expected coverage: E[s²] = (0.16 + 0.28 + 0.49) / 3 = 0.31 of each cell, minus overlaps.
    assert!(covered > 0.2 && covered < 0.31, "coverage {covered:.3}");
}
