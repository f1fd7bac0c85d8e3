//! Coarse vtex levels from the synthesis pyramid itself, for mip coherence: vtex
//! level j must approximate the 2×2-box chain of level 0, which a 100k texture cannot afford.
//!
//! * Levels 1..=`exact_levels`: level 0 rendered and box-filtered j times (exact).
//! * Up to K − 1 + `noise_levels`: the synthesis level r = min(j − lookahead, K − 1) steps
//!   coarser than the finest, evaluated over the tile's footprint, each entry coloured with the
//!   exemplar's own box mip B_r at its coordinate, then box-filtered j − r times with the same
//!   rounding as vtex. With lookahead 1, level 1 is exact. At the coarsest synthesis level the
//!   colour of an exemplar coordinate u is g(u), the measured mean colour of the level-0 blocks
//!   grown from u, so levels beyond the pyramid are exact averages of coloured noise.
//!   Finer levels correct what coarser ones drew, so a coarse entry's colour predicts its
//!   block only in part and the averages lose contrast; each level's deviations from the mean
//!   are scaled by a gain measured on the calibration windows, where the exact chain is known,
//!   so its σ is the chain's.
//! * With `mip_generations`, level j reads an earlier generation m of its synthesis level,
//!   skipping the last subpasses (most of a tile one level finer than itself costs). Generation
//!   0 (the upsampled coordinates) is coloured whole; a later one by its searched entries
//!   alone, which with four subpasses are final, the others being upsampled guesses whose
//!   errors would not average out at coarser levels. Either is coloured with g_s, the measured
//!   mean colour of the level-0 blocks grown from an entry, as the coarsest level is with g.
//! * Beyond: the texture's mean colour, flat (a pixel there averages thousands of independent
//!   noise cells).

use super::levels::SynthesisLevels;
use super::rect::Rect;
use crate::hash::hash4;
use crate::mip::downsample_n;
use crate::pixels::Rgba8Image;
use crate::texture::wrap;
use crate::Stop;
use std::sync::OnceLock;

/// Hash stream of the calibration windows' positions.
pub const STREAM_CALIBRATION: u64 = 0x0043_414c_4942;
/// Calibration windows of level 0, and their side (at least two coarsest-level pixels).
const WINDOWS: i64 = 64;
const WINDOW: u32 = 64;

/// Where a vtex level's pixels come from.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Source {
    /// Level 0, box-filtered.
    Exact,
    /// Generation m of synthesis level K − 1 − r, coloured with B_r (g at the coarsest),
    /// box-filtered j − r times.
    Pyramid { r: u32, m: u8 },
    /// The mean colour.
    Mean,
}

impl Source {
    /// Whether the source is level 0 itself, box-filtered.
    fn exact(self, p: &super::Params) -> bool {
        match self {
            Source::Exact => true,
            Source::Pyramid { r: 0, m } => m == latest(p, p.levels - 1),
            _ => false,
        }
    }
}

/// The latest generation of synthesis level `s`.
fn latest(p: &super::Params, s: u8) -> u8 {
    if s == 0 {
        p.coarsest_generations - 1
    } else {
        p.generations() - 1
    }
}

/// The source of vtex level `l` ≥ 1.
pub fn source(p: &super::Params, l: u32) -> Source {
    let fin = p.levels as u32 - 1;
    if l <= p.mip.exact_levels as u32 {
        Source::Exact
    } else if l > fin + p.mip.noise_levels as u32 {
        Source::Mean
    } else {
        let r = (l - p.mip.lookahead as u32).min(fin);
        let last = latest(p, (fin - r) as u8);
        Source::Pyramid { r, m: p.mip_generation(l, last) }
    }
}

/// How many times level `l`'s source is box-filtered: a pixel covers 2^span × 2^span of it.
pub fn span(p: &super::Params, l: u32) -> u32 {
    match (l, source(p, l.max(1))) {
        (0, _) => 0,
        (_, Source::Exact) => l,
        (_, Source::Pyramid { r, .. }) => l - r,
        (_, Source::Mean) => 0,
    }
}

/// What the coarsest synthesis level looks like from afar: a colour per exemplar coordinate,
/// and the texture's mean.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Calibration {
    /// g(u): mean level-0 colour of the blocks whose coarsest-level coordinate is u (B at u
    /// where no block of the windows grew from u, and everywhere in a stack).
    pub g: Vec<[u8; 3]>,
    /// Per synthesis level s above the coarsest that a coarse vtex level reads before its
    /// latest generation: g_s(u), the mean level-0 colour of the blocks grown from an entry u
    /// of the generation read (B_s where none grew, binned in a stack as g is).
    pub measured: Vec<Option<Vec<[u8; 3]>>>,
    pub mean: [u8; 3],
    /// Per vtex level, how its pyramid source is brought to the exact chain's contrast around
    /// the texture's mean; `None` where the source is exact, or a window is smaller than a
    /// pixel of the level.
    pub contrast: Vec<Option<Contrast>>,
}

