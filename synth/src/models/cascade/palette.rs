//! Colour through palettes: the cascade's scalar field, normalised by the encoding's
//! `range`, indexes a lookup table built once (in f64) from colour stops.

use crate::{Error, Result};
use serde::{Deserialize, Serialize};

/// Entries of the lookup table: finer than 8-bit output so steep gradients do not band.
pub const LUT_SIZE: usize = 1024;

/// A named palette or explicit stops `[[t, "#rrggbb"], …]` with t rising from 0 to 1.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(untagged)]
pub enum PaletteSpec {
    Named(String),
    Stops(Vec<(f64, String)>),
}

// Read as a JSON value and then as either variant, as the derive of `#[serde(untagged)]`
// would but without its buffered `Content` (which keeps the WebAssembly module small).
impl<'de> Deserialize<'de> for PaletteSpec {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> std::result::Result<Self, D::Error> {
        let value = serde_json::Value::deserialize(d)?;
        if let serde_json::Value::String(name) = value {
            return Ok(PaletteSpec::Named(name));
        }
        serde_json::from_value(value)
            .map(PaletteSpec::Stops)
            .map_err(|_| serde::de::Error::custom("data did not match any variant of untagged enum PaletteSpec"))
    }
}

impl Default for PaletteSpec {
    fn default() -> Self {
        PaletteSpec::Named("gray".into())
    }
}

/// Names of the built-in palettes.
pub const PALETTES: &[&str] = &["gray", "earth", "marble", "fire", "ocean", "moss", "granite"];

fn named(name: &str) -> Option<&'static [(f64, u32)]> {
    Some(match name {
        "gray" => &[(0.0, 0x000000), (1.0, 0xffffff)],
        "earth" => &[(0.0, 0x2b1a0e), (0.35, 0x6b4a2b), (0.6, 0xa8845a), (0.8, 0xcdb38a), (1.0, 0xf1e6cf)],
        "marble" => &[(0.0, 0x3a3f4a), (0.25, 0x8d96a3), (0.5, 0xe6e4de), (0.8, 0xf7f4ee), (1.0, 0xffffff)],
        "fire" => &[(0.0, 0x0a0000), (0.3, 0x6e0b00), (0.55, 0xd94a00), (0.8, 0xffb020), (1.0, 0xfff5c0)],
        "ocean" => &[(0.0, 0x02101f), (0.4, 0x0b4a6f), (0.7, 0x2f9bb3), (0.9, 0x9fe0e0), (1.0, 0xf0ffff)],
        "moss" => &[(0.0, 0x10180a), (0.4, 0x3c5a1c), (0.7, 0x7f9a3a), (1.0, 0xd9e0a0)],
        "granite" => &[(0.0, 0x1c1a1a), (0.3, 0x5a4e4a), (0.55, 0x9c8c84), (0.75, 0xc9b8ae), (1.0, 0xf2e9e4)],
        _ => return None,
    })
}

/// Builds the lookup table, validating the spec.
pub fn build(spec: &PaletteSpec) -> Result<Vec<[u8; 4]>> {
    let stops: Vec<(f64, u32)> = match spec {
        PaletteSpec::Named(n) => named(n)
            .ok_or_else(|| Error::param("palette", format!("unknown palette `{n}`; one of {}", PALETTES.join(", "))))?
            .to_vec(),
        PaletteSpec::Stops(s) => {
            if !(2..=64).contains(&s.len()) {
                return Err(Error::param("palette", format!("{} stops; 2 to 64", s.len())));
            }
            let mut out = Vec::with_capacity(s.len());
            for (i, (t, c)) in s.iter().enumerate() {
                let hex = c.strip_prefix('#').filter(|h| h.len() == 6).and_then(|h| u32::from_str_radix(h, 16).ok());
                let rgb = hex.ok_or_else(|| Error::param(format!("palette[{i}]"), format!("`{c}` is not #rrggbb")))?;
                let prev = out.last().map(|p: &(f64, u32)| p.0).unwrap_or(0.0);
                if !(t.is_finite() && (0.0..=1.0).contains(t) && *t >= prev) {
                    return Err(Error::param(format!("palette[{i}]"), format!("position {t} must rise within [0, 1]")));
                }
                out.push((*t, rgb));
            }
            out
        }
    };
    let chan = |c: u32, k: u32| ((c >> (16 - 8 * k)) & 0xff) as f64;
    let mut lut = Vec::with_capacity(LUT_SIZE);
    for i in 0..LUT_SIZE {
        let t = i as f64 / (LUT_SIZE - 1) as f64;
        let j = stops.iter().position(|s| s.0 >= t).unwrap_or(stops.len() - 1);
        let (a, b) = if j == 0 { (stops[0], stops[0]) } else { (stops[j - 1], stops[j]) };
        let f = if b.0 > a.0 { ((t - a.0) / (b.0 - a.0)).clamp(0.0, 1.0) } else { 1.0 };
        let px = [0, 1, 2].map(|k| (chan(a.1, k) + (chan(b.1, k) - chan(a.1, k)) * f + 0.5).floor() as u8);
        lut.push([px[0], px[1], px[2], 255]);
    }
    Ok(lut)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn named_and_explicit() {
        for n in PALETTES {
            assert_eq!(build(&PaletteSpec::Named(n.to_string())).unwrap().len(), LUT_SIZE);
        }
        let lut = build(&PaletteSpec::Stops(vec![(0.0, "#000000".into()), (1.0, "#ff0080".into())])).unwrap();
        assert_eq!(lut[0], [0, 0, 0, 255]);
        assert_eq!(lut[LUT_SIZE - 1], [255, 0, 128, 255]);
        assert!(build(&PaletteSpec::Named("neon".into())).unwrap_err().to_string().contains("unknown palette"));
        assert!(build(&PaletteSpec::Stops(vec![(0.5, "#000000".into()), (0.2, "#ffffff".into())])).is_err());
        assert!(build(&PaletteSpec::Stops(vec![(0.0, "red".into()), (1.0, "#ffffff".into())])).is_err());
    }
}

#[cfg(test)]
mod read_as_derived {
    use super::*;
    use serde_json::json;

    /// `PaletteSpec` as serde's derive reads it (of the same name, which serde's messages hold).
    #[allow(dead_code)] // read through Debug only
    mod derived {
        use serde::Deserialize;

        #[derive(Debug, Deserialize)]
        #[serde(untagged)]
        pub enum PaletteSpec {
            Named(String),
            Stops(Vec<(f64, String)>),
        }
    }

    #[test]
    fn palette_specs_read_as_the_derive_does() {
        let specs = [
            json!("earth"),
            json!([[0, "#000000"], [1.0, "#ffffff"]]),
            json!([]),
            json!([[0, "#000000", 1]]),
            json!([["0", "#000000"]]),
            json!({"name": "earth"}),
            json!(3),
            json!(null),
        ];
        for v in &specs {
            let new =
                serde_json::from_value::<PaletteSpec>(v.clone()).map(|t| format!("{t:?}")).map_err(|e| e.to_string());
            let old = serde_json::from_value::<derived::PaletteSpec>(v.clone())
                .map(|t| format!("{t:?}"))
                .map_err(|e| e.to_string());
            assert_eq!(new, old, "{v}");
        }
    }
}
