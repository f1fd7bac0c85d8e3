//! The exemplar, prepared once at load (integer only): its Gaussian pyramid or stack, its
//! 2×2-box mip chain (or box stack), which pixels are valid candidates and their neighbourhood
//! vectors; and a level's k-coherence sets ([`Coherence`]), built by the first search there.

use super::structure::Taps;
use crate::pixels::Rgba8Image;

/// Neighbourhood vectors are padded to a multiple of this many bytes, so the SSD kernel runs
/// on whole fixed-size chunks.
pub const CHUNK: usize = 32;

/// One level s of the exemplar pyramid or stack (0 = coarsest).
#[derive(Clone, Debug)]
pub struct Level {
    pub w: u32,
    pub h: u32,
    /// Exemplar pixels between the taps of a neighbourhood: 1 in a pyramid, h_s = 2^(fin − s)
    /// in a stack.
    pub spacing: u32,
    /// E_s: the Gaussian level the search compares.
    pub colour: Vec<[u8; 3]>,
    /// B_(fin − s), which colours coarse vtex levels: in a pyramid the 2×2-box mip of the sample
    /// at this size; in a stack, at each pixel u, the same rounding chain over the h_s × h_s
    /// block from u (the colour of an entry's block, had finer levels kept it).
    pub boxed: Vec<[u8; 3]>,
    /// V_s in index order: pixels whose whole neighbourhood lies in the sample.
    pub valid: Vec<u16>,
    /// Whether each pixel is in V_s.
    pub is_valid: Vec<bool>,
    /// V_s^low: pixels whose coarser-level part lies in the sample (generation-0 search).
    pub valid_low: Vec<u16>,
    /// Bytes of one neighbourhood vector (same-level taps, then coarser-level taps, then zeros).
    pub stride: usize,
    /// N_s(u) for every pixel u; taps outside the sample are mirrored (or wrapped).
    pub vectors: Vec<u8>,
}

impl Level {
    #[inline]
    pub fn vector(&self, u: usize) -> &[u8] {
        &self.vectors[u * self.stride..(u + 1) * self.stride]
    }
}

/// The k-coherence sets of one level and their shifts by the 3×3 window.
#[derive(Clone, Debug)]
pub struct Coherence {
    k: usize,
    /// C_s(u): `k` slots a pixel, the first `kset_len[u]` used; the pixel itself first.
    kset: Vec<u16>,
    kset_len: Vec<u8>,
    /// For each pixel v and 3×3 offset d (row-major), the valid pixels of C_s(v) − d: the
    /// candidates v contributes to the entry at −d from it; `k` slots, `shifted_len` used.
    shifted: Vec<u16>,
    shifted_len: Vec<u8>,
    /// Whether the first of those is v − d itself (v's coherent continuation), not a pixel
    /// merely similar to v.
    shifted_coherent: Vec<bool>,
}

impl Coherence {
    #[inline]
    pub fn kset(&self, u: usize) -> &[u16] {
        &self.kset[u * self.k..u * self.k + self.kset_len[u] as usize]
    }

    /// The valid pixels of C_s(v) − d, d the `d`-th offset of the 3×3 square.
    #[inline]
    pub fn shifted(&self, v: usize, d: usize) -> &[u16] {
        let at = v * 9 + d;
        &self.shifted[at * self.k..at * self.k + self.shifted_len[at] as usize]
    }

    /// Whether the first pixel of [`Coherence::shifted`] is v's coherent continuation.
    #[inline]
    pub fn shifted_coherent(&self, v: usize, d: usize) -> bool {
        self.shifted_coherent[v * 9 + d]
    }
}

/// What to prepare, from the parameters.
#[derive(Clone, Debug)]
pub struct Options {
    pub levels: u8,
    /// A Gaussian stack instead of a pyramid.
    pub stack: bool,
    pub same: Taps,
    pub lower: Taps,
    pub wrap: bool,
    /// k-coherence set size; 0 builds none (exhaustive search).
    pub k: usize,
    pub k_exclusion: u32,
    /// Whether the coarsest level is searched (more than one generation there).
    pub coarsest_search: bool,
}

