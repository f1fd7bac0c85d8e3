//! Box sums of the sample, extended periodically over the plane: prefix sums that give any
//! box in O(1), and tables of every box of a power-of-two side, built on first use, that give
//! a mip footprint's cell in one look-up. The prefiltered levels ([`prefilter`](super::prefilter))
//! integrate the sample with them.

use crate::pixels::Rgba8Image;
use std::sync::OnceLock;

/// The sample's pixels as little-endian `u32`s (RGBA8), the one copy a loaded mosaic keeps:
/// level 0 copies them a pixel at a time.
pub(super) struct Sample {
    pub(super) width: u32,
    pub(super) height: u32,
    pub(super) px: Vec<u32>,
}

impl Sample {
    pub(super) fn new(image: &Rgba8Image) -> Self {
        let px = image.data.chunks_exact(4).map(|p| u32::from_le_bytes(p.try_into().unwrap())).collect();
        Self { width: image.width, height: image.height, px }
    }

    pub(super) fn to_image(&self) -> Rgba8Image {
        Rgba8Image {
            width: self.width,
            height: self.height,
            data: self.px.iter().flat_map(|p| p.to_le_bytes()).collect(),
        }
    }
}

/// Side of the cells the prefix sums are split into: a sum within one cell (at most 15 × 15
/// pixels from its corner) fits 16 bits a channel.
const CELL: usize = 16;

/// Box sums of the sample extended periodically over the whole plane.
///
/// The prefix sum C(x, y) of sample[0..y][0..x] is kept as three terms, in 10 bytes a sample
/// pixel rather than the 16 of a plain table: with (X, Y) the corner of the 16 × 16 cell of
/// (x, y), C(x, y) = C(x, Y) + sum of [0, X) × [Y, y) + sum of [X, x) × [Y, y), the first two
/// in 32 bits a channel once every 16 rows or columns, the last in 16 bits a pixel. Every term
/// and C itself fit 32 bits for samples up to 4096² (4096² · 255 < 2^32).
pub(super) struct PeriodicSums {
    /// The sample's width and height, as periods that split a coordinate.
    pub(super) w: Period,
    pub(super) h: Period,
    /// C(x, Y) for each cell row Y = 16j: (w + 1) entries a cell row.
    above: Vec<[u32; 4]>,
    /// The sum of [0, X) × [Y, y) for each row y and cell column X = 16i: (w / 16 + 1) entries a row.
    left: Vec<[u32; 4]>,
    /// The sum of [X, x) × [Y, y): (w + 1) × (h + 1) entries.
    within: Vec<[u16; 4]>,
    /// C(w, h), the sum of the whole sample.
    total: [i64; 4],
}

impl PeriodicSums {
    pub fn new(sample: &Rgba8Image) -> Self {
        let (w, h) = (sample.width as usize, sample.height as usize);
        let (stride, cols) = (w + 1, w / CELL + 1);
        let mut above = Vec::with_capacity((h / CELL + 1) * stride);
        let mut left = Vec::with_capacity((h + 1) * cols);
        let mut within = Vec::with_capacity((h + 1) * stride);
        // C(·, y) for the current row and C(·, Y) for its cell row; every difference below is
        // a sum of pixels, so wrapping u32 arithmetic gives it exactly.
        let (mut cur, mut top) = (vec![[0u32; 4]; stride], vec![[0u32; 4]; stride]);
        let sub = |a: [u32; 4], b: [u32; 4]| -> [u32; 4] { std::array::from_fn(|c| a[c].wrapping_sub(b[c])) };
        for y in 0..=h {
            if y % CELL == 0 {
                top.copy_from_slice(&cur);
                above.extend_from_slice(&cur);
            }
            left.extend((0..cols).map(|i| sub(cur[i * CELL], top[i * CELL])));
            within.extend((0..stride).map(|x| {
                let cx = x / CELL * CELL;
                sub(sub(cur[x], cur[cx]), sub(top[x], top[cx])).map(|v| v as u16)
            }));
            if y < h {
                let mut row = [0u32; 4];
                for x in 0..w {
                    let p = sample.pixel(x as u32, y as u32);
                    for c in 0..4 {
                        row[c] += p[c] as u32;
                        cur[x + 1][c] = cur[x + 1][c].wrapping_add(row[c]);
                    }
                }
            }
        }
        let total = cur[w].map(i64::from);
        Self { w: Period::new(w as i64), h: Period::new(h as i64), above, left, within, total }
    }

