//! Seam ratio: are the places where a model joins copies of its sample visible?
//!
//! A join between two pixels that are not neighbours in the sample shows as a step in the
//! image, so the gradient is stronger on joins than elsewhere. The model knows where its joins
//! are (block and tile edges); it passes them in as a [`Mask`] or a predicate.

use crate::luma::luma;
use vtex_synth::{Error, Result, Rgba8Image};

/// Seam ratio of `img`: mean luminance gradient magnitude on the pixels where `is_boundary`
/// holds, over the mean on all other pixels.
///
/// Exact definition: on the luma plane L ([`crate::luma::luma`]), the gradient magnitude at an
/// interior pixel (1 ≤ x ≤ W−2, 1 ≤ y ≤ H−2) is
/// |∇L| = √( ((L(x+1,y) − L(x−1,y)) / 2)² + ((L(x,y+1) − L(x,y−1)) / 2)² ),
/// central differences, so a step between columns x−1 and x shows on both pixels beside it
/// — mark both (as [`Mask::join`] does). The 1-pixel image border is left out of both means.
///
/// 1 means the joins cannot be told from the rest of the texture; a hard seam gives ≫ 1.
/// When both means are 0 (a flat image) the ratio is 1; when only the second is, +∞.
/// Errors: an image smaller than 3 × 3, or no interior pixel in one of the two sets.
pub fn seam_ratio(img: &Rgba8Image, is_boundary: impl Fn(u32, u32) -> bool) -> Result<f64> {
    if img.width < 3 || img.height < 3 {
        return Err(Error::image("output", format!("{}×{} is too small for gradients", img.width, img.height)));
    }
    let l = luma(img);
    let (mut on, mut n_on, mut off, mut n_off) = (0.0, 0u64, 0.0, 0u64);
    for y in 1..l.height - 1 {
        for x in 1..l.width - 1 {
            let gx = (l.at(x + 1, y) - l.at(x - 1, y)) / 2.0;
            let gy = (l.at(x, y + 1) - l.at(x, y - 1)) / 2.0;
            let g = (gx * gx + gy * gy).sqrt();
            if is_boundary(x as u32, y as u32) {
                on += g;
                n_on += 1;
            } else {
                off += g;
                n_off += 1;
            }
        }
    }
    if n_on == 0 || n_off == 0 {
        return Err(Error::param(
            "boundary",
            format!("{n_on} interior boundary pixels and {n_off} others; both must be non-empty"),
        ));
    }
    let (on, off) = (on / n_on as f64, off / n_off as f64);
    Ok(match (on == 0.0, off == 0.0) {
        (true, true) => 1.0,
        (false, true) => f64::INFINITY,
        _ => on / off,
    })
}

/// A set of pixels of a `width × height` image, typically the joins of a synthesized texture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Mask {
    pub width: u32,
    pub height: u32,
    bits: Vec<bool>,
}

