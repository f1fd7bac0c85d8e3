//! The synthesized function itself: the value of one entry from the values it reads (the
//! [`Synthesis`] both evaluators call). Values are exemplar indices `y·w_s + x` at the entry's
//! level (the sample's own pixels at every level of a stack); the search compares
//! neighbourhoods by exact integer SSD on sRGB bytes and breaks ties by the lower index, as the
//! paper's strict `>` over a scanline scan does.

use super::exemplar::{ssd_below, Coherence, Exemplar, Level, Options, CHUNK};
use super::params::{ExemplarLevels, Generation0, LowerShape, Params, SameShape, Search};
use super::rect::Rect;
use super::served::{evaluate, Counts};
use super::structure::{circle5, square, union, without_centre, Entry, Structure, Synthesis, Taps};
use crate::hash::{below, hash4, hash4_x, hash4_y};
use crate::pixels::Rgba8Image;
use crate::{Error, Result};
use std::sync::OnceLock;

/// The plane is a torus of 2^PLANE_BITS level-0 pixels a side (2^58 coarsest pixels for four
/// levels): far beyond any served extent (2^40), and far enough from the i64 range that the
/// cone of any region, reduced into it, is evaluated without overflow.
pub const PLANE_BITS: u32 = 62;

/// Hash stream of the noise level.
pub const STREAM_NOISE: u64 = 0x004e_4f49_5345;
/// Hash stream of the jitter of upsampled coordinates; level s uses `STREAM_JITTER + s`.
pub const STREAM_JITTER: u64 = 0x004a_4954_0000;
/// Hash stream of the pilot window's position (the histogram balance's measurement).
pub const STREAM_PILOT: u64 = 0x0050_494c_4f54;
/// Side of the pilot window, in pixels of each searched level.
pub const PILOT: usize = 128;
/// Luma bands of the histogram balance (16 grey levels each).
const BANDS: usize = 16;

/// The longest neighbourhood vector: 24 same-level and 25 coarser taps, padded.
const MAX_STRIDE: usize = (3 * (24 + 25usize)).div_ceil(CHUNK) * CHUNK;
/// At most 9 shifted k-coherence sets of at most 8 pixels.
const MAX_CANDIDATES: usize = 9 * 8;

/// A loaded exemplar and its search: everything an entry's value depends on besides the
/// values it reads.
#[derive(Clone, Debug)]
pub struct Synthesizer {
    structure: Structure,
    exemplar: Exemplar,
    seed: u64,
    search: Search,
    generation0: Generation0,
    /// Weight, in percent, of the SSD of a candidate that is no neighbour's coherent
    /// continuation (100 + κ).
    jump_weight: u64,
    /// Radius of the hashed jitter of upsampled coordinates (0: none).
    jitter: u8,
    /// The sample tiles: a jittered coordinate wraps instead of staying put at an edge.
    wrap: bool,
    /// For each same-level tap of the neighbourhood vector, its position in the `same` reads.
    same_at: Vec<usize>,
    /// Coarser-level taps of the neighbourhood vector (the `lower` reads, in order).
    lower_taps: usize,
    /// For each offset of the 3×3 window whose k-coherence sets give candidates: its index
    /// in the 3×3 square and its position in the `same` reads. The centre comes first: the
    /// pixel's own coherent match is usually near the best, so later sums are abandoned early.
    coherent: Vec<(usize, usize)>,
    /// Position of (0, 0) in the `same` reads: the previous generation of the pixel itself.
    centre: Option<usize>,
    /// Histogram balance exponent, in halves (0: off).
    balance: u8,
    /// Per level, what its k-coherence search reads, prepared by the first search there: a
    /// view of coarse levels that searches nowhere builds none of it.
    prepared: Vec<OnceLock<Prepared>>,
}

/// What a k-coherence search at one level reads besides the exemplar: the level's sets, and
/// each candidate's histogram balance factor (in 1/256).
#[derive(Clone, Debug)]
struct Prepared {
    coherence: Coherence,
    balance: Vec<u16>,
}

