//! The dynamical system itself: A_{i+1} = p(N(A_i)) on each stage's lattice, and the cascade
//! in which a coarser stage, upsampled, is the initial condition of the next finer one.
//!
//! A stage's value at a lattice point after k iterations with a kernel reaching r lattice
//! points (its largest, under a dilation map) depends exactly on the initial values within
//! k·r of it, so any window is computed from its margin-expanded window, shrinking by r per
//! iteration; a cascade
//! recurses to the coarser stage for the upsampling footprint of that expanded window.
//! Every value is produced by the same operations in the same order whatever window it lies
//! in, so a region is bit-identical to the crop of any larger one.
//!
//! Every loop over the rows of a window polls a [`Stop`]: once it is requested the field is
//! abandoned (`None`), so a stop takes effect within one row of one iteration.

use super::kernel::{Kernel, Shape};
use super::lattice::{lattice_mask, noise, upsample, upsample_footprint, Grid, ImageField};
use super::maps::Map;
use crate::{Never, Stop};

/// Hash streams (one per use of the seed).
pub const STREAM_NOISE: u64 = 0x100;
pub const STREAM_CALIBRATION: u64 = 0x300;
/// The coarse levels' residual: one stream per level from here.
pub const STREAM_RESIDUAL: u64 = 0x400;

/// Steps per octave of dilation between the kernels a dilation map blends.
pub const LADDER_STEPS: f64 = 8.0;

/// One level of the cascade, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    /// The stage's kernel, with its dilation, stretch and rotation; with a dilation map,
    /// `kernels[k]` is it further dilated by 2^(k / LADDER_STEPS), up to the map's maximum.
    pub kernels: Vec<Kernel>,
    /// Per kernel, the gain on the stage's white noise (initial noise, jitter) that gives its
    /// first convolution the variance the untransformed kernel gives: ‖N‖₂ / ‖N'‖₂. A kernel
    /// dilated by d averages d² times more independent points, so without it a dilated
    /// texture would start from a nearly flat field and develop a different pattern, not the
    /// same one larger.
    pub gains: Vec<f32>,
    pub map: Map,
    pub iterations: u32,
    /// This stage's lattice spacing is 2^shift level-0 pixels.
    pub shift: u32,
    /// log2 of the upsampling factor from the previous (coarser) stage; 0 for the first.
    pub up: u32,
    /// Amplitude of fresh noise added to the upsampled initial condition.
    pub jitter: f32,
}

impl Stage {
    /// The stage's own kernel (undilated by any map).
    pub fn kernel(&self) -> &Kernel {
        &self.kernels[0]
    }

    /// The kernels and their noise gains for a stage whose kernel `base` has `shape`, under a
    /// dilation map whose largest factor is `max` (1 without a map). `at` names the stage in
    /// errors.
    pub fn kernels(base: &Kernel, shape: Shape, max: f64, at: &str) -> crate::Result<(Vec<Kernel>, Vec<f32>)> {
        let top = libm::ceil(LADDER_STEPS * libm::log2(max)) as u32;
        let kernels = (0..=top)
            .map(|k| base.transformed(shape.scaled(libm::exp2(k as f64 / LADDER_STEPS)), at))
            .collect::<crate::Result<Vec<_>>>()?;
        let energy = |k: &Kernel| k.taps.iter().map(|t| t.w as f64 * t.w as f64).sum::<f64>();
        let gains = kernels.iter().map(|k| libm::sqrt(energy(base) / energy(k)) as f32).collect();
        Ok((kernels, gains))
    }
}

/// Spatially varying dilation (the paper's image C): the control value c ∈ [0, 1] at a
/// point scales the kernel by the real factor f = 1 + c·(max − 1). The convolution there
/// blends the two kernels of the stage's ladder around f (log-linearly), so the kernel
/// grows continuously with the map and every kernel reads the whole lattice.
#[derive(Clone, Debug, PartialEq)]
pub struct Control {
    pub field: ImageField,
    pub max: f64,
}

impl Control {
    /// Ladder position at pixel (px, py): the lower kernel and the upper one's weight.
    fn position(&self, px: i64, py: i64) -> (usize, f32) {
        let c = self.field.sample(px, py).unwrap_or(0.0);
        let pos = LADDER_STEPS * libm::log2(1.0 + c * (self.max - 1.0));
        let k = libm::floor(pos);
        (k as usize, (pos - k) as f32)
    }
}

/// Structured initial condition (image D): the coarsest stage starts from
/// (1 − strength)·noise + strength·image where the image covers the plane.
#[derive(Clone, Debug, PartialEq)]
pub struct Initial {
    pub field: ImageField,
    pub strength: f32,
}

#[derive(Clone, Debug, PartialEq)]
pub struct Engine {
    pub seed: u64,
    /// Coarse to fine; the last stage is on the pixel lattice (shift 0).
    pub stages: Vec<Stage>,
    pub control: Option<Control>,
    pub initial: Option<Initial>,
}

