//! Level-0 evaluation: the lazy construction of §3.2 — the tiling under a region, the blocks
//! that touch it pasted in sequence order — followed by cross-edge filtering (§2.4).
//!
//! Every pixel carries the sample coordinate it was copied from. A *seam* is a pair of
//! neighbours whose sample coordinates are not consecutive (wrapping counts as consecutive
//! only for a seamless sample). Filtering acts on seams alone, so a block pasted where it was
//! cut (zero cat map iterations) leaves the plain tiling untouched, exactly.

use super::ChaosMosaic;
use crate::texture::wrap;

/// Per composite row, the column boundaries to test; and (row boundary, first column, end
/// column) pieces to test between rows.
type SeamCandidates = (Vec<Vec<usize>>, Vec<(usize, usize, usize)>);

/// A block at unwrapped texture coordinates (the torus unrolled around a region).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Placed {
    pub id: u32,
    pub x: i64,
    pub y: i64,
}

/// The unfiltered mosaic over a rectangle: sample coordinates packed as `sy << 16 | sx`
/// and the RGBA pixel (as a little-endian `u32`) copied from there.
pub(super) struct Composite {
    pub x0: i64,
    pub y0: i64,
    pub w: usize,
    pub h: usize,
    pub src: Vec<u32>,
    pub rgba: Vec<u32>,
    /// The blocks pasted, in order.
    pub placed: Vec<Placed>,
}

impl ChaosMosaic {
    /// Every placement of a block whose rectangle meets `[x0, x0+w) × [y0, y0+h)`, in
    /// sequence order, found through the tile index.
    pub(super) fn placements(&self, x0: i64, y0: i64, w: u64, h: u64) -> Vec<Placed> {
        let (sw, sh) = (self.sample.width as i64, self.sample.height as i64);
        let (tw, th) = (self.width as i64, self.height as i64);
        let mut out = Vec::new();
        for ty in y0.div_euclid(sh)..=(y0 + h as i64 - 1).div_euclid(sh) {
            let wty = ty.rem_euclid(self.params.tiles_y as i64);
            for tx in x0.div_euclid(sw)..=(x0 + w as i64 - 1).div_euclid(sw) {
                let wtx = tx.rem_euclid(self.params.tiles_x as i64);
                for &id in self.index.blocks(wtx as u32, wty as u32) {
                    let b = &self.blocks[id as usize];
                    // A block touching this tile starts at most one torus period before it.
                    let dx = (b.s as i64 - wtx * sw).rem_euclid(tw);
                    let dy = (b.t as i64 - wty * sh).rem_euclid(th);
                    for px in [tx * sw + dx, tx * sw + dx - tw] {
                        for py in [ty * sh + dy, ty * sh + dy - th] {
                            let meets = px < x0 + w as i64
                                && px + b.w as i64 > x0
                                && py < y0 + h as i64
                                && py + b.h as i64 > y0;
                            if meets {
                                out.push(Placed { id, x: px, y: py });
                            }
                        }
                    }
                }
            }
        }
        out.sort_unstable();
        out.dedup();
        out
    }

