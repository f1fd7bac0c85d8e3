//! The LCM texture: layers over a background, mapped to colour, evaluated region by region.
//!
//! Level L of the texture shifts every layer down L resolutions (paper §2.4): layer n renders
//! at resolution K + magnify − n − L with the element copy of that resolution, so coarse
//! levels cost no more than fine ones and are prefiltered by construction.

use super::colour::Colour;
use super::element::Copies;
use super::layer::{Counter, Layer, NoCount};
use crate::texture::{level_size, wrap};
use crate::{Domain, Never, Region, Stop, Texture};

/// A loaded, validated LCM texture.
#[derive(Debug)]
pub struct LcmTexture {
    pub(super) k: u32,
    pub(super) magnify: u32,
    /// One set of element copies per intensity plane.
    pub(super) copies: Vec<Copies>,
    /// Layers in order of application.
    pub(super) layers: Vec<Layer>,
    /// Background intensity per plane (Q20), added last.
    pub(super) background: Vec<i64>,
    pub(super) colour: Colour,
    /// The true period (px at level 0) and the served size, a multiple of it.
    pub(super) period: (u64, u64),
    pub(super) size: (u64, u64),
}

impl LcmTexture {
    /// The texture's period in pixels at level 0 (x, y): the least common multiple of its
    /// layers' periods (LCM period × replication spacing).
    pub fn period(&self) -> (u64, u64) {
        self.period
    }

    /// Each layer's own period in pixels at level 0 — its LCM's smallest period times its
    /// replication spacing — by the paper's layer number, layer 0 (the largest elements) first.
    pub fn layer_periods(&self) -> Vec<(u32, (u64, u64))> {
        let mut periods: Vec<(u32, (u64, u64))> = self
            .layers
            .iter()
            .map(|l| {
                let spacing = 1u64 << (self.k + self.magnify - l.index - 1);
                let (dx, dy) = super::period::mask_period(&l.codes, l.w, l.h);
                (l.index, (dx * spacing, dy * spacing))
            })
            .collect();
        periods.sort_by_key(|p| p.0);
        periods
    }

    /// Number of intensity planes (1 with a palette, 3 for RGB).
    pub fn planes(&self) -> usize {
        self.copies.len()
    }

    /// Number of layers.
    pub fn layer_count(&self) -> usize {
        self.layers.len()
    }

    /// The resolution of `layer` at `level` (may be ≤ 0: then it is evaluated prefiltered).
    fn resolution(&self, layer: &Layer, level: u32) -> i64 {
        (self.k + self.magnify) as i64 - layer.index as i64 - level as i64
    }

    /// Renders `region` while `cnt` counts the work of every pixel (row by row).
    pub fn render_counted<C: Counter + RowCounter>(&self, region: &Region, out: &mut [u8], cnt: &mut C) {
        self.render_rows(region, out, cnt, &Never);
    }

    /// Renders `region` a row at a time, polling `stop` before each row and returning once it
    /// is requested.
    fn render_rows<C: Counter + RowCounter>(&self, region: &Region, out: &mut [u8], cnt: &mut C, stop: &dyn Stop) {
        let (lw, lh) = level_size(self.size.0, self.size.1, region.level);
        let width = region.width as usize;
        // Runs of the row that do not cross the torus seam: (first x on the level, length).
        let mut runs = Vec::new();
        let (mut x, mut left) = (wrap(region.x, lw), width as u64);
        while left > 0 {
            let n = (lw - x).min(left);
            runs.push((x, n as usize));
            left -= n;
            x = 0;
        }
        let mut planes = vec![vec![0i64; width]; self.copies.len()];
        for row in 0..region.height as usize {
            if stop.requested() {
                return;
            }
            let y = wrap(region.y + row as i64, lh);
            cnt.start_row(width);
            planes.iter_mut().for_each(|p| p.fill(0));
            for (n, layer) in self.layers.iter().enumerate() {
                let r = self.resolution(layer, region.level);
                let mut cx = 0;
                for &(x0, len) in &runs {
                    let mut seg: Vec<&mut [i64]> = planes.iter_mut().map(|p| &mut p[cx..cx + len]).collect();
                    if r >= 1 {
                        layer.apply_native(&self.copies, r as u32, y, x0, &mut seg, None, n == 0, cnt, cx);
                    } else {
                        layer.apply_prefiltered(&self.copies, r, y, x0, &mut seg);
                    }
                    cx += len;
                }
            }
            // The final step (§2.2): the background intensity.
            for (acc, &background) in planes.iter_mut().zip(&self.background) {
                for (x, a) in acc.iter_mut().enumerate() {
                    *a += background;
                    cnt.add(x, 1);
                }
            }
            cnt.end_row();
            self.colour.write_row(&planes, &mut out[row * width * 4..(row + 1) * width * 4]);
        }
    }
}

/// Row boundaries for counters that keep per-pixel tallies.
pub trait RowCounter {
    #[inline]
    fn start_row(&mut self, _width: usize) {}
    #[inline]
    fn end_row(&mut self) {}
}
impl RowCounter for NoCount {}

impl Texture for LcmTexture {
    fn model(&self) -> &'static str {
        super::MODEL
    }
    fn width(&self) -> u64 {
        self.size.0
    }
    fn height(&self) -> u64 {
        self.size.1
    }
    fn domain(&self) -> Domain {
        Domain::Torus
    }
    fn render(&self, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        self.render_rows(region, out, &mut NoCount, stop);
    }
}

/// Operation counts per pixel of a rendered region (paper §6 counts additions and
/// multiplications, excluding the look-up of the replication pixels).
#[derive(Clone, Debug, Default)]
pub struct OpCount {
    adds: Vec<u32>,
    muls: Vec<u32>,
    touch: Vec<u32>,
    pub pixels: u64,
    pub total_adds: u64,
    pub total_muls: u64,
    pub max_adds: u32,
    pub max_muls: u32,
    /// Most replications of one layer seen at one pixel.
    pub max_touch: u32,
}

impl Counter for OpCount {
    fn add(&mut self, x: usize, n: u32) {
        self.adds[x] += n;
    }
    fn mul(&mut self, x: usize, n: u32) {
        self.muls[x] += n;
    }
    fn touch(&mut self, x: usize, k: u32) {
        self.touch[x] = self.touch[x].max(k);
    }
}

impl RowCounter for OpCount {
    fn start_row(&mut self, width: usize) {
        for v in [&mut self.adds, &mut self.muls, &mut self.touch] {
            v.clear();
            v.resize(width, 0);
        }
    }
    fn end_row(&mut self) {
        self.pixels += self.adds.len() as u64;
        self.total_adds += self.adds.iter().map(|&a| a as u64).sum::<u64>();
        self.total_muls += self.muls.iter().map(|&a| a as u64).sum::<u64>();
        self.max_adds = self.max_adds.max(self.adds.iter().copied().max().unwrap_or(0));
        self.max_muls = self.max_muls.max(self.muls.iter().copied().max().unwrap_or(0));
        self.max_touch = self.max_touch.max(self.touch.iter().copied().max().unwrap_or(0));
    }
}

impl OpCount {
    pub fn mean_adds(&self) -> f64 {
        self.total_adds as f64 / self.pixels.max(1) as f64
    }
    pub fn mean_muls(&self) -> f64 {
        self.total_muls as f64 / self.pixels.max(1) as f64
    }
}
