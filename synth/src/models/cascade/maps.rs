//! The pointwise nonlinear maps p of A_{i+1} = p(N(A_i)). Each maps [0, 1] into [0, 1];
//! inputs are clamped to [0, 1] first because a normalised kernel with negative weights can
//! overshoot. Chaotic settings (logistic r → 4, tent μ → 2, circle with large k) roughen;
//! contracting ones (small r, sigmoid) smooth and sharpen — the paper's tension.
//!
//! Arithmetic is f32 with + − × ÷ and floor only, plus `libm`'s software sin/exp, so wasm32
//! and native agree bit for bit (no fused multiply-add anywhere).

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// A map as written in the manifest, e.g. `{"kind": "logistic", "r": 3.7}`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
pub enum MapSpec {
    /// r·x·(1 − x), r ∈ [0, 4]; chaotic above ≈ 3.57.
    Logistic { r: f64 },
    /// μ·min(x, 1 − x), μ ∈ [0, 2]; chaotic above 1.
    Tent { mu: f64 },
    /// r·sin(πx), r ∈ [0, 1]; a smooth unimodal map like the logistic.
    Sine { r: f64 },
    /// x + ω − (k/2π)·sin(2πx) mod 1, ω ∈ [0, 1], k ∈ [0, 10]; wraps, giving veins and folds.
    Circle { omega: f64, k: f64 },
    /// 1 / (1 + e^{−gain·(x − center)}), gain ∈ (0, 100], center ∈ [0, 1]; with a
    /// centre-surround kernel this grows spots and stripes (reaction–diffusion-like).
    Sigmoid { gain: f64, center: f64 },
}

// Read as a JSON value, its tag and then its fields from that value, as the derive of
// `#[serde(tag)]` would but without its buffered `Content`: the fields are then deserialized
// by serde_json's value deserializer only, which keeps the WebAssembly module small.
impl<'de> Deserialize<'de> for MapSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        use serde::de::Error;
        #[derive(Deserialize)]
        #[serde(variant_identifier, rename_all = "lowercase")]
        enum Kind {
            Logistic,
            Tent,
            Sine,
            Circle,
            Sigmoid,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct R {
            r: f64,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Mu {
            mu: f64,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Circle {
            omega: f64,
            k: f64,
        }
        #[derive(Deserialize)]
        #[serde(deny_unknown_fields)]
        struct Sigmoid {
            gain: f64,
            center: f64,
        }
        let (kind, fields) = crate::bundle::tagged(d, "kind", "internally tagged enum MapSpec")?;
        let spec = match kind {
            Kind::Logistic => serde_json::from_value(fields).map(|R { r }| MapSpec::Logistic { r }),
            Kind::Tent => serde_json::from_value(fields).map(|Mu { mu }| MapSpec::Tent { mu }),
            Kind::Sine => serde_json::from_value(fields).map(|R { r }| MapSpec::Sine { r }),
            Kind::Circle => serde_json::from_value(fields).map(|Circle { omega, k }| MapSpec::Circle { omega, k }),
            Kind::Sigmoid => {
                serde_json::from_value(fields).map(|Sigmoid { gain, center }| MapSpec::Sigmoid { gain, center })
            }
        };
        spec.map_err(D::Error::custom)
    }
}

impl Default for MapSpec {
    fn default() -> Self {
        MapSpec::Logistic { r: 3.7 }
    }
}

/// A validated map with f32 parameters.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Map {
    Logistic(f32),
    Tent(f32),
    Sine(f32),
    Circle { omega: f32, k: f32 },
    Sigmoid { gain: f32, center: f32 },
}

const PI: f32 = core::f32::consts::PI;

impl Map {
    pub fn build(spec: &MapSpec, at: &str) -> Result<Self> {
        let check = |name: &str, v: f64, lo: f64, hi: f64, open_lo: bool| -> Result<f32> {
            let ok = v.is_finite() && v <= hi && if open_lo { v > lo } else { v >= lo };
            if !ok {
                let l = if open_lo { "(" } else { "[" };
                return Err(Error::param(format!("{at}.{name}"), format!("{v} is out of range {l}{lo}, {hi}]")));
            }
            Ok(v as f32)
        };
        Ok(match *spec {
            MapSpec::Logistic { r } => Map::Logistic(check("r", r, 0.0, 4.0, false)?),
            MapSpec::Tent { mu } => Map::Tent(check("mu", mu, 0.0, 2.0, false)?),
            MapSpec::Sine { r } => Map::Sine(check("r", r, 0.0, 1.0, false)?),
            MapSpec::Circle { omega, k } => {
                Map::Circle { omega: check("omega", omega, 0.0, 1.0, false)?, k: check("k", k, 0.0, 10.0, false)? }
            }
            MapSpec::Sigmoid { gain, center } => Map::Sigmoid {
                gain: check("gain", gain, 0.0, 100.0, true)?,
                center: check("center", center, 0.0, 1.0, false)?,
            },
        })
    }

