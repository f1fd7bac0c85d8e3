//! Coarse mip levels without brute force: each level approximates the 2×2-box downsample of
//! the level below, which a 100k texture cannot afford to compute.
//!
//! Level L must approximate the 2×2-box chain of level 0, i.e. the mean colour of each
//! 2^L × 2^L block. Levels up to `exact_levels`, and with a `stage_budget` those only the
//! final stage predicts, are computed exactly (render level 0, downsample). The others are
//! prefiltered through the cascade's own coarse stages:
//!
//! * pick the finest stage s whose lattice spacing 2^shift is at least 2^L / 4, so a block
//!   spans at most 4 × 4 of its lattice points (with a budget, at level 1 the finest such
//!   stage whose window a tile can afford, [`predicting_stage`]);
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

use super::engine::{Stage, STREAM_CALIBRATION};
use super::exact::Exact;
use super::lattice::{upsample, upsample_footprint};
use super::maps::Map;
use super::residual::{self, luminance, Residual};
use crate::hash::hash4;
use crate::pixels::Rgba8Image;
use crate::Stop;

/// Bins of the conditional-mean tables over stage values in [0, 1].
const BINS: usize = 64;
/// Calibration windows (level-0 pixels, `WINDOW²` each) scattered over the plane.
const WINDOWS: u64 = 256;
const WINDOW: u32 = 32;
/// Pixels a side of the spots on which a level beyond the measured ones is fitted to the
/// box filter of the level below; levels past the base whose σ is carried up from the last
/// measured level, and the side of their spots at the base (`SIDE << CARRIED`).
const SIDE: u32 = 2;
const CARRIED: u32 = 3;
const CARRIED_SIDE: u32 = SIDE << CARRIED;
/// Spots of the carried chain.
const CARRY_SPOTS: u64 = 128;
/// A bin needs this many samples to be trusted; others are interpolated.
const MIN_COUNT: f64 = 4.0;

/// The finest level whose blocks the calibration windows measure whole. (Larger windows for
/// level 6 would take the dilation-map demo's first coarse tile past the cost bound.)
const MEASURED_LEVELS: u32 = WINDOW.trailing_zeros();

/// A tile's side, for the work of a level's stage window.
const TILE: u64 = 256;

/// Work of stage `s` on an `n × n` window of its lattice, with the coarser stages it starts
/// from: kernel taps × iterations (plus the map and the noise) over the margin-grown windows.
/// It ranks the stages that can predict a level; it is part of what the pixels are (it picks
/// the stage), so it is a fixed formula rather than the plan's cost estimate.
fn window_work(stages: &[Stage], dilated: bool, s: usize, n: u64) -> f64 {
    let st = &stages[s];
    let reach = st.kernels.iter().map(|k| k.reach).max().unwrap_or(0) as u64;
    let taps = st.kernels.iter().map(|k| k.taps.len()).max().unwrap_or(0) as f64 * if dilated { 2.0 } else { 1.0 };
    // A map through `sinf` or `expf` costs a point as much as tens of vectorised taps.
    let map = match st.map {
        Map::Logistic(_) | Map::Tent(_) => 1.0,
        Map::Sigmoid { .. } => 8.0,
        Map::Sine(_) => 25.0,
        Map::Circle { .. } => 30.0,
    };
    let side = n + 2 * st.iterations as u64 * reach;
    let own = (side * side) as f64 * ((taps + map) * st.iterations as f64 + 4.0);
    own + if s > 0 { window_work(stages, dilated, s - 1, ((side + (1 << st.up) - 1) >> st.up) + 2) } else { 0.0 }
}

/// Levels a stage budget applies to. Beyond, the finest stage is kept whatever it costs: a
/// coarser one there leaves so much of the block means to the residual that the gates' mean
/// and PSNR floor fail over small windows (the demos' level 2, and levels 3–6 past their
/// coarsest stage's spacing).
pub const BUDGETED_LEVELS: u32 = 1;

