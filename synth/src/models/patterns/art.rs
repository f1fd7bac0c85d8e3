//! The demos' patterns, all drawn here (no downloaded images): families of tiles with
//! universally matchable edges, transition tiles on a transparent background, leaves, LED
//! states and a 5 × 7 font. Run once when an encoding is made, never in the pixel path.

use crate::{hash, Rgba8Image};

/// Periodic value noise with period `period` cells of `cell` pixels: smooth, and equal on
/// opposite edges of a `period · cell` square, so tiles built on it match each other.
pub fn noise(seed: u64, x: f32, y: f32, cell: f32, period: i64) -> f32 {
    let (fx, fy) = (x / cell, y / cell);
    let (x0, y0) = (fx.floor(), fy.floor());
    let (tx, ty) = (fx - x0, fy - y0);
    let s = |t: f32| t * t * (3.0 - 2.0 * t);
    let v = |i: i64, j: i64| hash::unit_f32(hash::hash4(seed, 77, i.rem_euclid(period), j.rem_euclid(period)));
    let (i, j) = (x0 as i64, y0 as i64);
    let a = v(i, j) + (v(i + 1, j) - v(i, j)) * s(tx);
    let b = v(i, j + 1) + (v(i + 1, j + 1) - v(i, j + 1)) * s(tx);
    a + (b - a) * s(ty)
}

/// Fractal sum of periodic noise, in [0, 1], periodic over `size` pixels.
pub fn fbm(seed: u64, x: f32, y: f32, size: u32) -> f32 {
    let mut acc = 0.0;
    let mut amp = 0.5;
    let mut cell = size as f32 / 4.0;
    let mut period = 4;
    let mut total = 0.0;
    for o in 0..4 {
        acc += amp * noise(seed + o, x, y, cell, period);
        total += amp;
        amp *= 0.5;
        cell *= 0.5;
        period *= 2;
    }
    acc / total
}

fn mix(a: [f32; 3], b: [f32; 3], t: f32) -> [f32; 3] {
    [a[0] + (b[0] - a[0]) * t, a[1] + (b[1] - a[1]) * t, a[2] + (b[2] - a[2]) * t]
}

fn rgba(c: [f32; 3], a: f32) -> [u8; 4] {
    let q = |v: f32| (v.clamp(0.0, 1.0) * 255.0 + 0.5) as u8;
    [q(c[0]), q(c[1]), q(c[2]), q(a)]
}

/// 0 on a tile's border band, rising to 1 inside: variants only differ where it is > 0, so
/// every tile of a family shares the same edges.
fn interior(x: f32, y: f32, s: f32, band: f32) -> f32 {
    let d = x.min(y).min(s - 1.0 - x).min(s - 1.0 - y);
    ((d - band * 0.5) / band).clamp(0.0, 1.0)
}

#[derive(Clone, Copy)]
pub enum Family {
    /// Sand with pebbles.
    Ground,
    /// Grass with flowers.
    Grass,
    /// Sand with flowers: the ground's base, so its tiles match the ground's edges.
    Meadow,
}

impl Family {
    fn base(self, seed: u64, x: f32, y: f32, s: u32) -> [f32; 3] {
        let n = fbm(seed, x, y, s);
        let fine = noise(seed + 9, x, y, 2.0, s as i64 / 2);
        match self {
            Family::Ground | Family::Meadow => mix([0.55, 0.43, 0.28], [0.78, 0.66, 0.45], n * 0.8 + fine * 0.2),
            Family::Grass => mix([0.16, 0.36, 0.10], [0.40, 0.62, 0.18], n * 0.6 + fine * 0.4),
        }
    }

    /// Tile `variant` of the family: the shared base plus interior features of its own.
    pub fn tile(self, seed: u64, variant: u64, s: u32) -> Rgba8Image {
        let mut img = Rgba8Image::new(s, s);
        let sf = s as f32;
        let features: Vec<(f32, f32, f32, [f32; 3])> = (0..3 + variant % 4)
            .map(|k| {
                let h = |i: u64| hash::unit_f32(hash::hash4(seed, 500 + variant, k as i64, i as i64));
                let (cx, cy) = (sf * (0.18 + 0.64 * h(0)), sf * (0.18 + 0.64 * h(1)));
                let r = sf * (0.05 + 0.08 * h(2));
                let colour = match self {
                    Family::Ground => mix([0.35, 0.33, 0.32], [0.70, 0.62, 0.55], h(3)),
                    Family::Grass | Family::Meadow => {
                        [[0.95, 0.9, 0.2], [0.95, 0.95, 0.95], [0.85, 0.3, 0.6], [0.3, 0.5, 0.95]]
                            [(h(4) * 4.0) as usize % 4]
                    }
                };
                (cx, cy, r, colour)
            })
            .collect();
        for y in 0..s {
            for x in 0..s {
                let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
                let mut c = self.base(seed, fx, fy, s);
                let inside = interior(x as f32, y as f32, sf, sf / 16.0);
                let var = fbm(seed + 100 + variant, fx, fy, s);
                // Zero-mean variation, so the shared border band is not a visible grid.
                let k = 1.0 + (var - 0.5) * 0.35 * inside;
                c = [c[0] * k, c[1] * k, c[2] * k];
                for &(cx, cy, r, colour) in &features {
                    let d = ((fx - cx) * (fx - cx) + (fy - cy) * (fy - cy)).sqrt();
                    let cover = ((r - d) + 0.5).clamp(0.0, 1.0) * inside;
                    let shade = 1.0 - 0.35 * (d / r).min(1.0);
                    c = mix(c, [colour[0] * shade, colour[1] * shade, colour[2] * shade], cover);
                }
                img.set_pixel(x, y, rgba(c, 1.0));
            }
        }
        img
    }

