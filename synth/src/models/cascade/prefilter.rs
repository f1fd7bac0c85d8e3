//! Coarse mip levels without brute force: each level approximates the 2×2-box downsample of
//! the level below, which a 100k texture cannot afford to compute.
//!
//! Level L must approximate the 2×2-box chain of level 0, i.e. the mean colour of each
//! 2^L × 2^L block. Levels up to `exact_levels` are computed exactly (render level 0,
//! downsample). Coarser ones are prefiltered through the cascade's own coarse stages:
//!
//! * pick the finest stage s whose lattice spacing 2^shift is at least 2^L / 4, so a block
//!   spans at most 4 × 4 of its lattice points;
//! * evaluate that stage's field (cheap: its lattice is coarse), upsample it bilinearly to
//!   q × q sample points per block (q = 2^L / 2^shift, at most 4) and map each value a to
//!   g_s(a) = E[final colour | stage-s value = a], a table measured once per texture from a
//!   deterministic sample of level-0 windows;
//! * average the q² colours. When s is the final stage this is the exact block mean.
//!
//! Beyond the coarsest stage (2^L > 4 × its spacing) every block spans many independent
//! dependency windows: the prediction there is a guide image's g, or the mean colour.
//!
//! A prediction is a conditional mean, so it varies less than the exact block means do (a
//! single-stage texture's prediction is flat): a [`residual`](super::residual) with the
//! exact downsample's measured distribution supplies the rest, so each level keeps the
//! exact downsample's σ. This is an approximation and the tests report how close it gets
//! (σ and PSNR against the exact downsample).

use super::engine::STREAM_CALIBRATION;
use super::lattice::{upsample, upsample_footprint};
use super::residual::{self, luminance, Residual};
use super::Cascade;
use crate::hash::hash4;
use crate::pixels::Rgba8Image;
use crate::Stop;

/// Bins of the conditional-mean tables over stage values in [0, 1].
const BINS: usize = 64;
/// Calibration windows (level-0 pixels, `WINDOW²` each) scattered over the plane.
const WINDOWS: u64 = 256;
const WINDOW: u32 = 32;
/// A bin needs this many samples to be trusted; others are interpolated.
const MIN_COUNT: f64 = 4.0;

/// The finest level whose blocks the calibration windows measure whole. (Larger windows for
/// level 6 would take the dilation-map demo's first coarse tile past the cost bound.)
const MEASURED_LEVELS: u32 = WINDOW.trailing_zeros();

/// Measured statistics of a texture for its prefiltered levels.
#[derive(Clone, Debug, PartialEq)]
pub struct Calibration {
    /// Per stage (coarse to fine; the last is unused): g_s as `BINS` RGB means.
    pub tables: Vec<Vec<[f32; 3]>>,
    /// g over the guide image's value (the initial image, else the control map), if any.
    pub image: Option<Vec<[f32; 3]>>,
    /// Mean colour of the texture.
    pub mean: [f32; 3],
    /// Per level k, the weight of the residual field's term of level k (zero up to the exact
    /// levels and at the top).
    pub weights: Vec<f32>,
    /// Per level, the residual's distribution; none up to the exact levels.
    pub residuals: Vec<Option<Residual>>,
}

/// The image whose value predicts the local mean beyond the coarsest stage: the structured
/// initial image, else the dilation control map.
fn guide(tex: &Cascade) -> Option<&super::lattice::ImageField> {
    let e = tex.engine();
    e.initial.as_ref().map(|i| &i.field).or(e.control.as_ref().map(|c| &c.field))
}

/// Stage `s` of the cascade upsampled straight to level-0 pixels (bilinear, one step), or
/// `None` once `stop` is requested.
pub fn stage_at_pixels(
    tex: &Cascade,
    s: usize,
    x: u64,
    y: u64,
    w: usize,
    h: usize,
    stop: &dyn Stop,
) -> Option<Vec<f32>> {
    let k = tex.engine().stages[s].shift;
    let (fw, fh) = (upsample_footprint(x, w, k), upsample_footprint(y, h, k));
    let g = tex.engine().field_until(s, x >> k, y >> k, fw, fh, stop)?;
    Some(upsample(&g, k, x, y, w, h))
}

