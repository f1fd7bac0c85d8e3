//! The loaded texture: vtex level 0 is the finest synthesis level's latest generation, coloured
//! by the exemplar; coarser levels come from [`prefilter`](super::prefilter).

use super::cache::BlockCache;
use super::levels::SynthesisLevels;
use super::params::{DomainSpec, Params};
use super::prefilter::{self, Calibration};
use super::rect::Rect;
use super::search::PLANE_BITS;
use super::served::CHUNK;
use super::shared::Shared;
use super::MODEL;
use crate::pixels::Rgba8Image;
use crate::texture::{Domain, Region, Stop, Texture};
use crate::Result;
use std::sync::{Arc, OnceLock};

/// A loaded, validated order-independent texture.
pub struct OrderIndependent {
    levels: SynthesisLevels,
    /// The colours of coarse levels beyond the pyramid: read from the bundle when it stores
    /// them, otherwise measured on first use (a pure function of the encoding, so when it is
    /// computed never changes a result).
    calibration: OnceLock<Calibration>,
}

impl std::fmt::Debug for OrderIndependent {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let p = self.params();
        write!(f, "OrderIndependent({} levels, seed {})", p.levels, p.seed)
    }
}

impl OrderIndependent {
    /// The texture of `params` over `sample`, sharing `shared` with the other textures of its
    /// owner; `key` (the start of its bundle's hash) names its entries in the shared cache.
    pub fn new(params: Params, sample: &Rgba8Image, key: u64, shared: Arc<Shared>) -> Result<Self> {
        Ok(OrderIndependent {
            levels: SynthesisLevels::new(params, sample, key, shared)?,
            calibration: OnceLock::new(),
        })
    }

    /// This texture with its calibration read from `bytes` (the bundle's section
    /// [`prefilter::SECTION`]), validated against its parameters and sample, instead of
    /// measured on first use.
    pub fn with_calibration(self, bytes: &[u8]) -> Result<Self> {
        let calibration = Calibration::from_bytes(&self.levels, bytes)?;
        Ok(OrderIndependent { calibration: OnceLock::from(calibration), ..self })
    }

    /// The synthesis levels the texture serves from.
    #[cfg(test)]
    pub(super) fn levels(&self) -> &SynthesisLevels {
        &self.levels
    }

    /// The calibration, measured now if it was neither stored nor measured yet.
    pub fn calibration(&self) -> &Calibration {
        self.calibration.get_or_init(|| {
            Calibration::compute(&self.levels, &crate::Never).expect("a render that is never stopped completes")
        })
    }

    /// Checks that `bytes` is the calibration [`Calibration::compute`] gives this texture
    /// (see [`prefilter::verify`]).
    pub fn verify_calibration(&self, bytes: &[u8]) -> Result<()> {
        prefilter::verify(&self.levels, bytes)
    }

    /// This texture with its entries kept in `cache` instead of the shared cache (the figures
    /// compare block sides and budgets with it).
    pub fn in_cache(self, cache: Arc<BlockCache>) -> Self {
        OrderIndependent { levels: self.levels.in_cache(cache), ..self }
    }

    pub fn params(&self) -> &Params {
        self.levels.params()
    }

    /// The work this texture's renders have done since it was loaded, by kind.
    pub fn work_counters(&self) -> Vec<(&'static str, u64)> {
        self.levels.work_counters()
    }

    /// The sample pixel, as (column, row), that each level-0 pixel of a `w × h` window at
    /// (x, y) copies, row-major: where neighbours in the output were not neighbours in the
    /// sample there is a join (the quality report's seam mask, `Mask::from_sources`).
    pub fn sources(&self, x: i64, y: i64, w: u32, h: u32) -> Vec<(u32, u32)> {
        let fin = self.params().levels - 1;
        let (x, y) = self.reduce(0, x, y);
        let values = self.levels.entries(fin, Rect { x, y, w: w as usize, h: h as usize }, &crate::Never);
        let side = self.levels.synthesizer().exemplar().levels[fin as usize].w;
        values
            .expect("a render that is never stopped completes")
            .iter()
            .map(|&v| (v as u32 % side, v as u32 / side))
            .collect()
    }