/// The prepared exemplar.
#[derive(Clone, Debug)]
pub struct Exemplar {
    pub levels: Vec<Level>,
    pub k: usize,
    pub stack: bool,
    k_exclusion: u32,
    /// Same-level and coarser-level taps of a neighbourhood vector (level 0 has no coarser ones).
    taps: (usize, usize),
    wrap: bool,
}

/// A coordinate reduced into 0..n: wrapped, or mirrored without repeating the edge
/// (reflect-101: −1 → 1, n → n − 2).
#[inline]
fn border(v: i64, n: i64, wrap: bool) -> i64 {
    if wrap {
        return v.rem_euclid(n);
    }
    let period = 2 * (n - 1);
    let m = v.rem_euclid(period);
    if m < n {
        m
    } else {
        period - m
    }
}

/// One level down the Gaussian pyramid: the separable binomial [1 4 6 4 1]/16 at the even
/// pixels, exact in integers with one rounding ((Σ + 128) >> 8).
pub fn gaussian_down(src: &[[u8; 3]], w: u32, h: u32, wrap: bool) -> Vec<[u8; 3]> {
    let blurred = blur(src, w, h, 1, wrap);
    let (ow, oh) = (w as usize / 2, h as usize / 2);
    (0..ow * oh).map(|i| blurred[(2 * (i / ow)) * w as usize + 2 * (i % ow)]).collect()
}

/// The separable binomial [1 4 6 4 1]/16 with its taps `step` pixels apart, at every pixel,
/// exact in integers with one rounding ((Σ + 128) >> 8): one level down a Gaussian stack.
pub fn blur(src: &[[u8; 3]], w: u32, h: u32, step: i64, wrap: bool) -> Vec<[u8; 3]> {
    const K: [u32; 5] = [1, 4, 6, 4, 1];
    let (w, h) = (w as i64, h as i64);
    // Horizontal pass, unrounded (≤ 16·255 a channel).
    let mut rows = vec![[0u32; 3]; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0u32; 3];
            for (i, k) in K.iter().enumerate() {
                let sx = border(x + step * (i as i64 - 2), w, wrap);
                let p = src[(y * w + sx) as usize];
                (0..3).for_each(|c| acc[c] += k * p[c] as u32);
            }
            rows[(y * w + x) as usize] = acc;
        }
    }
    let mut out = vec![[0u8; 3]; (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let mut acc = [0u32; 3];
            for (i, k) in K.iter().enumerate() {
                let sy = border(y + step * (i as i64 - 2), h, wrap);
                let p = rows[(sy * w + x) as usize];
                (0..3).for_each(|c| acc[c] += k * p[c]);
            }
            out[(y * w + x) as usize] = acc.map(|a| ((a + 128) >> 8) as u8);
        }
    }
    out
}

/// One level down a box stack: at each pixel, the rounded mean of `src` at the four corners of
/// a `step`-sided square from it (as `mip::downsample` rounds), wrapped or clamped at the edges.
fn box_down(src: &[[u8; 3]], w: u32, h: u32, step: i64, wrap: bool) -> Vec<[u8; 3]> {
    let (w, h) = (w as i64, h as i64);
    let at = |v: i64, n: i64| if wrap { v.rem_euclid(n) } else { v.min(n - 1) };
    (0..w * h)
        .map(|i| {
            let (x, y) = (i % w, i / w);
            let mut acc = [0u32; 3];
            for (dx, dy) in [(0, 0), (step, 0), (0, step), (step, step)] {
                let p = src[(at(y + dy, h) * w + at(x + dx, w)) as usize];
                (0..3).for_each(|c| acc[c] += p[c] as u32);
            }
            acc.map(|a| ((a + 2) / 4) as u8)
        })
        .collect()
}

/// Sum of squared differences of two padded vectors, in fixed-size chunks the compiler
/// vectorises.
#[cfg(test)]
pub fn ssd(a: &[u8], b: &[u8]) -> u32 {
    ssd_below(a, b, u32::MAX)
}

