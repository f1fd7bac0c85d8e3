//! The cascade model against the invariants every model keeps: seamless regions (also far from
//! the origin), agreement with a direct evaluation of the definition, determinism, mip
//! coherence with measured PSNR, and clear errors for bad encodings.

use serde_json::json;
use std::sync::Arc;
use vtex_synth::bundle::Bundle;
use vtex_synth::mip::{downsample_n, mean_rgba};
use vtex_synth::models::cascade::{self, demos::control_map, demos::initial_image, prefilter, Cascade};
use vtex_synth::models::{self, Inputs};
use vtex_synth::texture::{render_image, Region, Texture};
use vtex_synth::Rgba8Image;

fn tex(params: serde_json::Value) -> Cascade {
    cascade::load(&models::create("cascade", "t", &params, &Inputs::new()).unwrap()).unwrap()
}

fn single() -> serde_json::Value {
    json!({"seed": 3, "stages": [{"kernel": {"size": 5, "preset": "gauss"}, "map": {"kind": "logistic", "r": 3.8}}]})
}

fn cascade3() -> serde_json::Value {
    json!({"seed": 4, "palette": "earth", "stages": [
        {"kernel": {"size": 3, "weights": [1, 2, 1, 2, 4, 2, 1, 2, 1]}, "map": {"kind": "sine", "r": 0.95}},
        {"upsample": 4, "jitter": 0.1, "map": {"kind": "tent", "mu": 1.7}, "iterations": 3},
        {"upsample": 2, "jitter": 0.05, "kernel": {"size": 7, "preset": "dog"}, "map": {"kind": "circle", "omega": 0.2, "k": 2.0}, "iterations": 2}]})
}

fn render(t: &dyn Texture, level: u32, x: i64, y: i64, w: u32, h: u32) -> Rgba8Image {
    render_image(t, &Region::new(level, x, y, w, h)).unwrap()
}

fn all_textures() -> Vec<(String, Arc<dyn Texture>)> {
    let mut v: Vec<(String, Arc<dyn Texture>)> = cascade::demos()
        .into_iter()
        .map(|b| (b.manifest.name.clone(), models::load(&Bundle::from_bytes(&b.to_bytes()).unwrap()).unwrap()))
        .collect();
    v.push(("single".into(), Arc::new(tex(single()))));
    v.push(("cascade3".into(), Arc::new(tex(cascade3()))));
    v
}

#[test]
fn renders_are_not_degenerate() {
    for (name, t) in all_textures() {
        let img = render(t.as_ref(), 0, 1000, 1000, 128, 128);
        let m = mean_rgba(&img);
        let var: f64 = img
            .data
            .chunks_exact(4)
            .map(|p| (p[0] as f64 + p[1] as f64 + p[2] as f64) / 3.0)
            .map(|g| {
                let d = g - (m[0] + m[1] + m[2]) / 3.0;
                d * d
            })
            .sum::<f64>()
            / (128.0 * 128.0);
        assert!(var.sqrt() > 10.0, "{name}: flat image, σ = {}", var.sqrt());
        assert!(img.is_opaque());
        // Far from the origin the statistics are the same (no precision loss with distance).
        let far = render(t.as_ref(), 0, (1 << 50) + 1000, -(1 << 52), 128, 128);
        let mf = mean_rgba(&far);
        assert!((0..3).all(|c| (m[c] - mf[c]).abs() < 40.0), "{name}: near {m:?} far {mf:?}");
        assert_ne!(img, far);
    }
}

/// A direct evaluation of the definition, written independently of the model's window
/// machinery: whole lattices in i128 coordinates, per-point convolution, floor-division
/// upsampling. Used near and far from the origin (away from the 2^64 wrap).
fn direct(t: &Cascade, x0: i128, y0: i128, w: usize, h: usize) -> Vec<f32> {
    let e = t.exact().engine();
    fn stage(
        e: &vtex_synth::models::cascade::engine::Engine,
        s: usize,
        x0: i128,
        y0: i128,
        w: usize,
        h: usize,
    ) -> Vec<f32> {
        let st = &e.stages[s];
        let r = st.kernel().reach as i128;
        let m = st.iterations as i128 * r;
        let (ax, ay, aw, ah) = (x0 - m, y0 - m, w as i128 + 2 * m, h as i128 + 2 * m);
        let mut a = vec![0.0f32; (aw * ah) as usize];
        let f = 1i128 << st.up;
        let coarse = (s > 0).then(|| {
            let (cx, cy) = (ax.div_euclid(f), ay.div_euclid(f));
            let cw = (ax + aw - 1).div_euclid(f) - cx + 2;
            let ch = (ay + ah - 1).div_euclid(f) - cy + 2;
            (cx, cy, cw, stage(e, s - 1, cx, cy, cw as usize, ch as usize))
        });
        for j in 0..ah {
            for i in 0..aw {
                let (x, y) = (ax + i, ay + j);
                let n =
                    vtex_synth::hash::unit_f32(vtex_synth::hash::hash4(e.seed, 0x100 + s as u64, x as i64, y as i64));
                a[(j * aw + i) as usize] = match &coarse {
                    None => n,
                    Some((cx, cy, cw, c)) => {
                        let (qx, qy) = (x.div_euclid(f) - cx, y.div_euclid(f) - cy);
                        let (fx, fy) = (x.rem_euclid(f) as f32 / f as f32, y.rem_euclid(f) as f32 / f as f32);
                        let at = |u: i128, v: i128| c[(v * cw + u) as usize];
                        let r0 = at(qx, qy) + (at(qx + 1, qy) - at(qx, qy)) * fx;
                        let r1 = at(qx, qy + 1) + (at(qx + 1, qy + 1) - at(qx, qy + 1)) * fx;
                        let up = r0 + (r1 - r0) * fy;
                        if st.jitter > 0.0 {
                            up + st.jitter * (n - 0.5)
                        } else {
                            up
                        }
                    }
                };
            }
        }
        let (mut cur, mut cw, mut ch) = (a, aw, ah);
        for _ in 0..st.iterations {
            let (nw, nh) = (cw - 2 * r, ch - 2 * r);
            let mut next = vec![0.0f32; (nw * nh) as usize];
            for j in 0..nh {
                for i in 0..nw {
                    let mut acc = 0.0f32;
                    for tap in &st.kernel().taps {
                        let (sx, sy) = (i + r + tap.dx as i128, j + r + tap.dy as i128);
                        acc += tap.w * cur[(sy * cw + sx) as usize];
                    }
                    next[(j * nw + i) as usize] = acc;
                }
            }
            st.map.apply(&mut next);
            (cur, cw, ch) = (next, nw, nh);
        }
        assert_eq!((cw, ch), (w as i128, h as i128));
        cur
    }
    stage(e, e.stages.len() - 1, x0, y0, w, h)
}