    /// Applies the map in place to every value (one `match` per row keeps the loops tight).
    pub fn apply(&self, v: &mut [f32]) {
        let clamp = |x: f32| x.clamp(0.0, 1.0);
        match *self {
            Map::Logistic(r) => v.iter_mut().for_each(|x| {
                let c = clamp(*x);
                *x = r * c * (1.0 - c)
            }),
            Map::Tent(mu) => v.iter_mut().for_each(|x| {
                let c = clamp(*x);
                *x = mu * c.min(1.0 - c)
            }),
            // sin(π·1) rounds to −8.7e−8 in f32: keep the range closed.
            Map::Sine(r) => v.iter_mut().for_each(|x| *x = (r * libm::sinf(PI * clamp(*x))).max(0.0)),
            Map::Circle { omega, k } => {
                let a = k / (2.0 * PI);
                v.iter_mut().for_each(|x| {
                    let c = clamp(*x);
                    let y = c + omega - a * libm::sinf(2.0 * PI * c);
                    *x = y - libm::floorf(y)
                })
            }
            Map::Sigmoid { gain, center } => {
                v.iter_mut().for_each(|x| *x = 1.0 / (1.0 + libm::expf(-gain * (clamp(*x) - center))))
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn maps_stay_in_the_unit_interval() {
        let specs = [
            MapSpec::Logistic { r: 4.0 },
            MapSpec::Tent { mu: 2.0 },
            MapSpec::Sine { r: 1.0 },
            MapSpec::Circle { omega: 0.9, k: 10.0 },
            MapSpec::Sigmoid { gain: 100.0, center: 0.0 },
        ];
        let mut xs: Vec<f32> = (-20..=120).map(|i| i as f32 / 100.0).collect();
        xs.extend([f32::MAX, f32::MIN, 1e-30]);
        for s in specs {
            let m = Map::build(&s, "m").unwrap();
            let mut v = xs.clone();
            m.apply(&mut v);
            assert!(v.iter().all(|x| (0.0..=1.0).contains(x)), "{s:?}: {v:?}");
        }
    }

    #[test]
    fn parameters_out_of_range_are_named() {
        let e = Map::build(&MapSpec::Logistic { r: 4.5 }, "stages[2].map").unwrap_err().to_string();
        assert!(e.contains("stages[2].map.r") && e.contains("4.5"), "{e}");
        assert!(Map::build(&MapSpec::Tent { mu: -0.1 }, "m").is_err());
        assert!(Map::build(&MapSpec::Sine { r: f64::NAN }, "m").is_err());
        assert!(Map::build(&MapSpec::Circle { omega: 0.5, k: 11.0 }, "m").is_err());
        assert!(Map::build(&MapSpec::Sigmoid { gain: 0.0, center: 0.5 }, "m").is_err());
    }

    #[test]
    fn logistic_is_pinned() {
        // Bit patterns pinned: any change (e.g. a fused multiply-add) changes every texture.
        let mut v = [0.3f32, 0.7, 0.123_456];
        Map::Logistic(3.7).apply(&mut v);
        assert_eq!(
            v.map(f32::to_bits),
            [
                (3.7f32 * 0.3 * 0.7).to_bits(),
                (3.7f32 * 0.7 * (1.0 - 0.7)).to_bits(),
                (3.7f32 * 0.123_456 * (1.0 - 0.123_456)).to_bits()
            ]
        );
    }
}

#[cfg(test)]
mod read_as_derived {
    use super::*;
    use crate::bundle::read_both_ways;
    use serde_json::json;

    /// `MapSpec` as serde's derive reads it (of the same name, which serde's messages hold).
    #[allow(dead_code)] // read through Debug only
    mod derived {
        use serde::Deserialize;

        #[derive(Debug, Deserialize)]
        #[serde(tag = "kind", rename_all = "lowercase", deny_unknown_fields)]
        pub enum MapSpec {
            Logistic { r: f64 },
            Tent { mu: f64 },
            Sine { r: f64 },
            Circle { omega: f64, k: f64 },
            Sigmoid { gain: f64, center: f64 },
        }
    }

    #[test]
    fn map_specs_read_as_the_derive_does() {
        let specs = [
            json!({"kind": "logistic", "r": 3.7}),
            json!({"r": 3, "kind": "sine"}),
            json!({"kind": "tent", "mu": 1.5}),
            json!({"kind": "circle", "omega": 0.2, "k": 1}),
            json!({"kind": "sigmoid", "gain": 8, "center": 0.5}),
            json!({"kind": "logistic"}),
            json!({"kind": "logistic", "r": 3.7, "mu": 1}),
            json!({"kind": "logistic", "r": "3.7"}),
            json!({"kind": "tent", "r": 1}),
            json!({"kind": "spiral", "r": 1}),
            json!({"kind": 2, "r": 1}),
            json!({"r": 1}),
            json!("logistic"),
            json!(["logistic", 3.7]),
            json!(null),
        ];
        for v in &specs {
            assert_eq!(read_both_ways::<MapSpec>(v), read_both_ways::<derived::MapSpec>(v), "{v}");
        }
    }
}
