//! Level-0 evaluation: the unfiltered mosaic of [`super::layout`], then cross-edge filtering
//! (§2.4) across its seams. Filtering acts on seams alone, so a block pasted where it was cut
//! (zero cat map iterations) leaves the plain tiling untouched, exactly.

use super::layout::RowSeam;
use super::params::MAX_FILTER_WIDTH;
use super::ChaosMosaic;
use crate::Stop;

/// Rows of the mosaic made between two polls of the [`Stop`].
const POLL_ROWS: usize = 16;

impl ChaosMosaic {
    /// Level 0 of the chaos mosaic into `out` (RGBA8, `w × h`), streamed a row at a time:
    /// each row of the unfiltered mosaic (with `r` rows and columns of margin) is built from
    /// its spans and filtered across its column seams into a ring of the last 2r + 1 rows;
    /// each output row then takes the vertical filter across row seams from the ring. A pixel
    /// at distance d < r from the nearest seam becomes the mean of the 2(r − d) + 1 pixels
    /// centred on it across the seam (strongest at the seam, fading over r pixels). The
    /// working set is a few rows, whatever the region's size. `None` once `stop` is requested.
    pub(super) fn render_level0(
        &self,
        x0: i64,
        y0: i64,
        w: u32,
        h: u32,
        out: &mut [u8],
        stop: &dyn Stop,
    ) -> Option<()> {
        let r = self.params.filter_width as usize;
        let (w, h) = (w as usize, h as usize);
        let layout = self.layout(x0 - r as i64, y0 - r as i64, w + 2 * r, h + 2 * r);
        let row_seams: Vec<RowSeam> = self
            .row_seams(&layout)
            .into_iter()
            .filter_map(|s| {
                let (from, to) = (s.from.max(r) - r, s.to.min(r + w).saturating_sub(r));
                (from < to).then_some(RowSeam { from, to, ..s })
            })
            .collect();
        let ring_rows = 2 * r + 1;
        let mut ring = vec![0u32; ring_rows * w];
        let mut row = vec![0u32; w + 2 * r];
        let mut dist = vec![u8::MAX; w];
        // Per column seam of the current band, the mosaic columns its windows span and the
        // range of `near` it filters; per filtered pixel, its output column, its window as
        // bounds into the prefix sums of those columns, and the window's length.
        let mut seams: Vec<(std::ops::Range<usize>, std::ops::Range<usize>)> = Vec::new();
        let mut near: Vec<(usize, usize, usize, u32)> = Vec::new();
        let mut prefix = [(0u32, 0u32); 4 * MAX_FILTER_WIDTH as usize + 1];
        let mut first_seam = 0;
        for band in &layout.bands {
            seams.clear();
            near.clear();
            for b in self.column_seams(&layout, band) {
                mark_near_boundary(&mut dist, b as isize - r as isize, r);
            }
            for b in self.column_seams(&layout, band) {
                // The windows of the pixels near seam b all lie in mosaic columns [b − 2r, b + 2r).
                let base = b.saturating_sub(2 * r);
                let first = near.len();
                for (i, slot) in (base..).zip(&mut dist[base..b.min(w)]) {
                    let d = std::mem::replace(slot, u8::MAX) as usize;
                    if d < r {
                        near.push((i, i + d - base, i + 2 * r - d + 1 - base, (2 * (r - d) + 1) as u32));
                    }
                }
                seams.push((base..(b + 2 * r).min(w + 2 * r), first..near.len()));
            }
            for y in band.y0..band.y1 {
                if y % POLL_ROWS == 0 && stop.requested() {
                    return None;
                }
                self.fill_row(&layout, band, y, &mut row);
                let filtered = &mut ring[(y % ring_rows) * w..][..w];
                filtered.copy_from_slice(&row[r..r + w]);
                for (columns, pixels) in &seams {
                    let (mut even, mut odd) = (0, 0);
                    for (sum, &p) in prefix[1..].iter_mut().zip(&row[columns.clone()]) {
                        (even, odd) = (even + (p & 0x00ff_00ff), odd + ((p >> 8) & 0x00ff_00ff));
                        *sum = (even, odd);
                    }
                    for &(i, lo, hi, n) in &near[pixels.clone()] {
                        let (lo, hi) = (prefix[lo], prefix[hi]);
                        filtered[i] = mean_of_sums(hi.0 - lo.0, hi.1 - lo.1, n);
                    }
                }
                // Output row y − 2r (mosaic row y − r) now has every ring row it needs.
                if let Some(oy) = y.checked_sub(2 * r) {
                    while row_seams.get(first_seam).is_some_and(|s| s.b <= oy) {
                        first_seam += 1;
                    }
                    let seams = &row_seams[first_seam..];
                    let near = &seams[..seams.partition_point(|s| s.b <= oy + 2 * r)];
                    let out_row = &mut out[oy * w * 4..][..w * 4];
                    filter_row_seams(&ring, w, r, oy, near, &mut dist, out_row);
                }
            }
        }
        Some(())
    }