#[test]
fn far_coordinates_agree_with_a_direct_evaluation() {
    for params in [single(), cascade3()] {
        let t = tex(params);
        for (x, y) in [
            (0i64, 0i64),
            (-5, 7),
            ((1 << 31) - 20, (1 << 31) + 3),
            (-(1 << 31) - 9, 1 << 33),
            (1 << 40, -(1 << 41)),
            (-(1 << 58), 1 << 57),
        ] {
            let img = render(&t, 0, x, y, 40, 24);
            let reference = direct(&t, x as i128, y as i128, 40, 24);
            let field = t.exact().engine().field(t.exact().engine().stages.len() - 1, x as u64, y as u64, 40, 24);
            let same = field.v.iter().zip(&reference).filter(|(a, b)| a == b).count();
            assert_eq!(same, reference.len(), "at ({x}, {y}): {same} of {} values agree", reference.len());
            let expect: Vec<u8> = reference.iter().flat_map(|v| t.exact().colour(*v)).collect();
            assert!(img.data == expect, "at ({x}, {y}): colours differ");
        }
    }
}

#[test]
fn demos_cover_the_papers_looks_at_scale_in_kilobytes() {
    let a: Vec<Bundle> = cascade::demos();
    assert!(a.len() >= 6);
    // At least one demo is 100k × 100k or larger; encodings are kilobytes.
    let largest = a.iter().map(|b| models::load(b).unwrap()).map(|t| t.width().min(t.height())).max().unwrap();
    assert!(largest >= 100_000);
    for b in &a {
        assert!(b.to_bytes().len() < 64 << 10, "{}: {} bytes", b.manifest.name, b.to_bytes().len());
    }
    // The looks the issue asks for: single-scale, cascades, a dilation map, an initial image.
    let names: Vec<&Bundle> = a.iter().collect();
    let stages = |b: &Bundle| b.manifest.params["stages"].as_array().unwrap().len();
    assert!(names.iter().filter(|b| stages(b) == 1).count() >= 2);
    assert!(names.iter().filter(|b| stages(b) >= 2).count() >= 2);
    assert!(names.iter().any(|b| b.section("control.png").is_ok()));
    assert!(names.iter().any(|b| b.section("initial.png").is_ok()));
}

/// The levels the model serves exactly (up to `exact_levels`, and those its final stage
/// predicts) are rendered by brute force: exactly the 2×2 box chain of level 0.
#[test]
fn exact_levels_are_the_box_chain_of_level_0() {
    let mut textures: Vec<(String, Cascade)> = cascade::demos()
        .iter()
        .map(|b| (b.manifest.name.clone(), cascade::load(&Bundle::from_bytes(&b.to_bytes()).unwrap()).unwrap()))
        .collect();
    textures.push(("single".into(), tex(single())));
    textures.push(("cascade3".into(), tex(cascade3())));
    for (name, t) in textures {
        let (x, y) = (1i64 << 24, 3i64 << 22);
        let base = render(&t, 0, x, y, 256, 256);
        for l in (1..=3).filter(|&l| prefilter::is_exact(t.exact(), l)) {
            let served = render(&t, l, x >> l, y >> l, 256 >> l, 256 >> l);
            assert!(served == downsample_n(&base, l), "{name}: level {l} is not the exact downsample");
        }
    }
}

