//! Every metric of one output against its sample, and its rendering as markdown.

use crate::{
    contrast::contrast_ratio,
    histogram::histogram_w1,
    patch_sw::{patch_sliced_wasserstein, PatchSw, SwParams},
    repetition::{Autocorrelation, Repetition},
    seam::{seam_ratio, Mask},
};
use vtex_synth::{Error, Result, Rgba8Image};

/// The report's targets: repetition below this where a plain tiling is ≈ 1 …
pub const TARGET_REPETITION: f64 = 0.2;
/// … a seam ratio at most this …
pub const TARGET_SEAM: f64 = 1.3;
/// … and a contrast ratio in this range.
pub const TARGET_CONTRAST: (f64, f64) = (0.9, 1.1);

/// One output judged against its sample.
#[derive(Clone, Debug, PartialEq)]
pub struct Metrics {
    /// Long-range repetition with the sample's size as the exclusion.
    pub repetition: Repetition,
    /// r at one sample period across and down, (w, 0) and (0, h), when within half the
    /// output: how much of the plain tiling's exact repeat is left.
    pub period_r: [Option<f64>; 2],
    pub seam_ratio: f64,
    pub contrast: f64,
    /// R, G, B.
    pub histogram_w1: [f64; 3],
    pub patch_sw: PatchSw,
}

impl Metrics {
    /// Mean of the three channels' histogram distances.
    pub fn histogram_w1_mean(&self) -> f64 {
        self.histogram_w1.iter().sum::<f64>() / 3.0
    }

    /// Whether the three targets hold.
    pub fn meets_targets(&self) -> bool {
        self.repetition.value < TARGET_REPETITION
            && self.seam_ratio <= TARGET_SEAM
            && (TARGET_CONTRAST.0..=TARGET_CONTRAST.1).contains(&self.contrast)
    }
}

/// Measures `output` against `sample`; `seams` marks the output's joins (both pixels beside
/// each), and must have the output's size.
pub fn measure(output: &Rgba8Image, sample: &Rgba8Image, seams: &Mask, sw: &SwParams) -> Result<Metrics> {
    if (seams.width, seams.height) != (output.width, output.height) {
        return Err(Error::param(
            "seams",
            format!("mask {}×{} for output {}×{}", seams.width, seams.height, output.width, output.height),
        ));
    }
    let auto = Autocorrelation::new(output)?;
    Ok(Metrics {
        repetition: auto.max_outside(sample.width, sample.height)?,
        period_r: [auto.at(sample.width as i64, 0), auto.at(0, sample.height as i64)],
        seam_ratio: seam_ratio(output, |x, y| seams.get(x, y))?,
        contrast: contrast_ratio(output, sample)?,
        histogram_w1: histogram_w1(output, sample)?,
        patch_sw: patch_sliced_wasserstein(output, sample, sw)?,
    })
}

/// Images side by side on white, 16 pixels apart: the reports' comparison panels.
pub fn side_by_side(images: &[&Rgba8Image]) -> Rgba8Image {
    const GAP: u32 = 16;
    let width = images.iter().map(|i| i.width + GAP).sum::<u32>().saturating_sub(GAP);
    let mut out = Rgba8Image::new(width, images.iter().map(|i| i.height).max().unwrap_or(0));
    out.data.fill(255);
    let mut x = 0;
    for img in images {
        out.blit(img, x, 0);
        x += img.width + GAP;
    }
    out
}

/// A markdown table of named outputs side by side (one column each), with the targets.
pub fn comparison_table(columns: &[(&str, &Metrics)]) -> String {
    let mut s = String::from("| metric |");
    for (name, _) in columns {
        s += &format!(" {name} |");
    }
    s += " target |\n|---|";
    s += &"---:|".repeat(columns.len());
    s += "---|\n";
    let mut row = |label: &str, cell: &dyn Fn(&Metrics) -> String, target: &str| {
        s += &format!("| {label} |");
        for (_, m) in columns {
            s += &format!(" {} |", cell(m));
        }
        s += &format!(" {target} |\n");
    };
    row(
        "repetition (lag)",
        &|m| format!("{:.3} ({}, {})", m.repetition.value, m.repetition.dx, m.repetition.dy),
        &format!("< {TARGET_REPETITION}"),
    );
    row(
        "r at one period (w, 0) / (0, h)",
        &|m| m.period_r.map(|r| r.map_or("—".into(), |v| format!("{v:.3}"))).join(" / "),
        "",
    );
    row("seam ratio", &|m| format!("{:.3}", m.seam_ratio), &format!("≤ {TARGET_SEAM}"));
    row("contrast ratio", &|m| format!("{:.3}", m.contrast), &format!("{}–{}", TARGET_CONTRAST.0, TARGET_CONTRAST.1));
    row(
        "histogram W1 R/G/B",
        &|m| format!("{:.2} / {:.2} / {:.2}", m.histogram_w1[0], m.histogram_w1[1], m.histogram_w1[2]),
        "low",
    );
    row(
        "patch SW per scale (1, ½, ¼)",
        &|m| m.patch_sw.per_scale.iter().map(|v| format!("{v:.2}")).collect::<Vec<_>>().join(" / "),
        "low",
    );
    row("patch SW mean", &|m| format!("{:.2}", m.patch_sw.mean), "low");
    s
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::{noise, tiled};

    #[test]
    fn a_tiling_measured_against_its_tile() {
        let sample = noise(32, 32, 1);
        let out = tiled(&sample, 128, 128);
        let m = measure(&out, &sample, &Mask::grid(128, 128, 32, 32, 0, 0), &SwParams::default()).unwrap();
        assert!((m.repetition.value - 1.0).abs() < 1e-9);
        assert!(m.period_r.iter().all(|r| (r.unwrap() - 1.0).abs() < 1e-9), "{m:?}");
        assert!((m.contrast - 1.0).abs() < 1e-12);
        assert_eq!(m.histogram_w1, [0.0; 3]);
        // Noise has no seams to hide: joins look like everything else.
        assert!((m.seam_ratio - 1.0).abs() < 0.1, "{m:?}");
        assert!(!m.meets_targets());
        let table = comparison_table(&[("plain tiling", &m), ("again", &m)]);
        assert!(table.contains("| repetition (lag) | 1.000 ("), "{table}");
        assert_eq!(table.lines().count(), 2 + 7);
        assert!(table.lines().all(|l| l.matches('|').count() == 5), "{table}");
    }

    #[test]
    fn panels_are_laid_out_left_to_right_16_pixels_apart() {
        let (a, b) = (noise(3, 2, 1), noise(5, 4, 2));
        let p = side_by_side(&[&a, &b]);
        assert_eq!((p.width, p.height), (3 + 16 + 5, 4));
        assert_eq!(p.crop(0, 0, 3, 2), a);
        assert_eq!(p.crop(19, 0, 5, 4), b);
        assert_eq!(p.pixel(10, 1), [255; 4]);
        assert_eq!(p.pixel(0, 3), [255; 4]);
    }

    #[test]
    fn refuses_a_mask_of_another_size() {
        let img = noise(64, 64, 1);
        let err = measure(&img, &img, &Mask::new(32, 32), &SwParams::default()).unwrap_err();
        assert!(err.to_string().contains("seams"), "{err}");
    }
}
