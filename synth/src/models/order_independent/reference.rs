//! The reference evaluator: the paper's Table 1, one requested entry at a time.
//!
//! `SynthesizePixel` looks the entry up in a per-pixel cache and, on a miss, runs
//! `BuildOutputNeighborhood`, which obtains every entry the neighbourhood reads (from the cache,
//! or by synthesizing it first), then computes the entry and adds it to the cache. The mutual
//! recursion is depth-first in the fixed order of [`Structure::dependencies`], on an explicit
//! stack so that deep pyramids cannot overflow the thread's stack.
//!
//! The cache is bounded in entries with least-recently-used replacement. A value is copied into
//! the neighbourhood being built as soon as it is obtained, so evicting it later in the same
//! recursion only costs a recomputation, never a failure: any capacity works, 0 included.
//! Pinned entries (the paper's pixels "fixed" at initialization, §3) are held beside the cache
//! and never evicted.
//!
//! This evaluator exists to be obviously the paper: tests compare the served evaluator with it,
//! and the paper's cache figures count its work (in structure-only mode, [`StructureOnly`]).

pub use super::structure::{paper, toy};
use super::structure::{Entry, Structure, Synthesis};
use crate::hash::fmix64;
use std::collections::HashMap;
use std::hash::{BuildHasherDefault, Hasher};

/// The capacity of a cache that never evicts.
pub const UNBOUNDED: usize = usize::MAX;

/// Every entry of a torus structure: Σ over levels of generations × pixels.
pub fn entries(structure: &Structure) -> u64 {
    (0..structure.levels)
        .map(|s| {
            let (w, h) = structure.period(s).expect("a torus has a finite number of entries");
            structure.generations_of(s) as u64 * w * h
        })
        .sum()
}

/// The search skipped: every entry is 0. Which entries are computed does not depend on their
/// values, so the traversal, the cache and the counters are those of a real synthesis.
pub struct StructureOnly;

impl Synthesis for StructureOnly {
    fn noise(&self, _x: i64, _y: i64) -> u16 {
        0
    }

    fn entry(&self, _e: Entry, _same: &[u16], _lower: &[u16]) -> u16 {
        0
    }
}

/// A borrowed synthesis, so a texture's own per-entry function can drive the reference.
impl<T: Synthesis + ?Sized> Synthesis for &T {
    fn noise(&self, x: i64, y: i64) -> u16 {
        (**self).noise(x, y)
    }

    fn entry(&self, e: Entry, same: &[u16], lower: &[u16]) -> u16 {
        (**self).entry(e, same, lower)
    }
}

/// The work done so far.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counters {
    /// Entries computed, noise included: the paper's count (one cold request = 1148).
    pub computed: u64,
    /// Entries computed other than noise: the searches run.
    pub computed_without_noise: u64,
    /// Requests made through [`Reference::value`] or [`Reference::request`].
    pub requests: u64,
}

/// A hasher for cache tags: multiply-rotate per field, one avalanche at the end.
#[derive(Default)]
struct TagHasher(u64);

impl Hasher for TagHasher {
    fn write(&mut self, bytes: &[u8]) {
        for &b in bytes {
            self.write_u64(b as u64);
        }
    }

    fn write_u8(&mut self, v: u8) {
        self.write_u64(v as u64);
    }

    fn write_i64(&mut self, v: i64) {
        self.write_u64(v as u64);
    }

    fn write_u64(&mut self, v: u64) {
        self.0 = (self.0.rotate_left(5) ^ v).wrapping_mul(0x517c_c1b7_2722_0a95);
    }

    fn finish(&self) -> u64 {
        fmix64(self.0)
    }
}

type TagMap<V> = HashMap<Entry, V, BuildHasherDefault<TagHasher>>;

const NIL: u32 = u32::MAX;

/// Tori with at most this many entries index their cache slots by a table over all entries.
const DENSE_ENTRIES: u64 = 1 << 26;

/// Which slot holds an entry: a table over every entry of a small torus (one load, no
/// hashing), a hash map otherwise.
enum Index {
    /// `bases[s · stride + m]`: where (s, m) starts in `table`.
    Dense {
        structure: Structure,
        stride: usize,
        bases: Vec<usize>,
        table: Vec<u32>,
    },
    Hashed(TagMap<u32>),
}