    /// Heap bytes of the three terms.
    pub fn heap_bytes(&self) -> usize {
        (self.above.capacity() + self.left.capacity()) * 16 + self.within.capacity() * 8
    }

    /// Bytes [`Self::new`] keeps for a `w` × `h` sample, for the plan.
    pub fn bytes_for(w: u64, h: u64) -> u64 {
        let cell = CELL as u64;
        16 * (h / cell + 1) * (w + 1) + 16 * (h + 1) * (w / cell + 1) + 8 * (h + 1) * (w + 1)
    }

    /// C(x, y) for 0 ≤ x ≤ w, 0 ≤ y ≤ h.
    #[inline]
    fn corner(&self, x: i64, y: i64) -> [u32; 4] {
        let (x, y) = (x as usize, y as usize);
        let stride = self.w.n as usize + 1;
        let a = self.above[y / CELL * stride + x];
        let l = self.left[y * (self.w.n as usize / CELL + 1) + x / CELL];
        let s = self.within[y * stride + x];
        std::array::from_fn(|c| a[c].wrapping_add(l[c]).wrapping_add(s[c] as u32))
    }

    /// Sum over [x0, x1) × [y0, y1) of the periodic sample. With x = qx·w + rx and
    /// C(rx, ry) the prefix sums, the periodic prefix sum is
    /// qx·qy·C(w,h) + qx·C(w,ry) + qy·C(rx,h) + C(rx,ry); the box is its four-corner difference.
    #[inline]
    pub fn box_sum(&self, x0: i64, y0: i64, x1: i64, y1: i64) -> [i64; 4] {
        let (qx0, rx0, qx1, rx1) = self.w.split(x0, x1);
        let (qy0, ry0, qy1, ry1) = self.h.split(y0, y1);
        let c = |x, y| self.corner(x, y).map(i64::from);
        let (a, b, d, e) = (c(rx1, ry1), c(rx0, ry1), c(rx1, ry0), c(rx0, ry0));
        let inner: [i64; 4] = std::array::from_fn(|k| a[k] - b[k] - d[k] + e[k]);
        if qx0 == qx1 && qy0 == qy1 {
            return inner;
        }
        let (dqx, dqy, w, h) = (qx1 - qx0, qy1 - qy0, self.w.n, self.h.n);
        let diff = |p: [i64; 4], q: [i64; 4]| -> [i64; 4] { std::array::from_fn(|k| p[k] - q[k]) };
        let (right, bottom) = (diff(c(w, ry1), c(w, ry0)), diff(c(rx1, h), c(rx0, h)));
        std::array::from_fn(|k| dqx * dqy * self.total[k] + dqx * right[k] + dqy * bottom[k] + inner[k])
    }
}

/// The sums of every `side` × `side` box of the periodic sample, by the box's corner in the
/// sample: a cell of a mip footprint then costs one look-up, whatever its layer's offset.
///
/// Entries are stored with columns (and rows) ordered by their remainder modulo the side,
/// then by quotient: the corners a layer's cells take, `side` apart, are then neighbours in
/// memory, so the cells of a footprint and consecutive footprints share cache lines instead of
/// taking one each.
pub(super) struct BoxTable {
    w: u32,
    h: u32,
    /// Where column u is stored in a row, and where row v starts.
    col: Vec<u32>,
    row: Vec<u32>,
    sums: Lanes,
    /// For a power-of-two side, each box's rounded mean, RGBA8 packed little-endian: what a
    /// footprint of that side inside one layer evaluates to, in one look-up.
    means: Vec<u32>,
}

