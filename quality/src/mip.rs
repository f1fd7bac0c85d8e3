//! Mip coherence measured: how close a texture's served coarse levels are to the exact 2×2 box
//! chain of its level 0, with point sampling (no prefilter, the aliasing baseline) beside it.

use vtex_synth::mip::{downsample_n, psnr};
use vtex_synth::texture::render_image;
use vtex_synth::{Region, Result, Rgba8Image, Texture};

/// One level's PSNR against the exact box chain, in dB (infinite when equal).
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LevelPsnr {
    pub level: u32,
    pub served_db: f64,
    pub point_db: f64,
}

/// Levels 1..=`levels` of the `side × side` level-0 window at the origin, each against the box
/// chain of that window (`side` a multiple of 2^`levels`).
pub fn psnr_by_level(texture: &dyn Texture, side: u32, levels: u32) -> Result<Vec<LevelPsnr>> {
    let level0 = render_image(texture, &Region::new(0, 0, 0, side, side))?;
    (1..=levels)
        .map(|level| {
            let served = render_image(texture, &Region::new(level, 0, 0, side >> level, side >> level))?;
            let exact = downsample_n(&level0, level);
            let point = point_sample(&level0, level);
            Ok(LevelPsnr { level, served_db: psnr(&served, &exact), point_db: psnr(&point, &exact) })
        })
        .collect()
}

/// Every 2^`level`-th pixel of `img`: what a level looks like without prefiltering.
pub fn point_sample(img: &Rgba8Image, level: u32) -> Rgba8Image {
    let (w, h) = (img.width >> level, img.height >> level);
    let mut out = Rgba8Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            let from = (((y << level) * img.width + (x << level)) * 4) as usize;
            let to = ((y * w + x) * 4) as usize;
            out.data[to..to + 4].copy_from_slice(&img.data[from..from + 4]);
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::test_images::noise;

    #[test]
    fn point_sampling_takes_the_top_left_pixel_of_each_block() {
        let img = noise(8, 8, 3);
        let p = point_sample(&img, 2);
        assert_eq!((p.width, p.height), (2, 2));
        assert_eq!(&p.data[4..8], &img.data[4 * 4..4 * 4 + 4]);
        assert_eq!(&p.data[12..16], &img.data[(4 * 8 + 4) * 4..(4 * 8 + 4) * 4 + 4]);
    }
}