impl Calibration {
    /// The statistics, or `None` once `stop` is requested.
    pub fn compute(tex: &Cascade, stop: &dyn Stop) -> Option<Self> {
        let e = tex.engine();
        let n = e.stages.len();
        // One table per stage, plus one over the initial image's value.
        let mut sums = vec![vec![[0.0f64; 4]; BINS]; n + 1];
        let mut mean = [0.0f64; 3];
        let mut count = 0.0;
        // The windows, aligned to whole blocks of the measured levels, are kept for the residuals.
        let mut windows = Vec::with_capacity(WINDOWS as usize);
        for i in 0..WINDOWS {
            let h = hash4(e.seed, STREAM_CALIBRATION, i as i64, 1);
            let (x, y) = (h & !(WINDOW as u64 - 1), h.rotate_left(29) & !(WINDOW as u64 - 1));
            let img = tex.level0(x, y, WINDOW, WINDOW, stop)?;
            for p in img.data.chunks_exact(4) {
                for c in 0..3 {
                    mean[c] += p[c] as f64;
                }
                count += 1.0;
            }
            if let Some(guide) = guide(tex) {
                for (k, p) in img.data.chunks_exact(4).enumerate() {
                    let (i, j) = ((k % WINDOW as usize) as u64, (k / WINDOW as usize) as u64);
                    if let Some(v) = guide.sample(x.wrapping_add(i) as i64, y.wrapping_add(j) as i64) {
                        let b = &mut sums[n][bin(v as f32)];
                        for c in 0..3 {
                            b[c] += p[c] as f64;
                        }
                        b[3] += 1.0;
                    }
                }
            }
            for (s, bins) in sums.iter_mut().enumerate().take(n - 1) {
                let a = stage_at_pixels(tex, s, x, y, WINDOW as usize, WINDOW as usize, stop)?;
                for (v, p) in a.iter().zip(img.data.chunks_exact(4)) {
                    let b = &mut bins[bin(*v)];
                    for c in 0..3 {
                        b[c] += p[c] as f64;
                    }
                    b[3] += 1.0;
                }
            }
            windows.push((x, y, img));
        }
        let mean = mean.map(|m| (m / count) as f32);
        let mut tables: Vec<Vec<[f32; 3]>> = sums.iter().map(|bins| fill(bins, mean)).collect();
        let image = tables.pop().filter(|_| guide(tex).is_some());
        let p = tex.params();
        let levels = crate::texture::level_count(p.width, p.height) as usize;
        let mut cal = Calibration { tables, image, mean, weights: vec![0.0; levels], residuals: vec![None; levels] };
        cal.measure_residuals(tex, &windows, stop)?;
        Some(cal)
    }

