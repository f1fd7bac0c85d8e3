//! Tile and page formats. Every encoder here is deterministic, so a tile's bytes are a pure
//! function of its pixels and format — the property that lets tiles carry strong ETags.

use crate::ktx2::{self, Ktx2};
use image::codecs::{jpeg::JpegEncoder, webp::WebPEncoder};
use image::{ExtendedColorType, ImageEncoder};
use vtex_synth::Rgba8Image;

/// JPEG quality for tiles: visually lossless for textures at a third of PNG's size.
pub const JPEG_QUALITY: u8 = 90;
/// Bytes of compressed data a PNG's IDAT chunks carry each.
const PNG_IDAT_BYTES: usize = 32 * 1024;
/// Bytes of a PNG besides its IDAT data at most: signature, header, chunk framing, zlib's.
const PNG_HEADERS: usize = 4096;

#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Format {
    Png,
    /// Lossless WebP (the only WebP encoder the `image` crate offers).
    Webp,
    /// Baseline JPEG; alpha is dropped.
    Jpg,
    /// Raw row-major RGBA8; width and height travel in `X-Vtex-Width`/`X-Vtex-Height`.
    Rgba,
    /// A GPU-ready KTX2 file of one level ([`crate::ktx2`]); served for pages, not tiles.
    Ktx2(Ktx2),
}

impl Format {
    pub const ALL: [Format; 4] = [Format::Png, Format::Webp, Format::Jpg, Format::Rgba];

    /// The tile format for a file extension or `format=` value.
    pub fn parse(s: &str) -> Option<Format> {
        match s {
            "png" => Some(Format::Png),
            "webp" => Some(Format::Webp),
            "jpg" | "jpeg" => Some(Format::Jpg),
            "rgba" => Some(Format::Rgba),
            _ => None,
        }
    }

    pub fn ext(self) -> &'static str {
        match self {
            Format::Png => "png",
            Format::Webp => "webp",
            Format::Jpg => "jpg",
            Format::Rgba => "rgba",
            Format::Ktx2(_) => "ktx2",
        }
    }

    pub fn content_type(self) -> &'static str {
        match self {
            Format::Png => "image/png",
            Format::Webp => "image/webp",
            Format::Jpg => "image/jpeg",
            Format::Rgba => "application/octet-stream",
            Format::Ktx2(_) => "image/ktx2",
        }
    }

    /// The sentence used in errors that list the accepted formats.
    pub const EXPECTED: &'static str = "expected png, webp, jpg or rgba";
}

/// Headroom over [`peak_bytes`]' multiples of the pixels: an encoder's headers, tables,
/// buffers and compressor state.
const ENCODING_SLACK: u64 = 512 * 1024;

/// Most bytes rendering and encoding a `width` × `height` image holds at once: its pixels, the
/// encoder's copies of them and its output at its largest, for images that do not compress
/// (`tests/encode_peak.rs` measures each format against it).
pub fn peak_bytes(format: Format, width: u32, height: u32) -> u64 {
    let pixels = width as u64 * height as u64 * 4;
    match format {
        Format::Rgba => pixels,
        // The output, made at its bound's capacity (`png_capacity`).
        Format::Png => pixels + png_capacity(pixels as usize) as u64 + ENCODING_SLACK,
        // The RGB copy (3/4) and an output grown once past half the pixels.
        Format::Jpg => pixels * 11 / 4 + ENCODING_SLACK,
        // The lossless encoder's transformed copies and its bit writer, grown by moves.
        Format::Webp => pixels * 6 + ENCODING_SLACK,
        // Its encoder's measured working memory (`ktx2::working_bytes`).
        Format::Ktx2(k) => pixels + ktx2::working_bytes(k, width as u64 * height as u64),
    }
}

/// Capacity of a PNG's output, so that it never grows by reallocation: fast deflate's output
/// before [`write_png`] finds it larger than the pixels stored (up to 1.4× them, on noise).
fn png_capacity(pixels: usize) -> usize {
    pixels * 3 / 2 + PNG_HEADERS
}

