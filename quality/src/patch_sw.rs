//! Patch sliced-Wasserstein distance: do the output's local neighbourhoods look like the
//! sample's, at several scales? Histograms see single pixels; patches see structure (edges,
//! grains, bricks), and the pyramid sees it from fine to coarse.

use vtex_synth::{hash, mip, Error, Result, Rgba8Image};

/// How [`patch_sliced_wasserstein`] samples patches and directions.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct SwParams {
    /// Side of the square patches, in pixels of each scale.
    pub patch: u32,
    /// Pyramid scales compared: scale s is the image after s exact 2×2 box downsamples
    /// ([`vtex_synth::mip::downsample`]).
    pub scales: u32,
    /// Random unit directions the patch vectors are projected on.
    pub projections: u32,
    /// Most patches taken from one image at one scale; above it, positions are drawn.
    pub max_patches: u32,
    /// Seed of the directions and of the drawn positions (via [`vtex_synth::hash`]).
    pub seed: u64,
}

impl Default for SwParams {
    /// 5 × 5 patches at 3 scales, 32 directions, at most 16384 patches an image and scale.
    fn default() -> Self {
        Self { patch: 5, scales: 3, projections: 32, max_patches: 16_384, seed: 0x5eed }
    }
}

/// The distance at each scale (finest first) and their mean, in grey levels.
#[derive(Clone, Debug, PartialEq)]
pub struct PatchSw {
    pub per_scale: Vec<f64>,
    pub mean: f64,
}

/// Patch sliced-Wasserstein distance between `output` and `sample`, per pyramid scale.
///
/// Exact definition, at each scale s < `scales`: every `patch × patch` window that lies
/// inside the image is a vector of 3·patch² values (RGB in grey levels, alpha ignored); when an
/// image has more than `max_patches` windows, `max_patches` of them are drawn uniformly with
/// replacement from `hash4(seed, 1 + s, i, 0)`. Each vector is projected on `projections` unit
/// directions θ_k (Gaussian components from `hash4(seed, 0, k, j)` by Box–Muller, normalised,
/// the same for both images), and
///
/// SW_s = (1/K) Σ_k W1(θ_k · patches(output), θ_k · patches(sample)),
///
/// with W1 the exact 1-D Wasserstein distance between the two empirical distributions,
/// ∫₀¹ |Q_out(t) − Q_sample(t)| dt over their quantile functions (sizes may differ). An image
/// against itself gives 0; adding c to every channel gives c · (1/K) Σ_k |Σ_j θ_kj|.
/// Errors: a zero parameter, or an image smaller than a patch at the coarsest scale.
pub fn patch_sliced_wasserstein(output: &Rgba8Image, sample: &Rgba8Image, params: &SwParams) -> Result<PatchSw> {
    for (name, v) in [
        ("patch", params.patch),
        ("scales", params.scales),
        ("projections", params.projections),
        ("max_patches", params.max_patches),
    ] {
        if v == 0 {
            return Err(Error::param(name, "must be at least 1"));
        }
    }
    let dim = 3 * params.patch as usize * params.patch as usize;
    let dirs = directions(dim, params.projections, params.seed);
    let (mut a, mut b) = (output.clone(), sample.clone());
    let mut per_scale = Vec::with_capacity(params.scales as usize);
    for s in 0..params.scales {
        if s > 0 {
            a = mip::downsample(&a);
            b = mip::downsample(&b);
        }
        for (name, img) in [("output", &a), ("sample", &b)] {
            if img.width < params.patch || img.height < params.patch {
                return Err(Error::image(
                    name,
                    format!(
                        "{}×{} at scale {s} is smaller than a {p}×{p} patch; use fewer scales",
                        img.width,
                        img.height,
                        p = params.patch
                    ),
                ));
            }
        }
        let pa = projected(&a, params, s, &dirs);
        let pb = projected(&b, params, s, &dirs);
        let total: f64 = pa.iter().zip(&pb).map(|(x, y)| w1_sorted(x, y)).sum();
        per_scale.push(total / dirs.len() as f64);
    }
    let mean = per_scale.iter().sum::<f64>() / per_scale.len() as f64;
    Ok(PatchSw { per_scale, mean })
}

/// The `count` unit directions in `dim` dimensions that [`patch_sliced_wasserstein`] uses.
pub fn directions(dim: usize, count: u32, seed: u64) -> Vec<Vec<f64>> {
    (0..count as i64)
        .map(|k| {
            let mut v: Vec<f64> = (0..dim as i64)
                .map(|j| {
                    // Box–Muller; u1 in (0, 1] keeps the logarithm finite.
                    let h = hash::hash4(seed, 0, k, j);
                    let u1 = 1.0 - hash::unit_f64(h);
                    let u2 = hash::unit_f64(hash::fmix64(h));
                    (-2.0 * u1.ln()).sqrt() * (std::f64::consts::TAU * u2).cos()
                })
                .collect();
            let norm = v.iter().map(|x| x * x).sum::<f64>().sqrt();
            v.iter_mut().for_each(|x| *x /= norm);
            v
        })
        .collect()
}