/// `mean` + `gain` × (v − `centre`): the deviations of a level's source from its own mean,
/// scaled to the σ of the exact chain.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Contrast {
    /// The source's mean colour on the windows, in 1/256.
    centre: [i64; 3],
    /// σ of the exact chain over σ of the source on the windows, in 1/256.
    gain: i64,
}

impl Calibration {
    /// Measured over [`WINDOWS`] deterministic level-0 windows; `None` once `stop` is requested.
    pub fn compute(tex: &SynthesisLevels, stop: &dyn Stop) -> Option<Calibration> {
        let p = tex.params();
        let fin = p.levels as u32 - 1;
        let block = 1i64 << fin;
        let side = WINDOW.max(2 * block as u32);
        let coarsest = &tex.synthesizer().exemplar().levels[0];
        let n = coarsest.colour.len();
        // A stack's coarsest level has a coordinate per sample pixel, too many for the windows
        // to measure one by one: g is measured per bin of `bin` × `bin` coordinates.
        let stack = tex.synthesizer().exemplar().stack;
        let bin: usize = if stack { 1 << fin } else { 1 };
        let bins_w = coarsest.w as usize / bin;
        let key = |u: usize| (u / coarsest.w as usize / bin) * bins_w + u % coarsest.w as usize / bin;
        let mut sums = vec![[0u64; 4]; n / (bin * bin)];
        let mut windows = Vec::with_capacity(WINDOWS as usize);
        for i in 0..WINDOWS {
            let h = hash4(p.seed, STREAM_CALIBRATION, i, 0);
            let (mut x, mut y) = ((h as i64) >> 24, (h.rotate_left(32) as i64) >> 24);
            if p.domain == super::params::DomainSpec::Torus {
                (x, y) = (wrap(x, p.width) as i64, wrap(y, p.height) as i64);
            }
            // Aligned to the window's side, so each window is whole pixels of every level measured.
            let (x, y) = (x & !(side as i64 - 1), y & !(side as i64 - 1));
            let img = tex.level0(x, y, side, side, stop)?;
            let cells = side as usize >> fin;
            let rect = Rect { x: x >> fin, y: y >> fin, w: cells, h: cells };
            let coarse = tex.entries(0, rect, stop)?;
            for (k, &u) in coarse.iter().enumerate() {
                let (bx, by) = ((k % cells) << fin, (k / cells) << fin);
                let acc = &mut sums[key(u as usize)];
                for j in 0..block as usize {
                    let row = (by + j) * side as usize + bx;
                    for px in img.data[row * 4..(row + block as usize) * 4].chunks_exact(4) {
                        (0..3).for_each(|c| acc[c] += px[c] as u64);
                        acc[3] += 1;
                    }
                }
            }
            windows.push((x, y, img));
        }
        let g: Vec<[u8; 3]> = (0..n)
            .map(|u| match sums[key(u)] {
                s if s[3] == 0 => coarsest.boxed[u],
                s => [0, 1, 2].map(|c| ((s[c] + s[3] / 2) / s[3]) as u8),
            })
            .collect();
        // The noise is uniform over a pyramid's coarsest level, so with one generation there
        // the texture's mean is g's plain mean; otherwise (or binned) weigh g by how often each
        // u grew.
        let (total, weight) = if p.coarsest_generations == 1 && !stack {
            let t = g.iter().fold([0u64; 3], |a, c| [0, 1, 2].map(|k| a[k] + c[k] as u64));
            (t, n as u64)
        } else {
            let t = sums.iter().fold([0u64; 3], |a, s| [0, 1, 2].map(|k| a[k] + s[k]));
            (t, sums.iter().map(|s| s[3]).sum())
        };
        let mean = total.map(|t| ((t + weight / 2) / weight) as u8);
        let top = fin + p.mip.noise_levels as u32;
        let mut measured = vec![None; fin as usize + 1];
        for (s, slot) in measured.iter_mut().enumerate().skip(1) {
            let r = fin - s as u32;
            let read = (1..=top).find_map(|l| match source(p, l) {
                Source::Pyramid { r: rr, m } if rr == r && m < latest(p, s as u8) => Some(m),
                _ => None,
            });
            // Generation 0 is coloured whole; a later one by its searched entries, which are
            // the latest's.
            if let Some(m) = read {
                let m = if m == 0 { 0 } else { latest(p, s as u8) };
                *slot = Some(measure(tex, &windows, s as u8, m, stop)?);
            }
        }
        let mut contrast = vec![None; top as usize + 1];
        for (l, contrast) in contrast.iter_mut().enumerate().skip(1) {
            let l = l as u32;
            let src = source(p, l);
            let Source::Pyramid { r, m } = src else { continue };
            if src.exact(p) || side >> l == 0 {
                continue;
            }
            let (mut exact, mut raw) = (Moments::default(), Moments::default());
            for (x, y, img) in &windows {
                exact.add(&downsample_n(img, l));
                raw.add(&pyramid(tex, &g, &measured, r, m, l - r, x >> l, y >> l, side >> l, side >> l, stop)?);
            }
            *contrast = Some(Contrast { centre: raw.mean_q8(), gain: exact.gain_over(&raw) });
        }
        Some(Calibration { g, measured, mean, contrast })
    }