/// The compared taps of each shape (centre excluded at the own level).
pub fn same_taps(shape: SameShape) -> Taps {
    match shape {
        SameShape::Circle5 => circle5(),
        SameShape::Square5 => without_centre(square(2)),
        SameShape::Square3 => without_centre(square(1)),
    }
}

pub fn lower_taps(shape: LowerShape) -> Taps {
    match shape {
        LowerShape::Square3 => square(1),
        LowerShape::Square5 => square(2),
    }
}

/// The dependency structure the parameters describe: what each entry reads.
pub fn structure(p: &Params) -> Structure {
    let compared = same_taps(p.neighbourhood.same);
    // A stack's coordinates already carry the coarser levels: only generation 0 reads them.
    let lower = match p.exemplar() {
        ExemplarLevels::Pyramid => lower_taps(p.neighbourhood.lower),
        ExemplarLevels::Stack => Vec::new(),
    };
    // k-coherence also reads the 3×3 window whose sets give the candidates.
    let same = match p.search {
        Search::Exhaustive => compared,
        Search::Kcoherence => union(&compared, &square(1)),
    };
    let generation0_lower = match p.generation0() {
        Generation0::Upsample => vec![(0, 0)],
        Generation0::Search => lower.clone(),
    };
    Structure {
        levels: p.levels,
        generations: p.generations(),
        coarsest_generations: p.coarsest_generations,
        coarsest_same: same.clone(),
        same,
        lower,
        generation0_lower,
        subpasses: p.subpasses(),
        torus: match p.domain {
            super::params::DomainSpec::Plane => None,
            super::params::DomainSpec::Torus => Some((p.width, p.height)),
        },
    }
}

impl Synthesizer {
    /// Prepares the search over `sample` for valid parameters (see `Params::validate`); an
    /// error names a neighbourhood that leaves a level with no candidate.
    pub fn new(p: &Params, sample: &Rgba8Image) -> Result<Synthesizer> {
        p.validate(sample.width, sample.height)?;
        let structure = structure(p);
        let compared = same_taps(p.neighbourhood.same);
        let options = Options {
            levels: p.levels,
            stack: p.exemplar() == ExemplarLevels::Stack,
            same: compared.clone(),
            lower: structure.lower.clone(),
            wrap: p.exemplar_wrap,
            k: if p.search == Search::Kcoherence { p.k as usize } else { 0 },
            k_exclusion: p.k_exclusion as u32,
            coarsest_search: p.coarsest_generations > 1,
        };
        let exemplar = Exemplar::build(sample, &options);
        for (s, level) in exemplar.levels.iter().enumerate() {
            let searched = s > 0 || p.coarsest_generations > 1;
            let low = s > 0 && p.generation0() == Generation0::Search;
            if (searched && level.valid.is_empty()) || (low && level.valid_low.is_empty()) {
                return Err(Error::param(
                    "neighbourhood",
                    format!(
                        "no pixel of the {}×{} sample level {s} has its whole neighbourhood inside it",
                        level.w, level.h
                    ),
                ));
            }
        }
        let position = |t: &(i8, i8)| structure.same.iter().position(|x| x == t);
        let same_at = compared.iter().map(|t| position(t).expect("compared taps are read")).collect();
        let coherent = match p.search {
            Search::Exhaustive => Vec::new(),
            Search::Kcoherence => {
                let mut window: Vec<(usize, usize)> = square(1)
                    .iter()
                    .enumerate()
                    .map(|(d, t)| (d, position(t).expect("the 3×3 window is read")))
                    .collect();
                window.swap(0, 4);
                window
            }
        };
        Ok(Synthesizer {
            centre: position(&(0, 0)),
            lower_taps: structure.lower.len(),
            structure,
            exemplar,
            seed: p.seed,
            search: p.search,
            generation0: p.generation0(),
            jump_weight: 100 + p.kappa() as u64,
            jitter: p.jitter(),
            wrap: p.exemplar_wrap,
            same_at,
            coherent,
            balance: p.balance(),
            prepared: (0..p.levels).map(|_| OnceLock::new()).collect(),
        })
    }