    /// Transition tile: this family where the corners in `mask` (bit 0 top-left, 1
    /// top-right, 2 bottom-left, 3 bottom-right) pull it, transparent elsewhere. The boundary
    /// depends only on the two corners of each edge and a periodic noise, so it continues
    /// across cells into the neighbouring transition or plain tiles.
    pub fn transition(self, seed: u64, mask: u32, s: u32) -> Rgba8Image {
        let mut img = Rgba8Image::new(s, s);
        let sf = s as f32;
        let bit = |i: u32| ((mask >> i) & 1) as f32;
        for y in 0..s {
            for x in 0..s {
                let (fx, fy) = (x as f32 + 0.5, y as f32 + 0.5);
                let (u, v) = (fx / sf, fy / sf);
                let field =
                    bit(0) * (1.0 - u) * (1.0 - v) + bit(1) * u * (1.0 - v) + bit(2) * (1.0 - u) * v + bit(3) * u * v;
                let wobble = (fbm(seed + 300, fx, fy, s) - 0.5) * 0.45;
                let alpha = ((field + wobble - 0.5) * sf / 3.0 + 0.5).clamp(0.0, 1.0);
                img.set_pixel(x, y, rgba(self.base(seed, fx, fy, s), alpha));
            }
        }
        img
    }
}

/// A leaf on a transparent background, pointing up, 4 × 4 supersampled edges.
pub fn leaf(seed: u64, variant: u64, s: u32) -> Rgba8Image {
    let h = |i: i64| hash::unit_f32(hash::hash4(seed, 900 + variant, i, 0));
    let palette = [
        [0.85, 0.35, 0.08],
        [0.75, 0.12, 0.08],
        [0.92, 0.70, 0.15],
        [0.50, 0.30, 0.12],
        [0.45, 0.55, 0.15],
        [0.95, 0.50, 0.10],
    ];
    let base = palette[(h(0) * palette.len() as f32) as usize % palette.len()];
    let width = 0.35 + 0.25 * h(1);
    let lobes = (h(2) * 3.0) as i32;
    let mut img = Rgba8Image::new(s, s);
    let sf = s as f32;
    for y in 0..s {
        for x in 0..s {
            let (mut cover, mut vein) = (0.0f32, 0.0f32);
            for sy in 0..4 {
                for sx in 0..4 {
                    // Leaf axis t ∈ [-1, 1] from tip (top) to stem (bottom), n across.
                    let px = (x as f32 + (sx as f32 + 0.5) / 4.0) / sf * 2.0 - 1.0;
                    let py = (y as f32 + (sy as f32 + 0.5) / 4.0) / sf * 2.0 - 1.0;
                    let t = py / 0.8;
                    let n = px;
                    let mut half = width * (1.0 - t * t).max(0.0).sqrt();
                    if lobes > 0 {
                        half *= 1.0 + 0.18 * libm::cosf(t * (3 + 2 * lobes) as f32 * core::f32::consts::PI).abs();
                    }
                    let stem = t > 0.95 && t < 1.2 && n.abs() < 0.03;
                    if n.abs() < half || stem {
                        cover += 1.0 / 16.0;
                        let side = (n.abs() - (t + 1.0) * 0.35).abs();
                        if n.abs() < 0.025 || (side < 0.02 && n.abs() < half * 0.85) {
                            vein += 1.0 / 16.0;
                        }
                    }
                }
            }
            if cover > 0.0 {
                let n = fbm(seed + variant, x as f32, y as f32, s);
                let c = mix(base, [base[0] * 0.6, base[1] * 0.6, base[2] * 0.5], n * 0.7);
                let c = mix(c, [c[0] * 0.55, c[1] * 0.5, c[2] * 0.4], (vein / cover).min(1.0));
                img.set_pixel(x, y, rgba(c, cover));
            }
        }
    }
    img
}

/// The states of a red LED on a dark board: `level` 0 is off (the rest state), 1 full on.
pub fn led(level: f32, s: u32) -> Rgba8Image {
    let mut img = Rgba8Image::new(s, s);
    let c = (s as f32 - 1.0) / 2.0;
    for y in 0..s {
        for x in 0..s {
            let d = (((x as f32 - c) * (x as f32 - c) + (y as f32 - c) * (y as f32 - c)).sqrt()) / (s as f32 / 2.0);
            let board = [0.06, 0.06, 0.07];
            let lens = (1.0 - ((d - 0.62) * 12.0)).clamp(0.0, 1.0);
            let glow = level * (1.0 - d).max(0.0) * (1.0 - d).max(0.0) * 0.5;
            let core = [0.25 + 0.75 * level, 0.03 + 0.35 * level * (1.0 - d).max(0.0), 0.03];
            let mut col = mix(board, core, lens);
            col[0] += glow;
            col[1] += glow * 0.15;
            img.set_pixel(x, y, rgba(col, 1.0));
        }
    }
    img
}

