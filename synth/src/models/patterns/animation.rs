//! Animation Sequence, Animation Map and Temporal Transitions (§3.4). Time t is the request's
//! frame; the state of a cell is a pure function of (t, φ(g), Z(g), a) — no state variables.
//! A cell may pick one of several animated patterns (Fig. 20), the (a, Z) may change several
//! times (each change a temporal transition), and the sequence parameter may be the distance
//! to moving target sprites instead of time (Fig. 21a).

use super::maps::Map;
use super::params::{AnimationParams, DistanceParams, Params, ValueParams};
use super::random::LayerRng;
use super::sigma::Role;
use super::sprites::Motion;
use crate::{bundle::Bundle, Error, Result};

/// p = max(0, (t + φ) mod (n + R) − R) with R = ⌊a Z⌋ rest frames: the sequence frame shown.
#[inline]
pub fn frame(t: i64, phi: i64, n: i64, rest: i64) -> i64 {
    ((t + phi).rem_euclid(n + rest) - rest).max(0)
}

/// The rest length ⌊a Z⌋ in frames.
#[inline]
pub fn rest(a: f64, z: u32) -> i64 {
    (a * z as f64).floor() as i64
}

/// The frame during a temporal transition at `t0` from rest length `old` to `new` (§3.4,
/// Fig. 13): the old cycle runs to its end t_f, then the new one starts only from rest —
/// if it is mid-cycle at t_f, the cell rests until that cycle's theoretical end t_end.
pub fn transition_frame(t: i64, phi: i64, n: i64, old: i64, new: i64, t0: i64) -> i64 {
    let p_old_t0 = frame(t0, phi, n, old);
    let t_f = if p_old_t0 == 0 { t0 - 1 } else { t0 + n - p_old_t0 };
    if t <= t_f {
        return frame(t, phi, n, old);
    }
    let p_new_tf = frame(t_f, phi, n, new);
    if p_new_tf == 0 {
        return frame(t, phi, n, new);
    }
    let t_end = t_f + n - p_new_tf;
    if t < t_end {
        0
    } else {
        frame(t, phi, n, new)
    }
}

/// A per-cell integer: explicit map value plus a virtual random value.
pub struct Value {
    map: Option<Map>,
    random: u32,
    role: Role,
}

impl Value {
    fn load(
        what: &str,
        v: &ValueParams,
        bundle: &Bundle,
        rng: &LayerRng,
        grid: (u64, u64),
        role: Role,
    ) -> Result<Self> {
        let map =
            v.map.as_ref().map(|m| Map::load(what, m, bundle, grid, u16::MAX as u32, Some(u16::MAX))).transpose()?;
        if v.random > 0 {
            rng.check_range(&format!("{what}.random"), v.random)?;
        }
        Ok(Self { map, random: v.random, role })
    }

    #[inline]
    pub fn at(&self, rng: &LayerRng, gx: u64, gy: u64) -> u32 {
        let m = self.map.as_ref().map_or(0, |m| m.at(gx as i64, gy as i64) as u32);
        let r = if self.random > 0 { rng.below(self.role, gx, gy, self.random) } else { 0 };
        m + r
    }

    /// How many values this can take at most: distinct map values × the random range.
    fn count(&self) -> u64 {
        let distinct = self.map.as_ref().map_or(1, |m| distinct(m.values.iter().map(|&x| x as u32)).len() as u64);
        distinct * self.random.max(1) as u64
    }

    /// Every value this can take, for the period of the animation.
    fn values(&self) -> Vec<u32> {
        let base: Vec<u32> = match &self.map {
            Some(m) => distinct(m.values.iter().map(|&x| x as u32)),
            None => vec![0],
        };
        base.iter().flat_map(|&b| (0..self.random.max(1)).map(move |r| b + r)).collect()
    }
}

/// Most Z values a period is computed over; beyond, the animation is taken as aperiodic.
const MAX_PERIOD_VALUES: u64 = 1 << 16;

/// Most targets a distance-driven sequence measures.
pub const MAX_TARGETS: usize = 64;

/// What advances the sequence of a cell.
enum Drive {
    /// Time: φ, and the (a, Z) of each period of the schedule — the current one last — with
    /// the frames `t0s` at which each earlier one gave way to the next.
    Time { phi: Value, segments: Vec<(f64, Value)>, t0s: Vec<i64> },
    /// The distance from the cell's centre to the nearest target sprite.
    Distance { targets: Vec<Motion>, radius: f64, cell: f64, texture: (u64, u64), size: u32 },
}

pub struct AnimationBlock {
    /// The animated patterns (`None` = blank); one is chosen per cell.
    sequences: Vec<Vec<Option<u32>>>,
    /// Probability map over `sequences`; uniform when empty.
    probabilities: Vec<u32>,
    drive: Drive,
}

