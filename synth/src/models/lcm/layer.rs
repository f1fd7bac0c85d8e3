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

/// One replication over a run of pixels: which oriented copy, where in it the run starts,
/// its sign, sign × weight and operation (the same in every plane).
#[derive(Clone, Copy, Default)]
struct Rep {
    orientation: usize,
    at: usize,
    sign: i64,
    weighted: i64,
    op: Operation,
}

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
    /// Summed-area tables of the resolution-1 field, made when first needed.
    sat: OnceLock<Sat>,
}

impl Layer {
    pub fn new(index: u32, weight: i64, w: usize, h: usize, codes: &[u8]) -> Layer {
        let codes: Vec<u8> = codes.iter().map(|&c| Event::canonical(c)).collect();
        let all_add = codes.iter().all(|&c| c == 0 || Event::operation_of(c) == Operation::Add);
        Layer { index, weight, w, h, codes, all_add, sat: OnceLock::new() }
    }

    /// Applies the layer at resolution `r` ≥ 1 to the pixels (x0 .. x0 + len, y) of its level,
    /// in every intensity plane at once: `acc[p]` holds plane p's intensities and takes
    /// `copies[p]`'s elements, so each run of pixels finds its replications once for all
    /// planes. `first` says `acc` holds nothing yet. `cover[p]`, when given, accumulates the
    /// coverage (0..=256) of plane p's non-additive replications.
    #[allow(clippy::too_many_arguments)]
    pub fn apply_native<C: Counter>(
        &self,
        copies: &[Copies],
        r: u32,
        y: u64,
        x0: u64,
        acc: &mut [&mut [i64]],
        mut cover: Option<&mut [&mut [u16]]>,
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
        let end = x0 + acc[0].len() as u64;
        let planes = acc.len() as u32;
        let mut x = x0;
        // The LCM column of the current point span, advanced without division.
        let mut col = (x0 >> sh) % w;
        let mut sums = [0i64; 1 << (super::element::MAX_TOP - 1)];
        while x < end {
            let u0 = (x & (hh - 1)) as usize;
            let len = (hh - u0 as u64).min(end - x) as usize;
            let cols = [(if col == 0 { w - 1 } else { col - 1 }, hh as usize), (col, 0)];
            col = if col + 1 == w { 0 } else { col + 1 };
            let mut reps = [Rep::default(); 4];
            let mut k = 0;
            for &(row, vl) in &rows {
                for &(col, uoff) in &cols {
                    let code = self.codes[(row * w + col) as usize];
                    if code != 0 {
                        let sign = Event::sign_of(code) as i64;
                        reps[k] = Rep {
                            orientation: Event::orientation_of(code),
                            at: vl * s + uoff + u0,
                            sign,
                            weighted: sign * self.weight,
                            op: Event::operation_of(code),
                        };
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
                for (plane, acc) in copies.iter().zip(acc.iter_mut()) {
                    let sum = &mut sums[..len];
                    let line = |rep: &Rep| &plane.get(r, rep.orientation)[rep.at..rep.at + len];
                    let negate = reps[0].sign < 0;
                    for (d, &e) in sum.iter_mut().zip(line(&reps[0])) {
                        *d = if negate { -(e as i64) } else { e as i64 };
                    }
                    for rep in &reps[1..] {
                        if rep.sign > 0 {
                            sum.iter_mut().zip(line(rep)).for_each(|(d, &e)| *d += e as i64);
                        } else {
                            sum.iter_mut().zip(line(rep)).for_each(|(d, &e)| *d -= e as i64);
                        }
                    }
                    let dst = &mut acc[p0..p0 + len];
                    if first {
                        dst.iter_mut().zip(sum.iter()).for_each(|(d, &v)| *d = v * self.weight);
                    } else {
                        dst.iter_mut().zip(sum.iter()).for_each(|(d, &v)| *d += v * self.weight);
                    }
                }
                if C::ACTIVE {
                    let into = if first { 0 } else { 1 };
                    for t in 0..len {
                        cnt.add(cx + p0 + t, (k as u32 - 1 + into) * planes);
                        cnt.mul(cx + p0 + t, planes);
                    }
                }
            } else {
                // Replication by replication over the run, in order: each pixel still sees its
                // replications in row-major order, and every loop is branch-light.
                for (p, (plane, acc)) in copies.iter().zip(acc.iter_mut()).enumerate() {
                    let dst = &mut acc[p0..p0 + len];
                    for rep in reps {
                        let at = rep.at..rep.at + len;
                        let (line, alpha) =
                            (&plane.get(r, rep.orientation)[at.clone()], &plane.alpha(r, rep.orientation)[at]);
                        let sw = rep.weighted;
                        match rep.op {
                            Operation::Add => dst.iter_mut().zip(line).for_each(|(a, &e)| *a += e as i64 * sw),
                            Operation::NonZero => {
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
                        if let (Some(c), false) = (cover.as_deref_mut(), rep.op == Operation::Add) {
                            for (cv, &al) in c[p][p0..p0 + len].iter_mut().zip(alpha) {
                                *cv = (*cv as u32 + al as u32 - ((*cv as u32 * al as u32) >> 8)) as u16;
                            }
                        }
                    }
                }
                if C::ACTIVE {
                    let blends = reps.iter().filter(|rep| rep.op == Operation::NonZero).count() as u32;
                    for t in 0..len {
                        cnt.add(cx + p0 + t, k as u32 * planes);
                        cnt.mul(cx + p0 + t, (k as u32 + blends) * planes);
                    }
                }
            }
            x += len as u64;
        }
    }

    /// Applies the layer prefiltered at resolution `r` ≤ 0 to the pixels (x0 .., y) of its
    /// level in every plane (`acc[p]` is plane p): every pixel is the box mean of the
    /// resolution-1 field over 2^(1−r) pixels a side. Footprints repeat along a row with the
    /// period w / gcd(w, 2^(1−r)), so a row looks up one period and applies it over and over.
    pub fn apply_prefiltered(&self, copies: &[Copies], r: i64, y: u64, x0: u64, acc: &mut [&mut [i64]]) {
        let sat = self.sat.get_or_init(|| Sat::build(self, copies));
        let shift = (1 - r) as u32;
        let f = 1u64 << shift;
        let (w, h) = (self.w as u64, self.h as u64);
        // The footprint [fx, fx + f) × [fy, fy + f) of the resolution-1 field, reduced by its
        // period; fx advances by f mod w per pixel, without division.
        let fy = ((y as u128 * f as u128) % h as u128) as u64;
        let rows = sat.rows(fy, f);
        let step = f % w;
        let period = (w / gcd(w, step)) as usize;
        let len = acc[0].len();
        let mut fx = ((x0 as u128 * f as u128) % w as u128) as u64;
        let whole = 1i128 << (2 * shift + 8);
        // Up to 64 × 64 footprints every term fits in i64 (a footprint's sum is below 2^47 and
        // its prefix sums may wrap but their difference does not), beyond that in i128.
        let narrow = shift <= 6;
        let planes = acc.len();
        // (sum, coverage) of one period of footprints, plane by plane.
        let n = period.min(len);
        let mut looked = vec![(0i128, 0i128); n * planes];
        for i in 0..n {
            let corners = sat.corners(fx, &rows);
            for p in 0..planes {
                looked[p * n + i] = if narrow {
                    let (s, c) = sat.rect::<i64>(&corners, p);
                    (s as i128, c as i128)
                } else {
                    sat.rect::<i128>(&corners, p)
                };
            }
            fx += step;
            if fx >= w {
                fx -= w;
            }
        }
        for (acc, looked) in acc.iter_mut().zip(looked.chunks(n)) {
            for (a, &(sum, cov)) in acc.iter_mut().zip(looked.iter().cycle()) {
                *a = if self.all_add {
                    *a + (sum >> (2 * shift)) as i64
                } else if narrow {
                    // Coverage is in 1/256 of a pixel; a·(whole − cov) < 2^41 · 2^20.
                    (*a * (whole - cov) as i64 + ((sum as i64) << 8)) >> (2 * shift + 8)
                } else {
                    ((*a as i128 * (whole - cov) + (sum << 8)) >> (2 * shift + 8)) as i64
                };
            }
        }
    }
}

/// Greatest common divisor (gcd(w, 0) = w).
fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
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

/// Where a footprint's four prefix sums F(x, y) = qx·qy·T + qx·S(w, ry) + qy·S(rx, h) + S(rx, ry)
/// (x = qx·w + rx, y = qy·h + ry) read the table: the 9 points S is taken at and the whole
/// periods qx (of x1) and qy (of y1). The same for every plane.
struct Corners {
    /// (x0, y0), (w, y0), (rx1, y0), (x0, h), (x0, ry1), (w, h), (w, ry1), (rx1, h), (rx1, ry1).
    at: [usize; 9],
    qx: i64,
    qy: i64,
}

/// Summed-area tables over one LCM period of a layer's resolution-1 field, applied onto zero,
/// for every plane: each point holds (value, coverage) of plane 0, then of plane 1, …
#[derive(Debug)]
struct Sat {
    w: usize,
    h: usize,
    planes: usize,
    table: Vec<i64>,
}

impl Sat {
    fn build(layer: &Layer, copies: &[Copies]) -> Sat {
        let (w, h, planes) = (layer.w, layer.h, copies.len());
        let stride = 2 * planes;
        let mut table = vec![0i64; (w + 1) * (h + 1) * stride];
        let mut rows = vec![vec![0i64; w]; planes];
        let mut covs = vec![vec![0u16; w]; planes];
        for y in 0..h {
            rows.iter_mut().for_each(|r| r.fill(0));
            covs.iter_mut().for_each(|c| c.fill(0));
            let mut acc: Vec<&mut [i64]> = rows.iter_mut().map(|r| &mut r[..]).collect();
            let mut cover: Vec<&mut [u16]> = covs.iter_mut().map(|c| &mut c[..]).collect();
            layer.apply_native(copies, 1, y as u64, 0, &mut acc, Some(&mut cover), true, &mut NoCount, 0);
            for p in 0..planes {
                let (mut rs, mut rc) = (0i64, 0i64);
                for x in 0..w {
                    rs += rows[p][x];
                    rc += covs[p][x] as i64;
                    let at = ((y + 1) * (w + 1) + x + 1) * stride + 2 * p;
                    let above = at - (w + 1) * stride;
                    table[at] = table[above] + rs;
                    table[at + 1] = table[above + 1] + rc;
                }
            }
        }
        Sat { w, h, planes, table }
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

    /// The corners of the f × f square at (fx, rows.y0) of the periodic field, fx < w.
    fn corners(&self, fx: u64, rows: &Rows) -> Corners {
        // x1 = fx + f, split as f = fq·w + fr without dividing per pixel.
        let t = fx + rows.fr;
        let (qx, rx1) =
            if t >= self.w as u64 { (rows.fq + 1, (t - self.w as u64) as usize) } else { (rows.fq, t as usize) };
        let (x0, w, h) = (fx as usize, self.w, self.h);
        let point = |x: usize, y: usize| (y * (w + 1) + x) * 2 * self.planes;
        let (y0, ry1) = (rows.y0, rows.r1);
        Corners {
            at: [
                point(x0, y0),
                point(w, y0),
                point(rx1, y0),
                point(x0, h),
                point(x0, ry1),
                point(w, h),
                point(w, ry1),
                point(rx1, h),
                point(rx1, ry1),
            ],
            qx: qx as i64,
            qy: rows.q1 as i64,
        }
    }

    /// (sum, coverage) of `plane` over the square of `c`.
    fn rect<T: Wide>(&self, c: &Corners, plane: usize) -> (T, T) {
        let (qx, qy) = (T::of(c.qx), T::of(c.qy));
        let one = |field: usize| {
            let s = |i: usize| T::of(self.table[c.at[i] + 2 * plane + field]);
            let f00 = s(0);
            let f10 = qx.mul(s(1)).add(s(2));
            let f01 = qy.mul(s(3)).add(s(4));
            let f11 = qx.mul(qy).mul(s(5)).add(qx.mul(s(6))).add(qy.mul(s(7))).add(s(8));
            f11.sub(f10).sub(f01).add(f00)
        };
        (one(0), one(1))
    }
}
