//! Material layers: what a renderer samples beside a texture's colour, derived from the colour
//! of the same level so that every model has them and the server needs no model's help.
//!
//! The normal layer is the tangent-space normal of a height field: the colour's luminance
//! (BT.709 weights), the whole luminance range spanning [`RELIEF`] level-0 pixels of height.
//! Level L's normal is the normal of level L's height — central differences over level L's
//! pixels, which are 2^L level-0 pixels apart — not a downsampled normal map, so coarse levels
//! are as flat as the averaged surface is. Each normal reads its four neighbours, so a layer
//! region is derived from the colour of the region grown by [`Layer::margin`] on every side:
//! the texture's own pixels there, wrapped on a torus. A page's border therefore equals its
//! neighbour's pixels and the torus wraps without a seam, as for colour.
//!
//! Normals follow glTF's convention (+X right, +Y up — towards the image's first row — and +Z
//! out of the surface), stored as `round((n + 1) · 127.5)` in R, G and B with A = 255: linear
//! data, not sRGB colour. A renderer wanting more relief scales X and Y before normalising,
//! which is exactly the normal of a height scaled the same.

use crate::{Region, Rgba8Image};

/// Height of the full luminance range, in level-0 pixels.
pub const RELIEF: f32 = 8.0;

/// A layer of a texture.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, Hash)]
pub enum Layer {
    /// The colour the model renders.
    #[default]
    Color,
    /// Tangent-space normals of the colour's luminance height.
    Normal,
}

impl Layer {
    pub const EXPECTED: &'static str = "expected color or normal";

    pub fn parse(s: &str) -> Option<Layer> {
        match s {
            "color" => Some(Layer::Color),
            "normal" => Some(Layer::Normal),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Layer::Color => "color",
            Layer::Normal => "normal",
        }
    }

    /// Whether the layer's pixels are linear data rather than sRGB-encoded colour (a GPU must
    /// not decode them from sRGB).
    pub fn is_linear(self) -> bool {
        self == Layer::Normal
    }

    /// Pixels of colour around a pixel that its value reads, on each side.
    pub fn margin(self) -> u32 {
        match self {
            Layer::Color => 0,
            Layer::Normal => 1,
        }
    }

    /// The colour region whose pixels make `region` of this layer: `region` grown by the
    /// margin on every side.
    pub fn source(self, region: &Region) -> Region {
        let m = self.margin();
        Region {
            x: region.x - m as i64,
            y: region.y - m as i64,
            width: region.width + 2 * m,
            height: region.height + 2 * m,
            ..*region
        }
    }

    /// This layer at level `level` from `colour`, the colour of [`Layer::source`] of the
    /// region wanted: an image the margin smaller on every side.
    pub fn derive(self, colour: Rgba8Image, level: u32) -> Rgba8Image {
        match self {
            Layer::Color => colour,
            Layer::Normal => normals(&colour, level),
        }
    }
}

/// BT.709 luminance of an sRGB-encoded pixel in 1/256ths of a code value (weights summing to 256).
fn luminance(p: &[u8]) -> i32 {
    54 * p[0] as i32 + 183 * p[1] as i32 + 19 * p[2] as i32
}

/// The normals of `colour`'s inner pixels (all but a one-pixel frame) at level `level`.
fn normals(colour: &Rgba8Image, level: u32) -> Rgba8Image {
    let (w, h) = (colour.width as usize, colour.height as usize);
    assert!(w >= 3 && h >= 3, "a normal needs its four neighbours");
    let height: Vec<i32> = colour.data.chunks_exact(4).map(luminance).collect();
    // Slope per unit of luminance difference: RELIEF level-0 pixels over the whole range,
    // central differences spanning two level-L pixels of 2^L level-0 pixels each.
    let spacing = (1u64 << level.min(63)) as f32;
    let scale = RELIEF / (255.0 * 256.0 * 2.0 * spacing);
    let mut out = Rgba8Image::new(w as u32 - 2, h as u32 - 2);
    for (y, row) in out.data.chunks_exact_mut((w - 2) * 4).enumerate() {
        let at = |dx: usize, dy: usize| height[(y + dy) * w + dx];
        for (x, px) in row.chunks_exact_mut(4).enumerate() {
            let dx = (at(x + 2, 1) - at(x, 1)) as f32 * scale;
            let d_row = (at(x + 1, 2) - at(x + 1, 0)) as f32 * scale;
            // The surface (x, v, height) with v = −row: its normal is (−∂h/∂x, −∂h/∂v, 1).
            let inv = 1.0 / (dx * dx + d_row * d_row + 1.0).sqrt();
            px.copy_from_slice(&[unit_byte(-dx * inv), unit_byte(d_row * inv), unit_byte(inv), 255]);
        }
    }
    out
}

/// A component in [−1, 1] as a byte.
fn unit_byte(c: f32) -> u8 {
    ((c + 1.0) * 127.5).round() as u8
}

#[cfg(test)]
mod tests {
    use super::*;

    fn image(w: u32, h: u32, f: impl Fn(u32, u32) -> u8) -> Rgba8Image {
        let mut img = Rgba8Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let v = f(x, y);
                img.set_pixel(x, y, [v, v, v, 255]);
            }
        }
        img
    }

    #[test]
    fn a_flat_colour_faces_straight_out() {
        let n = Layer::Normal.derive(image(6, 5, |_, _| 90), 0);
        assert_eq!((n.width, n.height), (4, 3));
        assert!(n.data.chunks_exact(4).all(|p| p == [128, 128, 255, 255]), "{:?}", &n.data[..8]);
    }

    #[test]
    fn a_slope_tilts_the_normal_away_from_the_rise() {
        // Luminance rising to the right (+X) and towards the bottom row (−Y): the normal leans
        // left (R < 128) and up (G > 128).
        let right = Layer::Normal.derive(image(5, 5, |x, _| 40 * x as u8), 0);
        let down = Layer::Normal.derive(image(5, 5, |_, y| 40 * y as u8), 0);
        let (r, d) = (right.pixel(1, 1), down.pixel(1, 1));
        assert!(r[0] < 128 && r[1] == 128, "{r:?}");
        assert!(d[1] > 128 && d[0] == 128, "{d:?}");
        // The slope: 80 code values over two pixels, RELIEF pixels for 255 of them.
        let slope = 80.0 / 255.0 * RELIEF / 2.0;
        let expected = unit_byte(-slope / (slope * slope + 1.0f32).sqrt());
        assert_eq!(r[0], expected);
    }

    #[test]
    fn coarser_levels_are_flatter_by_their_spacing() {
        let ramp = image(5, 5, |x, _| 40 * x as u8);
        let fine = Layer::Normal.derive(ramp.clone(), 0).pixel(2, 2)[0];
        let coarse = Layer::Normal.derive(ramp, 3).pixel(2, 2)[0];
        assert!(fine < coarse && coarse < 128, "level 0 {fine}, level 3 {coarse}");
    }

    #[test]
    fn the_source_is_the_region_grown_by_the_margin() {
        let r = Region::new(3, 10, -4, 8, 6).at_frame(2);
        assert_eq!(Layer::Normal.source(&r), Region::new(3, 9, -5, 10, 8).at_frame(2));
        assert_eq!(Layer::Color.source(&r), r);
    }
}