/// The stage that predicts level `l ≥ 1`, among those whose spacing is at least 2^l / 4 (at
/// most 4 × 4 samples a pixel): the finest, or with a budget and `l ≤ BUDGETED_LEVELS` the
/// finest whose tile window costs at most `budget` level-0 tiles, else the cheapest. `None`
/// past the coarsest stage.
pub fn predicting_stage(stages: &[Stage], dilated: bool, budget: Option<f64>, l: u32) -> Option<usize> {
    let last = stages.len() - 1;
    let mut candidates = (0..=last).rev().filter(|&s| stages[s].shift + 2 >= l);
    let Some(budget) = budget.filter(|_| l <= BUDGETED_LEVELS) else { return candidates.next() };
    let limit = budget * window_work(stages, dilated, last, TILE);
    let tile = |s: usize| window_work(stages, dilated, s, ((TILE << l) >> stages[s].shift).max(1) + 3);
    let costs: Vec<(usize, f64)> = candidates.map(|s| (s, tile(s))).collect();
    costs.iter().find(|(_, w)| *w <= limit).or_else(|| costs.iter().min_by(|a, b| a.1.total_cmp(&b.1))).map(|(s, _)| *s)
}

/// Whether level `l` of `tex` is the exact box downsample of level 0: up to `exact_levels`,
/// and with a stage budget wherever the final stage is the one that predicts it (its
/// prediction would be the exact block mean, at the same cost).
pub fn is_exact(tex: &Exact, l: u32) -> bool {
    let (p, e) = (tex.params(), tex.engine());
    l <= p.exact_levels()
        || p.stage_budget.is_some()
            && predicting_stage(&e.stages, e.control.is_some(), p.stage_budget, l) == Some(e.stages.len() - 1)
}

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
fn guide(tex: &Exact) -> Option<&super::lattice::ImageField> {
    let e = tex.engine();
    e.initial.as_ref().map(|i| &i.field).or(e.control.as_ref().map(|c| &c.field))
}

/// Stage `s` of the cascade upsampled straight to level-0 pixels (bilinear, one step), or
/// `None` once `stop` is requested.
pub fn stage_at_pixels(tex: &Exact, s: usize, x: u64, y: u64, w: usize, h: usize, stop: &dyn Stop) -> Option<Vec<f32>> {
    let k = tex.engine().stages[s].shift;
    let (fw, fh) = (upsample_footprint(x, w, k), upsample_footprint(y, h, k));
    let g = tex.engine().field_until(s, x >> k, y >> k, fw, fh, stop)?;
    Some(upsample(&g, k, x, y, w, h))
}

/// Calibration window `i`'s corner, aligned to `WINDOW`. Over a repeating guide the windows
/// are stratified, one to each cell of a 16 × 16 grid over the guide's period: the guide's
/// values weigh on the colour, and a plain random sample of 256 of them is a poor sample of
/// their distribution.
fn window(tex: &Exact, i: u64) -> (u64, u64) {
    let h = hash4(tex.engine().seed, STREAM_CALIBRATION, i as i64, 1);
    let align = !(WINDOW as u64 - 1);
    match guide(tex).filter(|g| g.repeat) {
        Some(g) => {
            const GRID: u64 = 16;
            let (pw, ph) = (g.cell * g.w as u64, g.cell * g.h as u64);
            let at = |period: u64, k: u64, far: u64, jitter: u64| {
                let cell = (period / GRID).max(1);
                far.wrapping_mul(period).wrapping_add(k * period / GRID).wrapping_add(jitter % cell) & align
            };
            (at(pw, i % GRID, h >> 40, h), at(ph, (i / GRID) % GRID, (h >> 16) & 0xff_ffff, h.rotate_left(23)))
        }
        None => (h & align, h.rotate_left(29) & align),
    }
}

