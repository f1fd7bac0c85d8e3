//! Convolution kernels N of the cascade: at most 7 × 7, given as explicit weights or built
//! from a named preset. Weights are normalised to sum 1 (in f64, then rounded once to f32)
//! so that N keeps values near the unit interval the maps act on.

use crate::{Error, Result};
use schemars::JsonSchema;
use serde::{Deserialize, Serialize};

/// Largest kernel side the paper allows (7 × 7).
pub const MAX_KERNEL_SIZE: u32 = 7;

/// A kernel as written in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize, JsonSchema)]
#[serde(deny_unknown_fields)]
pub struct KernelSpec {
    /// Side length: 1, 3, 5 or 7.
    pub size: u32,
    /// `box`, `gauss`, `dog` (difference of Gaussians: centre excitation, surround
    /// inhibition), `cross` or `ring`. Exclusive with `weights`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub preset: Option<String>,
    /// size × size weights, row-major. Exclusive with `preset`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub weights: Option<Vec<f64>>,
    /// Gaussian width in lattice units (`gauss`, and the centre of `dog`).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma: Option<f64>,
    /// Surround width of `dog`.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub sigma2: Option<f64>,
    /// Surround strength of `dog` (0..=1).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub amount: Option<f64>,
}

impl Default for KernelSpec {
    fn default() -> Self {
        Self { size: 5, preset: Some("gauss".into()), weights: None, sigma: None, sigma2: None, amount: None }
    }
}

/// One non-zero kernel weight at lattice offset (dx, dy), before dilation.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Tap {
    pub dx: i32,
    pub dy: i32,
    pub w: f32,
}

/// A validated kernel: its non-zero taps in row-major order (the summation order, fixed so
/// that every platform adds the same numbers in the same sequence).
#[derive(Clone, Debug, PartialEq)]
pub struct Kernel {
    pub radius: u32,
    pub taps: Vec<Tap>,
}

