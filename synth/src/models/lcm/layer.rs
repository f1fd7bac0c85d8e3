//! One layer: the replications of one resolution, controlled by one LCM, and its evaluation
//! over a row of pixels directly from the LCM entries that cover it (paper §6).
//!
//! At resolution r (element side s = 2^r) the replication points sit every h = s/2 pixels,
//! so a pixel lies in exactly two point spans per axis: at most four replications of a layer
//! meet at a pixel, those of points (i0−1, j0−1), (i0, j0−1), (i0−1, j0), (i0, j0) with
//! i0 = ⌊x/h⌋, j0 = ⌊y/h⌋. They are applied in that (row-major) order, which is what the
//! non-commutative operations see within a layer.
//!
//! When a mip level shifts a layer below resolution 1 (§2.4: its elements would be smaller
//! than 2 pixels), the layer is evaluated prefiltered instead: each pixel takes the exact box
//! mean of the layer's resolution-1 field over its footprint, read in O(1) from a summed-area
//! table of one LCM period. Non-additive replications also carry their coverage, so that
//! a ← a·(1 − coverage) + mean is the box filter of "paint over a" (exact for opaque or
//! additive layers, an approximation where partly transparent replications overlap).

use super::colour::QI;
use super::element::{Copies, Q};
use super::event::{Event, Operation};
use std::sync::OnceLock;

/// Fixed-point shift of layer weights: element (Q8) × weight (Q12) = intensity (Q20).
pub const QW: u32 = QI - Q;

/// Counts the work of evaluation, per pixel of the current row. The renderer is generic over
/// it so that the counting build and the real one run the same code; [`NoCount`] costs nothing.
pub trait Counter {
    /// False for [`NoCount`]: the counting loops compile away.
    const ACTIVE: bool = true;
    /// `n` additions (or the similar operations non-zero / maximum) at row pixel `x`.
    #[inline]
    fn add(&mut self, _x: usize, _n: u32) {}
    /// `n` multiplications at row pixel `x`.
    #[inline]
    fn mul(&mut self, _x: usize, _n: u32) {}
    /// `k` replications of one layer meet at row pixel `x`.
    #[inline]
    fn touch(&mut self, _x: usize, _k: u32) {}
}

/// One replication over a run of pixels: its element row, coverage row, sign, sign × weight
/// and operation.
type Rep<'a> = (&'a [i16], &'a [u16], i64, i64, Operation);

/// The counter of real rendering.
pub struct NoCount;
impl Counter for NoCount {
    const ACTIVE: bool = false;
}

/// A layer as rendered: its LCM, weight and resolution offset.
#[derive(Debug)]
pub struct Layer {
    /// The paper's layer number: layer n renders at resolution K + magnify − n at level 0.
    pub index: u32,
    /// Weight in Q12.
    pub weight: i64,
    pub w: usize,
    pub h: usize,
    /// Event codes, row-major, every "no replication" as 0.
    pub codes: Vec<u8>,
    /// Every replication adds (the paper's fast path: sum, then one multiplication).
    pub all_add: bool,
    /// Summed-area tables of the resolution-1 field, per intensity plane, made when first needed.
    sat: Vec<OnceLock<Sat>>,
}

impl Layer {
    pub fn new(index: u32, weight: i64, w: usize, h: usize, codes: &[u8], planes: usize) -> Layer {
        let codes: Vec<u8> = codes.iter().map(|&c| Event::canonical(c)).collect();
        let all_add = codes.iter().all(|&c| c == 0 || Event::operation_of(c) == Operation::Add);
        Layer { index, weight, w, h, codes, all_add, sat: (0..planes).map(|_| OnceLock::new()).collect() }
    }

