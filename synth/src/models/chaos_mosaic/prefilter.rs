//! Mip levels without brute force (DESIGN §3.3).
//!
//! Levels 1..=[`EXACT_LEVELS`] are computed exactly: the level-0 footprint is rendered and
//! box-filtered 2×2 at a time, the reference filter itself (cost 4^L a pixel).
//!
//! Coarser levels integrate the sample directly. Every layer of the mosaic — the tiling and
//! each pasted block — shows the sample translated, so the sum of a footprint that lies
//! inside one layer is a box sum of the periodically extended sample, O(1) from a summed-area
//! table. A footprint whose neighbourhood holds no seam is therefore exact (to rounding); one
//! that straddles seams is split into 4 × 4 cells, each integrated with the layer at its
//! centre. The cost is a few table look-ups a pixel at every level, so the coarsest level of a
//! 100k × 100k texture costs no more than level 4.

use super::ChaosMosaic;
use crate::{mip, pixels::Rgba8Image, texture::level_size, Region};

/// Levels computed by rendering level 0 and downsampling (exact, bit for bit).
pub const EXACT_LEVELS: u32 = 2;
/// Cells per axis for footprints that straddle seams.
const CELLS: i64 = 4;

/// Box sums of the sample extended periodically over the whole plane.
pub(super) struct PeriodicSums {
    w: i64,
    h: i64,
    /// `table[y][x]` = sum of sample[0..y][0..x], (w+1) × (h+1) entries.
    table: Vec<[i64; 4]>,
}

impl PeriodicSums {
    pub fn new(sample: &Rgba8Image) -> Self {
        let (w, h) = (sample.width as usize, sample.height as usize);
        let mut table = vec![[0i64; 4]; (w + 1) * (h + 1)];
        for y in 0..h {
            let mut row = [0i64; 4];
            for x in 0..w {
                let p = sample.pixel(x as u32, y as u32);
                for c in 0..4 {
                    row[c] += p[c] as i64;
                    table[(y + 1) * (w + 1) + x + 1][c] = table[y * (w + 1) + x + 1][c] + row[c];
                }
            }
        }
        Self { w: w as i64, h: h as i64, table }
    }

    #[inline]
    fn corner(&self, x: i64, y: i64) -> [i64; 4] {
        self.table[(y * (self.w + 1) + x) as usize]
    }

    /// Sum over [0, x) × [0, y) of the periodic sample, for any integers (negative too).
    #[inline]
    fn prefix(&self, x: i64, y: i64) -> [i64; 4] {
        let (qx, rx, qy, ry) = (x.div_euclid(self.w), x.rem_euclid(self.w), y.div_euclid(self.h), y.rem_euclid(self.h));
        let (all, cols, rows, part) =
            (self.corner(self.w, self.h), self.corner(self.w, ry), self.corner(rx, self.h), self.corner(rx, ry));
        std::array::from_fn(|c| qx * qy * all[c] + qx * cols[c] + qy * rows[c] + part[c])
    }

    /// Sum over [x0, x1) × [y0, y1) of the periodic sample.
    #[inline]
    pub fn box_sum(&self, x0: i64, y0: i64, x1: i64, y1: i64) -> [i64; 4] {
        let (a, b, c, d) = (self.prefix(x1, y1), self.prefix(x0, y1), self.prefix(x1, y0), self.prefix(x0, y0));
        std::array::from_fn(|i| a[i] - b[i] - c[i] + d[i])
    }
}

impl ChaosMosaic {
    /// Renders a level ≥ 1.
    pub(super) fn render_prefiltered(&self, region: &Region, out: &mut [u8]) {
        if region.level <= EXACT_LEVELS {
            self.render_exact(region, out);
            return;
        }
        let (lw, lh) = level_size(self.width, self.height, region.level);
        for j in 0..region.height as i64 {
            for i in 0..region.width as i64 {
                let x = (region.x + i).rem_euclid(lw as i64);
                let y = (region.y + j).rem_euclid(lh as i64);
                let px = self.footprint_mean(region.level, x, y);
                let o = ((j * region.width as i64 + i) * 4) as usize;
                out[o..o + 4].copy_from_slice(&px);
            }
        }
    }

    /// Exact levels: render the level-0 footprint and apply the reference 2×2 filter L times.
    /// The region is cut where it wraps so that every footprint is aligned.
    fn render_exact(&self, region: &Region, out: &mut [u8]) {
        let (lw, lh) = level_size(self.width, self.height, region.level);
        let f = 1i64 << region.level;
        let mut dst = Rgba8Image::new(region.width, region.height);
        for (oy, ly, ny) in wrap_runs(region.y, region.height, lh) {
            for (ox, lx, nx) in wrap_runs(region.x, region.width, lw) {
                let (x0, x1) = (lx as i64 * f, ((lx + nx as u64) as i64 * f).min(self.width as i64));
                let (y0, y1) = (ly as i64 * f, ((ly + ny as u64) as i64 * f).min(self.height as i64));
                let mut full = Rgba8Image::new((x1 - x0) as u32, (y1 - y0) as u32);
                self.render_level0(x0, y0, full.width, full.height, &mut full.data);
                dst.blit(&mip::downsample_n(&full, region.level), ox, oy);
            }
        }
        out.copy_from_slice(&dst.data);
    }

