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
    /// The transform of sprites: never clipped to a cell (the positioning map records every
    /// cell a sprite's box crosses), so any scale range and no `overflow`.
    pub fn for_sprites(p: &TransformParams) -> Result<Self> {
        let [smin, smax] = Self::scale_range(p)?;
        if p.overflow {
            return Err(Error::param("transform.overflow", "sprites are never clipped to a cell; leave it false"));
        }
        Ok(Self { smin, smax, rotate: p.rotate, overflow: false, left: 0, right: 0 })
    }

    fn scale_range(p: &TransformParams) -> Result<[f32; 2]> {
        let [smin, smax] = p.scale;
        if !(smin > 0.0 && smin <= smax && smax <= 4.0) {
            return Err(Error::param("transform.scale", format!("[{smin}, {smax}]: need 0 < min ≤ max ≤ 4")));
        }
        Ok([smin, smax])
    }

    pub fn load(p: &TransformParams) -> Result<Self> {
        let [smin, smax] = Self::scale_range(p)?;
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
        let s = self.scale_at(rng, gx, gy);
        let e = if self.rotate { s * SQRT2_2 } else { s * 0.5 };
        let (dx, dy) = (rng.unit(Role::OffsetX, gx, gy), rng.unit(Role::OffsetY, gx, gy));
        let (cx, cy) = if self.overflow {
            (dx + s * 0.5, dy + s * 0.5)
        } else {
            (e + (1.0 - 2.0 * e) * dx, e + (1.0 - 2.0 * e) * dy)
        };
        let (cos, sin) = self.rotation_at(rng, gx, gy);
        Placed { pattern, cx, cy, cos, sin, texels: pattern_size as f32 / s, scale: s }
    }

    /// Cell g's random scale s = min + r (max − min).
    pub fn scale_at(&self, rng: &LayerRng, gx: u64, gy: u64) -> f32 {
        self.smin + rng.unit(Role::Scale, gx, gy) * (self.smax - self.smin)
    }

    /// Cell g's random rotation in [0, 2π) as (cos, sin); the identity without `rotate`.
    pub fn rotation_at(&self, rng: &LayerRng, gx: u64, gy: u64) -> (f32, f32) {
        if self.rotate {
            let theta = rng.unit(Role::Rotation, gx, gy) * (2.0 * core::f32::consts::PI);
            (libm::cosf(theta), libm::sinf(theta))
        } else {
            (1.0, 0.0)
        }
    }

    /// Largest scale and whether patterns turn: what bounds a transformed sprite's box.
    pub fn largest(&self) -> (f32, bool) {
        (self.smax, self.rotate)
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
