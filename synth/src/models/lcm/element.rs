//! The base element: a square bitmap of side 2^K with signed intensity whose zero pixels are
//! transparent, and its scaled copies at every resolution the renderer may need.
//!
//! The encoding stores the element either explicitly at the resolutions its layers use (as
//! the paper counts bytes, one signed byte a pixel) or as its Haar transform (§6). In memory
//! every resolution 1 ..= K + magnify is kept in all eight orientations (4 rotations × mirror),
//! in Q8 fixed point (i16), so rendering is one table read per replication. Resolutions the
//! encoding does not hold are made here: coarser ones by the 2 × 2 box mean of the next finer
//! copy (so a mip level of a layer is the box filter of the level above), finer ones
//! (magnification, §2.4) by a 2× bilinear stretch.

use super::haar;
use crate::{Error, Result};

/// Largest K: a 256 × 256 element.
pub const MAX_K: u32 = 8;
/// Largest K + magnification: the biggest in-memory copy is 512 × 512.
pub const MAX_TOP: u32 = 9;
/// Fixed-point shift of in-memory copies.
pub const Q: u32 = 8;

/// One signed-intensity plane of side 2^K, as stored in an encoding (one byte a pixel).
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct Plane {
    pub k: u32,
    pub pixels: Vec<i8>,
}

impl Plane {
    /// Checks that `side` is a power of two within bounds and matches the data.
    pub fn new(side: usize, pixels: Vec<i8>, what: &str) -> Result<Plane> {
        let k = side_exponent(side, what)?;
        if pixels.len() != side * side {
            return Err(Error::param(what, format!("{} pixels for a {side}×{side} element", pixels.len())));
        }
        Ok(Plane { k, pixels })
    }

    pub fn side(&self) -> usize {
        1 << self.k
    }

    /// The 2 × 2 box mean, rounded half up: the copy one resolution lower.
    pub fn halve(&self) -> Plane {
        let s = self.side() / 2;
        let src = |x: usize, y: usize| self.pixels[y * 2 * s + x] as i32;
        let pixels = (0..s * s)
            .map(|i| {
                let (x, y) = (i % s * 2, i / s * 2);
                ((src(x, y) + src(x + 1, y) + src(x, y + 1) + src(x + 1, y + 1) + 2) >> 2) as i8
            })
            .collect();
        Plane { k: self.k - 1, pixels }
    }

    /// Sum of all pixels (the element's mean times its area).
    pub fn sum(&self) -> i64 {
        self.pixels.iter().map(|&p| p as i64).sum()
    }
}

/// K for a side of 2^K pixels, or an error naming `what`.
pub fn side_exponent(side: usize, what: &str) -> Result<u32> {
    if side < 2 || !side.is_power_of_two() || side > 1 << MAX_K {
        return Err(Error::param(
            what,
            format!("base element side {side} is not a power of two 2^K with 1 ≤ K ≤ {MAX_K}"),
        ));
    }
    Ok(side.trailing_zeros())
}

/// How an encoding holds one plane of the element.
#[derive(Clone, Debug, PartialEq, Eq)]
pub enum Stored {
    /// Explicit copies, finest first; the first is resolution K.
    Explicit(Vec<Plane>),
    /// The Haar pyramid of resolution K.
    Haar(Vec<i16>),
}

impl Stored {
    /// Explicit copies of `plane` at `resolutions` (each ≤ K; K itself is always kept).
    pub fn explicit(plane: &Plane, resolutions: &[u32]) -> Stored {
        let mut copies = vec![plane.clone()];
        let mut cur = plane.clone();
        while cur.k > 1 {
            cur = cur.halve();
            if resolutions.contains(&cur.k) {
                copies.push(cur.clone());
            }
        }
        Stored::Explicit(copies)
    }

    pub fn haar(plane: &Plane) -> Stored {
        let img: Vec<i32> = plane.pixels.iter().map(|&p| p as i32).collect();
        Stored::Haar(haar::forward(&img, plane.side()).into_iter().map(|c| c as i16).collect())
    }