    /// `img` (a source of level `l`) brought to the exact chain's contrast.
    fn adjust(&self, l: u32, img: &mut Rgba8Image) {
        let Some(Contrast { centre, gain }) = self.contrast[l as usize] else { return };
        for px in img.data.chunks_exact_mut(4) {
            for c in 0..3 {
                let deviation = ((px[c] as i64) << 8) - centre[c];
                px[c] = (self.mean[c] as i64 + ((deviation * gain + (1 << 15)) >> 16)).clamp(0, 255) as u8;
            }
        }
    }
}

/// g_s: the mean level-0 colour over `windows` of the blocks whose level-`s` entry at generation
/// `m` is u, per bin of u (see [`Calibration::measured`]); `None` once `stop` is requested.
fn measure(
    tex: &SynthesisLevels,
    windows: &[(i64, i64, Rgba8Image)],
    s: u8,
    m: u8,
    stop: &dyn Stop,
) -> Option<Vec<[u8; 3]>> {
    let shift = tex.params().levels as u32 - 1 - s as u32;
    let block = 1usize << shift;
    let level = &tex.synthesizer().exemplar().levels[s as usize];
    let bin: usize = if tex.synthesizer().exemplar().stack { block } else { 1 };
    let (w, n) = (level.w as usize, level.colour.len());
    let bins_w = w.div_ceil(bin);
    let key = |u: usize| (u / w / bin) * bins_w + u % w / bin;
    let mut sums = vec![[0u64; 4]; bins_w * (n / w).div_ceil(bin)];
    for (x, y, img) in windows {
        let side = img.width as usize;
        let cells = side >> shift;
        let entries = tex.entries_at(s, m, Rect { x: x >> shift, y: y >> shift, w: cells, h: cells }, stop)?;
        for (k, &u) in entries.iter().enumerate() {
            let (bx, by) = ((k % cells) << shift, (k / cells) << shift);
            let acc = &mut sums[key(u as usize)];
            for j in 0..block {
                let row = (by + j) * side + bx;
                for px in img.data[row * 4..(row + block) * 4].chunks_exact(4) {
                    (0..3).for_each(|c| acc[c] += px[c] as u64);
                    acc[3] += 1;
                }
            }
        }
    }
    Some(
        (0..n)
            .map(|u| match sums[key(u)] {
                s if s[3] == 0 => level.boxed[u],
                s => [0, 1, 2].map(|c| ((s[c] + s[3] / 2) / s[3]) as u8),
            })
            .collect(),
    )
}

/// Sums of the RGB channels and their squares over some images, for σ.
#[derive(Default)]
struct Moments {
    sum: [u64; 3],
    squares: [u64; 3],
    n: u64,
}

impl Moments {
    fn add(&mut self, img: &Rgba8Image) {
        for px in img.data.chunks_exact(4) {
            for (c, &v) in px[..3].iter().enumerate() {
                self.sum[c] += v as u64;
                self.squares[c] += (v as u64).pow(2);
            }
        }
        self.n += img.data.len() as u64 / 4;
    }

    /// The mean of each channel in 1/256.
    fn mean_q8(&self) -> [i64; 3] {
        self.sum.map(|s| (((s << 9) / self.n.max(1)) as i64 + 1) >> 1)
    }

    /// Variance summed over the channels, times n² (exact in integers).
    fn variance_n2(&self) -> u128 {
        (0..3).map(|c| self.squares[c] as u128 * self.n as u128 - (self.sum[c] as u128).pow(2)).sum()
    }

    /// σ of `self` over σ of `other` in 1/256 (of equal counts; one where `other` is flat).
    fn gain_over(&self, other: &Moments) -> i64 {
        let (a, b) = (self.variance_n2(), other.variance_n2());
        if b == 0 {
            return 256;
        }
        ((a << 16) / b).isqrt() as i64
    }
}

