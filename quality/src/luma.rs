//! Luminance planes: the scalar signal that repetition, seam and contrast are measured on.

use vtex_synth::Rgba8Image;

/// Rec. 709 luma weights applied to sRGB-coded bytes.
pub const WEIGHTS: [f64; 3] = [0.2126, 0.7152, 0.0722];

/// A row-major plane of luminance values in grey levels (0 to 255).
#[derive(Clone, Debug, PartialEq)]
pub struct Plane {
    pub width: usize,
    pub height: usize,
    pub data: Vec<f64>,
}

impl Plane {
    #[inline]
    pub fn at(&self, x: usize, y: usize) -> f64 {
        self.data[y * self.width + x]
    }
}

/// Luma Y' = 0.2126 R + 0.7152 G + 0.0722 B of every pixel, on the coded byte values; alpha is
/// ignored. A grey pixel (v, v, v) has luma v.
pub fn luma(img: &Rgba8Image) -> Plane {
    let data = img
        .data
        .chunks_exact(4)
        .map(|p| WEIGHTS[0] * p[0] as f64 + WEIGHTS[1] * p[1] as f64 + WEIGHTS[2] * p[2] as f64)
        .collect();
    Plane { width: img.width as usize, height: img.height as usize, data }
}

/// Mean and population standard deviation (divided by n, not n − 1); (0, 0) when empty.
pub fn mean_sd(values: &[f64]) -> (f64, f64) {
    if values.is_empty() {
        return (0.0, 0.0);
    }
    let n = values.len() as f64;
    let mean = values.iter().sum::<f64>() / n;
    let var = values.iter().map(|v| (v - mean) * (v - mean)).sum::<f64>() / n;
    (mean, var.sqrt())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn grey_pixels_have_their_own_luma() {
        let img = Rgba8Image::from_raw(2, 1, vec![0, 0, 0, 255, 200, 200, 200, 0]).unwrap();
        let l = luma(&img);
        assert_eq!((l.width, l.height), (2, 1));
        assert_eq!(l.at(0, 0), 0.0);
        assert!((l.at(1, 0) - 200.0).abs() < 1e-9);
    }

    #[test]
    fn green_weighs_most() {
        let img = Rgba8Image::from_raw(3, 1, vec![255, 0, 0, 255, 0, 255, 0, 255, 0, 0, 255, 255]).unwrap();
        let l = luma(&img);
        assert!(l.at(1, 0) > l.at(0, 0) && l.at(0, 0) > l.at(2, 0));
        assert!((l.at(0, 0) - 0.2126 * 255.0).abs() < 1e-9);
    }

    #[test]
    fn mean_sd_known_values() {
        assert_eq!(mean_sd(&[]), (0.0, 0.0));
        let (m, s) = mean_sd(&[2.0, 4.0, 4.0, 4.0, 5.0, 5.0, 7.0, 9.0]);
        assert_eq!(m, 5.0);
        assert_eq!(s, 2.0);
    }
}