/// A table's entries, in 16 bits a channel where every box sum fits (sides ≤ 16), halving the
/// table's cache footprint for the cells of levels 2–6.
enum Lanes {
    Narrow(Vec<[u16; 4]>),
    Wide(Vec<[u32; 4]>),
}

impl BoxTable {
    /// Samples up to this many pixels get tables (5 MiB each with their means); larger ones sum each box instead.
    const MAX_SAMPLE_PIXELS: usize = 1 << 18;

    /// Sliding sums along rows, then along columns of those. `None` for samples too large and
    /// for sides whose sums may not fit 32 bits.
    fn new(sample: &Sample, side: usize) -> Option<Self> {
        let (w, h) = (sample.width as usize, sample.height as usize);
        if w * h > Self::MAX_SAMPLE_PIXELS || (side * side) as u64 * 255 > u32::MAX as u64 {
            return None;
        }
        let px = |i: usize| sample.px[i].to_le_bytes().map(u32::from);
        let mut rows = Vec::with_capacity(w * h);
        let mut line = Vec::new();
        for y in 0..h {
            line.clear();
            line.extend((0..w).map(|x| px(y * w + x)));
            rows.extend(window_sums(&line, side));
        }
        let mut sums = vec![[0; 4]; w * h];
        for x in 0..w {
            line.clear();
            line.extend((0..h).map(|y| rows[y * w + x]));
            for (y, s) in window_sums(&line, side).enumerate() {
                sums[y * w + x] = s;
            }
        }
        let (col, row) = (by_remainder(w, side), by_remainder(h, side));
        let mut stored = vec![[0; 4]; w * h];
        for (y, line) in sums.chunks_exact(w).enumerate() {
            for (x, s) in line.iter().enumerate() {
                stored[(row[y] * w as u32 + col[x]) as usize] = *s;
            }
        }
        let (row, sums): (Vec<u32>, _) = (row.iter().map(|r| r * w as u32).collect(), stored);
        let means = match side.is_power_of_two() {
            true => sums.iter().map(|s| u32::from_le_bytes(s.map(|v| mean_of_pow2_box(v, side)))).collect(),
            false => Vec::new(),
        };
        let sums = match side * side * 255 <= u16::MAX as usize {
            true => Lanes::Narrow(sums.iter().map(|s| s.map(|v| v as u16)).collect()),
            false => Lanes::Wide(sums),
        };
        Some(Self { w: w as u32, h: h as u32, col, row, sums, means })
    }

    /// The sum of the box with corner (x, y) of the plane.
    pub(super) fn sum(&self, x: i64, y: i64) -> [u32; 4] {
        self.at(x.rem_euclid(self.w as i64) as u32, y.rem_euclid(self.h as i64) as u32, 0)
    }

    /// The sum of the box with corner (x + dx, y + dy) of the plane, for a sample point
    /// (x, y) and an offset packed by [`pack`] — two additions and no division.
    #[inline]
    pub(super) fn at(&self, x: u32, y: u32, offset: u32) -> [u32; 4] {
        let i = self.index(x, y, offset);
        match &self.sums {
            Lanes::Narrow(s) => s[i].map(u32::from),
            Lanes::Wide(s) => s[i],
        }
    }

    /// The rounded mean (RGBA8) of the box that [`Self::at`] sums; power-of-two sides only.
    #[inline]
    pub(super) fn mean_at(&self, x: u32, y: u32, offset: u32) -> [u8; 4] {
        self.means[self.index(x, y, offset)].to_le_bytes()
    }

