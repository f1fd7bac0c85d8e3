//! Contrast ratio: does the output keep the sample's contrast? Blending and filtering
//! (averaging overlapping copies) wash texture out; a ratio below 1 shows it.

use crate::luma::{luma, mean_sd};
use vtex_synth::{Error, Result, Rgba8Image};

/// σ(output luma) / σ(sample luma): population standard deviations of
/// [`crate::luma::luma`] over every pixel of each image. 1 is the target; a model that only
/// rearranges sample pixels stays near 1, one that blends them falls below.
/// Errors: a sample (or output) without pixels, or a sample of constant luminance.
pub fn contrast_ratio(output: &Rgba8Image, sample: &Rgba8Image) -> Result<f64> {
    if output.data.is_empty() || sample.data.is_empty() {
        return Err(Error::image("output", "an image without pixels has no contrast"));
    }
    let (_, s) = mean_sd(&luma(sample).data);
    if s == 0.0 {
        return Err(Error::image("sample", "constant luminance: contrast ratio is undefined"));
    }
    Ok(mean_sd(&luma(output).data).1 / s)
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::{grey, noise, tiled};

    #[test]
    fn scaled_contrast_gives_the_scale() {
        // Two grey levels 28 apart around 128, then 14 and 56 apart: σ scales exactly.
        let two = |d: f64| grey(16, 16, move |x, y| if (x + y) % 2.0 == 0.0 { 128.0 - d } else { 128.0 + d });
        let sample = two(28.0);
        assert!((contrast_ratio(&two(14.0), &sample).unwrap() - 0.5).abs() < 1e-9);
        assert!((contrast_ratio(&two(56.0), &sample).unwrap() - 2.0).abs() < 1e-9);
    }

    #[test]
    fn tiling_keeps_contrast_and_flat_loses_it() {
        let s = noise(32, 32, 1);
        assert!((contrast_ratio(&tiled(&s, 128, 96), &s).unwrap() - 1.0).abs() < 1e-12);
        assert_eq!(contrast_ratio(&grey(8, 8, |_, _| 100.0), &s).unwrap(), 0.0);
    }

    #[test]
    fn refuses_flat_or_empty_samples() {
        let flat = grey(8, 8, |_, _| 100.0);
        assert!(contrast_ratio(&noise(8, 8, 1), &flat).unwrap_err().to_string().contains("sample"));
        assert!(contrast_ratio(&Rgba8Image::new(0, 0), &noise(8, 8, 1)).is_err());
    }
}
