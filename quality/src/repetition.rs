//! Long-range repetition: how strongly an output repeats itself at distances beyond the
//! sample size — the periodic "wallpaper" look a plain tiling has and a good synthesis avoids.

use crate::luma::{luma, mean_sd};
use rustfft::{num_complex::Complex64, FftPlanner};
use vtex_synth::{Error, Result, Rgba8Image};

/// The strongest long-range repetition found, and at which lag.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Repetition {
    /// Normalised autocorrelation at the lag; 1 means a perfect copy, 0 no linear relation.
    pub value: f64,
    pub dx: i64,
    pub dy: i64,
}

/// Long-range repetition of `img`: the maximum normalised autocorrelation of its luminance
/// ([`crate::luma::luma`]) over the lags (dx, dy) with |dx| ≥ `exclude_w` or |dy| ≥ `exclude_h`
/// (pass the sample's size: shorter lags are the texture's own structure, not repetition),
/// and |dx| ≤ ⌊W/2⌋, |dy| ≤ ⌊H/2⌋; r is defined in [`Autocorrelation`].
///
/// A plain tiling of a sample whose size divides the image has r = 1 at the sample period;
/// white noise stays near 0. Errors: no lag outside the exclusion fits in half the image, or
/// the luminance is constant (σ = 0, correlation undefined).
pub fn repetition(img: &Rgba8Image, exclude_w: u32, exclude_h: u32) -> Result<Repetition> {
    Autocorrelation::new(img)?.max_outside(exclude_w, exclude_h)
}

/// The normalised autocorrelation of an image's luminance at every lag up to half its size.
///
/// Exact definition, with L the luma plane, f = L − mean(L) over the whole W × H image and
/// σ² = mean(f²):
///
/// r(dx, dy) = [ Σ f(x, y) · f(x + dx, y + dy) / n(dx, dy) ] / σ²,
///
/// summed over the n(dx, dy) = (W − |dx|)(H − |dy|) positions where both pixels lie inside the
/// image — zero-padded, not circular, so the image need not be periodic, and divided by the
/// overlap count so that long lags are not biased towards 0. Lags stop at |dx| ≤ ⌊W/2⌋,
/// |dy| ≤ ⌊H/2⌋ so that every estimate averages at least a quarter of the image. Computed with
/// a 2-D FFT (rustfft) of the plane zero-padded to (W + ⌊W/2⌋) × (H + ⌊H/2⌋), which holds every
/// such lag without circular aliasing. The image is used as given: a window of a larger
/// texture works. r(0, 0) = 1 and r(d) = r(−d).
pub struct Autocorrelation {
    w: usize,
    h: usize,
    pw: usize,
    ph: usize,
    /// r at lag (dx, dy), stored at ((dy mod ph) · pw + (dx mod pw)).
    r: Vec<f64>,
}

impl Autocorrelation {
    /// Errors: constant luminance (σ = 0), including an image without pixels.
    pub fn new(img: &Rgba8Image) -> Result<Self> {
        let (w, h) = (img.width as usize, img.height as usize);
        let plane = luma(img);
        let (mean, sd) = mean_sd(&plane.data);
        if sd == 0.0 {
            return Err(Error::image("output", "constant luminance: autocorrelation is undefined"));
        }
        let (pw, ph) = (w + w / 2, h + h / 2);
        let mut buf = vec![Complex64::new(0.0, 0.0); pw * ph];
        for y in 0..h {
            for x in 0..w {
                buf[y * pw + x].re = plane.at(x, y) - mean;
            }
        }
        let mut planner = FftPlanner::<f64>::new();
        // Forward: rows, then columns (by transposing); the power spectrum is left transposed,
        // which is harmless since the inverse undoes the two passes in the opposite order.
        planner.plan_fft_forward(pw).process(&mut buf);
        let mut t = transpose(&buf, pw, ph);
        planner.plan_fft_forward(ph).process(&mut t);
        for v in t.iter_mut() {
            *v = Complex64::new(v.norm_sqr(), 0.0);
        }
        planner.plan_fft_inverse(ph).process(&mut t);
        let mut corr = transpose(&t, ph, pw);
        drop(t);
        planner.plan_fft_inverse(pw).process(&mut corr);
        // rustfft does not normalise: forward then inverse multiplies by pw · ph.
        let scale = 1.0 / (pw as f64 * ph as f64 * sd * sd);
        let r = corr.iter().map(|c| c.re * scale).collect();
        let mut out = Self { w, h, pw, ph, r };
        // Divide each lag in range by its overlap count.
        for dy in -((h / 2) as i64)..=(h / 2) as i64 {
            for dx in -((w / 2) as i64)..=(w / 2) as i64 {
                let overlap = (w - dx.unsigned_abs() as usize) as f64 * (h - dy.unsigned_abs() as usize) as f64;
                let i = out.index(dx, dy);
                out.r[i] /= overlap;
            }
        }
        Ok(out)
    }

    fn index(&self, dx: i64, dy: i64) -> usize {
        dy.rem_euclid(self.ph as i64) as usize * self.pw + dx.rem_euclid(self.pw as i64) as usize
    }

    /// r(dx, dy), or `None` beyond half the image.
    pub fn at(&self, dx: i64, dy: i64) -> Option<f64> {
        let inside = dx.unsigned_abs() as usize <= self.w / 2 && dy.unsigned_abs() as usize <= self.h / 2;
        inside.then(|| self.r[self.index(dx, dy)])
    }

