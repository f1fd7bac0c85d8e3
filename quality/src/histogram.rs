//! Histogram distance: does the output use the sample's colours in the sample's proportions?

use vtex_synth::{Error, Result, Rgba8Image};

/// Per-channel 1-D Wasserstein (earth mover's) distance W1 between the R, G and B histograms
/// of `a` and `b`, in grey levels: the average distance each unit of pixel mass must move
/// along the 0..=255 axis to turn one histogram into the other.
///
/// Exact definition, with F_a, F_b the normalised cumulative histograms of one channel:
/// W1 = Σ_{k=0}^{254} |F_a(k) − F_b(k)|. Images of different sizes compare as distributions.
/// Shifting every value by s (without clipping) gives exactly s; identical histograms give 0.
/// Alpha is ignored. Errors: an image without pixels.
pub fn histogram_w1(a: &Rgba8Image, b: &Rgba8Image) -> Result<[f64; 3]> {
    let (ha, hb) = (histograms(a)?, histograms(b)?);
    Ok([0, 1, 2].map(|c| w1_of_histograms(&ha[c], &hb[c])))
}

/// The R, G, B histograms of an image.
pub fn histograms(img: &Rgba8Image) -> Result<[[u64; 256]; 3]> {
    if img.data.is_empty() {
        return Err(Error::image("histogram", "an image without pixels has no histogram"));
    }
    let mut h = [[0u64; 256]; 3];
    for p in img.data.chunks_exact(4) {
        for c in 0..3 {
            h[c][p[c] as usize] += 1;
        }
    }
    Ok(h)
}

/// W1 between two non-empty 256-bin histograms, normalised to unit mass, in bins.
pub fn w1_of_histograms(a: &[u64; 256], b: &[u64; 256]) -> f64 {
    let (na, nb) = (a.iter().sum::<u64>() as f64, b.iter().sum::<u64>() as f64);
    let (mut ca, mut cb, mut acc) = (0u64, 0u64, 0.0);
    for k in 0..255 {
        ca += a[k];
        cb += b[k];
        acc += (ca as f64 / na - cb as f64 / nb).abs();
    }
    acc
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::{grey, noise, tiled};

    #[test]
    fn self_distance_is_zero() {
        let img = noise(40, 30, 1);
        assert_eq!(histogram_w1(&img, &img).unwrap(), [0.0; 3]);
        // A tiling has the sample's histogram when whole tiles fit.
        assert_eq!(histogram_w1(&tiled(&img, 120, 90), &img).unwrap(), [0.0; 3]);
    }

    #[test]
    fn shift_gives_the_shift() {
        let a = grey(50, 20, |x, y| (x * 3.0 + y * 7.0) % 230.0);
        let mut b = a.clone();
        for p in b.data.chunks_exact_mut(4) {
            p[0] += 10;
            p[1] += 25;
        }
        let w = histogram_w1(&a, &b).unwrap();
        assert!((w[0] - 10.0).abs() < 1e-9 && (w[1] - 25.0).abs() < 1e-9 && w[2] == 0.0, "{w:?}");
        let (black, white) = (grey(4, 4, |_, _| 0.0), grey(3, 5, |_, _| 255.0));
        assert_eq!(histogram_w1(&black, &white).unwrap(), [255.0; 3]);
    }

    #[test]
    fn refuses_empty_images() {
        assert!(histogram_w1(&Rgba8Image::new(0, 3), &noise(4, 4, 1)).is_err());
    }
}
