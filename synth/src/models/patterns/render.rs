//! The composed texture: loads and validates an encoding, then evaluates any region of any
//! level and frame, layer by layer, pixel by pixel — each pixel a pure function of
//! (encoding, level, x, y, frame).
//!
//! Filtering (§5): while a level-L pixel stays inside one pattern (2^L ≤ S) it reads that
//! pattern's own mip level L, which is exactly the box downsample for aligned tilings. Beyond
//! one pattern per pixel the indirection level itself is filtered: up to 4 × 4 cells per
//! pixel their exact means are combined as the 2 × 2 box chain would ("oversampling"), and
//! beyond that materials are replaced by their mean colours weighted by their probabilities
//! (the law-of-large-numbers option of §5.1), or by a stratified 4 × 4 sample of cells where
//! no expectation exists (explicit maps, animation, pixel maps).

use super::animation::{AnimationBlock, Context};
use super::materials::ChoiceBlock;
use super::params::{Choice, LayerKind, LayerParams, Params};
use super::plan::{animation, in_layer};
use super::random::LayerRng;
use super::reference::{over_pm, over_u8, Reference};
use super::sigma::{self, RangeTable, Sigma};
use super::sprites::{self, Positioning};
use super::transform::{Placed, TransformBlock};
use super::transitions::{Pick, Transitions};
use super::MODEL;
use crate::texture::{level_size, wrap};
use crate::{bundle::Bundle, Animation, Domain, Error, Region, Result, Stop, Texture};
use std::sync::Arc;

/// Sprites splatted between two polls of the [`Stop`] at levels where they are under a pixel.
const SPRITES_A_POLL: usize = 64;
/// Cells per pixel side up to which coarse levels combine exact cell means.
const OVERSAMPLE: u64 = 4;

pub struct PatternTexture {
    width: u64,
    height: u64,
    reference: Reference,
    background: [u8; 4],
    layers: Vec<Layer>,
    animation: Option<Animation>,
}

struct Layer {
    kind: LayerKind,
    cell: u32,
    grid: (u64, u64),
    rng: LayerRng,
    choice: Option<ChoiceBlock>,
    transform: Option<TransformBlock>,
    transitions: Option<Transitions>,
    animation: Option<AnimationBlock>,
    positioning: Option<Positioning>,
}

impl PatternTexture {
    /// Builds the texture of `bundle`, whose plan has checked it (its size, layer count,
    /// reference header and sprites).
    pub(super) fn load(bundle: &Bundle) -> Result<Self> {
        let p: Params = bundle.params()?;
        let img = crate::pixels::decode_png("reference", bundle.section("reference.png")?)?;
        let reference = Reference::new(&img, p.pattern_size, p.reference[0], p.reference[1])?;
        let tables: Arc<[Sigma]> = sigma::from_bytes(bundle.section("sigma")?)?.into();
        let ranges = sigma::ranges_of(bundle)?;
        if (tables[0].tx, tables[0].ty) != (reference.tx, reference.ty) {
            return Err(Error::bundle(format!(
                "section `sigma`: the pattern table is {}×{} but the reference packs {}×{} patterns",
                tables[0].tx, tables[0].ty, reference.tx, reference.ty
            )));
        }
        let mut layers = Vec::with_capacity(p.layers.len());
        for (i, lp) in p.layers.iter().enumerate() {
            let tables = (tables.clone(), ranges.clone());
            layers.push(Layer::load(i, lp, &p, bundle, &reference, tables).map_err(|e| in_layer(i, e))?);
        }
        let mut periods: Vec<u64> = layers.iter().filter_map(|l| l.animation.as_ref()?.period()).collect();
        periods.extend(sprites::moving_periods(&p.sprites, (p.width, p.height)));
        let animation = animation(&periods, p.fps)?;
        Ok(Self { width: p.width, height: p.height, reference, background: p.background, layers, animation })
    }

    pub fn reference(&self) -> &Reference {
        &self.reference
    }

    /// Grid size (cells) of layer `layer`.
    pub fn grid(&self, layer: usize) -> (u64, u64) {
        self.layers[layer].grid
    }