    /// Encoded size in bytes.
    pub fn byte_len(&self) -> usize {
        match self {
            Stored::Explicit(c) => c.iter().map(|p| p.pixels.len()).sum(),
            Stored::Haar(c) => c.len() * 2,
        }
    }
}

/// Every resolution of one plane in every orientation, ready to render.
#[derive(Clone, Debug)]
pub struct Copies {
    /// `by_res[r]` for r in 0..=top holds 8 oriented copies of side 2^r (index 0 unused).
    by_res: Vec<[Vec<i16>; 8]>,
    /// The same for coverage: the share of opaque (non-zero) resolution-K pixels under each
    /// pixel, 0..=256. At resolution K it is 0 or 256; below, the box mean of that mask, so
    /// that non-zero application of a downsampled copy blends like the pixels it stands for.
    alpha: Vec<[Vec<u16>; 8]>,
    /// The finest resolution held: K + magnification.
    pub top: u32,
}

impl Copies {
    /// Builds every copy from what the encoding stores, for resolutions up to K + `magnify`.
    pub fn build(stored: &Stored, k: u32, magnify: u32) -> Copies {
        let top = k + magnify;
        // Unoriented Q8 copies, index = resolution.
        let mut plain: Vec<Vec<i32>> = vec![Vec::new(); top as usize + 1];
        match stored {
            Stored::Explicit(copies) => {
                for c in copies {
                    plain[c.k as usize] = c.pixels.iter().map(|&p| (p as i32) << Q).collect();
                }
                for r in (0..k).rev() {
                    if plain[r as usize].is_empty() {
                        plain[r as usize] = box_half(&plain[r as usize + 1], 1 << (r + 1));
                    }
                }
            }
            Stored::Haar(coef) => {
                let coef: Vec<i32> = coef.iter().map(|&c| c as i32).collect();
                for (j, low) in haar::low_passes(&coef, 1 << k).into_iter().enumerate() {
                    plain[(k as usize) - j] = low.into_iter().map(|p| p.clamp(-128, 127) << Q).collect();
                }
            }
        }
        let mut mask: Vec<Vec<i32>> = vec![Vec::new(); top as usize + 1];
        mask[k as usize] = plain[k as usize].iter().map(|&p| if p != 0 { 1 << Q } else { 0 }).collect();
        for r in (0..k).rev() {
            mask[r as usize] = box_half(&mask[r as usize + 1], 1 << (r + 1));
        }
        for r in k + 1..=top {
            plain[r as usize] = stretch(&plain[r as usize - 1], 1 << (r - 1));
            mask[r as usize] = stretch(&mask[r as usize - 1], 1 << (r - 1));
        }
        let all = |imgs: &[Vec<i32>]| -> Vec<[Vec<i32>; 8]> {
            imgs.iter()
                .enumerate()
                .map(|(r, img)| std::array::from_fn(|o| if r == 0 { Vec::new() } else { orient(img, 1 << r, o) }))
                .collect()
        };
        let by_res = all(&plain).into_iter().map(|a| a.map(|v| v.into_iter().map(|p| p as i16).collect())).collect();
        let alpha = all(&mask).into_iter().map(|a| a.map(|v| v.into_iter().map(|p| p as u16).collect())).collect();
        Copies { by_res, alpha, top }
    }

    /// The copy of resolution `r` (1 ..= top) in orientation `o` (mirror × 4 + quarter turns).
    #[inline]
    pub fn get(&self, r: u32, o: usize) -> &[i16] {
        &self.by_res[r as usize][o]
    }

    /// The coverage (0..=256) of [`Copies::get`]'s pixels.
    #[inline]
    pub fn alpha(&self, r: u32, o: usize) -> &[u16] {
        &self.alpha[r as usize][o]
    }
}