    /// The residuals: at each prefiltered level L up to [`MEASURED_LEVELS`], measured from the
    /// blocks of the calibration windows. Beyond,
    /// σ(exact) is extrapolated at the ratio of the last two measured levels, the predictions'
    /// σ measured (they are cheap), and the last measured residuals scaled to the σ they lack:
    /// s_L² = σ²(exact) − σ²(predictions). Where the level's prediction is the flat mean they
    /// are centred: a band's mean residual corrects that band's prediction, and carried to a
    /// flat one it would shift the level's mean. The field's term of level k weighs 2^−k, the
    /// spectrum of box-filtered white noise: at each level most of z's variance is its own
    /// level's term, as for the short-range detail the residual stands for.
    fn measure_residuals(&mut self, tex: &Cascade, windows: &[(u64, u64, Rgba8Image)], stop: &dyn Stop) -> Option<()> {
        let e = tex.engine();
        let levels = self.weights.len() as u32;
        let first = tex.params().exact_levels + 1;
        let sigma = |v: &[f32]| {
            let n = v.len() as f64;
            let m = v.iter().map(|&x| x as f64).sum::<f64>() / n;
            (v.iter().map(|&x| (x as f64 - m).powi(2)).sum::<f64>() / n).sqrt()
        };
        let lum = |img: &Rgba8Image| -> Vec<f32> {
            img.data.chunks_exact(4).map(|p| luminance([p[0] as f32, p[1] as f32, p[2] as f32])).collect()
        };
        let rgb = |p: &[u8]| [p[0] as f32, p[1] as f32, p[2] as f32];
        // Luminance σ of the exact block means per level; the last measured residual at unit σ.
        let mut exact_sigma = vec![0.0f64; levels as usize];
        let (mut banded, mut centred): (Option<Residual>, Option<Residual>) = (None, None);
        let last = e.stages.len() - 1;
        for l in first..levels.saturating_sub(1) {
            let at = l as usize;
            if l > MEASURED_LEVELS {
                let ratio = (exact_sigma[at - 1] / exact_sigma[at - 2]).clamp(0.5, 1.0);
                exact_sigma[at] = if ratio.is_finite() { exact_sigma[at - 1] * ratio } else { 0.0 };
                const SIDE: u32 = 4;
                let mut predicted = Vec::new();
                for i in 0..WINDOWS {
                    let h = hash4(e.seed, STREAM_CALIBRATION, i as i64, 3);
                    predicted.extend(lum(&render(tex, self, l, h, h.rotate_left(29), SIDE, SIDE, stop)?));
                }
                let s = (exact_sigma[at].powi(2) - sigma(&predicted).powi(2)).max(0.0).sqrt();
                // A level predicted by a stage or a guide keeps the bands (their means correct
                // the prediction's bias, as they did below); a flat one takes the centred shape.
                let flat = guide(tex).is_none() && !(0..=last).any(|s| e.stages[s].shift + 2 >= l);
                let shape = if flat { &centred } else { &banded };
                self.residuals[at] = shape.as_ref().map(|r| r.scaled(s as f32));
                continue;
            }
            let (mut pairs, mut exact_lum) = (Vec::new(), Vec::new());
            for (x, y, img) in windows {
                let exact = crate::mip::downsample_n(img, l);
                let side = WINDOW >> l;
                let predicted = render(tex, self, l, x >> l, y >> l, side, side, stop)?;
                exact_lum.extend(lum(&exact));
                for (a, b) in exact.data.chunks_exact(4).zip(predicted.data.chunks_exact(4)) {
                    let (a, b) = (rgb(a), rgb(b));
                    pairs.push((b, [0, 1, 2].map(|c| a[c] - b[c])));
                }
            }
            exact_sigma[at] = sigma(&exact_lum);
            let deviations: Vec<[f32; 3]> = pairs.iter().map(|(_, r)| *r).collect();
            if let Some((r, s)) = Residual::centred(&deviations) {
                centred = (s > 0.0).then(|| r.scaled((1.0 / s) as f32)).or(centred);
            }
            if let Some((r, s)) = Residual::measure(pairs) {
                banded = (s > 0.0).then(|| r.scaled((1.0 / s) as f32)).or(banded);
                self.residuals[at] = Some(r);
            }
        }
        for k in first as usize..levels as usize - 1 {
            self.weights[k] = libm::exp2f(-(k as f32));
        }
        Some(())
    }

    /// The residual field over `w × h` pixels of level `l` at (x, y), where the level has a residual.
    fn field(&self, seed: u64, l: u32, x: u64, y: u64, w: u32, h: u32) -> Option<Vec<f32>> {
        self.residuals[l as usize].as_ref()?;
        residual::field(&self.weights, seed, l, x, y, w as usize, h as usize)
    }

    /// Pixel `at` of a region of level `l` whose prediction is `colour`, with its residual
    /// from the region's field `z`, rounded.
    #[inline]
    fn pixel(&self, colour: [f32; 3], l: u32, z: Option<&[f32]>, at: usize) -> [u8; 4] {
        let r = match (&self.residuals[l as usize], z) {
            (Some(r), Some(z)) => r.at(luminance(colour), z[at]),
            _ => [0.0; 3],
        };
        let p = [0, 1, 2].map(|c| (colour[c] + r[c] + 0.5).floor().clamp(0.0, 255.0) as u8);
        [p[0], p[1], p[2], 255]
    }
}

