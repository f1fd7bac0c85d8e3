//! Wei & Levoy 2000, *Fast Texture Synthesis using Tree-structured Vector Quantization*: the
//! sequential synthesis that order-independent synthesis ([19] in Wei & Levoy 2002) is compared
//! with in its Fig. 5. A baseline for the figures, not served.
//!
//! The output pyramid is initialised with random exemplar pixels of each level (so its noise
//! has the exemplar's histogram), then synthesized coarsest level first, each level in scanline
//! passes. In the first, a pixel's neighbourhood is the causal half of an N×N square at its own
//! level (rows above and pixels to the left: what the pass has already written) and the full
//! n×n square around its parent at the next coarser level, which is finished; later passes, if
//! any, read the whole N×N square of the level as it stands. The output is a
//! torus, so the first rows and columns read the initial noise of the last ones, as in the
//! paper; the exemplar wraps only when it tiles. The best match is found by exhaustive L2
//! search over every exemplar pixel whose neighbourhood lies inside it: the exact answer that
//! the paper's tree-structured vector quantization approximates.

use vtex_synth::hash::hash4;
use vtex_synth::{Error, Result, Rgba8Image};

/// The synthesis's settings.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Params {
    /// Seed of the initial noise.
    pub seed: u64,
    /// Pyramid levels (1: single resolution).
    pub levels: u8,
    /// Side N of the square whose causal half is read at the pixel's own level (odd).
    pub same: u32,
    /// Side n of the square read around the parent at the next coarser level (odd).
    pub lower: u32,
    /// The exemplar tiles: its neighbourhoods wrap and every pixel is a candidate.
    pub exemplar_wrap: bool,
    /// Scanline passes per level: the first reads the causal half; each later one refines the
    /// level in place with the whole square around the pixel (the centre excluded), as [19]'s
    /// constrained synthesis improves its first guess.
    pub passes: u32,
}

impl Params {
    /// The settings of Wei & Levoy 2002's Fig. 5 for [19]: a 4-level Gaussian pyramid, a 5×5
    /// neighbourhood over 2 levels (5×5 here, 3×3 below, as the order-independent reference
    /// reads) and three passes.
    pub fn fig5(seed: u64, exemplar_wrap: bool) -> Params {
        Params { seed, levels: 4, same: 5, lower: 3, exemplar_wrap, passes: 3 }
    }
}

/// A synthesized texture and, for each of its pixels (row-major), the exemplar pixel it copies.
#[derive(Clone, Debug, PartialEq)]
pub struct Synthesis {
    pub image: Rgba8Image,
    pub sources: Vec<(u32, u32)>,
}

/// One pyramid level of the exemplar: RGB colours, row-major.
struct Level {
    w: u32,
    h: u32,
    rgb: Vec<[u8; 3]>,
}

impl Level {
    fn at(&self, x: i64, y: i64) -> [u8; 3] {
        self.rgb[(y.rem_euclid(self.h as i64) * self.w as i64 + x.rem_euclid(self.w as i64)) as usize]
    }
}

/// The Gaussian pyramid of `sample`, finest first: each level the 5-tap binomial blur of the
/// one above, every other pixel; borders wrap when the exemplar tiles and clamp otherwise.
fn gaussian_pyramid(sample: &Rgba8Image, levels: u8, wrap: bool) -> Vec<Level> {
    const TAPS: [u32; 5] = [1, 4, 6, 4, 1];
    let rgb = sample.data.chunks_exact(4).map(|p| [p[0], p[1], p[2]]).collect();
    let mut pyramid = vec![Level { w: sample.width, h: sample.height, rgb }];
    for _ in 1..levels {
        let fine = pyramid.last().expect("the finest level");
        let coord = |v: i64, size: u32| if wrap { v.rem_euclid(size as i64) } else { v.clamp(0, size as i64 - 1) };
        let (w, h) = (fine.w / 2, fine.h / 2);
        let mut rgb = Vec::with_capacity((w * h) as usize);
        for y in 0..h as i64 {
            for x in 0..w as i64 {
                let mut sum = [0u32; 3];
                for (j, ty) in TAPS.iter().enumerate() {
                    for (i, tx) in TAPS.iter().enumerate() {
                        let (sx, sy) = (coord(2 * x + i as i64 - 2, fine.w), coord(2 * y + j as i64 - 2, fine.h));
                        let c = fine.rgb[(sy * fine.w as i64 + sx) as usize];
                        for k in 0..3 {
                            sum[k] += tx * ty * c[k] as u32;
                        }
                    }
                }
                rgb.push(sum.map(|s| ((s + 128) / 256) as u8));
            }
        }
        pyramid.push(Level { w, h, rgb });
    }
    pyramid
}

