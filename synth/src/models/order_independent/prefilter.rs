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
/// and the texture's mean. A pure function of the encoding ([`Calibration::compute`]); `create`
/// stores it in the bundle (section [`SECTION`], [`Calibration::to_bytes`]) so that opening a
/// texture and rendering a coarse tile synthesizes no level-0 window.
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
    /// What g (level 0) and each g_s are expanded from, and what is stored: per synthesis
    /// level, the colour of each bin of coordinates ([`binning`]), `None` where no block grew
    /// (its coordinates then take their box colour).
    bins: Vec<Option<Vec<Option<[u8; 3]>>>>,
}

/// The bundle section holding the calibration ([`Calibration::to_bytes`]).
pub const SECTION: &str = "calibration.bin";
/// The version byte of [`SECTION`]'s layout.
pub const SECTION_VERSION: u8 = 1;
/// Bounds of a stored contrast, which every computed one is within: a centre is a mean of
/// bytes in 1/256, and a gain σ ⁄ σ in 1/256 of at most 2^32 (the windows' pixel count times
/// the largest σ); within them `adjust` cannot overflow.
const MAX_CENTRE: u32 = 255 << 8;
const MAX_GAIN: u64 = 1 << 40;

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
        let n = tex.synthesizer().exemplar().levels[0].colour.len();
        // A stack's coarsest level has a coordinate per sample pixel, too many for the windows
        // to measure one by one: g is measured per bin of `bin` × `bin` coordinates.
        let stack = tex.synthesizer().exemplar().stack;
        let binning = binning(tex, 0);
        let mut sums = vec![[0u64; 4]; binning.count];
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
                let acc = &mut sums[binning.key(u as usize)];
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
        let mut bins = vec![None; fin as usize + 1];
        bins[0] = Some(bin_means(&sums));
        let g = expand(tex, 0, bins[0].as_ref().expect("just set"));
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
        for s in 1..=fin as u8 {
            if let Some(m) = measured_generation(p, s) {
                let b = measure(tex, &windows, s, m, stop)?;
                measured[s as usize] = Some(expand(tex, s, &b));
                bins[s as usize] = Some(b);
            }
        }
        let mut contrast = vec![None; top as usize + 1];
        for (l, contrast) in contrast.iter_mut().enumerate().skip(1) {
            let l = l as u32;
            let Source::Pyramid { r, m } = source(p, l) else { continue };
            if !has_contrast(p, l) {
                continue;
            }
            let (mut exact, mut raw) = (Moments::default(), Moments::default());
            for (x, y, img) in &windows {
                exact.add(&downsample_n(img, l));
                raw.add(&pyramid(tex, &g, &measured, r, m, l - r, x >> l, y >> l, side >> l, side >> l, stop)?);
            }
            *contrast = Some(Contrast { centre: raw.mean_q8(), gain: exact.gain_over(&raw) });
        }
        Some(Calibration { g, measured, mean, contrast, bins })
    }

    /// The section's bytes (version 1, integers little-endian; docs/models/order-independent.md,
    /// "Mip levels"):
    ///
    /// ```text
    /// u8        version (1)
    /// [u8; 3]   mean colour
    /// per synthesis level s = 0..K − 1:
    ///   u32       bin count c_s (0: level s has no measured colours; g is s = 0)
    ///   ⌈c_s/8⌉   bytes, bit i (of byte i/8, least significant first) set where bin i has a colour
    ///   [u8; 3]   per set bit, in bin order, the colour
    /// u8        contrast slots T (vtex levels 0..=K − 1 + noise_levels)
    /// per slot: u8 0 (none) or 1, then [u32; 3] centre (1/256) and u64 gain (1/256)
    /// ```
    pub fn to_bytes(&self) -> Vec<u8> {
        let mut out = vec![SECTION_VERSION];
        out.extend_from_slice(&self.mean);
        for bins in &self.bins {
            let bins = bins.as_deref().unwrap_or(&[]);
            out.extend_from_slice(&(bins.len() as u32).to_le_bytes());
            let mut bits = vec![0u8; bins.len().div_ceil(8)];
            for (i, b) in bins.iter().enumerate() {
                if b.is_some() {
                    bits[i / 8] |= 1 << (i % 8);
                }
            }
            out.extend_from_slice(&bits);
            for c in bins.iter().flatten() {
                out.extend_from_slice(c);
            }
        }
        out.push(self.contrast.len() as u8);
        for c in &self.contrast {
            match c {
                None => out.push(0),
                Some(Contrast { centre, gain }) => {
                    out.push(1);
                    for v in centre {
                        out.extend_from_slice(&(*v as u32).to_le_bytes());
                    }
                    out.extend_from_slice(&(*gain as u64).to_le_bytes());
                }
            }
        }
        out
    }

    /// The calibration stored as `bytes` ([`to_bytes`](Self::to_bytes)) for `tex`, checked
    /// strictly against what its parameters and sample imply (every count, which levels have
    /// measured colours and which have a contrast, value bounds, no byte left over): an error
    /// naming the part otherwise. Whether it is the one [`compute`](Self::compute) gives is
    /// not checked here, which would cost what storing it saves: see [`verify`].
    pub fn from_bytes(tex: &SynthesisLevels, bytes: &[u8]) -> crate::Result<Calibration> {
        let p = tex.params();
        let fin = p.levels as u32 - 1;
        let bad = |why: String| crate::Error::bundle(format!("section `{SECTION}`: {why}"));
        let mut r = Cursor { bytes, pos: 0 };
        let version = r.take(1, "the version").map_err(bad)?[0];
        if version != SECTION_VERSION {
            return Err(bad(format!("version {version}; this build reads {SECTION_VERSION}")));
        }
        let mean: [u8; 3] = r.take(3, "the mean").map_err(bad)?.try_into().expect("3 bytes");
        let mut bins = Vec::with_capacity(fin as usize + 1);
        for s in 0..=fin as u8 {
            let what = if s == 0 { "g".to_string() } else { format!("g_{s}") };
            let count = u32::from_le_bytes(r.take(4, &what).map_err(bad)?.try_into().expect("4 bytes")) as usize;
            let expected = if s == 0 || measured_generation(p, s).is_some() { binning(tex, s).count } else { 0 };
            if count != expected {
                return Err(bad(format!(
                    "{what} has {count} bins; the params and sample give synthesis level {s} {expected}"
                )));
            }
            if count == 0 {
                bins.push(None);
                continue;
            }
            let bits = r.take(count.div_ceil(8), &what).map_err(bad)?;
            if count % 8 != 0 && bits[count / 8] >> (count % 8) != 0 {
                return Err(bad(format!("{what} marks bins past its {count}")));
            }
            let present = bits.iter().map(|b| b.count_ones() as usize).sum::<usize>();
            let mut colours = r.take(3 * present, &what).map_err(bad)?.chunks_exact(3);
            let level: Vec<Option<[u8; 3]>> = (0..count)
                .map(|i| {
                    (bits[i / 8] >> (i % 8) & 1 == 1)
                        .then(|| colours.next().expect("one colour a set bit").try_into().expect("3 bytes"))
                })
                .collect();
            bins.push(Some(level));
        }
        let top = fin + p.mip.noise_levels as u32;
        let slots = r.take(1, "the contrast count").map_err(bad)?[0] as usize;
        if slots != top as usize + 1 {
            return Err(bad(format!("{slots} contrast slots; the params give {}", top + 1)));
        }
        let mut contrast = Vec::with_capacity(slots);
        for l in 0..slots as u32 {
            let what = format!("the contrast of level {l}");
            let tag = r.take(1, &what).map_err(bad)?[0];
            let expected = l > 0 && has_contrast(p, l);
            match (tag, expected) {
                (0, false) => contrast.push(None),
                (1, true) => {
                    let v = r.take(20, &what).map_err(bad)?;
                    let word = |i: usize| u32::from_le_bytes(v[4 * i..4 * i + 4].try_into().expect("4 bytes"));
                    let centre = [word(0), word(1), word(2)];
                    let gain = u64::from_le_bytes(v[12..20].try_into().expect("8 bytes"));
                    if centre.iter().any(|&c| c > MAX_CENTRE) || gain > MAX_GAIN {
                        return Err(bad(format!("{what} is out of bounds (centre ≤ {MAX_CENTRE}, gain ≤ 2^40)")));
                    }
                    contrast.push(Some(Contrast { centre: centre.map(|c| c as i64), gain: gain as i64 }));
                }
                (0 | 1, _) => {
                    return Err(bad(format!(
                        "{what} is {}; the params give {}",
                        if tag == 1 { "present" } else { "absent" },
                        if expected { "one" } else { "none" }
                    )))
                }
                _ => return Err(bad(format!("{what} has tag {tag}, not 0 or 1"))),
            }
        }
        if r.pos != bytes.len() {
            return Err(bad(format!("{} bytes after the last contrast", bytes.len() - r.pos)));
        }
        let g = expand(tex, 0, bins[0].as_ref().expect("level 0 always has bins"));
        let measured =
            bins.iter().enumerate().map(|(s, b)| if s == 0 { None } else { Some(expand(tex, s as u8, b.as_ref()?)) });
        let measured = measured.collect();
        Ok(Calibration { g, measured, mean, contrast, bins })
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

/// The generation of synthesis level `s` ≥ 1 whose measured colours g_s a coarse vtex level
/// reads (0, coloured whole, or the latest, whose searched entries colour an earlier one), or
/// `None` where every level reading `s` reads its latest generation.
fn measured_generation(p: &super::Params, s: u8) -> Option<u8> {
    let fin = p.levels as u32 - 1;
    let r = fin - s as u32;
    let top = fin + p.mip.noise_levels as u32;
    let read = (1..=top).find_map(|l| match source(p, l) {
        Source::Pyramid { r: rr, m } if rr == r && m < latest(p, s) => Some(m),
        _ => None,
    })?;
    Some(if read == 0 { 0 } else { latest(p, s) })
}

/// Whether vtex level `l` ≥ 1 has a measured contrast: its source is a pyramid level that is
/// not exact, and a calibration window covers a pixel of it.
fn has_contrast(p: &super::Params, l: u32) -> bool {
    let side = WINDOW.max(2 << (p.levels as u32 - 1));
    let src = source(p, l);
    matches!(src, Source::Pyramid { .. }) && !src.exact(p) && side >> l != 0
}

/// How the coordinates of a synthesis level are binned for its measured colours.
struct Binning {
    /// Bin side, in coordinates (1 but in a stack, 2^(K − 1 − s)).
    bin: usize,
    /// The level's width, and its bins a row.
    w: usize,
    bins_w: usize,
    count: usize,
}

impl Binning {
    /// The bin of coordinate `u`.
    fn key(&self, u: usize) -> usize {
        (u / self.w / self.bin) * self.bins_w + u % self.w / self.bin
    }
}

fn binning(tex: &SynthesisLevels, s: u8) -> Binning {
    let shift = tex.params().levels as u32 - 1 - s as u32;
    let level = &tex.synthesizer().exemplar().levels[s as usize];
    let bin: usize = if tex.synthesizer().exemplar().stack { 1 << shift } else { 1 };
    let (w, h) = (level.w as usize, level.colour.len() / level.w as usize);
    let bins_w = w.div_ceil(bin);
    Binning { bin, w, bins_w, count: bins_w * h.div_ceil(bin) }
}

/// Rounded mean colour of each bin's sums, `None` where nothing was summed.
fn bin_means(sums: &[[u64; 4]]) -> Vec<Option<[u8; 3]>> {
    sums.iter().map(|s| (s[3] > 0).then(|| [0, 1, 2].map(|c| ((s[c] + s[3] / 2) / s[3]) as u8))).collect()
}

/// A colour per coordinate of synthesis level `s` from its bins, B_s where a bin has none.
fn expand(tex: &SynthesisLevels, s: u8, bins: &[Option<[u8; 3]>]) -> Vec<[u8; 3]> {
    let b = binning(tex, s);
    let level = &tex.synthesizer().exemplar().levels[s as usize];
    (0..level.colour.len()).map(|u| bins[b.key(u)].unwrap_or(level.boxed[u])).collect()
}

/// Reads a byte slice front to back; each shortfall names what it was reading.
struct Cursor<'a> {
    bytes: &'a [u8],
    pos: usize,
}