    /// What the k-coherence search at level `s` reads, prepared on first use.
    fn prepared(&self, s: usize) -> &Prepared {
        self.prepared[s].get_or_init(|| {
            let coherence = self.exemplar.coherence(s);
            let unbalanced = Prepared { coherence, balance: vec![256; self.exemplar.levels[s].colour.len()] };
            if self.balance == 0 || self.exemplar.levels[s].valid.is_empty() {
                return unbalanced;
            }
            let balance = self.measure_balance(s, &unbalanced);
            Prepared { balance, ..unbalanced }
        })
    }

    /// The histogram balance of level `s`, exponent `halves`/2, the coarser levels balanced
    /// already: the level is synthesised over a pilot window as it is now, and a pixel's factor
    /// is (used ⁄ fair)^(halves/2) of its luma band, fair being the band's share of the valid
    /// pixels, clamped to ½..=2. Balancing coarse to fine, each pilot sees the coarser levels
    /// as they will be served, so the corrections do not compound.
    fn measure_balance(&self, s: usize, unbalanced: &Prepared) -> Vec<u16> {
        let (level, halves) = (&self.exemplar.levels[s], self.balance);
        let h = hash4(self.seed, STREAM_PILOT, 0, 0);
        let (x, y) = ((h as i64) >> 24, (h.rotate_left(32) as i64) >> 24);
        let band = |c: [u8; 3]| ((77 * c[0] as u32 + 150 * c[1] as u32 + 29 * c[2] as u32) >> 12) as usize;
        let rect = Rect { x, y, w: PILOT, h: PILOT };
        let pilot = Pilot { syn: self, s: s as u8, prepared: unbalanced };
        let used = evaluate(&pilot, &self.structure, None, s as u8, rect, &mut Counts::default(), &crate::Never)
            .expect("a pilot that is never stopped completes");
        let (mut fair, mut got) = ([0u64; BANDS], [0u64; BANDS]);
        level.valid.iter().for_each(|&u| fair[band(level.colour[u as usize])] += 1);
        used.iter().for_each(|&u| got[band(level.colour[u as usize])] += 1);
        let factor: Vec<u64> = (0..BANDS)
            .map(|b| {
                if fair[b] == 0 {
                    return 256;
                }
                // (used ⁄ fair) in 1/256, its square root, raised to `halves`.
                let ratio = (got[b] << 8) * level.valid.len() as u64 / (fair[b] * used.len() as u64);
                let root = (ratio << 8).isqrt();
                (0..halves).fold(256u64, |f, _| (f * root) >> 8).clamp(128, 512)
            })
            .collect();
        level.colour.iter().map(|&c| factor[band(c)] as u16).collect()
    }

    pub fn structure(&self) -> &Structure {
        &self.structure
    }

    pub fn exemplar(&self) -> &Exemplar {
        &self.exemplar
    }

    /// The output neighbourhood of an entry at level `s`, as a padded vector; generation 0
    /// reads no `same` values and fills only the coarser part.
    #[inline(always)]
    fn output_vector(&self, s: usize, same: &[u16], lower: &[u16], out: &mut [u8; MAX_STRIDE]) {
        let level = &self.exemplar.levels[s];
        if !same.is_empty() {
            for (t, &i) in self.same_at.iter().enumerate() {
                out[3 * t..3 * t + 3].copy_from_slice(&level.colour[same[i] as usize]);
            }
        }
        if s > 0 {
            let coarser = &self.exemplar.levels[s - 1];
            let base = 3 * self.same_at.len();
            for (t, &v) in lower.iter().enumerate() {
                out[base + 3 * t..base + 3 * t + 3].copy_from_slice(&coarser.colour[v as usize]);
            }
        }
    }

