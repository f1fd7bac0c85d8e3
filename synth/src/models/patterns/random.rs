//! The Virtual Random Map block (§3.2) as one layer sees it: per-cell random numbers from the
//! stored σ tables. Each parameter (choice, dithering, offsets, scale, rotation, phase, rest)
//! has its own table, so they are uncorrelated; layers add a large offset to g ("distant
//! locations in the aperiodic tiling are uncorrelated") so stacked layers differ too.

use super::sigma::{needs_range_table, RangeTable, Role, Sigma, MAX_RANGE, RANGES_SECTION};
use crate::{Error, Result};
use std::sync::Arc;

#[derive(Clone)]
pub struct LayerRng {
    tables: Arc<[Sigma]>,
    off: (u64, u64),
    /// Hashing steps covering the offset grid with the 16 × 16 random tables.
    steps: u32,
    /// Steps for the pattern table, when it can hash this grid (both sides > 1 or grid 1-wide).
    pattern_steps: Option<u32>,
    /// Tables for ranges that do not divide the random tables, with their hashing steps.
    ranges: Arc<[RangeTable]>,
    range_steps: Vec<u32>,
    /// Largest offset cell coordinate, what the hashing steps must cover.
    span: u64,
}

impl LayerRng {
    pub fn new(tables: Arc<[Sigma]>, layer: usize, grid: (u64, u64)) -> Self {
        let off = (layer as u64 * 7_919_777, layer as u64 * 5_003_227);
        let span = (grid.0 + off.0, grid.1 + off.1);
        let steps = tables[Role::Choice as usize].steps_for(span.0, span.1).expect("16×16 tables hash any grid");
        let pattern_steps = tables[Role::Pattern as usize].steps_for(span.0, span.1);
        let span = span.0.max(span.1);
        Self { tables, off, steps, pattern_steps, ranges: Arc::from([]), range_steps: Vec::new(), span }
    }

    /// Draws ranges that do not divide 256 from `ranges` (the `sigma-ranges` section).
    pub fn with_ranges(mut self, ranges: Arc<[RangeTable]>) -> Self {
        self.range_steps = ranges.iter().map(|t| t.steps_for(self.span)).collect();
        self.ranges = ranges;
        self
    }

    /// Checks that `m` values can be drawn without aliasing: m divides the random tables, or
    /// a range table of m entries is stored.
    pub fn check_range(&self, what: &str, m: u32) -> Result<()> {
        if m == 0 || m > MAX_RANGE {
            return Err(Error::param(what, format!("a range of {m} values; 1..={MAX_RANGE}")));
        }
        if needs_range_table(m) && !self.ranges.iter().any(|t| t.range() == m) {
            return Err(Error::param(
                what,
                format!(
                    "a range of {m} values does not divide the σ table size {} and section `{RANGES_SECTION}`                      has no permutation of 0..{m}; without one the random choice would be biased (aliasing,                      Fig. 2.2) — make the bundle with `create`, which stores the tables its ranges need",
                    self.tables[Role::Choice as usize].len()
                ),
            ));
        }
        Ok(())
    }

    pub fn table(&self, role: Role) -> &Sigma {
        &self.tables[role as usize]
    }

    pub fn pattern_steps(&self) -> Option<u32> {
        self.pattern_steps
    }

    /// Vectorial pattern index from the pattern table (basic aperiodic tiling), row-major.
    #[inline]
    pub fn pattern(&self, gx: u64, gy: u64) -> u32 {
        match self.pattern_steps {
            Some(steps) => self.tables[0].index(gx + self.off.0, gy + self.off.1, steps),
            // A one-pattern reference (basic sparse convolution, T = 1): always pattern 0.
            None => 0,
        }
    }

    #[inline]
    pub fn unit(&self, role: Role, gx: u64, gy: u64) -> f32 {
        self.tables[role as usize].unit(gx + self.off.0, gy + self.off.1, self.steps)
    }

    /// A uniform integer in 0..m for cell g (m checked by [`Self::check_range`]).
    #[inline]
    pub fn below(&self, role: Role, gx: u64, gy: u64, m: u32) -> u32 {
        if !needs_range_table(m) {
            return self.tables[role as usize].below(gx + self.off.0, gy + self.off.1, self.steps, m);
        }
        let i = self.ranges.iter().position(|t| t.range() == m).expect("ranges are checked at load");
        self.ranges[i].below(gx + self.off.0, gy + self.off.1, role as u64, self.range_steps[i])
    }
}
