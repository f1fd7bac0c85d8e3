//! Mip levels without brute force: each level approximates the 2×2-box downsample of the
//! level below, which a 100k texture cannot afford to compute.
//!
//! Levels 1..=[`EXACT_LEVELS`] are computed exactly: the level-0 footprint is rendered and
//! box-filtered 2×2 at a time, the reference filter itself (cost 4^L a pixel).
//!
//! Coarser levels integrate the sample directly. Every layer of the mosaic — the tiling and
//! each pasted block — shows the sample translated, so the sum of a footprint that lies
//! inside one layer is a box sum of the periodically extended sample, O(1) from a summed-area
//! table. A footprint whose neighbourhood holds no seam is therefore exact (to rounding); one
//! that straddles seams is split into 4 × 4 cells (one once it spans half a sample), each
//! integrated with the layer at its centre, and cells of one layer are merged into one box
//! (tables of box sums at every power-of-two side, cached in the model). The cost is a few
//! table look-ups a pixel at every level, so the coarsest level of a 100k × 100k texture costs
//! no more than level 4.

use super::homes::Indexed;
use super::render::ChaosMosaic;
use super::sums::{pack, BoxTable};
use crate::{mip, pixels::Rgba8Image, texture::level_size, Region, Stop};

/// Levels computed by rendering level 0 and downsampling (exact, bit for bit).
pub const EXACT_LEVELS: u32 = 1;

/// Cells per axis for footprints that straddle seams and span less than half a sample.
const CELLS: i64 = 4;

/// How [`ChaosMosaic::integrate`] works, for tests that show every way gives the same result.
#[derive(Clone, Copy, Default)]
struct Paths {
    /// Cell layers rasterized from the blocks (`Some(true)`) or looked up through the tile
    /// index (`Some(false)`); `None` picks the cheaper way.
    rasterize: Option<bool>,
    /// Every footprint summed cell by cell with the division by its area, no merged cells.
    general: bool,
}

impl ChaosMosaic {
    /// Renders a level ≥ 1; `None` once `stop` is requested.
    pub(super) fn render_prefiltered(&self, region: &Region, out: &mut [u8], stop: &dyn Stop) -> Option<()> {
        let (lw, lh) = level_size(self.width, self.height, region.level);
        let f = 1i64 << region.level;
        for (oy, ly, ny) in pieces(region.y, region.height, lh) {
            for (ox, lx, nx) in pieces(region.x, region.width, lw) {
                let row = nx as usize * 4;
                let mut put = |data: &[u8]| {
                    for (j, src) in data.chunks_exact(row).enumerate() {
                        let at = ((oy as usize + j) * region.width as usize + ox as usize) * 4;
                        out[at..at + row].copy_from_slice(src);
                    }
                };
                if region.level <= EXACT_LEVELS {
                    // The level-0 footprint, filtered by the reference 2×2 filter L times.
                    let (x0, x1) = (lx as i64 * f, ((lx + nx as u64) as i64 * f).min(self.width as i64));
                    let (y0, y1) = (ly as i64 * f, ((ly + ny as u64) as i64 * f).min(self.height as i64));
                    let mut full = Rgba8Image::new((x1 - x0) as u32, (y1 - y0) as u32);
                    self.render_level0(x0, y0, full.width, full.height, &mut full.data, stop)?;
                    put(&mip::downsample_n(&full, region.level).data);
                } else {
                    put(self
                        .integrate(region.level, lx as i64, ly as i64, nx, ny, Paths::default(), stop)?
                        .as_flattened());
                }
            }
        }
        Some(())
    }

