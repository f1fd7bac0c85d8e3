//! The Tile Transform block (§3.2, Fig. 4–5): scale, rotate and translate a pattern within its
//! virtual tile map cell. Either the pattern is shrunk so it stays strictly inside the cell,
//! or it may overflow, and every pixel gathers the contributions of the neighbouring cells
//! whose pattern reaches it — the paper's multipass with d − 1, generalised to rotations.

use super::params::TransformParams;
use super::random::LayerRng;
use super::sigma::Role;
use crate::{Error, Result};

const SQRT2_2: f32 = 0.707_106_77;

pub struct TransformBlock {
    smin: f32,
    smax: f32,
    rotate: bool,
    overflow: bool,
    /// Neighbour cells to gather from: `left` before g and `right` after it, per axis.
    pub left: i64,
    pub right: i64,
}

/// A pattern placed in its cell: centre in cell units from the cell's corner, rotation and
/// pattern texels per cell unit.
#[derive(Clone, Copy, Debug)]
pub struct Placed {
    pub pattern: u32,
    pub cx: f32,
    pub cy: f32,
    pub cos: f32,
    pub sin: f32,
    /// Pattern level-0 texels per cell unit: S / s.
    pub texels: f32,
    pub scale: f32,
}

impl TransformBlock {
    pub fn load(p: &TransformParams) -> Result<Self> {
        let [smin, smax] = p.scale;
        if !(smin > 0.0 && smin <= smax && smax <= 4.0) {
            return Err(Error::param("transform.scale", format!("[{smin}, {smax}]: need 0 < min ≤ max ≤ 4")));
        }
        let half = |s: f32| if p.rotate { s * SQRT2_2 } else { s * 0.5 };
        if !p.overflow && half(smax) > 0.5 {
            return Err(Error::param(
                "transform.scale",
                format!(
                    "max scale {smax} does not fit inside a cell without overflow{}",
                    if p.rotate { " once rotated" } else { "" }
                ),
            ));
        }
        // Overflow: the corner is at d ∈ [0,1), the centre at d + s/2, the box ±e around it.
        let (left, right) = if p.overflow {
            ((smax * 0.5 + half(smax)).ceil() as i64, (half(smax) - smax * 0.5).max(0.0).ceil() as i64)
        } else {
            (0, 0)
        };
        Ok(Self { smin, smax, rotate: p.rotate, overflow: p.overflow, left, right })
    }

    /// Places `pattern` in cell g with this cell's random translation, scale and rotation.
    pub fn place(&self, rng: &LayerRng, gx: u64, gy: u64, pattern: u32, pattern_size: u32) -> Placed {
        let s = self.smin + rng.unit(Role::Scale, gx, gy) * (self.smax - self.smin);
        let e = if self.rotate { s * SQRT2_2 } else { s * 0.5 };
        let (dx, dy) = (rng.unit(Role::OffsetX, gx, gy), rng.unit(Role::OffsetY, gx, gy));
        let (cx, cy) = if self.overflow {
            (dx + s * 0.5, dy + s * 0.5)
        } else {
            (e + (1.0 - 2.0 * e) * dx, e + (1.0 - 2.0 * e) * dy)
        };
        let (cos, sin) = if self.rotate {
            let theta = rng.unit(Role::Rotation, gx, gy) * (2.0 * core::f32::consts::PI);
            (libm::cosf(theta), libm::sinf(theta))
        } else {
            (1.0, 0.0)
        };
        Placed { pattern, cx, cy, cos, sin, texels: pattern_size as f32 / s, scale: s }
    }

    /// Expected s² (area factor) of the random scale, for coarse-level filtering.
    pub fn mean_area(&self) -> f32 {
        let (a, b) = (self.smin, self.smax);
        (a * a + a * b + b * b) / 3.0
    }
}

impl Placed {
    /// Pattern level-0 texel coordinates of a point at (rx, ry) cell units from this cell's
    /// corner, or `None` when it falls outside the pattern (the fragment is discarded).
    #[inline]
    pub fn local(&self, rx: f32, ry: f32, size: f32) -> Option<(f32, f32)> {
        let (x, y) = (rx - self.cx, ry - self.cy);
        let u = (self.cos * x + self.sin * y) * self.texels + size * 0.5;
        let v = (self.cos * y - self.sin * x) * self.texels + size * 0.5;
        (u >= 0.0 && v >= 0.0 && u < size && v < size).then_some((u, v))
    }
}