    /// Pixels of `[x0, x0+w) × [y0, y0+h)` at level 0 that touch a seam (either side).
    /// The quality metrics measure gradient energy there against everywhere else.
    pub fn seam_mask(&self, x0: i64, y0: i64, w: u32, h: u32) -> Vec<bool> {
        let (w, h) = (w as usize, h as usize);
        // A margin of one pixel: mosaic (x + 1, y + 1) is pixel (x, y) of the mask.
        let layout = self.layout(x0 - 1, y0 - 1, w + 2, h + 2);
        let mut mask = vec![false; w * h];
        let mut set = |x: usize, y: usize| {
            if (1..=w).contains(&x) && (1..=h).contains(&y) {
                mask[(y - 1) * w + x - 1] = true;
            }
        };
        for band in &layout.bands {
            for b in self.column_seams(&layout, band) {
                for y in band.y0..band.y1 {
                    set(b - 1, y);
                    set(b, y);
                }
            }
        }
        for s in self.row_seams(&layout) {
            for x in s.from..s.to {
                set(x, s.b - 1);
                set(x, s.b);
            }
        }
        mask
    }
}

/// The vertical filter of output row `oy` (mosaic row `oy + r`): the row as filtered
/// horizontally, with the pixels near the row seams `near` replaced by the means of their
/// columns in the ring of horizontally filtered rows. `dist` is all `u8::MAX` and left so.
fn filter_row_seams(ring: &[u32], w: usize, r: usize, oy: usize, near: &[RowSeam], dist: &mut [u8], out: &mut [u8]) {
    // Where mosaic rows oy … oy + 2r start in the ring.
    let mut starts = [0usize; 2 * MAX_FILTER_WIDTH as usize + 1];
    for (k, start) in starts[..2 * r + 1].iter_mut().enumerate() {
        *start = (oy + k) % (2 * r + 1) * w;
    }
    for (o, v) in out.chunks_exact_mut(4).zip(&ring[starts[r]..][..w]) {
        o.copy_from_slice(&v.to_le_bytes());
    }
    let y = oy + r;
    for s in near {
        let d = if y >= s.b { y - s.b } else { s.b - 1 - y } as u8;
        dist[s.from..s.to].iter_mut().for_each(|slot| *slot = (*slot).min(d));
    }
    // Runs of columns at one distance take their means together, a row of the ring at a time.
    for s in near {
        let mut x = s.from;
        while x < s.to {
            let d = dist[x];
            let run = x..x + dist[x..s.to].iter().take_while(|&&e| e == d).count();
            dist[run.clone()].fill(u8::MAX);
            if (d as usize) < r {
                let d = d as usize;
                column_means(ring, &starts[d..=2 * r - d], run.clone(), &mut out[run.start * 4..run.end * 4]);
            }
            x = run.end;
        }
    }
}

