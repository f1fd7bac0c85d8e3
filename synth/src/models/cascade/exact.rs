//! The exact evaluation of a cascade: level-0 pixels of any window, the engine's final stage
//! through the palette. The exact levels downsample it and the prefiltered ones are calibrated
//! on it ([`prefilter`](super::prefilter)).

use super::engine::{Engine, STREAM_CALIBRATION};
use super::palette;
use super::params::Params;
use super::plan::build_engine;
use crate::pixels::Rgba8Image;
use crate::texture::Stop;
use crate::{Error, Result};

/// A validated engine and palette: what every level of a cascade is computed from.
pub struct Exact {
    params: Params,
    engine: Engine,
    lut: Vec<[u8; 4]>,
    lo: f32,
    scale: f32,
}

impl Exact {
    pub(super) fn build(params: Params, control: Option<&Rgba8Image>, initial: Option<&Rgba8Image>) -> Result<Self> {
        let engine = build_engine(&params, control, initial)?;
        let lut = palette::build(&params.palette)?;
        let [lo, hi] = params.range.unwrap_or_else(|| auto_range(&engine));
        let (lo, scale) = (lo as f32, (1.0 / (hi - lo)) as f32);
        if !(scale.is_finite() && scale > 0.0) {
            return Err(Error::param("range", format!("[{lo}, {hi}] is too narrow")));
        }
        Ok(Self { params, engine, lut, lo, scale })
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    pub fn engine(&self) -> &Engine {
        &self.engine
    }

    /// The palette colour of a final-stage value.
    #[inline]
    pub fn colour(&self, v: f32) -> [u8; 4] {
        let t = ((v - self.lo) * self.scale).clamp(0.0, 1.0);
        self.lut[(t * (palette::LUT_SIZE - 1) as f32 + 0.5) as usize]
    }

    /// Level-0 pixels of the window at (x, y) (plane coordinates as u64 on the 2^64 torus),
    /// or `None` once `stop` is requested.
    pub fn level0(&self, x: u64, y: u64, w: u32, h: u32, stop: &dyn Stop) -> Option<Rgba8Image> {
        let last = self.engine.stages.len() - 1;
        let g = self.engine.field_until(last, x, y, w as usize, h as usize, stop)?;
        let mut img = Rgba8Image::new(w, h);
        for (px, v) in img.data.chunks_exact_mut(4).zip(&g.v) {
            px.copy_from_slice(&self.colour(*v));
        }
        Some(img)
    }
}

/// Final-stage value range from a deterministic sample of windows: the 0.5 % and 99.5 %
/// quantiles, rounded to 1e-4 so the manifest stays short and parses exactly.
pub(super) fn auto_range(engine: &Engine) -> [f64; 2] {
    let last = engine.stages.len() - 1;
    let mut v: Vec<f32> = Vec::new();
    for i in 0..8 {
        let h = crate::hash::hash4(engine.seed, STREAM_CALIBRATION, i, 7);
        let g = engine.field(last, h, h.rotate_left(32), 48, 48);
        v.extend(g.v);
    }
    v.sort_by(f32::total_cmp);
    let q = |f: f64| v[((v.len() - 1) as f64 * f) as usize] as f64;
    let round = |x: f64| (x * 1e4).round() / 1e4;
    let (lo, hi) = (round(q(0.005)), round(q(0.995)));
    if hi - lo < 1e-3 {
        [round(lo - 0.05), round(lo + 0.05)]
    } else {
        [lo, hi]
    }
}
