//! A rectangle of one level's pixels, as the evaluator's cones and the cache's blocks are.

/// A rectangle of one level's pixels; coordinates wrap like the plane's.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Rect {
    pub x: i64,
    pub y: i64,
    pub w: usize,
    pub h: usize,
}

/// The extent of a tap set: (min dx, max dx, min dy, max dy).
fn extent(taps: &[(i8, i8)]) -> (i64, i64, i64, i64) {
    let xs = || taps.iter().map(|t| t.0 as i64);
    let ys = || taps.iter().map(|t| t.1 as i64);
    (xs().min().unwrap_or(0), xs().max().unwrap_or(0), ys().min().unwrap_or(0), ys().max().unwrap_or(0))
}

impl Rect {
    /// Its pixel count.
    pub fn area(&self) -> usize {
        self.w * self.h
    }

    /// The pixels any of `taps` reaches from this rectangle.
    pub(super) fn reach(&self, taps: &[(i8, i8)]) -> Rect {
        let (x0, x1, y0, y1) = extent(taps);
        Rect {
            x: self.x.wrapping_add(x0),
            y: self.y.wrapping_add(y0),
            w: self.w + (x1 - x0) as usize,
            h: self.h + (y1 - y0) as usize,
        }
    }

    /// The parents of its pixels at the next coarser level.
    pub(super) fn parent(&self) -> Rect {
        let last = |v: i64, n: usize| v.wrapping_add(n as i64 - 1) >> 1;
        let (x, y) = (self.x >> 1, self.y >> 1);
        Rect {
            x,
            y,
            w: last(self.x, self.w).wrapping_sub(x) as usize + 1,
            h: last(self.y, self.h).wrapping_sub(y) as usize + 1,
        }
    }

    /// The bounding rectangle of both.
    pub(super) fn union(&self, o: &Rect) -> Rect {
        let x = self.x.min(o.x);
        let y = self.y.min(o.y);
        let x1 = (self.x + self.w as i64).max(o.x + o.w as i64);
        let y1 = (self.y + self.h as i64).max(o.y + o.h as i64);
        Rect { x, y, w: (x1 - x) as usize, h: (y1 - y) as usize }
    }

    /// Index of pixel (x, y), which must lie inside.
    #[inline]
    pub(super) fn at(&self, x: i64, y: i64) -> usize {
        y.wrapping_sub(self.y) as usize * self.w + x.wrapping_sub(self.x) as usize
    }
}