impl Index {
    fn new(structure: &Structure) -> Self {
        if structure.torus.is_none() || entries(structure) > DENSE_ENTRIES {
            return Index::Hashed(TagMap::default());
        }
        let stride = structure.generations.max(structure.coarsest_generations) as usize;
        let mut bases = vec![0; structure.levels as usize * stride];
        let mut next = 0;
        for s in 0..structure.levels {
            let (w, h) = structure.period(s).expect("a torus");
            for m in 0..structure.generations_of(s) {
                bases[s as usize * stride + m as usize] = next;
                next += (w * h) as usize;
            }
        }
        Index::Dense { structure: structure.clone(), stride, bases, table: vec![NIL; next] }
    }

    /// The table position of a canonical entry of a torus.
    fn position(structure: &Structure, stride: usize, bases: &[usize], e: &Entry) -> usize {
        let w = structure.period(e.s).expect("a torus").0 as usize;
        bases[e.s as usize * stride + e.m as usize] + e.y as usize * w + e.x as usize
    }

    fn get(&self, e: &Entry) -> Option<u32> {
        match self {
            Index::Dense { structure, stride, bases, table } => {
                Some(table[Self::position(structure, *stride, bases, e)]).filter(|&i| i != NIL)
            }
            Index::Hashed(map) => map.get(e).copied(),
        }
    }

    fn set(&mut self, e: &Entry, slot: u32) {
        match self {
            Index::Dense { structure, stride, bases, table } => {
                table[Self::position(structure, *stride, bases, e)] = slot;
            }
            Index::Hashed(map) if slot == NIL => {
                map.remove(e);
            }
            Index::Hashed(map) => {
                map.insert(*e, slot);
            }
        }
    }
}

struct Slot {
    entry: Entry,
    value: u16,
    newer: u32,
    older: u32,
}

/// Entries in a slab threaded by a doubly linked recency list (not kept when nothing is ever
/// evicted).
struct Lru {
    capacity: usize,
    index: Index,
    slots: Vec<Slot>,
    newest: u32,
    oldest: u32,
}

impl Lru {
    fn new(structure: &Structure, capacity: usize) -> Self {
        Self { capacity, index: Index::new(structure), slots: Vec::new(), newest: NIL, oldest: NIL }
    }

    fn get(&mut self, e: &Entry) -> Option<u16> {
        let i = self.index.get(e)?;
        if self.capacity != UNBOUNDED && i != self.newest {
            self.unlink(i);
            self.link_newest(i);
        }
        Some(self.slots[i as usize].value)
    }

    /// Adds an entry that is not in the cache, evicting the least recently used when full.
    fn insert(&mut self, entry: Entry, value: u16) {
        if self.capacity == 0 {
            return;
        }
        let i = if self.slots.len() < self.capacity {
            assert!(self.slots.len() < NIL as usize, "more cache entries than slot indices");
            self.slots.push(Slot { entry, value, newer: NIL, older: NIL });
            self.slots.len() as u32 - 1
        } else {
            let i = self.oldest;
            self.unlink(i);
            self.index.set(&self.slots[i as usize].entry, NIL);
            self.slots[i as usize].entry = entry;
            self.slots[i as usize].value = value;
            i
        };
        self.index.set(&entry, i);
        self.link_newest(i);
    }

    fn unlink(&mut self, i: u32) {
        let Slot { newer, older, .. } = self.slots[i as usize];
        match newer {
            NIL => self.newest = older,
            n => self.slots[n as usize].older = older,
        }
        match older {
            NIL => self.oldest = newer,
            o => self.slots[o as usize].newer = newer,
        }
    }

    fn link_newest(&mut self, i: u32) {
        self.slots[i as usize].newer = NIL;
        self.slots[i as usize].older = self.newest;
        match self.newest {
            NIL => self.oldest = i,
            n => self.slots[n as usize].newer = i,
        }
        self.newest = i;
    }
}

/// One `SynthesizePixel` in progress: its neighbourhood's tags and the values obtained so far.
#[derive(Default)]
struct Frame {
    entry: Option<Entry>,
    tags: Vec<Entry>,
    values: Vec<u16>,
}

/// The paper's per-pixel evaluator over a [`Structure`] and a per-entry [`Synthesis`].
pub struct Reference<S> {
    structure: Structure,
    synthesis: S,
    cache: Lru,
    pinned: TagMap<u16>,
    counters: Counters,
    /// Frames of the recursion, outermost first; those deeper than the current one are spare,
    /// kept for their allocations.
    stack: Vec<Frame>,
}

