//! The integer lattices the cascade acts on, their hashed initial noise, and low-resolution
//! images (dilation control map, structured initial image) sampled onto them.
//!
//! Coordinates are integers only: a lattice of spacing 2^k pixels has coordinates modulo
//! 2^(64−k) held in `u64` with wrapping arithmetic, so the "unbounded" plane is a torus of
//! 2^64 pixels on which every operation is exact — a tile at 2^40 costs and looks the same as
//! one at the origin, and nothing overflows near ±2^63.

use crate::hash::{hash4, unit_f32};
use crate::pixels::Rgba8Image;

/// A rectangular window of lattice values: (x0, y0) is its corner in lattice coordinates.
#[derive(Clone, Debug, PartialEq)]
pub struct Grid {
    pub x0: u64,
    pub y0: u64,
    pub w: usize,
    pub h: usize,
    pub v: Vec<f32>,
}

impl Grid {
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f32 {
        self.v[y * self.w + x]
    }
}

/// The mask of a lattice whose spacing is 2^`shift` pixels.
#[inline]
pub fn lattice_mask(shift: u32) -> u64 {
    u64::MAX >> shift
}

/// The signed representative of a coordinate of the lattice with spacing 2^`shift`:
/// lattice point −1 is −1 (not 2^(64−shift) − 1), so hashes near the origin are those of
/// the plain integer plane.
#[inline]
pub fn signed(c: u64, shift: u32) -> i64 {
    ((c << shift) as i64) >> shift
}

/// Uniform noise in [0, 1) at lattice point (x, y) of the lattice with spacing 2^`shift`.
#[inline]
pub fn noise(seed: u64, stream: u64, x: u64, y: u64, shift: u32) -> f32 {
    unit_f32(hash4(seed, stream, signed(x, shift), signed(y, shift)))
}

/// A grey image stretched over the plane at `cell` pixels per texel, sampled bilinearly
/// between texel centres with integer weights (exact on every platform).
#[derive(Clone, Debug, PartialEq)]
pub struct ImageField {
    pub w: u32,
    pub h: u32,
    /// Luminance per texel, row-major.
    pub lum: Vec<u8>,
    pub cell: u64,
    /// Periodic over the plane; otherwise the image covers [0, w·cell) × [0, h·cell) only.
    pub repeat: bool,
}

impl ImageField {
    pub fn from_image(img: &Rgba8Image, cell: u64, repeat: bool) -> Self {
        let lum = img
            .data
            .chunks_exact(4)
            .map(|p| ((p[0] as u32 * 77 + p[1] as u32 * 150 + p[2] as u32 * 29 + 128) >> 8) as u8)
            .collect();
        Self { w: img.width, h: img.height, lum, cell, repeat }
    }

    /// Texel pair and the right one's weight in units of 1/(2·cell) along one axis at pixel `p`.
    #[inline]
    fn axis(&self, p: i64, n: u32) -> Option<(usize, usize, i64)> {
        let cell = self.cell as i64;
        let c = p.div_euclid(cell);
        let pos2 = 2 * p.rem_euclid(cell) + 1 - cell;
        let (left, t2) = if pos2 < 0 { (c.wrapping_sub(1), pos2 + 2 * cell) } else { (c, pos2) };
        let n = n as i64;
        if self.repeat {
            Some((left.rem_euclid(n) as usize, left.wrapping_add(1).rem_euclid(n) as usize, t2))
        } else if (0..n).contains(&c) {
            Some((left.clamp(0, n - 1) as usize, (left.wrapping_add(1)).clamp(0, n - 1) as usize, t2))
        } else {
            None
        }
    }

    /// The image value in [0, 1] at pixel (px, py), or `None` outside a non-repeating image.
    /// Always inlined: the guided coarse levels take thousands of samples a pixel.
    #[inline(always)]
    pub fn sample(&self, px: i64, py: i64) -> Option<f64> {
        let (x0, x1, tx) = self.axis(px, self.w)?;
        let (y0, y1, ty) = self.axis(py, self.h)?;
        let s = 2 * self.cell as i64;
        let at = |x: usize, y: usize| self.lum[y * self.w as usize + x] as i64;
        let row = |y: usize| at(x0, y) * (s - tx) + at(x1, y) * tx;
        let v = row(y0) * (s - ty) + row(y1) * ty;
        Some(v as f64 / (255.0 * (s * s) as f64))
    }
}

