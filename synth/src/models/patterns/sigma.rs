//! Permutation tables σ: the Virtual Indirection Map and the Virtual Random Map (§3.2),
//! vectorial in 2D (§3.5).
//!
//! A table is a bijection of the `tx × ty` vector indices. A cell g = (gx, gy) is hashed like
//! Perlin's σ(x + σ(y)) but along the base-T digits of g: s₀ = σ(g mod T),
//! sᵢ = σ(⌊g / Tⁱ⌋ + sᵢ₋₁) (componentwise, mod T), for as many steps k as T^k covers the grid:
//! σ(g/T² + σ(g/T + σ(g))) for k = 3. Within the grid no two cells share all digits, so the
//! choice is aperiodic. Tables are generated once from a seed and stored in the encoding.

use crate::{hash, Error, Result};

/// Which stored table a random parameter uses. Distinct tables give uncorrelated values.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Role {
    /// The vectorial table over the reference texture's `Tx × Ty` patterns.
    Pattern = 0,
    /// Index into a probability map.
    Choice,
    DitherX,
    DitherY,
    OffsetX,
    OffsetY,
    Scale,
    Rotation,
    Phase,
    Rest,
}

/// Number of stored tables ([`Role`] count).
pub const TABLES: usize = 10;
/// Side of the random tables: 16 × 16 = 256 entries, the paper's σ size (§4), so random
/// numbers have a resolution of 1/256 and any power-of-two range up to 256 is unbiased.
pub const RANDOM_SIDE: u32 = 16;
pub const RANDOM_SIZE: u32 = RANDOM_SIDE * RANDOM_SIDE;

#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Sigma {
    pub tx: u32,
    pub ty: u32,
    /// Entry (x, y) at index y·tx + x holds the permuted vector (σx, σy).
    table: Vec<[u8; 2]>,
}

impl Sigma {
    /// A uniformly random bijection of the `tx × ty` vectors (Fisher–Yates on a counter hash).
    pub fn generate(tx: u32, ty: u32, seed: u64, stream: u64) -> Self {
        let n = (tx * ty) as usize;
        let mut cells: Vec<[u8; 2]> = (0..n).map(|i| [(i as u32 % tx) as u8, (i as u32 / tx) as u8]).collect();
        for i in (1..n).rev() {
            let j = hash::below(hash::hash4(seed, 0x5167_0000 + stream, i as i64, 0), i as u64 + 1) as usize;
            cells.swap(i, j);
        }
        Self { tx, ty, table: cells }
    }

    #[allow(clippy::len_without_is_empty)] // a table always has entries
    pub fn len(&self) -> u32 {
        self.tx * self.ty
    }

    /// Smallest number of hashing steps k with tx^k ≥ nx and ty^k ≥ ny, or `None` when an
    /// axis of the table has one entry and so cannot tell cells of that axis apart.
    pub fn steps_for(&self, nx: u64, ny: u64) -> Option<u32> {
        let covers =
            |t: u32, n: u64, k: u32| n <= 1 || (t > 1 && (t as u128).checked_pow(k).is_none_or(|p| p >= n as u128));
        (1..=64).find(|&k| covers(self.tx, nx, k) && covers(self.ty, ny, k))
    }

    /// The hashed vector index of cell (gx, gy) after `steps` steps.
    #[inline]
    pub fn hash(&self, mut gx: u64, mut gy: u64, steps: u32) -> (u32, u32) {
        let (tx, ty) = (self.tx as u64, self.ty as u64);
        let (mut sx, mut sy) = (0u64, 0u64);
        if tx.is_power_of_two() && ty.is_power_of_two() {
            // The same digits by masks and shifts: a division by a table side is most of a
            // step's work otherwise.
            let (bx, by) = (tx.trailing_zeros(), ty.trailing_zeros());
            let (mx, my) = (tx - 1, ty - 1);
            for _ in 0..steps {
                let ix = ((gx & mx) + sx) & mx;
                let iy = ((gy & my) + sy) & my;
                let e = self.table[((iy << bx) | ix) as usize];
                sx = e[0] as u64;
                sy = e[1] as u64;
                gx >>= bx;
                gy >>= by;
            }
            return (sx as u32, sy as u32);
        }
        for _ in 0..steps {
            let ix = (gx % tx + sx) % tx;
            let iy = (gy % ty + sy) % ty;
            let e = self.table[(iy * tx + ix) as usize];
            sx = e[0] as u64;
            sy = e[1] as u64;
            gx /= tx;
            gy /= ty;
        }
        (sx as u32, sy as u32)
    }