    #[inline]
    fn index(&self, x: u32, y: u32, offset: u32) -> usize {
        let (mut u, mut v) = (x + (offset & 0xffff), y + (offset >> 16));
        u -= self.w * (u >= self.w) as u32;
        v -= self.h * (v >= self.h) as u32;
        (self.row[v as usize] + self.col[u as usize]) as usize
    }
}

/// For each of `n` positions, its place when ordered by remainder modulo `side`, then by
/// quotient.
fn by_remainder(n: usize, side: usize) -> Vec<u32> {
    let mut order: Vec<usize> = (0..n).collect();
    order.sort_by_key(|&u| (u % side, u / side));
    let mut place = vec![0u32; n];
    for (k, &u) in order.iter().enumerate() {
        place[u] = k as u32;
    }
    place
}

/// The box tables of one sample, one a power-of-two side, each built on first use and kept:
/// at most 13 tables of at most 5 MiB with their means. A
/// cached table is the table built afresh, so the cache never changes a result.
#[derive(Default)]
pub(super) struct BoxTables([OnceLock<Option<BoxTable>>; 13]);

impl BoxTables {
    /// The table of `side` × `side` boxes, or `None` when the side is no power of two or the
    /// sample or the side is too large for a table.
    pub(super) fn get(&self, sample: &Sample, side: i64) -> Option<&BoxTable> {
        let k = side.trailing_zeros() as usize;
        if side <= 0 || side.count_ones() != 1 || k >= self.0.len() {
            return None;
        }
        self.0[k].get_or_init(|| BoxTable::new(sample, side as usize)).as_ref()
    }
}

/// The rounded mean of a box of `side²` pixels (side a power of two) from its sum `s`: the
/// division is a shift, as the prefiltered levels divide full footprints.
#[inline]
fn mean_of_pow2_box(s: u32, side: usize) -> u8 {
    let area = (side * side) as u64;
    ((s as u64 + area / 2) >> area.trailing_zeros()) as u8
}

/// A layer's translation (dx, dy) from texture to sample coordinates, reduced modulo the sample
/// (sides ≤ 4096) and packed as `dy << 16 | dx`: equal packed offsets give equal box sums.
/// Translations within one period either way reduce without dividing.
pub(super) fn pack(dx: i64, dy: i64, sw: i64, sh: i64) -> u32 {
    let reduce = |v: i64, n: i64| match v {
        v if (0..n).contains(&v) => v,
        v if (-n..0).contains(&v) => v + n,
        v => v.rem_euclid(n),
    };
    (reduce(dy, sh) as u32) << 16 | reduce(dx, sw) as u32
}

/// For each i of a periodic `line`, the sum of its `side` values from i on. Sums wrap in u32
/// arithmetic, exact because every window of the sample (≤ 4096² · 255) is below 2^32.
fn window_sums(line: &[[u32; 4]], side: usize) -> impl Iterator<Item = [u32; 4]> + '_ {
    let n = line.len();
    let (laps, rest) = ((side / n) as u32, side % n);
    let mut prefix = vec![[0u32; 4]; n + rest + 1];
    for k in 0..n + rest {
        prefix[k + 1] = std::array::from_fn(|c| prefix[k][c].wrapping_add(line[k % n][c]));
    }
    (0..n).map(move |i| {
        std::array::from_fn(|c| {
            laps.wrapping_mul(prefix[n][c]).wrapping_add(prefix[i + rest][c]).wrapping_sub(prefix[i][c])
        })
    })
}

/// A period of the sample, with a reciprocal so that splitting a coordinate into periods
/// multiplies instead of dividing (Lemire's fastmod; exact for 0 ≤ v < 2^32 and n ≥ 2).
pub(super) struct Period {
    n: i64,
    /// ⌈2^64 / n⌉, or 0 for n = 1 (which divides the slow way).
    reciprocal: u64,
}

impl Period {
    fn new(n: i64) -> Self {
        Self { n, reciprocal: (u64::MAX / n as u64).wrapping_add(1) }
    }