/// Offsets of the causal half of a `side`² square: the rows above, then the pixels to the left.
pub fn causal(side: u32) -> Vec<(i64, i64)> {
    let r = (side / 2) as i64;
    (-r..=0).flat_map(|dy| (-r..=r).map(move |dx| (dx, dy))).take_while(|&(dx, dy)| (dy, dx) < (0, 0)).collect()
}

/// Offsets of the full `side`² square.
fn square(side: u32) -> Vec<(i64, i64)> {
    let r = (side / 2) as i64;
    (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| (dx, dy))).collect()
}

/// The exemplar's neighbourhoods at one level, flattened for the search.
struct Candidates {
    /// Exemplar pixel index of each candidate.
    index: Vec<u32>,
    /// Their neighbourhood vectors, `dim` values each.
    vectors: Vec<i32>,
    dim: usize,
}

impl Candidates {
    fn new(ex: &Level, coarse: Option<&Level>, same: &[(i64, i64)], lower: &[(i64, i64)], wrap: bool) -> Self {
        let inside = |l: &Level, x: i64, y: i64, taps: &[(i64, i64)]| {
            wrap || taps
                .iter()
                .all(|&(dx, dy)| (0..l.w as i64).contains(&(x + dx)) && (0..l.h as i64).contains(&(y + dy)))
        };
        let dim = 3 * (same.len() + coarse.map_or(0, |_| lower.len()));
        let (mut index, mut vectors) = (Vec::new(), Vec::new());
        for y in 0..ex.h as i64 {
            for x in 0..ex.w as i64 {
                let parent_inside = coarse.is_none_or(|c| inside(c, x >> 1, y >> 1, lower));
                if !inside(ex, x, y, same) || !parent_inside {
                    continue;
                }
                index.push((y * ex.w as i64 + x) as u32);
                vectors.extend(same.iter().flat_map(|&(dx, dy)| ex.at(x + dx, y + dy)).map(i32::from));
                if let Some(c) = coarse {
                    vectors
                        .extend(lower.iter().flat_map(|&(dx, dy)| c.at((x >> 1) + dx, (y >> 1) + dy)).map(i32::from));
                }
            }
        }
        Candidates { index, vectors, dim }
    }

    /// The exemplar pixel whose neighbourhood is nearest to `query` in L2 (the first on ties).
    fn best(&self, query: &[i32]) -> u32 {
        let mut best = (i32::MAX, 0);
        for (i, v) in self.vectors.chunks_exact(self.dim).enumerate() {
            let mut d = 0;
            // Stopping once a candidate is worse than the best so far leaves the answer exact.
            for (a, b) in v.chunks(3).zip(query.chunks(3)) {
                d += (a[0] - b[0]).pow(2) + (a[1] - b[1]).pow(2) + (a[2] - b[2]).pow(2);
                if d >= best.0 {
                    break;
                }
            }
            if d < best.0 {
                best = (d, i);
            }
        }
        self.index[best.1]
    }
}

/// A `width × height` texture like `sample`. Both sides must be multiples of 2^(levels − 1)
/// and the exemplar's coarsest level must hold one neighbourhood.
pub fn synthesize(sample: &Rgba8Image, width: u32, height: u32, params: &Params) -> Result<Synthesis> {
    let levels = params.levels as usize;
    let init = (0..levels)
        .map(|l| {
            let (w, h) = (width >> l, height >> l);
            let n = ((sample.width >> l) * (sample.height >> l)) as u64;
            (0..h as i64)
                .flat_map(|y| (0..w as i64).map(move |x| (hash4(params.seed, l as u64, x, y) % n.max(1)) as u32))
                .collect()
        })
        .collect();
    synthesize_from(sample, width, height, params, init)
}

