//! The reference mip filter: a 2×2 box in sRGB byte space, rounded to nearest.
//!
//! Models evaluate coarse levels prefiltered (they cannot afford brute force at 100k²);
//! tests hold them to this exact downsample of the level below.

use crate::pixels::Rgba8Image;

/// One level down: each output pixel is the rounded mean of its 2×2 children. An odd last
/// row or column averages the pixels that exist.
pub fn downsample(img: &Rgba8Image) -> Rgba8Image {
    let (w, h) = (img.width.div_ceil(2), img.height.div_ceil(2));
    let mut out = Rgba8Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let (x0, y0) = (2 * x, 2 * y);
            let xs = if x0 + 1 < img.width { 2 } else { 1 };
            let ys = if y0 + 1 < img.height { 2 } else { 1 };
            let n = xs * ys;
            let mut acc = [0u32; 4];
            for dy in 0..ys {
                for dx in 0..xs {
                    let p = img.pixel(x0 + dx, y0 + dy);
                    for c in 0..4 {
                        acc[c] += p[c] as u32;
                    }
                }
            }
            out.set_pixel(x, y, acc.map(|a| ((a + n / 2) / n) as u8));
        }
    }
    out
}

/// `levels` successive [`downsample`]s.
pub fn downsample_n(img: &Rgba8Image, levels: u32) -> Rgba8Image {
    (0..levels).fold(img.clone(), |acc, _| downsample(&acc))
}

/// Peak signal-to-noise ratio in dB over the RGB channels (alpha ignored); infinite when equal.
pub fn psnr(a: &Rgba8Image, b: &Rgba8Image) -> f64 {
    assert_eq!((a.width, a.height), (b.width, b.height), "psnr of images of different sizes");
    let mut se = 0.0f64;
    let mut n = 0u64;
    for (p, q) in a.data.chunks_exact(4).zip(b.data.chunks_exact(4)) {
        for c in 0..3 {
            let d = p[c] as f64 - q[c] as f64;
            se += d * d;
            n += 1;
        }
    }
    if se == 0.0 {
        return f64::INFINITY;
    }
    10.0 * (255.0f64 * 255.0 / (se / n as f64)).log10()
}

/// Mean of each RGBA channel over the image.
pub fn mean_rgba(img: &Rgba8Image) -> [f64; 4] {
    let mut acc = [0u64; 4];
    for p in img.data.chunks_exact(4) {
        for c in 0..4 {
            acc[c] += p[c] as u64;
        }
    }
    let n = (img.width as u64 * img.height as u64).max(1) as f64;
    acc.map(|a| a as f64 / n)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn downsample_averages_and_rounds() {
        let img =
            Rgba8Image::from_raw(2, 2, vec![0, 0, 0, 255, 1, 10, 255, 255, 0, 20, 0, 255, 0, 30, 0, 255]).unwrap();
        let d = downsample(&img);
        assert_eq!((d.width, d.height), (1, 1));
        // (0+1+0+0)/4 = 0.25 → 0; (0+10+20+30)/4 = 15; (0+255+0+0)/4 = 63.75 → 64.
        assert_eq!(d.pixel(0, 0), [0, 15, 64, 255]);
    }

    #[test]
    fn odd_sizes_keep_edge_pixels() {
        let img = Rgba8Image::from_raw(3, 1, vec![10, 10, 10, 255, 20, 20, 20, 255, 200, 200, 200, 255]).unwrap();
        let d = downsample(&img);
        assert_eq!((d.width, d.height), (2, 1));
        assert_eq!(d.pixel(1, 0), [200, 200, 200, 255]);
        assert_eq!(d.pixel(0, 0), [15, 15, 15, 255]);
    }

    #[test]
    fn psnr_of_known_error() {
        let a = Rgba8Image::from_raw(1, 1, vec![100, 100, 100, 255]).unwrap();
        let b = Rgba8Image::from_raw(1, 1, vec![110, 100, 100, 0]).unwrap();
        // MSE = 100/3 over RGB; alpha is ignored.
        let expected = 10.0 * (255.0f64 * 255.0 * 3.0 / 100.0).log10();
        assert!((psnr(&a, &b) - expected).abs() < 1e-9);
        assert!(psnr(&a, &a).is_infinite());
    }
}