#[inline]
fn bin(v: f32) -> usize {
    ((v.clamp(0.0, 1.0) * BINS as f32) as usize).min(BINS - 1)
}

/// Bin means, with sparse bins interpolated linearly between trusted neighbours.
fn fill(bins: &[[f64; 4]], mean: [f32; 3]) -> Vec<[f32; 3]> {
    let good: Vec<usize> = (0..BINS).filter(|&b| bins[b][3] >= MIN_COUNT).collect();
    let at = |b: usize| [0, 1, 2].map(|c| (bins[b][c] / bins[b][3]) as f32);
    (0..BINS)
        .map(|b| {
            let below = good.iter().rev().find(|&&g| g <= b);
            let above = good.iter().find(|&&g| g >= b);
            match (below, above) {
                (None, None) => mean,
                (Some(&g), None) | (None, Some(&g)) => at(g),
                (Some(&lo), Some(&hi)) if lo == hi => at(lo),
                (Some(&lo), Some(&hi)) => {
                    let f = (b - lo) as f32 / (hi - lo) as f32;
                    let (a, c) = (at(lo), at(hi));
                    [0, 1, 2].map(|k| a[k] + (c[k] - a[k]) * f)
                }
            }
        })
        .collect()
}

/// g(a) with linear interpolation between bin centres.
#[inline]
fn eval(table: &[[f32; 3]], a: f32) -> [f32; 3] {
    let pos = (a.clamp(0.0, 1.0) * BINS as f32 - 0.5).clamp(0.0, (BINS - 1) as f32);
    let i = (pos as usize).min(BINS - 2);
    let f = pos - i as f32;
    let (p, q) = (table[i], table[i + 1]);
    [0, 1, 2].map(|k| p[k] + (q[k] - p[k]) * f)
}

/// The guided path's sample budget is set for the level's own extent, capped at the largest
/// chunk the renderer passes (256 × 256), never for the region at hand, so that a pixel does
/// not depend on the size of the region it is rendered in.
const BUDGET_PIXELS: u64 = 256 * 256;