    /// A level-`l` origin moved by a whole period of the texture to near 0, so that nothing
    /// evaluated under a region overflows: by the torus's period, or the plane's 2^PLANE_BITS
    /// (its signed representative).
    fn reduce(&self, l: u32, x: i64, y: i64) -> (i64, i64) {
        let p = self.params();
        let fin = p.levels as u32 - 1;
        match p.domain {
            DomainSpec::Torus => {
                // Beyond the pyramid a level's size may not divide the texture's; the coarsest
                // synthesis level's period is a whole number of its pixels.
                let shift = l.min(fin);
                let (w, h) = ((p.width >> shift) as i64, (p.height >> shift) as i64);
                (x.rem_euclid(w), y.rem_euclid(h))
            }
            DomainSpec::Plane => {
                let bits = 64 - (PLANE_BITS - l);
                ((x << bits) >> bits, (y << bits) >> bits)
            }
        }
    }
}

impl Texture for OrderIndependent {
    fn model(&self) -> &'static str {
        MODEL
    }
    fn width(&self) -> u64 {
        self.params().width
    }
    fn height(&self) -> u64 {
        self.params().height
    }
    fn domain(&self) -> Domain {
        match self.params().domain {
            DomainSpec::Plane => Domain::Plane,
            DomainSpec::Torus => Domain::Torus,
        }
    }

    fn render(&self, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        self.levels.count_request(region.pixel_count());
        let l = region.level;
        let (x, y) = self.reduce(l, region.x, region.y);
        let region = &Region { x, y, ..*region };
        // Each output pixel depends on its own block of finer pixels only, so chunking never
        // changes a pixel.
        let step = (CHUNK >> prefilter::span(self.params(), l).min(8)).max(1);
        let row = region.width as usize * 4;
        for cy in (0..region.height).step_by(step as usize) {
            for cx in (0..region.width).step_by(step as usize) {
                let (w, h) = (step.min(region.width - cx), step.min(region.height - cy));
                let (x, y) = (region.x.wrapping_add(cx as i64), region.y.wrapping_add(cy as i64));
                let img = if l == 0 {
                    self.levels.level0(x, y, w, h, stop)
                } else {
                    prefilter::render(
                        &self.levels,
                        &self.calibration,
                        l,
                        Rect { x, y, w: w as usize, h: h as usize },
                        stop,
                    )
                };
                let Some(img) = img else { return };
                for r in 0..h as usize {
                    let dst = (cy as usize + r) * row + cx as usize * 4;
                    out[dst..dst + w as usize * 4]
                        .copy_from_slice(&img.data[r * w as usize * 4..(r + 1) * w as usize * 4]);
                }
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::super::cache::{Pyramid, BLOCK_BYTES};
    use super::super::served::{evaluate, Counts};
    use super::super::{create, load, load_with, MODEL};
    use super::*;
    use crate::models::Inputs;
    use crate::Never;
    use serde_json::json;

    fn bundle(params: serde_json::Value, sample: Rgba8Image) -> crate::bundle::Bundle {
        let mut inputs = Inputs::new();
        inputs.insert("sample".into(), sample.to_png());
        create("t", &params, &inputs).unwrap()
    }

    fn texture(params: serde_json::Value, sample: Rgba8Image) -> OrderIndependent {
        load(&bundle(params, sample)).unwrap()
    }

    fn regions() -> Vec<Region> {
        vec![
            Region::new(0, -40, 17, 70, 50),
            Region::new(0, -10, 30, 33, 40),
            Region::new(0, 1 << 33, -(1 << 35), 40, 24),
            Region::new(1, -20, 8, 40, 30),
            Region::new(2, 3, -9, 24, 24),
            Region::new(4, 0, 0, 16, 16),
            Region::new(7, 0, 0, 4, 4),
        ]
    }

    fn render_all(t: &OrderIndependent, order: &[usize]) -> Vec<Vec<u8>> {
        let regions = regions();
        let mut out = vec![Vec::new(); regions.len()];
        for &i in order {
            out[i] = crate::texture::render_image(t, &regions[i]).unwrap().data;
        }
        out
    }

    /// Entries computed other than noise (drawn directly, never cached).
    fn computed(t: &OrderIndependent) -> u64 {
        t.work_counters()[0].1 - t.work_counters()[1].1
    }

    /// Budgets of 0, a few blocks and plenty; cold and warm; shuffled orders on two threads:
    /// the same bytes. The warm pass with plenty computes less, so the cache was in use.
    #[test]
    fn the_pyramidal_cache_never_changes_a_result() {
        let b = bundle(json!({"seed": 8, "levels": 3, "width": 4096, "height": 4096}), crate::samples::lichen(32, 2));
        let n = regions().len();
        let forward: Vec<usize> = (0..n).collect();
        let cold = render_all(&load(&b).unwrap(), &forward);
        for budget in [16 * 3 * BLOCK_BYTES, 64 << 20] {
            let resources = crate::Resources::new(budget);
            let t = load_with(&b, &resources).unwrap();
            for pass in 0..2 {
                let before = computed(&t);
                let parts: Vec<Vec<Vec<u8>>> = std::thread::scope(|s| {
                    let workers: Vec<_> = (0..2)
                        .map(|k| {
                            let order: Vec<usize> = (0..n).map(|i| (i * 3 + k * 5 + pass) % n).collect();
                            let t = &t;
                            s.spawn(move || render_all(t, &order))
                        })
                        .collect();
                    workers.into_iter().map(|w| w.join().unwrap()).collect()
                });
                for got in parts {
                    assert_eq!(got, cold, "budget {budget}, pass {pass}");
                }
                assert!(resources.cache_bytes(MODEL) <= budget.max(BLOCK_BYTES * 16));
                if budget == 64 << 20 && pass == 1 {
                    let warm = computed(&t) - before;
                    assert!(warm < 2 * 1000, "a warm pass computed {warm} entries");
                }
            }
        }
    }

    /// Regions at the ends of the i64 range render (no overflow in their cones), equal the crop
    /// of a larger region across the plane's period, and repeat with it.
    #[test]
    fn the_plane_repeats_every_2_to_the_62_and_renders_at_the_ends_of_i64() {
        let t = texture(json!({"seed": 3, "levels": 3}), crate::samples::lichen(32, 4));
        let at = |l: u32, x: i64, y: i64, w: u32, h: u32| {
            crate::texture::render_image(&t, &Region::new(l, x, y, w, h)).unwrap()
        };
        let period = 1i64 << PLANE_BITS;
        for l in [0, 1, 3] {
            let p = period >> l;
            let big = at(l, p - 30, -p - 20, 60, 40);
            assert_eq!(at(l, -30, -20, 60, 40), big, "level {l}: one period away");
            assert_eq!(at(l, i64::MIN, -20, 30, 40), big.crop(30, 0, 30, 40), "level {l}: at i64::MIN");
            assert_eq!(at(l, i64::MAX - 30, i64::MAX - 40, 30, 40), at(l, -31, -41, 30, 40), "level {l}: at i64::MAX");
        }
    }

    /// Searches (the dear entries) under a 256² tile of every vtex level 1–6 of each demo, as
    /// `render` chunks it, are at most twice those under a level-0 tile.
    #[test]
    fn a_coarse_tile_searches_at_most_twice_what_a_level_0_tile_does() {
        use super::super::prefilter::{source, span, Source};
        use super::super::search::Synthesizer;
        use super::super::structure::{Entry, Synthesis};
        use std::cell::Cell;
        struct Searches<'a>(&'a Synthesizer, Cell<u64>);
        impl Synthesis for Searches<'_> {
            fn noise(&self, x: i64, y: i64) -> u16 {
                self.0.noise(x, y)
            }
            fn entry(&self, e: Entry, same: &[u16], lower: &[u16]) -> u16 {
                if e.m > 0 && self.0.structure().updates(e.m, e.x, e.y) {
                    self.1.set(self.1.get() + 1);
                }
                self.0.entry(e, same, lower)
            }
        }
        for bundle in super::super::demos() {
            let t = load(&bundle).unwrap();
            let (p, syn) = (t.params(), t.levels.synthesizer());
            let fin = p.levels - 1;
            let searches = |s: u8, m: u8| {
                let counting = Searches(syn, Cell::new(0));
                let rect = Rect { x: 4096, y: -8192, w: CHUNK as usize, h: CHUNK as usize };
                super::super::served::evaluate_generation(
                    &counting,
                    syn.structure(),
                    None,
                    s,
                    m,
                    rect,
                    &mut Counts::default(),
                    &Never,
                );
                counting.1.get()
            };
            let level0 = searches(fin, syn.structure().last(fin));
            for l in 1..=6 {
                let tile = match source(p, l) {
                    Source::Pyramid { r, m } => (1u64 << (2 * span(p, l))) * searches(fin - r as u8, m),
                    Source::Mean => 0,
                    Source::Exact => unreachable!("the demos have no exact levels"),
                };
                assert!(tile <= 2 * level0, "{}: level {l} searches {tile}, level 0 {level0}", bundle.manifest.name);
            }
        }
    }

    /// A stored encoding without `mip_generations` keeps its coarse levels (level 1 the exact
    /// box of level 0); `create` writes the default, with which level 1 is coloured from an
    /// earlier generation.
    #[test]
    fn a_stored_encoding_without_mip_generations_keeps_its_coarse_levels() {
        let made =
            bundle(json!({"seed": 5, "levels": 3, "width": 4096, "height": 4096}), crate::samples::lichen(32, 2));
        let written = made.manifest.full_params().unwrap()["mip_generations"].clone();
        assert_eq!(written, json!(super::super::params::DEFAULT_MIP_GENERATIONS));
        let mut stored = made.clone();
        stored.manifest.derived.remove("mip_generations");
        // Stored before the calibration section too (whose shape follows `mip_generations`).
        stored.sections.retain(|s| s.name != prefilter::SECTION);
        let region = Region::new(1, 40, -24, 32, 16);
        let exact = crate::mip::downsample(
            &crate::texture::render_image(&load(&stored).unwrap(), &Region::new(0, 80, -48, 64, 32)).unwrap(),
        );
        assert_eq!(crate::texture::render_image(&load(&stored).unwrap(), &region).unwrap(), exact);
        assert_ne!(crate::texture::render_image(&load(&made).unwrap(), &region).unwrap(), exact);
    }

    /// The paper's computation ratio for an isolated cold 256² tile of the paper's structure
    /// (three generations, no subpasses):
    /// through the cache's need masks, exactly the cone, 276,360 entries with the noise (4.22 a
    /// pixel, as the specification's prototype counts); without a cache, its bounding
    /// rectangles (the disc's cut corners computed too).
    #[test]
    fn a_cold_tile_computes_its_cone_once() {
        let paper = json!({"seed": 1, "generations": 3, "subpasses": 1});
        let t = texture(paper, crate::samples::pebbles(64, 9, 22, false));
        let syn = t.levels.synthesizer();
        let rect = Rect { x: 0, y: 0, w: 256, h: 256 };
        let count = |cache: Option<&Pyramid>| {
            let mut counts = Counts::default();
            let v = evaluate(syn, syn.structure(), cache, 3, rect, &mut counts, &Never).unwrap();
            (v, counts.computed + counts.noise)
        };
        let cache = Arc::new(BlockCache::new(super::super::cache::SIDE));
        let (exact, masked) = count(Some(&Pyramid::new(0x5eed, cache)));
        let (dense, rectangles) = count(None);
        assert_eq!((masked, rectangles), (276_360, 276_412));
        assert_eq!(exact, dense);
    }
}