    /// The k-coherence candidates of an entry, each with the weight of its SSD: each set C(v)
    /// of its 3×3 window's previous values v, shifted back by the window offset, kept when
    /// valid, without repeats; weight 100 for a coherent continuation (v − d itself), 100 + κ
    /// for the others, times the candidate's histogram balance.
    #[inline(always)]
    fn candidates<'a>(
        &self,
        prepared: &Prepared,
        same: &[u16],
        buf: &'a mut [(u16, u64); MAX_CANDIDATES],
    ) -> &'a [(u16, u64)] {
        let mut n = 0;
        let sets = &prepared.coherence;
        for &(d, i) in &self.coherent {
            let v = same[i] as usize;
            let coherent = sets.shifted_coherent(v, d);
            for (j, &c) in sets.shifted(v, d).iter().enumerate() {
                let kind = if j == 0 && coherent { 100 } else { self.jump_weight };
                let weight = kind * prepared.balance[c as usize] as u64;
                match buf[..n].iter_mut().find(|b| b.0 == c) {
                    Some(b) => b.1 = b.1.min(weight),
                    None => {
                        buf[n] = (c, weight);
                        n += 1;
                    }
                }
            }
        }
        &buf[..n]
    }
}

/// The pixel of `pixels` whose vector part `range` is nearest to `target`'s, the lowest
/// index on a tie.
#[inline(always)]
fn argmin(level: &Level, pixels: &[u16], target: &[u8], range: std::ops::Range<usize>) -> Option<u16> {
    let mut best: Option<(u32, u16)> = None;
    let target = &target[range.clone()];
    for &u in pixels {
        let v = &level.vector(u as usize)[range.clone()];
        // Abandoning a sum once it exceeds the best keeps it exact wherever it can win or tie.
        let bound = best.map_or(u32::MAX, |b| b.0.saturating_add(1));
        let d = if range.len() % CHUNK == 0 {
            ssd_below(target, v, bound)
        } else {
            target.iter().zip(v).map(|(&a, &b)| (a as i32 - b as i32).pow(2) as u32).sum()
        };
        if best.is_none_or(|b| (d, u) < b) {
            best = Some((d, u));
        }
    }
    best.map(|b| b.1)
}

impl Synthesizer {
    /// The noise entry drawn by hash `h`.
    #[inline]
    fn noise_of(&self, h: u64) -> u16 {
        let (nw, nh) = self.noise_area();
        let i = below(h, (nw * nh) as u64) as u32;
        (i / nw * self.exemplar.levels[0].w + i % nw) as u16
    }

    /// The noise over `rect`, row-major, as [`Synthesis::noise`] draws it entry by entry (the
    /// hash's steps that depend on the column alone are taken once a column), or `None` once
    /// `stop` is requested.
    pub fn noise_over(&self, rect: Rect, stop: &dyn crate::Stop) -> Option<Vec<u16>> {
        let at = |i: usize, j: usize| self.hashed_at(0, rect.x.wrapping_add(i as i64), rect.y.wrapping_add(j as i64));
        let columns: Vec<u64> = (0..rect.w).map(|i| hash4_x(self.seed, STREAM_NOISE, at(i, 0).0)).collect();
        let mut values = Vec::with_capacity(rect.area());
        for j in 0..rect.h {
            if stop.requested() {
                return None;
            }
            let y = at(0, j).1;
            values.extend(columns.iter().map(|&hx| self.noise_of(hash4_y(hx, y))));
        }
        Some(values)
    }

    /// The coordinates a pixel of level `s` is hashed at: reduced onto the torus, and on the
    /// plane to their signed representatives modulo the plane's period at that level (which
    /// repeats every 2^PLANE_BITS pixels of level 0, so that no evaluation comes near the i64
    /// wrap).
    fn hashed_at(&self, s: u8, x: i64, y: i64) -> (i64, i64) {
        let e = self.structure.canonical(Entry { s, m: 0, x, y });
        let bits = 64 - (PLANE_BITS - (self.structure.finest() - s) as u32);
        ((e.x << bits) >> bits, (e.y << bits) >> bits)
    }

    /// The noise draws coordinates (x, y) with x < w and y < h of the coarsest level: all of a
    /// pyramid's; in a stack of a sample that does not tile, those whose h_0-sided block lies
    /// inside the sample.
    fn noise_area(&self) -> (u32, u32) {
        let level = &self.exemplar.levels[0];
        let margin = if self.wrap { 0 } else { level.spacing - 1 };
        (level.w - margin, level.h - margin)
    }

