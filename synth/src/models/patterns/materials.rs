//! Pattern choice per cell: Explicit / Virtual Indirection Map, Probability Map, Materials
//! Map, Areas Map and Dithered Areas Map (§3.2), with the Pixel Map (§3.3) as an alternative
//! placement of materials.

use super::maps::Map;
use super::params::{Choice, MaterialParams};
use super::pixel_map::PixelMap;
use super::random::LayerRng;
use super::reference::Reference;
use super::sigma::Role;
use crate::{bundle::Bundle, Error, Result};

/// "No pattern" in explicit indirection maps.
pub const BLANK_INDEX: u16 = u16::MAX;

/// A material: a probability map over patterns (`None` = blank), and its family.
pub struct Material {
    pub patterns: Vec<Option<u32>>,
    pub family: u16,
    /// Mean of its patterns' exact 1×1 mip levels (straight RGBA, blank = transparent).
    pub mean: [f32; 4],
    /// Mean premultiplied colour of its patterns.
    pub pm_mean: [f32; 4],
}

pub enum Placement {
    /// Material 0 everywhere.
    Uniform,
    Areas {
        map: Map,
        dithered: bool,
    },
    Pixels(PixelMap),
}

pub enum ChoiceBlock {
    Virtual,
    Explicit(Map),
    Materials { materials: Vec<Material>, placement: Placement },
}

impl ChoiceBlock {
    /// Compiles a choice for a grid of `grid` cells over a texture of `texture` pixels.
    pub fn load(
        c: &Choice,
        bundle: &Bundle,
        reference: &Reference,
        rng: &LayerRng,
        grid: (u64, u64),
        texture: (u64, u64),
        allow_blank: bool,
    ) -> Result<Self> {
        let count = reference.count();
        Ok(match c {
            Choice::Virtual => {
                if rng.pattern_steps().is_none() && reference.count() > 1 {
                    return Err(Error::param(
                        "choice",
                        format!(
                            "a virtual indirection map over a {}×{} reference cannot hash a {}×{} grid: a reference \
                             side of 1 pattern gives that axis no digits (§3.5); pack the patterns in 2D",
                            reference.tx, reference.ty, grid.0, grid.1
                        ),
                    ));
                }
                ChoiceBlock::Virtual
            }
            Choice::Explicit { map } => {
                let allowed = allow_blank.then_some(BLANK_INDEX);
                ChoiceBlock::Explicit(Map::load("choice.map", map, bundle, grid, count, allowed)?)
            }
            Choice::Materials { materials, areas, pixel_map } => {
                if materials.is_empty() || materials.len() > 255 {
                    return Err(Error::param("materials", "1 to 255 materials"));
                }
                let mats = materials
                    .iter()
                    .enumerate()
                    .map(|(i, m)| material(i, m, reference, rng, allow_blank))
                    .collect::<Result<Vec<_>>>()?;
                let placement = match (areas, pixel_map) {
                    (None, None) => Placement::Uniform,
                    (Some(a), None) => Placement::Areas {
                        map: Map::load("areas.map", &a.map, bundle, grid, mats.len() as u32, None)?,
                        dithered: a.dithered,
                    },
                    (None, Some(p)) => Placement::Pixels(PixelMap::load(p, bundle, texture, mats.len())?),
                    (Some(_), Some(_)) => {
                        return Err(Error::param("choice", "give an areas map or a pixel map, not both"))
                    }
                };
                ChoiceBlock::Materials { materials: mats, placement }
            }
        })
    }

    pub fn materials(&self) -> &[Material] {
        match self {
            ChoiceBlock::Materials { materials, .. } => materials,
            _ => &[],
        }
    }

    pub fn pixel_map(&self) -> Option<&PixelMap> {
        match self {
            ChoiceBlock::Materials { placement: Placement::Pixels(p), .. } => Some(p),
            _ => None,
        }
    }

    /// The material of cell g (Areas Map, dithered or not); 0 without materials.
    pub fn material(&self, rng: &LayerRng, gx: u64, gy: u64, grid: (u64, u64)) -> u16 {
        let ChoiceBlock::Materials { placement, .. } = self else { return 0 };
        match placement {
            Placement::Uniform | Placement::Pixels(_) => 0,
            Placement::Areas { map, dithered: false } => map.at_scaled(gx, gy, grid),
            Placement::Areas { map, dithered: true } => {
                let ax = dither_axis(gx, map.w, grid.0, rng.unit(Role::DitherX, gx, gy));
                let ay = dither_axis(gy, map.h, grid.1, rng.unit(Role::DitherY, gx, gy));
                map.at(ax, ay)
            }
        }
    }

    /// The pattern material `m` puts in cell g: its probability map indexed by σ (Fig. 7).
    #[inline]
    pub fn pattern_of(&self, rng: &LayerRng, m: u16, gx: u64, gy: u64) -> Option<u32> {
        match self {
            ChoiceBlock::Virtual => Some(rng.pattern(gx, gy)),
            ChoiceBlock::Explicit(map) => {
                let v = map.at(gx as i64, gy as i64);
                (v != BLANK_INDEX).then_some(v as u32)
            }
            ChoiceBlock::Materials { materials, .. } => {
                let pats = &materials[m as usize].patterns;
                pats[rng.below(Role::Choice, gx, gy, pats.len() as u32) as usize]
            }
        }
    }

