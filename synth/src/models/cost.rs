//! What a texture costs the machine serving it, known before anything is drawn, generated or
//! indexed: each model computes a [`Plan`] from its parameters and the headers of its inputs,
//! and [`Limits::check`] refuses an encoding over a bound with an error naming the cause.
//!
//! Work is counted in *work units*: one unit is about one nanosecond of one core on the
//! reference machine (each model calibrates its formula against its own renders), so bounds can
//! be read as time.

use crate::{Animation, Domain, Error, Result};

/// One quantity of a [`Cost`], with what it is made of in words, for error messages
/// (`12 stages × 49 taps × …`).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Measure {
    pub value: u64,
    /// The formula, in the parameters' own names.
    pub why: String,
}

impl Measure {
    pub fn new(value: u64, why: impl Into<String>) -> Measure {
        Measure { value, why: why.into() }
    }
}

/// The cost of one texture.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Cost {
    /// Bytes the loaded texture holds for as long as it is loaded (tables, decoded inputs,
    /// prefiltered levels, caches it fills on first use at their largest).
    pub resident_bytes: Measure,
    /// Worst-case work units of rendering one 256 × 256 tile, over every level, position and frame.
    pub tile_work: Measure,
    /// Work units of making the texture: `create` (generating, drawing, indexing) and `load`.
    pub build_work: Measure,
}

/// What an encoding will be and what it will cost, read without building it.
#[derive(Clone, Debug, PartialEq)]
pub struct Plan {
    pub width: u64,
    pub height: u64,
    pub domain: Domain,
    pub animation: Option<Animation>,
    pub cost: Cost,
}

/// Work units of an estimate in floating point, rounded up and saturated at `u64::MAX` (the
/// formulas multiply parameters that may each be at their bound).
pub fn units(v: f64) -> u64 {
    v.ceil() as u64
}

/// Bounds an encoding's [`Cost`] must stay within to be created or loaded.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Limits {
    pub max_resident_bytes: u64,
    pub max_tile_work: u64,
    pub max_build_work: u64,
}

impl Limits {
    /// No bound: for offline tools that run what they are given.
    pub const NONE: Limits = Limits { max_resident_bytes: u64::MAX, max_tile_work: u64::MAX, max_build_work: u64::MAX };

    /// Bounds for a public server, in the time of one core of a loaded machine. A tile may
    /// take about ten seconds: the dearest demo tiles (the first coarse tile of a pattern
    /// texture with transition tiles, which fills its caches) stay at least twice below it,
    /// while a cascade whose tile takes minutes is refused. Making a texture may take about
    /// twenty seconds: twice the 100k chaos mosaic's 781,250 blocks made and loaded, and a
    /// fifth of a mosaic with the most blocks allowed. One texture may hold 2 GiB: the
    /// server's default budget for all loaded textures, which it passes here in place of this.
    pub const SERVE: Limits =
        Limits { max_resident_bytes: 2 << 30, max_tile_work: 10_000_000_000, max_build_work: 20_000_000_000 };

    /// Refuses `plan` of `model` when any part of its cost is over its bound.
    pub fn check(&self, model: &str, plan: &Plan) -> Result<()> {
        let c = &plan.cost;
        let over = |what: &'static str, m: &Measure, bound: u64| {
            (m.value > bound).then(|| Error::TooCostly {
                model: model.to_string(),
                what,
                value: m.value,
                why: m.why.clone(),
                bound,
            })
        };
        match over("resident bytes", &c.resident_bytes, self.max_resident_bytes)
            .or_else(|| over("work units per tile", &c.tile_work, self.max_tile_work))
            .or_else(|| over("work units to build", &c.build_work, self.max_build_work))
        {
            Some(e) => Err(e),
            None => Ok(()),
        }
    }
}
