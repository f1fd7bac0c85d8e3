//! The residual of the prefiltered levels: what a prediction of a block mean cannot place,
//! supplied with the exact downsample's distribution.
//!
//! Per level, the calibration's residuals (exact block mean − prediction) are ranked into
//! quantile tables, one per band of the prediction's luminance (a bright prediction leaves
//! room to darken, not to brighten). A pixel takes the residual at the Gaussian quantile of a
//! field z, interpolated between the bands around its prediction: prediction plus residual
//! then has the distribution of the exact block means, as far as the bands resolve it. z is a Haar-like noise:
//! each level's term sums to zero over the four children of a pixel of the next level, so z
//! at level L + 1 is the box filter of z at level L up to its normalisation, and coarse and
//! fine levels show the same grains.

use super::engine::STREAM_RESIDUAL;
use crate::hash::hash4;

/// Quantiles of a band's table, and bands of prediction luminance.
const QUANTILES: usize = 64;
const BANDS: usize = 4;

/// Rec. 601 luma of an RGB colour.
pub fn luminance(c: [f32; 3]) -> f32 {
    0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2]
}

/// One level's residual distribution.
#[derive(Clone, Debug, PartialEq)]
pub struct Residual {
    /// Mean prediction luminance of each band, rising.
    centres: Vec<f32>,
    /// Per band, `QUANTILES` RGB residuals at rising luminance.
    tables: Vec<Vec<[f32; 3]>>,
}

impl Residual {
    /// The distribution of `(prediction, residual)` pairs, and the residuals' luminance σ.
    /// `None` without pairs.
    pub fn measure(mut pairs: Vec<([f32; 3], [f32; 3])>) -> Option<(Self, f64)> {
        if pairs.is_empty() {
            return None;
        }
        let n = pairs.len();
        let lum: Vec<f64> = pairs.iter().map(|(_, r)| luminance(*r) as f64).collect();
        let mean = lum.iter().sum::<f64>() / n as f64;
        let sigma = (lum.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / n as f64).sqrt();
        pairs.sort_by(|a, b| luminance(a.0).total_cmp(&luminance(b.0)));
        let (mut centres, mut tables) = (Vec::new(), Vec::new());
        for b in 0..BANDS.min(n) {
            let band = &mut pairs[share(b, BANDS.min(n), n)];
            centres.push(band.iter().map(|(p, _)| luminance(*p)).sum::<f32>() / band.len() as f32);
            band.sort_by(|a, b| luminance(a.1).total_cmp(&luminance(b.1)));
            tables.push(quantiles(&band.iter().map(|(_, r)| *r).collect::<Vec<_>>()));
        }
        Some((Residual { centres, tables }, sigma))
    }

    /// One band of the residuals' deviations from their mean, and their luminance σ: a
    /// distribution that adds no bias whatever prediction it is added to. `None` without
    /// residuals.
    pub fn centred(residuals: &[[f32; 3]]) -> Option<(Self, f64)> {
        let n = residuals.len();
        if n == 0 {
            return None;
        }
        let mut mean = [0.0f64; 3];
        for r in residuals {
            (0..3).for_each(|c| mean[c] += r[c] as f64);
        }
        let mut dev: Vec<[f32; 3]> =
            residuals.iter().map(|r| [0, 1, 2].map(|c| (r[c] as f64 - mean[c] / n as f64) as f32)).collect();
        let lum: Vec<f64> = dev.iter().map(|r| luminance(*r) as f64).collect();
        let sigma = (lum.iter().map(|v| v * v).sum::<f64>() / n as f64).sqrt();
        dev.sort_by(|a, b| luminance(*a).total_cmp(&luminance(*b)));
        Some((Residual { centres: vec![0.0], tables: vec![quantiles(&dev)] }, sigma))
    }

    /// The same distribution with every residual multiplied by `f`.
    pub fn scaled(&self, f: f32) -> Self {
        let tables = self.tables.iter().map(|t| t.iter().map(|r| r.map(|v| v * f)).collect()).collect();
        Residual { centres: self.centres.clone(), tables }
    }

    /// The same distribution with each channel's residuals multiplied by its `f`.
    pub fn scaled_each(&self, f: [f32; 3]) -> Self {
        let tables = self.tables.iter().map(|t| t.iter().map(|r| [0, 1, 2].map(|c| r[c] * f[c])).collect()).collect();
        Residual { centres: self.centres.clone(), tables }
    }

    /// The same distribution with `offset` added to every residual.
    pub fn shifted(&self, offset: [f32; 3]) -> Self {
        let tables =
            self.tables.iter().map(|t| t.iter().map(|r| [0, 1, 2].map(|c| r[c] + offset[c])).collect()).collect();
        Residual { centres: self.centres.clone(), tables }
    }