/// What an animation block reads besides its parameters.
pub struct Context<'a> {
    pub params: &'a Params,
    pub bundle: &'a Bundle,
    pub cell: u32,
    pub grid: (u64, u64),
    pub patterns: u32,
    /// Sparse layers may rest on a blank.
    pub allow_blank: bool,
}

impl AnimationBlock {
    pub fn load(p: &AnimationParams, cx: &Context, rng: &LayerRng) -> Result<Self> {
        let lists: Vec<&Vec<i32>> = match (p.sequence.is_empty(), p.sequences.is_empty()) {
            (false, true) => vec![&p.sequence],
            (true, false) => p.sequences.iter().collect(),
            _ => return Err(Error::param("animation", "give exactly one of `sequence` and `sequences`")),
        };
        if lists.len() > 256 {
            return Err(Error::param("animation.sequences", format!("{}: at most 256 sequences", lists.len())));
        }
        let mut sequences = Vec::with_capacity(lists.len());
        for (i, list) in lists.iter().enumerate() {
            let what = if p.sequences.is_empty() {
                "animation.sequence".to_string()
            } else {
                format!("animation.sequences[{i}]")
            };
            if list.is_empty() || list.len() > 4096 {
                return Err(Error::param(&what, "1 to 4096 patterns"));
            }
            let mut seq = Vec::with_capacity(list.len());
            for &q in list.iter() {
                seq.push(match q {
                    -1 if cx.allow_blank => None,
                    q if q >= 0 && (q as u32) < cx.patterns => Some(q as u32),
                    q => {
                        return Err(Error::param(
                            &what,
                            format!(
                                "pattern {q} is missing: the reference holds 0..{}{}",
                                cx.patterns,
                                if cx.allow_blank { " (-1 = blank)" } else { " and tiling layers cannot be blank" }
                            ),
                        ))
                    }
                });
            }
            sequences.push(seq);
        }
        if let Some(&q) = p.probabilities.iter().find(|&&q| q as usize >= sequences.len()) {
            return Err(Error::param(
                "animation.probabilities",
                format!("sequence {q} is missing: there are {}", sequences.len()),
            ));
        }
        let choices = if p.probabilities.is_empty() { sequences.len() } else { p.probabilities.len() };
        rng.check_range("animation.probabilities", choices as u32)?;
        let drive = match &p.distance {
            Some(d) => Self::distance(p, d, cx)?,
            None => Self::time(p, cx, rng, sequences.iter().map(Vec::len).max().unwrap_or(1))?,
        };
        Ok(Self { sequences, probabilities: p.probabilities.clone(), drive })
    }

    fn time(p: &AnimationParams, cx: &Context, rng: &LayerRng, n: usize) -> Result<Drive> {
        let check_a = |what: &str, a: f64| {
            if !(0.0..=1e6).contains(&a) {
                return Err(Error::param(what, format!("{a}: must be in 0..=1e6")));
            }
            Ok(())
        };
        let (bundle, grid) = (cx.bundle, cx.grid);
        let phi = Value::load("animation.phi", &p.phi, bundle, rng, grid, Role::Phase)?;
        let mut segments = Vec::new();
        let mut t0s: Vec<i64> = Vec::new();
        for (i, q) in p.schedule().iter().enumerate() {
            let what = format!("animation.previous[{i}]");
            check_a(&format!("{what}.a"), q.a)?;
            if let Some(&last) = t0s.last() {
                if (q.t0 as i64) < last + 2 * n as i64 {
                    return Err(Error::param(
                        format!("{what}.t0"),
                        format!(
                            "{} is less than 2n = {} frames after the previous transition at {last}: a set of                              parameters must be kept 2n frames so transitions never collide (§3.4)",
                            q.t0,
                            2 * n
                        ),
                    ));
                }
            }
            segments.push((q.a, Value::load(&format!("{what}.z"), &q.z, bundle, rng, grid, Role::Rest)?));
            t0s.push(q.t0 as i64);
        }
        check_a("animation.a", p.a)?;
        segments.push((p.a, Value::load("animation.z", &p.z, bundle, rng, grid, Role::Rest)?));
        Ok(Drive::Time { phi, segments, t0s })
    }

