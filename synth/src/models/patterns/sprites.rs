//! The Explicit Positioning block (§3.2, Fig. 6): texture sprites. A positioning map (one
//! entry per cell of a grid at least as coarse as a pattern) holds the pattern index and the
//! position of the pattern whose box crosses that cell, so a sprite updates four cells. The
//! sprites live in the manifest params, so moving one is a JSON merge patch of its x, y.

use super::params::SpriteParams;
use crate::{Error, Result};
use std::collections::BTreeMap;

/// Most sprites one texture may hold.
pub const MAX_SPRITES: usize = 4096;

#[derive(Clone, Copy, Debug)]
pub struct Entry {
    pub pattern: u32,
    /// Top-left corner, level-0 pixels, wrapped into the texture.
    pub x: u64,
    pub y: u64,
}

pub struct Positioning {
    pub cell: u32,
    grid: (u64, u64),
    /// The positioning map's occupied cells, sorted by cell key (y · width + x).
    map: Vec<(u64, Entry)>,
    pub list: Vec<Entry>,
}

impl Positioning {
    pub fn load(
        sprites: &BTreeMap<String, SpriteParams>,
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
        if sprites.len() > MAX_SPRITES {
            return Err(Error::param("sprites", format!("{} sprites; at most {MAX_SPRITES}", sprites.len())));
        }
        let grid = (texture.0 / cell as u64, texture.1 / cell as u64);
        let mut map: BTreeMap<u64, Entry> = BTreeMap::new();
        let mut owner: BTreeMap<u64, &str> = BTreeMap::new();
        let mut list = Vec::with_capacity(sprites.len());
        for (name, s) in sprites {
            if s.pattern >= patterns {
                return Err(Error::param(
                    format!("sprites.{name}.pattern"),
                    format!("pattern {} is missing: the reference holds 0..{patterns}", s.pattern),
                ));
            }
            let e = Entry {
                pattern: s.pattern,
                x: s.x.rem_euclid(texture.0 as i64) as u64,
                y: s.y.rem_euclid(texture.1 as i64) as u64,
            };
            let (c0x, c0y) = (e.x / cell as u64, e.y / cell as u64);
            let (c1x, c1y) =
                ((e.x + pattern_size as u64 - 1) / cell as u64, (e.y + pattern_size as u64 - 1) / cell as u64);
            for cy in [c0y, c1y] {
                for cx in [c0x, c1x] {
                    let key = (cy % grid.1) * grid.0 + (cx % grid.0);
                    if let Some(other) = owner.get(&key) {
                        if *other != name.as_str() {
                            return Err(Error::param(
                                format!("sprites.{name}"),
                                format!("shares positioning cell ({}, {}) with sprite `{other}`; a positioning map holds one pattern per cell (§3.2) — move it or add a sprites layer", cx % grid.0, cy % grid.1),
                            ));
                        }
                    }
                    owner.insert(key, name);
                    map.insert(key, e);
                }
            }
            list.push(e);
        }
        Ok(Self { cell, grid, map: map.into_iter().collect(), list })
    }

    /// The sprite recorded in the positioning cell containing level-0 pixel (x, y).
    #[inline]
    pub fn at(&self, x: u64, y: u64) -> Option<&Entry> {
        let (cx, cy) = (x / self.cell as u64 % self.grid.0, y / self.cell as u64 % self.grid.1);
        let key = cy * self.grid.0 + cx;
        self.map.binary_search_by_key(&key, |e| e.0).ok().map(|i| &self.map[i].1)
    }
}