    /// Level-`level` pixels [lx, lx+nx) × [ly, ly+ny), which must not wrap, by integration.
    ///
    /// First every pixel is classified by rasterizing the blocks near it in sequence order:
    /// a pixel is *clean* when one layer covers its footprint grown by the filter's reach
    /// (then the last block to touch that neighbourhood covers it whole); otherwise *dirty*.
    /// `rasterize` forces how cells find their layers (the two ways give the same result);
    /// `None` picks the cheaper one. Polls `stop` a band of rows at a time: `None` once it is
    /// requested.
    #[allow(clippy::too_many_arguments)]
    fn integrate(
        &self,
        level: u32,
        lx: i64,
        ly: i64,
        nx: u32,
        ny: u32,
        paths: Paths,
        stop: &dyn Stop,
    ) -> Option<Vec<[u8; 4]>> {
        let f = 1i64 << level;
        let (nx, ny) = (nx as usize, ny as usize);
        let (tw, th) = (self.width as i64, self.height as i64);
        let (sw, sh) = (self.sample.width as i64, self.sample.height as i64);
        let span = |i: i64, lo: i64, n: i64| ((lo + i) * f, ((lo + i + 1) * f).min(n));
        let reach = self.params.filter_width as i64 + 1;
        let (x0, x1) = (lx * f, ((lx + nx as i64) * f).min(tw));
        let (y0, y1) = (ly * f, ((ly + ny as i64) * f).min(th));
        // Three regimes by footprint size: small footprints are classified and rasterized from
        // the blocks near the region; footprints up to two sample periods take the layer of
        // each cell, from the blocks rasterized onto the cells or, when the region holds more
        // blocks than cells, looked up per cell through the tile index; larger ones span so
        // many blocks that each box of the periodic sample is the tiling's own mean to within
        // a level, so blocks are skipped.
        let fine = f + 2 * reach <= sw.min(sh) / 2;
        let coarse = f >= 2 * sw.max(sh);
        // One cell from half a sample on: 4× fewer layer look-ups through the tile index, for
        // a small loss of accuracy at the levels where a footprint spans half a sample.
        let cells = if 2 * f >= sw.min(sh) { 1 } else { CELLS.min(f / 2) } as usize;
        let cheaper = || {
            let tiles_met = ((x1 - x0 + 2 * reach) / sw + 2) as u64 * ((y1 - y0 + 2 * reach) / sh + 2) as u64;
            let (entries, tiles) = self.homes.indexed().index.blocks_per_tile();
            4 * tiles_met * entries / tiles < (nx * ny * cells * cells) as u64
        };
        let rasterize = fine || (!coarse && paths.rasterize.unwrap_or_else(cheaper));
        let placed = match rasterize {
            true => self.placements(x0 - reach, y0 - reach, (x1 - x0 + 2 * reach) as u64, (y1 - y0 + 2 * reach) as u64),
            false => Vec::new(),
        };

        const DIRTY: u32 = u32::MAX;
        const BACKGROUND: u32 = u32::MAX - 1;
        let mut state = vec![if coarse { BACKGROUND } else { DIRTY }; nx * ny];
        if fine {
            // Background where no tile edge is near, or none is a seam.
            let one_tile = |i: usize, lo: i64, extent: i64, side: i64| {
                let (a, b) = span(i as i64, lo, extent);
                self.seamless || (a - reach).div_euclid(side) == (b + reach - 1).div_euclid(side)
            };
            let one_col: Vec<bool> = (0..nx).map(|i| one_tile(i, lx, tw, sw)).collect();
            for (j, row) in state.chunks_exact_mut(nx).enumerate() {
                if one_tile(j, ly, th, sh) {
                    row.iter_mut().zip(&one_col).filter(|(_, &one)| one).for_each(|(s, _)| *s = BACKGROUND);
                }
            }
            // Pixels i whose grown footprint [(lo+i)·f − reach, (lo+i+1)·f + reach) meets [a, b).
            let meets = |a: i64, b: i64, lo: i64, n: usize| {
                // f = 2^level: the floor division is a shift.
                ((((a - reach) >> level) - lo).max(0), (((b + reach - 1) >> level) - lo).min(n as i64 - 1))
            };
            // Per placement, the columns whose grown footprint lies inside it, then row by row.
            let mut cols_in = Vec::new();
            for (k, p) in placed.iter().enumerate() {
                let b = &p.block;
                let (bx1, by1) = (p.x + b.w as i64, p.y + b.h as i64);
                let (i0, i1) = meets(p.x, bx1, lx, nx);
                let (j0, j1) = meets(p.y, by1, ly, ny);
                if i0 > i1 {
                    continue;
                }
                cols_in.clear();
                cols_in.extend((i0..=i1).map(|i| {
                    let (fx0, fx1) = span(i, lx, tw);
                    fx0 - reach >= p.x && fx1 + reach <= bx1
                }));
                for j in j0..=j1 {
                    let (fy0, fy1) = span(j, ly, th);
                    let row = &mut state[j as usize * nx..][i0 as usize..=i1 as usize];
                    match fy0 - reach >= p.y && fy1 + reach <= by1 {
                        true => row.iter_mut().zip(&cols_in).for_each(|(s, &c)| *s = if c { k as u32 } else { DIRTY }),
                        false => row.fill(DIRTY),
                    }
                }
            }
        }

        // Dirty pixels are split into cells of at least 2 × 2 level-0 pixels, each integrated
        // with the layer at its centre; once a footprint spans half a sample, it is one cell.
        let centres = |lo: i64, n: usize, extent: i64| -> Vec<(i64, i64, i64)> {
            (0..n as i64)
                .flat_map(|i| {
                    let (a, b) = span(i, lo, extent);
                    (0..cells as i64).map(move |c| {
                        // (b − a)·c ≥ 0 over a power of two: a shift.
                        let k = cells.trailing_zeros();
                        let (c0, c1) = (a + (((b - a) * c) >> k), a + (((b - a) * (c + 1)) >> k));
                        (c0, c1, (c0 + c1) / 2)
                    })
                })
                .collect()
        };
        let (cols, rows) = (centres(lx, nx, tw), centres(ly, ny, th));
        let gw = cols.len();
        // Each label's layer, then each cell's, as packed offsets (0 is the tiling).
        let offsets: Vec<u32> = std::iter::once(0)
            .chain(placed.iter().map(|p| {
                // The placement's corner reduced by a multiplication, then within one period.
                let b = &p.block;
                let (rx, ry) = (self.sums.w.div_rem(p.x).1, self.sums.h.div_rem(p.y).1);
                pack(b.x as i64 - rx, b.y as i64 - ry, sw, sh)
            }))
            .collect();
        // Each placement's cells (the columns and rows whose centres it covers); for the tile
        // index, each cell column's centre, tile and remainder.
        // Centres of full pixels' cells lie every `side` pixels from lo·f + side/2: the count
        // below x is estimated by a shift, then corrected (partial pixels at the texture's edge).
        let side = f / cells as i64;
        let below = |v: &[(i64, i64, i64)], lo: i64, x: i64| {
            let d = x - lo * f - side / 2;
            let mut k = if d <= 0 { 0 } else { ((d + side - 1) >> side.trailing_zeros()).min(v.len() as i64) as usize };
            while k > 0 && v[k - 1].2 >= x {
                k -= 1;
            }
            while k < v.len() && v[k].2 < x {
                k += 1;
            }
            k
        };
        let inside = |v: &[(i64, i64, i64)], lo: i64, a: i64, b: i64| below(v, lo, a)..below(v, lo, b);
        let painted: Vec<_> = placed
            .iter()
            .map(|p| {
                let b = &p.block;
                (inside(&cols, lx, p.x, p.x + b.w as i64), inside(&rows, ly, p.y, p.y + b.h as i64))
            })
            .collect();
        let indexed: Vec<_> = match rasterize || coarse {
            true => Vec::new(),
            false => cols.iter().map(|c| (c.2, (c.2 / sw) as u32, c.2 % sw)).collect(),
        };

        // Box tables for a cell and for 2 × 2, 4 × 4 … cells of one layer (up to the whole
        // footprint), and the cells' and pixels' corners modulo the sample.
        let merges = cells.trailing_zeros() as usize;
        let whole = self.tables.get(&self.sample, f).filter(|_| !paths.general);
        let merged: Option<Vec<&BoxTable>> = match coarse || paths.general {
            true => None,
            false => (0..=merges).map(|t| self.tables.get(&self.sample, side << t)).collect(),
        };
        let cx: Vec<u32> = cols.iter().map(|c| self.sums.w.div_rem(c.0).1 as u32).collect();
        let cy: Vec<u32> = rows.iter().map(|c| self.sums.h.div_rem(c.0).1 as u32).collect();
        // Only the last column can be a partial pixel (at the texture's right edge).
        let full_cols = (0..nx).take_while(|&i| span(i as i64, lx, tw).1 - span(i as i64, lx, tw).0 == f).count();

        // The cells' layers are made a band of pixel rows at a time, about 64 KiB of them, so
        // that they are still in cache when summed; each band paints only its placements.
        let band = (16384 / (gw * cells)).max(1);
        // Each band's placements (those with cell rows in it), in sequence order.
        let band_rows = band * cells;
        let mut in_band = vec![0u32; ny.div_ceil(band) + 1];
        let bands_of = |cj: &std::ops::Range<usize>| match cj.is_empty() {
            true => 0..0,
            false => cj.start / band_rows..(cj.end - 1) / band_rows + 1,
        };
        for (_, cj) in &painted {
            bands_of(cj).for_each(|k| in_band[k + 1] += 1);
        }
        for k in 1..in_band.len() {
            in_band[k] += in_band[k - 1];
        }
        let mut by_band = vec![0u32; in_band[in_band.len() - 1] as usize];
        let mut fill = in_band.clone();
        for (n, (_, cj)) in painted.iter().enumerate() {
            for k in bands_of(cj) {
                by_band[fill[k] as usize] = n as u32;
                fill[k] += 1;
            }
        }
        let mut layer = vec![0u32; if coarse { 0 } else { gw * cells * band.min(ny) }];
        let mut out = vec![[0u8; 4]; nx * ny];
        for j0 in (0..ny).step_by(band) {
            if stop.requested() {
                return None;
            }
            let (j1, r0) = ((j0 + band).min(ny), j0 * cells);
            let r1 = j1 * cells;
            if rasterize {
                layer.fill(0);
                let k = j0 / band;
                for &n in &by_band[in_band[k] as usize..in_band[k + 1] as usize] {
                    let ((ci, cj), o) = (&painted[n as usize], offsets[n as usize + 1]);
                    for j in cj.start.max(r0)..cj.end.min(r1) {
                        layer[(j - r0) * gw + ci.start..(j - r0) * gw + ci.end].fill(o);
                    }
                }
            } else if !coarse {
                // The tile index walked in row order.
                let whole = self.homes.indexed();
                for (cj, &(_, _, y)) in rows.iter().enumerate().take(r1).skip(r0) {
                    let (ty, ym) = ((y / sh) as u32, y % sh);
                    for (l, &(x, tx, xm)) in layer[(cj - r0) * gw..(cj - r0 + 1) * gw].iter_mut().zip(&indexed) {
                        *l = self.layer_at(whole, x, y, tx, ty, (xm, ym));
                    }
                }
            }
            for j in j0..j1 {
                let (fy0, fy1) = span(j as i64, ly, th);
                let cj = j * cells;
                let (state, out) = (&state[j * nx..][..nx], &mut out[j * nx..][..nx]);
                // Full pixels of a full row with tables: a look-up of the mean, or a merged sum
                // and a shift. Coarse regions have neither dirty pixels nor layers.
                let fast = match (fy1 - fy0 == f, whole) {
                    (true, Some(whole)) if merged.is_some() || coarse => {
                        let (rows, tables) = match &merged {
                            Some(tables) => (&layer[(cj - r0) * gw..], tables.as_slice()),
                            None => (&layer[..0], &[][..]),
                        };
                        let cy0 = cy[cj];
                        for (i, (o, &k)) in out[..full_cols].iter_mut().zip(state).enumerate() {
                            let ci = i * cells;
                            *o = match k {
                                DIRTY => merged_mean(&rows[ci..], gw, cells, tables, &cx[ci..], &cy[cj..], f),
                                BACKGROUND => whole.mean_at(cx[ci], cy0, 0),
                                k => whole.mean_at(cx[ci], cy0, offsets[k as usize + 1]),
                            };
                        }
                        full_cols
                    }
                    _ => 0,
                };
                for i in fast..nx {
                    let (fx0, fx1) = span(i as i64, lx, tw);
                    let full = fx1 - fx0 == f && fy1 - fy0 == f;
                    let ci = i * cells;
                    let sum = match state[i] {
                        DIRTY => {
                            let mut acc = [0u64; 4];
                            for (cj, &(y0, y1, _)) in rows.iter().enumerate().skip(cj).take(cells) {
                                for (ci, &(c0, c1, _)) in cols.iter().enumerate().skip(ci).take(cells) {
                                    if c0 < c1 && y0 < y1 {
                                        let s = self.cell_sum((c0, c1), (y0, y1), side, layer[(cj - r0) * gw + ci]);
                                        acc.iter_mut().zip(s).for_each(|(a, s)| *a += s);
                                    }
                                }
                            }
                            acc
                        }
                        k => {
                            let o = if k == BACKGROUND { 0 } else { offsets[k as usize + 1] };
                            match whole {
                                Some(t) if full => t.at(cx[ci], cy[cj], o).map(u64::from),
                                _ => {
                                    let (dx, dy) = ((o & 0xffff) as i64, (o >> 16) as i64);
                                    self.sums.box_sum(fx0 + dx, fy0 + dy, fx1 + dx, fy1 + dy).map(|s| s as u64)
                                }
                            }
                        }
                    };
                    let area = ((fx1 - fx0) * (fy1 - fy0)) as u64;
                    out[i] = sum.map(|s| match full {
                        // area = 4^level: the rounded division is a shift.
                        true => ((s + area / 2) >> (2 * level)) as u8,
                        false => ((s + area / 2) / area) as u8,
                    });
                }
            }
        }
        Some(out)
    }

