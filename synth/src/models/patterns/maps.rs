//! Explicit maps (§3.1, §3.6): small grids of integers that wrap, read either per cell of the
//! virtual tile map (indirection, Z and φ maps) or scaled over it (areas maps).

use super::params::MapRef;
use crate::{bundle::Bundle, Error, Result};

/// Largest explicit map, in values.
pub const MAX_MAP_VALUES: u64 = 1 << 22;

#[derive(Clone, Debug)]
pub struct Map {
    pub w: u32,
    pub h: u32,
    pub values: Vec<u16>,
}

impl Map {
    /// Reads `r` (named `what` in errors), checks its size divides the `grid` it is laid over
    /// and every value is below `limit` (or equals `allowed` when given).
    pub fn load(
        what: &str,
        r: &MapRef,
        bundle: &Bundle,
        grid: (u64, u64),
        limit: u32,
        allowed: Option<u16>,
    ) -> Result<Self> {
        let [w, h] = r.size;
        if w == 0 || h == 0 || w as u64 * h as u64 > MAX_MAP_VALUES {
            return Err(Error::param(what, format!("size {w}×{h}: each side ≥ 1, at most {MAX_MAP_VALUES} values")));
        }
        if grid.0 % w as u64 != 0 || grid.1 % h as u64 != 0 {
            return Err(Error::param(
                what,
                format!("size {w}×{h} does not divide the {}×{} virtual tile map it is laid over", grid.0, grid.1),
            ));
        }
        let n = (w * h) as usize;
        let values = match (&r.values, &r.section) {
            (Some(v), None) => v.clone(),
            (None, Some(name)) => {
                let data = bundle.section(name)?;
                if data.len() != n * r.depth.max(1) as usize {
                    return Err(Error::param(
                        what,
                        format!("section `{name}` has {} bytes for {w}×{h} values of {} bytes", data.len(), r.depth),
                    ));
                }
                match r.depth {
                    1 => data.iter().map(|&b| b as u16).collect(),
                    2 => data.chunks(2).map(|c| u16::from_le_bytes([c[0], *c.get(1).unwrap_or(&0)])).collect(),
                    d => return Err(Error::param(what, format!("depth {d}: must be 1 or 2 bytes per value"))),
                }
            }
            _ => return Err(Error::param(what, "give exactly one of `values` and `section`")),
        };
        if values.len() != n {
            return Err(Error::param(what, format!("{} values for a {w}×{h} map", values.len())));
        }
        if let Some((i, v)) = values.iter().enumerate().find(|(_, &v)| v as u32 >= limit && Some(v) != allowed) {
            return Err(Error::param(
                what,
                format!(
                    "value {v} at ({}, {}) is out of range; values must be below {limit}",
                    i as u32 % w,
                    i as u32 / w
                ),
            ));
        }
        Ok(Self { w, h, values })
    }

    /// The value at map cell (x, y), wrapping.
    #[inline]
    pub fn at(&self, x: i64, y: i64) -> u16 {
        let (x, y) = (x.rem_euclid(self.w as i64) as usize, y.rem_euclid(self.h as i64) as usize);
        self.values[y * self.w as usize + x]
    }

    /// The value covering grid cell g of an `n`-cell grid (each map cell covers n / size cells).
    #[inline]
    pub fn at_scaled(&self, gx: u64, gy: u64, n: (u64, u64)) -> u16 {
        self.at((gx * self.w as u64 / n.0) as i64, (gy * self.h as u64 / n.1) as i64)
    }
}
