//! The interface every texture model implements, and the checks made before calling it.

use crate::{pixels::Rgba8Image, Error, Result};

/// Largest region one call may render: 64 Mpx (256 MiB of RGBA8). Servers set lower bounds.
pub const MAX_REGION_PIXELS: u64 = 1 << 26;

/// A rectangle of one mip level at one animation frame. Level 0 is full resolution; level L
/// has size ceil(W / 2^L) × ceil(H / 2^L). Coordinates may lie outside the level: a
/// [`Domain::Torus`] texture wraps, a [`Domain::Plane`] texture is defined everywhere.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Region {
    pub level: u32,
    pub x: i64,
    pub y: i64,
    pub width: u32,
    pub height: u32,
    /// Animation frame; ignored by textures that do not move.
    pub frame: u32,
}

impl Region {
    pub fn new(level: u32, x: i64, y: i64, width: u32, height: u32) -> Self {
        Self { level, x, y, width, height, frame: 0 }
    }

    pub fn at_frame(self, frame: u32) -> Self {
        Self { frame, ..self }
    }

    pub fn pixel_count(&self) -> u64 {
        self.width as u64 * self.height as u64
    }

    /// Bytes of the RGBA8 output buffer.
    pub fn byte_len(&self) -> usize {
        self.pixel_count() as usize * 4
    }
}

/// Heap one render may hold besides its output and what it leaves in the texture's caches,
/// whatever the region: models render large regions in bounded chunks, so that the renders
/// running at once add at most this much each to a server's budgets. The conformance suite
/// measures every demo against it.
pub const MAX_RENDER_WORKING_BYTES: u64 = 32 << 20;

pub use vtex_wire::{Animation, Domain};

/// A virtual texture: a pure function from a region to RGBA8 pixels.
///
/// Implementations must make every output pixel depend only on (encoding, level, x, y,
/// frame) — never on the region's other pixels, its size, the call order or any cache —
/// so that a tile always equals the matching crop of any larger region.
pub trait Texture: Send + Sync {
    /// The model id, as the registry lists it (`chaos-mosaic`, `lcm`, …).
    fn model(&self) -> &'static str;
    /// Level-0 width in pixels.
    fn width(&self) -> u64;
    /// Level-0 height in pixels.
    fn height(&self) -> u64;
    fn domain(&self) -> Domain;
    fn animation(&self) -> Option<Animation> {
        None
    }
    /// Writes `region` as row-major RGBA8 into `out` (exactly `region.byte_len()` bytes).
    /// Called only with regions that passed [`check_region`]. Polls `stop` between bands of
    /// work and returns early once it is requested, leaving `out` incomplete: the caller
    /// discards it. `stop` never changes a pixel that is written.
    fn render(&self, region: &Region, out: &mut [u8], stop: &dyn Stop);
}

/// A request to stop a render in progress: its client left, its deadline passed, or the
/// server is shutting down. An input like the region, so models stay pure functions.
pub trait Stop: Sync {
    fn requested(&self) -> bool;
}

/// The stop that is never requested, for renders that must finish.
pub struct Never;

impl Stop for Never {
    fn requested(&self) -> bool {
        false
    }
}

impl Stop for std::sync::atomic::AtomicBool {
    fn requested(&self) -> bool {
        self.load(std::sync::atomic::Ordering::Relaxed)
    }
}

pub use vtex_wire::levels::{level_count, level_size};

/// Checks a region against a texture before rendering: a level that exists, a non-empty
/// area within [`MAX_REGION_PIXELS`], coordinates whose far corner does not overflow.
pub fn check_region(tex: &dyn Texture, region: &Region) -> Result<()> {
    let levels = level_count(tex.width(), tex.height());
    if region.level >= levels {
        return Err(Error::Region(format!("level {} does not exist; levels are 0..{}", region.level, levels)));
    }
    if region.width == 0 || region.height == 0 {
        return Err(Error::Region(format!("empty region {}×{}", region.width, region.height)));
    }
    if region.pixel_count() > MAX_REGION_PIXELS {
        return Err(Error::Region(format!(
            "{}×{} is {} pixels; at most {MAX_REGION_PIXELS} per call",
            region.width,
            region.height,
            region.pixel_count()
        )));
    }
    let far = |v: i64, d: u32| v.checked_add(d as i64).is_none();
    if far(region.x, region.width) || far(region.y, region.height) {
        return Err(Error::Region("coordinates overflow".into()));
    }
    Ok(())
}

/// Checks and renders a region into a new image.
pub fn render_image(tex: &dyn Texture, region: &Region) -> Result<Rgba8Image> {
    Ok(render_image_until(tex, region, &Never)?.expect("a render that is never stopped completes"))
}

/// Checks and renders a region into a new image, unless `stop` is requested first: then `None`.
pub fn render_image_until(tex: &dyn Texture, region: &Region, stop: &dyn Stop) -> Result<Option<Rgba8Image>> {
    check_region(tex, region)?;
    let mut img = Rgba8Image::new(region.width, region.height);
    tex.render(region, &mut img.data, stop);
    Ok((!stop.requested()).then_some(img))
}

/// Reduces a coordinate onto a torus of period `period`.
#[inline]
pub fn wrap(v: i64, period: u64) -> u64 {
    v.rem_euclid(period as i64) as u64
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn level_sizes_round_up() {
        assert_eq!(level_size(100_000, 100_000, 0), (100_000, 100_000));
        assert_eq!(level_size(100_000, 100_000, 5), (3125, 3125));
        assert_eq!(level_size(100_000, 100_000, 6), (1563, 1563));
        assert_eq!(level_size(100_000, 3, 10), (98, 1));
        assert_eq!(level_count(1, 1), 1);
        assert_eq!(level_count(2, 1), 2);
        assert_eq!(level_count(256, 256), 9);
        assert_eq!(level_count(257, 3), 10);
        assert_eq!(level_size(100_000, 100_000, level_count(100_000, 100_000) - 1), (1, 1));
        assert_eq!(level_size(100_000, 100_000, level_count(100_000, 100_000) - 2).0, 2);
    }

    #[test]
    fn wrap_handles_negatives() {
        assert_eq!(wrap(-1, 10), 9);
        assert_eq!(wrap(25, 10), 5);
        assert_eq!(wrap(i64::MIN, 7), i64::MIN.rem_euclid(7) as u64);
    }
}