/// Encodes an image, taking it so that raw RGBA is the pixels without a copy. Fails only for
/// sizes a format cannot hold (WebP: 16383 px a side), which the API's region bound keeps out
/// of reach.
pub fn encode(img: Rgba8Image, format: Format) -> Result<Vec<u8>, String> {
    let (w, h) = (img.width, img.height);
    let failed = |e: &dyn std::fmt::Display| format!("{} encoding of {w}×{h} failed: {e}", format.ext());
    let mut out = match format {
        Format::Rgba => return Ok(img.data),
        Format::Ktx2(k) => return ktx2::encode(&[img], k),
        Format::Png => write_png(&img).map_err(|e| failed(&e))?,
        Format::Webp => {
            let mut out = Vec::with_capacity(img.data.len() / 2);
            WebPEncoder::new_lossless(&mut out)
                .write_image(&img.data, w, h, ExtendedColorType::Rgba8)
                .map_err(|e| failed(&e))?;
            out
        }
        Format::Jpg => {
            let rgb: Vec<u8> = img.data.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
            let mut out = Vec::with_capacity(img.data.len() / 2);
            JpegEncoder::new_with_quality(&mut out, JPEG_QUALITY)
                .write_image(&rgb, w, h, ExtendedColorType::Rgb8)
                .map_err(|e| failed(&e))?;
            out
        }
    };
    // The cache charges a tile by its length; make that the memory it really holds.
    out.shrink_to_fit();
    Ok(out)
}

/// PNG with fast deflate and adaptive filters (a cold 256² tile within a few milliseconds,
/// still lossless), compressed as it is written so that the whole compressed image is never
/// held beside `out`; stored uncompressed instead when fast deflate would make it larger (noise).
fn write_png(img: &Rgba8Image) -> Result<Vec<u8>, png::EncodingError> {
    let mut out = Vec::with_capacity(png_capacity(img.data.len()));
    write_png_with(img, &mut out, png::Compression::Fast)?;
    if out.len() > img.data.len() + img.height as usize + PNG_HEADERS {
        out.clear();
        write_png_with(img, &mut out, png::Compression::NoCompression)?;
    }
    Ok(out)
}

fn write_png_with(
    img: &Rgba8Image,
    out: &mut Vec<u8>,
    compression: png::Compression,
) -> Result<(), png::EncodingError> {
    let mut encoder = png::Encoder::new(out, img.width, img.height);
    encoder.set_color(png::ColorType::Rgba);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.set_compression(compression);
    encoder.set_filter(png::Filter::Adaptive);
    let mut writer = encoder.write_header()?;
    let mut stream = writer.stream_writer_with_size(PNG_IDAT_BYTES)?;
    std::io::Write::write_all(&mut stream, &img.data)?;
    stream.finish()
}

#[cfg(test)]
mod tests {
    use super::*;

    fn gradient(w: u32, h: u32) -> Rgba8Image {
        let mut img = Rgba8Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                img.set_pixel(x, y, [(x * 7) as u8, (y * 5) as u8, (x ^ y) as u8, 255]);
            }
        }
        img
    }

    #[test]
    fn lossless_formats_round_trip_and_are_deterministic() {
        let img = gradient(37, 21);
        for f in Format::ALL {
            let a = encode(img.clone(), f).unwrap();
            assert_eq!(a, encode(img.clone(), f).unwrap(), "{f:?} is deterministic");
            assert!(a.len() as u64 <= peak_bytes(f, 37, 21), "{f:?}");
            if f == Format::Jpg {
                let back = image::load_from_memory(&a).unwrap();
                assert_eq!((back.width(), back.height()), (37, 21));
                continue;
            }
            let back = if f == Format::Rgba {
                img.data.clone()
            } else {
                image::load_from_memory(&a).unwrap().into_rgba8().into_raw()
            };
            assert_eq!(back, img.data, "{f:?} is lossless");
        }
    }

    #[test]
    fn parse_and_names_agree() {
        for f in Format::ALL {
            assert_eq!(Format::parse(f.ext()), Some(f));
        }
        assert_eq!(Format::parse("gif"), None);
        assert_eq!(Format::parse("PNG"), None);
    }
}