    /// The pattern of cell g when materials are placed per cell.
    #[inline]
    pub fn pattern(&self, rng: &LayerRng, gx: u64, gy: u64, grid: (u64, u64)) -> Option<u32> {
        self.pattern_of(rng, self.material(rng, gx, gy, grid), gx, gy)
    }

    /// Material weights at a continuous position (in cells) for law-of-large-numbers
    /// filtering (§5.1): the area's material, or the bilinear weights the dithering
    /// operator realises in expectation. `None` when the choice has no expectation here.
    pub fn weights(&self, cx: f64, cy: f64, grid: (u64, u64)) -> Option<[(u16, f32); 4]> {
        let ChoiceBlock::Materials { placement, .. } = self else { return None };
        match placement {
            Placement::Uniform => Some([(0, 1.0), (0, 0.0), (0, 0.0), (0, 0.0)]),
            Placement::Pixels(_) => None,
            Placement::Areas { map, dithered } => {
                let ax = cx * map.w as f64 / grid.0 as f64;
                let ay = cy * map.h as f64 / grid.1 as f64;
                if !dithered {
                    return Some([(map.at(ax.floor() as i64, ay.floor() as i64), 1.0), (0, 0.0), (0, 0.0), (0, 0.0)]);
                }
                let (fx, fy) = (ax - 0.5, ay - 0.5);
                let (x0, y0) = (fx.floor(), fy.floor());
                let (bx, by) = ((fx - x0) as f32, (fy - y0) as f32);
                let (x0, y0) = (x0 as i64, y0 as i64);
                Some([
                    (map.at(x0, y0), (1.0 - bx) * (1.0 - by)),
                    (map.at(x0 + 1, y0), bx * (1.0 - by)),
                    (map.at(x0, y0 + 1), (1.0 - bx) * by),
                    (map.at(x0 + 1, y0 + 1), bx * by),
                ])
            }
        }
    }

    /// The expected straight colour of a cell at a continuous position, by the law of large
    /// numbers: material means weighted by their probabilities. Virtual choice: the mean of
    /// all patterns.
    pub fn expected(&self, reference: &Reference, cx: f64, cy: f64, grid: (u64, u64), pm: bool) -> Option<[f32; 4]> {
        if let ChoiceBlock::Virtual = self {
            let mut acc = [0f32; 4];
            for p in 0..reference.count() {
                let c = if pm { reference.pm_mean(p) } else { reference.mean_texel(p).map(|v| v as f32) };
                for i in 0..4 {
                    acc[i] += c[i];
                }
            }
            return Some(acc.map(|v| v / reference.count() as f32));
        }
        let w = self.weights(cx, cy, grid)?;
        let mats = self.materials();
        let mut acc = [0f32; 4];
        for (m, wt) in w {
            let c = if pm { mats[m as usize].pm_mean } else { mats[m as usize].mean };
            for i in 0..4 {
                acc[i] += wt * c[i];
            }
        }
        Some(acc)
    }
}

/// The dithering operator along one axis (Fig. 8–9): the barycentric coordinate b of cell
/// g's centre between area centres a' and a' + 1 is compared with the random number r;
/// a' + 1 is chosen with probability b. Exact integer arithmetic for a'; returns the area.
#[inline]
pub fn dither_axis(g: u64, areas: u32, cells: u64, r: f32) -> i64 {
    // Area coordinate of the cell centre minus ½: ((2g + 1) A − N) / 2N.
    let num = (2 * g as i128 + 1) * areas as i128 - cells as i128;
    let den = 2 * cells as i128;
    let a0 = num.div_euclid(den);
    let b = num.rem_euclid(den) as f64 / den as f64;
    (a0 + (r < b as f32) as i128) as i64
}

fn material(
    i: usize,
    m: &MaterialParams,
    reference: &Reference,
    rng: &LayerRng,
    allow_blank: bool,
) -> Result<Material> {
    let what = format!("materials[{i}].patterns");
    rng.check_range(&what, m.patterns.len() as u32)?;
    let mut patterns = Vec::with_capacity(m.patterns.len());
    let (mut mean, mut pm_mean) = ([0f32; 4], [0f32; 4]);
    for &p in &m.patterns {
        if p == -1 && allow_blank {
            patterns.push(None);
            continue;
        }
        if p < 0 || p as u32 >= reference.count() {
            return Err(Error::param(
                &what,
                format!(
                    "pattern {p} is missing: the reference holds patterns 0..{}{}",
                    reference.count(),
                    if allow_blank { " (-1 = blank)" } else { " and tiling layers cannot be blank" }
                ),
            ));
        }
        let p = p as u32;
        patterns.push(Some(p));
        let (c, q) = (reference.mean_texel(p), reference.pm_mean(p));
        for k in 0..4 {
            mean[k] += c[k] as f32;
            pm_mean[k] += q[k];
        }
    }
    let n = m.patterns.len() as f32;
    Ok(Material { patterns, family: m.family, mean: mean.map(|v| v / n), pm_mean: pm_mean.map(|v| v / n) })
}
