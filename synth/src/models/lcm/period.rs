//! The period of an LCM texture (paper §5): each layer repeats with its LCM's own period
//! times its replication spacing, and the texture with the least common multiple of those.
//! LCM sizes that are not multiples of each other (50 × 60 and 75 × 45) give a period much
//! larger than any one layer's.

use super::event::Event;

/// Greatest common divisor.
pub fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

/// Least common multiple, or `None` on overflow.
pub fn lcm(a: u64, b: u64) -> Option<u64> {
    (a / gcd(a, b)).checked_mul(b)
}

/// The smallest shifts (dx, dy), in points, that map the `w × h` mask onto itself along each
/// axis. Codes are compared as rendered, so every "no replication" code counts as one.
pub fn mask_period(codes: &[u8], w: usize, h: usize) -> (u64, u64) {
    let at = |i: usize, j: usize| Event::canonical(codes[j * w + i]);
    let shifts_to_itself = |d: usize, horizontal: bool| {
        (0..h).all(|j| {
            (0..w).all(|i| if horizontal { at(i, j) == at((i + d) % w, j) } else { at(i, j) == at(i, (j + d) % h) })
        })
    };
    let smallest = |n: usize, horizontal: bool| {
        (1..=n).find(|d| n % d == 0 && shifts_to_itself(*d, horizontal)).unwrap_or(n) as u64
    };
    (smallest(w, true), smallest(h, false))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paper_example_sizes() {
        // §5: layer 0 LCM 50×60 at spacing 16, layer 1 LCM 75×45 at spacing 8.
        let px = lcm(50 * 16, 75 * 8).unwrap();
        let py = lcm(60 * 16, 45 * 8).unwrap();
        assert_eq!((px, py), (2400, 2880));
        assert!(px > 800 && py > 960);
    }

    #[test]
    fn masks_with_inner_repetition() {
        // A 6×4 mask that repeats every 3 columns and every 2 rows.
        let row = [1u8, 5, 9, 1, 5, 9];
        let other = [0u8, 0, 13, 0, 0, 13];
        let codes: Vec<u8> = [row, other, row, other].concat();
        assert_eq!(mask_period(&codes, 6, 4), (3, 2));
        // "No replication" codes with different spare bits are the same event.
        let codes = [0u8, 4, 0, 8];
        assert_eq!(mask_period(&codes, 4, 1), (1, 1));
        assert_eq!(mask_period(&[1, 2, 3, 1, 2, 3, 1], 7, 1), (7, 1));
    }
}
