//! Project-made texture samples for demos and tests: generated from a seed, so no image from
//! elsewhere is ever committed. Only + − × ÷ and sqrt are used, so the bytes (and the ids of
//! the demo bundles made from them) are the same on every platform.

use crate::{hash, pixels::Rgba8Image};

/// Pebbles: Voronoi cells with per-cell earthy colours, darker mortar between them and a
/// little grain. With `wrap` the cells are laid on a torus and the sample tiles seamlessly.
pub fn pebbles(size: u32, cells: u32, seed: u64, wrap: bool) -> Rgba8Image {
    let s = size as f64;
    let centres: Vec<(f64, f64, [f64; 3])> = (0..cells as i64)
        .map(|i| {
            let h = |k| hash::unit_f64(hash::hash4(seed, k, i, 0));
            let shade = 0.55 + 0.45 * h(3);
            let warm = h(4);
            (
                h(1) * s,
                h(2) * s,
                [shade * (150.0 + 60.0 * warm), shade * (125.0 + 35.0 * warm), shade * (95.0 + 20.0 * h(5))],
            )
        })
        .collect();
    let mut img = Rgba8Image::new(size, size);
    for y in 0..size {
        for x in 0..size {
            let (px, py) = (x as f64 + 0.5, y as f64 + 0.5);
            let (mut d1, mut d2, mut best) = (f64::MAX, f64::MAX, (0usize, 0.0, 0.0));
            for (i, &(cx, cy, _)) in centres.iter().enumerate() {
                // Signed offset from the pixel to the centre, the short way round on a torus.
                let (mut dx, mut dy) = (cx - px, cy - py);
                if wrap {
                    dx -= s * (dx / s + 0.5).floor();
                    dy -= s * (dy / s + 0.5).floor();
                }
                let d = (dx * dx + dy * dy).sqrt();
                if d < d1 {
                    (d2, d1, best) = (d1, d, (i, dx, dy));
                } else if d < d2 {
                    d2 = d;
                }
            }
            // Distance to the cell border, and a rounded, lit-from-the-top-left stone.
            let edge = (d2 - d1) / 2.0;
            let mortar = (edge / 2.5).min(1.0);
            let dome = (edge / 6.0).min(1.0);
            let (i, dx, dy) = best;
            let base = centres[i].2;
            let lit = 1.0 + 0.18 * (dx + dy).clamp(-12.0, 12.0) / 12.0 * dome;
            let grain = 0.92 + 0.16 * hash::unit_f64(hash::hash4(seed, 9, x as i64, y as i64));
            let px = base.map(|c| {
                let stone = c * lit * grain;
                (stone * mortar + 58.0 * (1.0 - mortar)).clamp(0.0, 255.0) as u8
            });
            img.set_pixel(x, y, [px[0], px[1], px[2], 255]);
        }
    }
    img
}

/// Lichen: four octaves of periodic value noise through a grey-green-ochre gradient; tiles
/// seamlessly because every octave's lattice wraps at the sample size.
pub fn lichen(size: u32, seed: u64) -> Rgba8Image {
    let mut img = Rgba8Image::new(size, size);
    for y in 0..size {
        for x in 0..size {
            let mut v = 0.0;
            let mut amp = 0.5;
            for octave in 0..4u32 {
                let cells = 4u32 << octave;
                v += amp * value_noise(seed + octave as u64, x, y, size, cells);
                amp *= 0.5;
            }
            let t = (v / 0.9375).clamp(0.0, 1.0);
            let stops = [[70.0, 78.0, 60.0], [128.0, 140.0, 96.0], [186.0, 170.0, 110.0], [222.0, 214.0, 180.0]];
            let k = (t * 3.0).min(2.999);
            let (i, f) = (k as usize, k - (k as usize) as f64);
            let c: [f64; 3] = std::array::from_fn(|ch| stops[i][ch] * (1.0 - f) + stops[i + 1][ch] * f);
            img.set_pixel(x, y, [c[0] as u8, c[1] as u8, c[2] as u8, 255]);
        }
    }
    img
}

/// Smoothly interpolated lattice noise in [0, 1) with `cells` lattice cells across `size`
/// pixels, periodic with period `size`.
fn value_noise(seed: u64, x: u32, y: u32, size: u32, cells: u32) -> f64 {
    let (fx, fy) = (x as f64 * cells as f64 / size as f64, y as f64 * cells as f64 / size as f64);
    let (ix, iy) = (fx as u32, fy as u32);
    let (tx, ty) = (fx - ix as f64, fy - iy as f64);
    let smooth = |t: f64| t * t * (3.0 - 2.0 * t);
    let at = |i: u32, j: u32| hash::unit_f64(hash::hash4(seed, 17, (i % cells) as i64, (j % cells) as i64));
    let (sx, sy) = (smooth(tx), smooth(ty));
    let top = at(ix, iy) * (1.0 - sx) + at(ix + 1, iy) * sx;
    let bottom = at(ix, iy + 1) * (1.0 - sx) + at(ix + 1, iy + 1) * sx;
    top * (1.0 - sy) + bottom * sy
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::models::chaos_mosaic::is_seamless;

    #[test]
    fn samples_are_deterministic_and_seamless_as_asked() {
        assert_eq!(pebbles(64, 12, 3, true), pebbles(64, 12, 3, true));
        assert!(is_seamless(&pebbles(96, 14, 3, true)));
        assert!(!is_seamless(&pebbles(96, 14, 3, false)));
        assert!(is_seamless(&lichen(64, 5)));
    }
}