impl Calibration {
    /// The statistics, or `None` once `stop` is requested.
    pub fn compute(tex: &Exact, stop: &dyn Stop) -> Option<Self> {
        let e = tex.engine();
        let n = e.stages.len();
        // One table per stage, plus one over the initial image's value.
        let mut sums = vec![vec![[0.0f64; 4]; BINS]; n + 1];
        let mut mean = [0.0f64; 3];
        let mut count = 0.0;
        // The windows, aligned to whole blocks of the measured levels, are kept for the residuals.
        let mut windows = Vec::with_capacity(WINDOWS as usize);
        for i in 0..WINDOWS {
            let (x, y) = window(tex, i);
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
    /// blocks of the calibration windows. Beyond, the level is what a box filter makes of the
    /// served levels below: on deterministic spots, the last measured residual's shape,
    /// centred, is scaled (and shifted to the last measured level's mean) so that prediction
    /// plus residual has the σ of level L − 1 as served and box-filtered — or, for the
    /// [`CARRIED`] levels past the base, of the last measured level box-filtered up to L, so
    /// that structure at a scale the blocks have not outgrown keeps its σ. The field's weights
    /// follow that chain's fall across those levels and are 2^−k elsewhere (box-filtered white
    /// noise: the short-range detail the residual stands for); z at level L + 1 is z at level
    /// L box-filtered, so the levels' residuals share their grains.
    fn measure_residuals(&mut self, tex: &Exact, windows: &[(u64, u64, Rgba8Image)], stop: &dyn Stop) -> Option<()> {
        let e = tex.engine();
        let levels = self.weights.len() as u32;
        let first = tex.params().exact_levels() + 1;
        for k in first as usize..levels as usize - 1 {
            self.weights[k] = libm::exp2f(-(k as f32));
        }
        // The finest level whose served blocks hold structure of their own: the last measured
        // one, or beyond it the last one a stage's lattice predicts.
        let base = e.stages.iter().map(|s| s.shift + 2).max().unwrap_or(0).max(MEASURED_LEVELS);
        let rgb = |p: &[u8]| [p[0] as f32, p[1] as f32, p[2] as f32];
        let spot = |i: u64| {
            let h = hash4(e.seed, STREAM_CALIBRATION, i as i64, 3);
            (h, h.rotate_left(29))
        };
        let mut centred: Option<Residual> = None;
        // Per level k, how the σ of level k + 1 compares with level k's: from the carried
        // chain past the base, ½ (white noise box-filtered) elsewhere.
        let mut ratios = vec![0.5f64; levels as usize];
        // The mean colour of the exact blocks of the last measured level, over all the
        // windows: the levels beyond keep it, rather than the mean of the few blocks a fit
        // sees, whose error would add up from level to level.
        let mut reference = self.mean.map(|m| m as f64);
        // Per level base + m (m = 1..=CARRIED), the last measured level as served,
        // box-filtered up to it.
        let mut carried: Vec<Vec<[f32; 3]>> = Vec::new();
        // Up to the top (one pixel, no field): its residual is the offset alone.
        for l in first..levels {
            let at = l as usize;
            if l <= MEASURED_LEVELS {
                if is_exact(tex, l) {
                    continue;
                }
                let mut pairs = Vec::new();
                for (x, y, img) in windows {
                    let exact = crate::mip::downsample_n(img, l);
                    let side = WINDOW >> l;
                    let predicted = render(tex, self, l, x >> l, y >> l, side, side, stop)?;
                    for (a, b) in exact.data.chunks_exact(4).zip(predicted.data.chunks_exact(4)) {
                        let (a, b) = (rgb(a), rgb(b));
                        pairs.push((b, [0, 1, 2].map(|c| a[c] - b[c])));
                    }
                }
                let n = pairs.len() as f64;
                reference = [0, 1, 2].map(|c| pairs.iter().map(|(p, r)| (p[c] + r[c]) as f64).sum::<f64>() / n);
                let deviations: Vec<[f32; 3]> = pairs.iter().map(|(_, r)| *r).collect();
                if let Some((r, s)) = Residual::centred(&deviations) {
                    centred = (s > 0.0).then(|| r.scaled((1.0 / s) as f32)).or(centred);
                }
                if let Some((r, _)) = Residual::measure(pairs) {
                    self.residuals[at] = Some(r);
                }
                continue;
            }
            let Some(shape) = centred.clone() else { continue };
            if l == base + 1 {
                // The structure of the levels up to the base carried up: the last measured
                // level as served (it has the exact blocks' statistics) over CARRIED_SIDE <<
                // depth pixels a spot, box-filtered level by level, sets both the σ of the
                // levels past the base and how fast the field's σ falls across them.
                let from = MEASURED_LEVELS.max(first).min(base);
                let depth = base - from;
                let mut filtered: Vec<Rgba8Image> = Vec::new();
                for i in 0..CARRY_SPOTS {
                    let (x, y) = spot(i);
                    let side = CARRIED_SIDE << depth;
                    filtered.push(render(
                        tex,
                        self,
                        from,
                        x << (CARRIED + depth),
                        y << (CARRIED + depth),
                        side,
                        side,
                        stop,
                    )?);
                }
                let pixels = |imgs: &[Rgba8Image]| -> Vec<[f32; 3]> {
                    imgs.iter().flat_map(|img| img.data.chunks_exact(4).map(rgb)).collect()
                };
                for _ in 0..depth {
                    filtered = filtered.iter().map(|img| crate::mip::downsample_n(img, 1)).collect();
                }
                let mut sigmas = vec![lum_sigma(pixels(&filtered).into_iter())];
                for _ in 0..CARRIED {
                    filtered = filtered.iter().map(|img| crate::mip::downsample_n(img, 1)).collect();
                    carried.push(pixels(&filtered));
                    sigmas.push(lum_sigma(carried.last().unwrap().iter().copied()));
                }
                for m in 0..CARRIED as usize {
                    if sigmas[m] > 0.0 && base as usize + m < ratios.len() {
                        ratios[base as usize + m] = sigmas[m + 1] / sigmas[m];
                    }
                }
                self.weights_from(&ratios, first);
            }
            // A level at or below the base (a stage deeper than the measured levels) has no
            // carried chain: like those past it, its target is the level below box-filtered.
            let carried_at = l.checked_sub(base).filter(|m| (1..=CARRIED).contains(m));
            let (target, side, shift) = if let Some(m) = carried_at {
                (carried[m as usize - 1].clone(), CARRIED_SIDE >> m, CARRIED - m)
            } else {
                let mut target = Vec::new();
                for i in 0..WINDOWS {
                    let (x, y) = spot(i);
                    let below = render(tex, self, l - 1, x << 1, y << 1, 2 * SIDE, 2 * SIDE, stop)?;
                    target.extend(crate::mip::downsample_n(&below, 1).data.chunks_exact(4).map(rgb));
                }
                (target, SIDE, 0)
            };
            let spots = if carried_at.is_some() { CARRY_SPOTS } else { WINDOWS };
            let (mut predicted, mut unit) = (Vec::new(), Vec::new());
            for i in 0..spots {
                let (x, y) = spot(i);
                let (x, y) = (x << shift, y << shift);
                let n = (side * side) as usize;
                let z = residual::field(&self.weights, e.seed, l, x, y, side as usize, side as usize)
                    .unwrap_or_else(|| vec![0.0; n]);
                let mut p = vec![[0.0f32; 3]; n];
                predict(tex, self, l, x, y, side, side, stop, |i, j, c| p[(j * side + i) as usize] = c)?;
                for (c, z) in p.into_iter().zip(z) {
                    unit.push(shape.at(luminance(c), z));
                    predicted.push(c);
                }
            }
            self.residuals[at] = Some(fit(&shape, &target, reference, &predicted, &unit));
        }
        Some(())
    }

    /// The field's weights from the σ ratios of consecutive levels (`ratios[k]`: level k + 1
    /// against level k). z at level L is normalised by N_L = √(Σ_{k≥L} a_k²), and z at L + 1
    /// is z at L box-filtered times N_{L+1}/N_L: N_{L+1}/N_L = ratios[L] makes the field fall
    /// across levels as the texture's block means do (a_k = 2^−k where the ratio is ½). Ratios
    /// are kept within [½, 0.95], so that every term keeps a share.
    fn weights_from(&mut self, ratios: &[f64], first: u32) {
        let top = self.weights.len() - 2;
        let mut tail = half_pow(top) * half_pow(top);
        self.weights[top] = half_pow(top) as f32;
        for k in (first as usize..top).rev() {
            let r = ratios[k].clamp(0.5, 0.95);
            let n2 = tail / (r * r);
            self.weights[k] = (n2 - tail).sqrt() as f32;
            tail = n2;
        }
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
        // Without a field (the top level) the residual's median: its offset.
        let r = match (&self.residuals[l as usize], z) {
            (Some(r), z) => r.at(luminance(colour), z.map_or(0.0, |z| z[at])),
            (None, _) => [0.0; 3],
        };
        // Rounded half up and clamped to [0, 255]: a float-to-u8 cast truncates toward zero and
        // saturates (NaN to 0), which on these values is floor and clamp without a libm call.
        let round = |c: usize| (colour[c] + r[c] + 0.5) as u8;
        [round(0), round(1), round(2), 255]
    }
}

/// 2^−k, exactly.
fn half_pow(k: usize) -> f64 {
    1.0 / (1u64 << k.min(63)) as f64
}

/// Luminance σ of colours.
fn lum_sigma(colours: impl Iterator<Item = [f32; 3]>) -> f64 {
    let v: Vec<f64> = colours.map(|c| luminance(c) as f64).collect();
    let n = v.len() as f64;
    let m = v.iter().sum::<f64>() / n;
    (v.iter().map(|x| (x - m) * (x - m)).sum::<f64>() / n).sqrt()
}

/// `shape` (a unit-σ residual) scaled by f and shifted by o so that the served colours,
/// `predicted + f·unit + o` clamped to [0, 255], have the luminance σ of `target` and the
/// mean colour `mt`. Without the clamp, with v(·) the luminance variance,
/// v(p) + 2f·cov(p, u) + f²·v(u) = v(t) (the larger root, or f = 0 where the prediction alone
/// varies as much); the clamp (a bright prediction's residual cut at 255) then takes off mean
/// and σ, which a few corrections of o and f give back.
fn fit(shape: &Residual, target: &[[f32; 3]], mt: [f64; 3], predicted: &[[f32; 3]], unit: &[[f32; 3]]) -> Residual {
    let n = target.len() as f64;
    let mean = |v: &[[f64; 3]]| [0, 1, 2].map(|c| v.iter().map(|p| p[c]).sum::<f64>() / n);
    let wide = |v: &[[f32; 3]]| v.iter().map(|p| p.map(|c| c as f64)).collect::<Vec<[f64; 3]>>();
    let (target, predicted, unit) = (wide(target), wide(predicted), wide(unit));
    let luma = |c: [f64; 3]| 0.299 * c[0] + 0.587 * c[1] + 0.114 * c[2];
    let lum = |v: &[[f64; 3]]| v.iter().map(|p| luma(*p)).collect::<Vec<f64>>();
    let cov = |a: &[f64], b: &[f64]| {
        let (ma, mb) = (a.iter().sum::<f64>() / n, b.iter().sum::<f64>() / n);
        a.iter().zip(b).map(|(x, y)| (x - ma) * (y - mb)).sum::<f64>() / n
    };
    let (t, p, u) = (lum(&target), lum(&predicted), lum(&unit));
    let (vt, vp, vu, cpu) = (cov(&t, &t), cov(&p, &p), cov(&u, &u), cov(&p, &u));
    // A unit residual that does not vary (the top level, without a field) only shifts.
    let mut f = if vu > 1e-6 && vp < vt { (-cpu + (cpu * cpu + vu * (vt - vp)).sqrt()) / vu } else { 0.0 };
    let (mp, mu) = (mean(&predicted), mean(&unit));
    let mut offset = [0, 1, 2].map(|c| mt[c] - mp[c] - f * mu[c]);
    for _ in 0..4 {
        let served: Vec<[f64; 3]> = predicted
            .iter()
            .zip(&unit)
            .map(|(p, u)| [0, 1, 2].map(|c| (p[c] + f * u[c] + offset[c]).clamp(0.0, 255.0)))
            .collect();
        let ms = mean(&served);
        (0..3).for_each(|c| offset[c] += mt[c] - ms[c]);
        let vs = cov(&lum(&served), &lum(&served));
        if f > 0.0 && vs > vp && vt > vp {
            // Only the residual's share of the variance is f's to correct.
            f *= ((vt - vp) / (vs - vp)).sqrt().clamp(0.5, 2.0);
        }
    }
    // Each channel's share: where a channel varies by more than a level either way, its own
    // σ (a palette's channels saturate differently: a fire palette's red at 255).
    let served: Vec<[f64; 3]> = predicted
        .iter()
        .zip(&unit)
        .map(|(p, u)| [0, 1, 2].map(|c| (p[c] + f * u[c] + offset[c]).clamp(0.0, 255.0)))
        .collect();
    let each = [0, 1, 2].map(|c| {
        let (t, s) = (target.iter().map(|v| v[c]).collect::<Vec<_>>(), served.iter().map(|v| v[c]).collect::<Vec<_>>());
        let (vt, vs) = (cov(&t, &t), cov(&s, &s));
        let g = if vt > 1.0 && vs > 1.0 { (vt / vs).sqrt().clamp(0.5, 2.0) } else { 1.0 };
        (f * g) as f32
    });
    shape.scaled_each(each).shifted(offset.map(|o| o as f32))
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
    tex: &Exact,
    cal: &Calibration,
    l: u32,
    x: u64,
    y: u64,
    w: u32,
    h: u32,
    stop: &dyn Stop,
) -> Option<Rgba8Image> {
    let mut img = Rgba8Image::new(w, h);
    let z = cal.field(tex.engine().seed, l, x, y, w, h);
    predict(tex, cal, l, x, y, w, h, stop, |i, j, colour| {
        img.set_pixel(i, j, cal.pixel(colour, l, z.as_deref(), (j * w + i) as usize))
    })?;
    Some(img)
}

/// The prediction (without the residual, unrounded) of each of the `w × h` pixels of level
/// `l` at (x, y), handed to `put(i, j, colour)`; `None` once `stop` is requested.
#[allow(clippy::too_many_arguments)]
fn predict(
    tex: &Exact,
    cal: &Calibration,
    l: u32,
    x: u64,
    y: u64,
    w: u32,
    h: u32,
    stop: &dyn Stop,
    mut put: impl FnMut(u32, u32, [f32; 3]),
) -> Option<()> {
    let e = tex.engine();
    let last = e.stages.len() - 1;
    let Some(s) = predicting_stage(&e.stages, e.control.is_some(), tex.params().stage_budget, l) else {
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
                    put(i as u32, j as u32, acc.map(|v| v * inv));
                }
            }
            return Some(());
        }
        // The mean colour and the residual, a row at a time: a region may be as large as a
        // render allows.
        for j in 0..h {
            if stop.requested() {
                return None;
            }
            for i in 0..w {
                put(i, j, cal.mean);
            }
        }
        return Some(());
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
            put(i as u32, j as u32, acc.map(|v| v * inv_n));
        }
    }
    Some(())
}