/// `create` writes the defaults of new textures (no exact levels, a stage budget) into the
/// manifest, and a stored manifest without them keeps their old meaning: levels 1 and 2
/// exact, every coarser level predicted by its finest stage.
#[test]
fn a_stored_manifest_keeps_the_mip_defaults_it_was_made_with() {
    let made = models::create("cascade", "c", &cascade3(), &Inputs::new()).unwrap();
    let derived = &made.manifest.derived;
    assert_eq!(derived.get("exact_levels"), Some(&json!(cascade::params::EXACT_LEVELS)));
    assert_eq!(derived.get("stage_budget"), Some(&json!(cascade::params::STAGE_BUDGET)));
    let mut old = made.clone();
    old.manifest.derived.retain(|k, _| k != "exact_levels" && k != "stage_budget");
    let (new, old) =
        (cascade::load(&made).unwrap(), cascade::load(&Bundle::from_bytes(&old.to_bytes()).unwrap()).unwrap());
    let (x, y) = (5i64 << 20, -(3i64 << 21));
    let base = render(&new, 0, x, y, 256, 256);
    for l in 1..=2 {
        let exact = downsample_n(&base, l);
        assert!(render(&old, l, x >> l, y >> l, 256 >> l, 256 >> l) == exact, "level {l} of a stored texture");
        // A new texture's level 1 comes from a coarser stage; its level 2, which only the
        // final stage predicts within the gates, stays exact.
        let new_l = render(&new, l, x >> l, y >> l, 256 >> l, 256 >> l);
        assert_eq!(new_l == exact, l == 2, "level {l} of a new texture");
    }
    // The old rule predicts by the finest stage whatever it costs; the budget takes a coarser
    // one at level 1, where the finest costs too much.
    let e = new.exact().engine();
    let stages = |budget| (1..=6).map(|l| prefilter::predicting_stage(&e.stages, false, budget, l)).collect::<Vec<_>>();
    assert_eq!(stages(None), vec![Some(2), Some(2), Some(1), Some(0), Some(0), None]);
    assert_ne!(stages(Some(cascade::params::STAGE_BUDGET))[0], stages(None)[0]);
    assert_eq!(stages(Some(cascade::params::STAGE_BUDGET))[1..], stages(None)[1..]);
}

/// A grey control map of `w × 2` texels, column i at luminance `columns[i]`.
fn control(columns: &[u8]) -> Inputs {
    let mut img = Rgba8Image::new(columns.len() as u32, 2);
    for (x, &v) in columns.iter().enumerate() {
        for y in 0..2 {
            img.set_pixel(x as u32, y, [v, v, v, 255]);
        }
    }
    Inputs::from([("control".to_string(), img.to_png())])
}

/// The final-stage lattice values (before the palette) of a `w × h` window at (x, y).
fn lattice(t: &Cascade, x: u64, y: u64, w: usize, h: usize) -> Vec<f32> {
    t.exact().engine().field(t.exact().engine().stages.len() - 1, x, y, w, h).v
}

/// The control map scales the kernel by 1 + c·(max − 1) at each point: where the map is
/// white the lattice is exactly the one of a uniform dilation `max`, where it is black
/// exactly the undilated one, and in between neither.
#[test]
fn the_dilation_map_dilates_the_lattice_by_its_control_value() {
    let stage = json!({"kernel": {"size": 3, "preset": "gauss"}, "map": {"kind": "sine", "r": 0.97}, "iterations": 6});
    let with = |dilation: f64, map: Option<(&[u8], u64)>| {
        let mut s = stage.clone();
        s["dilation"] = json!(dilation);
        let mut p = json!({"seed": 5, "stages": [s]});
        let inputs = match map {
            Some((columns, cell)) => {
                p["dilation_map"] = json!({"max": 4, "cell": cell});
                control(columns)
            }
            None => Inputs::new(),
        };
        cascade::load(&models::create("cascade", "d", &p, &inputs).unwrap()).unwrap()
    };
    let (plain, by4) = (with(1.0, None), with(4.0, None));
    let (x, y, w, h) = ((1u64 << 33) + 7, 5u64, 96usize, 64usize);
    assert_ne!(lattice(&plain, x, y, w, h), lattice(&by4, x, y, w, h), "dilation 4 changes the lattice");
    // Uniform maps: white is dilation 4 everywhere, black is no dilation.
    assert!(
        lattice(&with(1.0, Some((&[255, 255], 64))), x, y, w, h) == lattice(&by4, x, y, w, h),
        "white ≠ dilation 4"
    );
    assert!(lattice(&with(1.0, Some((&[0, 0], 64))), x, y, w, h) == lattice(&plain, x, y, w, h), "black ≠ no dilation");
    // Columns white, white, black, black at 256 px a texel, repeating: between the centres of
    // the two white texels (x ∈ [128, 384] mod 1024) the map is exactly 1, between the black
    // ones ([640, 896]) exactly 0. A point's value depends on the lattice within the margin
    // (iterations × the dilated kernel's reach), so away from the transitions by that much
    // each half is the uniform texture; in the transitions it is neither.
    let split = with(1.0, Some((&[255, 255, 0, 0], 256)));
    let m = by4.exact().engine().margin(0) as u64;
    let period = 10u64 * 1024;
    let (white, black, ramp) = (period + 128 + m, period + 640 + m, period + 384 + m);
    let side = 256 - 2 * m as usize;
    assert!(lattice(&split, white, y, side, h) == lattice(&by4, white, y, side, h), "white half ≠ dilation 4");
    assert!(lattice(&split, black, y, side, h) == lattice(&plain, black, y, side, h), "black half ≠ no dilation");
    let (mid, a, b) =
        (lattice(&split, ramp, y, 200, h), lattice(&by4, ramp, y, 200, h), lattice(&plain, ramp, y, 200, h));
    let differ = |u: &[f32]| mid.iter().zip(u).filter(|(p, q)| p != q).count();
    assert!(differ(&a) > mid.len() / 2 && differ(&b) > mid.len() / 2, "the ramp is not an intermediate dilation");
}