    /// `v` as (quotient, remainder) by the period, rounding down.
    #[inline]
    pub(super) fn div_rem(&self, v: i64) -> (i64, i64) {
        if self.reciprocal != 0 && (0..1 << 32).contains(&v) {
            let q = ((self.reciprocal as u128 * v as u128) >> 64) as i64;
            (q, v - q * self.n)
        } else {
            (v.div_euclid(self.n), v.rem_euclid(self.n))
        }
    }

    /// Both ends of [a, b) as (quotient, remainder), with one split when the interval is
    /// shorter than two periods.
    #[inline]
    fn split(&self, a: i64, b: i64) -> (i64, i64, i64, i64) {
        let (qa, ra) = self.div_rem(a);
        let rb = ra + (b - a);
        if rb < self.n {
            (qa, ra, qa, rb)
        } else if rb < 2 * self.n {
            (qa, ra, qa + 1, rb - self.n)
        } else {
            let (qb, rb) = self.div_rem(b);
            (qa, ra, qb, rb)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn periodic_sums_match_brute_force() {
        let mut s = Rgba8Image::new(5, 3);
        for (i, b) in s.data.iter_mut().enumerate() {
            *b = (i * 37 % 251) as u8;
        }
        let sums = PeriodicSums::new(&s);
        for (x0, y0, x1, y1) in
            [(0i64, 0i64, 5i64, 3i64), (-7, -4, 9, 2), (3, 1, 4, 2), (-1, -1, 0, 0), (12, 7, 30, 11)]
        {
            let mut want = [0i64; 4];
            for y in y0..y1 {
                for x in x0..x1 {
                    let p = s.pixel(x.rem_euclid(5) as u32, y.rem_euclid(3) as u32);
                    for c in 0..4 {
                        want[c] += p[c] as i64;
                    }
                }
            }
            assert_eq!(sums.box_sum(x0, y0, x1, y1), want, "box ({x0},{y0})-({x1},{y1})");
        }
    }

    #[test]
    fn prefix_sums_split_in_cells_match_brute_force() {
        // Sides that are and are not multiples of the cell, every corner of every cell.
        for (w, h) in [(37u32, 21u32), (32, 48), (16, 17)] {
            let mut s = Rgba8Image::new(w, h);
            for (i, b) in s.data.iter_mut().enumerate() {
                *b = (i * 7919 % 256) as u8;
            }
            let sums = PeriodicSums::new(&s);
            let mut prefix = vec![[0i64; 4]; (w as usize + 1) * (h as usize + 1)];
            for y in 0..h as usize {
                for x in 0..w as usize {
                    let p = s.pixel(x as u32, y as u32);
                    let at = |x: usize, y: usize| y * (w as usize + 1) + x;
                    prefix[at(x + 1, y + 1)] = std::array::from_fn(|c| {
                        prefix[at(x, y + 1)][c] + prefix[at(x + 1, y)][c] - prefix[at(x, y)][c] + p[c] as i64
                    });
                }
            }
            for y in 0..=h as i64 {
                for x in 0..=w as i64 {
                    let want = prefix[(y * (w as i64 + 1) + x) as usize];
                    assert_eq!(sums.corner(x, y).map(i64::from), want, "{w}×{h} at ({x}, {y})");
                    assert_eq!(sums.box_sum(0, 0, x, y), want);
                }
            }
            assert_eq!(sums.box_sum(-3, -2, 2 * w as i64 + 5, h as i64 + 1)[0], {
                let row = |y: i64| {
                    (-3..2 * w as i64 + 5)
                        .map(|x| s.pixel(x.rem_euclid(w as i64) as u32, y as u32)[0] as i64)
                        .sum::<i64>()
                };
                (-2..h as i64 + 1).map(|y| row(y.rem_euclid(h as i64))).sum::<i64>()
            });
        }
    }

    #[test]
    fn the_largest_white_sample_sums_exactly() {
        // 4096² · 255 is the largest sum a corner holds; its terms must not wrap.
        let s = Rgba8Image { width: 4096, height: 4096, data: vec![255; 4096 * 4096 * 4] };
        let sums = PeriodicSums::new(&s);
        for (x0, y0, x1, y1) in
            [(0i64, 0i64, 4096i64, 4096i64), (1, 2, 4095, 4093), (-5, 17, 8000, 9001), (100, 0, 116, 4096)]
        {
            let area = (x1 - x0) * (y1 - y0);
            assert_eq!(sums.box_sum(x0, y0, x1, y1), [255 * area; 4], "({x0},{y0})-({x1},{y1})");
        }
        assert!(sums.heap_bytes() as u64 <= PeriodicSums::bytes_for(4096, 4096));
        assert!(sums.heap_bytes() <= 11 * 4096 * 4096, "{} bytes", sums.heap_bytes());
    }

    #[test]
    fn periods_split_like_euclidean_division() {
        for n in [1i64, 2, 3, 7, 64, 160, 4095, 4096] {
            let p = Period::new(n);
            for v in [0i64, 1, n - 1, n, n + 1, 12_345, (1 << 32) - 1, 1 << 32, -1, -n, -12_345, i64::MAX / 4] {
                assert_eq!(p.div_rem(v), (v.div_euclid(n), v.rem_euclid(n)), "v={v} n={n}");
            }
        }
    }

    #[test]
    fn box_tables_match_box_sums() {
        let mut s = Rgba8Image::new(7, 5);
        for (i, b) in s.data.iter_mut().enumerate() {
            *b = (i * 53 % 256) as u8;
        }
        let sums = PeriodicSums::new(&s);
        for side in [1, 2, 3, 5, 7, 8, 16, 33] {
            let table = BoxTable::new(&Sample::new(&s), side).unwrap();
            for (x, y) in [(0i64, 0i64), (3, 4), (6, 1), (-2, -9), (100, 37)] {
                let side = side as i64;
                assert_eq!(
                    table.sum(x, y).map(i64::from),
                    sums.box_sum(x, y, x + side, y + side),
                    "side {side} at ({x}, {y})"
                );
            }
        }
    }

    #[test]
    fn cached_tables_are_fresh_tables_and_take_packed_offsets() {
        let s = crate::samples::pebbles(24, 4, 2, true);
        let (sums, tables, px) = (PeriodicSums::new(&s), BoxTables::default(), Sample::new(&s));
        assert_eq!(px.to_image().data, s.data);
        for side in [1i64, 2, 4, 16, 32, 64, 4096] {
            let cached = tables.get(&px, side).unwrap();
            assert!(std::ptr::eq(cached, tables.get(&px, side).unwrap()), "built once");
            let fresh = BoxTable::new(&px, side as usize).unwrap();
            assert_eq!(matches!(cached.sums, Lanes::Narrow(_)), side <= 16, "side {side}");
            for (x, y, dx, dy) in [(0i64, 0i64, 0i64, 0i64), (23, 23, 23, 23), (5, 17, -40, 3), (11, 0, 7, -1000)] {
                let want = sums.box_sum(x + dx, y + dy, x + dx + side, y + dy + side);
                let got = cached.at(x as u32, y as u32, pack(dx, dy, 24, 24));
                assert_eq!(got.map(i64::from), want, "side {side} at ({x}, {y}) + ({dx}, {dy})");
                assert_eq!(fresh.at(x as u32, y as u32, pack(dx, dy, 24, 24)), got);
                let mean = want.map(|v| ((v + side * side / 2) / (side * side)) as u8);
                assert_eq!(cached.mean_at(x as u32, y as u32, pack(dx, dy, 24, 24)), mean, "mean, side {side}");
            }
        }
        assert!(tables.get(&px, 3).is_none() && tables.get(&px, 8192).is_none() && tables.get(&px, 0).is_none());
    }
}