    /// Applies the layer at resolution `r` ≥ 1 to `acc`, the intensities of the pixels
    /// (x0 .. x0 + acc.len(), y) of its level. `first` says `acc` holds nothing yet.
    /// `cover`, when given, accumulates the coverage (0..=256) of non-additive replications.
    #[allow(clippy::too_many_arguments)]
    pub fn apply_native<C: Counter>(
        &self,
        copies: &Copies,
        r: u32,
        y: u64,
        x0: u64,
        acc: &mut [i64],
        mut cover: Option<&mut [u16]>,
        first: bool,
        cnt: &mut C,
        cx: usize,
    ) {
        let sh = r - 1;
        let hh = 1u64 << sh;
        let s = 2 * hh as usize;
        let (w, h) = (self.w as u64, self.h as u64);
        let j0 = y >> sh;
        let v = (y & (hh - 1)) as usize;
        // Earlier point row first: (row in the LCM, local y within the element).
        let rows = [(((j0 % h) + h - 1) % h, v + hh as usize), (j0 % h, v)];
        let end = x0 + acc.len() as u64;
        let mut x = x0;
        // The LCM column of the current point span, advanced without division.
        let mut col = (x0 >> sh) % w;
        let mut sums = [0i64; 1 << (super::element::MAX_TOP - 1)];
        while x < end {
            let u0 = (x & (hh - 1)) as usize;
            let len = (hh - u0 as u64).min(end - x) as usize;
            let cols = [(if col == 0 { w - 1 } else { col - 1 }, hh as usize), (col, 0)];
            col = if col + 1 == w { 0 } else { col + 1 };
            let mut reps: [Rep; 4] = [(&[], &[], 0, 0, Operation::Add); 4];
            let mut k = 0;
            for &(row, vl) in &rows {
                for &(col, uoff) in &cols {
                    let code = self.codes[(row * w + col) as usize];
                    if code != 0 {
                        let o = Event::orientation_of(code);
                        let at = vl * s + uoff + u0..vl * s + uoff + u0 + len;
                        let (line, alpha) = (&copies.get(r, o)[at.clone()], &copies.alpha(r, o)[at]);
                        let sign = Event::sign_of(code) as i64;
                        reps[k] = (line, alpha, sign, sign * self.weight, Event::operation_of(code));
                        k += 1;
                    }
                }
            }
            let p0 = (x - x0) as usize;
            let reps = &reps[..k];
            if C::ACTIVE && k > 0 {
                for t in 0..len {
                    cnt.touch(cx + p0 + t, k as u32);
                }
            }
            if k == 0 {
                // Nothing of this layer here.
            } else if self.all_add {
                // The paper's count: up to 3 additions, 1 multiplication, 1 addition into the sum
                // of layers (none for the first layer). Written as whole-run loops that vectorize.
                let sum = &mut sums[..len];
                let (line, _, sign, _, _) = reps[0];
                for (d, &e) in sum.iter_mut().zip(line) {
                    *d = if sign > 0 { e as i64 } else { -(e as i64) };
                }
                for (line, _, sign, _, _) in &reps[1..] {
                    if *sign > 0 {
                        sum.iter_mut().zip(*line).for_each(|(d, &e)| *d += e as i64);
                    } else {
                        sum.iter_mut().zip(*line).for_each(|(d, &e)| *d -= e as i64);
                    }
                }
                let dst = &mut acc[p0..p0 + len];
                if first {
                    dst.iter_mut().zip(sum.iter()).for_each(|(d, &v)| *d = v * self.weight);
                } else {
                    dst.iter_mut().zip(sum.iter()).for_each(|(d, &v)| *d += v * self.weight);
                }
                if C::ACTIVE {
                    let into = if first { 0 } else { 1 };
                    for t in 0..len {
                        cnt.add(cx + p0 + t, k as u32 - 1 + into);
                        cnt.mul(cx + p0 + t, 1);
                    }
                }
            } else {
                // Replication by replication over the run, in order: each pixel still sees its
                // replications in row-major order, and every loop is branch-light.
                let dst = &mut acc[p0..p0 + len];
                let mut blends = 0;
                for &(line, alpha, _, sw, op) in reps {
                    match op {
                        Operation::Add => dst.iter_mut().zip(line).for_each(|(a, &e)| *a += e as i64 * sw),
                        Operation::NonZero => {
                            blends += 1;
                            for ((a, &e), &al) in dst.iter_mut().zip(line).zip(alpha) {
                                *a = *a - ((*a * al as i64) >> 8) + e as i64 * sw;
                            }
                        }
                        Operation::Maximum => {
                            for (a, &e) in dst.iter_mut().zip(line) {
                                let b = e as i64 * sw;
                                if b.abs() >= a.abs() {
                                    *a = b;
                                }
                            }
                        }
                    }
                    if let (Some(c), false) = (cover.as_deref_mut(), op == Operation::Add) {
                        for (cv, &al) in c[p0..p0 + len].iter_mut().zip(alpha) {
                            *cv = (*cv as u32 + al as u32 - ((*cv as u32 * al as u32) >> 8)) as u16;
                        }
                    }
                }
                if C::ACTIVE {
                    for t in 0..len {
                        cnt.add(cx + p0 + t, k as u32);
                        cnt.mul(cx + p0 + t, k as u32 + blends);
                    }
                }
            }
            x += len as u64;
        }
    }

    /// Applies the layer prefiltered at resolution `r` ≤ 0 to the pixels (x0 .., y) of its
    /// level: every pixel is the box mean of the resolution-1 field over 2^(1−r) pixels a side.
    pub fn apply_prefiltered(&self, copies: &Copies, plane: usize, r: i64, y: u64, x0: u64, acc: &mut [i64]) {
        let sat = self.sat[plane].get_or_init(|| Sat::build(self, copies));
        let shift = (1 - r) as u32;
        let f = 1u64 << shift;
        let (w, h) = (self.w as u64, self.h as u64);
        // The footprint [fx, fx + f) × [fy, fy + f) of the resolution-1 field, reduced by its
        // period; fx advances by f mod w per pixel, without division.
        let fy = ((y as u128 * f as u128) % h as u128) as u64;
        let rows = sat.rows(fy, f);
        let step = f % w;
        let mut fx = ((x0 as u128 * f as u128) % w as u128) as u64;
        let whole = 1i128 << (2 * shift + 8);
        // Up to 64 × 64 footprints every term fits in i64 (a footprint's sum is below 2^47 and
        // its prefix sums may wrap but their difference does not), beyond that in i128.
        let narrow = shift <= 6;
        for a in acc.iter_mut() {
            let (sum, cov) = if narrow {
                let (s, c) = sat.rect::<i64>(fx, &rows);
                (s as i128, c as i128)
            } else {
                sat.rect::<i128>(fx, &rows)
            };
            *a = if self.all_add {
                *a + (sum >> (2 * shift)) as i64
            } else if narrow {
                // Coverage is in 1/256 of a pixel; a·(whole − cov) < 2^41 · 2^20.
                (*a * (whole - cov) as i64 + ((sum as i64) << 8)) >> (2 * shift + 8)
            } else {
                ((*a as i128 * (whole - cov) + (sum << 8)) >> (2 * shift + 8)) as i64
            };
            fx += step;
            if fx >= w {
                fx -= w;
            }
        }
    }
}