/// Renders `w × h` pixels of level `l` at (x, y) (level-`l` coordinates on the torus), or
/// `None` once `stop` is requested.
#[allow(clippy::too_many_arguments)]
pub fn render(
    tex: &Cascade,
    cal: &Calibration,
    l: u32,
    x: u64,
    y: u64,
    w: u32,
    h: u32,
    stop: &dyn Stop,
) -> Option<Rgba8Image> {
    let e = tex.engine();
    let last = e.stages.len() - 1;
    let mut img = Rgba8Image::new(w, h);
    let z = cal.field(e.seed, l, x, y, w, h);
    let Some(s) = (0..=last).rev().find(|&s| e.stages[s].shift + 2 >= l) else {
        if let (Some(guide), Some(table)) = (guide(tex), &cal.image) {
            // A guide image (texture transfer, dilation map) carries structure at every
            // scale; average g over n × n samples of it per block, about one per texel
            // (4 to 64 per axis; at most 2^22 samples for a chunk
            // no larger than its level).
            let per_texel = ((1u64 << l.min(40)) / guide.cell).clamp(4, 64);
            let (lw, lh) = crate::texture::level_size(tex.params().width, tex.params().height, l);
            let budget = libm::sqrt((1u64 << 22) as f64 / (lw * lh).min(BUDGET_PIXELS) as f64) as u64;
            let n = per_texel.min(budget.max(4)).next_power_of_two().min(1 << (l - 1));
            // Spread the samples over the block, or over one period of a repeating guide
            // when the block is larger (sampling a period at a fixed phase would alias).
            let offsets = |texels: u32| -> Vec<u64> {
                let block = 1u64 << l.min(62);
                let span = if guide.repeat { block.min(guide.cell * texels as u64) } else { block };
                (0..n).map(|j| (2 * j + 1) * span / (2 * n)).collect()
            };
            let (offs_x, offs_y) = (offsets(guide.w), offsets(guide.h));
            let inv = 1.0 / (n * n) as f32;
            // A pixel can take thousands of samples: poll every 2^14 samples or so (n is a power of two).
            let poll = ((1u64 << 14) / (n * n)).max(1) - 1;
            for j in 0..h as u64 {
                for i in 0..w as u64 {
                    if (j * w as u64 + i) & poll == 0 && stop.requested() {
                        return None;
                    }
                    let (px, py) = (x.wrapping_add(i) << l, y.wrapping_add(j) << l);
                    let mut acc = [0.0f32; 3];
                    for oy in &offs_y {
                        for ox in &offs_x {
                            let v = guide.sample(px.wrapping_add(*ox) as i64, py.wrapping_add(*oy) as i64);
                            let c = v.map_or(cal.mean, |v| eval(table, v as f32));
                            (0..3).for_each(|k| acc[k] += c[k]);
                        }
                    }
                    let at = (j * w as u64 + i) as usize;
                    img.set_pixel(i as u32, j as u32, cal.pixel(acc.map(|v| v * inv), l, z.as_deref(), at));
                }
            }
            return Some(img);
        }
        // The mean colour and the residual, a row at a time: a region may be as large as a
        // render allows.
        for j in 0..h {
            if stop.requested() {
                return None;
            }
            for i in 0..w {
                img.set_pixel(i, j, cal.pixel(cal.mean, l, z.as_deref(), (j * w + i) as usize));
            }
        }
        return Some(img);
    };
    let shift = e.stages[s].shift;
    let ql = l.saturating_sub(shift);
    let q = 1usize << ql;
    let half = if l > ql { 1u64 << (l - ql - 1) } else { 0 };
    let offs: Vec<u64> = (0..q as u64).map(|j| (j << (l - ql)) + half).collect();
    let cell = (1u64 << shift) - 1;
    let (bx, by) = ((x << l) & cell, (y << l) & cell);
    let span = |b: u64, n: u32| ((b + ((n as u64 - 1) << l) + offs[q - 1]) >> shift) as usize + 2;
    let g = e.field_until(s, (x << l) >> shift, (y << l) >> shift, span(bx, w), span(by, h), stop)?;
    let inv_f = 1.0 / (1u64 << shift) as f32;
    let split = |p: u64| ((p >> shift) as usize, (p & cell) as f32 * inv_f);
    let xs: Vec<Vec<(usize, f32)>> =
        (0..w as u64).map(|i| offs.iter().map(|o| split(bx + (i << l) + o)).collect()).collect();
    let inv_n = 1.0 / (q * q) as f32;
    for j in 0..h as u64 {
        if stop.requested() {
            return None;
        }
        let ys: Vec<(usize, f32)> = offs.iter().map(|o| split(by + (j << l) + o)).collect();
        for (i, xi) in xs.iter().enumerate() {
            let mut acc = [0.0f32; 3];
            for &(cy, fy) in &ys {
                for &(cx, fx) in xi {
                    let a0 = g.at(cx, cy) + (g.at(cx + 1, cy) - g.at(cx, cy)) * fx;
                    let a1 = g.at(cx, cy + 1) + (g.at(cx + 1, cy + 1) - g.at(cx, cy + 1)) * fx;
                    let a = a0 + (a1 - a0) * fy;
                    let c = if s == last {
                        let p = tex.colour(a);
                        [p[0] as f32, p[1] as f32, p[2] as f32]
                    } else {
                        eval(&cal.tables[s], a)
                    };
                    for k in 0..3 {
                        acc[k] += c[k];
                    }
                }
            }
            let at = j as usize * w as usize + i;
            img.set_pixel(i as u32, j as u32, cal.pixel(acc.map(|v| v * inv_n), l, z.as_deref(), at));
        }
    }
    Some(img)
}