    /// The hashed jitter of pixel (x, y) of level `s`: on each axis one of the 2r·h offsets
    /// −r·h..=r·h−1, h the level's tap spacing, a pure function of (seed, level, pixel).
    #[inline]
    fn jitter_of(&self, s: u8, x: i64, y: i64) -> (i64, i64) {
        let r = self.jitter as u64 * self.exemplar.levels[s as usize].spacing as u64;
        let (x, y) = self.hashed_at(s, x, y);
        let h = hash4(self.seed, STREAM_JITTER + s as u64, x, y);
        (below(h, 2 * r) as i64 - r as i64, below(h.rotate_left(32), 2 * r) as i64 - r as i64)
    }

    /// A coordinate `v` moved by `d` on an axis of `n` pixels: wrapped on a tiling sample; on
    /// another, left where it was if the offset would leave the sample.
    #[inline]
    fn moved(&self, v: i64, d: i64, n: i64) -> i64 {
        match (self.wrap, v + d) {
            (true, t) => t.rem_euclid(n),
            (false, t) if (0..n).contains(&t) => t,
            _ => v,
        }
    }
}

/// The candidate with the smallest (weight · SSD, index) against `target`.
#[inline(always)]
fn argmin_weighted(level: &Level, candidates: &[(u16, u64)], target: &[u8]) -> Option<u16> {
    let mut best: Option<(u64, u16)> = None;
    for &(u, weight) in candidates {
        // Exact wherever weight · SSD can win or tie.
        let bound = best.map_or(u32::MAX, |b| (b.0 / weight + 1).min(u32::MAX as u64) as u32);
        let d = ssd_below(target, level.vector(u as usize), bound) as u64 * weight;
        if best.is_none_or(|b| (d, u) < b) {
            best = Some((d, u));
        }
    }
    best.map(|b| b.1)
}

impl Synthesis for Synthesizer {
    fn noise(&self, x: i64, y: i64) -> u16 {
        let (x, y) = self.hashed_at(0, x, y);
        self.noise_of(hash4(self.seed, STREAM_NOISE, x, y))
    }

    fn entry(&self, e: Entry, same: &[u16], lower: &[u16]) -> u16 {
        entry(self, e, same, lower, None)
    }
}

/// Level `s` synthesised as it is before its histogram balance is measured (every factor 1),
/// the coarser levels as served: what the balance's pilot window measures.
struct Pilot<'a> {
    syn: &'a Synthesizer,
    s: u8,
    prepared: &'a Prepared,
}

impl Synthesis for Pilot<'_> {
    fn noise(&self, x: i64, y: i64) -> u16 {
        self.syn.noise(x, y)
    }

    fn entry(&self, e: Entry, same: &[u16], lower: &[u16]) -> u16 {
        entry(self.syn, e, same, lower, (e.s == self.s).then_some(self.prepared))
    }
}