/// Bilinear upsampling by 2^`k` of `coarse` onto the fine window of `w × h` points at
/// (x0, y0) in the fine lattice. Fine point X sits between coarse points X >> k and
/// (X >> k) + 1 at fraction (X mod 2^k) / 2^k (exact in f32). `coarse` must start at
/// (x0 >> k, y0 >> k) and cover [`upsample_footprint`].
pub fn upsample(coarse: &Grid, k: u32, x0: u64, y0: u64, w: usize, h: usize) -> Vec<f32> {
    let f = 1u64 << k;
    let inv = 1.0 / f as f32;
    let (tx0, ty0) = ((x0 & (f - 1)) as usize, (y0 & (f - 1)) as usize);
    let cols: Vec<(usize, f32)> = (0..w).map(|i| ((tx0 + i) >> k, ((tx0 + i) as u64 & (f - 1)) as f32 * inv)).collect();
    let mut out = Vec::with_capacity(w * h);
    for j in 0..h {
        let cy = (ty0 + j) >> k;
        let fy = ((ty0 + j) as u64 & (f - 1)) as f32 * inv;
        let (r0, r1) =
            (&coarse.v[cy * coarse.w..(cy + 1) * coarse.w], &coarse.v[(cy + 1) * coarse.w..(cy + 2) * coarse.w]);
        for &(cx, fx) in &cols {
            let a = r0[cx] + (r0[cx + 1] - r0[cx]) * fx;
            let b = r1[cx] + (r1[cx + 1] - r1[cx]) * fx;
            out.push(a + (b - a) * fy);
        }
    }
    out
}

/// Number of coarse points (per axis) that upsampling `n` fine points starting at `x0` reads.
#[inline]
pub fn upsample_footprint(x0: u64, n: usize, k: u32) -> usize {
    ((((x0 & ((1u64 << k) - 1)) as usize) + n - 1) >> k) + 2
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn image_field_interpolates_between_centres() {
        let img = Rgba8Image::from_raw(2, 1, vec![0, 0, 0, 255, 255, 255, 255, 255]).unwrap();
        let f = ImageField::from_image(&img, 4, false);
        // Texel centres at pixels 1.5 and 5.5: pixel 1 is 1/8 of the way past centre 0 towards… clamped.
        assert_eq!(f.sample(0, 0), Some(0.0));
        assert_eq!(f.sample(7, 0), Some(1.0));
        let mid = f.sample(3, 0).unwrap();
        assert!((mid - 0.375).abs() < 1e-12, "{mid}");
        assert_eq!(f.sample(8, 0), None);
        assert_eq!(f.sample(-1, 0), None);
        let r = ImageField { repeat: true, ..f };
        assert_eq!(r.sample(8, 0), r.sample(0, 0));
        assert_eq!(r.sample(-8 * 1_000_000_007, 0), r.sample(0, 0));
        assert!(r.sample(i64::MIN, i64::MAX).is_some());
    }

    #[test]
    fn upsampling_hits_coarse_points_exactly() {
        let coarse = Grid { x0: 0, y0: 0, w: 3, h: 3, v: (0..9).map(|i| i as f32).collect() };
        let fine = upsample(&coarse, 1, 0, 0, 4, 4);
        assert_eq!(fine[0], 0.0);
        assert_eq!(fine[2], 1.0);
        assert_eq!(fine[1], 0.5);
        assert_eq!(fine[2 * 4 + 2], 4.0);
        assert_eq!(upsample_footprint(0, 4, 1), 3);
        assert_eq!(upsample_footprint(1, 4, 1), 4);
        // Wrapping coordinates: the fraction only depends on the low bits.
        let far = upsample(&coarse, 1, u64::MAX - 1, 0, 2, 1);
        assert_eq!(far, vec![0.0, 0.5]);
    }
}
