//! Arnold's cat map (x, y) → (x + y, x + 2y) on the texture torus (paper eq. 1–2).

/// `iterations` steps of the cat map on a `width × height` torus, as one linear map.
///
/// The paper's map is defined on a square. A non-square torus is scaled onto the square torus
/// of side lcm(width, height) — exact for square textures, where the scale is 1 — mapped
/// there, and scaled back. The map is linear, so `iterations` steps are the matrix
/// [[1, 1], [1, 2]] raised to that power modulo the side, computed once by squaring: a block
/// costs two multiply-adds however many iterations there are.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct CatMap {
    n: u64,
    scale: (u64, u64),
    /// [[a, b], [c, d]]: (x, y) → (a·x + b·y, c·x + d·y) mod n.
    matrix: [[u64; 2]; 2],
}

impl CatMap {
    pub fn new(width: u64, height: u64, iterations: u32) -> Self {
        let n = lcm(width, height);
        let mut matrix = [[1 % n, 0], [0, 1 % n]];
        let mut power = [[1 % n, 1 % n], [1 % n, 2 % n]];
        let mut e = iterations;
        while e > 0 {
            if e & 1 == 1 {
                matrix = mul(&matrix, &power, n);
            }
            power = mul(&power, &power, n);
            e >>= 1;
        }
        Self { n, scale: (n / width, n / height), matrix }
    }

    /// Where (x, y) of the `width × height` torus goes.
    pub fn apply(&self, x: u64, y: u64) -> (u64, u64) {
        let (u, v) = (x * self.scale.0, y * self.scale.1);
        let [[a, b], [c, d]] = self.matrix;
        let n = self.n;
        let row = |p: u64, q: u64| add(mul_mod(p, u, n), mul_mod(q, v, n), n);
        (row(a, b) / self.scale.0, row(c, d) / self.scale.1)
    }

    /// The factors scaling the texture onto the square torus (1 × 1 for square textures).
    pub fn scale(&self) -> (u64, u64) {
        self.scale
    }

    /// Points of the square torus taken back to the `width × height` torus each `[x0, x0 + w) ×
    /// [y0, y0 + h)` point of the texture comes from: `visit(x, y)` for every (x, y) that
    /// [`apply`](Self::apply) moves into that rectangle (which must lie in the texture), found
    /// by running the inverse matrix over the rectangle scaled onto the square torus. The work
    /// is the rectangle's area times the scale's, whatever the size of the torus.
    pub fn preimages(&self, (x0, y0): (u64, u64), (w, h): (u64, u64), mut visit: impl FnMut(u64, u64)) {
        let n = self.n;
        let (sx, sy) = self.scale;
        // The matrix has determinant 1: its inverse is [[d, −b], [−c, a]].
        let [[a, b], [c, d]] = self.matrix;
        let neg = |v: u64| (n - v) % n;
        let [[ia, ib], [ic, id]] = [[d, neg(b)], [neg(c), a]];
        let (u0, u1) = (x0 * sx, (x0 + w) * sx);
        let unscaled = |v: u64, s: u64| match s {
            1 => Some(v),
            _ => (v % s == 0).then(|| v / s),
        };
        for v in y0 * sy..(y0 + h) * sy {
            let (mut x, mut y) =
                (add(mul_mod(ia, u0, n), mul_mod(ib, v, n), n), add(mul_mod(ic, u0, n), mul_mod(id, v, n), n));
            for _ in u0..u1 {
                if let (Some(x), Some(y)) = (unscaled(x, sx), unscaled(y, sy)) {
                    visit(x, y);
                }
                (x, y) = (add(x, ia, n), add(y, ic, n));
            }
        }
    }
}

fn mul(x: &[[u64; 2]; 2], y: &[[u64; 2]; 2], n: u64) -> [[u64; 2]; 2] {
    let cell = |i: usize, j: usize| add(mul_mod(x[i][0], y[0][j], n), mul_mod(x[i][1], y[1][j], n), n);
    [[cell(0, 0), cell(0, 1)], [cell(1, 0), cell(1, 1)]]
}

