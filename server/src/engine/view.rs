//! A rectangle of level 0 shown at any output size: the one rendering that Deep Zoom, IIIF and
//! XYZ share. A view that is exactly a tile of the pyramid is that tile, from the cache (so the
//! bytes, ETag and cost are the tile API's); any other view is rendered from the finest mip
//! level no finer than its output, then resampled — so its work is bounded by its output, like
//! a region's, whatever rectangle it covers.

use super::{Engine, Error};
use crate::config::MAX_REGION_SIDE;
use crate::encode::Format;
use crate::store::Entry;
use std::sync::Arc;
use vtex_synth::layer::Layer;
use vtex_synth::texture::{level_count, level_size};
use vtex_synth::{Region, Rgba8Image};

/// Level-0 pixels `x..x+w` × `y..y+h` (inside the texture's extent) shown at `out_w` × `out_h`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct View {
    pub x: u64,
    pub y: u64,
    pub w: u64,
    pub h: u64,
    pub out_w: u32,
    pub out_h: u32,
    pub frame: u32,
}

/// Whether `w` × `h` is over the region bounds.
fn over(w: u64, h: u64, max_pixels: u64) -> bool {
    w > MAX_REGION_SIDE as u64 || h > MAX_REGION_SIDE as u64 || w * h > max_pixels
}

/// Where a view is read from: `region` of its mip level, resampled unless `exact`.
struct Source {
    region: Region,
    exact: bool,
}

impl View {
    /// The finest level whose pixels are no smaller than the output's in both directions (the
    /// coarsest level when the output is smaller still) — or a coarser one when the view's
    /// rectangle of it would be over the region bounds (an output stretched far in one
    /// direction) — and the rectangle of it the view covers.
    fn source(&self, entry: &Entry, max_pixels: u64) -> Source {
        let (tw, th) = (entry.texture.width(), entry.texture.height());
        let top = level_count(tw, th) - 1;
        let fits = |l: u32| ((self.out_w as u64) << l) <= self.w && ((self.out_h as u64) << l) <= self.h;
        let mut level = 0;
        while level < top && fits(level + 1) {
            level += 1;
        }
        loop {
            let (lw, lh) = level_size(tw, th, level);
            let (x0, y0) = (self.x >> level, self.y >> level);
            let x1 = (self.x + self.w).div_ceil(1 << level).min(lw);
            let y1 = (self.y + self.h).div_ceil(1 << level).min(lh);
            let (w, h) = ((x1 - x0).max(1), (y1 - y0).max(1));
            if level < top && over(w, h, max_pixels) {
                level += 1;
                continue;
            }
            let aligned = self.x % (1 << level) == 0 && self.y % (1 << level) == 0;
            let exact = aligned && (w, h) == (self.out_w as u64, self.out_h as u64);
            let region = Region::new(level, x0 as i64, y0 as i64, w as u32, h as u32).at_frame(self.frame);
            return Source { region, exact };
        }
    }

    /// The tile (level, x, y) of `entry`'s served pyramid this view is exactly, if any.
    pub fn as_tile(&self, entry: &Entry, max_pixels: u64) -> Option<(u32, u32, u32)> {
        let Source { region: r, exact } = self.source(entry, max_pixels);
        let ts = entry.tile_size as i64;
        if !exact || r.level >= entry.levels || r.x % ts != 0 || r.y % ts != 0 {
            return None;
        }
        let (lw, lh) = level_size(entry.texture.width(), entry.texture.height(), r.level);
        let full = |at: i64, len: u32, size: u64| len as u64 == (size - at as u64).min(ts as u64);
        (full(r.x, r.width, lw) && full(r.y, r.height, lh)).then(|| (r.level, (r.x / ts) as u32, (r.y / ts) as u32))
    }

    /// Refuses a view whose output is over the region bounds (`--max-region-pixels`,
    /// [`MAX_REGION_SIDE`] a side), before anything is reserved; its source is then within them
    /// too ([`View::source`]).
    pub fn check(&self, max_pixels: u64) -> Result<(), Error> {
        if self.out_w == 0 || self.out_h == 0 || over(self.out_w as u64, self.out_h as u64, max_pixels) {
            return Err(Error::Invalid(format!(
                "output {}×{} is outside the limits: 1..={MAX_REGION_SIDE} pixels a side and at most \
                 {max_pixels} pixels in all",
                self.out_w, self.out_h
            )));
        }
        Ok(())
    }

