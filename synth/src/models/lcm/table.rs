//! Event tables (paper §2.3) and the layer control masks generated from them (§5).
//!
//! A table is a small grid of cells repeated over a layer's replication points (one cell for
//! the whole layer, the paper's 2 × 2 tables, or one cell per point). A cell gives the
//! probability of each value of each attribute — sign, rotation, mirroring, operation — drawn
//! independently, as the paper's tables list them. The LCM is drawn once, when the encoding
//! is made, from a counter-based hash of (seed, layer, attribute, point), and then stored one
//! byte a point: rendering never draws anything.

use super::event::{Event, Operation, Sign};
use crate::{hash, Error, Result};
use serde::{Deserialize, Serialize};

/// Probabilities may be off 1 by this much (decimal fractions such as 0.33 + 0.33 + 0.34).
const SUM_TOLERANCE: f64 = 1e-6;

/// The distribution of events at one replication point.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Cell {
    /// P(positive), P(negative), P(no replication).
    #[serde(default = "Cell::default_sign")]
    pub sign: [f64; 3],
    /// P(0°), P(90°), P(180°), P(270°), clockwise.
    #[serde(default = "Cell::default_rotation")]
    pub rotation: [f64; 4],
    /// P(mirrored).
    #[serde(default)]
    pub mirror: f64,
    /// P(addition), P(non-zero application), P(maximum application).
    #[serde(default = "Cell::default_operation")]
    pub operation: [f64; 3],
}

impl Cell {
    fn default_sign() -> [f64; 3] {
        [1.0, 0.0, 0.0]
    }
    fn default_rotation() -> [f64; 4] {
        [1.0, 0.0, 0.0, 0.0]
    }
    fn default_operation() -> [f64; 3] {
        [1.0, 0.0, 0.0]
    }

    /// "No replication" with probability 1 (the zero entries of the paper's tables).
    pub fn none() -> Cell {
        Cell { sign: [0.0, 0.0, 1.0], ..Cell::positive([1.0, 0.0, 0.0, 0.0], 0.0, [1.0, 0.0, 0.0]) }
    }

    /// Always a positive replication, with these rotation, mirror and operation odds.
    pub fn positive(rotation: [f64; 4], mirror: f64, operation: [f64; 3]) -> Cell {
        Cell { sign: [1.0, 0.0, 0.0], rotation, mirror, operation }
    }

    fn check(&self, what: &str) -> Result<()> {
        distribution(&self.sign, &format!("{what}.sign"))?;
        distribution(&self.rotation, &format!("{what}.rotation"))?;
        distribution(&self.operation, &format!("{what}.operation"))?;
        if !(0.0..=1.0).contains(&self.mirror) {
            return Err(Error::param(
                format!("{what}.mirror"),
                format!("probability {} is not in [0, 1]", self.mirror),
            ));
        }
        Ok(())
    }

    /// Draws the event of point (i, j) of layer `layer` and returns its code.
    fn draw(&self, seed: u64, layer: u64, i: i64, j: i64) -> u8 {
        let u = |attr: u64| hash::unit_f64(hash::hash4(seed, layer * 4 + attr, i, j));
        let sign = match pick(&self.sign, u(0)) {
            0 => Sign::Positive,
            1 => Sign::Negative,
            _ => return Event::NONE.encode(),
        };
        let operation = match pick(&self.operation, u(3)) {
            0 => Operation::Add,
            1 => Operation::NonZero,
            _ => Operation::Maximum,
        };
        Event { sign, rotation: pick(&self.rotation, u(1)) as u8, mirror: u(2) < self.mirror, operation }.encode()
    }

    /// The probability that [`Cell::draw`] yields `code` (every "no replication" is code 0).
    pub fn probability_of(&self, code: u8) -> f64 {
        let Ok(e) = Event::decode(code) else { return 0.0 };
        let p_sign = match e.sign {
            Sign::None => return if code == 0 { self.sign[2] } else { 0.0 },
            Sign::Positive => self.sign[0],
            Sign::Negative => self.sign[1],
        };
        let p_mirror = if e.mirror { self.mirror } else { 1.0 - self.mirror };
        let p_op = match e.operation {
            Operation::Add => self.operation[0],
            Operation::NonZero => self.operation[1],
            Operation::Maximum => self.operation[2],
        };
        p_sign * self.rotation[e.rotation as usize] * p_mirror * p_op
    }
}

