//! Turning a real image into a chaos-mosaic sample for the quality report.
//!
//! Two kinds of input, prepared differently so that neither is distorted:
//! * a **pattern** (a GIMP `.pat`, made to tile) is used exactly as it is, at its own size —
//!   cropping would break its seamless wrap and resampling would blur it;
//! * a **photo** (a PNG such as scikit-image's brick, grass, gravel) is box-downsampled by 2
//!   ([`vtex_synth::mip::downsample`]) while its shorter side is at least 4 × `side`, then
//!   centre-cropped to `side × side` (128 × 128 in the report): small enough that a 1024 × 1024
//!   output holds 8 × 8 tiles, large enough to hold several texture elements.

use vtex_synth::{mip, Error, Result, Rgba8Image};

/// The report's photo sample side, in pixels.
pub const PHOTO_SIDE: u32 = 128;
/// Largest pattern side the report accepts: at least four tiles across a 1024 canvas.
pub const MAX_PATTERN_SIDE: u32 = 256;

/// A sample's name in file names and tables: its file stem, every character other than an ASCII
/// letter, a digit, `-` or `_` replaced by `-`.
pub fn name_of(path: &std::path::Path) -> String {
    let stem = path.file_stem().map(|s| s.to_string_lossy().into_owned()).unwrap_or_default();
    stem.chars().map(|c| if c.is_ascii_alphanumeric() || c == '-' || c == '_' { c } else { '-' }).collect()
}

/// A photo reduced and centre-cropped to `side × side`, as described in the module docs.
/// Errors: a photo whose shorter side is below `side`.
pub fn prepare_photo(img: &Rgba8Image, side: u32) -> Result<Rgba8Image> {
    if side == 0 {
        return Err(Error::param("side", "must be at least 1"));
    }
    let mut img = img.clone();
    while img.width.min(img.height) >= 4 * side {
        img = mip::downsample(&img);
    }
    if img.width < side || img.height < side {
        return Err(Error::image(
            "photo",
            format!("{}×{} is smaller than the {side}×{side} sample", img.width, img.height),
        ));
    }
    Ok(img.crop((img.width - side) / 2, (img.height - side) / 2, side, side))
}

/// A pattern checked for use as is. Errors: a side above [`MAX_PATTERN_SIDE`].
pub fn prepare_pattern(img: &Rgba8Image) -> Result<Rgba8Image> {
    if img.width > MAX_PATTERN_SIDE || img.height > MAX_PATTERN_SIDE {
        return Err(Error::image(
            "pattern",
            format!("{}×{}; the report takes patterns up to {MAX_PATTERN_SIDE} a side", img.width, img.height),
        ));
    }
    Ok(img.clone())
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::noise;

    #[test]
    fn photos_are_halved_then_centre_cropped() {
        let big = noise(600, 520, 1);
        let s = prepare_photo(&big, 128).unwrap();
        assert_eq!((s.width, s.height), (128, 128));
        // 520 ≥ 512 → one halving to 300 × 260, then the centre crop at (86, 66).
        assert_eq!(s, mip::downsample(&big).crop(86, 66, 128, 128));
        let small = noise(200, 130, 2);
        assert_eq!(prepare_photo(&small, 128).unwrap(), small.crop(36, 1, 128, 128));
    }

    #[test]
    fn names_keep_letters_digits_dashes_and_underscores() {
        assert_eq!(name_of(std::path::Path::new("/x/skimage-brick.png")), "skimage-brick");
        assert_eq!(name_of(std::path::Path::new("a b/Stone 33 (old).pat")), "Stone-33--old-");
    }

    #[test]
    fn refuses_what_does_not_fit() {
        assert!(prepare_photo(&noise(300, 100, 1), 128).unwrap_err().to_string().contains("300×100"));
        assert!(prepare_photo(&noise(8, 8, 1), 0).is_err());
        assert!(prepare_pattern(&noise(257, 10, 1)).is_err());
        let p = noise(50, 31, 1);
        assert_eq!(prepare_pattern(&p).unwrap(), p);
    }
}