impl<S: Synthesis> Reference<S> {
    /// An empty cache of `capacity` entries (0: no cache, [`UNBOUNDED`]: never evicts).
    pub fn new(structure: Structure, synthesis: S, capacity: usize) -> Self {
        Self {
            cache: Lru::new(&structure, capacity),
            structure,
            synthesis,
            pinned: TagMap::default(),
            counters: Counters::default(),
            stack: Vec::new(),
        }
    }

    pub fn structure(&self) -> &Structure {
        &self.structure
    }

    pub fn counters(&self) -> Counters {
        self.counters
    }

    /// Fixes entry `e` to `value` (the paper's initialization of constrained pixels): it is read
    /// like a cached entry, never computed, never evicted, and not counted in the capacity.
    pub fn pin(&mut self, e: Entry, value: u16) {
        self.pinned.insert(self.structure.canonical(e), value);
    }

    /// The entries the cache holds, pinned ones excluded, in no particular order.
    pub fn cached(&self) -> impl Iterator<Item = Entry> + '_ {
        self.cache.slots.iter().map(|slot| slot.entry)
    }

    /// The served pixel (x, y) of level `s`: entry (s, last(s), x, y).
    pub fn request(&mut self, s: u8, x: i64, y: i64) -> u16 {
        self.value(self.structure.output(s, x, y))
    }

    /// `SynthesizePixel` of entry `e`.
    pub fn value(&mut self, e: Entry) -> u16 {
        self.counters.requests += 1;
        let e = self.structure.canonical(e);
        if let Some(v) = self.lookup(&e) {
            return v;
        }
        let mut depth = 0;
        self.open(depth, e);
        loop {
            let frame = &mut self.stack[depth];
            if frame.values.len() < frame.tags.len() {
                let tag = frame.tags[frame.values.len()];
                match self.lookup(&tag) {
                    Some(v) => self.stack[depth].values.push(v),
                    None => {
                        depth += 1;
                        self.open(depth, tag);
                    }
                }
                continue;
            }
            let v = self.compute(depth);
            if depth == 0 {
                return v;
            }
            depth -= 1;
            self.stack[depth].values.push(v);
        }
    }

    fn lookup(&mut self, e: &Entry) -> Option<u16> {
        if !self.pinned.is_empty() {
            if let Some(&v) = self.pinned.get(e) {
                return Some(v);
            }
        }
        self.cache.get(e)
    }

    /// Starts `SynthesizePixel(e)` on a miss: lists the tags `BuildOutputNeighborhood` reads.
    fn open(&mut self, depth: usize, e: Entry) {
        if self.stack.len() == depth {
            self.stack.push(Frame::default());
        }
        let frame = &mut self.stack[depth];
        frame.entry = Some(e);
        frame.tags.clear();
        frame.values.clear();
        self.structure.dependencies(e, &mut frame.tags);
    }

    /// Ends `SynthesizePixel` once its neighbourhood is complete: the search, then the cache.
    fn compute(&mut self, depth: usize) -> u16 {
        let frame = &self.stack[depth];
        let e = frame.entry.expect("an open frame has an entry");
        let v = if self.structure.is_noise(e.s, e.m) {
            self.synthesis.noise(e.x, e.y)
        } else {
            let same = self.structure.reads(e.s, e.m, e.x, e.y).same.len();
            self.counters.computed_without_noise += 1;
            self.synthesis.entry(e, &frame.values[..same], &frame.values[same..])
        };
        self.counters.computed += 1;
        self.cache.insert(e, v);
        v
    }
}

#[cfg(test)]
mod tests {
    use super::super::structure::{cross4, square};
    use super::*;
    use crate::hash::hash4;

    /// A synthesis whose every value depends on all it reads, so a wrong or misordered read
    /// changes the result.
    struct Hashing;

    impl Synthesis for Hashing {
        fn noise(&self, x: i64, y: i64) -> u16 {
            hash4(7, 0, x, y) as u16
        }

        fn entry(&self, e: Entry, same: &[u16], lower: &[u16]) -> u16 {
            let mut h = fmix64(((e.s as u64) << 8 | e.m as u64) ^ (same.len() as u64) << 16);
            for &v in same.iter().chain(lower) {
                h = fmix64(h ^ v as u64);
            }
            h as u16
        }
    }

