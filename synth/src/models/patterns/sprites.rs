//! The Explicit Positioning block (§3.2, Fig. 6): texture sprites. A positioning map (one
//! entry per cell of a grid at least as coarse as a pattern) holds the sprite whose box
//! crosses that cell, so an untransformed sprite updates four cells. A map holds one pattern a
//! cell; "allowing n patterns to be present in a same cell would require the use of n grids":
//! every sprites layer is one grid and draws only its own sprites. The Tile Transform is
//! plugged after the positioning (explicit scale and rotation per sprite, random ones per
//! layer), and a sprite with a velocity moves with the frame (long-range displacement, §4).
//! The sprites live in the manifest params, so moving one is a JSON merge patch of its x, y.

use super::params::{LayerKind, LayerParams, SpriteParams};
use super::random::LayerRng;
use super::transform::TransformBlock;
use crate::{Error, Result};
use std::borrow::Cow;
use std::collections::BTreeMap;

/// Most sprites one texture may hold.
pub const MAX_SPRITES: usize = 4096;
/// Most sprite placements (frames of the common period × sprites) checked for collisions when
/// moving sprites share a layer.
pub const MAX_COLLISION_CHECKS: u64 = 1 << 18;
/// Largest scale of a sprite, its own times its layer's random one.
const MAX_SCALE: f32 = 4.0;

/// Where a sprite is at frame t: its rest corner moved by t · velocity, on the torus.
#[derive(Clone, Copy, Debug)]
pub struct Motion {
    x: i64,
    y: i64,
    velocity: [i64; 2],
}

impl Motion {
    pub fn of(s: &SpriteParams) -> Self {
        Motion { x: s.x, y: s.y, velocity: s.velocity }
    }

    /// Top-left corner at frame t, wrapped into the `texture`.
    pub fn corner(&self, t: u32, texture: (u64, u64)) -> (u64, u64) {
        let at = |p: i64, v: i64, n: u64| (p as i128 + v as i128 * t as i128).rem_euclid(n as i128) as u64;
        (at(self.x, self.velocity[0], texture.0), at(self.y, self.velocity[1], texture.1))
    }

    /// Centre of a `size`-pixel pattern's box at frame t.
    pub fn centre(&self, t: u32, texture: (u64, u64), size: u32) -> (f64, f64) {
        let (x, y) = self.corner(t, texture);
        (x as f64 + size as f64 * 0.5, y as f64 + size as f64 * 0.5)
    }

    /// Frames after which the sprite is back at its place (1 when it stays).
    pub fn period(&self, texture: (u64, u64)) -> u64 {
        let axis = |v: i64, n: u64| n / gcd(n, v.rem_euclid(n as i64) as u64);
        lcm(axis(self.velocity[0], texture.0), axis(self.velocity[1], texture.1))
    }

    pub fn moves(&self) -> bool {
        self.velocity != [0, 0]
    }
}

/// A sprite of one layer, transformed.
#[derive(Clone, Debug)]
pub struct Sprite {
    pub name: String,
    pub pattern: u32,
    pub motion: Motion,
    pub scale: f32,
    pub cos: f32,
    pub sin: f32,
    /// Half side of the axis-aligned box holding the transformed pattern, level-0 pixels.
    pub half: f64,
}

impl Sprite {
    /// Pattern texel coordinates (level 0) of a point at offset d from the sprite's centre
    /// (level-0 pixels), or `None` outside the pattern.
    #[inline]
    pub fn local(&self, d: (f64, f64), size: u32) -> Option<(f32, f32)> {
        let s = size as f32;
        let (dx, dy) = (d.0 as f32, d.1 as f32);
        let (u, v) = if self.cos == 1.0 && self.sin == 0.0 && self.scale == 1.0 {
            (dx + s * 0.5, dy + s * 0.5)
        } else {
            (
                (self.cos * dx + self.sin * dy) / self.scale + s * 0.5,
                (self.cos * dy - self.sin * dx) / self.scale + s * 0.5,
            )
        };
        (u >= 0.0 && v >= 0.0 && u < s && v < s).then_some((u, v))
    }
}

/// A positioning map at one frame: occupied cells sorted by key (y · width + x), each with
/// the index of its sprite.
pub type CellMap = Vec<(u64, u32)>;

pub struct Positioning {
    pub cell: u32,
    grid: (u64, u64),
    texture: (u64, u64),
    size: u32,
    pub sprites: Vec<Sprite>,
    /// The map when no sprite of the layer moves.
    still: Option<CellMap>,
    period: u64,
}