/// The calibration kept in `cell`, computed there first if no render has yet; `None` when
/// `stop` is requested before it is whole.
fn calibration<'a>(tex: &SynthesisLevels, cell: &'a OnceLock<Calibration>, stop: &dyn Stop) -> Option<&'a Calibration> {
    if let Some(c) = cell.get() {
        return Some(c);
    }
    let c = Calibration::compute(tex, stop)?;
    Some(cell.get_or_init(|| c))
}

/// Renders the pixels of `area` of level `l` ≥ 1 with the calibration kept in `cell`, or
/// `None` once `stop` is requested.
pub fn render(
    tex: &SynthesisLevels,
    cell: &OnceLock<Calibration>,
    l: u32,
    area: Rect,
    stop: &dyn Stop,
) -> Option<Rgba8Image> {
    let Rect { x, y, w, h } = area;
    let (w, h) = (w as u32, h as u32);
    let src = source(tex.params(), l);
    match src {
        Source::Exact => Some(downsample_n(&tex.level0(x << l, y << l, w << l, h << l, stop)?, l)),
        Source::Mean => {
            let c = calibration(tex, cell, stop)?.mean;
            let mut img = Rgba8Image::new(w, h);
            for px in img.data.chunks_exact_mut(4) {
                px.copy_from_slice(&[c[0], c[1], c[2], 255]);
            }
            Some(img)
        }
        // The finest synthesis level's latest generation coloured by the sample: exact.
        Source::Pyramid { r, m } if src.exact(tex.params()) => pyramid(tex, &[], &[], r, m, l, x, y, w, h, stop),
        Source::Pyramid { r, m } => {
            let cal = calibration(tex, cell, stop)?;
            let mut img = pyramid(tex, &cal.g, &cal.measured, r, m, l - r, x, y, w, h, stop)?;
            cal.adjust(l, &mut img);
            Some(img)
        }
    }
}

/// `w × h` pixels at (x, y) of generation `m` of synthesis level K − 1 − `r` coloured with
/// B_r (`g` at the coarsest) and box-filtered `d` times, or `None` once `stop` is requested.
#[allow(clippy::too_many_arguments)]
fn pyramid(
    tex: &SynthesisLevels,
    g: &[[u8; 3]],
    measured: &[Option<Vec<[u8; 3]>>],
    r: u32,
    m: u8,
    d: u32,
    x: i64,
    y: i64,
    w: u32,
    h: u32,
    stop: &dyn Stop,
) -> Option<Rgba8Image> {
    let s = tex.params().levels as u32 - 1 - r;
    let rect = Rect { x: x << d, y: y << d, w: (w as usize) << d, h: (h as usize) << d };
    let colours = match measured.get(s as usize) {
        _ if s == 0 => g,
        Some(Some(g)) => g,
        _ => &tex.synthesizer().exemplar().levels[s as usize].boxed,
    };
    let values = tex.entries_at(s as u8, m, rect, stop)?;
    let st = tex.synthesizer().structure();
    if d == 0 || m == 0 || m == st.last(s as u8) {
        let mut img = Rgba8Image::new(w << d, h << d);
        for (px, &v) in img.data.chunks_exact_mut(4).zip(&values) {
            let c = colours[v as usize];
            px.copy_from_slice(&[c[0], c[1], c[2], 255]);
        }
        return Some(downsample_n(&img, d));
    }
    // Before a level's latest generation, the entries some generation has updated are the
    // searched ones (with four subpasses, final), the others still upsampled guesses whose
    // errors do not average out over coarser levels: each 2×2 block is coloured by its
    // updated entries alone.
    let updated = |i: usize, j: usize| (1..=m).any(|g| st.updates(g, rect.x + i as i64, rect.y + j as i64));
    let (bw, bh) = (rect.w / 2, rect.h / 2);
    let mut img = Rgba8Image::new(bw as u32, bh as u32);
    for (k, px) in img.data.chunks_exact_mut(4).enumerate() {
        let (bx, by) = (2 * (k % bw), 2 * (k / bw));
        let (mut sum, mut n) = ([0u32; 3], 0u32);
        for (i, j) in [(bx, by), (bx + 1, by), (bx, by + 1), (bx + 1, by + 1)] {
            if updated(i, j) {
                let c = colours[values[j * rect.w + i] as usize];
                (0..3).for_each(|ch| sum[ch] += c[ch] as u32);
                n += 1;
            }
        }
        let c = sum.map(|v| ((v + n / 2) / n) as u8);
        px.copy_from_slice(&[c[0], c[1], c[2], 255]);
    }
    Some(downsample_n(&img, d - 1))
}