    /// Most bytes [`render`] holds at once: the source pixels and the output pixels.
    pub fn peak_bytes(&self, entry: &Entry, max_pixels: u64) -> u64 {
        let r = self.source(entry, max_pixels).region;
        r.pixel_count() * 4 + self.out_w as u64 * self.out_h as u64 * 4
    }
}

impl Engine {
    /// The pixels of `view` (checked with [`View::check`]) under the region bounds
    /// `max_pixels`: its source region rendered holding a synthesis slot, then resampled to the
    /// output size unless it is exact.
    pub async fn view(&self, entry: Arc<Entry>, view: View, max_pixels: u64) -> Result<Rgba8Image, Error> {
        let Source { region, exact } = view.source(&entry, max_pixels);
        vtex_synth::texture::check_region(&*entry.texture, &region)?;
        let raw = self.synthesize(entry, region, Layer::Color, Format::Rgba).await?;
        let src = Rgba8Image::from_raw(region.width, region.height, raw)
            .map_err(|e| Error::failed("a rendered region has the wrong size", e))?;
        if exact {
            return Ok(src);
        }
        tokio::task::spawn_blocking(move || resample(&src, &region, &view))
            .await
            .map_err(|e| Error::failed("resampling failed", e))
    }
}

/// Bilinear resampling of `src` (level `region.level` pixels from `region.x`, `region.y`) at the
/// centres of the output pixels of `view`, in sRGB space like the mip filter.
fn resample(src: &Rgba8Image, region: &Region, view: &View) -> Rgba8Image {
    let scale = (1u64 << region.level) as f64;
    let axis = |out: u32, start: u64, len: u64, origin: i64, size: u32| -> Vec<(usize, usize, f64)> {
        (0..out)
            .map(|i| {
                let at = (start as f64 + (i as f64 + 0.5) * len as f64 / out as f64) / scale - origin as f64 - 0.5;
                let at = at.clamp(0.0, (size - 1) as f64);
                let lo = at.floor() as usize;
                (lo, (lo + 1).min(size as usize - 1), at - lo as f64)
            })
            .collect()
    };
    let xs = axis(view.out_w, view.x, view.w, region.x, src.width);
    let ys = axis(view.out_h, view.y, view.h, region.y, src.height);
    let mut out = Rgba8Image::new(view.out_w, view.out_h);
    let stride = src.width as usize * 4;
    for (j, &(y0, y1, fy)) in ys.iter().enumerate() {
        for (i, &(x0, x1, fx)) in xs.iter().enumerate() {
            let o = (j * view.out_w as usize + i) * 4;
            for c in 0..4 {
                let p = |x: usize, y: usize| src.data[y * stride + x * 4 + c] as f64;
                let top = p(x0, y0) + (p(x1, y0) - p(x0, y0)) * fx;
                let bottom = p(x0, y1) + (p(x1, y1) - p(x0, y1)) * fx;
                out.data[o + c] = (top + (bottom - top) * fy).round() as u8;
            }
        }
    }
    out
}

#[cfg(test)]
mod tests {
    use super::*;

    fn view(x: u64, y: u64, w: u64, h: u64, out_w: u32, out_h: u32) -> View {
        View { x, y, w, h, out_w, out_h, frame: 0 }
    }

    #[test]
    fn resampling_at_the_source_scale_is_the_identity() {
        let mut src = Rgba8Image::new(8, 4);
        for (i, b) in src.data.iter_mut().enumerate() {
            *b = (i * 7) as u8;
        }
        let region = Region::new(1, 3, 5, 8, 4);
        let same = resample(&src, &region, &view(6, 10, 16, 8, 8, 4));
        assert_eq!(same.data, src.data);
    }

    #[test]
    fn resampling_halves_by_averaging_pairs() {
        let mut src = Rgba8Image::new(4, 1);
        for x in 0..4 {
            src.set_pixel(x, 0, [x as u8 * 10, 0, 0, 255]);
        }
        let half = resample(&src, &Region::new(0, 0, 0, 4, 1), &view(0, 0, 4, 1, 2, 1));
        assert_eq!(half.pixel(0, 0)[0], 5);
        assert_eq!(half.pixel(1, 0)[0], 25);
    }
}