fn err(params: serde_json::Value, inputs: &Inputs) -> String {
    models::create("cascade", "bad", &params, inputs).unwrap_err().to_string()
}

fn with_stage(stage: serde_json::Value) -> serde_json::Value {
    json!({"seed": 1, "stages": [stage]})
}

#[test]
fn bad_input_gives_clear_errors() {
    let none = Inputs::new();
    let cases: Vec<(serde_json::Value, &str)> = vec![
        (with_stage(json!({"kernel": {"size": 9, "preset": "box"}})), "7×7"),
        (with_stage(json!({"kernel": {"size": 4, "preset": "box"}})), "kernel.size"),
        (with_stage(json!({"kernel": {"size": 3, "weights": [1, 2, 3]}})), "3 weights"),
        (with_stage(json!({"iterations": 0})), "iterations"),
        (with_stage(json!({"iterations": 1000})), "iterations"),
        (with_stage(json!({"map": {"kind": "logistic", "r": 4.2}})), "stages[0].map.r"),
        (with_stage(json!({"map": {"kind": "tent", "mu": -1}})), "map.mu"),
        (with_stage(json!({"map": {"kind": "sigmoid", "gain": 0, "center": 0.5}})), "map.gain"),
        (with_stage(json!({"map": {"kind": "henon", "a": 1.4}})), "stages[0].map"),
        (with_stage(json!({"dilation": 0})), "dilation"),
        (with_stage(json!({"dilation": 0.5})), "stages[0].dilation"),
        (with_stage(json!({"aspect": 0.5})), "stages[0].aspect"),
        (with_stage(json!({"dilation": 8, "aspect": 4})), "dilation × aspect"),
        (with_stage(json!({"rotation": 1e9})), "stages[0].rotation"),
        (with_stage(json!({"upsample": 2})), "upsample"),
        (json!({"seed": 1, "stages": [{}, {"upsample": 3}]}), "stages[1].upsample"),
        (json!({"seed": 1, "stages": []}), "stages"),
        (json!({"seed": 1, "stages": [{}], "colour": "red"}), "unknown field"),
        (json!({"seed": 1, "stages": [{}], "palette": "neon"}), "palette"),
        (json!({"seed": 1, "stages": [{}], "width": 0}), "width"),
        (json!({"seed": 1, "stages": [{}], "range": [1, 0]}), "range"),
        (json!({"seed": 1, "stages": [{}], "exact_levels": 9}), "exact_levels"),
        (json!({"seed": -1, "stages": [{}]}), "seed"),
        (json!({"seed": 1, "stages": [{}], "dilation_map": {"max": 3, "cell": 16}}), "control"),
        (
            json!({"seed": 1, "stages": [{"iterations": 64, "kernel": {"size": 7, "preset": "box"}, "dilation": 8}]}),
            "at most",
        ),
    ];
    for (params, needle) in cases {
        let e = err(params.clone(), &none);
        assert!(e.contains(needle), "{params}: `{e}` should mention `{needle}`");
    }
    // Control maps of the wrong size, and images that are not PNGs.
    let dm = json!({"seed": 1, "stages": [{}], "dilation_map": {"max": 3, "cell": 16}});
    for (img, needle) in [(control_map(300), "300×300"), (Rgba8Image::new(1, 1), "1×1")] {
        let mut inputs = Inputs::new();
        inputs.insert("control".into(), img.to_png());
        let e = err(dm.clone(), &inputs);
        assert!(e.contains("control") && e.contains(needle) && e.contains("low resolution"), "{e}");
    }
    let mut junk = Inputs::new();
    junk.insert("control".into(), b"not a png".to_vec());
    assert!(err(dm.clone(), &junk).contains("control"));
    let mut stray = Inputs::new();
    stray.insert("initial".into(), initial_image(16, 16).to_png());
    assert!(err(json!({"seed": 1, "stages": [{}]}), &stray).contains("`initial` is not set"));
    let mut sample = Inputs::new();
    sample.insert("sample".into(), initial_image(16, 16).to_png());
    assert!(err(json!({"seed": 1, "stages": [{}]}), &sample).contains("sample"));

    // Loading validates too: a tampered manifest or a stray section is refused.
    let good = models::create("cascade", "ok", &single(), &none).unwrap();
    let mut bad = good.clone();
    bad.manifest.params["stages"][0]["kernel"]["size"] = json!(11);
    assert!(models::load(&bad).err().unwrap().to_string().contains("7×7"));
    let stray_section = good.clone().with_section("blocks", vec![1, 2, 3]);
    assert!(models::load(&stray_section).err().unwrap().to_string().contains("unexpected section"));
    let mut broken = models::create("cascade", "c", &dm, &{
        let mut i = Inputs::new();
        i.insert("control".into(), control_map(32).to_png());
        i
    })
    .unwrap();
    broken.sections[0].data.truncate(40);
    assert!(models::load(&broken).err().unwrap().to_string().contains("control"));
}