crate::simd::widest! {
    /// Table 1's search for one entry, compiled for the CPU's widest vector unit; a
    /// k-coherence search reads `prepared`, else the level's own.
    fn entry(syn: &Synthesizer, e: Entry, same: &[u16], lower: &[u16], prepared: Option<&Prepared>) -> u16 {
        let s = e.s as usize;
        let level = &syn.exemplar.levels[s];
        if e.m == 0 {
            let coarser = &syn.exemplar.levels[s - 1];
            return match syn.generation0 {
                Generation0::Upsample => {
                    // The parent's coordinate at this level, plus the child's offset in taps.
                    let scale = if syn.exemplar.stack { 1 } else { 2 };
                    let (px, py) = (lower[0] as u32 % coarser.w, lower[0] as u32 / coarser.w);
                    let (px, py) = (scale * px as i64, scale * py as i64);
                    let step = level.spacing as i64;
                    let (w, h) = (level.w as i64, level.h as i64);
                    let (mut x, mut y) = (syn.moved(px, step * (e.x & 1), w), syn.moved(py, step * (e.y & 1), h));
                    if syn.jitter > 0 {
                        let (dx, dy) = syn.jitter_of(e.s, e.x, e.y);
                        (x, y) = (syn.moved(x, dx, w), syn.moved(y, dy, h));
                    }
                    (y * level.w as i64 + x) as u16
                }
                Generation0::Search => {
                    let mut target = [0u8; MAX_STRIDE];
                    syn.output_vector(s, &[], lower, &mut target);
                    let base = 3 * syn.same_at.len();
                    let range = base..base + 3 * syn.lower_taps;
                    argmin(level, &level.valid_low, &target, range).expect("V^low is checked non-empty at load")
                }
            };
        }
        if !syn.structure.updates(e.m, e.x, e.y) {
            return same[0];
        }
        let mut target = [0u8; MAX_STRIDE];
        syn.output_vector(s, same, lower, &mut target);
        let target = &target[..level.stride];
        match syn.search {
            Search::Exhaustive => argmin(level, &level.valid, target, 0..level.stride),
            Search::Kcoherence => {
                let mut buf = [(0u16, 0u64); MAX_CANDIDATES];
                let prepared = prepared.unwrap_or_else(|| syn.prepared(s));
                let candidates = syn.candidates(prepared, same, &mut buf);
                argmin_weighted(level, candidates, target)
            }
        }
        .unwrap_or_else(|| same[syn.centre.expect("k-coherence reads the pixel itself")])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use serde_json::json;

    fn synthesizer(params: serde_json::Value) -> Synthesizer {
        let p: Params = serde_json::from_value(params).unwrap();
        Synthesizer::new(&p, &crate::samples::lichen(32, 1)).unwrap()
    }

    /// A rectangle's noise drawn at once is the noise drawn entry by entry: on the plane
    /// (across its period's wrap and at the ends of i64) and on a torus.
    #[test]
    fn noise_over_a_rectangle_is_the_noise_of_each_entry() {
        for params in [
            json!({"seed": 4, "levels": 3}),
            json!({"seed": 5, "levels": 3, "exemplar": "stack", "jitter": 1}),
            json!({"seed": 6, "levels": 3, "domain": "torus", "width": 24, "height": 40}),
        ] {
            let syn = synthesizer(params.clone());
            let coarsest = 1i64 << (PLANE_BITS - 2);
            for (x, y) in [(-7, 3), (coarsest - 5, -coarsest - 4), (i64::MIN, i64::MAX - 8), (i64::MAX - 10, 30)] {
                let rect = Rect { x, y, w: 13, h: 9 };
                let got = syn.noise_over(rect, &crate::Never).unwrap();
                for (k, &v) in got.iter().enumerate() {
                    let (i, j) = ((k % rect.w) as i64, (k / rect.w) as i64);
                    assert_eq!(v, syn.noise(x.wrapping_add(i), y.wrapping_add(j)), "{params}: ({x}, {y}) + ({i}, {j})");
                }
            }
        }
    }

    /// The noise is a pure function of (seed, x, y), covers the coarsest level, and is
    /// periodic on a torus.
    #[test]
    fn the_noise_is_hashed_from_the_seed_and_the_pixel() {
        let (a, b, c) = (
            synthesizer(json!({"seed": 5, "levels": 3})),
            synthesizer(json!({"seed": 5, "levels": 3})),
            synthesizer(json!({"seed": 6, "levels": 3})),
        );
        let n = 8 * 8;
        let mut seen = vec![false; n];
        let mut differ = 0;
        for y in -100..100i64 {
            for x in [-(1i64 << 40), -3, 0, 7, 1 << 50].map(|o| o + y * 3) {
                let v = a.noise(x, y);
                assert_eq!(v, b.noise(x, y));
                assert!((v as usize) < n);
                seen[v as usize] = true;
                differ += (v != c.noise(x, y)) as u32;
                assert_eq!(v, below(hash4(5, STREAM_NOISE, x, y), n as u64) as u16);
            }
        }
        assert!(seen.iter().all(|&s| s), "every coarsest pixel is drawn");
        assert!(differ > 900, "another seed, other noise: {differ} of 1000 differ");
        let t = synthesizer(json!({"seed": 5, "levels": 3, "domain": "torus", "width": 40, "height": 24}));
        assert_eq!(t.noise(3, 4), t.noise(3 + 10, 4 - 6));
        assert_ne!(t.noise(3, 4), t.noise(3 + 5, 4));
    }
}