/// Integer arithmetic for summed-area look-ups: i64 wraps (its results are exact when the true
/// result fits), i128 never overflows here.
trait Wide: Copy {
    fn of(v: i64) -> Self;
    fn add(self, o: Self) -> Self;
    fn sub(self, o: Self) -> Self;
    fn mul(self, o: Self) -> Self;
}

impl Wide for i64 {
    #[inline]
    fn of(v: i64) -> Self {
        v
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        self.wrapping_add(o)
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        self.wrapping_sub(o)
    }
    #[inline]
    fn mul(self, o: Self) -> Self {
        self.wrapping_mul(o)
    }
}

impl Wide for i128 {
    #[inline]
    fn of(v: i64) -> Self {
        v as i128
    }
    #[inline]
    fn add(self, o: Self) -> Self {
        self + o
    }
    #[inline]
    fn sub(self, o: Self) -> Self {
        self - o
    }
    #[inline]
    fn mul(self, o: Self) -> Self {
        self * o
    }
}

/// The two rows of a footprint, y0 = fy < h and y1 = fy + f: (whole periods, remainder).
struct Rows {
    y0: usize,
    q1: i128,
    r1: usize,
    /// f = fq·w + fr.
    fq: i128,
    fr: u64,
}

/// Summed-area tables over one LCM period of a layer's resolution-1 field, applied onto zero.
#[derive(Debug)]
struct Sat {
    w: usize,
    h: usize,
    value: Vec<i64>,
    cover: Vec<i64>,
}

impl Sat {
    fn build(layer: &Layer, copies: &Copies) -> Sat {
        let (w, h) = (layer.w, layer.h);
        let mut value = vec![0i64; (w + 1) * (h + 1)];
        let mut cover = vec![0i64; (w + 1) * (h + 1)];
        let mut row = vec![0i64; w];
        let mut cov = vec![0u16; w];
        for y in 0..h {
            row.fill(0);
            cov.fill(0);
            layer.apply_native(copies, 1, y as u64, 0, &mut row, Some(&mut cov), true, &mut NoCount, 0);
            let (mut rs, mut rc) = (0i64, 0i64);
            for x in 0..w {
                rs += row[x];
                rc += cov[x] as i64;
                let at = (y + 1) * (w + 1) + x + 1;
                value[at] = value[at - (w + 1)] + rs;
                cover[at] = cover[at - (w + 1)] + rc;
            }
        }
        Sat { w, h, value, cover }
    }

    fn rows(&self, fy: u64, f: u64) -> Rows {
        let y1 = fy + f;
        let w = self.w as u64;
        Rows {
            y0: fy as usize,
            q1: (y1 / self.h as u64) as i128,
            r1: (y1 % self.h as u64) as usize,
            fq: (f / w) as i128,
            fr: f % w,
        }
    }

    /// (sum, coverage) over the f × f square at (fx, rows.y0) of the periodic field, fx < w:
    /// four corners of the prefix sum F(x, y) = qx·qy·T + qx·S(w, ry) + qy·S(rx, h) + S(rx, ry)
    /// where x = qx·w + rx and y = qy·h + ry.
    fn rect<T: Wide>(&self, fx: u64, rows: &Rows) -> (T, T) {
        // x1 = fx + f, split as f = fq·w + fr without dividing per pixel.
        let (fq, fr) = (rows.fq, rows.fr);
        let t = fx + fr;
        let (q1, r1) = if t >= self.w as u64 { (fq + 1, (t - self.w as u64) as usize) } else { (fq, t as usize) };
        let x0 = fx as usize;
        let (w, h) = (self.w, self.h);
        let (q1, rq1) = (T::of(q1 as i64), T::of(rows.q1 as i64));
        let one = |t: &[i64]| {
            let s = |a: usize, b: usize| T::of(t[b * (w + 1) + a]);
            let f00 = s(x0, rows.y0);
            let f10 = q1.mul(s(w, rows.y0)).add(s(r1, rows.y0));
            let f01 = rq1.mul(s(x0, h)).add(s(x0, rows.r1));
            let f11 = q1.mul(rq1).mul(s(w, h)).add(q1.mul(s(w, rows.r1))).add(rq1.mul(s(r1, h))).add(s(r1, rows.r1));
            f11.sub(f10).sub(f01).add(f00)
        };
        (one(&self.value), one(&self.cover))
    }
}