impl Positioning {
    /// The positioning map of sprites layer `layer`: the sprites naming it, and those naming
    /// no layer when it is the first sprites layer.
    #[allow(clippy::too_many_arguments)]
    pub fn load(
        layer: usize,
        first: bool,
        all: &BTreeMap<String, SpriteParams>,
        transform: Option<&TransformBlock>,
        rng: &LayerRng,
        cell: u32,
        texture: (u64, u64),
        pattern_size: u32,
        patterns: u32,
    ) -> Result<Self> {
        if cell < pattern_size {
            return Err(Error::param(
                "cell",
                format!("a positioning map cell ({cell}) must be at least the pattern size {pattern_size}, so a sprite spans ≤ 4 cells"),
            ));
        }
        let grid = (texture.0 / cell as u64, texture.1 / cell as u64);
        let mut sprites = Vec::new();
        for (name, s) in all.iter().filter(|(_, s)| s.layer.map_or(first, |l| l == layer)) {
            if s.pattern >= patterns {
                return Err(Error::param(
                    format!("sprites.{name}.pattern"),
                    format!("pattern {} is missing: the reference holds 0..{patterns}", s.pattern),
                ));
            }
            let (smax, _) = transform.map_or((1.0, false), |t| t.largest());
            if !(s.scale > 0.0 && s.scale * smax <= MAX_SCALE) {
                return Err(Error::param(
                    format!("sprites.{name}.scale"),
                    format!("{} (× the layer's largest random scale {smax}): must be in (0, {MAX_SCALE}]", s.scale),
                ));
            }
            if !s.rotation.is_finite() {
                return Err(Error::param(format!("sprites.{name}.rotation"), "must be a finite number of degrees"));
            }
            let motion = Motion::of(s);
            // The layer's random transform is drawn for the cell of the sprite's rest corner.
            let (rx, ry) = motion.corner(0, texture);
            let (gx, gy) = (rx / cell as u64 % grid.0, ry / cell as u64 % grid.1);
            let (random_scale, (c2, s2)) =
                transform.map_or((1.0, (1.0, 0.0)), |t| (t.scale_at(rng, gx, gy), t.rotation_at(rng, gx, gy)));
            let theta = s.rotation.to_radians();
            let (c1, s1) = (libm::cosf(theta), libm::sinf(theta));
            let (cos, sin) = (c1 * c2 - s1 * s2, s1 * c2 + c1 * s2);
            let scale = s.scale * random_scale;
            let half = pattern_size as f64 * scale as f64 * (cos.abs() + sin.abs()) as f64 * 0.5;
            sprites.push(Sprite { name: name.clone(), pattern: s.pattern, motion, scale, cos, sin, half });
        }
        let period = sprites.iter().fold(1u64, |p, s| lcm(p, s.motion.period(texture)).min(u64::MAX / 2));
        let mut pos = Positioning { cell, grid, texture, size: pattern_size, sprites, still: None, period };
        if !pos.sprites.iter().any(|s| s.motion.moves()) {
            pos.still = Some(pos.build(0)?);
            return Ok(pos);
        }
        if pos.sprites.len() > 1 {
            let checks = period.saturating_mul(pos.sprites.len() as u64);
            if checks > MAX_COLLISION_CHECKS {
                let name = &pos.sprites.iter().find(|s| s.motion.moves()).unwrap().name;
                return Err(Error::param(
                    format!("sprites.{name}.velocity"),
                    format!(
                        "moving sprites sharing a layer are checked for collisions over their common period: \
                         {period} frames × {} sprites is more than {MAX_COLLISION_CHECKS}; give a moving sprite \
                         its own sprites layer (`\"layer\"`) or velocities with a shorter period",
                        pos.sprites.len()
                    ),
                ));
            }
            for t in 0..period as u32 {
                pos.build(t)?;
            }
        }
        Ok(pos)
    }

    /// Frames after which every sprite of the layer is back (1 when none moves).
    pub fn period(&self) -> u64 {
        self.period
    }