/// For each direction, the sorted projections of the image's (drawn) patches.
fn projected(img: &Rgba8Image, params: &SwParams, scale: u32, dirs: &[Vec<f64>]) -> Vec<Vec<f64>> {
    let p = params.patch;
    let (nx, ny) = ((img.width - p + 1) as u64, (img.height - p + 1) as u64);
    let total = nx * ny;
    let positions: Vec<(u32, u32)> = if total <= params.max_patches as u64 {
        (0..total).map(|i| ((i % nx) as u32, (i / nx) as u32)).collect()
    } else {
        (0..params.max_patches as i64)
            .map(|i| {
                let at = hash::below(hash::hash4(params.seed, 1 + scale as u64, i, 0), total);
                ((at % nx) as u32, (at / nx) as u32)
            })
            .collect()
    };
    let mut out = vec![Vec::with_capacity(positions.len()); dirs.len()];
    let mut v = Vec::with_capacity(3 * (p * p) as usize);
    for &(x0, y0) in &positions {
        v.clear();
        for y in y0..y0 + p {
            for x in x0..x0 + p {
                let px = img.pixel(x, y);
                v.extend([px[0] as f64, px[1] as f64, px[2] as f64]);
            }
        }
        for (d, o) in dirs.iter().zip(out.iter_mut()) {
            o.push(d.iter().zip(&v).map(|(a, b)| a * b).sum());
        }
    }
    for o in out.iter_mut() {
        o.sort_by(f64::total_cmp);
    }
    out
}

/// Exact W1 between the empirical distributions of two sorted, non-empty samples: the area
/// between their quantile step functions, walked in order of the steps at i/n and j/m.
pub fn w1_sorted(a: &[f64], b: &[f64]) -> f64 {
    let (n, m) = (a.len() as u64, b.len() as u64);
    let (mut i, mut j, mut acc, mut t) = (0u64, 0u64, 0.0, 0.0);
    while i < n && j < m {
        // Next step of a is at (i+1)/n, of b at (j+1)/m; compare exactly in integers.
        let (ea, eb) = ((i + 1) * m, (j + 1) * n);
        let next = if ea <= eb { (i + 1) as f64 / n as f64 } else { (j + 1) as f64 / m as f64 };
        acc += (next - t) * (a[i as usize] - b[j as usize]).abs();
        t = next;
        if ea <= eb {
            i += 1;
        }
        if eb <= ea {
            j += 1;
        }
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::{grey, noise, tiled};

    #[test]
    fn w1_of_known_samples() {
        assert_eq!(w1_sorted(&[1.0, 2.0, 3.0], &[1.0, 2.0, 3.0]), 0.0);
        assert!((w1_sorted(&[0.0, 1.0], &[5.0, 6.0]) - 5.0).abs() < 1e-12);
        // Uniform on {0, 1} against the point 0.5: half the mass moves 0.5.
        assert!((w1_sorted(&[0.0, 1.0], &[0.5]) - 0.5).abs() < 1e-12);
        // Sizes 2 and 3: quantiles [0,½)→0 vs [0,⅓)→0, [⅓,⅔)→0, [⅔,1)→3; a = [0, 3].
        assert!((w1_sorted(&[0.0, 3.0], &[0.0, 0.0, 3.0]) - 3.0 / 6.0).abs() < 1e-12);
    }

    #[test]
    fn directions_are_unit_and_stable() {
        let d = directions(75, 8, 1);
        assert_eq!(d.len(), 8);
        for v in &d {
            assert!((v.iter().map(|x| x * x).sum::<f64>() - 1.0).abs() < 1e-12);
        }
        assert_eq!(d, directions(75, 8, 1));
        assert_ne!(d, directions(75, 8, 2));
    }

    #[test]
    fn image_against_itself_is_zero() {
        let img = noise(96, 80, 1);
        let sw = patch_sliced_wasserstein(&img, &img, &SwParams::default()).unwrap();
        assert_eq!(sw.per_scale, vec![0.0; 3]);
        assert_eq!(sw.mean, 0.0);
    }

    #[test]
    fn a_uniform_shift_moves_every_projection_by_its_direction_sum() {
        let a = grey(64, 64, |x, y| 100.0 + 60.0 * ((x * 0.3).sin() * (y * 0.2).cos()));
        let mut b = a.clone();
        b.data.chunks_exact_mut(4).for_each(|p| p[..3].iter_mut().for_each(|v| *v += 12));
        let params = SwParams { max_patches: 500, ..SwParams::default() };
        let sw = patch_sliced_wasserstein(&b, &a, &params).unwrap();
        let dirs = directions(75, params.projections, params.seed);
        let expected = 12.0 * dirs.iter().map(|d| d.iter().sum::<f64>().abs()).sum::<f64>() / dirs.len() as f64;
        for s in &sw.per_scale {
            assert!((s - expected).abs() < 1e-9, "{sw:?} vs {expected}");
        }
    }

    #[test]
    fn tiling_is_close_and_blur_is_far() {
        let sample = noise(64, 64, 3);
        let tiling = tiled(&sample, 256, 256);
        let blurred = mip::downsample(&tiled(&sample, 128, 128));
        let p = SwParams::default();
        let near = patch_sliced_wasserstein(&tiling, &sample, &p).unwrap();
        let far = patch_sliced_wasserstein(&tiled(&blurred, 256, 256), &sample, &p).unwrap();
        for s in 0..3 {
            assert!(near.per_scale[s] * 5.0 < far.per_scale[s], "{near:?} vs {far:?}");
        }
        assert!(near.per_scale[0] < 3.0, "{near:?}");
    }

    #[test]
    fn refuses_zero_params_and_tiny_images() {
        let img = noise(32, 32, 1);
        let err = patch_sliced_wasserstein(&img, &img, &SwParams { projections: 0, ..SwParams::default() });
        assert!(err.unwrap_err().to_string().contains("projections"));
        let err = patch_sliced_wasserstein(&img, &noise(16, 16, 2), &SwParams::default()).unwrap_err();
        assert!(err.to_string().contains("sample") && err.to_string().contains("scale 2"), "{err}");
    }
}
