//! From intensity to colour: one intensity plane through a palette (a piecewise-linear
//! gradient), or one plane per channel (a base element per channel), each clamped to a byte.
//! Intensities arrive in Q20 fixed point, in the units of the base element's pixels.

use crate::{Error, Result};

/// Fixed-point shift of intensities.
pub const QI: u32 = 20;
const LUT_LEN: usize = 4096;
/// Palette stops must lie within ± this many intensity units.
const MAX_STOP: f64 = (1u64 << 20) as f64;

/// How intensities become RGB.
#[derive(Clone)]
pub enum Colour {
    /// One plane through a gradient sampled into a table over [lo, hi] (Q20); clamped outside.
    Palette { lo: i64, hi: i64, scale: u64, lut: Vec<[u8; 3]> },
    /// Three planes, each rounded and clamped to 0..=255.
    Channels,
}

impl std::fmt::Debug for Colour {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Colour::Palette { lo, hi, .. } => write!(f, "Palette({lo}..{hi})"),
            Colour::Channels => f.write_str("Channels"),
        }
    }
}

impl Colour {
    /// A gradient through `stops` of `[intensity, r, g, b]`, intensities strictly increasing.
    pub fn palette(stops: &[[f64; 4]]) -> Result<Colour> {
        if stops.len() < 2 {
            return Err(Error::param("palette", format!("{} stops; a gradient needs at least 2", stops.len())));
        }
        for (n, s) in stops.iter().enumerate() {
            if !s[0].is_finite() || s[0].abs() > MAX_STOP {
                return Err(Error::param("palette", format!("stop {n}: intensity {} is not within ±{MAX_STOP}", s[0])));
            }
            if s[1..].iter().any(|c| !(0.0..=255.0).contains(c)) {
                return Err(Error::param("palette", format!("stop {n}: colour {:?} is not within 0..=255", &s[1..])));
            }
            if n > 0 && s[0] <= stops[n - 1][0] {
                return Err(Error::param("palette", format!("stop {n}: intensities must strictly increase")));
            }
        }
        let q = |t: f64| libm::floor(t * (1u64 << QI) as f64) as i64;
        let (lo, hi) = (q(stops[0][0]), q(stops[stops.len() - 1][0]));
        if hi <= lo {
            return Err(Error::param("palette", "the stops span no intensity"));
        }
        let span = stops[stops.len() - 1][0] - stops[0][0];
        let lut = (0..LUT_LEN)
            .map(|i| {
                let t = stops[0][0] + span * i as f64 / (LUT_LEN - 1) as f64;
                let seg = stops.windows(2).position(|w| t <= w[1][0]).unwrap_or(stops.len() - 2);
                let (a, b) = (stops[seg], stops[seg + 1]);
                let f = ((t - a[0]) / (b[0] - a[0])).clamp(0.0, 1.0);
                std::array::from_fn(|c| libm::floor(a[c + 1] + (b[c + 1] - a[c + 1]) * f + 0.5) as u8)
            })
            .collect();
        let scale = (((LUT_LEN as u128 - 1) << 32) / (hi - lo) as u128) as u64;
        Ok(Colour::Palette { lo, hi, scale, lut })
    }

    /// The number of intensity planes this mapping reads.
    pub fn planes(&self) -> usize {
        match self {
            Colour::Palette { .. } => 1,
            Colour::Channels => 3,
        }
    }

    /// Writes one row of RGBA from per-plane Q20 intensities.
    pub fn write_row(&self, planes: &[Vec<i64>], out: &mut [u8]) {
        match self {
            Colour::Palette { lo, hi, scale, lut } => {
                for (px, &v) in out.chunks_exact_mut(4).zip(&planes[0]) {
                    let d = (v.clamp(*lo, *hi) - lo) as u128;
                    let idx = ((d * *scale as u128 + (1 << 31)) >> 32).min(LUT_LEN as u128 - 1) as usize;
                    let c = lut[idx];
                    px.copy_from_slice(&[c[0], c[1], c[2], 255]);
                }
            }
            Colour::Channels => {
                let byte = |v: i64| ((v + (1 << (QI - 1))) >> QI).clamp(0, 255) as u8;
                for (x, px) in out.chunks_exact_mut(4).enumerate() {
                    px.copy_from_slice(&[byte(planes[0][x]), byte(planes[1][x]), byte(planes[2][x]), 255]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn palette_interpolates_and_clamps() {
        let p = Colour::palette(&[[-100.0, 0.0, 0.0, 0.0], [0.0, 100.0, 200.0, 50.0], [100.0, 255.0, 255.0, 255.0]])
            .unwrap();
        let px = |t: f64| {
            let mut out = [0u8; 4];
            p.write_row(&[vec![(t * (1u64 << QI) as f64) as i64]], &mut out);
            out
        };
        assert_eq!(px(-1000.0), [0, 0, 0, 255]);
        assert_eq!(px(0.0), [100, 200, 50, 255]);
        assert_eq!(px(5000.0), [255, 255, 255, 255]);
        let mid = px(-50.0);
        assert!((49..=51).contains(&mid[0]) && (99..=101).contains(&mid[1]), "{mid:?}");
    }

    #[test]
    fn bad_palettes_are_named() {
        assert!(Colour::palette(&[[0.0, 1.0, 2.0, 3.0]]).unwrap_err().to_string().contains("at least 2"));
        let e = Colour::palette(&[[0.0, 0.0, 0.0, 0.0], [0.0, 1.0, 1.0, 1.0]]).unwrap_err();
        assert!(e.to_string().contains("strictly increase"));
        let e = Colour::palette(&[[0.0, 0.0, 0.0, 0.0], [1.0, 300.0, 1.0, 1.0]]).unwrap_err();
        assert!(e.to_string().contains("0..=255"));
    }
}