    /// The sum of cell [c0, c1) × [r0, r1) of the layer with packed `offset`: one look-up when
    /// the cell is `side` pixels square and the sample has tables, else four corners.
    fn cell_sum(&self, (c0, c1): (i64, i64), (r0, r1): (i64, i64), side: i64, offset: u32) -> [u64; 4] {
        let (dx, dy) = ((offset & 0xffff) as i64, (offset >> 16) as i64);
        if c1 - c0 == side && r1 - r0 == side {
            if let Some(t) = self.tables.get(&self.sample, side) {
                return t.sum(c0 + dx, r0 + dy).map(u64::from);
            }
        }
        self.sums.box_sum(c0 + dx, r0 + dy, c1 + dx, r1 + dy).map(|s| s as u64)
    }

    /// The packed offset (see [`pack`]) of the top layer at a level-0 point (x, y) of the
    /// torus, in tile (tx, ty), through the whole index; (xm, ym) is the point modulo the sample.
    #[inline]
    fn layer_at(&self, whole: &Indexed, x: i64, y: i64, tx: u32, ty: u32, (xm, ym): (i64, i64)) -> u32 {
        let (tw, th) = (self.width as i64, self.height as i64);
        let (sw, sh) = (self.sample.width as i64, self.sample.height as i64);
        for &pos in whole.index.blocks(tx, ty).iter().rev() {
            let b = &whole.blocks[pos as usize].block;
            // x and b.s both lie on [0, width): the wrapped difference needs no division.
            let (u, v) = (x - b.s as i64, y - b.t as i64);
            let (u, v) = (u + tw * (u < 0) as i64, v + th * (v < 0) as i64);
            if u < b.w as i64 && v < b.h as i64 {
                // The sample point b + (u, v) and (xm, ym) both lie in the sample.
                let (dx, dy) = (b.x as i64 + u - xm, b.y as i64 + v - ym);
                return ((dy + sh * (dy < 0) as i64) as u32) << 16 | (dx + sw * (dx < 0) as i64) as u32;
            }
        }
        0
    }
}