    /// What tiling layer `layer` shows in cell g at frame t (for tests and tools).
    pub fn pick(&self, layer: usize, gx: u64, gy: u64, t: u32) -> Pick {
        self.layers[layer].pick(gx, gy, t)
    }

    /// The material the (dithered) areas map gives cell g of layer `layer`.
    pub fn material(&self, layer: usize, gx: u64, gy: u64) -> u16 {
        let l = &self.layers[layer];
        l.choice.as_ref().map_or(0, |c| c.material(&l.rng, gx, gy, l.grid))
    }

    /// The pixel map's material at level-0 pixel (x, y) of layer `layer`, if it has one.
    pub fn pixel_material(&self, layer: usize, x: u64, y: u64) -> Option<u16> {
        self.layers[layer].choice.as_ref()?.pixel_map().map(|p| p.at(x, y))
    }
}

impl Layer {
    fn load(
        i: usize,
        lp: &LayerParams,
        p: &Params,
        bundle: &Bundle,
        reference: &Reference,
        (tables, ranges): (Arc<[Sigma]>, Arc<[RangeTable]>),
    ) -> Result<Self> {
        let c = lp.cell as u64;
        if c == 0 || p.width % c != 0 || p.height % c != 0 {
            return Err(Error::param(
                "cell",
                format!(
                    "{c} px cells do not divide the {}×{} texture (the virtual tile map must tile it)",
                    p.width, p.height
                ),
            ));
        }
        let grid = (p.width / c, p.height / c);
        let texture = (p.width, p.height);
        let rng = LayerRng::new(tables, i, grid).with_ranges(ranges);
        let count = reference.count();
        let unused = |what: &str, present: bool| {
            if present {
                Err(Error::param(what, format!("not used by {:?} layers", lp.kind)))
            } else {
                Ok(())
            }
        };
        let mut layer = Layer {
            kind: lp.kind,
            cell: lp.cell,
            grid,
            rng,
            choice: None,
            transform: None,
            transitions: None,
            animation: None,
            positioning: None,
        };
        match lp.kind {
            LayerKind::Tiling => {
                if lp.cell != p.pattern_size {
                    return Err(Error::param(
                        "cell",
                        format!(
                            "{}: a tiling cell holds one pattern, so it must equal pattern_size {}",
                            lp.cell, p.pattern_size
                        ),
                    ));
                }
                unused("transform", lp.transform.is_some())?;
                match (&lp.choice, &lp.animation) {
                    (Some(ch), None) => {
                        let choice = ChoiceBlock::load(ch, bundle, reference, &layer.rng, grid, texture, false)?;
                        if let Some(t) = &lp.transitions {
                            if choice.pixel_map().is_some() {
                                return Err(Error::param("transitions", "a pixel map already gives sharp transitions; use an areas map with transition tiles"));
                            }
                            layer.transitions = Some(Transitions::load(t, &choice, count)?);
                        }
                        layer.choice = Some(choice);
                    }
                    (None, Some(a)) => {
                        unused("transitions", lp.transitions.is_some())?;
                        let cx =
                            Context { params: p, bundle, cell: lp.cell, grid, patterns: count, allow_blank: false };
                        layer.animation = Some(AnimationBlock::load(a, &cx, &layer.rng)?);
                    }
                    _ => {
                        return Err(Error::param(
                            "choice",
                            "a tiling layer has exactly one of `choice` and `animation`",
                        ))
                    }
                }
            }
            LayerKind::Sparse => {
                unused("transitions", lp.transitions.is_some())?;
                match (&lp.choice, &lp.animation) {
                    (Some(ch), None) => {
                        if let Choice::Explicit { .. } = ch {
                            return Err(Error::param(
                                "choice",
                                "sparse layers choose virtually or by materials; explicit positions are sprites",
                            ));
                        }
                        let choice = ChoiceBlock::load(ch, bundle, reference, &layer.rng, grid, texture, true)?;
                        if choice.pixel_map().is_some() {
                            return Err(Error::param(
                                "choice.pixel_map",
                                "sparse layers place materials per cell (areas maps)",
                            ));
                        }
                        layer.choice = Some(choice);
                    }
                    (None, Some(a)) => {
                        let cx = Context { params: p, bundle, cell: lp.cell, grid, patterns: count, allow_blank: true };
                        layer.animation = Some(AnimationBlock::load(a, &cx, &layer.rng)?);
                    }
                    _ => {
                        return Err(Error::param(
                            "choice",
                            "a sparse layer has exactly one of `choice` and `animation`",
                        ))
                    }
                }
                let t = lp
                    .transform
                    .as_ref()
                    .ok_or_else(|| Error::param("transform", "a sparse layer needs a transform"))?;
                layer.transform = Some(TransformBlock::load(t)?);
            }
            LayerKind::Sprites => {
                for (what, present) in [
                    ("choice", lp.choice.is_some()),
                    ("transitions", lp.transitions.is_some()),
                    ("animation", lp.animation.is_some()),
                ] {
                    unused(what, present)?;
                }
                let transform = lp.transform.as_ref().map(TransformBlock::for_sprites).transpose()?;
                let first = p.layers.iter().position(|l| l.kind == LayerKind::Sprites) == Some(i);
                layer.positioning = Some(Positioning::load(
                    i,
                    first,
                    &p.sprites,
                    transform.as_ref(),
                    &layer.rng,
                    lp.cell,
                    texture,
                    p.pattern_size,
                    count,
                )?);
            }
        }
        Ok(layer)
    }