/// The sum of squared differences of two padded vectors, abandoned once it reaches `bound`:
/// exact below `bound`, otherwise some value ≥ `bound`. Fixed-size chunks let the compiler
/// vectorise.
#[inline(always)]
pub fn ssd_below(a: &[u8], b: &[u8], bound: u32) -> u32 {
    let mut total = 0u32;
    for (x, y) in a.chunks_exact(CHUNK).zip(b.chunks_exact(CHUNK)) {
        let mut acc = 0i32;
        for i in 0..CHUNK {
            let d = x[i].abs_diff(y[i]) as i32;
            acc += d * d;
        }
        total += acc as u32;
        if total >= bound {
            return total;
        }
    }
    total
}

impl Exemplar {
    /// Prepares `sample` (its sides multiples of 2^(levels − 1), at least 4 × that).
    pub fn build(sample: &Rgba8Image, o: &Options) -> Exemplar {
        let n = o.levels as usize;
        let fin = n - 1;
        // Gaussian levels E_s and box levels B_j, finest first.
        let rgb = |img: &Rgba8Image| img.data.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect::<Vec<_>>();
        let mut colours = vec![rgb(sample)];
        let mut boxed = vec![rgb(sample)];
        let (mut w, mut h) = (sample.width, sample.height);
        let mut mip = sample.clone();
        for j in 0..fin {
            if o.stack {
                let step = 1 << j;
                colours.push(blur(colours.last().unwrap(), w, h, step, o.wrap));
                boxed.push(box_down(boxed.last().unwrap(), w, h, step, o.wrap));
            } else {
                colours.push(gaussian_down(colours.last().unwrap(), w, h, o.wrap));
                mip = crate::mip::downsample(&mip);
                boxed.push(rgb(&mip));
                (w, h) = (w / 2, h / 2);
            }
        }
        colours.reverse();
        boxed.reverse();
        let mut levels: Vec<Level> = Vec::with_capacity(n);
        for s in 0..n {
            let (w, h, spacing) = match o.stack {
                true => (sample.width, sample.height, 1 << (fin - s)),
                false => (sample.width >> (fin - s), sample.height >> (fin - s), 1),
            };
            let lower = if s == 0 { &[][..] } else { &o.lower[..] };
            let searched = s > 0 || o.coarsest_search;
            let mut level = Level {
                w,
                h,
                spacing,
                colour: std::mem::take(&mut colours[s]),
                boxed: std::mem::take(&mut boxed[s]),
                valid: Vec::new(),
                is_valid: Vec::new(),
                valid_low: Vec::new(),
                stride: 0,
                vectors: Vec::new(),
            };
            if searched {
                fill_neighbourhoods(&mut level, levels.last(), &o.same, lower, o.wrap);
            }
            levels.push(level);
        }
        let taps = (o.same.len(), o.lower.len());
        Exemplar { levels, k: o.k, stack: o.stack, k_exclusion: o.k_exclusion, taps, wrap: o.wrap }
    }

    /// The k-coherence sets of level `s` (searched, with k > 0).
    pub fn coherence(&self, s: usize) -> Coherence {
        let level = &self.levels[s];
        let taps = self.taps.0 + if s == 0 { 0 } else { self.taps.1 };
        let (kset, kset_len) = ksets(level, self.k, self.k_exclusion, taps);
        let mut coherence = Coherence {
            k: self.k,
            kset,
            kset_len,
            shifted: Vec::new(),
            shifted_len: Vec::new(),
            shifted_coherent: Vec::new(),
        };
        fill_shifted(level, &mut coherence, self.wrap);
        coherence
    }
}