    /// The unfiltered mosaic over `[x0, x0+w) × [y0, y0+h)`: sample rows copied run by run.
    pub(super) fn composite(&self, x0: i64, y0: i64, w: usize, h: usize) -> Composite {
        let (sw, sh) = (self.sample.width as usize, self.sample.height as usize);
        let mut src = Vec::with_capacity(w * h);
        let mut rgba = Vec::with_capacity(w * h);
        // The tiling T: each row is its sample row, repeated from the wrapped start column.
        let sx0 = wrap(x0, sw as u64) as usize;
        let sy0 = wrap(y0, sh as u64) as usize;
        for j in 0..h {
            let sy = (sy0 + j) % sh;
            let sample_row = &self.sample_px[sy * sw..(sy + 1) * sw];
            let (mut i, mut sx) = (0, sx0);
            while i < w {
                let n = (sw - sx).min(w - i);
                rgba.extend_from_slice(&sample_row[sx..sx + n]);
                src.extend((sx..sx + n).map(|k| (sy as u32) << 16 | k as u32));
                (i, sx) = (i + n, 0);
            }
        }
        // The random blocks, later ones over earlier ones.
        let placed = self.placements(x0, y0, w as u64, h as u64);
        for p in &placed {
            let b = &self.blocks[p.id as usize];
            let (cx0, cx1) = ((p.x.max(x0) - x0) as usize, ((p.x + b.w as i64).min(x0 + w as i64) - x0) as usize);
            let (cy0, cy1) = ((p.y.max(y0) - y0) as usize, ((p.y + b.h as i64).min(y0 + h as i64) - y0) as usize);
            let sx = b.x as usize + (x0 + cx0 as i64 - p.x) as usize;
            let n = cx1 - cx0;
            for j in cy0..cy1 {
                let sy = b.y as usize + (y0 + j as i64 - p.y) as usize;
                let at = j * w + cx0;
                rgba[at..at + n].copy_from_slice(&self.sample_px[sy * sw + sx..sy * sw + sx + n]);
                for (k, s) in src[at..at + n].iter_mut().enumerate() {
                    *s = (sy as u32) << 16 | (sx + k) as u32;
                }
            }
        }
        Composite { x0, y0, w, h, src, rgba, placed }
    }

    /// True when the pixel with sample coordinate `b` may follow `a` to its right unseamed.
    #[inline]
    fn continues_x(&self, a: u32, b: u32) -> bool {
        b == a.wrapping_add(1) || (self.seamless && a & 0xffff == self.sample.width - 1 && b == a & 0xffff_0000)
    }

    /// True when the pixel with sample coordinate `b` may follow `a` below it unseamed.
    #[inline]
    fn continues_y(&self, a: u32, b: u32) -> bool {
        b == a.wrapping_add(1 << 16) || (self.seamless && a >> 16 == self.sample.height - 1 && b == a & 0xffff)
    }

    /// Where seams can be in a composite: a seam needs a change of layer, so it lies on a
    /// block's edge, or on a tile edge when the sample is not seamless. Returns, per
    /// composite row, the column boundaries to test, and the (row boundary, column range)
    /// pieces to test between rows. A boundary `b` lies between pixels `b − 1` and `b`.
    fn seam_candidates(&self, c: &Composite) -> SeamCandidates {
        let (sw, sh) = (self.sample.width as i64, self.sample.height as i64);
        let mut cols: Vec<Vec<usize>> = vec![Vec::new(); c.h];
        let mut rows = Vec::new();
        let inner = |v: i64, n: usize| (v > 0 && v < n as i64).then_some(v as usize);
        for p in &c.placed {
            let b = &self.blocks[p.id as usize];
            let (x0, x1) = ((p.x - c.x0).max(0) as usize, ((p.x + b.w as i64 - c.x0).min(c.w as i64)) as usize);
            let (y0, y1) = ((p.y - c.y0).max(0) as usize, ((p.y + b.h as i64 - c.y0).min(c.h as i64)) as usize);
            for edge in [p.x - c.x0, p.x + b.w as i64 - c.x0].into_iter().filter_map(|e| inner(e, c.w)) {
                cols[y0..y1].iter_mut().for_each(|row| row.push(edge));
            }
            for edge in [p.y - c.y0, p.y + b.h as i64 - c.y0].into_iter().filter_map(|e| inner(e, c.h)) {
                rows.push((edge, x0, x1));
            }
        }
        if !self.seamless {
            let first_col = (sw - c.x0.rem_euclid(sw)) % sw;
            for edge in (first_col as usize..c.w).step_by(sw as usize).filter(|&e| e > 0) {
                cols.iter_mut().for_each(|row| row.push(edge));
            }
            let first_row = (sh - c.y0.rem_euclid(sh)) % sh;
            for edge in (first_row as usize..c.h).step_by(sh as usize).filter(|&e| e > 0) {
                rows.push((edge, 0, c.w));
            }
        }
        (cols, rows)
    }

