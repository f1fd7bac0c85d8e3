//! The unfiltered mosaic over a rectangle — the lazy construction of §3.2: the tiling under
//! the rectangle with the blocks that touch it pasted in sequence order — kept as structure,
//! not pixels.
//!
//! Rows are cut into *bands* at every block's top and bottom edge and at every tile row edge.
//! Inside a band every row is the same list of *spans*, runs of consecutive sample pixels
//! whose sample row advances by one a row. So a row costs one copy per span, and the seams
//! (neighbours whose sample coordinates are not consecutive) are found per band and per band
//! boundary, never per pixel.

use super::{Block, ChaosMosaic};
use crate::texture::wrap;
use std::ops::Range;

/// A block at unwrapped texture coordinates (the torus unrolled around a region).
#[derive(Clone, Copy, Debug, PartialEq, Eq, PartialOrd, Ord)]
pub(super) struct Placed {
    /// The sequence number, first so that placements sort into paste order.
    pub id: u32,
    pub x: i64,
    pub y: i64,
    pub block: Block,
}

/// Columns `[x, end)` of a band's rows, copied from sample columns `sx..` of sample row `sy`
/// in the band's first row (`sy + k` in its k-th row).
#[derive(Clone, Copy, Debug)]
pub(super) struct Span {
    pub x: usize,
    pub end: usize,
    pub sx: u32,
    pub sy: u32,
}

/// Rows `[y0, y1)` of a layout, all made of the same spans.
#[derive(Clone, Debug)]
pub(super) struct Band {
    pub y0: usize,
    pub y1: usize,
    spans: Range<usize>,
}

/// A seam between rows `b − 1` and `b` over columns `[from, to)`.
#[derive(Clone, Copy, Debug)]
pub(super) struct RowSeam {
    pub b: usize,
    pub from: usize,
    pub to: usize,
}

/// The unfiltered mosaic over `[x0, x0 + w) × [y0, y0 + h)`, as bands of spans.
pub(super) struct Layout {
    pub bands: Vec<Band>,
    spans: Vec<Span>,
}

impl Layout {
    pub fn spans(&self, band: &Band) -> &[Span] {
        &self.spans[band.spans.clone()]
    }
}

impl ChaosMosaic {
    /// Every placement of a block whose rectangle meets `[x0, x0+w) × [y0, y0+h)`, in
    /// sequence order: the blocks whose corner lies in the tiles under the rectangle or one
    /// tile left of or above it (a block is never larger than a tile), each once per unrolled
    /// copy of its home tile.
    pub(super) fn placements(&self, x0: i64, y0: i64, w: u64, h: u64) -> Vec<Placed> {
        let (sw, sh) = (self.sample.width as i64, self.sample.height as i64);
        let (tiles_x, tiles_y) = (self.params.tiles_x as i64, self.params.tiles_y as i64);
        let (x1, y1) = (x0 + w as i64, y0 + h as i64);
        let (tx0, ty0) = (x0.div_euclid(sw) - 1, y0.div_euclid(sh) - 1);
        let unrolled: Vec<(i64, i64)> = (ty0..=(y1 - 1).div_euclid(sh))
            .flat_map(|ty| (tx0..=(x1 - 1).div_euclid(sw)).map(move |tx| (tx, ty)))
            .collect();
        let homes: Vec<(u32, u32)> =
            unrolled.iter().map(|&(tx, ty)| (tx.rem_euclid(tiles_x) as u32, ty.rem_euclid(tiles_y) as u32)).collect();
        let mut out = Vec::new();
        self.homes.with_homed(&homes, |lists| {
            for ((&(tx, ty), &(htx, hty)), list) in unrolled.iter().zip(&homes).zip(lists) {
                // The home tile's blocks lie in it: the unrolled corner is the tile's plus the
                // corner's place in the tile.
                let (dx, dy) = ((tx - htx as i64) * sw, (ty - hty as i64) * sh);
                for n in list.iter() {
                    let b = n.block;
                    let (px, py) = (b.s as i64 + dx, b.t as i64 + dy);
                    if px < x1 && px + b.w as i64 > x0 && py < y1 && py + b.h as i64 > y0 {
                        out.push(Placed { id: n.id, x: px, y: py, block: b });
                    }
                }
            }
        });
        sort_in_sequence(&mut out);
        out
    }