/// Valid masks and neighbourhood vectors of `level`, whose coarser level is `coarser`.
fn fill_neighbourhoods(level: &mut Level, coarser: Option<&Level>, same: &[(i8, i8)], lower: &[(i8, i8)], wrap: bool) {
    let (w, h) = (level.w as i64, level.h as i64);
    let bytes = 3 * (same.len() + lower.len());
    let stride = bytes.div_ceil(CHUNK) * CHUNK;
    let inside = |x: i64, y: i64, w: i64, h: i64| (0..w).contains(&x) && (0..h).contains(&y);
    let mut vectors = vec![0u8; stride * (w * h) as usize];
    for y in 0..h {
        for x in 0..w {
            let u = (y * w + x) as usize;
            let v = &mut vectors[u * stride..(u + 1) * stride];
            let mut same_in = true;
            let step = level.spacing as i64;
            for (t, &(dx, dy)) in same.iter().enumerate() {
                let (sx, sy) = (x + step * dx as i64, y + step * dy as i64);
                same_in &= inside(sx, sy, w, h);
                let p = level.colour[(border(sy, h, wrap) * w + border(sx, w, wrap)) as usize];
                v[3 * t..3 * t + 3].copy_from_slice(&p);
            }
            let mut lower_in = true;
            if let Some(c) = coarser {
                let (cw, ch) = (c.w as i64, c.h as i64);
                for (t, &(dx, dy)) in lower.iter().enumerate() {
                    let (px, py) = ((x >> 1) + dx as i64, (y >> 1) + dy as i64);
                    lower_in &= inside(px, py, cw, ch);
                    let p = c.colour[(border(py, ch, wrap) * cw + border(px, cw, wrap)) as usize];
                    let at = 3 * (same.len() + t);
                    v[at..at + 3].copy_from_slice(&p);
                }
            }
            let valid = wrap || (same_in && lower_in);
            level.is_valid.push(valid);
            if valid {
                level.valid.push(u as u16);
            }
            if wrap || lower_in {
                level.valid_low.push(u as u16);
            }
        }
    }
    level.stride = stride;
    level.vectors = vectors;
}

crate::simd::widest! {
    /// C_s(u) for every pixel u: u, then the k − 1 valid v ≠ u outside its exclusion square
    /// (`exclusion` taps a side) with the smallest (SSD(N(u), N(v)), index v); compiled for the
    /// CPU's widest vector unit. Exact, but not a scan of every pair: over `taps` RGB taps,
    /// SSD(a, b) ≥ Σ_c (S_c(a) − S_c(b))² ⁄ taps ≥ (S(a) − S(b))² ⁄ (3·taps) for the channel
    /// sums S_c and their total S (Cauchy–Schwarz), so candidates are visited nearest total
    /// first and the visit ends once even that bound exceeds the worst kept.
    fn ksets(level: &Level, k: usize, exclusion: u32, taps: usize) -> (Vec<u16>, Vec<u8>) {
        let n = (level.w * level.h) as usize;
        let w = level.w as i64;
        let exclusion = (exclusion * level.spacing) as i64;
        let mut kset = vec![0u16; n * k];
        let mut kset_len = vec![0u8; n];
        let mut best: Vec<(u32, u16)> = Vec::with_capacity(k);
        let sums: Vec<[i64; 3]> = (0..n).map(|u| channel_sums(level.vector(u))).collect();
        let total = |u: usize| sums[u].iter().sum::<i64>();
        let mut order: Vec<(i64, u16)> = level.valid.iter().map(|&v| (total(v as usize), v)).collect();
        order.sort_unstable();
        let taps = taps as i64;
        for u in 0..n {
            best.clear();
            let a = level.vector(u);
            let (ux, uy, su, tu) = (u as i64 % w, u as i64 / w, sums[u], total(u));
            // Nothing to visit when the set is the pixel alone.
            let start = if k > 1 { order.partition_point(|c| c.0 < tu) } else { order.len() };
            let (mut up, mut down) = (start, if k > 1 { start } else { 0 });
            loop {
                // The nearer total of the two directions; every later one is farther.
                let next = match (order.get(up), down.checked_sub(1).map(|d| order[d])) {
                    (Some(&a), Some(b)) => if a.0 - tu <= tu - b.0 { up += 1; a } else { down -= 1; b },
                    (Some(&a), None) => { up += 1; a }
                    (None, Some(b)) => { down -= 1; b }
                    (None, None) => break,
                };
                let (tv, v) = next;
                let worst = (best.len() == k - 1).then(|| best[k - 2]);
                if let Some((d, _)) = worst {
                    if (tv - tu).pow(2) > 3 * taps * d as i64 {
                        break;
                    }
                }
                let (vx, vy) = (v as i64 % w, v as i64 / w);
                if (vx - ux).abs().max((vy - uy).abs()) <= exclusion || v as usize == u {
                    continue;
                }
                let sv = sums[v as usize];
                if let Some((d, _)) = worst {
                    if (0..3).map(|c| (su[c] - sv[c]).pow(2)).sum::<i64>() > taps * d as i64 {
                        continue;
                    }
                }
                // Exact up to the worst kept's distance, so that a tie is broken by index.
                let d = ssd_below(a, level.vector(v as usize), worst.map_or(u32::MAX, |(d, _)| d + 1));
                if worst.is_some_and(|b| (d, v) >= b) {
                    continue;
                }
                if worst.is_some() {
                    best.pop();
                }
                let at = best.partition_point(|&b| b < (d, v));
                best.insert(at, (d, v));
            }
            kset[u * k] = u as u16;
            for (i, b) in best.iter().enumerate() {
                kset[u * k + 1 + i] = b.1;
            }
            kset_len[u] = 1 + best.len() as u8;
        }
        (kset, kset_len)
    }
}