/// 2 × 2 box mean of a Q8 image of side `s`, rounded half up.
fn box_half(img: &[i32], s: usize) -> Vec<i32> {
    let h = s / 2;
    (0..h * h)
        .map(|i| {
            let (x, y) = (i % h * 2, i / h * 2);
            (img[y * s + x] + img[y * s + x + 1] + img[(y + 1) * s + x] + img[(y + 1) * s + x + 1] + 2) >> 2
        })
        .collect()
}

/// 2× bilinear stretch of a Q8 image of side `s` (outside the element is transparent zero).
fn stretch(img: &[i32], s: usize) -> Vec<i32> {
    let at = |x: isize, y: isize| -> i32 {
        if x < 0 || y < 0 || x >= s as isize || y >= s as isize {
            0
        } else {
            img[y as usize * s + x as usize]
        }
    };
    let n = 2 * s;
    (0..n * n)
        .map(|i| {
            let (x, y) = ((i % n) as isize, (i / n) as isize);
            // Pixel centre (x + ½)/2 − ½ in source pixels: the near neighbour weighs 3/4.
            let (sx, sy) = (x >> 1, y >> 1);
            let (nx, ny) = (if x & 1 == 0 { sx - 1 } else { sx + 1 }, if y & 1 == 0 { sy - 1 } else { sy + 1 });
            let v = 9 * at(sx, sy) + 3 * at(nx, sy) + 3 * at(sx, ny) + at(nx, ny);
            (v + 8) >> 4
        })
        .collect()
}

/// The element mirrored left–right if `o` ≥ 4, then turned clockwise by `o` mod 4 quarters.
fn orient(img: &[i32], s: usize, o: usize) -> Vec<i32> {
    let (mirror, rot) = (o >= 4, o & 3);
    let mut out = vec![0i32; s * s];
    for v in 0..s {
        for u in 0..s {
            // Undo the rotation: which pixel of the mirrored element lands at (u, v).
            let (x, y) = match rot {
                0 => (u, v),
                1 => (v, s - 1 - u),
                2 => (s - 1 - u, s - 1 - v),
                _ => (s - 1 - v, u),
            };
            let x = if mirror { s - 1 - x } else { x };
            out[v * s + u] = img[y * s + x];
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn orientations_turn_clockwise_and_mirror() {
        // 2×2 element [1 2; 3 4].
        let img = vec![1, 2, 3, 4];
        assert_eq!(orient(&img, 2, 0), vec![1, 2, 3, 4]);
        assert_eq!(orient(&img, 2, 1), vec![3, 1, 4, 2], "90° clockwise");
        assert_eq!(orient(&img, 2, 2), vec![4, 3, 2, 1]);
        assert_eq!(orient(&img, 2, 3), vec![2, 4, 1, 3]);
        assert_eq!(orient(&img, 2, 4), vec![2, 1, 4, 3], "mirrored");
    }

    #[test]
    fn sides_must_be_powers_of_two() {
        for bad in [0, 1, 3, 48, 512] {
            assert!(side_exponent(bad, "element").unwrap_err().to_string().contains("power of two"));
        }
        assert_eq!(side_exponent(32, "element").unwrap(), 5);
    }

    #[test]
    fn stretch_then_box_is_close_to_identity() {
        let img: Vec<i32> = (0..64).map(|i| ((i * 29) % 200 - 100) << Q).collect();
        let back = box_half(&stretch(&img, 8), 16);
        // Interior pixels come back within a blur of their neighbours.
        for y in 1..7 {
            for x in 1..7 {
                let (a, b) = (img[y * 8 + x], back[y * 8 + x]);
                let spread = (0..9).map(|i| (img[(y + i / 3 - 1) * 8 + x + i % 3 - 1] - a).abs()).max().unwrap();
                // The neighbours weigh 28/64 in all after the stretch and the box.
                assert!((a - b).abs() <= spread * 28 / 64 + 2, "({x},{y}): {a} vs {b}");
            }
        }
        let flat = vec![50 << Q; 16];
        let s = stretch(&flat, 4);
        assert_eq!(s[2 * 8 + 3], 50 << Q, "interior of a flat element stays flat");
    }
}
