//! The synthesis levels of a loaded texture: the per-entry function over the exemplar, the
//! shared cache its entries go through, and the work they cost. The texture serves level 0
//! from the finest of them and the prefilter colours coarse levels from the others.

use super::cache::{BlockCache, Pyramid};
use super::params::Params;
use super::rect::Rect;
use super::search::Synthesizer;
use super::served::{evaluate_generation, Counts};
use super::shared::{Shared, Work};
use crate::pixels::Rgba8Image;
use crate::texture::Stop;
use crate::Result;
use std::sync::Arc;

pub struct SynthesisLevels {
    params: Params,
    synthesizer: Synthesizer,
    pyramid: Pyramid,
    /// This texture's share of the shared work, since it was loaded.
    work: Work,
    shared: Arc<Shared>,
}

impl SynthesisLevels {
    /// The levels of `params` over `sample`, sharing `shared` with the other textures of its
    /// owner; `key` (the start of its bundle's hash) names its entries in the shared cache.
    pub fn new(params: Params, sample: &Rgba8Image, key: u64, shared: Arc<Shared>) -> Result<Self> {
        let synthesizer = Synthesizer::new(&params, sample)?;
        let pyramid = Pyramid::new(key, shared.cache.clone());
        Ok(SynthesisLevels { params, synthesizer, pyramid, work: Work::default(), shared })
    }

    /// These levels with their entries kept in `cache` instead of the shared cache.
    pub fn in_cache(self, cache: Arc<BlockCache>) -> Self {
        SynthesisLevels { pyramid: self.pyramid.in_cache(cache), ..self }
    }

    pub fn params(&self) -> &Params {
        &self.params
    }

    /// The work done through these levels since they were loaded, by kind.
    pub fn work_counters(&self) -> Vec<(&'static str, u64)> {
        self.work.counters()
    }

    /// Counts `pixels` requested of the texture.
    pub fn count_request(&self, pixels: u64) {
        for work in [&self.work, &self.shared.work] {
            work.add(0, 0, pixels);
        }
    }

    /// The per-entry function, shared with the reference evaluator.
    pub fn synthesizer(&self) -> &Synthesizer {
        &self.synthesizer
    }

    /// The latest generation of synthesis level `s` over `rect` (exemplar indices), through
    /// the shared cache when it has a budget; `None` once `stop` is requested.
    pub fn entries(&self, s: u8, rect: Rect, stop: &dyn Stop) -> Option<Vec<u16>> {
        self.entries_at(s, self.synthesizer.structure().last(s), rect, stop)
    }

    /// Generation `m` of synthesis level `s` over `rect`, as [`entries`](Self::entries).
    pub fn entries_at(&self, s: u8, m: u8, rect: Rect, stop: &dyn Stop) -> Option<Vec<u16>> {
        let st = self.synthesizer.structure();
        if st.is_noise(s, m) {
            return self.noise(rect, stop);
        }
        let cache = (self.pyramid.cache().budget() > 0).then_some(&self.pyramid);
        let mut counts = Counts::default();
        let values = evaluate_generation(&self.synthesizer, st, cache, s, m, rect, &mut counts, stop);
        for work in [&self.work, &self.shared.work] {
            work.add(counts.computed + counts.noise, counts.noise, 0);
        }
        values
    }

    /// The noise over `rect`, drawn directly: a hash an entry costs less than the evaluator's
    /// bookkeeping around it, and caching it would only evict dearer entries.
    fn noise(&self, rect: Rect, stop: &dyn Stop) -> Option<Vec<u16>> {
        let values = self.synthesizer.noise_over(rect, stop)?;
        for work in [&self.work, &self.shared.work] {
            work.add(values.len() as u64, values.len() as u64, 0);
        }
        Some(values)
    }

    /// Level-0 pixels of a `w × h` window at (x, y), or `None` once `stop` is requested.
    pub fn level0(&self, x: i64, y: i64, w: u32, h: u32, stop: &dyn Stop) -> Option<Rgba8Image> {
        let fin = self.params.levels - 1;
        let values = self.entries(fin, Rect { x, y, w: w as usize, h: h as usize }, stop)?;
        let colour = &self.synthesizer.exemplar().levels[fin as usize].colour;
        let mut img = Rgba8Image::new(w, h);
        for (px, &v) in img.data.chunks_exact_mut(4).zip(&values) {
            let c = colour[v as usize];
            px.copy_from_slice(&[c[0], c[1], c[2], 255]);
        }
        Some(img)
    }
}