    /// What tiling cell g shows at frame t.
    #[inline]
    fn pick(&self, gx: u64, gy: u64, t: u32) -> Pick {
        if let Some(a) = &self.animation {
            return Pick::single(a.pattern(&self.rng, gx, gy, t));
        }
        let choice = self.choice.as_ref().expect("tiling layers have a choice or an animation");
        match &self.transitions {
            Some(tr) => tr.pick(choice, &self.rng, gx, gy, self.grid),
            None => Pick::single(choice.pattern(&self.rng, gx, gy, self.grid)),
        }
    }

    /// Texel (x, y) of a pick's patterns at `level`, overlays composited on the base.
    #[inline(always)]
    fn compose(&self, r: &Reference, pick: &Pick, level: u32, x: u32, y: u32) -> [u8; 4] {
        let mut c = match pick.base {
            Some(p) => r.texel(p, level, x, y),
            None => [0; 4],
        };
        for &o in &pick.overlays[..pick.n_overlays as usize] {
            over_u8(&mut c, r.texel(o, level, x, y));
        }
        c
    }

    /// Paints this layer over `out`, polling `stop` a row (or a few sprites) at a time and
    /// returning once it is requested.
    fn render(&self, tex: &PatternTexture, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        match self.kind {
            LayerKind::Tiling => self.render_tiling(tex, region, out, stop),
            LayerKind::Sparse => self.render_sparse(tex, region, out, stop),
            LayerKind::Sprites => self.render_sprites(tex, region, out, stop),
        }
    }

    fn render_tiling(&self, tex: &PatternTexture, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        let r = &tex.reference;
        let level = region.level;
        let t = region.frame;
        let (lw, lh) = level_size(tex.width, tex.height, level);
        let w = region.width as usize;
        if level <= r.log2 {
            let cs = (r.size >> level) as u64;
            let pixel_map = self.choice.as_ref().and_then(|c| c.pixel_map());
            for row in 0..region.height as usize {
                if stop.requested() {
                    return;
                }
                let py = wrap(region.y + row as i64, lh);
                let (gy, ly) = (py / cs, (py % cs) as u32);
                let mut last = u64::MAX;
                let mut pick = Pick::default();
                for col in 0..w {
                    let px = wrap(region.x + col as i64, lw);
                    let (gx, lx) = (px / cs, (px % cs) as u32);
                    let c = if let Some(pm) = pixel_map {
                        let half = (1u64 << level) >> 1;
                        let m = pm.at((px << level) + half, (py << level) + half);
                        let choice = self.choice.as_ref().unwrap();
                        self.compose(r, &Pick::single(choice.pattern_of(&self.rng, m, gx, gy)), level, lx, ly)
                    } else {
                        if gx != last {
                            pick = self.pick(gx, gy, t);
                            last = gx;
                        }
                        self.compose(r, &pick, level, lx, ly)
                    };
                    over_u8(&mut out[(row * w + col) * 4..][..4], c);
                }
            }
            return;
        }
        let k = 1u64 << (level - r.log2);
        for row in 0..region.height as usize {
            if stop.requested() {
                return;
            }
            let py = wrap(region.y + row as i64, lh);
            for col in 0..w {
                let px = wrap(region.x + col as i64, lw);
                let c = self.coarse_tiling(tex, px * k, py * k, k, t);
                over_u8(&mut out[(row * w + col) * 4..][..4], c);
            }
        }
    }