/// For each column of `columns`, the mean of that column over the ring rows starting at
/// `starts`, into `out` (RGBA8).
fn column_means(ring: &[u32], starts: &[usize], columns: std::ops::Range<usize>, out: &mut [u8]) {
    const CHUNK: usize = 64;
    let (mut even, mut odd) = ([0u32; CHUNK], [0u32; CHUNK]);
    for (first, out) in columns.step_by(CHUNK).zip(out.chunks_mut(CHUNK * 4)) {
        let n = out.len() / 4;
        even[..n].fill(0);
        odd[..n].fill(0);
        for &start in starts {
            let row = &ring[start + first..][..n];
            for ((e, o), &p) in even.iter_mut().zip(odd.iter_mut()).zip(row) {
                *e += p & 0x00ff_00ff;
                *o += (p >> 8) & 0x00ff_00ff;
            }
        }
        for ((px, &e), &o) in out.chunks_exact_mut(4).zip(&even).zip(&odd) {
            px.copy_from_slice(&mean_of_sums(e, o, starts.len() as u32).to_le_bytes());
        }
    }
}

/// Records, for output columns `i` (composite column `i + r`), the distance to a seam
/// between composite columns `b − 1` and `b`, where `first = b − r`.
fn mark_near_boundary(dist: &mut [u8], first: isize, r: usize) {
    // Output column i is composite column x = i + r; distance is x − b right of the seam,
    // b − 1 − x left of it. Only distances below r matter.
    for d in 0..r as isize {
        for i in [first + d, first - 1 - d] {
            if (0..dist.len() as isize).contains(&i) {
                let slot = &mut dist[i as usize];
                *slot = (*slot).min(d as u8);
            }
        }
    }
}

/// 2^18 / n + 1 for every window length n, so that no mean divides.
const RECIPROCALS: [u64; 2 * MAX_FILTER_WIDTH as usize + 2] = {
    let mut table = [0; 2 * MAX_FILTER_WIDTH as usize + 2];
    let mut n = 1;
    while n < table.len() {
        table[n] = (1 << 18) / n as u64 + 1;
        n += 1;
    }
    table
};

/// The rounded means of `n` pixels from their channel sums in two 16-bit lanes a half: even
/// bytes (R, B) and odd bytes (G, A), which add without carries for up to 257 pixels.
#[inline]
fn mean_of_sums(even: u32, odd: u32, n: u32) -> u32 {
    // (v + n/2) / n by an 18-bit reciprocal, two lanes a multiply (32 bits each in a u64):
    // exact while (v + n/2) · n < 2^18, i.e. for every sum of up to 17 bytes.
    let (reciprocal, half) = (RECIPROCALS[n as usize], (n / 2) as u64 * 0x1_0000_0001);
    let divide = |v: u32| ((((v & 0xffff) as u64 | ((v >> 16) as u64) << 32) + half) * reciprocal) >> 18;
    let (e, o) = (divide(even), divide(odd));
    (e & 0xff | (o & 0xff) << 8 | (e >> 16 & 0xff_0000) | (o >> 8 & 0xff00_0000)) as u32
}

#[cfg(test)]
mod tests {
    use super::mean_of_sums;

    #[test]
    fn means_round_each_channel_exactly_for_every_sum() {
        for n in 1..=17u32 {
            let want = |s: u32| (s + n / 2) / n;
            for s in 0..=255 * n {
                // Each channel its own sum: s, its mirror, and two values between.
                let (r, g, b, a) = (s, 255 * n - s, s / 2, (s * 7) % (255 * n + 1));
                let got = mean_of_sums(r | b << 16, g | a << 16, n);
                assert_eq!(got.to_le_bytes(), [want(r), want(g), want(b), want(a)].map(|v| v as u8), "n={n} s={s}");
            }
        }
    }
}
