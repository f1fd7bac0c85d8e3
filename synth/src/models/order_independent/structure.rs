//! The dependency structure of order-independent synthesis (Wei & Levoy 2002, §3): which cache
//! entries an entry reads. An entry is a pixel `p` of synthesis level `s` (0 = coarsest) at
//! generation `m`. It reads only entries that are lexically smaller, `(s', m') ≺ (s, m)`: the
//! previous generation of its own level around `p`, and the latest generation of the next
//! coarser level around `parent(p)`. The graph is therefore acyclic and every entry is a pure
//! function of the noise at `(0, 0)`, whatever order entries are computed in.
//!
//! Both evaluators (the literal per-pixel recursion and the served dense one) and the paper's
//! figures walk this one description, so they count and compute the same entries.

/// Pixel offsets, row-major (dy, then dx): the fixed order in which neighbourhoods are read.
pub type Taps = Vec<(i8, i8)>;

/// One cache entry's tag: level `s` (0 = coarsest), generation `m`, pixel `(x, y)` at level `s`.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash, PartialOrd, Ord)]
pub struct Entry {
    pub s: u8,
    pub m: u8,
    pub x: i64,
    pub y: i64,
}

/// The "circular 5×5" of the paper's Fig. 7 without its centre: the 20 offsets of the 5×5
/// square with dx² + dy² ≤ 6.25, (0, 0) excluded. With a 3×3 parent window it reproduces the
/// paper's single-pixel footprint of 1148 entries.
pub fn circle5() -> Taps {
    without_centre(disc5())
}

/// The 21 offsets of the 5×5 square with dx² + dy² ≤ 6.25, centre included.
pub fn disc5() -> Taps {
    square(2).into_iter().filter(|&(dx, dy)| 4 * (dx as i32 * dx as i32 + dy as i32 * dy as i32) <= 25).collect()
}

/// The `(2r+1)²` square, centre included, row-major.
pub fn square(r: i8) -> Taps {
    (-r..=r).flat_map(|dy| (-r..=r).map(move |dx| (dx, dy))).collect()
}

/// A tap set without its centre.
pub fn without_centre(taps: Taps) -> Taps {
    taps.into_iter().filter(|&t| t != (0, 0)).collect()
}

/// The four edge neighbours (the paper's Fig. 3 toy).
pub fn cross4() -> Taps {
    vec![(0, -1), (-1, 0), (1, 0), (0, 1)]
}

/// The union of two tap sets, kept in row-major order without repeats.
pub fn union(a: &[(i8, i8)], b: &[(i8, i8)]) -> Taps {
    let mut all: Taps = a.iter().chain(b).copied().collect();
    all.sort_by_key(|&(dx, dy)| (dy, dx));
    all.dedup();
    all
}

/// The value of one entry from the values it reads: the per-entry function every evaluator
/// calls. Values are exemplar coordinates (an index into the exemplar at the entry's level).
pub trait Synthesis {
    /// The noise entry (0, 0, x, y).
    fn noise(&self, x: i64, y: i64) -> u16;
    /// Entry `e` (not noise), given the values of [`Structure::reads`] in its order: `same` at
    /// (s, m − 1) around p, `lower` at (s − 1, last) around parent(p).
    fn entry(&self, e: Entry, same: &[u16], lower: &[u16]) -> u16;
}

/// What an entry reads: offsets around `p` at `(s, m − 1)` and offsets around `parent(p)` at
/// `(s − 1, last(s − 1))`. Either may be empty; both empty means noise.
#[derive(Clone, Copy, Debug)]
pub struct Reads<'a> {
    pub same: &'a [(i8, i8)],
    pub lower: &'a [(i8, i8)],
}

/// The levels, generations and neighbourhoods of one synthesis, and the domain it is on.
#[derive(Clone, Debug)]
pub struct Structure {
    /// K: synthesis levels, 0 (coarsest, noise) to K − 1 (finest = vtex level 0).
    pub levels: u8,
    /// Generations of every level but the coarsest.
    pub generations: u8,
    /// Generations of the coarsest level; its generation 0 is the noise.
    pub coarsest_generations: u8,
    /// Generation m ≥ 1 of a level s ≥ 1 reads these around p at (s, m − 1).
    pub same: Taps,
    /// Generation m ≥ 1 of the coarsest level reads these around p at (0, m − 1).
    pub coarsest_same: Taps,
    /// Every generation of a level s ≥ 1 reads these around parent(p) at (s − 1, last); for
    /// generation 0 unless `generation0_lower` says otherwise.
    pub lower: Taps,
    /// What generation 0 of a level s ≥ 1 reads around parent(p): `lower` to search on the
    /// coarser level alone (the paper), `[(0, 0)]` to upsample the parent's coordinate.
    pub generation0_lower: Taps,
    /// With 4, generation m ≥ 1 updates only the pixels of parity class
    /// `[(0,0),(1,1),(1,0),(0,1)][(m − 1) mod 4]`; the others copy (s, m − 1, p).
    pub subpasses: u8,
    /// The finest level's period when the texture is a torus; coarser levels have it halved
    /// per level. `None`: the unbounded plane (i64 coordinates, wrapping arithmetic).
    pub torus: Option<(u64, u64)>,
}

/// Reading only the pixel itself (a copy of the previous generation).
const SELF: &[(i8, i8)] = &[(0, 0)];

/// Parity classes of the four subpasses, in the order they are updated.
const SUBPASS_CLASSES: [(i64, i64); 4] = [(0, 0), (1, 1), (1, 0), (0, 1)];

impl Structure {
    /// The finest level, K − 1.
    pub fn finest(&self) -> u8 {
        self.levels - 1
    }