/// Correlation length of a `w × h` field along the lattice direction (dx, dy) (each 0 or 1):
/// the lag, interpolated, at which its autocorrelation first falls to 1/2.
fn correlation_length(v: &[f32], w: usize, h: usize, (dx, dy): (usize, usize)) -> f64 {
    let n = v.len() as f64;
    let mean = v.iter().map(|&x| x as f64).sum::<f64>() / n;
    let var = v.iter().map(|&x| (x as f64 - mean).powi(2)).sum::<f64>() / n;
    let r = |lag: usize| {
        let (mut sum, mut count) = (0.0, 0.0);
        for j in 0..h - lag * dy {
            for i in 0..w - lag * dx {
                sum += (v[j * w + i] as f64 - mean) * (v[(j + lag * dy) * w + i + lag * dx] as f64 - mean);
                count += 1.0;
            }
        }
        sum / count / var
    };
    let mut prev = 1.0;
    for lag in 1..w.min(h) / 2 {
        let now = r(lag);
        if now < 0.5 {
            return (lag - 1) as f64 + (prev - 0.5) / (prev - now);
        }
        prev = now;
    }
    f64::INFINITY
}

fn correlation_lengths(v: &[f32], w: usize, h: usize) -> [f64; 2] {
    [correlation_length(v, w, h, (1, 0)), correlation_length(v, w, h, (0, 1))]
}

/// A one-stage texture of `stage` with `extra` set on the stage.
fn one_stage(stage: &serde_json::Value, extra: serde_json::Value) -> Cascade {
    let mut s = stage.clone();
    s.as_object_mut().unwrap().extend(extra.as_object().unwrap().clone());
    tex(json!({"seed": 21, "stages": [s]}))
}