impl Kernel {
    /// Validates `spec`; `at` names it in errors (e.g. `stages[1].kernel`).
    pub fn build(spec: &KernelSpec, at: &str) -> Result<Self> {
        let n = spec.size;
        if n > MAX_KERNEL_SIZE || n % 2 == 0 {
            return Err(Error::param(
                format!("{at}.size"),
                format!("{n}: kernels are odd-sized and at most {MAX_KERNEL_SIZE}×{MAX_KERNEL_SIZE} (1, 3, 5 or 7)"),
            ));
        }
        let r = (n / 2) as i32;
        let positive = |name: &str, v: Option<f64>, default: f64, max: f64| -> Result<f64> {
            let v = v.unwrap_or(default);
            if !(v.is_finite() && v > 0.0 && v <= max) {
                return Err(Error::param(format!("{at}.{name}"), format!("{v}: must be in (0, {max}]")));
            }
            Ok(v)
        };
        let gauss = |s: f64| -> Vec<f64> {
            let mut g = Vec::with_capacity((n * n) as usize);
            for y in -r..=r {
                for x in -r..=r {
                    g.push(libm::exp(-((x * x + y * y) as f64) / (2.0 * s * s)));
                }
            }
            let sum: f64 = g.iter().sum();
            g.iter().map(|v| v / sum).collect()
        };
        let raw: Vec<f64> = match (&spec.preset, &spec.weights) {
            (Some(_), Some(_)) => {
                return Err(Error::param(at, "give either `preset` or `weights`, not both"));
            }
            (None, None) => return Err(Error::param(at, "needs `preset` or `weights`")),
            (None, Some(w)) => {
                if w.len() != (n * n) as usize {
                    return Err(Error::param(
                        format!("{at}.weights"),
                        format!("{} weights for a {n}×{n} kernel; expected {}", w.len(), n * n),
                    ));
                }
                if let Some(bad) = w.iter().find(|v| !v.is_finite() || v.abs() > 1e6) {
                    return Err(Error::param(
                        format!("{at}.weights"),
                        format!("{bad}: weights must be finite, |w| ≤ 1e6"),
                    ));
                }
                w.clone()
            }
            (Some(p), None) => match p.as_str() {
                "box" => vec![1.0; (n * n) as usize],
                "gauss" => gauss(positive("sigma", spec.sigma, n as f64 / 4.0, 16.0)?),
                "dog" => {
                    let s1 = positive("sigma", spec.sigma, 0.7, 16.0)?;
                    let s2 = positive("sigma2", spec.sigma2, n as f64 / 3.0, 16.0)?;
                    let a = positive("amount", spec.amount, 0.5, 1.0)?;
                    if s2 <= s1 {
                        return Err(Error::param(
                            format!("{at}.sigma2"),
                            "must exceed `sigma` (the surround is wider)",
                        ));
                    }
                    gauss(s1).iter().zip(gauss(s2)).map(|(c, s)| c - a * s).collect()
                }
                "cross" => {
                    (-r..=r).flat_map(|y| (-r..=r).map(move |x| if x == 0 || y == 0 { 1.0 } else { 0.0 })).collect()
                }
                "ring" => (-r..=r)
                    .flat_map(|y| {
                        (-r..=r).map(move |x| {
                            let d2 = x * x + y * y;
                            if d2 == 0 || (d2 >= r * r - r && d2 <= r * r + r) {
                                1.0
                            } else {
                                0.0
                            }
                        })
                    })
                    .collect(),
                other => {
                    return Err(Error::param(
                        format!("{at}.preset"),
                        format!("unknown preset `{other}`; one of box, gauss, dog, cross, ring"),
                    ))
                }
            },
        };
        let sum: f64 = raw.iter().sum();
        let abs: f64 = raw.iter().map(|v| v.abs()).sum();
        if sum.abs() <= 1e-6 * abs.max(f64::MIN_POSITIVE) {
            return Err(Error::param(
                at,
                format!("weights sum to {sum}; they must not cancel (the kernel is normalised to sum 1)"),
            ));
        }
        let mut taps = Vec::new();
        for (i, v) in raw.iter().enumerate() {
            let w = (v / sum) as f32;
            if w != 0.0 {
                taps.push(Tap { dx: (i as i32 % n as i32) - r, dy: (i as i32 / n as i32) - r, w });
            }
        }
        Ok(Kernel { radius: r as u32, taps })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn spec(size: u32, preset: &str) -> KernelSpec {
        KernelSpec { size, preset: Some(preset.into()), ..KernelSpec::default() }
    }

    #[test]
    fn presets_are_normalised() {
        for p in ["box", "gauss", "dog", "cross", "ring"] {
            for n in [3, 5, 7] {
                let k = Kernel::build(&spec(n, p), "k").unwrap();
                let s: f32 = k.taps.iter().map(|t| t.w).sum();
                assert!((s - 1.0).abs() < 1e-5, "{p} {n}: {s}");
                assert_eq!(k.radius, n / 2);
            }
        }
    }

    #[test]
    fn too_large_or_even_kernels_are_refused() {
        for n in [0, 2, 8, 9, 100] {
            let e = Kernel::build(&spec(n, "box"), "stages[0].kernel").unwrap_err().to_string();
            assert!(e.contains("stages[0].kernel.size") && e.contains("7×7"), "{e}");
        }
        let bad = KernelSpec { size: 3, preset: None, weights: Some(vec![1.0; 8]), ..KernelSpec::default() };
        assert!(Kernel::build(&bad, "k").unwrap_err().to_string().contains("8 weights"));
        let cancel = KernelSpec {
            size: 3,
            preset: None,
            weights: Some(vec![1., -1., 0., 0., 0., 0., 0., 0., 0.]),
            ..bad.clone()
        };
        assert!(Kernel::build(&cancel, "k").unwrap_err().to_string().contains("cancel"));
        let nan = KernelSpec { size: 1, preset: None, weights: Some(vec![f64::NAN]), ..bad };
        assert!(Kernel::build(&nan, "k").is_err());
        assert!(Kernel::build(&spec(3, "blur"), "k").unwrap_err().to_string().contains("unknown preset"));
    }
}