    /// The residual at field value `z` for a prediction of luminance `lum`.
    pub fn at(&self, lum: f32, z: f32) -> [f32; 3] {
        let u = 0.5 * (1.0 + libm::erff(z * core::f32::consts::FRAC_1_SQRT_2));
        let pos = (u * QUANTILES as f32 - 0.5).clamp(0.0, (QUANTILES - 1) as f32);
        let i = (pos as usize).min(QUANTILES - 2);
        let f = pos - i as f32;
        // Written out per channel: this runs once a pixel at every prefiltered level.
        let quantile = |t: &[[f32; 3]]| {
            let (a, b) = (t[i], t[i + 1]);
            [a[0] + (b[0] - a[0]) * f, a[1] + (b[1] - a[1]) * f, a[2] + (b[2] - a[2]) * f]
        };
        let above = self.centres.iter().position(|&c| c > lum).unwrap_or(self.centres.len());
        if above == 0 || above == self.centres.len() {
            return quantile(&self.tables[above.min(self.centres.len() - 1)]);
        }
        let (lo, hi) = (quantile(&self.tables[above - 1]), quantile(&self.tables[above]));
        let t = (lum - self.centres[above - 1]) / (self.centres[above] - self.centres[above - 1]);
        [lo[0] + (hi[0] - lo[0]) * t, lo[1] + (hi[1] - lo[1]) * t, lo[2] + (hi[2] - lo[2]) * t]
    }
}

/// The share of `len` items that part `i` of `parts` holds (never empty).
fn share(i: usize, parts: usize, len: usize) -> std::ops::Range<usize> {
    i * len / parts..((i + 1) * len / parts).max(i * len / parts + 1)
}

/// `QUANTILES` residuals from residuals ranked by luminance: each the mean of an equal share.
fn quantiles(ranked: &[[f32; 3]]) -> Vec<[f32; 3]> {
    (0..QUANTILES)
        .map(|q| {
            let group = &ranked[share(q, QUANTILES, ranked.len())];
            let sum = group.iter().fold([0.0f32; 3], |acc, r| [0, 1, 2].map(|c| acc[c] + r[c]));
            sum.map(|v| v / group.len() as f32)
        })
        .collect()
}

/// The ancestor `shift` levels up of a level coordinate, taken as signed (as regions give it):
/// −1's parent is −1, so the pixels on either side of the origin keep one hierarchy (as
/// unsigned, level L's −1 would not be a child of level L + 1's −1).
#[inline]
fn ancestor(c: u64, shift: u32) -> i64 {
    (c as i64) >> shift
}

/// The field z (unit variance) over the `w × h` pixels at (x, y) of level `l`, row-major:
/// at each pixel the sum over levels k ≥ l of `weights[k]` times the term of level k — a Haar
/// pattern of the pixel's ancestor at level k among its three siblings, with three weights
/// hashed from their parent (each uniform in [−1, 1), so a term has unit variance) —
/// normalised. Each ancestor's term is hashed once, and every pixel sums its terms in the
/// same order whatever region it is in. `None` when every weight is zero.
pub fn field(weights: &[f32], seed: u64, l: u32, x: u64, y: u64, w: usize, h: usize) -> Option<Vec<f32>> {
    let (mut z, mut var) = (vec![0.0f32; w * h], 0.0f32);
    let mut row = vec![0.0f32; w];
    for (k, &a) in weights.iter().enumerate().skip(l as usize) {
        if a == 0.0 {
            continue;
        }
        let shift = (k as u32 - l).min(63);
        let term = |qx: i64, qy: i64| {
            let h = hash4(seed, STREAM_RESIDUAL + k as u64, qx >> 1, qy >> 1);
            let r = [0, 21, 42].map(|b| ((h >> b) & 0x1f_ffff) as f32 * (2.0 / (1u32 << 21) as f32) - 1.0);
            let (sx, sy) = (if qx & 1 == 0 { 1.0 } else { -1.0 }, if qy & 1 == 0 { 1.0 } else { -1.0 });
            a * (r[0] * sy + r[1] * sx + r[2] * sx * sy)
        };
        let mut row_of = None;
        for j in 0..h {
            let qy = ancestor(y.wrapping_add(j as u64), shift);
            if row_of != Some(qy) {
                let mut last: Option<(i64, f32)> = None;
                for (i, t) in row.iter_mut().enumerate() {
                    let qx = ancestor(x.wrapping_add(i as u64), shift);
                    *t = match last {
                        Some((q, v)) if q == qx => v,
                        _ => term(qx, qy),
                    };
                    last = Some((qx, *t));
                }
                row_of = Some(qy);
            }
            for (o, t) in z[j * w..(j + 1) * w].iter_mut().zip(&row) {
                *o += *t;
            }
        }
        var += a * a;
    }
    if var == 0.0 {
        return None;
    }
    let norm = libm::sqrtf(var);
    z.iter_mut().for_each(|v| *v /= norm);
    Some(z)
}