impl<'a> Cursor<'a> {
    fn take(&mut self, n: usize, what: &str) -> Result<&'a [u8], String> {
        let left = self.bytes.len() - self.pos;
        if n > left {
            return Err(format!("truncated: {what} needs {n} bytes, {left} left"));
        }
        self.pos += n;
        Ok(&self.bytes[self.pos - n..self.pos])
    }
}

/// Checks that `bytes`, a stored calibration of `tex`, is exactly the one
/// [`Calibration::compute`] gives: what a server does once where it accepts an uploaded bundle,
/// since a crafted one would colour coarse levels unlike the chain of level 0, breaking mip coherence.
pub fn verify(tex: &SynthesisLevels, bytes: &[u8]) -> crate::Result<()> {
    let stored = Calibration::from_bytes(tex, bytes)?;
    let computed = Calibration::compute(tex, &crate::Never).expect("a render that is never stopped completes");
    if stored == computed {
        return Ok(());
    }
    let part = if stored.mean != computed.mean {
        "the mean".to_string()
    } else if let Some(s) = (0..stored.bins.len()).find(|&s| stored.bins[s] != computed.bins[s]) {
        if s == 0 {
            "g".to_string()
        } else {
            format!("g_{s}")
        }
    } else {
        let l = (0..stored.contrast.len()).find(|&l| stored.contrast[l] != computed.contrast[l]).unwrap_or(0);
        format!("the contrast of level {l}")
    };
    Err(crate::Error::bundle(format!(
        "section `{SECTION}`: {part} is not what the params and sample give (the calibration is recomputed where a \
         bundle is accepted)"
    )))
}