    /// The mean of a cell at the level where its pattern is one texel.
    fn cell_mean(&self, r: &Reference, gx: u64, gy: u64, t: u32) -> [u8; 4] {
        if let Some(pm) = self.choice.as_ref().and_then(|c| c.pixel_map()) {
            let half = r.size as u64 / 2;
            let m = pm.at(gx * r.size as u64 + half, gy * r.size as u64 + half);
            let p = self.choice.as_ref().unwrap().pattern_of(&self.rng, m, gx, gy);
            return self.compose(r, &Pick::single(p), r.log2, 0, 0);
        }
        self.compose(r, &self.pick(gx, gy, t), r.log2, 0, 0)
    }

    /// A k × k block of cells as the 2 × 2 box chain filters it: recursive rounded means of
    /// the sub-blocks that exist (the grid's last block may be partial, as odd levels are).
    fn block_mean(&self, r: &Reference, cx: u64, cy: u64, k: u64, t: u32) -> [u8; 4] {
        if k == 1 {
            return self.cell_mean(r, cx, cy, t);
        }
        let h = k / 2;
        let (mut acc, mut n) = ([0u32; 4], 0u32);
        for (dx, dy) in [(0, 0), (h, 0), (0, h), (h, h)] {
            if cx + dx < self.grid.0 && cy + dy < self.grid.1 {
                let c = self.block_mean(r, cx + dx, cy + dy, h, t);
                for i in 0..4 {
                    acc[i] += c[i] as u32;
                }
                n += 1;
            }
        }
        acc.map(|a| ((a + n / 2) / n) as u8)
    }

    fn coarse_tiling(&self, tex: &PatternTexture, cx: u64, cy: u64, k: u64, t: u32) -> [u8; 4] {
        let r = &tex.reference;
        if k <= OVERSAMPLE {
            return self.block_mean(r, cx, cy, k, t);
        }
        let centre = (
            (cx as f64 + k as f64 * 0.5).min(self.grid.0 as f64),
            (cy as f64 + k as f64 * 0.5).min(self.grid.1 as f64),
        );
        if self.transitions.is_none() && self.animation.is_none() {
            if let Some(e) = self.choice.as_ref().and_then(|c| c.expected(r, centre.0, centre.1, self.grid, false)) {
                return e.map(|v| (v + 0.5).floor().clamp(0.0, 255.0) as u8);
            }
        }
        // Stratified sample: the centre cell of each of 4 × 4 sub-blocks of the part of the
        // block inside the grid (the last block of a level may be partial).
        let (ex, ey) = (k.min(self.grid.0 - cx), k.min(self.grid.1 - cy));
        let (mut acc, mut n) = ([0u32; 4], 0u32);
        for j in 0..4 {
            for i in 0..4 {
                let (x, y) = (cx + (2 * i + 1) * ex / 8, cy + (2 * j + 1) * ey / 8);
                let c = self.cell_mean(r, x, y, t);
                for ch in 0..4 {
                    acc[ch] += c[ch] as u32;
                }
                n += 1;
            }
        }
        let n = n.max(1);
        acc.map(|a| ((a + n / 2) / n) as u8)
    }

    /// Pattern of sparse cell g at frame t, if the cell is not blank.
    #[inline]
    fn sparse_pattern(&self, gx: u64, gy: u64, t: u32) -> Option<u32> {
        match &self.animation {
            Some(a) => a.pattern(&self.rng, gx, gy, t),
            None => self.choice.as_ref().unwrap().pattern(&self.rng, gx, gy, self.grid),
        }
    }