    fn distance(p: &AnimationParams, d: &DistanceParams, cx: &Context) -> Result<Drive> {
        if p.previous.is_some() {
            return Err(Error::param("animation.previous", "a distance-driven sequence has no temporal transitions"));
        }
        if !(d.radius > 0.0 && d.radius <= 1e9) {
            return Err(Error::param("animation.distance.radius", format!("{}: must be in (0, 1e9] pixels", d.radius)));
        }
        if d.targets.is_empty() || d.targets.len() > MAX_TARGETS {
            return Err(Error::param("animation.distance.targets", format!("1 to {MAX_TARGETS} sprite names")));
        }
        let targets =
            d.targets
                .iter()
                .map(|name| {
                    cx.params.sprites.get(name).map(Motion::of).ok_or_else(|| {
                        Error::param("animation.distance.targets", format!("`{name}` is not in `sprites`"))
                    })
                })
                .collect::<Result<Vec<_>>>()?;
        let texture = (cx.params.width, cx.params.height);
        Ok(Drive::Distance { targets, radius: d.radius, cell: cx.cell as f64, texture, size: cx.params.pattern_size })
    }

    /// The sequence cell g plays.
    #[inline]
    fn sequence(&self, rng: &LayerRng, gx: u64, gy: u64) -> &[Option<u32>] {
        let i = match (self.sequences.len(), self.probabilities.len()) {
            (1, _) => 0,
            (n, 0) => rng.below(Role::Choice, gx, gy, n as u32) as usize,
            (_, m) => self.probabilities[rng.below(Role::Choice, gx, gy, m as u32) as usize] as usize,
        };
        &self.sequences[i]
    }

    /// The pattern cell g shows at frame t (`None`: blank).
    #[inline]
    pub fn pattern(&self, rng: &LayerRng, gx: u64, gy: u64, t: u32) -> Option<u32> {
        let seq = self.sequence(rng, gx, gy);
        let n = seq.len() as i64;
        let p = match &self.drive {
            Drive::Time { phi, segments, t0s } => {
                let phi = phi.at(rng, gx, gy) as i64;
                let rest_of = |k: usize| rest(segments[k].0, segments[k].1.at(rng, gx, gy));
                let t = t as i64;
                match t0s.iter().rposition(|&t0| t0 <= t) {
                    None => frame(t, phi, n, rest_of(0)),
                    Some(k) => transition_frame(t, phi, n, rest_of(k), rest_of(k + 1), t0s[k]),
                }
            }
            Drive::Distance { targets, radius, cell, texture, size } => {
                let c = ((gx as f64 + 0.5) * cell, (gy as f64 + 0.5) * cell);
                let d = targets
                    .iter()
                    .map(|m| torus_distance(c, m.centre(t, *texture, *size), *texture))
                    .fold(f64::INFINITY, f64::min);
                if d >= *radius {
                    0
                } else {
                    ((n as f64 * (1.0 - d / radius)).floor() as i64).min(n - 1)
                }
            }
        };
        seq[p as usize]
    }

    /// Frames after which every cell repeats: lcm of all cycle lengths n + ⌊aZ⌋; 0 when
    /// temporal transitions make the animation aperiodic, the lcm exceeds u32 or Z takes more
    /// than [`MAX_PERIOD_VALUES`] values; `None` when
    /// the sequence follows target sprites (their motion gives the period).
    pub fn period(&self) -> Option<u64> {
        let Drive::Time { segments, t0s, .. } = &self.drive else { return None };
        if !t0s.is_empty() {
            return Some(0);
        }
        let (a, z) = &segments[0];
        if z.count() > MAX_PERIOD_VALUES {
            return Some(0);
        }
        let lengths = distinct(self.sequences.iter().map(|s| u32::try_from(s.len()).unwrap_or(u32::MAX)));
        let mut l = 1u64;
        for n in lengths {
            for &zv in &z.values() {
                let c = n as u64 + rest(*a, zv) as u64;
                l = l / gcd(l, c) * c;
                if l > u32::MAX as u64 {
                    return Some(0);
                }
            }
        }
        Some(l)
    }

    /// Every pattern some cell may show (for the expected colour of coarse levels).
    pub fn patterns(&self) -> impl Iterator<Item = Option<u32>> + '_ {
        self.sequences.iter().flatten().copied()
    }
}

/// Distance between two points of the torus `texture`.
fn torus_distance(a: (f64, f64), b: (f64, f64), texture: (u64, u64)) -> f64 {
    let d = |p: f64, q: f64, n: u64| {
        let d = (p - q).abs() % n as f64;
        d.min(n as f64 - d)
    };
    let (dx, dy) = (d(a.0, b.0, texture.0), d(a.1, b.1, texture.1));
    (dx * dx + dy * dy).sqrt()
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// The values `v` gives, sorted and each once (one sort of one type for the module: the
/// animation's values and lengths, the range tables).
pub(super) fn distinct(v: impl Iterator<Item = u32>) -> Vec<u32> {
    let mut v: Vec<u32> = v.collect();
    v.sort_unstable();
    v.dedup();
    v
}