/// The sums of a neighbourhood vector's red, green and blue bytes.
fn channel_sums(vector: &[u8]) -> [i64; 3] {
    let mut sums = [0i64; 3];
    for (i, &b) in vector.iter().enumerate() {
        sums[i % 3] += b as i64;
    }
    sums
}

/// The k-coherence sets of `level` shifted by each 3×3 offset (in taps), invalid pixels dropped.
fn fill_shifted(level: &Level, coherence: &mut Coherence, wrap: bool) {
    let k = coherence.k;
    let (w, h) = (level.w as i64, level.h as i64);
    let step = level.spacing as i64;
    let n = (w * h) as usize;
    let mut shifted = vec![0u16; n * 9 * k];
    let mut shifted_len = vec![0u8; n * 9];
    let mut shifted_coherent = vec![false; n * 9];
    for v in 0..n {
        for (d, (dx, dy)) in (-1..=1).flat_map(|dy| (-1..=1).map(move |dx| (dx, dy))).enumerate() {
            let at = v * 9 + d;
            for &c in coherence.kset(v) {
                let (mut x, mut y) = (c as i64 % w - step * dx, c as i64 / w - step * dy);
                if wrap {
                    (x, y) = (x.rem_euclid(w), y.rem_euclid(h));
                } else if !(0..w).contains(&x) || !(0..h).contains(&y) {
                    continue;
                }
                let u = (y * w + x) as usize;
                if level.is_valid[u] {
                    shifted_coherent[at] |= c as usize == v;
                    shifted[at * k + shifted_len[at] as usize] = u as u16;
                    shifted_len[at] += 1;
                }
            }
        }
    }
    coherence.shifted = shifted;
    coherence.shifted_len = shifted_len;
    coherence.shifted_coherent = shifted_coherent;
}

#[cfg(test)]
mod tests {
    use super::super::structure::{circle5, square};
    use super::*;

    #[test]
    fn the_gaussian_level_of_a_constant_is_the_constant_and_of_a_step_is_exact() {
        let flat = vec![[200u8, 7, 0]; 64];
        assert_eq!(gaussian_down(&flat, 8, 8, false), vec![[200, 7, 0]; 16]);
        // A vertical step (0 left of x = 4, 255 from it) of an 8-wide image. Output column 1
        // (x = 2) sees the step with weight 1: 255·1·16/256 → 16; column 2 (x = 4) with
        // 6 + 4 + 1: 255·11·16/256 = 175.3 → 175; mirrored edges stay inside each half.
        let step: Vec<[u8; 3]> = (0..64).map(|i| if i % 8 >= 4 { [255; 3] } else { [0; 3] }).collect();
        let down = gaussian_down(&step, 8, 8, false);
        let row: Vec<u8> = down[..4].iter().map(|p| p[0]).collect();
        assert_eq!(row, vec![0, 16, 175, 255]);
        // Wrapping instead of mirroring changes only the borders: x = 0 sees 255 at x = −1, −2.
        let wrapped = gaussian_down(&step, 8, 8, true);
        assert_eq!(wrapped[0][0], ((255 * (1 + 4) * 16 + 128) >> 8) as u8);
        // Against the 2-D sum of a hashed image, rounded once, mirrored at the borders.
        let (w, h) = (64i64, 48i64);
        let img: Vec<[u8; 3]> = (0..w * h).map(|i| [0, 1, 2].map(|c| crate::hash::hash4(1, c, i, 0) as u8)).collect();
        let k = [1u32, 4, 6, 4, 1];
        let mirror = |v: i64, n: i64| {
            if v < 0 {
                -v
            } else if v >= n {
                2 * n - 2 - v
            } else {
                v
            }
        };
        let down = gaussian_down(&img, w as u32, h as u32, false);
        for y in 0..h / 2 {
            for x in 0..w / 2 {
                let mut acc = [0u32; 3];
                for j in 0..5 {
                    for i in 0..5 {
                        let p = img[(mirror(2 * y + j - 2, h) * w + mirror(2 * x + i - 2, w)) as usize];
                        (0..3).for_each(|c| acc[c] += k[i as usize] * k[j as usize] * p[c] as u32);
                    }
                }
                assert_eq!(down[(y * w / 2 + x) as usize], acc.map(|a| ((a + 128) >> 8) as u8), "({x}, {y})");
            }
        }
    }