    /// Placed pattern of sparse cell (unwrapped) u at frame t, if the cell is not blank.
    fn placed(&self, tex: &PatternTexture, ux: i64, uy: i64, t: u32) -> Option<Placed> {
        let (gx, gy) = (wrap(ux, self.grid.0), wrap(uy, self.grid.1));
        let p = self.sparse_pattern(gx, gy, t)?;
        Some(self.transform.as_ref().unwrap().place(&self.rng, gx, gy, p, tex.reference.size))
    }

    /// Mean premultiplied colour of the sparse cells in the square of side `k` cells at cell
    /// coordinates (x, y), at frame t: every cell up to 4 × 4 of them, else a stratified 4 × 4
    /// sample.
    fn cells_mean(&self, r: &Reference, x: f64, y: f64, k: f64, t: u32) -> [f32; 4] {
        let n = (k.ceil() as u64).clamp(1, OVERSAMPLE);
        let (mut acc, step) = ([0f32; 4], k / n as f64);
        for j in 0..n {
            for i in 0..n {
                let gx = wrap((x + (i as f64 + 0.5) * step) as i64, self.grid.0);
                let gy = wrap((y + (j as f64 + 0.5) * step) as i64, self.grid.1);
                if let Some(p) = self.sparse_pattern(gx, gy, t) {
                    let m = r.pm_mean(p);
                    for ch in 0..4 {
                        acc[ch] += m[ch];
                    }
                }
            }
        }
        acc.map(|v| v / (n * n) as f32)
    }

    fn render_sparse(&self, tex: &PatternTexture, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        let r = &tex.reference;
        let tr = self.transform.as_ref().unwrap();
        let level = region.level;
        let f = (1u64 << level.min(62)) as f64;
        let c = self.cell as f64;
        let w = region.width as usize;
        let (lw, lh) = level_size(tex.width, tex.height, level);
        if f * 4.0 > c {
            if f <= c * OVERSAMPLE as f64 {
                return self.splat_sparse(tex, region, out, stop);
            }
            // Past 4 × 4 cells a pixel: the mean of a stratified 4 × 4 sample of its cells; a
            // static texture's is drawn toward the expected coverage (law of large numbers) by
            // 4/k, which gives its deviation the spread of a k × k mean, not a 4 × 4 one.
            let area = tr.mean_area();
            for row in 0..region.height as usize {
                if stop.requested() {
                    return;
                }
                let py = wrap(region.y + row as i64, lh) as f64;
                for col in 0..w {
                    let px = wrap(region.x + col as i64, lw) as f64;
                    let k = f / c;
                    let mut e = self.cells_mean(r, px * k, py * k, k, region.frame);
                    if let (Some(choice), true) = (&self.choice, k > OVERSAMPLE as f64) {
                        let (cx, cy) = ((px + 0.5) * k, (py + 0.5) * k);
                        let expected = choice
                            .expected(r, cx.min(self.grid.0 as f64), cy.min(self.grid.1 as f64), self.grid, true)
                            .unwrap_or([0.0; 4]);
                        let shrink = (OVERSAMPLE as f64 / k) as f32;
                        e = std::array::from_fn(|i| expected[i] + (e[i] - expected[i]) * shrink);
                    }
                    over_pm(&mut out[(row * w + col) * 4..][..4], e.map(|v| v * area));
                }
            }
            return;
        }
        let size = r.size as f32;
        let (left, right) = (tr.left, tr.right);
        let x_first = region.x as f64 * f;
        let ux0 = (x_first / c).floor() as i64 - left;
        let ux1 = (((region.x + w as i64) as f64 * f) / c).floor() as i64 + right;
        let span = (ux1 - ux0 + 1) as usize;
        let mut rows: Vec<Vec<Option<Placed>>> = Vec::new();
        let mut rows_y0 = i64::MIN;
        for row in 0..region.height as usize {
            if stop.requested() {
                return;
            }
            let y = (region.y + row as i64) as f64 * f + f * 0.5;
            let uy = (y / c).floor() as i64;
            let ry = ((y - uy as f64 * c) / c) as f32;
            let first = uy - left;
            if first != rows_y0 {
                rows = (first..=uy + right)
                    .map(|yy| (0..span).map(|i| self.placed(tex, ux0 + i as i64, yy, region.frame)).collect())
                    .collect();
                rows_y0 = first;
            }
            for col in 0..w {
                let x = (region.x + col as i64) as f64 * f + f * 0.5;
                let ux = (x / c).floor() as i64;
                let rx = ((x - ux as f64 * c) / c) as f32;
                let mut acc = [0f32; 4];
                // Cells in row-major order, later ones on top ("over" instead of a sum so
                // colliding patterns hide each other).
                for dy in -left..=right {
                    let cells = &rows[(dy + left) as usize];
                    for dx in -left..=right {
                        let Some(pl) = &cells[(ux + dx - ux0) as usize] else { continue };
                        let Some((u, v)) = pl.local(rx - dx as f32, ry - dy as f32, size) else { continue };
                        let lvl = mip_for(level, pl.texels / c as f32, r.log2);
                        let k = 1.0 / (1u32 << lvl) as f32;
                        let s = r.bilinear_pm(pl.pattern, lvl, u * k, v * k);
                        let keep = 1.0 - s[3];
                        acc = [s[0] + acc[0] * keep, s[1] + acc[1] * keep, s[2] + acc[2] * keep, s[3] + acc[3] * keep];
                    }
                }
                over_pm(&mut out[(row * w + col) * 4..][..4], acc);
            }
        }
    }

