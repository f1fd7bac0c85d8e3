//! The loaded texture: level 0 and the exact levels by brute force over bounded chunks
//! ([`exact`](super::exact)), coarser levels through [`prefilter`](super::prefilter).

use super::exact::Exact;
use super::params::Params;
use super::{prefilter, MODEL};
use crate::pixels::Rgba8Image;
use crate::texture::{Domain, Region, Stop, Texture};
use crate::Result;
use std::sync::OnceLock;

/// Level-0 pixels computed per chunk: bounds the memory of one render call.
const CHUNK: u32 = 1024;

/// A loaded, validated cascade texture.
pub struct Cascade {
    exact: Exact,
    /// Statistics for the prefiltered mip levels, computed on first use (a pure function of
    /// the encoding, so when it is computed never changes a result).
    calibration: OnceLock<prefilter::Calibration>,
}

impl std::fmt::Debug for Cascade {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let e = self.exact.engine();
        write!(f, "Cascade({} stages, seed {})", e.stages.len(), e.seed)
    }
}

impl Cascade {
    pub(super) fn build(params: Params, control: Option<&Rgba8Image>, initial: Option<&Rgba8Image>) -> Result<Self> {
        Ok(Self { exact: Exact::build(params, control, initial)?, calibration: OnceLock::new() })
    }

    /// The exact evaluation every level is computed from.
    pub fn exact(&self) -> &Exact {
        &self.exact
    }

    /// The calibration, kept once a render has computed it whole; `None` when `stop` is
    /// requested first. Renders that need it before it is kept each compute it (the same
    /// value), rather than wait on one another, so that each can stop on its own.
    fn calibration(&self, stop: &dyn Stop) -> Option<&prefilter::Calibration> {
        if let Some(c) = self.calibration.get() {
            return Some(c);
        }
        let c = prefilter::Calibration::compute(&self.exact, stop)?;
        Some(self.calibration.get_or_init(|| c))
    }
}

impl Texture for Cascade {
    fn model(&self) -> &'static str {
        MODEL
    }
    fn width(&self) -> u64 {
        self.exact.params().width
    }
    fn height(&self) -> u64 {
        self.exact.params().height
    }
    fn domain(&self) -> Domain {
        Domain::Plane
    }

    fn render(&self, region: &Region, out: &mut [u8], stop: &dyn Stop) {
        let l = region.level;
        // Chunks keep every buffer bounded; each pixel is independent of the chunking.
        let exact = prefilter::is_exact(&self.exact, l);
        let step = if exact { (CHUNK >> l).max(1) } else { 256 };
        let row = region.width as usize * 4;
        for cy in (0..region.height).step_by(step as usize) {
            for cx in (0..region.width).step_by(step as usize) {
                let (w, h) = (step.min(region.width - cx), step.min(region.height - cy));
                let (x, y) = ((region.x as u64).wrapping_add(cx as u64), (region.y as u64).wrapping_add(cy as u64));
                let img = if l == 0 {
                    self.exact.level0(x, y, w, h, stop)
                } else if exact {
                    self.exact
                        .level0(x << l, y << l, w << l, h << l, stop)
                        .map(|full| crate::mip::downsample_n(&full, l))
                } else {
                    self.calibration(stop).and_then(|cal| prefilter::render(&self.exact, cal, l, x, y, w, h, stop))
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
    use super::super::{create, load};
    use super::*;
    use crate::models::Inputs;
    use crate::Never;
    use serde_json::json;

    fn cascade(params: serde_json::Value) -> Cascade {
        load(&create("t", &params, &Inputs::new()).unwrap()).unwrap()
    }

    /// The dependency margin is exactly right: computing any stage from a window one point
    /// narrower (edge values repeated) changes the result, and the full margin reproduces it.
    #[test]
    fn one_point_less_of_margin_changes_the_result() {
        let t = cascade(json!({"seed": 9, "stages": [
            {"kernel": {"size": 5, "preset": "gauss"}, "map": {"kind": "logistic", "r": 3.8}},
            {"upsample": 2, "jitter": 0.1, "kernel": {"size": 3, "preset": "box"}, "map": {"kind": "tent", "mu": 1.7}, "iterations": 3},
            {"upsample": 4, "jitter": 0.1, "kernel": {"size": 7, "preset": "gauss"}, "map": {"kind": "sine", "r": 0.95}, "iterations": 2, "dilation": 2}]}));
        let e = t.exact().engine();
        let last = e.stages.len() - 1;
        let (x, y, w, h) = (u64::MAX - 20, 1 << 40, 48, 40);
        let full = e.field(last, x, y, w, h);
        assert_eq!(e.field_with(last, x, y, w, h, None, &Never), Some(full.clone()));
        for s in 0..=last {
            let short = e.field_with(last, x, y, w, h, Some(s), &Never).unwrap();
            let differ = full.v.iter().zip(&short.v).filter(|(a, b)| a != b).count();
            assert!(differ > 0, "stage {s}: a margin one point short went unnoticed");
        }
        // The margins are iterations × reach: 5·2, 3·1, and 2·7 for the 7×7 dilated by 2 (the
        // continuous kernel spans 2·(3 + 1) = 8 points each side and vanishes at the 8th).
        assert_eq!((0..=last).map(|s| e.margin(s)).collect::<Vec<_>>(), vec![10, 3, 14]);
    }

    #[test]
    fn margin_with_a_dilation_map_uses_the_largest_dilation() {
        let mut inputs = Inputs::new();
        let white = Rgba8Image::from_raw(2, 2, vec![255; 16]).unwrap();
        inputs.insert("control".into(), white.to_png());
        let params = json!({"seed": 2, "stages": [{"kernel": {"size": 3, "preset": "box"}, "map": {"kind": "logistic", "r": 3.9}, "iterations": 4}],
                            "dilation_map": {"max": 2, "cell": 8}});
        let t = load(&create("d", &params, &inputs).unwrap()).unwrap();
        let e = t.exact().engine();
        // Dilated by 2 the 3×3 box spans 2·(1 + 1) = 4 points each side and vanishes at the
        // 4th: it reaches 3.
        assert_eq!(e.margin(0), 4 * 3);
        let full = e.field(0, 5, 5, 30, 30);
        assert_ne!(e.field_with(0, 5, 5, 30, 30, Some(0), &Never), Some(full));
    }
}