    /// Level 0 of the chaos mosaic into `out` (RGBA8, `w × h`): the composite, then a
    /// horizontal and a vertical filter pass that touch only the pixels near seams. A pixel
    /// at distance d < r from the nearest seam becomes the mean of the 2(r − d) + 1 pixels
    /// centred on it across the seam (strongest at the seam, fading over r pixels).
    pub(super) fn render_level0(&self, x0: i64, y0: i64, w: u32, h: u32, out: &mut [u8]) {
        let r = self.params.filter_width as usize;
        let (w, h) = (w as usize, h as usize);
        let c = self.composite(x0 - r as i64, y0 - r as i64, w + 2 * r, h + 2 * r);
        let (seam_cols, seam_rows) = self.seam_candidates(&c);
        // Horizontal pass: every composite row, the output columns.
        let mut hbuf = Vec::with_capacity(c.h * w);
        let mut dist = vec![u8::MAX; w];
        let mut row_seams = Vec::new();
        let mut prefix: Vec<(u32, u32)> = Vec::with_capacity(4 * r + 2);
        for (j, candidates) in seam_cols.iter().enumerate() {
            let (row_src, row_rgba) = (&c.src[j * c.w..(j + 1) * c.w], &c.rgba[j * c.w..(j + 1) * c.w]);
            hbuf.extend_from_slice(&row_rgba[r..r + w]);
            let hrow = &mut hbuf[j * w..(j + 1) * w];
            row_seams.clear();
            row_seams
                .extend(candidates.iter().copied().filter(|&b| r > 0 && !self.continues_x(row_src[b - 1], row_src[b])));
            for &b in &row_seams {
                mark_near_boundary(&mut dist, b as isize - r as isize, r);
            }
            // Each marked pixel is filtered once, then unmarked for the next row. The windows
            // near one seam all lie in composite columns [b − 2r, b + 2r): sum them from one
            // lane-packed prefix sum of that band.
            for &b in &row_seams {
                let base = b.saturating_sub(2 * r);
                let band = &row_rgba[base..(b + 2 * r).min(c.w)];
                prefix.clear();
                prefix.push((0, 0));
                for &p in band {
                    let &(even, odd) = prefix.last().unwrap();
                    prefix.push((even + (p & 0x00ff_00ff), odd + ((p >> 8) & 0x00ff_00ff)));
                }
                for i in b.saturating_sub(2 * r)..b.min(w) {
                    let d = std::mem::replace(&mut dist[i], u8::MAX) as usize;
                    if d < r {
                        let (lo, hi) = (prefix[i + d - base], prefix[i + 2 * r - d + 1 - base]);
                        hrow[i] = mean_of_sums(hi.0 - lo.0, hi.1 - lo.1, (2 * (r - d) + 1) as u32);
                    }
                }
            }
        }
        // Vertical pass over the horizontally filtered rows.
        for (o, v) in out.chunks_exact_mut(4).zip(&hbuf[r * w..(r + h) * w]) {
            o.copy_from_slice(&v.to_le_bytes());
        }
        if r == 0 {
            return;
        }
        let mut seams = Vec::new();
        for &(b, from, to) in &seam_rows {
            let (above, below) = (&c.src[(b - 1) * c.w..b * c.w], &c.src[b * c.w..(b + 1) * c.w]);
            for x in from.max(r)..to.min(r + w) {
                if !self.continues_y(above[x], below[x]) {
                    seams.push((b, x - r));
                }
            }
        }
        let mut vdist = vec![u8::MAX; w * h];
        let near = |b: usize| (b as isize - r as isize).max(r as isize) as usize..(b + r).min(h + r);
        for &(b, i) in &seams {
            for y in near(b) {
                let d = if y >= b { y - b } else { b - 1 - y };
                let slot = &mut vdist[(y - r) * w + i];
                *slot = (*slot).min(d as u8);
            }
        }
        let mut column = vec![0u32; 2 * r + 1];
        for &(b, i) in &seams {
            for y in near(b) {
                let d = std::mem::replace(&mut vdist[(y - r) * w + i], u8::MAX) as usize;
                if d >= r {
                    continue;
                }
                let n = 2 * (r - d) + 1;
                for (k, v) in column[..n].iter_mut().enumerate() {
                    *v = hbuf[(y - (r - d) + k) * w + i];
                }
                let at = ((y - r) * w + i) * 4;
                out[at..at + 4].copy_from_slice(&mean(&column[..n]).to_le_bytes());
            }
        }
    }

