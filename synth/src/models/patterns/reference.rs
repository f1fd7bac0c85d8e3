//! The Reference Texture block (§3.2): T patterns packed Tx × Ty (§3.5), each with its own
//! mip chain built from that pattern alone — the "sub-textures" §5.2 asks hardware for — so
//! packed neighbours never bleed into each other at any level.

use crate::{mip, Result, Rgba8Image};

pub struct Reference {
    /// Pattern side S (a power of two) and log2 S.
    pub size: u32,
    pub log2: u32,
    pub tx: u32,
    pub ty: u32,
    /// `levels[l]` holds every pattern's level l, pattern after pattern, (S >> l)² RGBA8 each.
    levels: Vec<Vec<u8>>,
    /// Premultiplied mean colour of each pattern in [0, 1] (law-of-large-numbers filtering).
    pm_mean: Vec<[f32; 4]>,
}

impl Reference {
    /// Cuts `img` into `tx × ty` patterns of side `size` and builds their mip chains.
    pub fn new(img: &Rgba8Image, size: u32, tx: u32, ty: u32) -> Result<Self> {
        super::plan::check_reference(img.width, img.height, size, tx, ty)?;
        let log2 = size.trailing_zeros();
        let count = (tx * ty) as usize;
        let mut levels: Vec<Vec<u8>> =
            (0..=log2).map(|l| Vec::with_capacity(count * ((size >> l).pow(2) * 4) as usize)).collect();
        let mut pm_mean = Vec::with_capacity(count);
        for p in 0..count as u32 {
            let mut level = img.crop((p % tx) * size, (p / tx) * size, size, size);
            let mut acc = [0f64; 4];
            for px in level.data.chunks_exact(4) {
                let a = px[3] as f64 / 255.0;
                for c in 0..3 {
                    acc[c] += px[c] as f64 / 255.0 * a;
                }
                acc[3] += a;
            }
            let n = (size * size) as f64;
            pm_mean.push(acc.map(|v| (v / n) as f32));
            for l in 0..=log2 {
                if l > 0 {
                    level = mip::downsample(&level);
                }
                levels[l as usize].extend_from_slice(&level.data);
            }
        }
        Ok(Self { size, log2, tx, ty, levels, pm_mean })
    }

    pub fn count(&self) -> u32 {
        self.tx * self.ty
    }

    /// Texel (x, y) of pattern `p` at its mip level `level` (coordinates inside the level).
    #[inline(always)]
    pub fn texel(&self, p: u32, level: u32, x: u32, y: u32) -> [u8; 4] {
        let side = self.size >> level;
        let i = ((p as usize * side as usize + y as usize) * side as usize + x as usize) * 4;
        let d = &self.levels[level as usize];
        [d[i], d[i + 1], d[i + 2], d[i + 3]]
    }

    /// The pattern's 1 × 1 level: its exact box-filtered mean, as the mip chain rounds it.
    #[inline]
    pub fn mean_texel(&self, p: u32) -> [u8; 4] {
        self.texel(p, self.log2, 0, 0)
    }

    pub fn pm_mean(&self, p: u32) -> [f32; 4] {
        self.pm_mean[p as usize]
    }

    /// Bilinear sample of pattern `p` at level `level`, premultiplied, in [0, 1]. (u, v) are in
    /// that level's texels with centres at +0.5; neighbours are clamped inside the pattern.
    #[inline]
    pub fn bilinear_pm(&self, p: u32, level: u32, u: f32, v: f32) -> [f32; 4] {
        let side = (self.size >> level) as i32;
        let (fu, fv) = (u - 0.5, v - 0.5);
        let (x0, y0) = (fu.floor(), fv.floor());
        let (wx, wy) = (fu - x0, fv - y0);
        let clamp = |c: i32| c.clamp(0, side - 1) as u32;
        let (x0, y0) = (x0 as i32, y0 as i32);
        let mut acc = [0f32; 4];
        for (dy, wyv) in [(0, 1.0 - wy), (1, wy)] {
            for (dx, wxv) in [(0, 1.0 - wx), (1, wx)] {
                let w = wxv * wyv;
                if w == 0.0 {
                    continue;
                }
                let t = self.texel(p, level, clamp(x0 + dx), clamp(y0 + dy));
                let a = t[3] as f32 * (1.0 / 255.0);
                acc[0] += w * t[0] as f32 * (1.0 / 255.0) * a;
                acc[1] += w * t[1] as f32 * (1.0 / 255.0) * a;
                acc[2] += w * t[2] as f32 * (1.0 / 255.0) * a;
                acc[3] += w * a;
            }
        }
        acc
    }
}

/// Straight RGBA8 → premultiplied [0, 1].
#[inline]
pub fn to_pm(c: [u8; 4]) -> [f32; 4] {
    let a = c[3] as f32 * (1.0 / 255.0);
    [c[0] as f32 * (1.0 / 255.0) * a, c[1] as f32 * (1.0 / 255.0) * a, c[2] as f32 * (1.0 / 255.0) * a, a]
}

/// Composites `src` (straight RGBA8) over `dst` in place. Opaque and empty sources are exact
/// copies / no-ops, so opaque tilings keep their patterns' bytes.
#[inline]
pub fn over_u8(dst: &mut [u8], src: [u8; 4]) {
    match src[3] {
        255 => dst.copy_from_slice(&src),
        0 => {}
        _ => over_pm(dst, to_pm(src)),
    }
}

/// Composites a premultiplied [0, 1] colour over straight RGBA8 `dst` in place.
#[inline]
pub fn over_pm(dst: &mut [u8], src: [f32; 4]) {
    if src[3] <= 0.0 {
        return;
    }
    let d = to_pm([dst[0], dst[1], dst[2], dst[3]]);
    let k = 1.0 - src[3];
    let out = [src[0] + d[0] * k, src[1] + d[1] * k, src[2] + d[2] * k, src[3] + d[3] * k];
    let q = |v: f32| (v * 255.0 + 0.5).floor().clamp(0.0, 255.0) as u8;
    if out[3] <= 0.0 {
        dst.copy_from_slice(&[0, 0, 0, 0]);
        return;
    }
    let inv = 1.0 / out[3];
    dst.copy_from_slice(&[q(out[0] * inv), q(out[1] * inv), q(out[2] * inv), q(out[3])]);
}