/// g_s: the mean level-0 colour over `windows` of the blocks whose level-`s` entry at generation
/// `m` is u, per bin of u (see [`Calibration::measured`]), `None` in a bin where none grew;
/// `None` once `stop` is requested.
fn measure(
    tex: &SynthesisLevels,
    windows: &[(i64, i64, Rgba8Image)],
    s: u8,
    m: u8,
    stop: &dyn Stop,
) -> Option<Vec<Option<[u8; 3]>>> {
    let shift = tex.params().levels as u32 - 1 - s as u32;
    let block = 1usize << shift;
    let binning = binning(tex, s);
    let mut sums = vec![[0u64; 4]; binning.count];
    for (x, y, img) in windows {
        let side = img.width as usize;
        let cells = side >> shift;
        let entries = tex.entries_at(s, m, Rect { x: x >> shift, y: y >> shift, w: cells, h: cells }, stop)?;
        for (k, &u) in entries.iter().enumerate() {
            let (bx, by) = ((k % cells) << shift, (k / cells) << shift);
            let acc = &mut sums[binning.key(u as usize)];
            for j in 0..block {
                let row = (by + j) * side + bx;
                for px in img.data[row * 4..(row + block) * 4].chunks_exact(4) {
                    (0..3).for_each(|c| acc[c] += px[c] as u64);
                    acc[3] += 1;
                }
            }
        }
    }
    Some(bin_means(&sums))
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
            // A row at a time, polling `stop` as every render does (with a stored calibration
            // this is all the render does).
            for row in img.data.chunks_exact_mut(4 * w as usize) {
                if stop.requested() {
                    return None;
                }
                for px in row.chunks_exact_mut(4) {
                    px.copy_from_slice(&[c[0], c[1], c[2], 255]);
                }
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

#[cfg(all(test, feature = "create"))]
mod tests {
    use super::super::{demos, load, load_with, OrderIndependent};
    use super::*;
    use crate::bundle::Bundle;
    use crate::texture::render_image;
    use crate::{Error, Region};

    /// `bundle` as stored before the calibration section existed.
    fn without_section(bundle: &Bundle) -> Bundle {
        let mut old = bundle.clone();
        old.sections.retain(|s| s.name != SECTION);
        assert_eq!(old.sections.len() + 1, bundle.sections.len(), "{}: no section", bundle.manifest.name);
        old
    }

    fn section(bundle: &Bundle) -> Vec<u8> {
        bundle.section(SECTION).unwrap().to_vec()
    }

    fn with_section(bundle: &Bundle, data: Vec<u8>) -> Bundle {
        without_section(bundle).with_section(SECTION, data)
    }

    /// Entries computed, noise included.
    fn computed(t: &OrderIndependent) -> u64 {
        t.work_counters()[0].1
    }

    /// Every demo stores the calibration that measuring it gives (and it round-trips), in a
    /// at most 20 kB, and the stored one passes the check a server makes on upload.
    #[test]
    fn every_demo_stores_the_calibration_it_measures() {
        for bundle in demos() {
            let name = &bundle.manifest.name;
            let stored = section(&bundle);
            let measured = load(&without_section(&bundle)).unwrap().calibration().clone();
            assert_eq!(stored, measured.to_bytes(), "{name}");
            let opened = load(&bundle).unwrap();
            assert_eq!(*opened.calibration(), measured, "{name}");
            assert!(stored.len() < 20_000, "{name}: {} bytes", stored.len());
            super::super::verify(&bundle).unwrap_or_else(|e| panic!("{name}: {e}"));
        }
    }

    /// A bundle stored before the section existed renders the same bytes as one with it, at
    /// every level: the stored calibration only saves measuring it.
    #[test]
    fn a_bundle_without_the_section_renders_the_same_bytes() {
        for bundle in demos() {
            let (new, old) = (load(&bundle).unwrap(), load(&without_section(&bundle)).unwrap());
            let (w, h) = (new.params().width, new.params().height);
            for l in 0..crate::texture::level_count(w, h) {
                let (lw, lh) = crate::texture::level_size(w, h, l);
                let region = Region::new(l, 0, 0, lw.min(24) as u32, lh.min(16) as u32);
                assert_eq!(
                    render_image(&new, &region).unwrap(),
                    render_image(&old, &region).unwrap(),
                    "{}, level {l}",
                    bundle.manifest.name
                );
            }
        }
    }

    /// Opening the 100k pebbles demo and rendering a 256² tile of level 7 computes exactly the
    /// entries of that tile — what it costs once the calibration is known — and no window of
    /// level 0; the bundle without the section measures its 64 windows first.
    #[test]
    fn opening_and_a_coarse_tile_synthesize_no_level_0_window() {
        let bundle = demos().into_iter().find(|b| b.manifest.name.contains("B — pebbles")).unwrap();
        let tile = Region::new(7, 256, 0, 256, 256);
        let opened = load_with(&bundle, &crate::Resources::default()).unwrap();
        assert_eq!(computed(&opened), 0, "opening computes nothing");
        let image = render_image(&opened, &tile).unwrap();
        let tile_alone = computed(&opened);

        let lazy = load_with(&without_section(&bundle), &crate::Resources::default()).unwrap();
        render_image(&lazy, &tile).unwrap();
        let with_calibration = computed(&lazy);
        let known = load_with(&without_section(&bundle), &crate::Resources::default()).unwrap();
        known.calibration();
        let measuring = computed(&known);
        assert_eq!(render_image(&known, &tile).unwrap(), image);
        assert_eq!(computed(&known) - measuring, tile_alone, "the tile alone");
        assert_eq!(with_calibration, measuring + tile_alone);
        // 64 windows of 64² of level 0, each through its whole cone.
        assert!(measuring > 64 * 64 * 64, "measuring computed {measuring} entries");
    }

    /// A truncated, lengthened or reshaped section is refused when the bundle is opened, by an
    /// error naming the section and the part, never a panic.
    #[test]
    fn a_malformed_section_is_refused_by_name() {
        let bundle = demos().remove(1);
        let good = section(&bundle);
        let opened = load(&bundle).unwrap();
        // What opening a bundle with `data` as its section says (the texture's own analysis of
        // the sample is the same whatever the section holds: done once here).
        let refused = |data: &[u8]| match Calibration::from_bytes(opened.levels(), data) {
            Err(Error::Bundle(why)) => why,
            Err(e) => panic!("refused, but not as a bundle: {e}"),
            Ok(_) => panic!("accepted"),
        };
        for cut in 0..good.len() {
            let why = refused(&good[..cut]);
            assert!(why.starts_with("section `calibration.bin`: truncated: "), "cut at {cut}: {why}");
        }
        // Through `load` too.
        let why = match load(&with_section(&bundle, good[..good.len() / 2].to_vec())) {
            Err(Error::Bundle(why)) => why,
            other => panic!("{other:?}"),
        };
        assert!(why.starts_with("section `calibration.bin`: truncated: "), "{why}");
        let edited = |at: usize, f: &dyn Fn(&mut u8)| {
            let mut b = good.clone();
            f(&mut b[at]);
            refused(&b)
        };
        assert!(edited(0, &|v| *v = 2).contains("version 2; this build reads 1"));
        assert!(edited(4, &|v| *v ^= 1).contains("g has "), "{}", edited(4, &|v| *v ^= 1));
        let mut longer = good.clone();
        longer.push(0);
        assert!(refused(&longer).contains("1 bytes after the last contrast"));
        // The contrast part is the section's end: its slot count, then a tag and 20 bytes a slot.
        let cal = load(&bundle).unwrap().calibration().clone();
        let present = cal.contrast.iter().flatten().count();
        let start = good.len() - present * 21 - (cal.contrast.len() - present) - 1;
        assert!(edited(start, &|v| *v += 1).contains("contrast slots; the params give"));
        let first = cal.contrast.iter().position(Option::is_some).unwrap();
        let tag = start + 1 + first;
        assert!(edited(tag, &|v| *v = 0).contains(&format!("the contrast of level {first} is absent")));
        assert!(edited(tag, &|v| *v = 7).contains("has tag 7"));
        assert!(edited(tag + 1 + 3, &|v| *v = 0xff).contains("out of bounds"));
        assert!(edited(tag + 1 + 19, &|v| *v = 0xff).contains("out of bounds"));
        assert!(edited(start + 1, &|v| *v = 1).contains("the contrast of level 0 is present"));
    }

    /// A well-formed section that is not the measured calibration opens (checking it would
    /// cost what storing it saves) but fails the check made where a bundle is accepted, which
    /// names the part that differs; so does another demo's calibration of the same shape.
    #[test]
    fn a_crafted_calibration_is_refused_where_a_bundle_is_accepted() {
        let all = demos();
        let bundle = &all[1];
        let mut crafted = section(bundle);
        crafted[1] ^= 0x40; // the mean's red
        let b = with_section(bundle, crafted);
        load(&b).expect("well-formed: it opens");
        let why = super::super::verify(&b).unwrap_err().to_string();
        assert!(why.contains("section `calibration.bin`: the mean is not what the params and sample give"), "{why}");
        let mut crafted = section(bundle);
        let gain = crafted.len() - 8;
        crafted[gain] ^= 1; // the last contrast's gain, by 1/256
        let why = super::super::verify(&with_section(bundle, crafted)).unwrap_err().to_string();
        assert!(why.contains("the contrast of level") && why.contains("is not what"), "{why}");
        let mut crafted = section(bundle);
        let bins = u32::from_le_bytes(crafted[4..8].try_into().unwrap()) as usize;
        crafted[8 + bins.div_ceil(8)] ^= 0x11; // g's first colour, past its count and bits
        let why = super::super::verify(&with_section(bundle, crafted)).unwrap_err().to_string();
        assert!(why.contains("calibration.bin`: g is not"), "{why}");
        // Another demo's calibration, where the shapes agree.
        for other in all.iter().filter(|o| o.manifest.name != bundle.manifest.name) {
            let b = with_section(bundle, section(other));
            if load(&b).is_ok() {
                assert!(super::super::verify(&b).is_err(), "{}'s calibration passed", other.manifest.name);
            }
        }
    }

    /// A bundle stored before the section existed can still be patched: `create` adding the
    /// section is not a part made elsewhere ([`crate::models::Model::cached_sections`]), and the
    /// result is what a fresh `create` makes; a stored section unlike the measured one is.
    #[test]
    fn a_bundle_without_the_section_patches_as_a_fresh_create() {
        use crate::models::{create, remake_within, Limits};
        let ex = super::super::demos::example();
        let made = create(super::super::MODEL, "ex", &ex.params, &ex.inputs()).unwrap();
        let mut params = ex.params.clone();
        params["seed"] = serde_json::json!(2);
        let fresh = create(super::super::MODEL, "ex", &params, &ex.inputs()).unwrap();
        let patched = remake_within(&without_section(&made), "ex", &params, &Limits::NONE).unwrap();
        assert_eq!(patched.to_bytes(), fresh.to_bytes());
        let mut crafted = section(&made);
        crafted[1] ^= 1;
        let why = remake_within(&with_section(&made, crafted), "ex", &params, &Limits::NONE).unwrap_err().to_string();
        assert!(why.contains("section `calibration.bin`"), "{why}");
    }
}