    /// Pixels of `[x0, x0+w) × [y0, y0+h)` at level 0 that touch a seam (either side).
    /// The quality metrics measure gradient energy there against everywhere else.
    pub fn seam_mask(&self, x0: i64, y0: i64, w: u32, h: u32) -> Vec<bool> {
        let (w, h) = (w as usize, h as usize);
        let c = self.composite(x0 - 1, y0 - 1, w + 2, h + 2);
        let mut mask = vec![false; w * h];
        for y in 0..h {
            for x in 0..w {
                let at = |dx: usize, dy: usize| c.src[(y + dy) * c.w + x + dx];
                let centre = at(1, 1);
                mask[y * w + x] = !self.continues_x(at(0, 1), centre)
                    || !self.continues_x(centre, at(2, 1))
                    || !self.continues_y(at(1, 0), centre)
                    || !self.continues_y(centre, at(1, 2));
            }
        }
        mask
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

/// Per-channel rounded mean of RGBA pixels packed as little-endian `u32`; at most
/// 2 · `MAX_FILTER_WIDTH` + 1 of them.
#[inline]
fn mean(pixels: &[u32]) -> u32 {
    let (mut even, mut odd) = (0u32, 0u32);
    for &p in pixels {
        even += p & 0x00ff_00ff;
        odd += (p >> 8) & 0x00ff_00ff;
    }
    mean_of_sums(even, odd, pixels.len() as u32)
}

/// The rounded means of `n` pixels from their channel sums in two 16-bit lanes a half: even
/// bytes (R, B) and odd bytes (G, A), which add without carries for up to 257 pixels.
#[inline]
fn mean_of_sums(even: u32, odd: u32, n: u32) -> u32 {
    // (v + n/2) / n by a 20-bit reciprocal: exact for v < 2^20 / n, far above 255 · 17.
    let reciprocal = (1 << 20) / n + 1;
    let lane = |v: u32, shift: u32| ((((v >> shift) & 0xffff) + n / 2) * reciprocal) >> 20;
    lane(even, 0) | lane(odd, 0) << 8 | lane(even, 16) << 16 | lane(odd, 16) << 24
}

#[cfg(test)]
mod tests {
    use super::mean;

    #[test]
    fn mean_rounds_each_channel_exactly() {
        for n in 1..=17u32 {
            for v in [0u32, 1, 2, 127, 128, 200, 254, 255] {
                for w in [0u32, 3, 255] {
                    let px: Vec<u32> = (0..n)
                        .map(|i| if i == 0 { v | w << 8 | v << 16 | w << 24 } else { w | v << 8 | w << 16 | v << 24 })
                        .collect();
                    let sum_even = v + (n - 1) * w;
                    let sum_odd = w + (n - 1) * v;
                    let want = |s: u32| (s + n / 2) / n;
                    let got = mean(&px);
                    assert_eq!(got & 0xff, want(sum_even), "n={n} v={v} w={w}");
                    assert_eq!(got >> 8 & 0xff, want(sum_odd));
                    assert_eq!(got >> 16 & 0xff, want(sum_even));
                    assert_eq!(got >> 24, want(sum_odd));
                }
            }
        }
    }
}