    /// Every entry of a torus structure, computed level by level and generation by generation
    /// (no recursion, no cache), with `pins` fixed.
    fn dense(st: &Structure, syn: &impl Synthesis, pins: &[(Entry, u16)]) -> HashMap<Entry, u16> {
        let mut all = HashMap::new();
        let mut tags = Vec::new();
        for s in 0..st.levels {
            let (w, h) = st.period(s).unwrap();
            for m in 0..st.generations_of(s) {
                for y in 0..h as i64 {
                    for x in 0..w as i64 {
                        let e = Entry { s, m, x, y };
                        let v = if let Some(&(_, v)) = pins.iter().find(|(p, _)| *p == e) {
                            v
                        } else if st.is_noise(s, m) {
                            syn.noise(x, y)
                        } else {
                            tags.clear();
                            st.dependencies(e, &mut tags);
                            let values: Vec<u16> = tags.iter().map(|t| all[t]).collect();
                            let same = st.reads(s, m, x, y).same.len();
                            syn.entry(e, &values[..same], &values[same..])
                        };
                        all.insert(e, v);
                    }
                }
            }
        }
        all
    }

    /// Small enough to evaluate without a cache (10,355 entries for one request) and larger than
    /// 1000 entries: 3 levels, 2 generations, a 32² torus.
    fn small(subpasses: u8) -> Structure {
        Structure {
            levels: 3,
            generations: 2,
            coarsest_generations: 2,
            same: cross4(),
            coarsest_same: cross4(),
            lower: square(1),
            generation0_lower: square(1),
            subpasses,
            torus: Some((32, 32)),
        }
    }

    /// Every pixel of every level in an order shuffled by `seed`.
    fn shuffled_requests(st: &Structure, seed: u64) -> Vec<(u8, i64, i64)> {
        let mut all: Vec<(u64, (u8, i64, i64))> = Vec::new();
        for s in 0..st.levels {
            let (w, h) = st.period(s).unwrap();
            for y in 0..h as i64 {
                for x in 0..w as i64 {
                    all.push((hash4(seed, s as u64, x, y), (s, x, y)));
                }
            }
        }
        all.sort_unstable();
        all.into_iter().map(|(_, r)| r).collect()
    }

    fn footprint(st: &Structure, s: u8, x: i64, y: i64) -> Reference<StructureOnly> {
        let mut r = Reference::new(st.clone(), StructureOnly, UNBOUNDED);
        r.request(s, x, y);
        r
    }

    fn by_level_and_generation(r: &Reference<StructureOnly>) -> Vec<((u8, u8), usize)> {
        let mut counts: std::collections::BTreeMap<(u8, u8), usize> = Default::default();
        for e in r.cached() {
            *counts.entry((e.s, e.m)).or_default() += 1;
        }
        counts.into_iter().rev().collect()
    }

    #[test]
    fn values_do_not_depend_on_the_cache_capacity_or_the_request_order() {
        for subpasses in [1, 4] {
            let st = small(subpasses);
            let truth = dense(&st, &Hashing, &[]);
            let mut computed = Vec::new();
            for (capacity, seed) in [(0, 1), (16, 2), (1000, 3), (UNBOUNDED, 4), (UNBOUNDED, 5)] {
                let mut r = Reference::new(st.clone(), Hashing, capacity);
                for (s, x, y) in shuffled_requests(&st, seed) {
                    assert_eq!(r.request(s, x, y), truth[&st.output(s, x, y)], "capacity {capacity}");
                }
                computed.push(r.counters().computed);
                if capacity == UNBOUNDED {
                    assert_eq!(r.counters().computed, r.cached().count() as u64, "each entry computed once");
                }
            }
            assert!(
                computed[0] > computed[1] && computed[1] > computed[2] && computed[2] > computed[3],
                "{computed:?}"
            );
            assert_eq!(computed[3], computed[4]);
        }
    }