    /// The layout of the unfiltered mosaic over `[x0, x0+w) × [y0, y0+h)`.
    pub(super) fn layout(&self, x0: i64, y0: i64, w: usize, h: usize) -> Layout {
        let (sw, sh) = (self.sample.width as usize, self.sample.height as usize);
        let placed = self.placements(x0, y0, w as u64, h as u64);
        let inside = |e: i64| (e > 0 && e < h as i64).then_some(e as usize);
        let mut cuts = vec![0, h];
        cuts.extend(((sh - wrap(y0, sh as u64) as usize) % sh..h).step_by(sh));
        for p in &placed {
            let b = &p.block;
            cuts.extend([p.y - y0, p.y + b.h as i64 - y0].into_iter().filter_map(inside));
        }
        cuts.sort_unstable();
        cuts.dedup();

        let (sx0, sy0) = (wrap(x0, sw as u64) as usize, wrap(y0, sh as u64) as usize);
        let mut layout = Layout { bands: Vec::with_capacity(cuts.len()), spans: Vec::new() };
        let (mut row, mut scratch) = (Vec::new(), Vec::new());
        for rows in cuts.windows(2) {
            let (ya, yb) = (rows[0], rows[1]);
            // The tiling T, one span per sample tile crossed.
            row.clear();
            let sy = ((sy0 + ya) % sh) as u32;
            let (mut x, mut sx) = (0, sx0);
            while x < w {
                let n = (sw - sx).min(w - x);
                row.push(Span { x, end: x + n, sx: sx as u32, sy });
                (x, sx) = (x + n, 0);
            }
            // The blocks covering the band (a block meeting it covers it: its edges are cuts).
            let (top, bottom) = (y0 + ya as i64, y0 + yb as i64);
            for p in &placed {
                let b = &p.block;
                if p.y <= top && p.y + b.h as i64 >= bottom {
                    let (from, to) = ((p.x - x0).max(0) as usize, (p.x + b.w as i64 - x0).min(w as i64) as usize);
                    let sx = b.x as u32 + (x0 + from as i64 - p.x) as u32;
                    let sy = b.y as u32 + (top - p.y) as u32;
                    paint(&mut row, Span { x: from, end: to, sx, sy }, &mut scratch);
                }
            }
            let start = layout.spans.len();
            layout.spans.extend_from_slice(&row);
            layout.bands.push(Band { y0: ya, y1: yb, spans: start..layout.spans.len() });
        }
        layout
    }

    /// Copies row `y` of `band` (unfiltered) into `out`, one sample run per span.
    #[inline]
    pub(super) fn fill_row(&self, layout: &Layout, band: &Band, y: usize, out: &mut [u32]) {
        let sw = self.sample.width as usize;
        let dy = (y - band.y0) as u32;
        for s in layout.spans(band) {
            let at = (s.sy + dy) as usize * sw + s.sx as usize;
            out[s.x..s.end].copy_from_slice(&self.sample.px[at..at + s.end - s.x]);
        }
    }

    /// The seams inside the rows of `band`: column boundaries `b` (between `b − 1` and `b`).
    pub(super) fn column_seams<'a>(&'a self, layout: &'a Layout, band: &Band) -> impl Iterator<Item = usize> + 'a {
        layout.spans(band).windows(2).filter_map(move |pair| {
            let (l, r) = (pair[0], pair[1]);
            let last = pack(l.sx + (l.end - l.x - 1) as u32, l.sy);
            (!self.continues_x(last, pack(r.sx, r.sy))).then_some(r.x)
        })
    }

    /// The seams between bands, sorted by row boundary.
    pub(super) fn row_seams(&self, layout: &Layout) -> Vec<RowSeam> {
        let mut seams = Vec::new();
        for pair in layout.bands.windows(2) {
            let (above, below) = (&pair[0], &pair[1]);
            let (a, c) = (layout.spans(above), layout.spans(below));
            let last_row = (above.y1 - 1 - above.y0) as u32;
            let (mut i, mut j) = (0, 0);
            while i < a.len() && j < c.len() {
                let (u, v) = (a[i], c[j]);
                let (from, to) = (u.x.max(v.x), u.end.min(v.end));
                // Both spans step one sample column a column: one test holds for the overlap.
                let up = pack(u.sx + (from - u.x) as u32, u.sy + last_row);
                if !self.continues_y(up, pack(v.sx + (from - v.x) as u32, v.sy)) {
                    seams.push(RowSeam { b: below.y0, from, to });
                }
                i += (u.end <= v.end) as usize;
                j += (v.end <= u.end) as usize;
            }
        }
        seams
    }

