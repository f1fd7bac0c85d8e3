//! Convolution kernels N of the cascade: at most 7 × 7, given as explicit weights or built
//! from a named preset. Weights are normalised to sum 1 (in f64, then rounded once to f32)
//! so that N keeps values near the unit interval the maps act on.
//!
//! A kernel can be scaled, stretched and rotated ([`Kernel::transformed`]): convolution is
//! closed under linear transforms, so the transformed kernel is the same continuous function
//! with its argument transformed, sampled at every lattice offset it covers.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Largest kernel side the paper allows (7 × 7).
pub const MAX_KERNEL_SIZE: u32 = 7;

/// A kernel as written in the manifest.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
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
    /// Largest |dx| or |dy| of a tap: how far one convolution reaches.
    pub reach: u32,
    pub taps: Vec<Tap>,
    /// The weights as given, `side × side` row-major and not normalised: what transforms act on.
    grid: Vec<f64>,
    side: u32,
}

/// A linear transform of a kernel: its x axis stretched by `sx`, its y axis by `sy` (both
/// ≥ 1), then rotated by `angle` radians anticlockwise.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Shape {
    pub sx: f64,
    pub sy: f64,
    pub angle: f64,
}

impl Shape {
    pub const IDENTITY: Shape = Shape { sx: 1.0, sy: 1.0, angle: 0.0 };

    /// The same shape with both axes scaled by `f`.
    pub fn scaled(self, f: f64) -> Shape {
        Shape { sx: self.sx * f, sy: self.sy * f, ..self }
    }
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
        let weights = (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| (dx, dy))).zip(raw.iter().copied());
        Self::normalised(weights, raw.clone(), n).map_err(|sum| {
            Error::param(at, format!("weights sum to {sum}; they must not cancel (the kernel is normalised to sum 1)"))
        })
    }

    /// The kernel of `(offset, weight)` pairs in row-major order, normalised to sum 1; `Err(sum)`
    /// when the weights cancel.
    fn normalised(
        weights: impl Iterator<Item = ((i32, i32), f64)> + Clone,
        grid: Vec<f64>,
        side: u32,
    ) -> std::result::Result<Self, f64> {
        let sum: f64 = weights.clone().map(|(_, v)| v).sum();
        let abs: f64 = weights.clone().map(|(_, v)| v.abs()).sum();
        if sum.abs() <= 1e-6 * abs.max(f64::MIN_POSITIVE) {
            return Err(sum);
        }
        let taps: Vec<Tap> =
            weights.map(|((dx, dy), v)| Tap { dx, dy, w: (v / sum) as f32 }).filter(|t| t.w != 0.0).collect();
        let reach = taps.iter().map(|t| t.dx.unsigned_abs().max(t.dy.unsigned_abs())).max().unwrap_or(0);
        Ok(Kernel { reach, taps, grid, side })
    }

    /// The kernel as a continuous function: its weights interpolated bilinearly between the
    /// grid points, zero one step beyond the outermost ones. At grid points it is the weight.
    fn continuous(&self, u: f64, v: f64) -> f64 {
        let n = self.side as i64;
        let r = (n / 2) as f64;
        let (gx, gy) = (u + r, v + r);
        let (ix, iy) = (libm::floor(gx), libm::floor(gy));
        let (fx, fy) = (gx - ix, gy - iy);
        let (ix, iy) = (ix as i64, iy as i64);
        let at = |x: i64, y: i64| {
            if (0..n).contains(&x) && (0..n).contains(&y) {
                self.grid[(y * n + x) as usize]
            } else {
                0.0
            }
        };
        let row = |y: i64| at(ix, y) * (1.0 - fx) + at(ix + 1, y) * fx;
        row(iy) * (1.0 - fy) + row(iy + 1) * fy
    }

    /// The kernel transformed by `shape`: N'(o) ∝ N(M⁻¹·o) for every lattice offset o, where
    /// M stretches then rotates. Tap t of the original lands on M·t with its relative weight,
    /// and the offsets between the transformed taps carry the interpolated weights, so a
    /// dilated kernel reads the whole lattice (integer dilation with holes would split it into
    /// independent sub-lattices, and features would not grow). The identity returns the
    /// kernel unchanged. `at` names the kernel in the error when the transformed weights cancel.
    pub fn transformed(&self, shape: Shape, at: &str) -> Result<Kernel> {
        if shape == Shape::IDENTITY {
            return Ok(self.clone());
        }
        let (sin, cos) = (libm::sin(shape.angle), libm::cos(shape.angle));
        let support = (self.side / 2 + 1) as f64;
        let hx = libm::floor(support * (cos.abs() * shape.sx + sin.abs() * shape.sy)) as i32;
        let hy = libm::floor(support * (sin.abs() * shape.sx + cos.abs() * shape.sy)) as i32;
        let weights = (-hy..=hy).flat_map(|dy| (-hx..=hx).map(move |dx| (dx, dy))).map(|(dx, dy)| {
            let (ox, oy) = (dx as f64, dy as f64);
            let u = (cos * ox + sin * oy) / shape.sx;
            let v = (cos * oy - sin * ox) / shape.sy;
            ((dx, dy), self.continuous(u, v))
        });
        Self::normalised(weights, self.grid.clone(), self.side).map_err(|sum| {
            Error::param(at, format!("transformed, the weights sum to {sum}: they cancel (make the surround weaker)"))
        })
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
                assert_eq!(k.reach, n / 2);
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