/// The rounded mean of a full footprint of side `f` split into `n` × `n` cells (n = 1, 2 or
/// 4) whose packed layers are `layer` (rows `gw` apart) and whose corners modulo the sample are
/// `cx`, `cy`. Cells of one layer are merged — the whole footprint, else 2 × 2 cells — into
/// one look-up in `tables[log2 of the merge]`, the same sum, as the merged cells tile a box of
/// that layer; a footprint of one layer reads its mean directly.
#[inline]
fn merged_mean(layer: &[u32], gw: usize, n: usize, tables: &[&BoxTable], cx: &[u32], cy: &[u32], f: i64) -> [u8; 4] {
    let area = (f * f) as u64;
    let round = |s: [u32; 4]| s.map(|v| ((v as u64 + area / 2) >> area.trailing_zeros()) as u8);
    match n {
        4 => {
            let row = |b: usize| -> [u32; 4] { layer[b * gw..b * gw + 4].try_into().unwrap() };
            let l = [row(0), row(1), row(2), row(3)];
            let o = l[0][0];
            // One layer: compared without a branch a cell.
            if l.iter().flatten().fold(0, |d, &v| d | (v ^ o)) == 0 {
                return tables[2].mean_at(cx[0], cy[0], o);
            }
            let (cx, cy): ([u32; 4], [u32; 4]) = (cx[..4].try_into().unwrap(), cy[..4].try_into().unwrap());
            let mut acc = [0u32; 4];
            for b in [0, 2] {
                for a in [0, 2] {
                    let q = [l[b][a], l[b][a + 1], l[b + 1][a], l[b + 1][a + 1]];
                    let s = quad_sum(q, &tables[..2], [cx[a], cx[a + 1]], [cy[b], cy[b + 1]]);
                    acc.iter_mut().zip(s).for_each(|(a, s)| *a += s);
                }
            }
            round(acc)
        }
        2 => {
            let q = [layer[0], layer[1], layer[gw], layer[gw + 1]];
            match q.iter().all(|&v| v == q[0]) {
                true => tables[1].mean_at(cx[0], cy[0], q[0]),
                false => round(quad_sum(q, &tables[..2], [cx[0], cx[1]], [cy[0], cy[1]])),
            }
        }
        _ => tables[0].mean_at(cx[0], cy[0], layer[0]),
    }
}

