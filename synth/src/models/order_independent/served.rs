//! The served evaluator: the entries of one rectangle of one level, computed as dense arrays.
//!
//! Top-down, each (level, generation) gets the rectangle its readers need (the cone of a
//! rectangle is a rectangle). With a pyramidal cache, needed pixels found there are loaded and
//! the rest marked *to compute*, whose reads alone are needed one step down, so only the true
//! cone of the misses is computed. Bottom-up, every entry to compute is handed to the same
//! per-entry function as the reference recursion ([`Synthesis::entry`]), with the values it
//! reads gathered from the arrays below, so both evaluators agree on every entry.

use super::cache::Pyramid;
use super::rect::Rect;
use super::structure::{Entry, Structure, Synthesis};
use crate::Stop;

/// Side of the chunks a large region is evaluated in, in pixels of the evaluated level:
/// bounds the memory of one call (about 2 bytes an entry over the chunk's cone).
pub const CHUNK: u32 = 256;

/// Entries computed by one evaluation.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Counts {
    /// Entries searched or upsampled (copies of a subpass's untouched pixels excluded).
    pub computed: u64,
    /// Noise entries drawn.
    pub noise: u64,
}

/// One (level, generation) of an evaluation: its rectangle, values, and which are to compute
/// (`None`: all of them).
struct Layer {
    rect: Rect,
    values: Vec<u16>,
    compute: Option<Vec<bool>>,
}

/// The latest generation of level `s` over `rect`, or `None` once `stop` is requested.
pub fn evaluate<S: Synthesis>(
    syn: &S,
    st: &Structure,
    cache: Option<&Pyramid>,
    s: u8,
    rect: Rect,
    counts: &mut Counts,
    stop: &dyn Stop,
) -> Option<Vec<u16>> {
    evaluate_generation(syn, st, cache, s, st.last(s), rect, counts, stop)
}

/// Generation `m` of level `s` over `rect` (the later generations of `s` are not computed),
/// or `None` once `stop` is requested.
#[allow(clippy::too_many_arguments)]
pub fn evaluate_generation<S: Synthesis>(
    syn: &S,
    st: &Structure,
    cache: Option<&Pyramid>,
    s: u8,
    m: u8,
    rect: Rect,
    counts: &mut Counts,
    stop: &dyn Stop,
) -> Option<Vec<u16>> {
    let mut layers: Vec<Vec<Layer>> = cone_to(st, s, m, rect)
        .into_iter()
        .map(|gens| gens.into_iter().map(|rect| Layer { rect, values: vec![0; rect.area()], compute: None }).collect())
        .collect();
    if let Some(cache) = cache {
        prune(st, cache, &mut layers);
    }
    for l in 0..=s {
        for m in 0..layers[l as usize].len() as u8 {
            compute(syn, st, &mut layers, l, m, counts, stop)?;
            if let Some(cache) = cache {
                let layer = &layers[l as usize][m as usize];
                cache.store(st, l, m, &layer.rect, layer.compute.as_deref(), &layer.values);
            }
        }
    }
    Some(std::mem::take(&mut layers[s as usize][m as usize].values))
}

/// The rectangle of every (level, generation) the latest generation of `s` over `rect` reads,
/// indexed [level][generation].
pub fn cone(st: &Structure, s: u8, rect: Rect) -> Vec<Vec<Rect>> {
    cone_to(st, s, st.last(s), rect)
}

/// The rectangle of every (level, generation) generation `last` of `s` over `rect` reads,
/// indexed [level][generation]; level `s` ends at generation `last`.
pub fn cone_to(st: &Structure, s: u8, last: u8, rect: Rect) -> Vec<Vec<Rect>> {
    let gens = |l: u8| if l == s { last + 1 } else { st.generations_of(l) };
    let mut rects: Vec<Vec<Rect>> = (0..=s).map(|l| vec![rect; gens(l) as usize]).collect();
    let mut top = rect;
    for l in (0..=s).rev() {
        let g = gens(l) as usize;
        rects[l as usize][g - 1] = top;
        for m in (1..g).rev() {
            let same = if l == 0 { &st.coarsest_same } else { &st.same };
            rects[l as usize][m - 1] = rects[l as usize][m].reach(same);
        }
        if l > 0 {
            let lower = |m: usize| if m == 0 { &st.generation0_lower } else { &st.lower };
            top = (0..g).map(|m| rects[l as usize][m].parent().reach(lower(m))).reduce(|a, b| a.union(&b)).unwrap();
        }
    }
    rects
}