    /// The largest r over the lags with |dx| ≥ `exclude_w` or |dy| ≥ `exclude_h`; see
    /// [`repetition`]. Ties go to the first in scan order (dy ascending from 0, then dx from
    /// −⌊W/2⌋); only dy ≥ 0 is scanned since r(d) = r(−d).
    pub fn max_outside(&self, exclude_w: u32, exclude_h: u32) -> Result<Repetition> {
        let (max_dx, max_dy) = (self.w / 2, self.h / 2);
        if exclude_w as usize > max_dx && exclude_h as usize > max_dy {
            return Err(Error::param(
                "exclude",
                format!(
                    "{exclude_w}×{exclude_h} excludes every lag of a {}×{} image; lags go up to half the image",
                    self.w, self.h
                ),
            ));
        }
        let mut best = Repetition { value: f64::NEG_INFINITY, dx: 0, dy: 0 };
        for dy in 0..=max_dy as i64 {
            for dx in -(max_dx as i64)..=max_dx as i64 {
                if dx.unsigned_abs() < exclude_w as u64 && dy.unsigned_abs() < exclude_h as u64 {
                    continue;
                }
                let r = self.r[self.index(dx, dy)];
                if r > best.value {
                    best = Repetition { value: r, dx, dy };
                }
            }
        }
        Ok(best)
    }
}

/// `src` is `rows` rows of `cols`; the result is `cols` rows of `rows`.
fn transpose(src: &[Complex64], cols: usize, rows: usize) -> Vec<Complex64> {
    let mut out = vec![Complex64::new(0.0, 0.0); src.len()];
    for r in 0..rows {
        for c in 0..cols {
            out[c * rows + r] = src[r * cols + c];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::{grey, noise, tiled};

    /// The definition evaluated directly, for checking the FFT path.
    fn direct(img: &Rgba8Image, dx: i64, dy: i64) -> f64 {
        let p = luma(img);
        let (mean, sd) = mean_sd(&p.data);
        let (w, h) = (p.width as i64, p.height as i64);
        let mut acc = 0.0;
        let mut n = 0.0;
        for y in 0..h {
            for x in 0..w {
                let (x2, y2) = (x + dx, y + dy);
                if (0..w).contains(&x2) && (0..h).contains(&y2) {
                    acc += (p.at(x as usize, y as usize) - mean) * (p.at(x2 as usize, y2 as usize) - mean);
                    n += 1.0;
                }
            }
        }
        acc / n / (sd * sd)
    }

    #[test]
    fn plain_tiling_repeats_perfectly() {
        let img = tiled(&noise(32, 32, 1), 256, 128);
        let r = repetition(&img, 32, 32).unwrap();
        assert!((r.value - 1.0).abs() < 1e-9, "{r:?}");
        assert_eq!((r.dx.rem_euclid(32), r.dy.rem_euclid(32)), (0, 0), "{r:?}");
    }

    #[test]
    fn non_square_tiles_and_wider_exclusion() {
        // Period 24 × 40; excluding lags below 30 × 50 still finds a period multiple.
        let img = tiled(&noise(24, 40, 2), 240, 200);
        let r = repetition(&img, 30, 50).unwrap();
        assert!((r.value - 1.0).abs() < 1e-9, "{r:?}");
        assert!(r.dx.abs() >= 30 || r.dy.abs() >= 50, "{r:?}");
        assert_eq!((r.dx.rem_euclid(24), r.dy.rem_euclid(40)), (0, 0), "{r:?}");
    }

    #[test]
    fn white_noise_does_not_repeat() {
        let r = repetition(&noise(256, 256, 3), 32, 32).unwrap();
        assert!(r.value.abs() < 0.05, "{r:?}");
    }

    #[test]
    fn fft_matches_the_definition() {
        // Smooth, non-periodic content with a partial copy: compare several lags one by one by
        // checking the maximum against a direct search over a small image.
        let mut img = grey(40, 30, |x, y| 128.0 + 60.0 * ((x * 0.37).sin() + (y * 0.21 + x * 0.05).cos()) / 2.0);
        let patch = noise(10, 10, 4);
        img.blit(&patch, 2, 3);
        img.blit(&patch, 25, 14);
        let r = repetition(&img, 8, 8).unwrap();
        let mut best = (f64::NEG_INFINITY, 0, 0);
        for dy in 0..=15i64 {
            for dx in -20..=20i64 {
                if dx.abs() < 8 && dy.abs() < 8 {
                    continue;
                }
                let v = direct(&img, dx, dy);
                if v > best.0 {
                    best = (v, dx, dy);
                }
            }
        }
        assert!((r.value - best.0).abs() < 1e-9, "{r:?} vs {best:?}");
        assert_eq!((r.dx, r.dy), (best.1, best.2));
    }

    #[test]
    fn lags_are_symmetric_and_bounded() {
        let img = noise(30, 20, 6);
        let a = Autocorrelation::new(&img).unwrap();
        assert!((a.at(0, 0).unwrap() - 1.0).abs() < 1e-12);
        for (dx, dy) in [(3, 2), (-15, 10), (7, -4), (15, -10)] {
            let (p, q) = (a.at(dx, dy).unwrap(), a.at(-dx, -dy).unwrap());
            assert!((p - q).abs() < 1e-12 && (p - direct(&img, dx, dy)).abs() < 1e-9, "({dx}, {dy})");
        }
        assert_eq!(a.at(16, 0), None);
        assert_eq!(a.at(0, -11), None);
    }

    #[test]
    fn refuses_constant_images_and_empty_lag_sets() {
        let flat = grey(64, 64, |_, _| 90.0);
        assert!(repetition(&flat, 8, 8).unwrap_err().to_string().contains("constant"));
        let err = repetition(&noise(64, 64, 5), 33, 33).unwrap_err().to_string();
        assert!(err.contains("exclude"), "{err}");
    }
}