    /// A sparse layer under four pixels a cell, up to four cells a pixel: each placed pattern's
    /// mean colour splat over the pixels an unrotated square of its area and centre overlaps,
    /// weighted by the overlap, so the level keeps where patterns lie.
    fn splat_sparse(&self, tex: &PatternTexture, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        let r = &tex.reference;
        let tr = self.transform.as_ref().unwrap();
        let k = (1u64 << region.level.min(62)) as f64 / self.cell as f64;
        let (w, h) = (region.width as i64, region.height as i64);
        // Cells whose pattern may reach a pixel of [p, p + n): a point reads from `left` cells
        // before its own to `right` cells after it.
        let sources =
            |p: i64, n: i64| (p as f64 * k).floor() as i64 - tr.left..=((p + n) as f64 * k).floor() as i64 + tr.right;
        // Summed in premultiplied f32 (the squares of neighbouring cells hardly overlap, so their
        // coverages add), scaled back where they overlap past full, then put over `out` once.
        let mut acc = vec![[0f32; 4]; (w * h) as usize];
        for uy in sources(region.y, h) {
            if stop.requested() {
                return;
            }
            for ux in sources(region.x, w) {
                let Some(pl) = self.placed(tex, ux, uy, region.frame) else { continue };
                let (cx, cy) = (ux as f64 + pl.cx as f64, uy as f64 + pl.cy as f64);
                let e = pl.scale as f64 * 0.5;
                let pm = r.pm_mean(pl.pattern);
                let span = |c: f64, p: i64, n: i64| {
                    ((c - e) / k).floor().max(p as f64) as i64..((c + e) / k).ceil().min((p + n) as f64) as i64
                };
                for py in span(cy, region.y, h) {
                    let cov_y = overlap(py as f64 * k, k, cy - e, 2.0 * e);
                    for px in span(cx, region.x, w) {
                        let cov = (cov_y * overlap(px as f64 * k, k, cx - e, 2.0 * e) / (k * k)) as f32;
                        let a = &mut acc[((py - region.y) * w + (px - region.x)) as usize];
                        *a = std::array::from_fn(|i| a[i] + pm[i] * cov);
                    }
                }
            }
        }
        for (pixel, a) in out.chunks_exact_mut(4).zip(acc) {
            over_pm(pixel, a.map(|v| v / a[3].max(1.0)));
        }
    }

