//! The Virtual Random Map block (§3.2) as one layer sees it: per-cell random numbers from the
//! stored σ tables. Each parameter (choice, dithering, offsets, scale, rotation, phase, rest)
//! has its own table, so they are uncorrelated; layers add a large offset to g ("distant
//! locations in the aperiodic tiling are uncorrelated") so stacked layers differ too.

use super::sigma::{Role, Sigma};
use std::sync::Arc;

#[derive(Clone)]
pub struct LayerRng {
    tables: Arc<[Sigma]>,
    off: (u64, u64),
    /// Hashing steps covering the offset grid with the 16 × 16 random tables.
    steps: u32,
    /// Steps for the pattern table, when it can hash this grid (both sides > 1 or grid 1-wide).
    pattern_steps: Option<u32>,
}

impl LayerRng {
    pub fn new(tables: Arc<[Sigma]>, layer: usize, grid: (u64, u64)) -> Self {
        let off = (layer as u64 * 7_919_777, layer as u64 * 5_003_227);
        let span = (grid.0 + off.0, grid.1 + off.1);
        let steps = tables[Role::Choice as usize].steps_for(span.0, span.1).expect("16×16 tables hash any grid");
        let pattern_steps = tables[Role::Pattern as usize].steps_for(span.0, span.1);
        Self { tables, off, steps, pattern_steps }
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

    #[inline]
    pub fn below(&self, role: Role, gx: u64, gy: u64, m: u32) -> u32 {
        self.tables[role as usize].below(gx + self.off.0, gy + self.off.1, self.steps, m)
    }
}