    /// True when the pixel with sample coordinate `b` may follow `a` to its right unseamed
    /// (wrapping counts as consecutive only for a seamless sample).
    #[inline]
    fn continues_x(&self, a: u32, b: u32) -> bool {
        b == a.wrapping_add(1) || (self.seamless && a & 0xffff == self.sample.width - 1 && b == a & 0xffff_0000)
    }

    /// True when the pixel with sample coordinate `b` may follow `a` below it unseamed.
    #[inline]
    fn continues_y(&self, a: u32, b: u32) -> bool {
        b == a.wrapping_add(1 << 16) || (self.seamless && a >> 16 == self.sample.height - 1 && b == a & 0xffff)
    }
}

/// Sorts placements as `sort_unstable` does (by sequence number, then place), by a radix
/// sort of the sequence numbers: placements of one block (a region wider than the torus) are
/// then put in order among themselves.
fn sort_in_sequence(v: &mut Vec<Placed>) {
    const BITS: u32 = 11;
    if v.len() < 256 {
        v.sort_unstable();
        return;
    }
    let max = v.iter().map(|p| p.id).max().unwrap_or(0);
    let mut scratch = v.clone();
    let mut shift = 0;
    while shift == 0 || (shift < u32::BITS && max >> shift != 0) {
        let mut at = [0usize; 1 << BITS];
        let digit = |p: &Placed| (p.id >> shift) as usize & ((1 << BITS) - 1);
        v.iter().for_each(|p| at[digit(p)] += 1);
        let mut sum = 0;
        for a in at.iter_mut() {
            (*a, sum) = (sum, sum + *a);
        }
        for p in v.iter() {
            let d = digit(p);
            scratch[at[d]] = *p;
            at[d] += 1;
        }
        std::mem::swap(v, &mut scratch);
        shift += BITS;
    }
    v.chunk_by_mut(|a, b| a.id == b.id).filter(|run| run.len() > 1).for_each(|run| run.sort_unstable());
}

/// A sample coordinate packed as `sy << 16 | sx`.
fn pack(sx: u32, sy: u32) -> u32 {
    sy << 16 | sx
}

/// Pastes `new` over the sorted, gapless `spans`, cutting the spans it overlaps.
fn paint(spans: &mut Vec<Span>, new: Span, scratch: &mut Vec<Span>) {
    scratch.clear();
    let mut pasted = false;
    for &s in spans.iter() {
        if s.x < new.x {
            scratch.push(Span { end: s.end.min(new.x), ..s });
        }
        if s.end > new.end {
            if !pasted {
                scratch.push(new);
                pasted = true;
            }
            let x = s.x.max(new.end);
            scratch.push(Span { x, sx: s.sx + (x - s.x) as u32, ..s });
        }
    }
    if !pasted {
        scratch.push(new);
    }
    std::mem::swap(spans, scratch);
}

#[cfg(test)]
mod tests {
    use super::{sort_in_sequence, Block, Placed};

    #[test]
    fn the_radix_sort_orders_placements_like_a_full_sort() {
        for n in [0u32, 5, 300, 5000] {
            // Sequence numbers up to 2^22 with repeats (one block placed several times).
            let mut v: Vec<Placed> = (0..n)
                .map(|i| {
                    let h = crate::hash::hash4(7, i as u64, n as i64, 0);
                    Placed {
                        id: (h % (1 << 22)) as u32 / (1 + (i % 3) * 1000),
                        x: (h >> 40) as i64 % 7 - 3,
                        y: i as i64 % 5,
                        block: Block { x: i as u16, ..Block::default() },
                    }
                })
                .collect();
            let mut want = v.clone();
            want.sort_unstable();
            sort_in_sequence(&mut v);
            assert_eq!(v, want, "n {n}");
        }
    }
}