    fn render_sprites(&self, tex: &PatternTexture, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        let r = &tex.reference;
        let pos = self.positioning.as_ref().unwrap();
        let t = region.frame;
        let level = region.level;
        let (lw, lh) = level_size(tex.width, tex.height, level);
        let w = region.width as usize;
        let f = (1u64 << level.min(62)) as f64;
        let centres: Vec<(f64, f64)> = (0..pos.sprites.len()).map(|i| pos.centre(i, t)).collect();
        if level <= r.log2 {
            let map = pos.map(t);
            for row in 0..region.height as usize {
                if stop.requested() {
                    return;
                }
                let y = (wrap(region.y + row as i64, lh) as f64 + 0.5) * f;
                for col in 0..w {
                    let x = (wrap(region.x + col as i64, lw) as f64 + 0.5) * f;
                    let Some(i) = pos.at(&map, x, y) else { continue };
                    let sprite = &pos.sprites[i];
                    let Some((u, v)) = sprite.local(pos.offset((x, y), centres[i]), r.size) else { continue };
                    let lvl = mip_for(level, 1.0 / sprite.scale, r.log2);
                    let k = 1.0 / (1u32 << lvl) as f32;
                    let c = r.bilinear_pm(sprite.pattern, lvl, u * k, v * k);
                    over_pm(&mut out[(row * w + col) * 4..][..4], c);
                }
            }
            return;
        }
        // Patterns smaller than a pixel: splat each sprite's mean colour over the pixels its
        // box overlaps, weighted by the overlap and the share of the box the pattern fills.
        for (n, (sprite, &(cx, cy))) in pos.sprites.iter().zip(&centres).enumerate() {
            if n % SPRITES_A_POLL == 0 && stop.requested() {
                return;
            }
            let pm = r.pm_mean(sprite.pattern);
            let e = sprite.half;
            let side = r.size as f64 * sprite.scale as f64;
            let fill = side * side / (4.0 * e * e);
            let span = |c: f64| ((c - e) / f).floor() as i64..=((c + e) / f).ceil() as i64 - 1;
            for sy in span(cy) {
                let cov_y = overlap(sy as f64 * f, f, cy - e, 2.0 * e);
                for sx in span(cx) {
                    let cov = (cov_y * overlap(sx as f64 * f, f, cx - e, 2.0 * e) * fill / (f * f)) as f32;
                    let (lx, ly) = (sx.rem_euclid(lw as i64), sy.rem_euclid(lh as i64));
                    let mut row = (ly - region.y).rem_euclid(lh as i64);
                    while row < region.height as i64 {
                        let mut col = (lx - region.x).rem_euclid(lw as i64);
                        while col < w as i64 {
                            over_pm(&mut out[(row as usize * w + col as usize) * 4..][..4], pm.map(|v| v * cov));
                            col += lw as i64;
                        }
                        row += lh as i64;
                    }
                }
            }
        }
    }
}

/// Length of [a, a + la) ∩ [b, b + lb).
fn overlap(a: f64, la: f64, b: f64, lb: f64) -> f64 {
    ((a + la).min(b + lb) - a.max(b)).max(0.0)
}

/// The pattern mip level for a level-L pixel when one level-0 pixel spans
/// `texels_per_pixel` pattern texels: the finest level with at least one texel per pixel.
fn mip_for(level: u32, texels_per_pixel: f32, log2: u32) -> u32 {
    let texels = (1u64 << level) as f32 * texels_per_pixel;
    let mut l = 0;
    while l < log2 && (2u64 << l) as f32 <= texels {
        l += 1;
    }
    l
}

impl Texture for PatternTexture {
    fn model(&self) -> &'static str {
        MODEL
    }
    fn width(&self) -> u64 {
        self.width
    }
    fn height(&self) -> u64 {
        self.height
    }
    fn domain(&self) -> Domain {
        Domain::Torus
    }
    fn animation(&self) -> Option<Animation> {
        self.animation
    }
    fn render(&self, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        for px in out.chunks_exact_mut(4) {
            px.copy_from_slice(&self.background);
        }
        for layer in &self.layers {
            if stop.requested() {
                return;
            }
            layer.render(self, region, out, stop);
        }
    }
}