/// a·b mod n for a, b < n; in 64 bits whenever the product fits (every side below 2^32).
fn mul_mod(a: u64, b: u64, n: u64) -> u64 {
    match a.checked_mul(b) {
        Some(p) => p % n,
        None => (a as u128 * b as u128 % n as u128) as u64,
    }
}

/// a + b mod n for a, b < n.
fn add(a: u64, b: u64, n: u64) -> u64 {
    let s = a as u128 + b as u128;
    (if s >= n as u128 { s - n as u128 } else { s }) as u64
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

    /// One step of the cat map on an `n × n` torus, as the paper writes it.
    fn step(x: u64, y: u64, n: u64) -> (u64, u64) {
        ((x + y) % n, (x + 2 * y) % n)
    }

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
                let (u, v) = CatMap::new(n, n, 10).apply(x, y);
                assert!(!std::mem::replace(&mut seen[(v * n + u) as usize], true));
            }
        }
    }

    #[test]
    fn zero_iterations_is_identity_and_known_values() {
        assert_eq!(CatMap::new(100, 100, 0).apply(5, 9), (5, 9));
        assert_eq!(step(3, 4, 10), (7, 1));
        // Non-square: stays on the torus.
        for (x, y) in [(0, 0), (99, 49), (37, 11)] {
            let (u, v) = CatMap::new(100, 50, 10).apply(x, y);
            assert!(u < 100 && v < 50);
        }
    }

    /// The paper's definition, one step at a time.
    fn stepped(x: u64, y: u64, width: u64, height: u64, iterations: u32) -> (u64, u64) {
        let n = lcm(width, height);
        let (sx, sy) = (n / width, n / height);
        let (mut u, mut v) = (x * sx, y * sy);
        for _ in 0..iterations {
            (u, v) = step(u, v, n);
        }
        (u / sx, v / sy)
    }

    #[test]
    fn the_matrix_power_equals_iterating_step_by_step() {
        for (w, h) in [(1, 1), (64, 64), (100, 50), (48, 80), (100_000, 100_000), (6_400, 25_600)] {
            for i in [0, 1, 2, 3, 10, 17, 64, 1000] {
                let map = CatMap::new(w, h, i);
                for k in 0..40u64 {
                    let (x, y) = (k * 7919 % w, k * 104_729 % h);
                    assert_eq!(map.apply(x, y), stepped(x, y, w, h, i), "{w}×{h}, {i} iterations, ({x}, {y})");
                }
            }
        }
    }

    #[test]
    fn preimages_are_exactly_the_points_moved_into_the_rectangle() {
        for (w, h, i) in [(64, 64, 10), (60, 40, 3), (48, 80, 10), (30, 30, 0), (17, 51, 7)] {
            let map = CatMap::new(w, h, i);
            let (at, size) = ((w / 3, h / 4), (w / 5 + 1, h / 3 + 2));
            let inside = |(u, v): (u64, u64)| (at.0..at.0 + size.0).contains(&u) && (at.1..at.1 + size.1).contains(&v);
            let mut want: Vec<(u64, u64)> =
                (0..h).flat_map(|y| (0..w).map(move |x| (x, y))).filter(|&(x, y)| inside(map.apply(x, y))).collect();
            let mut got = Vec::new();
            map.preimages(at, size, |x, y| got.push((x, y)));
            want.sort_unstable();
            got.sort_unstable();
            assert_eq!(got, want, "{w}×{h}, {i} iterations");
        }
    }

    #[test]
    fn sides_near_the_largest_allowed_do_not_overflow() {
        let side = u32::MAX as u64;
        let map = CatMap::new(side, side - 1, 1000);
        let (u, v) = map.apply(side - 1, side - 2);
        assert!(u < side && v < side - 1);
        assert_eq!(CatMap::new(side, side, 1).apply(side - 1, side - 1), (side - 2, side - 3));
    }
}