    /// The positioning map at frame t.
    pub fn map(&self, t: u32) -> Cow<'_, CellMap> {
        match &self.still {
            Some(m) => Cow::Borrowed(m),
            None => Cow::Owned(self.build(t).expect("collisions were checked over the whole period at load")),
        }
    }

    /// Centre of sprite `i` at frame t, level-0 pixels.
    pub fn centre(&self, i: usize, t: u32) -> (f64, f64) {
        self.sprites[i].motion.centre(t, self.texture, self.size)
    }

    /// The sprite recorded in the positioning cell containing level-0 point (x, y).
    #[inline]
    pub fn at(&self, map: &CellMap, x: f64, y: f64) -> Option<usize> {
        let cx = (x / self.cell as f64) as u64 % self.grid.0;
        let cy = (y / self.cell as f64) as u64 % self.grid.1;
        let key = cy * self.grid.0 + cx;
        map.binary_search_by_key(&key, |e| e.0).ok().map(|i| map[i].1 as usize)
    }

    /// Every cell (wrapped) the box of sprite `i` crosses at frame t: column and row ranges.
    fn cells(&self, i: usize, t: u32) -> (Vec<u64>, Vec<u64>) {
        let (cx, cy) = self.centre(i, t);
        let e = self.sprites[i].half;
        let c = self.cell as f64;
        let span = |centre: f64, n: u64| {
            let (a, b) = (((centre - e) / c).floor() as i64, ((centre + e) / c).ceil() as i64 - 1);
            (a..=b.max(a)).take(n as usize).map(|v| v.rem_euclid(n as i64) as u64).collect::<Vec<_>>()
        };
        (span(cx, self.grid.0), span(cy, self.grid.1))
    }

    /// The map at frame t, or the collision error naming both sprites and the cell.
    fn build(&self, t: u32) -> Result<CellMap> {
        let mut owner: BTreeMap<u64, u32> = BTreeMap::new();
        for i in 0..self.sprites.len() {
            let (xs, ys) = self.cells(i, t);
            for &gy in &ys {
                for &gx in &xs {
                    let key = gy * self.grid.0 + gx;
                    if let Some(&other) = owner.get(&key) {
                        if other as usize != i {
                            let when = if self.still.is_none() && self.period > 1 {
                                format!(" at frame {t}")
                            } else {
                                String::new()
                            };
                            return Err(Error::param(
                                format!("sprites.{}", self.sprites[i].name),
                                format!(
                                    "shares positioning cell ({gx}, {gy}) with sprite `{}`{when}; a positioning map \
                                     holds one pattern per cell (§3.2) — move it, or draw it on another sprites \
                                     layer: give it `\"layer\": <index>` of a sprites layer (add one to `layers`)",
                                    self.sprites[other as usize].name
                                ),
                            ));
                        }
                    }
                    owner.insert(key, i as u32);
                }
            }
        }
        Ok(owner.into_iter().collect())
    }

    /// Signed offset of level-0 point p from c on the torus, per axis in [−n/2, n/2).
    #[inline]
    pub fn offset(&self, p: (f64, f64), c: (f64, f64)) -> (f64, f64) {
        let d = |a: f64, b: f64, n: u64| {
            let n = n as f64;
            (a - b + n * 0.5).rem_euclid(n) - n * 0.5
        };
        (d(p.0, c.0, self.texture.0), d(p.1, c.1, self.texture.1))
    }
}

/// Checks the number of sprites and that every sprite naming a layer names a sprites layer.
pub fn check_layers(sprites: &BTreeMap<String, SpriteParams>, layers: &[LayerParams]) -> Result<()> {
    if sprites.len() > MAX_SPRITES {
        return Err(Error::param("sprites", format!("{} sprites; at most {MAX_SPRITES}", sprites.len())));
    }
    for (name, s) in sprites {
        let Some(l) = s.layer else { continue };
        match layers.get(l) {
            Some(lp) if lp.kind == LayerKind::Sprites => {}
            Some(lp) => {
                return Err(Error::param(
                    format!("sprites.{name}.layer"),
                    format!("layers[{l}] is a {:?} layer; a sprite is drawn by a sprites layer", lp.kind),
                ))
            }
            None => {
                return Err(Error::param(
                    format!("sprites.{name}.layer"),
                    format!("layers[{l}] does not exist ({} layers)", layers.len()),
                ))
            }
        }
    }
    Ok(())
}

/// The periods of the moving sprites (what makes a texture with sprites animated).
pub fn moving_periods(sprites: &BTreeMap<String, SpriteParams>, texture: (u64, u64)) -> Vec<u64> {
    sprites.values().map(Motion::of).filter(Motion::moves).map(|m| m.period(texture)).collect()
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

fn lcm(a: u64, b: u64) -> u64 {
    (a / gcd(a, b)).saturating_mul(b)
}