impl Engine {
    /// How far one iteration of stage `s` reaches, in its lattice units.
    pub fn step_margin(&self, s: usize) -> usize {
        self.stages[s].kernels.iter().map(|k| k.reach).max().unwrap_or(0) as usize
    }

    /// The dependency margin of stage `s`: its values depend on initial values this far away.
    pub fn margin(&self, s: usize) -> usize {
        self.stages[s].iterations as usize * self.step_margin(s)
    }

    /// Stage `s` after its iterations on the `w × h` window at lattice point (x0, y0).
    pub fn field(&self, s: usize, x0: u64, y0: u64, w: usize, h: usize) -> Grid {
        self.field_until(s, x0, y0, w, h, &Never).expect("a field that is never stopped completes")
    }

    /// [`Engine::field`], or `None` once `stop` is requested.
    pub fn field_until(&self, s: usize, x0: u64, y0: u64, w: usize, h: usize, stop: &dyn Stop) -> Option<Grid> {
        self.field_with(s, x0, y0, w, h, None, stop)
    }

    /// [`Engine::field`], but when `short == Some(t)` stage t is computed from a window one
    /// point narrower on each side than its margin needs, with the edge values repeated —
    /// what an implementation with an off-by-one margin would do. Tests use it to show the
    /// margin is exactly right.
    #[allow(clippy::too_many_arguments)]
    pub(crate) fn field_with(
        &self,
        s: usize,
        x0: u64,
        y0: u64,
        w: usize,
        h: usize,
        short: Option<usize>,
        stop: &dyn Stop,
    ) -> Option<Grid> {
        let st = &self.stages[s];
        let mask = lattice_mask(st.shift);
        let m = self.margin(s);
        let (iw, ih) = (w + 2 * m, h + 2 * m);
        let (ix0, iy0) = (x0.wrapping_sub(m as u64) & mask, y0.wrapping_sub(m as u64) & mask);
        let v = if short == Some(s) && m > 0 {
            let (x, y) = (ix0.wrapping_add(1) & mask, iy0.wrapping_add(1) & mask);
            pad_edges(&self.initial_values(s, x, y, iw - 2, ih - 2, short, stop)?, iw - 2, ih - 2)
        } else {
            self.initial_values(s, ix0, iy0, iw, ih, short, stop)?
        };
        let mut g = Grid { x0: ix0, y0: iy0, w: iw, h: ih, v };
        let e = self.step_margin(s);
        let ladder = match &self.control {
            Some(c) => {
                let (x, y) = (ix0.wrapping_add(e as u64) & mask, iy0.wrapping_add(e as u64) & mask);
                Some(self.ladder_positions(s, c, x, y, iw - 2 * e, ih - 2 * e, stop)?)
            }
            None => None,
        };
        for i in 0..st.iterations as usize {
            let view = ladder.as_ref().map(|d| Positions { at: d, row: iw - 2 * e, offset: i * e });
            g = self.step(s, &g, view, stop)?;
        }
        debug_assert_eq!((g.w, g.h, g.x0, g.y0), (w, h, x0 & mask, y0 & mask));
        Some(g)
    }

    /// Initial values of stage `s` on a window: hashed noise (mixed with the structured
    /// image) for the first stage, the upsampled coarser stage plus jitter for the others.
    #[allow(clippy::too_many_arguments)]
    fn initial_values(
        &self,
        s: usize,
        x0: u64,
        y0: u64,
        w: usize,
        h: usize,
        short: Option<usize>,
        stop: &dyn Stop,
    ) -> Option<Vec<f32>> {
        let st = &self.stages[s];
        let mask = lattice_mask(st.shift);
        let mut v = if s == 0 {
            let mut v = Vec::with_capacity(w * h);
            for j in 0..h as u64 {
                if stop.requested() {
                    return None;
                }
                let y = y0.wrapping_add(j) & mask;
                for i in 0..w as u64 {
                    let x = x0.wrapping_add(i) & mask;
                    let n = self.gained_noise(s, x, y);
                    v.push(match &self.initial {
                        Some(init) => match init.field.sample((x << st.shift) as i64, (y << st.shift) as i64) {
                            Some(l) => (1.0 - init.strength) * n + init.strength * l as f32,
                            None => n,
                        },
                        None => n,
                    });
                }
            }
            return Some(v);
        } else {
            let k = st.up;
            let (cw, ch) = (upsample_footprint(x0, w, k), upsample_footprint(y0, h, k));
            let coarse = self.field_with(s - 1, x0 >> k, y0 >> k, cw, ch, short, stop)?;
            upsample(&coarse, k, x0, y0, w, h)
        };
        if st.jitter > 0.0 {
            for j in 0..h {
                if stop.requested() {
                    return None;
                }
                let y = y0.wrapping_add(j as u64) & mask;
                for i in 0..w {
                    let x = x0.wrapping_add(i as u64) & mask;
                    v[j * w + i] += st.jitter * (self.gained_noise(s, x, y) - 0.5);
                }
            }
        }
        Some(v)
    }