    /// A stack level read every h_s pixels is the pyramid's level: its box colours exactly, its
    /// Gaussian colours wherever the filter's chain stays off the far edge (mirrored about the
    /// last pixel of each level in a pyramid, of the sample in a stack).
    #[test]
    fn a_stack_sampled_every_h_pixels_is_the_pyramid() {
        let img = crate::samples::pebbles(64, 7, 5, false);
        let o = |stack| Options {
            levels: 4,
            stack,
            same: circle5(),
            lower: Vec::new(),
            wrap: false,
            k: 0,
            k_exclusion: 0,
            coarsest_search: false,
        };
        let (pyramid, stack) = (Exemplar::build(&img, &o(false)), Exemplar::build(&img, &o(true)));
        for (s, (p, t)) in pyramid.levels.iter().zip(&stack.levels).enumerate() {
            let h = 1 << (3 - s);
            assert_eq!((t.w, t.spacing, p.spacing), (64, h, 1));
            for y in 0..p.h {
                for x in 0..p.w {
                    let (u, v) = ((y * p.w + x) as usize, (y * h * 64 + x * h) as usize);
                    assert_eq!(p.boxed[u], t.boxed[v], "level {s}, ({x}, {y})");
                    if x + 3 < p.w && y + 3 < p.h {
                        assert_eq!(p.colour[u], t.colour[v], "level {s}, ({x}, {y})");
                    }
                }
            }
        }
    }

    /// Checked against every pair, on a pyramid and a stack, with and without the exclusion
    /// square and wrapping: the visit that stops early finds what the full scan finds.
    #[test]
    fn ksets_start_with_the_pixel_and_are_sorted_by_ssd_then_index() {
        let img = crate::samples::lichen(32, 3);
        for (stack, wrap, k, k_exclusion) in [(false, false, 4, 0), (true, false, 2, 2), (true, true, 3, 1)] {
            let o = Options {
                levels: 2,
                stack,
                same: circle5(),
                lower: if stack { Vec::new() } else { square(1) },
                wrap,
                k,
                k_exclusion,
                coarsest_search: false,
            };
            let ex = Exemplar::build(&img, &o);
            for (s, l) in ex.levels.iter().enumerate().skip(1) {
                let coherence = ex.coherence(s);
                assert!(!l.valid.is_empty());
                let w = l.w as i64;
                let excluded = |u: usize, v: u16| {
                    let (u, v) = (u as i64, v as i64);
                    (u % w - v % w).abs().max((u / w - v / w).abs()) <= (k_exclusion * l.spacing) as i64
                };
                for u in 0..(l.w * l.h) as usize {
                    let set = coherence.kset(u);
                    assert_eq!(set[0] as usize, u);
                    assert_eq!(set.len(), k);
                    let key = |v: u16| (ssd(l.vector(u), l.vector(v as usize)), v);
                    // Sorted, and nothing valid outside the set beats its last member.
                    assert!(set[1..].windows(2).all(|p| key(p[0]) < key(p[1])), "{u}: {set:?}");
                    assert!(set[1..].iter().all(|&v| !excluded(u, v)), "{u}: {set:?}");
                    let worst = key(set[k - 1]);
                    for &v in &l.valid {
                        if !set.contains(&v) && v as usize != u && !excluded(u, v) {
                            assert!(key(v) > worst, "stack {stack}: {u}: {v} beats {set:?}");
                        }
                    }
                }
            }
        }
    }
}