const LOOKS: [(&str, &str); 2] = [
    (
        "logistic",
        r#"{"kernel": {"size": 5, "preset": "gauss", "sigma": 1.0}, "map": {"kind": "logistic", "r": 3.9}, "iterations": 5}"#,
    ),
    ("sine", r#"{"kernel": {"size": 3, "preset": "gauss"}, "map": {"kind": "sine", "r": 0.97}, "iterations": 6}"#),
];

/// Dilation scales the texture's features: the correlation length grows in proportion to
/// the dilation, for integer and real factors, and neighbouring points stay correlated
/// (integer dilation with holes splits the lattice into d² independent sub-lattices: pixel
/// noise, not a larger texture).
#[test]
fn dilation_scales_features_in_proportion() {
    const SIDE: usize = 512;
    for (label, stage) in LOOKS {
        let stage: serde_json::Value = serde_json::from_str(stage).unwrap();
        let field = |d: f64| lattice(&one_stage(&stage, json!({"dilation": d})), 1 << 36, 77, SIDE, SIDE);
        let base = correlation_lengths(&field(1.0), SIDE, SIDE);
        for d in [1.5, 2.0, 3.0, 4.0] {
            let v = field(d);
            let l = correlation_lengths(&v, SIDE, SIDE);
            for axis in 0..2 {
                let ratio = l[axis] / base[axis];
                assert!(
                    (0.85 * d..=1.2 * d).contains(&ratio),
                    "{label}, dilation {d}, axis {axis}: correlation length {:.2} against {:.2} undilated: ×{ratio:.2}",
                    l[axis],
                    base[axis]
                );
            }
        }
    }
}

/// An anisotropic kernel elongates features along its stretched axis by its aspect, and a
/// rotation by 90° turns them to the other axis.
#[test]
fn aspect_and_rotation_orient_features() {
    const SIDE: usize = 384;
    for (label, stage) in LOOKS {
        let stage: serde_json::Value = serde_json::from_str(stage).unwrap();
        let lengths =
            |extra| correlation_lengths(&lattice(&one_stage(&stage, extra), 99, 1 << 40, SIDE, SIDE), SIDE, SIDE);
        let [bx, by] = lengths(json!({"dilation": 1.5}));
        let [sx, sy] = lengths(json!({"dilation": 1.5, "aspect": 3.0}));
        assert!((2.4..=3.6).contains(&(sx / bx)), "{label}: stretched x ×{:.2}", sx / bx);
        assert!((0.8..=1.25).contains(&(sy / by)), "{label}: stretched kernel's y ×{:.2}", sy / by);
        let [rx, ry] = lengths(json!({"dilation": 1.5, "aspect": 3.0, "rotation": 90.0}));
        assert!(
            (0.8..=1.25).contains(&(rx / by)) && (2.4..=3.6).contains(&(ry / bx)),
            "{label}: rotated {rx:.2} × {ry:.2}"
        );
    }
}

/// Across a dilation map the features grow with the map, continuously: under a ramp of
/// control values from black to white, the correlation length around each step follows its
/// dilation 1 + c·(max − 1), rising from step to step (no dot grids where the dilation is
/// whole, no low-contrast bands between).
#[test]
fn features_follow_a_dilation_map_smoothly() {
    let columns: Vec<u8> = (0..8).map(|i| (i * 255 / 7) as u8).collect();
    let (cell, max) = (256u64, 4.0);
    for (label, stage) in LOOKS {
        let mut p = json!({"seed": 4, "stages": [serde_json::from_str::<serde_json::Value>(stage).unwrap()],
                           "dilation_map": {"max": max, "cell": cell}});
        let t = cascade::load(&models::create("cascade", "ramp", &p, &control(&columns)).unwrap()).unwrap();
        p["dilation_map"] = serde_json::Value::Null;
        let (w, h) = (96usize, 768usize);
        let length_at = |t: &Cascade, texel: u64| {
            let x = (1 << 30) * cell * columns.len() as u64 + texel * cell + cell / 2 - w as u64 / 2;
            correlation_length(&lattice(t, x, 3, w, h), w, h, (0, 1))
        };
        let base = length_at(&t, 0);
        for (texel, &c) in columns.iter().enumerate() {
            let d = 1.0 + c as f64 / 255.0 * (max - 1.0);
            let ratio = length_at(&t, texel as u64) / base;
            println!("{label}: control {c}: dilation {d:.2}, correlation length ×{ratio:.2}");
            assert!((0.8 * d..=1.25 * d).contains(&ratio), "{label}: control {c} (dilation {d:.2}): ×{ratio:.2}");
        }
    }
}

/// Per-channel standard deviation of an image's pixels.
fn sigma(img: &Rgba8Image) -> [f64; 3] {
    let n = (img.width * img.height) as f64;
    let m = mean_rgba(img);
    [0, 1, 2].map(|c| (img.data.chunks_exact(4).map(|p| (p[c] as f64 - m[c]).powi(2)).sum::<f64>() / n).sqrt())
}

/// Prefiltered levels keep the statistics of the exact downsample: at levels 3 to 5 of every
/// demo (those the calibration measures), each channel's σ is within 10 % of the exact box
/// chain's (of a 2048² level-0 region), and the PSNR against it stays above a floor of
/// 10 dB (a residual that has the truth's σ but not its place costs up to 3 dB against a
/// flat prediction). Level 6 (measured on fewer blocks) is printed. (A prediction alone — a conditional
/// mean — is smoother than the truth: a single-stage texture's would be one flat colour.)
#[test]
fn coarse_levels_keep_the_exact_downsamples_statistics() {
    const SIDE: u32 = 2048;
    for (name, t) in all_textures() {
        let (x, y) = (3i64 << 30, -(5i64 << 28));
        let base = render(t.as_ref(), 0, x, y, SIDE, SIDE);
        for l in 3..=6 {
            let exact = downsample_n(&base, l);
            let served = render(t.as_ref(), l, x >> l, y >> l, SIDE >> l, SIDE >> l);
            let (se, ss) = (sigma(&exact), sigma(&served));
            let psnr = vtex_synth::mip::psnr(&exact, &served);
            println!("{name} L{l}: σ exact {se:.1?} served {ss:.1?}, PSNR {psnr:.1} dB");
            if l == 6 {
                continue;
            }
            for c in 0..3 {
                assert!(
                    (ss[c] - se[c]).abs() <= 0.1 * se[c] + 0.5,
                    "{name}, level {l}, channel {c}: σ {:.2} against the exact {:.2}",
                    ss[c],
                    se[c]
                );
            }
            assert!(psnr >= 10.0, "{name}, level {l}: PSNR {psnr:.1} dB");
        }
    }
}

/// One level of a demo measured against the exact box chain: the served level, and the
/// answers that need no model (a flat colour, point sampling, the level above copied down).
struct LevelRow {
    level: u32,
    /// Where the exact chain starts: level 0, or a served level three below.
    base: u32,
    pixels: u32,
    mean_exact: [f64; 3],
    mean_served: [f64; 3],
    sigma_exact: [f64; 3],
    sigma_served: [f64; 3],
    psnr_served: f64,
    psnr_flat: f64,
    /// Point sampling of the chain's base level, and of the served level below.
    psnr_point_base: f64,
    psnr_point_below: f64,
    /// The served level above, each pixel copied to its 2×2 children.
    psnr_above: f64,
    /// Luminance correlation of the served level L + 1 with the served level L downsampled.
    corr_next: f64,
}

/// Side of the level-0 region whose box chain is the exact reference up to
/// [`FROM_LEVEL_0`], and the side of the compared region beyond, where the chain starts at
/// the served level three below (as the conformance suite's).
const REGION: u32 = 1024;
const FROM_LEVEL_0: u32 = 6;
const BEYOND: u32 = 64;
/// Aligned to 2^28, so blocks of every measured level align with the region.
const ANCHOR: (i64, i64) = (3 << 30, -(5 << 28));

fn luma(img: &Rgba8Image) -> Vec<f64> {
    img.data.chunks_exact(4).map(|p| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64).collect()
}

fn correlation(a: &[f64], b: &[f64]) -> f64 {
    let n = a.len() as f64;
    let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
    let cov: f64 = a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum();
    let va: f64 = a.iter().map(|x| (x - ma).powi(2)).sum();
    let vb: f64 = b.iter().map(|y| (y - mb).powi(2)).sum();
    if va == 0.0 || vb == 0.0 {
        return 0.0;
    }
    cov / (va * vb).sqrt()
}

/// `img` with each pixel replaced by its top-left child at `k` levels finer (`fine`).
fn point_sample(fine: &Rgba8Image, k: u32, w: u32, h: u32) -> Rgba8Image {
    let mut out = Rgba8Image::new(w, h);
    for j in 0..h {
        for i in 0..w {
            out.set_pixel(i, j, fine.pixel(i << k, j << k));
        }
    }
    out
}

/// A flat image of the rounded colour `c`.
fn flat(c: [f64; 3], w: u32, h: u32) -> Rgba8Image {
    let p = [c[0].round() as u8, c[1].round() as u8, c[2].round() as u8, 255];
    Rgba8Image::from_raw(w, h, p.iter().copied().cycle().take((w * h * 4) as usize).collect()).unwrap()
}

/// Every level from 1 to the top of `t` against its exact box chain. Up to
/// [`FROM_LEVEL_0`] the chain is that of a `REGION²` level-0 region (16 × 16 pixels at the
/// last such level, 256 independent blocks: σ known within ≈ 5 %); beyond, a level-0 region
/// large enough for σ would cost minutes a demo, so the chain starts at the served level
/// three below, over `BEYOND²` pixels, or the level's own size if smaller (8² at least).
fn level_table(t: &dyn Texture) -> Vec<LevelRow> {
    let top = vtex_synth::texture::level_count(t.width(), t.height()) - 1;
    // Each region is rendered once: a level-0 region of the dilation-map demo costs seconds.
    let cache = std::cell::RefCell::new(std::collections::HashMap::new());
    let at = |l: u32, side: u32| -> Rgba8Image {
        let key = (l, side);
        if let Some(img) = cache.borrow().get(&key) {
            return Rgba8Image::clone(img);
        }
        let img = render(t, l, ANCHOR.0 >> l, ANCHOR.1 >> l, side, side);
        cache.borrow_mut().insert(key, img.clone());
        img
    };
    let base0 = at(0, REGION);
    // Beyond, no larger than the level itself (at least 8 pixels): a guided level's pixel
    // averages up to 64 × 64 samples of its guide.
    let side_at = |l: u32| {
        let (w, h) = vtex_synth::texture::level_size(t.width(), t.height(), l);
        let fits = 1u32 << (w.min(h).max(8).ilog2().min(BEYOND.ilog2()));
        if l <= FROM_LEVEL_0 {
            REGION >> l
        } else {
            fits
        }
    };
    let mut rows = Vec::new();
    for l in 1..=top {
        let side = side_at(l);
        let (base, fine) = if l <= FROM_LEVEL_0 { (0, base0.clone()) } else { (l - 3, at(l - 3, side << 3)) };
        let exact = downsample_n(&fine, l - base);
        let served = at(l, side);
        let below = at(l - 1, side * 2);
        // The level above, over the same area (none above the top).
        let above = (l < top).then(|| at(l + 1, side / 2));
        let copy = above.as_ref().map(|above| {
            let mut copy = Rgba8Image::new(side, side);
            for j in 0..side {
                for i in 0..side {
                    copy.set_pixel(i, j, above.pixel(i / 2, j / 2));
                }
            }
            copy
        });
        let mean = |img: &Rgba8Image| {
            let m = mean_rgba(img);
            [m[0], m[1], m[2]]
        };
        let psnr = vtex_synth::mip::psnr;
        rows.push(LevelRow {
            level: l,
            base,
            pixels: side,
            mean_exact: mean(&exact),
            mean_served: mean(&served),
            sigma_exact: sigma(&exact),
            sigma_served: sigma(&served),
            psnr_served: psnr(&served, &exact),
            psnr_flat: psnr(&flat(mean(&exact), side, side), &exact),
            psnr_point_base: psnr(&point_sample(&fine, l - base, side, side), &exact),
            psnr_point_below: psnr(&point_sample(&below, 1, side, side), &exact),
            psnr_above: copy.map_or(f64::NAN, |c| psnr(&c, &exact)),
            corr_next: above.map_or(f64::NAN, |a| correlation(&luma(&a), &luma(&downsample_n(&served, 1)))),
        });
    }
    rows
}

fn db(v: f64) -> String {
    if v.is_infinite() {
        "∞".into()
    } else {
        format!("{v:.1}")
    }
}

/// What a level of a demo is served from, finest content first.
#[derive(Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Debug)]
enum Source {
    /// Level 0 box-filtered.
    Exact,
    /// A stage's lattice (up to its spacing × 4), by the stage's spacing (log2).
    Stage(u32),
    /// An initial image, which places content at every scale. (A dilation map sets the
    /// features' size, not where they are.)
    Guide,
    /// The mean and a residual with the right statistics in no particular place: the
    /// level's block means are sums of thousands of chaotic values that no bounded work a
    /// tile can place.
    Nothing,
}

/// The source of each level of `b`, as the model chooses it.
fn sources(b: &Bundle) -> impl Fn(u32) -> Source {
    let t = cascade::load(b).unwrap();
    let guide = b.manifest.full_params().unwrap().get("initial").is_some();
    move |l| {
        let (p, e) = (t.exact().params(), t.exact().engine());
        if prefilter::is_exact(t.exact(), l) {
            Source::Exact
        } else if let Some(s) = prefilter::predicting_stage(&e.stages, e.control.is_some(), p.stage_budget, l) {
            Source::Stage(e.stages[s].shift)
        } else if guide {
            Source::Guide
        } else {
            Source::Nothing
        }
    }
}

#[test]
fn every_level_keeps_the_exact_chains_mean_structure_and_grain() {
    let demos = cascade::demos();
    // The demos in parallel: the dilation-map demo alone costs seconds.
    let checked: Vec<(String, Vec<String>, Vec<String>)> = std::thread::scope(|scope| {
        let handles: Vec<_> = demos.iter().map(|b| scope.spawn(move || check_levels(b))).collect();
        handles.into_iter().map(|h| h.join().unwrap()).collect()
    });
    let (mut failures, mut shortfalls) = (Vec::new(), Vec::new());
    for (table, f, s) in checked {
        println!("{table}");
        failures.extend(f);
        shortfalls.extend(s);
    }
    println!("\nshortfalls where the model has no content at the level's scale:\n{}", shortfalls.join("\n"));
    assert!(failures.is_empty(), "{} failures:\n{}", failures.len(), failures.join("\n"));
}

/// One demo's per-level table, its failures and its shortfalls.
fn check_levels(b: &Bundle) -> (String, Vec<String>, Vec<String>) {
    use std::fmt::Write;
    let (mut failures, mut shortfalls) = (Vec::new(), Vec::new());
    let name = b.manifest.name.clone();
    let source = sources(b);
    let t = models::load(&Bundle::from_bytes(&b.to_bytes()).unwrap()).unwrap();
    let mut out = String::new();
    writeln!(out, "\n**{name}**\n").unwrap();
    writeln!(out, "| L | chain | px | mean exact | mean served | σ exact | σ served | PSNR served | flat | point base | point below | above | corr L+1 |").unwrap();
    writeln!(out, "|---|---|---|---|---|---|---|---|---|---|---|---|---|").unwrap();
    let rows = level_table(t.as_ref());
    for (i, r) in rows.iter().enumerate() {
        let rgb = |c: [f64; 3]| format!("{:.0},{:.0},{:.0}", c[0], c[1], c[2]);
        let rgb1 = |c: [f64; 3]| format!("{:.1},{:.1},{:.1}", c[0], c[1], c[2]);
        writeln!(
            out,
            "| {} | L{} | {}² | {} | {} | {} | {} | {} | {} | {} | {} | {} | {:.2} |",
            r.level,
            r.base,
            r.pixels,
            rgb(r.mean_exact),
            rgb(r.mean_served),
            rgb1(r.sigma_exact),
            rgb1(r.sigma_served),
            db(r.psnr_served),
            db(r.psnr_flat),
            db(r.psnr_point_base),
            db(r.psnr_point_below),
            db(r.psnr_above),
            r.corr_next
        )
        .unwrap();
        let l = r.level;
        for c in 0..3 {
            if (r.mean_served[c] - r.mean_exact[c]).abs() > 3.0 {
                failures
                    .push(format!("{name} L{l} ch{c}: mean {:.1} vs exact {:.1}", r.mean_served[c], r.mean_exact[c]));
            }
            if (r.sigma_served[c] - r.sigma_exact[c]).abs() > 0.15 * r.sigma_exact[c] + 0.5 {
                failures
                    .push(format!("{name} L{l} ch{c}: σ {:.1} vs exact {:.1}", r.sigma_served[c], r.sigma_exact[c]));
            }
        }
        let floor = r.psnr_flat.max(r.psnr_point_base).max(r.psnr_point_below);
        if r.psnr_served.is_finite() && r.psnr_served < floor {
            shortfalls.push(format!(
                "{name} L{l} ({:?}): PSNR {} below flat {} / point {} / point of L{} {}",
                source(l),
                db(r.psnr_served),
                db(r.psnr_flat),
                db(r.psnr_point_base),
                l - 1,
                db(r.psnr_point_below)
            ));
        }
        // The grain of level L + 1 against level L downsampled.
        let next_sigma = rows.get(i + 1).map_or(0.0, |n| n.sigma_exact.iter().cloned().fold(0.0, f64::max));
        if next_sigma >= 2.0 && r.corr_next < 0.5 {
            let (from, to) = (source(l), source(l + 1));
            let why = format!(
                "{name}: L{} ({to:?}) against L{l} ({from:?}) downsampled: correlation {:.2}",
                l + 1,
                r.corr_next
            );
            if to > from && to != Source::Guide {
                shortfalls.push(why)
            } else {
                failures.push(why)
            }
        }
    }
    (out, failures, shortfalls)
}