    /// The plane indexes its cache by hashing instead of a table: the same check, against an
    /// unbounded cache in scanline order.
    #[test]
    fn on_the_plane_values_do_not_depend_on_the_cache_capacity_or_the_request_order() {
        let st = Structure { torus: None, ..small(1) };
        let window: Vec<(i64, i64)> = (-8..8).flat_map(|y| (-8..8).map(move |x| (x * 3 - 1, y * 2 + 5))).collect();
        let mut unbounded = Reference::new(st.clone(), Hashing, UNBOUNDED);
        let truth: HashMap<(i64, i64), u16> =
            window.iter().map(|&(x, y)| ((x, y), unbounded.request(2, x, y))).collect();
        for (capacity, seed) in [(0, 1), (16, 2), (1000, 3)] {
            let mut order = window.clone();
            order.sort_by_key(|&(x, y)| hash4(seed, 0, x, y));
            let mut r = Reference::new(st.clone(), Hashing, capacity);
            for (x, y) in order {
                assert_eq!(r.request(2, x, y), truth[&(x, y)], "capacity {capacity}");
            }
            assert!(r.counters().computed > unbounded.counters().computed);
        }
    }

    #[test]
    fn pinned_entries_are_read_never_computed_and_never_evicted() {
        let st = small(1);
        let pins = [(st.output(2, 3, 4), 11), (st.output(1, 1, 1), 22), (Entry { s: 2, m: 0, x: 5, y: 5 }, 33)];
        let truth = dense(&st, &Hashing, &pins);
        let mut r = Reference::new(st.clone(), Hashing, 16);
        for &(e, v) in &pins {
            r.pin(e, v);
        }
        assert_eq!(r.request(2, 3, 4), 11);
        assert_eq!(r.counters().computed, 0);
        for (s, x, y) in shuffled_requests(&st, 9) {
            assert_eq!(r.request(s, x, y), truth[&st.output(s, x, y)]);
        }
        assert_eq!(r.request(1, 1, 1), 22);
        assert!(r.cached().all(|e| pins.iter().all(|&(p, _)| p != e)));
    }

    /// 255 levels × 255 generations reading one tap each: a recursion 65,025 entries deep.
    #[test]
    fn a_deep_pyramid_does_not_overflow_the_stack() {
        let chain = vec![(0, 0)];
        let st = Structure {
            levels: 255,
            generations: 255,
            coarsest_generations: 255,
            same: chain.clone(),
            coarsest_same: chain.clone(),
            lower: chain.clone(),
            generation0_lower: chain,
            subpasses: 1,
            torus: None,
        };
        let mut r = Reference::new(st, StructureOnly, UNBOUNDED);
        r.request(254, 1 << 40, -(1 << 40));
        assert_eq!(r.counters().computed, 255 * 255);
    }

    /// Fig. 7(a) and the phase table of spec §2.2.
    #[test]
    fn one_request_computes_1148_entries_at_phase_3_3_and_the_phase_table_of_fig_7a() {
        const PHASES: [[u64; 8]; 8] = [
            [1163, 1154, 1148, 1159, 1159, 1148, 1154, 1163],
            [1154, 1162, 1154, 1148, 1148, 1154, 1162, 1154],
            [1148, 1154, 1146, 1139, 1139, 1146, 1154, 1148],
            [1159, 1148, 1139, 1148, 1148, 1139, 1148, 1159],
            [1159, 1148, 1139, 1148, 1148, 1139, 1148, 1159],
            [1148, 1154, 1146, 1139, 1139, 1146, 1154, 1148],
            [1154, 1162, 1154, 1148, 1148, 1154, 1162, 1154],
            [1163, 1154, 1148, 1159, 1159, 1148, 1154, 1163],
        ];
        let st = paper(512);
        for (y, row) in PHASES.iter().enumerate() {
            for (x, &expected) in row.iter().enumerate() {
                let c = footprint(&st, 3, 256 + x as i64, 256 + y as i64).counters();
                assert_eq!(c.computed, expected, "phase ({x}, {y})");
                assert_eq!(c.requests, 1);
            }
        }
        let r = footprint(&st, 3, 3, 3);
        assert_eq!(r.counters().computed, 1148);
        assert_eq!(r.counters().computed_without_noise, 1148 - 117);
        let breakdown = [(3, 2, 1), (3, 1, 20), (3, 0, 69), (2, 2, 46), (2, 1, 111), (2, 0, 204)];
        let breakdown = breakdown.into_iter().chain([(1, 2, 96), (1, 1, 184), (1, 0, 300), (0, 0, 117)]);
        assert_eq!(by_level_and_generation(&r), breakdown.map(|(s, m, n)| ((s, m), n)).collect::<Vec<_>>());
    }