/// Loads cached entries and narrows what is to compute to the cone of the misses.
fn prune(st: &Structure, cache: &Pyramid, layers: &mut [Vec<Layer>]) {
    // The request is needed whole; every other need is set by the entries that read it.
    let mut need: Vec<Vec<Vec<bool>>> =
        layers.iter().map(|gens| gens.iter().map(|g| vec![false; g.rect.area()]).collect()).collect();
    need.last_mut().unwrap().last_mut().unwrap().fill(true);
    for l in (0..layers.len()).rev() {
        for m in (0..layers[l].len()).rev() {
            let (s, g) = (l as u8, m as u8);
            let mut miss = std::mem::take(&mut need[l][m]);
            let rect = layers[l][m].rect;
            cache.load(st, s, g, &rect, &mut miss, &mut layers[l][m].values);
            if !st.is_noise(s, g) {
                for (i, _) in miss.iter().enumerate().filter(|(_, &c)| c) {
                    let (x, y) = (rect.x.wrapping_add((i % rect.w) as i64), rect.y.wrapping_add((i / rect.w) as i64));
                    let reads = st.reads(s, g, x, y);
                    if g > 0 {
                        let r = layers[l][m - 1].rect;
                        for &(dx, dy) in reads.same {
                            need[l][m - 1][r.at(x.wrapping_add(dx as i64), y.wrapping_add(dy as i64))] = true;
                        }
                    }
                    if l > 0 && !reads.lower.is_empty() {
                        let c = st.last(s - 1) as usize;
                        let r = layers[l - 1][c].rect;
                        let (px, py) = (x >> 1, y >> 1);
                        for &(dx, dy) in reads.lower {
                            need[l - 1][c][r.at(px.wrapping_add(dx as i64), py.wrapping_add(dy as i64))] = true;
                        }
                    }
                }
            }
            layers[l][m].compute = Some(miss);
        }
    }
}

/// Computes the entries of (l, m) that are to compute, reading the layers below.
fn compute<S: Synthesis>(
    syn: &S,
    st: &Structure,
    layers: &mut [Vec<Layer>],
    l: u8,
    m: u8,
    counts: &mut Counts,
    stop: &dyn Stop,
) -> Option<()> {
    let (below, here) = layers.split_at_mut(l as usize);
    let (earlier, rest) = here[0].split_at_mut(m as usize);
    let layer = &mut rest[0];
    let rect = layer.rect;
    let prev = earlier.last();
    let coarser = (l > 0).then(|| &below[l as usize - 1][st.last(l - 1) as usize]);
    let mut same = Vec::with_capacity(32);
    let mut lower = Vec::with_capacity(32);
    // Reads are indexed from the pixel's (or its parent's) index in the rectangle below.
    let offset = |r: &Rect, x: i64, y: i64| (y.wrapping_sub(r.y) * r.w as i64 + x.wrapping_sub(r.x)) as isize;
    for j in 0..rect.h {
        if stop.requested() {
            return None;
        }
        let y = rect.y.wrapping_add(j as i64);
        for i in 0..rect.w {
            let at = j * rect.w + i;
            if layer.compute.as_ref().is_some_and(|c| !c[at]) {
                continue;
            }
            let x = rect.x.wrapping_add(i as i64);
            if st.is_noise(l, m) {
                layer.values[at] = syn.noise(x, y);
                counts.noise += 1;
                continue;
            }
            let reads = st.reads(l, m, x, y);
            same.clear();
            if let Some(p) = prev {
                let base = offset(&p.rect, x, y);
                let pw = p.rect.w as isize;
                same.extend(
                    reads.same.iter().map(|&(dx, dy)| p.values[(base + dy as isize * pw + dx as isize) as usize]),
                );
            }
            lower.clear();
            if let Some(c) = coarser {
                let base = offset(&c.rect, x >> 1, y >> 1);
                let cw = c.rect.w as isize;
                lower.extend(
                    reads.lower.iter().map(|&(dx, dy)| c.values[(base + dy as isize * cw + dx as isize) as usize]),
                );
            }
            layer.values[at] = syn.entry(Entry { s: l, m, x, y }, &same, &lower);
            if m == 0 || st.updates(m, x, y) {
                counts.computed += 1;
            }
        }
    }
    Some(())
}

