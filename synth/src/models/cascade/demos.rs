//! Demo encodings, one for each of the paper's images: two single-scale looks (A, B), a
//! dilation-map look (C), a texture-transfer look (D) and cascades on several scales (E–H;
//! G with stretched, rotated kernels, H with a dilated coarse stage). Their input images are drawn
//! here procedurally (with `libm`, so the bundles — and their ids — are the same on every
//! platform); nothing is downloaded.

use super::create;
use crate::bundle::Bundle;
use crate::models::Inputs;
use crate::pixels::Rgba8Image;
use serde_json::json;

/// A smooth low-resolution control map: soft blobs and bands (white = most dilated).
pub fn control_map(side: u32) -> Rgba8Image {
    let mut img = Rgba8Image::new(side, side);
    let tau = 2.0 * core::f64::consts::PI;
    for y in 0..side {
        for x in 0..side {
            let (u, v) = (x as f64 / side as f64, y as f64 / side as f64);
            let s = libm::sin(tau * u) * libm::cos(tau * v) * 0.6 + libm::sin(tau * 2.0 * (u + v)) * 0.4;
            let g = ((0.5 + 0.5 * s).clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
            img.set_pixel(x, y, [g, g, g, 255]);
        }
    }
    img
}

/// A structured initial image: the letters VTEX over concentric rings, softly shaded.
pub fn initial_image(w: u32, h: u32) -> Rgba8Image {
    const GLYPHS: [[u8; 7]; 4] = [
        [0b10001, 0b10001, 0b10001, 0b10001, 0b01010, 0b01010, 0b00100], // V
        [0b11111, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100, 0b00100], // T
        [0b11111, 0b10000, 0b10000, 0b11110, 0b10000, 0b10000, 0b11111], // E
        [0b10001, 0b10001, 0b01010, 0b00100, 0b01010, 0b10001, 0b10001], // X
    ];
    let mut img = Rgba8Image::new(w, h);
    let (cx, cy) = (w as f64 / 2.0, h as f64 / 2.0);
    let unit = (w / 26).max(1);
    let (ox, oy) = (w.saturating_sub(unit * 23) / 2, h.saturating_sub(unit * 7) / 2);
    for y in 0..h {
        for x in 0..w {
            let r = libm::sqrt((x as f64 - cx).powi(2) + (y as f64 - cy).powi(2)) / w as f64;
            let mut g = 0.3 + 0.15 * libm::cos(r * 60.0);
            if x >= ox && y >= oy {
                let (gx, gy) = ((x - ox) / unit, (y - oy) / unit);
                let (letter, col) = (gx / 6, gx % 6);
                if letter < 4 && col < 5 && gy < 7 && GLYPHS[letter as usize][gy as usize] >> (4 - col) & 1 == 1 {
                    g = 0.85;
                }
            }
            let v = (g * 255.0 + 0.5) as u8;
            img.set_pixel(x, y, [v, v, v, 255]);
        }
    }
    img
}

fn bundle(name: &str, params: serde_json::Value, inputs: Inputs) -> Bundle {
    create(name, &params, &inputs).unwrap_or_else(|e| panic!("demo `{name}` is invalid: {e}"))
}

/// The demo encodings (each well under a few kilobytes plus its input image).
pub fn demos() -> Vec<Bundle> {
    let gauss5 = json!({"size": 5, "preset": "gauss", "sigma": 1.0});
    let gauss3 = json!({"size": 3, "preset": "gauss", "sigma": 0.8});
    let mut out = vec![
        bundle(
            "Cascade A — logistic ripples",
            json!({"seed": 11, "stages": [{"kernel": gauss5, "map": {"kind": "logistic", "r": 3.9}, "iterations": 5}],
                   "palette": "ocean"}),
            Inputs::new(),
        ),
        bundle(
            "Cascade B — sigmoid labyrinth",
            json!({"seed": 12, "stages": [{"kernel": {"size": 7, "preset": "dog", "sigma": 1.0, "sigma2": 2.2, "amount": 0.9},
                   "map": {"kind": "sigmoid", "gain": 14.0, "center": 0.5}, "iterations": 5}],
                   "palette": "moss"}),
            Inputs::new(),
        ),
    ];
    let mut control = Inputs::new();
    control.insert("control".into(), control_map(64).to_png());
    out.push(bundle(
        "Cascade C — dilation map",
        json!({"seed": 13, "stages": [{"kernel": {"size": 3, "preset": "gauss"}, "map": {"kind": "sine", "r": 0.97}, "iterations": 6}],
               "dilation_map": {"max": 4, "cell": 16}, "palette": "earth"}),
        control,
    ));
    let mut initial = Inputs::new();
    initial.insert("initial".into(), initial_image(256, 128).to_png());
    out.push(bundle(
        "Cascade D — texture transfer",
        json!({"seed": 14, "width": 4096, "height": 2048,
               "stages": [{"kernel": gauss5, "map": {"kind": "sine", "r": 0.97}, "iterations": 5}],
               "initial": {"cell": 16, "strength": 0.8, "repeat": true}, "palette": "granite"}),
        initial,
    ));
    out.push(bundle(
        "Cascade E — marble veins",
        json!({"seed": 15, "stages": [
                 {"kernel": gauss5, "map": {"kind": "sine", "r": 0.95}, "iterations": 5},
                 {"upsample": 4, "jitter": 0.05, "kernel": gauss5, "map": {"kind": "sine", "r": 0.95}, "iterations": 5},
                 {"upsample": 4, "jitter": 0.05, "kernel": gauss5, "map": {"kind": "circle", "omega": 0.1, "k": 1.0}, "iterations": 3},
                 {"upsample": 2, "jitter": 0.02, "kernel": {"size": 3, "preset": "gauss", "sigma": 0.8}, "map": {"kind": "logistic", "r": 3.6}, "iterations": 2}],
               "palette": "marble"}),
        Inputs::new(),
    ));
    out.push(bundle(
        "Cascade F — lichen terrain",
        json!({"seed": 16, "width": 1u64 << 20, "height": 1u64 << 20, "stages": [
                 {"kernel": gauss5, "map": {"kind": "logistic", "r": 3.7}, "iterations": 5},
                 {"upsample": 2, "jitter": 0.1, "kernel": gauss5, "map": {"kind": "logistic", "r": 3.7}, "iterations": 4},
                 {"upsample": 2, "jitter": 0.1, "kernel": gauss5, "map": {"kind": "logistic", "r": 3.7}, "iterations": 4},
                 {"upsample": 2, "jitter": 0.1, "kernel": gauss5, "map": {"kind": "logistic", "r": 3.7}, "iterations": 4},
                 {"upsample": 2, "jitter": 0.1, "kernel": gauss5, "map": {"kind": "logistic", "r": 3.7}, "iterations": 3}],
               "palette": "moss"}),
        Inputs::new(),
    ));
    out.push(bundle(
        "Cascade G — wood grain",
        json!({"seed": 17, "stages": [
                 {"kernel": gauss3, "map": {"kind": "sine", "r": 0.96}, "iterations": 5, "aspect": 4.0, "rotation": 8.0},
                 {"upsample": 4, "jitter": 0.08, "kernel": gauss3, "map": {"kind": "circle", "omega": 0.05, "k": 1.5}, "iterations": 4, "aspect": 3.0, "rotation": 8.0},
                 {"upsample": 2, "jitter": 0.03, "kernel": {"size": 3, "preset": "gauss", "sigma": 0.8}, "map": {"kind": "sine", "r": 0.9}, "iterations": 2, "aspect": 2.0, "rotation": 8.0}],
               "palette": [[0.0, "#3b2412"], [0.4, "#7a4a24"], [0.7, "#b07a45"], [1.0, "#e2b887"]]}),
        Inputs::new(),
    ));
    out.push(bundle(
        "Cascade H — fire clouds",
        json!({"seed": 18, "stages": [
                 {"kernel": gauss5, "map": {"kind": "logistic", "r": 3.6}, "iterations": 5, "dilation": 2.5},
                 {"upsample": 4, "jitter": 0.1, "kernel": gauss5, "map": {"kind": "tent", "mu": 1.6}, "iterations": 4},
                 {"upsample": 4, "jitter": 0.05, "kernel": {"size": 3, "preset": "gauss", "sigma": 0.8}, "map": {"kind": "sine", "r": 0.98}, "iterations": 3}],
               "palette": "fire"}),
        Inputs::new(),
    ));
    out
}

/// A 4096² single-stage look (demo A's) without input images.
pub fn example() -> crate::models::Example {
    crate::models::Example {
        params: json!({"seed": 1, "width": 4096, "height": 4096, "palette": "ocean",
                       "stages": [{"kernel": {"size": 5, "preset": "gauss", "sigma": 1.0},
                                   "map": {"kind": "logistic", "r": 3.9}, "iterations": 5}]}),
        inputs: Vec::new(),
    }
}
