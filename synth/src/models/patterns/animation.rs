//! Animation Sequence, Animation Map and Temporal Transitions (§3.4). Time t is the request's
//! frame; the state of a cell is a pure function of (t, φ(g), Z(g), a) — no state variables.

use super::maps::Map;
use super::params::{AnimationParams, ValueParams};
use super::random::LayerRng;
use super::sigma::Role;
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
            rng.table(role).check_range(&format!("{what}.random"), v.random)?;
        }
        Ok(Self { map, random: v.random, role })
    }

    #[inline]
    pub fn at(&self, rng: &LayerRng, gx: u64, gy: u64) -> u32 {
        let m = self.map.as_ref().map_or(0, |m| m.at(gx as i64, gy as i64) as u32);
        let r = if self.random > 0 { rng.below(self.role, gx, gy, self.random) } else { 0 };
        m + r
    }

    /// Every value this can take, for the period of the animation (None when unbounded).
    fn values(&self) -> Vec<u32> {
        let base: Vec<u32> = match &self.map {
            Some(m) => {
                let mut v: Vec<u32> = m.values.iter().map(|&x| x as u32).collect();
                v.sort_unstable();
                v.dedup();
                v
            }
            None => vec![0],
        };
        base.iter().flat_map(|&b| (0..self.random.max(1)).map(move |r| b + r)).collect()
    }
}

pub struct AnimationBlock {
    pub sequence: Vec<u32>,
    a: f64,
    phi: Value,
    z: Value,
    previous: Option<(f64, Value, u32)>,
}

impl AnimationBlock {
    pub fn load(p: &AnimationParams, bundle: &Bundle, rng: &LayerRng, grid: (u64, u64), patterns: u32) -> Result<Self> {
        if p.sequence.is_empty() || p.sequence.len() > 4096 {
            return Err(Error::param("animation.sequence", "1 to 4096 patterns"));
        }
        if let Some(q) = p.sequence.iter().find(|&&q| q >= patterns) {
            return Err(Error::param(
                "animation.sequence",
                format!("pattern {q} is missing: the reference holds 0..{patterns}"),
            ));
        }
        let check_a = |what: &str, a: f64| {
            if !(0.0..=1e6).contains(&a) {
                return Err(Error::param(what, format!("{a}: must be in 0..=1e6")));
            }
            Ok(())
        };
        check_a("animation.a", p.a)?;
        let phi = Value::load("animation.phi", &p.phi, bundle, rng, grid, Role::Phase)?;
        let z = Value::load("animation.z", &p.z, bundle, rng, grid, Role::Rest)?;
        let previous = match &p.previous {
            Some(q) => {
                check_a("animation.previous.a", q.a)?;
                Some((q.a, Value::load("animation.previous.z", &q.z, bundle, rng, grid, Role::Rest)?, q.t0))
            }
            None => None,
        };
        Ok(Self { sequence: p.sequence.clone(), a: p.a, phi, z, previous })
    }

    /// The pattern cell g shows at frame t.
    #[inline]
    pub fn pattern(&self, rng: &LayerRng, gx: u64, gy: u64, t: u32) -> u32 {
        let n = self.sequence.len() as i64;
        let phi = self.phi.at(rng, gx, gy) as i64;
        let new = rest(self.a, self.z.at(rng, gx, gy));
        let p = match &self.previous {
            None => frame(t as i64, phi, n, new),
            Some((a_old, z_old, t0)) => {
                transition_frame(t as i64, phi, n, rest(*a_old, z_old.at(rng, gx, gy)), new, *t0 as i64)
            }
        };
        self.sequence[p as usize]
    }

    /// Frames after which every cell repeats: lcm of all cycle lengths n + ⌊aZ⌋; 0 when a
    /// temporal transition makes the animation aperiodic or the lcm exceeds u32.
    pub fn period(&self) -> u32 {
        if self.previous.is_some() {
            return 0;
        }
        let n = self.sequence.len() as u64;
        let mut l = 1u64;
        for z in self.z.values() {
            let c = n + rest(self.a, z) as u64;
            l = l / gcd(l, c) * c;
            if l > u32::MAX as u64 {
                return 0;
            }
        }
        l as u32
    }
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}