    /// Fig. 3: pixels 0–31, 1, 4, 9 at the fine level and 6, 6, 6 at the coarse one.
    #[test]
    fn the_fig_3_toy_computes_32_entries() {
        let r = footprint(&toy(), 1, 5, -3);
        assert_eq!(r.counters().computed, 32);
        let expected = [((1, 2), 1), ((1, 1), 4), ((1, 0), 9), ((0, 2), 6), ((0, 1), 6), ((0, 0), 6)];
        assert_eq!(by_level_and_generation(&r), expected);
    }

    /// Fig. 4: one request into a cache holding all 1,036,288 entries of a 512² texture touches
    /// 0.00111 of them; requesting every pixel computes each exactly once (Fig. 8's floor).
    #[test]
    fn the_fig_4_intercept_and_the_full_coverage_floor_of_fig_8() {
        let st = paper(512);
        assert_eq!(entries(&st), 1_036_288);
        let one = footprint(&st, 3, 3, 3).counters().computed;
        assert_eq!((one as f64 / 1_036_288.0 * 1e5).round(), 111.0);
        let mut r = Reference::new(st, StructureOnly, UNBOUNDED);
        for y in 0..512 {
            for x in 0..512 {
                r.request(3, x, y);
            }
        }
        let c = r.counters();
        assert_eq!((c.computed, c.requests), (1_036_288, 512 * 512));
        assert_eq!((c.computed as f64 / c.requests as f64 * 1000.0).round(), 3953.0);
    }

    /// The reference evaluator with the real per-entry function equals the served dense
    /// evaluator on random windows, in both search modes, on the plane and on a torus, whatever
    /// the cache capacity and request order.
    #[test]
    fn the_reference_equals_the_served_evaluator_with_the_real_kernel() {
        use super::super::params::Params;
        use super::super::rect::Rect;
        use super::super::search::Synthesizer;
        use super::super::served::{evaluate, Counts};
        use serde_json::json;

        let sample = crate::samples::pebbles(32, 6, 4, false);
        // Each bounded cache holds less than the window's cone, so it evicts and recomputes; with
        // four levels of the default generations, 300 entries are so far under one pixel's cone
        // that the recursion recomputes exponentially, so that case has 1,200.
        for (params, bounded) in [
            (json!({"seed": 11, "levels": 3, "search": "kcoherence"}), 300),
            (json!({"seed": 12, "levels": 3, "search": "exhaustive"}), 300),
            (
                json!({"seed": 13, "levels": 4, "search": "kcoherence", "domain": "torus", "width": 64, "height": 64}),
                1200,
            ),
            (json!({"seed": 14, "levels": 3, "search": "exhaustive", "subpasses": 4, "generations": 4}), 300),
        ] {
            let mut p: Params = serde_json::from_value(params.clone()).unwrap();
            p.generation0 = Some(p.generation0());
            let syn = Synthesizer::new(&p, &sample).unwrap();
            let st = syn.structure().clone();
            let fin = st.finest();
            for i in 0..2u64 {
                let h = hash4(21, i, 0, 0);
                let rect = Rect { x: (h as i64) >> 44, y: (h.rotate_left(32) as i64) >> 44, w: 6 + i as usize, h: 5 };
                let s = fin - i as u8;
                let served = evaluate(&syn, &st, None, s, rect, &mut Counts::default(), &crate::Never).unwrap();
                let mut computed = Vec::new();
                for capacity in [UNBOUNDED, bounded] {
                    let mut pixels: Vec<(usize, i64, i64)> = (0..rect.w * rect.h)
                        .map(|k| (k, rect.x + (k % rect.w) as i64, rect.y + (k / rect.w) as i64))
                        .collect();
                    pixels.sort_by_key(|&(_, x, y)| hash4(22, capacity as u64, x, y));
                    let mut r = Reference::new(st.clone(), &syn, capacity);
                    for (k, x, y) in pixels {
                        assert_eq!(r.request(s, x, y), served[k], "{params}: ({s}, {x}, {y}), capacity {capacity}");
                    }
                    computed.push(r.counters().computed);
                }
                assert!(computed[0] < computed[1], "the bounded cache evicts: {computed:?}");
            }
        }
    }
}