/// [`synthesize`] from a given initial output pyramid (exemplar pixel indices, finest first).
fn synthesize_from(
    sample: &Rgba8Image,
    width: u32,
    height: u32,
    params: &Params,
    mut out: Vec<Vec<u32>>,
) -> Result<Synthesis> {
    let levels = params.levels as u32;
    if !(1..=8).contains(&levels) {
        return Err(Error::param("levels", format!("{levels}: must be 1..=8")));
    }
    if params.passes == 0 {
        return Err(Error::param("passes", "0: at least 1"));
    }
    if params.same % 2 == 0 || params.lower % 2 == 0 || params.same < 3 {
        return Err(Error::param("same", format!("{} and {}: odd sides, at least 3", params.same, params.lower)));
    }
    let unit = 1 << (levels - 1);
    if width == 0 || height == 0 || width % unit != 0 || height % unit != 0 {
        return Err(Error::param("width", format!("{width}×{height}: sides must be multiples of {unit}")));
    }
    if sample.width % unit != 0 || sample.height % unit != 0 || sample.width / unit < params.same {
        return Err(Error::image(
            "sample",
            format!(
                "{}×{}: sides must be multiples of {unit}, {} at the coarsest level",
                sample.width, sample.height, params.same
            ),
        ));
    }
    let ex = gaussian_pyramid(sample, params.levels, params.exemplar_wrap);
    let lower = square(params.lower);
    let full: Vec<(i64, i64)> = square(params.same).into_iter().filter(|&o| o != (0, 0)).collect();
    for l in (0..levels as usize).rev() {
        let coarse = (l + 1 < levels as usize).then(|| &ex[l + 1]);
        let (w, h) = ((width >> l) as i64, (height >> l) as i64);
        let (done, rest) = out.split_at_mut(l + 1);
        let level = &mut done[l];
        let parent = rest.first().map(|p| (p, &ex[l + 1]));
        let colour = |level: &[u32], ex: &Level, w: i64, h: i64, x: i64, y: i64| {
            ex.rgb[level[(y.rem_euclid(h) * w + x.rem_euclid(w)) as usize] as usize]
        };
        for pass in 0..params.passes {
            let same = if pass == 0 { causal(params.same) } else { full.clone() };
            let candidates = Candidates::new(&ex[l], coarse, &same, &lower, params.exemplar_wrap);
            if candidates.index.is_empty() {
                return Err(Error::image(
                    "sample",
                    format!("level {l} has no pixel whose neighbourhood lies inside it"),
                ));
            }
            let mut query = Vec::with_capacity(candidates.dim);
            for y in 0..h {
                for x in 0..w {
                    query.clear();
                    query.extend(
                        same.iter().flat_map(|&(dx, dy)| colour(level, &ex[l], w, h, x + dx, y + dy)).map(i32::from),
                    );
                    if let Some((p, pex)) = parent {
                        let (pw, ph) = (w / 2, h / 2);
                        query.extend(
                            lower
                                .iter()
                                .flat_map(|&(dx, dy)| colour(p, pex, pw, ph, (x >> 1) + dx, (y >> 1) + dy))
                                .map(i32::from),
                        );
                    }
                    level[(y * w + x) as usize] = candidates.best(&query);
                }
            }
        }
    }
    let fine = &ex[0];
    let sources: Vec<(u32, u32)> = out[0].iter().map(|&i| (i % fine.w, i / fine.w)).collect();
    let mut image = Rgba8Image::new(width, height);
    for (px, &i) in image.data.chunks_exact_mut(4).zip(&out[0]) {
        let c = fine.rgb[i as usize];
        px.copy_from_slice(&[c[0], c[1], c[2], 255]);
    }
    Ok(Synthesis { image, sources })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::contrast::contrast_ratio;
    use crate::histogram::histogram_w1;
    use crate::test_images::noise;

    fn random_init(width: u32, height: u32, sample: &Rgba8Image, levels: u8, seed: u64) -> Vec<Vec<u32>> {
        (0..levels as u32)
            .map(|l| {
                let n = (sample.width >> l) * (sample.height >> l);
                (0..(width >> l) * (height >> l))
                    .map(|i| (hash4(seed, l as u64, i as i64, 0) % n as u64) as u32)
                    .collect()
            })
            .collect()
    }

    #[test]
    fn the_causal_half_is_what_a_scanline_pass_has_written() {
        assert_eq!(causal(3), vec![(-1, -1), (0, -1), (1, -1), (-1, 0)]);
        assert_eq!(causal(5).len(), 12);
        assert_eq!(causal(9).len(), 40);
        assert!(causal(9).iter().all(|&(dx, dy)| dy < 0 || (dy == 0 && dx < 0)));
    }

    /// A scanline pass reads each pixel only after writing it, except where the torus wraps:
    /// the first rows read the last rows' noise, the first columns the end of their own row. So
    /// the initial noise of every other pixel changes nothing, and that of the wrapped ones
    /// does. A neighbourhood that read below or to the right of the pixel would see the first
    /// change.
    #[test]
    fn a_pixel_depends_only_on_the_pixels_before_it() {
        let sample = noise(32, 32, 4);
        let params = Params { seed: 0, levels: 2, same: 5, lower: 3, exemplar_wrap: true, passes: 1 };
        let (w, h, r) = (32u32, 32u32, params.same / 2);
        let init = random_init(w, h, &sample, 2, 1);
        let synthesized = synthesize_from(&sample, w, h, &params, init.clone()).unwrap();
        let changed = |wrapped: bool| {
            let mut c = init.clone();
            for y in 0..h {
                for x in 0..w {
                    if (y >= h - r || x >= w - r) == wrapped {
                        let i = (y * w + x) as usize;
                        c[0][i] = (c[0][i] + 1 + (x * 7 + y) % 500) % 1024;
                    }
                }
            }
            synthesize_from(&sample, w, h, &params, c).unwrap()
        };
        assert_eq!(changed(false), synthesized);
        assert_ne!(changed(true).sources, synthesized.sources);
    }

    /// With an exemplar that tiles and an output pyramid that starts as the exemplar's own,
    /// every pixel's neighbourhood, causal or whole, is matched exactly at its own place: the
    /// search finds the minimum, and input and output neighbourhoods are built alike at both
    /// levels and in both kinds of pass.
    #[test]
    fn the_exemplar_itself_is_a_fixed_point() {
        let sample = noise(32, 32, 9);
        let params = Params { seed: 0, levels: 3, same: 5, lower: 3, exemplar_wrap: true, passes: 2 };
        let init = (0..3).map(|l| (0..(32u32 >> l) * (32 >> l)).collect()).collect();
        let s = synthesize_from(&sample, 32, 32, &params, init).unwrap();
        assert_eq!(s.image, sample);
        assert!(s.sources.iter().enumerate().all(|(i, &(x, y))| (y * 32 + x) as usize == i));
    }

    /// On a tileable exemplar the output is the exemplar's pixels, its histogram at most half as
    /// far from the exemplar's as the flat mean colour's and its contrast kept, not a copy of it
    /// in place; the same seed gives the same texture. With one pass and with Fig. 5's three.
    #[test]
    fn it_reproduces_the_exemplars_statistics() {
        let sample = vtex_synth::samples::lichen(32, 21);
        let mut mean = [0u64; 3];
        for p in sample.data.chunks_exact(4) {
            (0..3).for_each(|k| mean[k] += p[k] as u64);
        }
        let mut flat = Rgba8Image::new(32, 32);
        for p in flat.data.chunks_exact_mut(4) {
            p.copy_from_slice(&[(mean[0] / 1024) as u8, (mean[1] / 1024) as u8, (mean[2] / 1024) as u8, 255]);
        }
        let flat_w1 = histogram_w1(&flat, &sample).unwrap();
        for passes in [1, 3] {
            let params = Params { levels: 3, passes, ..Params::fig5(3, true) };
            let s = synthesize(&sample, 64, 64, &params).unwrap();
            for (i, &(sx, sy)) in s.sources.iter().enumerate() {
                let (x, y) = (i as u32 % 64, i as u32 / 64);
                assert_eq!(s.image.pixel(x, y), sample.pixel(sx, sy));
            }
            let w1 = histogram_w1(&s.image, &sample).unwrap();
            let contrast = contrast_ratio(&s.image, &sample).unwrap();
            assert!((0..3).all(|k| w1[k] < flat_w1[k] / 2.0), "{passes} passes: W1 {w1:?}, flat {flat_w1:?}");
            assert!((0.8..1.2).contains(&contrast), "{passes} passes: contrast {contrast}");
            let in_place =
                s.sources.iter().enumerate().filter(|&(i, &(x, y))| (x, y) == (i as u32 % 64 % 32, i as u32 / 64 % 32));
            assert!(in_place.count() < 64 * 64 / 4, "{passes} passes: mostly a tiling of the exemplar");
            assert_eq!(synthesize(&sample, 64, 64, &params).unwrap(), s);
            assert_ne!(synthesize(&sample, 64, 64, &Params { seed: 4, ..params }).unwrap().sources, s.sources);
        }
    }

    #[test]
    fn bad_sizes_are_refused_by_name() {
        let sample = noise(32, 32, 1);
        let p = Params::fig5(1, true);
        let name = |r: Result<Synthesis>| match r {
            Err(Error::Param { name, .. }) | Err(Error::Image { name, .. }) => name,
            other => panic!("{other:?}"),
        };
        assert_eq!(name(synthesize(&sample, 60, 64, &p)), "width");
        assert_eq!(name(synthesize(&noise(24, 24, 1), 64, 64, &p)), "sample");
        assert_eq!(name(synthesize(&sample, 64, 64, &Params { same: 4, ..p })), "same");
        assert_eq!(name(synthesize(&sample, 64, 64, &Params { levels: 0, ..p })), "levels");
        assert_eq!(name(synthesize(&sample, 64, 64, &Params { passes: 0, ..p })), "passes");
    }
}