    /// The mean colour of level-L pixel (x, y)'s footprint on level 0.
    fn footprint_mean(&self, level: u32, x: i64, y: i64) -> [u8; 4] {
        let f = 1i64 << level;
        let (x0, y0) = (x * f, y * f);
        let (x1, y1) = ((x0 + f).min(self.width as i64), (y0 + f).min(self.height as i64));
        let area = (x1 - x0) * (y1 - y0);
        let sum = match self.uniform_offset(x0, y0, x1, y1) {
            Some((ox, oy)) => self.sums.box_sum(x0 + ox, y0 + oy, x1 + ox, y1 + oy),
            None => {
                let mut acc = [0i64; 4];
                for cy in 0..CELLS {
                    let (b0, b1) = (y0 + (y1 - y0) * cy / CELLS, y0 + (y1 - y0) * (cy + 1) / CELLS);
                    for cx in 0..CELLS {
                        let (a0, a1) = (x0 + (x1 - x0) * cx / CELLS, x0 + (x1 - x0) * (cx + 1) / CELLS);
                        if a0 == a1 || b0 == b1 {
                            continue;
                        }
                        let (ox, oy) = self.offset_at((a0 + a1) / 2, (b0 + b1) / 2);
                        let s = self.sums.box_sum(a0 + ox, b0 + oy, a1 + ox, b1 + oy);
                        for c in 0..4 {
                            acc[c] += s[c];
                        }
                    }
                }
                acc
            }
        };
        sum.map(|s| ((s + area / 2) / area) as u8)
    }

    /// The translation from texture to (periodic) sample coordinates of the top layer at a
    /// level-0 point of the torus.
    fn offset_at(&self, x: i64, y: i64) -> (i64, i64) {
        let (sw, sh) = (self.sample.width as i64, self.sample.height as i64);
        for &id in self.index.blocks((x / sw) as u32, (y / sh) as u32).iter().rev() {
            let b = &self.blocks[id as usize];
            let u = (x - b.s as i64).rem_euclid(self.width as i64);
            let v = (y - b.t as i64).rem_euclid(self.height as i64);
            if u < b.w as i64 && v < b.h as i64 {
                return (b.x as i64 + u - x, b.y as i64 + v - y);
            }
        }
        (0, 0)
    }

    /// The translation shared by every pixel near a footprint, when one layer covers the
    /// footprint and the filter's reach around it with no seam; `None` otherwise.
    fn uniform_offset(&self, x0: i64, y0: i64, x1: i64, y1: i64) -> Option<(i64, i64)> {
        let r = self.params.filter_width as i64 + 1;
        let (sw, sh) = (self.sample.width as i64, self.sample.height as i64);
        if x1 - x0 + 2 * r > sw / 2 || y1 - y0 + 2 * r > sh / 2 {
            return None;
        }
        let (ex0, ey0, ex1, ey1) = (x0 - r, y0 - r, x1 + r, y1 + r);
        let placed = self.placements(ex0, ey0, (ex1 - ex0) as u64, (ey1 - ey0) as u64);
        match placed.last() {
            None => {
                let one_tile =
                    ex0.div_euclid(sw) == (ex1 - 1).div_euclid(sw) && ey0.div_euclid(sh) == (ey1 - 1).div_euclid(sh);
                (self.seamless || one_tile).then_some((0, 0))
            }
            Some(p) => {
                let b = &self.blocks[p.id as usize];
                let covers = p.x <= ex0 && p.y <= ey0 && p.x + b.w as i64 >= ex1 && p.y + b.h as i64 >= ey1;
                covers.then_some((b.x as i64 - p.x, b.y as i64 - p.y))
            }
        }
    }
}

/// Splits `count` pixels starting at `start` on a torus of `period` into runs that do not
/// wrap: (offset in the run's output, wrapped start, length).
fn wrap_runs(start: i64, count: u32, period: u64) -> impl Iterator<Item = (u32, u64, u32)> {
    let mut done = 0u32;
    std::iter::from_fn(move || {
        (done < count).then(|| {
            let at = (start + done as i64).rem_euclid(period as i64) as u64;
            let n = ((period - at) as u32).min(count - done);
            let run = (done, at, n);
            done += n;
            run
        })
    })
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
    fn wrap_runs_cover_the_region() {
        let runs: Vec<_> = wrap_runs(-3, 12, 5).collect();
        assert_eq!(runs, vec![(0, 2, 3), (3, 0, 5), (8, 0, 4)]);
    }
}