impl Mask {
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, bits: vec![false; width as usize * height as usize] }
    }

    /// Wraps row-major flags, e.g. a model's own seam mask; `bits` must hold `width × height`.
    pub fn from_bits(width: u32, height: u32, bits: Vec<bool>) -> Result<Self> {
        if bits.len() != width as usize * height as usize {
            return Err(Error::param("mask", format!("{} flags for {width}×{height} pixels", bits.len())));
        }
        Ok(Self { width, height, bits })
    }

    #[inline]
    pub fn get(&self, x: u32, y: u32) -> bool {
        self.bits[y as usize * self.width as usize + x as usize]
    }

    #[inline]
    pub fn set(&mut self, x: u32, y: u32) {
        self.bits[y as usize * self.width as usize + x as usize] = true;
    }

    pub fn count(&self) -> usize {
        self.bits.iter().filter(|&&b| b).count()
    }

    /// Marks a join between two 4-neighbours: both pixels, as [`seam_ratio`] expects.
    pub fn join(&mut self, a: (u32, u32), b: (u32, u32)) {
        self.set(a.0, a.1);
        self.set(b.0, b.1);
    }

    /// The joins of a grid of `cell_w × cell_h` cells with a corner at (`offset_x`, `offset_y`):
    /// the plain tiling's tile edges. Both pixels beside each grid line inside the image.
    pub fn grid(width: u32, height: u32, cell_w: u32, cell_h: u32, offset_x: u32, offset_y: u32) -> Self {
        let cell = |v: u32, size: u32, off: u32| (v as i64 - off as i64).rem_euclid(size as i64) as u32;
        Mask::from_sources(width, height, |x, y| (cell(x, cell_w, offset_x), cell(y, cell_h, offset_y)))
    }

    /// The joins of an image whose pixel (x, y) was copied from sample pixel `source(x, y)`:
    /// every pair of 4-neighbours whose sources are not the same neighbours in the sample
    /// (source of the right/lower pixel ≠ source of the left/upper one + (1, 0) / (0, 1)).
    /// The sample does not wrap: a copy that crosses its edge is a join too, since the two
    /// sides were not neighbours in the sample (pass sources reduced modulo the sample size).
    /// This defines seams for any example-based model without knowing how it pastes.
    pub fn from_sources(width: u32, height: u32, source: impl Fn(u32, u32) -> (u32, u32)) -> Self {
        let mut m = Mask::new(width, height);
        for y in 0..height {
            for x in 0..width {
                let s = source(x, y);
                if x + 1 < width && source(x + 1, y) != (s.0.wrapping_add(1), s.1) {
                    m.join((x, y), (x + 1, y));
                }
                if y + 1 < height && source(x, y + 1) != (s.0, s.1.wrapping_add(1)) {
                    m.join((x, y), (x, y + 1));
                }
            }
        }
        m
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::{grey, noise};
    use vtex_synth::hash;

    /// Smooth content whose 16 × 16 cells are brightened by random offsets: steps on the grid.
    fn stepped_cells(w: u32, h: u32) -> Rgba8Image {
        grey(w, h, |x, y| {
            let (cx, cy) = ((x / 16.0).floor() as i64, (y / 16.0).floor() as i64);
            let o = hash::below(hash::hash4(9, 0, cx, cy), 80) as f64 - 40.0;
            128.0 + 20.0 * (x * 0.1).sin() * (y * 0.07).cos() + o
        })
    }

    #[test]
    fn real_discontinuities_give_a_high_ratio() {
        let img = stepped_cells(128, 128);
        let m = Mask::grid(128, 128, 16, 16, 0, 0);
        let r = seam_ratio(&img, |x, y| m.get(x, y)).unwrap();
        assert!(r > 4.0, "{r}");
    }

    #[test]
    fn smooth_and_random_images_score_one() {
        let smooth = grey(128, 128, |x, y| 128.0 + 50.0 * (x * 0.2).sin() * (y * 0.15).cos() + 0.2 * x);
        let m = Mask::grid(128, 128, 16, 16, 0, 0);
        let r = seam_ratio(&smooth, |x, y| m.get(x, y)).unwrap();
        assert!((r - 1.0).abs() < 0.15, "{r}");
        let r = seam_ratio(&noise(128, 128, 1), |x, y| m.get(x, y)).unwrap();
        assert!((r - 1.0).abs() < 0.05, "{r}");
    }

    #[test]
    fn flat_and_degenerate_cases() {
        let flat = grey(10, 10, |_, _| 7.0);
        assert_eq!(seam_ratio(&flat, |x, _| x == 4).unwrap(), 1.0);
        // A single step on column boundary 4|5 of an otherwise flat image.
        let step = grey(10, 10, |x, _| if x < 5.0 { 10.0 } else { 50.0 });
        assert_eq!(seam_ratio(&step, |x, _| x == 4 || x == 5).unwrap(), f64::INFINITY);
        assert!(seam_ratio(&step, |_, _| true).is_err());
        assert!(seam_ratio(&step, |_, _| false).is_err());
        assert!(seam_ratio(&grey(2, 9, |_, _| 0.0), |_, _| false).is_err());
    }

    #[test]
    fn from_bits_checks_the_size() {
        assert!(Mask::from_bits(3, 2, vec![false; 5]).is_err());
        let m = Mask::from_bits(3, 2, vec![false, true, false, false, false, true]).unwrap();
        assert!(m.get(1, 0) && m.get(2, 1) && !m.get(0, 0));
        assert_eq!(m.count(), 2);
    }

    #[test]
    fn grid_marks_both_sides_of_each_line() {
        // Lines at x = 1, 5, 9 (offset 1, cell 4); the image border is not a join.
        let m = Mask::grid(12, 1, 4, 100, 1, 50);
        let cols: Vec<u32> = (0..12).filter(|&x| m.get(x, 0)).collect();
        assert_eq!(cols, vec![0, 1, 4, 5, 8, 9]);
        let m = Mask::grid(12, 1, 4, 100, 0, 0);
        let cols: Vec<u32> = (0..12).filter(|&x| m.get(x, 0)).collect();
        assert_eq!(cols, vec![3, 4, 7, 8]);
    }

    #[test]
    fn sources_of_a_tiling_give_the_grid() {
        // A tiling copies (x mod 8, y mod 8): its joins are exactly the tile edges.
        let m = Mask::from_sources(32, 24, |x, y| (x % 8, y % 8));
        assert_eq!(m, Mask::grid(32, 24, 8, 8, 0, 0));
        // An unbroken copy has no joins; a pasted block has joins along its visible edges.
        assert_eq!(Mask::from_sources(16, 16, |x, y| (x + 3, y + 5)).count(), 0);
        let block = |x: u32, y: u32| if (4..8).contains(&x) && (4..8).contains(&y) { (x + 20, y) } else { (x, y) };
        let m = Mask::from_sources(12, 12, block);
        // The block's 12 rim pixels and the 16 pixels beside its edges (not the corners).
        assert_eq!(m.count(), 12 + 16);
        assert!(m.get(3, 5) && m.get(4, 5) && m.get(8, 7) && !m.get(5, 5) && !m.get(2, 5));
    }
}
