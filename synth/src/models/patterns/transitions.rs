//! The Transition Tiles block (§3.3, Fig. 11): the tile of cell g is decided by the material
//! families of g and its three neighbours g + (1,0), g + (0,1), g + (1,1), taken as the
//! tile's four corners. Equal families: pass-through (the material's own pattern). Otherwise
//! the lowest family present is the base, and each higher family f lays its transition tile
//! — a border drawn on a transparent background, indexed by the 4-bit mask of corners in f —
//! over it ("if the pixel is on the background it takes the value of the other family").

use super::materials::ChoiceBlock;
use super::params::TransitionParams;
use super::random::LayerRng;
use crate::{Error, Result};

/// Corner bits of the mask: 1 = top-left (g), 2 = top-right, 4 = bottom-left, 8 = bottom-right.
pub const MASKS: usize = 14;

pub struct Transitions {
    /// `tiles[f - 1][mask - 1]`: the transition pattern of family f for a corner mask.
    tiles: Vec<Vec<u32>>,
}

/// What a tiling cell shows: a base pattern and up to three transition overlays on top.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Default)]
pub struct Pick {
    pub base: Option<u32>,
    pub overlays: [u32; 3],
    pub n_overlays: u8,
}

impl Pick {
    pub fn single(p: Option<u32>) -> Self {
        Pick { base: p, ..Default::default() }
    }
}

impl Transitions {
    pub fn load(t: &TransitionParams, choice: &ChoiceBlock, patterns: u32) -> Result<Self> {
        let mats = choice.materials();
        if mats.is_empty() {
            return Err(Error::param("transitions", "transition tiles need materials with families"));
        }
        let families = mats.iter().map(|m| m.family).max().unwrap_or(0) as usize + 1;
        if families < 2 || t.tiles.len() != families - 1 {
            return Err(Error::param(
                "transitions.tiles",
                format!(
                    "{} tile sets for {families} families; give one set per family above 0 (and ≥ 2 families)",
                    t.tiles.len()
                ),
            ));
        }
        for (f, set) in t.tiles.iter().enumerate() {
            if set.len() != MASKS {
                return Err(Error::param(
                    "transitions.tiles",
                    format!("family {}: {} tiles; one per corner mask 1..=14 is needed", f + 1, set.len()),
                ));
            }
            if let Some(p) = set.iter().find(|&&p| p >= patterns) {
                return Err(Error::param(
                    "transitions.tiles",
                    format!("pattern {p} is missing: the reference holds 0..{patterns}"),
                ));
            }
        }
        for f in 0..families as u16 {
            if !mats.iter().any(|m| m.family == f) {
                return Err(Error::param("materials", format!("family {f} has no material")));
            }
        }
        Ok(Self { tiles: t.tiles.clone() })
    }

    /// The pick of cell g from the materials of its four corner cells.
    pub fn pick(&self, choice: &ChoiceBlock, rng: &LayerRng, gx: u64, gy: u64, grid: (u64, u64)) -> Pick {
        let (nx, ny) = ((gx + 1) % grid.0, (gy + 1) % grid.1);
        let cells = [(gx, gy), (nx, gy), (gx, ny), (nx, ny)];
        let mats = cells.map(|(x, y)| choice.material(rng, x, y, grid));
        let materials = choice.materials();
        let fam = mats.map(|m| materials[m as usize].family);
        if fam.iter().all(|&f| f == fam[0]) {
            return Pick::single(choice.pattern_of(rng, mats[0], gx, gy));
        }
        let base_family = *fam.iter().min().unwrap();
        let corner = fam.iter().position(|&f| f == base_family).unwrap();
        let mut pick = Pick::single(choice.pattern_of(rng, mats[corner], gx, gy));
        let mut f = base_family;
        while let Some(&next) = fam.iter().filter(|&&x| x > f).min() {
            let mask = fam.iter().enumerate().fold(0usize, |m, (i, &x)| m | (((x == next) as usize) << i));
            pick.overlays[pick.n_overlays as usize] = self.tiles[next as usize - 1][mask - 1];
            pick.n_overlays += 1;
            f = next;
        }
        pick
    }
}
