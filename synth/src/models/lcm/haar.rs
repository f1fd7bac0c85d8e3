//! The Haar representation of a base element (paper §6): an integer (S-transform) Haar
//! pyramid of the same number of coefficients as the element, from which every dyadic
//! resolution is read directly as the low-pass band of its level. Integer lifting makes it
//! lossless: [`inverse`] of [`forward`] is the element, bit for bit.
//!
//! Layout (Mallat): after one step on an s × s image, the s/2 × s/2 low-pass band sits in the
//! top-left corner and the three detail bands in the other quadrants; the next step works on
//! the low-pass corner. Coefficients need 10 bits, so they are stored as i16.

/// One 2 × 2 lifting step on [a b; c d]: (LL, LH, HL, HH).
#[inline]
fn lift(a: i32, b: i32, c: i32, d: i32) -> (i32, i32, i32, i32) {
    let (l1, h1) = ((a + b) >> 1, a - b);
    let (l2, h2) = ((c + d) >> 1, c - d);
    ((l1 + l2) >> 1, l1 - l2, (h1 + h2) >> 1, h1 - h2)
}

/// Undoes one S-transform pair: (floor((a+b)/2), a−b) → (a, b).
#[inline]
fn unpair(l: i32, h: i32) -> (i32, i32) {
    let a = l + ((h + 1) >> 1);
    (a, a - h)
}

/// The full Haar pyramid of a `side` × `side` image (`side` a power of two).
pub fn forward(img: &[i32], side: usize) -> Vec<i32> {
    let mut out = img.to_vec();
    let mut s = side;
    while s >= 2 {
        let h = s / 2;
        let mut next = vec![0i32; s * s];
        for y in 0..h {
            for x in 0..h {
                let p = |dx: usize, dy: usize| out[(2 * y + dy) * side + 2 * x + dx];
                let (ll, lh, hl, hh) = lift(p(0, 0), p(1, 0), p(0, 1), p(1, 1));
                next[y * s + x] = ll;
                next[y * s + x + h] = hl;
                next[(y + h) * s + x] = lh;
                next[(y + h) * s + x + h] = hh;
            }
        }
        for y in 0..s {
            out[y * side..y * side + s].copy_from_slice(&next[y * s..y * s + s]);
        }
        s = h;
    }
    out
}

/// The low-pass images at every resolution, finest first: entry `j` is the
/// (`side` >> j)² image, entry 0 being the exact inverse transform.
pub fn low_passes(coef: &[i32], side: usize) -> Vec<Vec<i32>> {
    // Rebuild from the coarsest band up, keeping each level's low-pass.
    let mut levels: Vec<Vec<i32>> = vec![vec![coef[0]]];
    let mut s = 1;
    while s < side {
        let low = levels.last().expect("one level at least");
        let n = 2 * s;
        let mut img = vec![0i32; n * n];
        for y in 0..s {
            for x in 0..s {
                let ll = low[y * s + x];
                let hl = coef[y * side + x + s];
                let lh = coef[(y + s) * side + x];
                let hh = coef[(y + s) * side + x + s];
                let (l1, l2) = unpair(ll, lh);
                let (h1, h2) = unpair(hl, hh);
                let (a, b) = unpair(l1, h1);
                let (c, d) = unpair(l2, h2);
                img[2 * y * n + 2 * x] = a;
                img[2 * y * n + 2 * x + 1] = b;
                img[(2 * y + 1) * n + 2 * x] = c;
                img[(2 * y + 1) * n + 2 * x + 1] = d;
            }
        }
        levels.push(img);
        s = n;
    }
    levels.reverse();
    levels
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn round_trip_is_lossless() {
        let side = 16;
        let img: Vec<i32> = (0..side * side).map(|i| ((i * 37 + 11) % 256) as i32 - 128).collect();
        let coef = forward(&img, side);
        assert!(coef.iter().all(|c| (-1024..1024).contains(c)));
        let lows = low_passes(&coef, side);
        assert_eq!(lows[0], img);
        assert_eq!(lows.len(), 5);
        assert_eq!(lows[4].len(), 1);
        // The low-pass of a constant image is that constant at every level.
        let flat = vec![-7; 64];
        assert!(low_passes(&forward(&flat, 8), 8).iter().all(|l| l.iter().all(|&v| v == -7)));
    }
}