#[cfg(test)]
mod tests {
    use super::super::params::Params;
    use super::super::search::Synthesizer;
    use super::*;
    use crate::hash::hash4;
    use crate::Never;
    use serde_json::json;
    use std::collections::HashMap;

    /// The paper's recursion, literally: an entry from the entries it reads, memoised.
    fn recurse(syn: &Synthesizer, e: Entry, memo: &mut HashMap<Entry, u16>) -> u16 {
        let st = syn.structure();
        let e = st.canonical(e);
        if let Some(&v) = memo.get(&e) {
            return v;
        }
        let v = if st.is_noise(e.s, e.m) {
            syn.noise(e.x, e.y)
        } else {
            let mut deps = Vec::new();
            st.dependencies(e, &mut deps);
            let n = st.reads(e.s, e.m, e.x, e.y).same.len();
            let values: Vec<u16> = deps.iter().map(|&d| recurse(syn, d, memo)).collect();
            syn.entry(e, &values[..n], &values[n..])
        };
        memo.insert(e, v);
        v
    }

    pub(crate) fn synthesizer(params: serde_json::Value, sample: &crate::Rgba8Image) -> Synthesizer {
        let mut p: Params = serde_json::from_value(params).unwrap();
        p.generation0 = Some(p.generation0());
        Synthesizer::new(&p, sample).unwrap()
    }

    #[test]
    fn the_dense_evaluator_computes_what_the_recursion_does() {
        let sample = crate::samples::pebbles(32, 6, 4, false);
        for params in [
            json!({"seed": 1, "levels": 3}),
            json!({"seed": 2, "levels": 3, "search": "exhaustive"}),
            json!({"seed": 3, "levels": 3, "k": 3, "subpasses": 4, "generations": 4, "coarsest_generations": 2, "jitter": 2}),
            json!({"seed": 4, "levels": 3, "domain": "torus", "width": 24, "height": 40, "exemplar_wrap": true, "jitter": 1}),
            json!({"seed": 7, "levels": 4, "k": 2, "k_exclusion": 3, "jitter": 4, "kappa": 50}),
            json!({"seed": 5, "levels": 2, "neighbourhood": {"same": "square5", "lower": "square5"}, "generation0": "search"}),
            json!({"seed": 6, "levels": 3, "neighbourhood": {"same": "square3"}, "search": "exhaustive", "generation0": "upsample", "k_exclusion": 2}),
            json!({"seed": 8, "levels": 3, "exemplar": "stack", "jitter": 1, "kappa": 100, "balance": 1}),
            json!({"seed": 9, "levels": 3, "exemplar": "stack", "domain": "torus", "width": 24, "height": 40, "exemplar_wrap": true, "jitter": 2, "balance": 2, "subpasses": 1}),
        ] {
            let syn = synthesizer(params.clone(), &sample);
            let st = syn.structure();
            let fin = st.finest();
            let mut memo = HashMap::new();
            for i in 0..3 {
                let h = hash4(9, 9, i, 0);
                let rect =
                    Rect { x: (h as i64) >> 40, y: (h.rotate_left(20) as i64) >> 40, w: 5 + i as usize * 3, h: 7 };
                for s in [fin, fin - 1] {
                    let mut counts = Counts::default();
                    let dense = evaluate(&syn, st, None, s, rect, &mut counts, &Never).unwrap();
                    for (k, &v) in dense.iter().enumerate() {
                        let (x, y) = (rect.x + (k % rect.w) as i64, rect.y + (k / rect.w) as i64);
                        assert_eq!(v, recurse(&syn, st.output(s, x, y), &mut memo), "{params}: ({s}, {x}, {y})");
                    }
                }
                // An earlier generation, as the coarse vtex levels read it.
                for m in 0..st.last(fin) {
                    let dense = evaluate_generation(&syn, st, None, fin, m, rect, &mut Counts::default(), &Never);
                    for (k, &v) in dense.unwrap().iter().enumerate() {
                        let (x, y) = (rect.x + (k % rect.w) as i64, rect.y + (k / rect.w) as i64);
                        let e = st.canonical(Entry { s: fin, m, x, y });
                        assert_eq!(v, recurse(&syn, e, &mut memo), "{params}: ({fin}, {m}, {x}, {y})");
                    }
                }
            }
        }
    }
}