/// The sum of 2 × 2 cells with layers `q` (row by row): one look-up in `tables[1]` when they
/// share a layer, else one a cell in `tables[0]`.
#[inline]
fn quad_sum(q: [u32; 4], tables: &[&BoxTable], cx: [u32; 2], cy: [u32; 2]) -> [u32; 4] {
    if q[1] == q[0] && q[2] == q[0] && q[3] == q[0] {
        return tables[1].at(cx[0], cy[0], q[0]);
    }
    let t = tables[0];
    let s = [t.at(cx[0], cy[0], q[0]), t.at(cx[1], cy[0], q[1]), t.at(cx[0], cy[1], q[2]), t.at(cx[1], cy[1], q[3])];
    std::array::from_fn(|c| s[0][c] + s[1][c] + s[2][c] + s[3][c])
}

/// Level pixels a side of the pieces a region is rendered in: the blocks placed over a
/// piece's footprint, and an exact level's level-0 footprint, stay bounded whatever the region.
const PIECE: u32 = 256;

/// Splits `count` pixels starting at `start` on a torus of `period` into runs that do not
/// wrap, of at most [`PIECE`] pixels: (offset in the output, wrapped start, length).
fn pieces(start: i64, count: u32, period: u64) -> impl Iterator<Item = (u32, u64, u32)> {
    let mut done = 0u32;
    std::iter::from_fn(move || {
        (done < count).then(|| {
            let at = (start + done as i64).rem_euclid(period as i64) as u64;
            let n = ((period - at) as u32).min(count - done).min(PIECE);
            let run = (done, at, n);
            done += n;
            run
        })
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::Never;

    #[test]
    fn cells_find_the_same_layers_rasterized_or_through_the_index() {
        use crate::models::{self, Inputs};
        let sample = crate::samples::pebbles(40, 6, 3, true);
        let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
        for bpt in [1, 2] {
            let params = serde_json::json!({"tiles_x": 30, "tiles_y": 20, "seed": 5, "blocks_per_tile": bpt});
            let tex = super::super::load(&models::create("chaos-mosaic", "t", &params, &inputs).unwrap()).unwrap();
            // Footprints of 16 and 32 pixels: between the fine and the coarse regimes.
            for (level, lx, ly, n) in [(4, 0, 0, 50), (4, 13, 40, 9), (5, 3, 2, 20)] {
                let rasterized =
                    tex.integrate(level, lx, ly, n, n, Paths { rasterize: Some(true), general: false }, &Never);
                let indexed = Paths { rasterize: Some(false), general: false };
                assert_eq!(rasterized, tex.integrate(level, lx, ly, n, n, indexed, &Never), "level {level} bpt {bpt}");
            }
        }
    }

    #[test]
    fn merged_cells_give_the_cell_by_cell_sums() {
        use crate::models::{self, Inputs};
        for (n, seamless, bpt) in [(40, true, 2), (48, false, 1), (37, false, 2)] {
            let sample = crate::samples::pebbles(n, 6, 3, seamless);
            let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
            let params = serde_json::json!({"tiles_x": 30, "tiles_y": 20, "seed": 5, "blocks_per_tile": bpt});
            let tex = super::super::load(&models::create("chaos-mosaic", "t", &params, &inputs).unwrap()).unwrap();
            for level in 2..=8u32 {
                let (lw, lh) = level_size(tex.width, tex.height, level);
                let (lw, lh) = (lw as i64, lh as i64);
                // A region inside the level and one reaching its partial last pixels.
                for (lx, ly) in [(1, 2), (lw - 20, lh - 20)] {
                    let (lx, ly) = (lx.max(0), ly.max(0));
                    let (nx, ny) = ((lw - lx).min(24) as u32, (lh - ly).min(24) as u32);
                    for rasterize in [Some(true), Some(false), None] {
                        let fast = tex.integrate(level, lx, ly, nx, ny, Paths { rasterize, general: false }, &Never);
                        let general = tex.integrate(level, lx, ly, nx, ny, Paths { rasterize, general: true }, &Never);
                        assert_eq!(fast, general, "n {n} level {level} at ({lx}, {ly}) {rasterize:?}");
                    }
                }
            }
        }
    }

    #[test]
    fn pieces_cover_the_region() {
        let runs: Vec<_> = pieces(-3, 12, 5).collect();
        assert_eq!(runs, vec![(0, 2, 3), (3, 0, 5), (8, 0, 4)]);
        let runs: Vec<_> = pieces(10, 600, 1 << 20).collect();
        assert_eq!(runs, vec![(0, 10, 256), (256, 266, 256), (512, 522, 88)]);
    }
}
