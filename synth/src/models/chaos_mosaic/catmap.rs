//! Arnold's cat map on the texture torus (paper eq. 1–2).

/// The cat map (x, y) → (x + y, x + 2y) on an `n × n` torus: an area-preserving bijection.
#[inline]
pub fn step(x: u64, y: u64, n: u64) -> (u64, u64) {
    // x, y < n, so x + y < 2n and x + 2y < 3n: subtractions instead of divisions.
    let reduce = |mut v: u64| {
        while v >= n {
            v -= n;
        }
        v
    };
    (reduce(x + y), reduce(x + 2 * y))
}

/// `iterations` steps of the cat map on a `width × height` torus.
///
/// The paper's map is defined on a square. A non-square torus is scaled onto the square torus
/// of side lcm(width, height) — exact for square textures, where the scale is 1 — iterated
/// there, and scaled back.
pub fn iterate(x: u64, y: u64, width: u64, height: u64, iterations: u32) -> (u64, u64) {
    let n = lcm(width, height);
    let (sx, sy) = (n / width, n / height);
    let (mut u, mut v) = (x * sx, y * sy);
    for _ in 0..iterations {
        (u, v) = step(u, v, n);
    }
    (u / sx, v / sy)
}

fn gcd(a: u64, b: u64) -> u64 {
    if b == 0 {
        a
    } else {
        gcd(b, a % b)
    }
}

pub fn lcm(a: u64, b: u64) -> u64 {
    a / gcd(a, b) * b
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn is_a_bijection_on_square_tori() {
        for n in [1u64, 2, 7, 64, 160, 320] {
            let mut seen = vec![false; (n * n) as usize];
            for y in 0..n {
                for x in 0..n {
                    let (u, v) = step(x, y, n);
                    assert!(!std::mem::replace(&mut seen[(v * n + u) as usize], true), "n={n}: ({x},{y}) collides");
                }
            }
        }
    }

    #[test]
    fn ten_iterations_stay_bijective() {
        let n = 640u64;
        let mut seen = vec![false; (n * n) as usize];
        for y in 0..n {
            for x in 0..n {
                let (u, v) = iterate(x, y, n, n, 10);
                assert!(!std::mem::replace(&mut seen[(v * n + u) as usize], true));
            }
        }
    }

    #[test]
    fn zero_iterations_is_identity_and_known_values() {
        assert_eq!(iterate(5, 9, 100, 100, 0), (5, 9));
        assert_eq!(step(3, 4, 10), (7, 1));
        // Non-square: stays on the torus.
        for (x, y) in [(0, 0), (99, 49), (37, 11)] {
            let (u, v) = iterate(x, y, 100, 50, 10);
            assert!(u < 100 && v < 50);
        }
    }
}
