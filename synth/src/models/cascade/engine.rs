//! The dynamical system itself: A_{i+1} = p(N(A_i)) on each stage's lattice, and the cascade
//! in which a coarser stage, upsampled, is the initial condition of the next finer one.
//!
//! A stage's value at a lattice point after k iterations with kernel radius r and largest
//! dilation d depends exactly on the initial values within k·r·d of it, so any window is
//! computed from its margin-expanded window, shrinking by r·d per iteration; a cascade
//! recurses to the coarser stage for the upsampling footprint of that expanded window.
//! Every value is produced by the same operations in the same order whatever window it lies
//! in, so a region is bit-identical to the crop of any larger one.
//!
//! Every loop over the rows of a window polls a [`Stop`]: once it is requested the field is
//! abandoned (`None`), so a stop takes effect within one row of one iteration.

use super::kernel::Kernel;
use super::lattice::{lattice_mask, noise, upsample, upsample_footprint, Grid, ImageField};
use super::maps::Map;
use crate::{Never, Stop};

/// Hash streams (one per use of the seed).
pub const STREAM_NOISE: u64 = 0x100;
pub const STREAM_CALIBRATION: u64 = 0x300;

/// One level of the cascade, validated.
#[derive(Clone, Debug, PartialEq)]
pub struct Stage {
    pub kernel: Kernel,
    pub map: Map,
    pub iterations: u32,
    /// Base kernel dilation (tap spacing in lattice units).
    pub dilation: u32,
    /// This stage's lattice spacing is 2^shift level-0 pixels.
    pub shift: u32,
    /// log2 of the upsampling factor from the previous (coarser) stage; 0 for the first.
    pub up: u32,
    /// Amplitude of fresh noise added to the upsampled initial condition.
    pub jitter: f32,
}

/// Spatially varying dilation (the paper's image C): the control value c ∈ [0, 1] at a
/// point scales the kernel by the real factor 1 + c·(max − 1). Taps then fall between
/// lattice points and are read bilinearly, so the scale varies continuously and the lattice
/// does not split into independent sub-lattices (as integer dilation with holes would).
#[derive(Clone, Debug, PartialEq)]
pub struct Control {
    pub field: ImageField,
    pub max: u32,
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
    /// Largest tap spacing stage `s` can use.
    pub fn max_dilation(&self, s: usize) -> u32 {
        self.stages[s].dilation * self.control.as_ref().map_or(1, |c| c.max)
    }

    /// How far one iteration of stage `s` reaches, in its lattice units.
    pub fn step_margin(&self, s: usize) -> usize {
        (self.stages[s].kernel.radius * self.max_dilation(s)) as usize
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
        let dil = match &self.control {
            Some(c) => {
                let (x, y) = (ix0.wrapping_add(e as u64) & mask, iy0.wrapping_add(e as u64) & mask);
                Some(self.dilations(s, c, x, y, iw - 2 * e, ih - 2 * e, stop)?)
            }
            None => None,
        };
        for i in 0..st.iterations as usize {
            g = self.step(s, &g, dil.as_ref().map(|d| (d, iw - 2 * e, i * e)), stop)?;
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
        let stream = STREAM_NOISE + s as u64;
        let mut v = if s == 0 {
            let mut v = Vec::with_capacity(w * h);
            for j in 0..h as u64 {
                if stop.requested() {
                    return None;
                }
                let y = y0.wrapping_add(j) & mask;
                for i in 0..w as u64 {
                    let x = x0.wrapping_add(i) & mask;
                    let n = noise(self.seed, stream, x, y, st.shift);
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
                    v[j * w + i] += st.jitter * (noise(self.seed, stream, x, y, st.shift) - 0.5);
                }
            }
        }
        Some(v)
    }

    /// Per-point dilations of stage `s` on a window (its first iteration's output window).
    #[allow(clippy::too_many_arguments)]
    fn dilations(
        &self,
        s: usize,
        c: &Control,
        x0: u64,
        y0: u64,
        w: usize,
        h: usize,
        stop: &dyn Stop,
    ) -> Option<Vec<f32>> {
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
                let ctl = c.field.sample((x << st.shift) as i64, (y << st.shift) as i64).unwrap_or(0.0);
                out.push((st.dilation as f64 * (1.0 + ctl * (c.max - 1) as f64)) as f32);
            }
        }
        Some(out)
    }

    /// One iteration: convolve, then map. The output window is the input shrunk by the step
    /// margin on each side. `dil` = (per-point dilations, their row length, offset of this
    /// iteration's output window inside them).
    fn step(&self, s: usize, g: &Grid, dil: Option<(&Vec<f32>, usize, usize)>, stop: &dyn Stop) -> Option<Grid> {
        let st = &self.stages[s];
        let mask = lattice_mask(st.shift);
        let e = self.step_margin(s);
        let (ow, oh) = (g.w - 2 * e, g.h - 2 * e);
        let mut out = vec![0.0f32; ow * oh];
        match dil {
            None => {
                let d = st.dilation as isize;
                for (y, row) in out.chunks_exact_mut(ow).enumerate() {
                    if stop.requested() {
                        return None;
                    }
                    for t in &st.kernel.taps {
                        let sy = (y + e) as isize + t.dy as isize * d;
                        let sx = e as isize + t.dx as isize * d;
                        let start = sy as usize * g.w + sx as usize;
                        for (o, v) in row.iter_mut().zip(&g.v[start..start + ow]) {
                            *o += t.w * *v;
                        }
                    }
                    st.map.apply(row);
                }
            }
            Some((dv, dw, off)) => {
                let w = g.w as isize;
                for (y, row) in out.chunks_exact_mut(ow).enumerate() {
                    if stop.requested() {
                        return None;
                    }
                    let drow = &dv[(y + off) * dw + off..];
                    for (x, o) in row.iter_mut().enumerate() {
                        let d = drow[x];
                        let (cx, cy) = ((x + e) as isize, (y + e) as isize);
                        let mut acc = 0.0f32;
                        for t in &st.kernel.taps {
                            // The tap lands between lattice points: read it bilinearly (exact
                            // f32 ops; a zero fraction reads one point, so the margin holds).
                            let (ox, oy) = (t.dx as f32 * d, t.dy as f32 * d);
                            // Exact floor: truncate, then step down for negative fractions.
                            let floor = |v: f32| (v as isize) - ((v as isize as f32) > v) as isize;
                            let (ix, iy) = (floor(ox), floor(oy));
                            let (fx, fy) = (ox - ix as f32, oy - iy as f32);
                            let at = |dx: isize, dy: isize| g.v[((cy + iy + dy) * w + cx + ix + dx) as usize];
                            let row0 = if fx > 0.0 { at(0, 0) + (at(1, 0) - at(0, 0)) * fx } else { at(0, 0) };
                            let v = if fy > 0.0 {
                                let row1 = if fx > 0.0 { at(0, 1) + (at(1, 1) - at(0, 1)) * fx } else { at(0, 1) };
                                row0 + (row1 - row0) * fy
                            } else {
                                row0
                            };
                            acc += t.w * v;
                        }
                        *o = acc;
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