    /// The hash as a scalar in `0..len()` (row-major in the table).
    #[inline]
    pub fn index(&self, gx: u64, gy: u64, steps: u32) -> u32 {
        let (x, y) = self.hash(gx, gy, steps);
        y * self.tx + x
    }

    /// A random number r / T in [0, 1) with resolution 1 / len().
    #[inline]
    pub fn unit(&self, gx: u64, gy: u64, steps: u32) -> f32 {
        self.index(gx, gy, steps) as f32 / self.len() as f32
    }

    /// A uniform integer in `0..m`; `m` must divide `len()` (checked at load) or the
    /// quantisation of r / T would bias it (Fig. 2.2).
    #[inline]
    pub fn below(&self, gx: u64, gy: u64, steps: u32, m: u32) -> u32 {
        (self.index(gx, gy, steps) as u64 * m as u64 / self.len() as u64) as u32
    }
}

/// Serialises tables: u8 count, then per table u16 tx, u16 ty (LE) and tx·ty (σx, σy) bytes.
pub fn to_bytes(tables: &[Sigma]) -> Vec<u8> {
    let mut out = vec![tables.len() as u8];
    for t in tables {
        out.extend_from_slice(&(t.tx as u16).to_le_bytes());
        out.extend_from_slice(&(t.ty as u16).to_le_bytes());
        for e in &t.table {
            out.extend_from_slice(e);
        }
    }
    out
}

/// Parses and checks the `sigma` section: exactly [`TABLES`] tables, each a bijection.
pub fn from_bytes(bytes: &[u8]) -> Result<Vec<Sigma>> {
    let bad = |m: String| Error::bundle(format!("section `sigma`: {m}"));
    let (&count, mut rest) = bytes.split_first().ok_or_else(|| bad("empty".into()))?;
    if count as usize != TABLES {
        return Err(bad(format!("{count} tables; expected {TABLES}")));
    }
    let mut tables = Vec::with_capacity(TABLES);
    for i in 0..TABLES {
        if rest.len() < 4 {
            return Err(bad(format!("table {i} truncated")));
        }
        let tx = u16::from_le_bytes([rest[0], rest[1]]) as u32;
        let ty = u16::from_le_bytes([rest[2], rest[3]]) as u32;
        if !(1..=256).contains(&tx) || !(1..=256).contains(&ty) {
            return Err(bad(format!("table {i} is {tx}×{ty}; each side must be 1..=256")));
        }
        let n = (tx * ty) as usize;
        rest = &rest[4..];
        if rest.len() < 2 * n {
            return Err(bad(format!("table {i} truncated")));
        }
        let mut seen = vec![false; n];
        let mut table = Vec::with_capacity(n);
        for e in rest[..2 * n].chunks_exact(2) {
            let (x, y) = (e[0] as u32, e[1] as u32);
            if x >= tx || y >= ty || std::mem::replace(&mut seen[(y * tx + x) as usize], true) {
                return Err(bad(format!("table {i} is not a permutation of its {tx}×{ty} indices")));
            }
            table.push([e[0], e[1]]);
        }
        rest = &rest[2 * n..];
        tables.push(Sigma { tx, ty, table });
    }
    if !rest.is_empty() {
        return Err(bad(format!("{} unexpected bytes", rest.len())));
    }
    if tables[1..].iter().any(|t| t.len() != RANDOM_SIZE) {
        return Err(bad(format!("random tables must hold {RANDOM_SIZE} entries")));
    }
    Ok(tables)
}

/// The tables of a new encoding: the pattern table over the reference, then the random ones.
pub fn generate_all(tx: u32, ty: u32, seed: u64) -> Vec<Sigma> {
    let mut v = vec![Sigma::generate(tx, ty, seed, 0)];
    v.extend((1..TABLES as u64).map(|i| Sigma::generate(RANDOM_SIDE, RANDOM_SIDE, seed, i)));
    v
}

/// Largest range a [`RangeTable`] draws from (a probability map's size, a random φ or Z).
pub const MAX_RANGE: u32 = 4096;
/// The bundle section holding the range tables, present when some range needs one.
pub const RANGES_SECTION: &str = "sigma-ranges";

/// A permutation σ of 0..m, for ranges m that do not divide the random tables' size: "it is
/// better to use a permutation table σ adapted to the T' range" (§3.2, Fig. 2.2), so a
/// probability map of any size is indexed without bias.
#[derive(Clone, Debug)]
pub struct RangeTable {
    table: Vec<u16>,
}

