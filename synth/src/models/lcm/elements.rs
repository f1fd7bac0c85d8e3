//! Base elements made by the project, in code (the paper's were drawn "in a minute by means
//! of a simple graphic editor"). Transcendental functions come from `libm` so that every
//! build makes the same bytes, and hence the same bundle ids.

use super::element::Plane;
use crate::hash;

fn plane(k: u32, f: impl Fn(f64, f64) -> f64) -> Plane {
    let s = 1usize << k;
    let pixels =
        (0..s * s).map(|i| libm::floor(f((i % s) as f64 + 0.5, (i / s) as f64 + 0.5) + 0.5).clamp(-128.0, 127.0) as i8);
    Plane { k, pixels: pixels.collect() }
}

/// Smooth step from 0 (at d ≥ 1) to 1 (at d ≤ −1): a one-pixel anti-aliased edge.
fn edge(d: f64) -> f64 {
    ((1.0 - d) / 2.0).clamp(0.0, 1.0)
}

/// The "random rotation" element (§3, Tab. 1): a tapered circular stroke, pre-processed as
/// the paper says — summed with its mirrored and inverted copy — so that its mean is exactly
/// 0. It stays inside the square, so replications end smoothly.
pub fn stroke(k: u32) -> Plane {
    let s = (1u32 << k) as f64;
    let arc = |x: f64, y: f64| {
        // An arc of radius 0.27 s from −25° to 155° around (0.44 s, 0.56 s), thickest midway.
        let (dx, dy) = (x / s - 0.44, 0.56 - y / s);
        let r = libm::sqrt(dx * dx + dy * dy);
        let a = libm::atan2(dy, dx) * 180.0 / core::f64::consts::PI;
        let along = (a + 25.0) / 180.0;
        if !(0.0..=1.0).contains(&along) {
            return 0.0;
        }
        let width = 0.09 * libm::sin(core::f64::consts::PI * along);
        let t = (r - 0.27) / width.max(1e-9);
        if t.abs() >= 1.0 {
            0.0
        } else {
            let bump = 1.0 - t * t;
            110.0 * bump * bump
        }
    };
    // Quantize first, then subtract the mirror image, so the sum is exactly zero.
    let q = plane(k, arc);
    let n = 1usize << k;
    let pixels = (0..n * n).map(|i| q.pixels[i] - q.pixels[i / n * n + n - 1 - i % n]).collect();
    Plane { k, pixels }
}

/// The "cheese" hole (§3, Fig. 2): an irregular rounded hole, dark and deepest near its
/// middle, with a thin bright rim on one side; zero (transparent) outside.
pub fn hole(k: u32) -> Plane {
    let s = (1u32 << k) as f64;
    plane(k, |x, y| {
        let (dx, dy) = ((x - s * 0.5) / (s * 0.5), (y - s * 0.52) / (s * 0.5));
        let r = libm::sqrt(dx * dx + dy * dy);
        let a = libm::atan2(dy, dx);
        let radius = 0.74 * (1.0 + 0.12 * libm::cos(2.0 * a + 0.7) + 0.06 * libm::cos(3.0 * a - 1.1));
        // Signed distance to the outline in pixels.
        let d = (r - radius) * s * 0.5;
        let inside = edge(d);
        let depth = (1.0 - (r / radius).min(1.0)).max(0.0);
        let shadow = -70.0 - 45.0 * libm::sqrt(depth) + 25.0 * dy.max(0.0);
        // The rim: lit lip along the lower edge, just outside the hole.
        let rim = (1.0 - (d - 1.2).abs() / 1.2).max(0.0) * (dy * 2.0).clamp(0.0, 1.0) * 40.0;
        inside * shadow + (1.0 - inside) * rim
    })
}

/// The "brick wall" element (§3, Fig. 3): "half a brick". Tab. 3 replicates at every other
/// point of a row, staggered from row to row, so a row's elements abut and the next row, half
/// an element lower and shifted by half an element, paints over their lower halves: what shows
/// of each element is its upper half, one course high. That upper half is the left half of a
/// brick (mortar along its top and left edge); the lower half is the right half (mortar along
/// its top) turned 180°, so that an element turned 180° shows it. Points alternating 0° / 180°
/// lay a regular wall of bricks two elements long, and any other orientation breaks the bond.
/// Bricks are positive, mortar negative, nothing transparent.
pub fn brick(k: u32) -> Plane {
    let s = 1usize << k;
    let h = s / 2;
    let mortar = (s / 32).max(1);
    // Pixel (x, y) of the left (`right` false) or right half of a brick s wide, h tall.
    let half = |x: usize, y: usize, right: bool| -> f64 {
        let seed = (x + right as usize * s) as i64;
        if y < mortar || (!right && x < mortar) {
            return -62.0 + (hash::below(hash::hash4(5, 1, seed, y as i64), 9) as f64 - 4.0);
        }
        let grain = hash::below(hash::hash4(5, 3, seed, y as i64), 11) as f64 - 5.0;
        // A touch of darkening towards the brick's lower edge.
        50.0 + grain - 6.0 * (y as f64 / h as f64)
    };
    let mut pixels = vec![0i8; s * s];
    for y in 0..s {
        for x in 0..s {
            let v = if y < h { half(x, y, false) } else { half(s - 1 - x, s - 1 - y, true) };
            pixels[y * s + x] = libm::floor(v + 0.5).clamp(-128.0, 127.0) as i8;
        }
    }
    Plane { k, pixels }
}

/// A pebble for the colour demo: one plane per RGB channel, each the offset of a lit stone
/// colour from the sand `background`. Oval, slightly lopsided (so rotation and mirroring show),
/// domed shading; zero outside.
pub fn pebble(k: u32, stone: [f64; 3], background: [f64; 3]) -> [Plane; 3] {
    let s = (1u32 << k) as f64;
    std::array::from_fn(|c| {
        plane(k, |x, y| {
            let (dx, dy) = ((x - s * 0.5) / (s * 0.40), (y - s * 0.5) / (s * 0.29));
            let a = libm::atan2(dy, dx);
            let r = libm::sqrt(dx * dx + dy * dy);
            let radius = 1.0 + 0.08 * libm::cos(a + 0.4) + 0.05 * libm::cos(3.0 * a);
            let d = (r - radius) * s * 0.29;
            let inside = edge(d);
            let z = libm::sqrt((1.0 - (r / radius) * (r / radius)).max(0.0));
            // Light from the upper left, a darker rim.
            let light = 0.55 + 0.35 * z + 0.18 * (-dx * 0.5 - dy * 0.7).clamp(-1.0, 1.0);
            let speck = hash::below(hash::hash4(9, c as u64, x as i64, y as i64), 7) as f64 - 3.0;
            inside * (stone[c] * light + speck - background[c])
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn stroke_has_zero_mean_and_both_signs() {
        let p = stroke(6);
        assert_eq!(p.sum(), 0, "pre-processed element must have mean 0");
        assert!(p.pixels.iter().any(|&v| v > 50) && p.pixels.iter().any(|&v| v < -50));
    }

    #[test]
    fn hole_is_transparent_around_and_dark_inside() {
        let p = hole(6);
        assert_eq!(p.pixels[0], 0);
        assert_eq!(p.pixels[63], 0);
        assert!(p.pixels[32 * 64 + 32] < -60);
    }

    #[test]
    fn brick_is_opaque() {
        let p = brick(5);
        assert!(p.pixels.iter().all(|&v| v != 0), "non-zero application needs an opaque element");
    }
}