    /// Generations of level `s`.
    pub fn generations_of(&self, s: u8) -> u8 {
        if s == 0 {
            self.coarsest_generations
        } else {
            self.generations
        }
    }

    /// The latest generation of level `s`, the one finer levels and the output read.
    pub fn last(&self, s: u8) -> u8 {
        self.generations_of(s) - 1
    }

    /// The entry every served pixel of level `s` is: its latest generation.
    pub fn output(&self, s: u8, x: i64, y: i64) -> Entry {
        self.canonical(Entry { s, m: self.last(s), x, y })
    }

    /// Whether (s, m) is the noise level, which reads nothing.
    pub fn is_noise(&self, s: u8, m: u8) -> bool {
        s == 0 && m == 0
    }

    /// The period of level `s` on a torus.
    pub fn period(&self, s: u8) -> Option<(u64, u64)> {
        let shift = self.finest() - s;
        self.torus.map(|(w, h)| (w >> shift, h >> shift))
    }

    /// The one tag of an entry: its pixel reduced onto the torus, unchanged on the plane.
    pub fn canonical(&self, e: Entry) -> Entry {
        match self.period(e.s) {
            Some((w, h)) => Entry { x: e.x.rem_euclid(w as i64), y: e.y.rem_euclid(h as i64), ..e },
            None => e,
        }
    }

    /// Whether generation `m` ≥ 1 of a level updates pixel (x, y) or copies it.
    pub fn updates(&self, m: u8, x: i64, y: i64) -> bool {
        if self.subpasses == 1 || m == 0 {
            return true;
        }
        let (cx, cy) = SUBPASS_CLASSES[(m as usize - 1) % 4];
        (x & 1, y & 1) == (cx, cy)
    }

    /// What entry (s, m, x, y) reads.
    pub fn reads(&self, s: u8, m: u8, x: i64, y: i64) -> Reads<'_> {
        match (s, m) {
            (0, 0) => Reads { same: &[], lower: &[] },
            (0, _) if !self.updates(m, x, y) => Reads { same: SELF, lower: &[] },
            (0, _) => Reads { same: &self.coarsest_same, lower: &[] },
            (_, 0) => Reads { same: &[], lower: &self.generation0_lower },
            _ if !self.updates(m, x, y) => Reads { same: SELF, lower: &[] },
            _ => Reads { same: &self.same, lower: &self.lower },
        }
    }

    /// Appends the entries `e` reads, in the fixed order (same level, then lower), as tags.
    pub fn dependencies(&self, e: Entry, out: &mut Vec<Entry>) {
        let r = self.reads(e.s, e.m, e.x, e.y);
        for &(dx, dy) in r.same {
            let d = Entry { s: e.s, m: e.m - 1, x: e.x.wrapping_add(dx as i64), y: e.y.wrapping_add(dy as i64) };
            out.push(self.canonical(d));
        }
        if !r.lower.is_empty() {
            let (s, m) = (e.s - 1, self.last(e.s - 1));
            let (px, py) = (e.x >> 1, e.y >> 1);
            for &(dx, dy) in r.lower {
                let d = Entry { s, m, x: px.wrapping_add(dx as i64), y: py.wrapping_add(dy as i64) };
                out.push(self.canonical(d));
            }
        }
    }
}

/// The structure of the paper's Fig. 7 on a `side`² torus: 4 levels, 3 generations (1 at the
/// coarsest), a circular 5×5 at the same level and a 3×3 at the next coarser one.
pub fn paper(side: u64) -> Structure {
    Structure {
        levels: 4,
        generations: 3,
        coarsest_generations: 1,
        same: circle5(),
        coarsest_same: circle5(),
        lower: square(1),
        generation0_lower: square(1),
        subpasses: 1,
        torus: Some((side, side)),
    }
}

/// The toy of the paper's Fig. 3: 2 levels × 3 generations, 4 edge neighbours and the parent
/// at the fine level, the pixel's own previous generation at the coarse level.
pub fn toy() -> Structure {
    Structure {
        levels: 2,
        generations: 3,
        coarsest_generations: 3,
        same: cross4(),
        coarsest_same: vec![(0, 0)],
        lower: vec![(0, 0)],
        generation0_lower: vec![(0, 0)],
        subpasses: 1,
        torus: None,
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::collections::HashSet;

    /// Every entry a request reaches, the request included (the paper's footprint).
    fn footprint(st: &Structure, e: Entry) -> HashSet<Entry> {
        let mut seen = HashSet::from([e]);
        let mut todo = vec![e];
        let mut deps = Vec::new();
        while let Some(e) = todo.pop() {
            deps.clear();
            st.dependencies(e, &mut deps);
            for &d in &deps {
                if seen.insert(d) {
                    todo.push(d);
                }
            }
        }
        seen
    }

    #[test]
    fn circle5_is_the_twenty_taps_of_a_disc_of_radius_two_and_a_half() {
        assert_eq!(disc5().len(), 21);
        assert_eq!(circle5().len(), 20);
        assert!(!circle5().contains(&(0, 0)) && !circle5().contains(&(2, 2)) && circle5().contains(&(2, 1)));
        assert_eq!(union(&circle5(), &square(1)), disc5());
    }

    #[test]
    fn one_pixel_touches_1148_entries_at_phase_3_3_as_in_fig_7a() {
        let st = paper(512);
        assert_eq!(footprint(&st, st.output(3, 3, 3)).len(), 1148);
        assert_eq!(footprint(&st, st.output(3, 0, 0)).len(), 1163);
    }

    #[test]
    fn the_fig_3_toy_touches_32_entries() {
        let st = toy();
        for (x, y) in [(0, 0), (5, -3), (-7, 2)] {
            assert_eq!(footprint(&st, st.output(1, x, y)).len(), 32);
        }
    }
}