impl RangeTable {
    /// A uniformly random permutation of 0..m (Fisher–Yates on a counter hash).
    pub fn generate(m: u32, seed: u64) -> Self {
        let mut table: Vec<u16> = (0..m as u16).collect();
        for i in (1..m as usize).rev() {
            let j = hash::below(hash::hash4(seed, 0x5261_0000 + m as u64, i as i64, 0), i as u64 + 1) as usize;
            table.swap(i, j);
        }
        Self { table }
    }

    pub fn range(&self) -> u32 {
        self.table.len() as u32
    }

    /// Digits of base m needed to cover `n` cells per axis.
    pub fn steps_for(&self, n: u64) -> u32 {
        let m = self.range() as u128;
        (1..=64).find(|&k| m.checked_pow(k).is_none_or(|p| p >= n as u128)).unwrap_or(64)
    }

    /// The σ series of the Virtual Indirection Map in base m, the 2D digits folded as
    /// σ(x + σ(y + s)) (Perlin's way): sᵢ = σ(xᵢ + σ(yᵢ + sᵢ₋₁)) over the `steps` digits of g,
    /// starting from s₋₁ = `stream` so the parameters sharing the table differ. Every step is
    /// a bijection of xᵢ, so each aligned run of m cells takes every value once.
    #[inline]
    pub fn below(&self, mut gx: u64, mut gy: u64, stream: u64, steps: u32) -> u32 {
        let m = self.table.len() as u64;
        let mut s = stream % m;
        for _ in 0..steps {
            let inner = self.table[((gy % m + s) % m) as usize] as u64;
            s = self.table[((gx % m + inner) % m) as usize] as u64;
            gx /= m;
            gy /= m;
        }
        s as u32
    }
}

/// The range tables stored in `bundle` (none when it has no `sigma-ranges` section).
pub fn ranges_of(bundle: &crate::bundle::Bundle) -> Result<std::sync::Arc<[RangeTable]>> {
    match bundle.sections.iter().find(|s| s.name == RANGES_SECTION) {
        Some(s) => Ok(ranges_from_bytes(&s.data)?.into()),
        None => Ok(std::sync::Arc::from([])),
    }
}

/// Whether drawing from `m` values needs a range table (m does not divide the random tables).
pub fn needs_range_table(m: u32) -> bool {
    m > 0 && RANDOM_SIZE % m != 0
}

/// Serialises range tables: u16 count, then per table u16 m and m u16 entries (LE).
pub fn ranges_to_bytes(tables: &[RangeTable]) -> Vec<u8> {
    let mut out = (tables.len() as u16).to_le_bytes().to_vec();
    for t in tables {
        out.extend_from_slice(&(t.range() as u16).to_le_bytes());
        for &e in &t.table {
            out.extend_from_slice(&e.to_le_bytes());
        }
    }
    out
}

/// Parses and checks the range tables: each a permutation of 0..m, 2 ≤ m ≤ [`MAX_RANGE`].
pub fn ranges_from_bytes(bytes: &[u8]) -> Result<Vec<RangeTable>> {
    let bad = |m: String| Error::bundle(format!("section `{RANGES_SECTION}`: {m}"));
    let u16_at = |b: &[u8], i: usize| b.get(i..i + 2).map(|c| u16::from_le_bytes([c[0], c[1]]) as usize);
    let count = u16_at(bytes, 0).ok_or_else(|| bad("truncated".into()))?;
    let mut at = 2;
    let mut tables = Vec::with_capacity(count.min(64));
    for i in 0..count {
        let m = u16_at(bytes, at).ok_or_else(|| bad(format!("table {i} truncated")))?;
        if !(2..=MAX_RANGE as usize).contains(&m) {
            return Err(bad(format!("table {i} has {m} entries; 2..={MAX_RANGE}")));
        }
        at += 2;
        let mut seen = vec![false; m];
        let mut table = Vec::with_capacity(m);
        for k in 0..m {
            let e = u16_at(bytes, at + 2 * k).ok_or_else(|| bad(format!("table {i} truncated")))?;
            if e >= m || std::mem::replace(&mut seen[e], true) {
                return Err(bad(format!("table {i} is not a permutation of 0..{m}")));
            }
            table.push(e as u16);
        }
        at += 2 * m;
        tables.push(RangeTable { table });
    }
    if at != bytes.len() {
        return Err(bad(format!("{} unexpected bytes", bytes.len().saturating_sub(at))));
    }
    Ok(tables)
}