/// The index of the bucket of `u` ∈ [0, 1) in the cumulative distribution `p`; the last
/// bucket with positive probability takes any rounding slack.
fn pick(p: &[f64], u: f64) -> usize {
    let mut acc = 0.0;
    let mut last = 0;
    for (i, &q) in p.iter().enumerate() {
        if q > 0.0 {
            last = i;
            acc += q;
            if u < acc {
                return i;
            }
        }
    }
    last
}

fn distribution(p: &[f64], what: &str) -> Result<()> {
    if let Some(q) = p.iter().find(|q| !q.is_finite() || **q < 0.0) {
        return Err(Error::param(what, format!("probability {q} is negative or not a number")));
    }
    let sum: f64 = p.iter().sum();
    if (sum - 1.0).abs() > SUM_TOLERANCE {
        return Err(Error::param(what, format!("probabilities {p:?} sum to {sum}, not 1")));
    }
    Ok(())
}

/// An event table: `width × height` cells, row-major, repeated over the replication points.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Table {
    pub width: u32,
    pub height: u32,
    pub cells: Vec<Cell>,
}

impl Table {
    /// One distribution for every point of the layer.
    pub fn single(cell: Cell) -> Table {
        Table { width: 1, height: 1, cells: vec![cell] }
    }

    /// The cell that governs point (i, j).
    pub fn cell(&self, i: usize, j: usize) -> &Cell {
        &self.cells[(j % self.height as usize) * self.width as usize + i % self.width as usize]
    }

    /// Checks the table and that it repeats a whole number of times over an LCM of `size`
    /// points (otherwise its pattern would break where the LCM wraps).
    pub fn check(&self, size: [u32; 2], what: &str) -> Result<()> {
        if self.width == 0 || self.height == 0 {
            return Err(Error::param(what, "event table of zero size"));
        }
        if self.cells.len() != self.width as usize * self.height as usize {
            return Err(Error::param(
                what,
                format!("{} cells for a {}×{} event table", self.cells.len(), self.width, self.height),
            ));
        }
        if size[0] % self.width != 0 || size[1] % self.height != 0 {
            return Err(Error::param(
                what,
                format!(
                    "LCM of {}×{} points is not a whole number of {}×{} event tables",
                    size[0], size[1], self.width, self.height
                ),
            ));
        }
        for (n, c) in self.cells.iter().enumerate() {
            c.check(&format!("{what}.cells[{n}]"))?;
        }
        Ok(())
    }

    /// The LCM of layer `layer`: `size[0] × size[1]` event codes, row-major.
    pub fn generate(&self, size: [u32; 2], seed: u64, layer: u64) -> Vec<u8> {
        let (w, h) = (size[0] as usize, size[1] as usize);
        let mut out = Vec::with_capacity(w * h);
        for j in 0..h {
            for i in 0..w {
                out.push(self.cell(i, j).draw(seed, layer, i as i64, j as i64));
            }
        }
        out
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn probabilities_of_a_cell_sum_to_one() {
        let c = Cell { sign: [0.33, 0.33, 0.34], rotation: [0.25; 4], mirror: 0.5, operation: [0.5, 0.25, 0.25] };
        let total: f64 = (0..128u8).map(|code| c.probability_of(code)).sum();
        assert!((total - 1.0).abs() < 1e-12, "{total}");
    }

    #[test]
    fn pick_respects_zero_buckets() {
        assert_eq!(pick(&[0.0, 1.0, 0.0], 0.999_999), 1);
        assert_eq!(pick(&[0.5, 0.0, 0.5], 0.5), 2);
        assert_eq!(pick(&[0.5, 0.5, 0.0], 0.999_999_999), 1);
    }
}