/// A shaded blue ball on a transparent background (the targets of Fig. 21a).
pub fn ball(s: u32) -> Rgba8Image {
    let mut img = Rgba8Image::new(s, s);
    let (c, r) = (s as f32 / 2.0, s as f32 * 0.42);
    for y in 0..s {
        for x in 0..s {
            let (dx, dy) = ((x as f32 + 0.5 - c) / r, (y as f32 + 0.5 - c) / r);
            let d = (dx * dx + dy * dy).sqrt();
            let light = (1.0 - ((dx + 0.35) * (dx + 0.35) + (dy + 0.35) * (dy + 0.35)).sqrt() * 0.7).clamp(0.15, 1.0);
            let alpha = ((1.0 - d) * r + 0.5).clamp(0.0, 1.0);
            img.set_pixel(x, y, rgba([0.2 * light, 0.45 * light, 0.95 * light], alpha));
        }
    }
    img
}

/// 5 × 7 glyphs (rows top to bottom, bit 4 = left column) of the letters the demos use.
pub fn glyph(c: char) -> [u8; 7] {
    match c {
        'A' => [0x0E, 0x11, 0x11, 0x1F, 0x11, 0x11, 0x11],
        'B' => [0x1E, 0x11, 0x11, 0x1E, 0x11, 0x11, 0x1E],
        'D' => [0x1E, 0x11, 0x11, 0x11, 0x11, 0x11, 0x1E],
        'E' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x1F],
        'F' => [0x1F, 0x10, 0x10, 0x1E, 0x10, 0x10, 0x10],
        'I' => [0x0E, 0x04, 0x04, 0x04, 0x04, 0x04, 0x0E],
        'L' => [0x10, 0x10, 0x10, 0x10, 0x10, 0x10, 0x1F],
        'N' => [0x11, 0x19, 0x15, 0x13, 0x11, 0x11, 0x11],
        'P' => [0x1E, 0x11, 0x11, 0x1E, 0x10, 0x10, 0x10],
        'R' => [0x1E, 0x11, 0x11, 0x1E, 0x14, 0x12, 0x11],
        'S' => [0x0F, 0x10, 0x10, 0x0E, 0x01, 0x01, 0x1E],
        'T' => [0x1F, 0x04, 0x04, 0x04, 0x04, 0x04, 0x04],
        'U' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x11, 0x0E],
        'V' => [0x11, 0x11, 0x11, 0x11, 0x11, 0x0A, 0x04],
        'X' => [0x11, 0x11, 0x0A, 0x04, 0x0A, 0x11, 0x11],
        'Y' => [0x11, 0x11, 0x0A, 0x04, 0x04, 0x04, 0x04],
        '3' => [0x1E, 0x01, 0x01, 0x0E, 0x01, 0x01, 0x1E],
        '0' => [0x0E, 0x11, 0x13, 0x15, 0x19, 0x11, 0x0E],
        '2' => [0x0E, 0x11, 0x01, 0x06, 0x08, 0x10, 0x1F],
        _ => [0; 7],
    }
}

/// A `w × h` mask of `text` in the 5 × 7 font, each font pixel `scale` × `scale`, centred.
pub fn text_mask(text: &str, w: u32, h: u32, scale: u32) -> Vec<bool> {
    let mut mask = vec![false; (w * h) as usize];
    let chars: Vec<char> = text.chars().collect();
    let tw = chars.len() as u32 * 6 * scale - scale;
    let (x0, y0) = (w.saturating_sub(tw) / 2, h.saturating_sub(7 * scale) / 2);
    for (i, &c) in chars.iter().enumerate() {
        let g = glyph(c);
        for (row, bits) in g.iter().enumerate() {
            for col in 0..5 {
                if bits >> (4 - col) & 1 == 1 {
                    for dy in 0..scale {
                        for dx in 0..scale {
                            let x = x0 + (i as u32 * 6 + col) * scale + dx;
                            let y = y0 + row as u32 * scale + dy;
                            if x < w && y < h {
                                mask[(y * w + x) as usize] = true;
                            }
                        }
                    }
                }
            }
        }
    }
    mask
}

/// Packs equally sized patterns row-major into a `tx × ty` reference (missing ones transparent).
pub fn pack(patterns: &[Rgba8Image], tx: u32, ty: u32) -> Rgba8Image {
    let s = patterns[0].width;
    let mut out = Rgba8Image::new(tx * s, ty * s);
    for (i, p) in patterns.iter().enumerate() {
        out.blit(p, (i as u32 % tx) * s, (i as u32 / tx) * s);
    }
    out
}