    /// Stage `s`'s hashed noise at lattice point (x, y), its deviation from ½ scaled by the
    /// gain of the kernel there (exactly the noise where the kernel is untransformed).
    #[inline]
    fn gained_noise(&self, s: usize, x: u64, y: u64) -> f32 {
        let st = &self.stages[s];
        let n = noise(self.seed, STREAM_NOISE + s as u64, x, y, st.shift);
        let gain = match &self.control {
            None => st.gains[0],
            Some(c) => {
                let (k, t) = c.position((x << st.shift) as i64, (y << st.shift) as i64);
                if t > 0.0 {
                    st.gains[k] + (st.gains[k + 1] - st.gains[k]) * t
                } else {
                    st.gains[k]
                }
            }
        };
        0.5 + gain * (n - 0.5)
    }

    /// Per-point ladder positions of stage `s` on a window (its first iteration's output window).
    #[allow(clippy::too_many_arguments)]
    fn ladder_positions(
        &self,
        s: usize,
        c: &Control,
        x0: u64,
        y0: u64,
        w: usize,
        h: usize,
        stop: &dyn Stop,
    ) -> Option<Vec<(usize, f32)>> {
        let st = &self.stages[s];
        let mask = lattice_mask(st.shift);
        let mut out = Vec::with_capacity(w * h);
        for j in 0..h as u64 {
            if stop.requested() {
                return None;
            }
            let y = y0.wrapping_add(j) & mask;
            for i in 0..w as u64 {
                let x = x0.wrapping_add(i) & mask;
                out.push(c.position((x << st.shift) as i64, (y << st.shift) as i64));
            }
        }
        Some(out)
    }

    /// One iteration: convolve, then map. The output window is the input shrunk by the step
    /// margin on each side; under a dilation map each point blends the kernels at its
    /// ladder position.
    fn step(&self, s: usize, g: &Grid, ladder: Option<Positions>, stop: &dyn Stop) -> Option<Grid> {
        let st = &self.stages[s];
        let mask = lattice_mask(st.shift);
        let e = self.step_margin(s);
        let (ow, oh) = (g.w - 2 * e, g.h - 2 * e);
        let mut out = vec![0.0f32; ow * oh];
        match ladder {
            None => {
                for (y, row) in out.chunks_exact_mut(ow).enumerate() {
                    if stop.requested() {
                        return None;
                    }
                    for t in &st.kernel().taps {
                        let sy = (y + e) as isize + t.dy as isize;
                        let sx = e as isize + t.dx as isize;
                        let start = sy as usize * g.w + sx as usize;
                        for (o, v) in row.iter_mut().zip(&g.v[start..start + ow]) {
                            *o += t.w * *v;
                        }
                    }
                    st.map.apply(row);
                }
            }
            Some(Positions { at: positions, row: pw, offset: off }) => {
                // Each kernel's taps as offsets into this grid's rows.
                let offsets: Vec<Vec<(isize, f32)>> = st
                    .kernels
                    .iter()
                    .map(|k| k.taps.iter().map(|t| (t.dy as isize * g.w as isize + t.dx as isize, t.w)).collect())
                    .collect();
                let conv = |centre: isize, k: usize| {
                    let mut acc = 0.0f32;
                    for &(o, w) in &offsets[k] {
                        acc += w * g.v[(centre + o) as usize];
                    }
                    acc
                };
                for (y, row) in out.chunks_exact_mut(ow).enumerate() {
                    if stop.requested() {
                        return None;
                    }
                    let prow = &positions[(y + off) * pw + off..];
                    for (x, o) in row.iter_mut().enumerate() {
                        let (k, t) = prow[x];
                        let centre = ((y + e) * g.w + x + e) as isize;
                        let a = conv(centre, k);
                        *o = if t > 0.0 { a + (conv(centre, k + 1) - a) * t } else { a };
                    }
                    st.map.apply(row);
                }
            }
        }
        Some(Grid {
            x0: g.x0.wrapping_add(e as u64) & mask,
            y0: g.y0.wrapping_add(e as u64) & mask,
            w: ow,
            h: oh,
            v: out,
        })
    }
}

/// Per-point ladder positions (lower kernel, upper kernel's weight) of the first iteration's
/// output window: `row` points a row, this iteration's output window `offset` points in.
struct Positions<'a> {
    at: &'a [(usize, f32)],
    row: usize,
    offset: usize,
}

/// Grows a `w × h` buffer by one point on each side, repeating the edge values.
fn pad_edges(v: &[f32], w: usize, h: usize) -> Vec<f32> {
    let mut out = Vec::with_capacity((w + 2) * (h + 2));
    for j in 0..h + 2 {
        let sj = j.saturating_sub(1).min(h - 1);
        for i in 0..w + 2 {
            out.push(v[sj * w + i.saturating_sub(1).min(w - 1)]);
        }
    }
    out
}
