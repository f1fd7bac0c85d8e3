//! Lattice share: is a copy-based output locked to a grid of the sample? A model that copies
//! sample pixels and whose sources all satisfy S(p) ≡ p (mod 2^j) can place the sample at only
//! (w/2^j)·(h/2^j) translations; its output is a collage of those few shifted copies. A model
//! free of the lattice puts a pixel there by chance, 1/4^j of the time.

use vtex_synth::{Error, Result};

/// The share of pixels on the 2^j lattice, for one j.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct LatticeShare {
    /// The lattice's step is 2^bits.
    pub bits: u32,
    /// Fraction of pixels p whose source S(p) ≡ p (mod 2^bits) on both axes.
    pub share: f64,
    /// What a source unrelated to the pixel's position gives: 1/4^bits.
    pub chance: f64,
}

impl LatticeShare {
    /// The share over chance: 1 for no lattice, 4^bits for a locked one.
    pub fn excess(&self) -> f64 {
        self.share / self.chance
    }
}

/// Lattice shares for j = 1..=max_bits of a `w × h` window whose top-left pixel is (x0, y0) in
/// output coordinates and whose pixel (x, y) copies sample pixel `sources[y·w + x]`.
pub fn lattice_shares(x0: i64, y0: i64, w: u32, sources: &[(u32, u32)], max_bits: u32) -> Result<Vec<LatticeShare>> {
    if w == 0 || sources.is_empty() || sources.len() % w as usize != 0 {
        return Err(Error::param("sources", format!("{} sources do not fill rows of {w}", sources.len())));
    }
    if !(1..=16).contains(&max_bits) {
        return Err(Error::param("max_bits", format!("{max_bits}: must be 1..=16")));
    }
    let mut on = vec![0u64; max_bits as usize];
    for (i, &(sx, sy)) in sources.iter().enumerate() {
        let x = x0.wrapping_add((i % w as usize) as i64);
        let y = y0.wrapping_add((i / w as usize) as i64);
        // The lowest bit at which the source and the pixel differ on either axis.
        let dx = (sx as i64).wrapping_sub(x) as u64;
        let dy = (sy as i64).wrapping_sub(y) as u64;
        let agree = (dx | dy).trailing_zeros().min(max_bits);
        on.iter_mut().take(agree as usize).for_each(|c| *c += 1);
    }
    let n = sources.len() as f64;
    Ok(on
        .iter()
        .enumerate()
        .map(|(j, &c)| {
            let bits = j as u32 + 1;
            LatticeShare { bits, share: c as f64 / n, chance: 1.0 / (1u64 << (2 * bits)) as f64 }
        })
        .collect())
}

#[cfg(test)]
mod tests {
    use super::*;
    use vtex_synth::hash::hash4;

    /// A window of sources given by `f` at (x0, y0).
    fn window(x0: i64, y0: i64, w: u32, h: u32, f: impl Fn(i64, i64) -> (u32, u32)) -> Vec<(u32, u32)> {
        (0..h as i64).flat_map(|y| (0..w as i64).map(move |x| (x0 + x, y0 + y))).map(|(x, y)| f(x, y)).collect()
    }

    #[test]
    fn a_tiling_is_on_every_lattice_and_random_sources_are_at_chance() {
        // A plain tiling of a 64² sample copies p mod 64: every pixel on every lattice, even at
        // negative coordinates.
        let tiling = window(-37, 1000, 100, 60, |x, y| (x.rem_euclid(64) as u32, y.rem_euclid(64) as u32));
        for s in lattice_shares(-37, 1000, 100, &tiling, 3).unwrap() {
            assert_eq!(s.share, 1.0);
            assert_eq!(s.excess(), (1u64 << (2 * s.bits)) as f64);
        }
        // Coordinate upsampling without jitter: a 2^3-aligned block of the sample per cell.
        let blocks = window(5, 9, 64, 64, |x, y| {
            let h = hash4(1, 2, x >> 3, y >> 3);
            (((h as i64 & 7) * 8 + (x & 7)) as u32, (((h >> 8) as i64 & 7) * 8 + (y & 7)) as u32)
        });
        let shares = lattice_shares(5, 9, 64, &blocks, 4).unwrap();
        assert_eq!(shares.iter().map(|s| s.share).take(3).collect::<Vec<_>>(), vec![1.0; 3]);
        assert!(shares[3].share < 0.4, "not on the 16-lattice: {:?}", shares[3]);
        // Hashed sources: near 1/4, 1/16, 1/64.
        let random = window(0, 0, 256, 256, |x, y| {
            let h = hash4(3, 4, x, y);
            ((h & 63) as u32, ((h >> 6) & 63) as u32)
        });
        for s in lattice_shares(0, 0, 256, &random, 3).unwrap() {
            assert!((s.excess() - 1.0).abs() < 0.1, "{s:?}");
        }
        // One pixel shifted by one: on no lattice.
        let shifted = window(0, 0, 32, 32, |x, y| ((x + 1) as u32, y as u32));
        assert!(lattice_shares(0, 0, 32, &shifted, 2).unwrap().iter().all(|s| s.share == 0.0));
    }

    #[test]
    fn bad_windows_are_refused() {
        assert!(lattice_shares(0, 0, 0, &[(0, 0)], 3).is_err());
        assert!(lattice_shares(0, 0, 2, &[(0, 0); 3], 3).is_err());
        assert!(lattice_shares(0, 0, 1, &[(0, 0)], 0).is_err());
    }
}
