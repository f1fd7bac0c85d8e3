//! RGBA8 pixel buffers, and PNG decoding that refuses hostile input before allocating.

use crate::{Error, Result};

/// Largest side of a decoded sample or map image. Samples are small by design.
pub const MAX_IMAGE_SIDE: u32 = 4096;
/// Largest decoder allocation for one image: a 4096² RGBA8 image plus headroom.
pub const MAX_IMAGE_ALLOC: u64 = 96 << 20;

/// A row-major RGBA8 image: 4 bytes a pixel, no padding.
#[derive(Clone, PartialEq, Eq)]
pub struct Rgba8Image {
    pub width: u32,
    pub height: u32,
    pub data: Vec<u8>,
}

impl std::fmt::Debug for Rgba8Image {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "Rgba8Image({}×{})", self.width, self.height)
    }
}

impl Rgba8Image {
    /// A transparent black image.
    pub fn new(width: u32, height: u32) -> Self {
        Self { width, height, data: vec![0; width as usize * height as usize * 4] }
    }

    /// Wraps raw RGBA8 bytes; `data` must hold exactly `width × height × 4` bytes.
    pub fn from_raw(width: u32, height: u32, data: Vec<u8>) -> Result<Self> {
        if data.len() != width as usize * height as usize * 4 {
            return Err(Error::image("raw", format!("{} bytes for {width}×{height} RGBA8", data.len())));
        }
        Ok(Self { width, height, data })
    }

    #[inline]
    pub fn pixel(&self, x: u32, y: u32) -> [u8; 4] {
        let i = (y as usize * self.width as usize + x as usize) * 4;
        [self.data[i], self.data[i + 1], self.data[i + 2], self.data[i + 3]]
    }

    #[inline]
    pub fn set_pixel(&mut self, x: u32, y: u32, p: [u8; 4]) {
        let i = (y as usize * self.width as usize + x as usize) * 4;
        self.data[i..i + 4].copy_from_slice(&p);
    }

    /// The `w × h` rectangle at (x, y), which must lie inside the image.
    pub fn crop(&self, x: u32, y: u32, w: u32, h: u32) -> Rgba8Image {
        assert!(x + w <= self.width && y + h <= self.height, "crop outside the image");
        let mut out = Rgba8Image::new(w, h);
        let row = w as usize * 4;
        for r in 0..h as usize {
            let src = ((y as usize + r) * self.width as usize + x as usize) * 4;
            out.data[r * row..(r + 1) * row].copy_from_slice(&self.data[src..src + row]);
        }
        out
    }

    /// Copies `src` into this image with its top-left corner at (x, y); it must fit.
    pub fn blit(&mut self, src: &Rgba8Image, x: u32, y: u32) {
        assert!(x + src.width <= self.width && y + src.height <= self.height, "blit outside the image");
        let row = src.width as usize * 4;
        for r in 0..src.height as usize {
            let dst = ((y as usize + r) * self.width as usize + x as usize) * 4;
            self.data[dst..dst + row].copy_from_slice(&src.data[r * row..(r + 1) * row]);
        }
    }

    /// True when every pixel is fully opaque.
    pub fn is_opaque(&self) -> bool {
        self.data.chunks_exact(4).all(|p| p[3] == 255)
    }

    /// The PNG encoding of this image (lossless; used for samples inside bundles).
    #[cfg(feature = "create")]
    pub fn to_png(&self) -> Vec<u8> {
        let mut out = Vec::new();
        let encoder = image::codecs::png::PngEncoder::new(&mut out);
        image::ImageEncoder::write_image(encoder, &self.data, self.width, self.height, image::ExtendedColorType::Rgba8)
            .expect("encoding a well-formed RGBA8 buffer to memory cannot fail");
        out
    }
}

/// Decodes an untrusted PNG into RGBA8. The declared size is checked against
/// [`MAX_IMAGE_SIDE`] and what it decodes to against [`MAX_IMAGE_ALLOC`] before any pixel
/// memory is allocated, so a decompression bomb or a header that lies about its size is
/// refused, not obeyed. Every chunk's CRC and the image data's Adler-32 are checked. Every
/// colour type and bit depth gives RGBA8: grey is replicated, a palette and `tRNS` are
/// expanded, missing alpha is opaque, 16-bit samples are rounded to 8 bits. `name` is used in
/// errors.
pub fn decode_png(name: &str, bytes: &[u8]) -> Result<Rgba8Image> {
    use zune_core::{bit_depth::BitDepth, bytestream::ZCursor, options::DecoderOptions};
    let fail = |reason: String| Error::image(name, reason);
    let (w, h) = png_dimensions(name, bytes)?;
    let bytes = check_chunks(bytes).map_err(|reason| fail(reason.into()))?;
    let options = DecoderOptions::default()
        .set_max_width(MAX_IMAGE_SIDE as usize)
        .set_max_height(MAX_IMAGE_SIDE as usize)
        .set_strict_mode(true)
        .png_set_confirm_crc(true)
        .inflate_set_confirm_adler(true)
        .png_set_add_alpha_channel(false)
        .png_set_strip_to_8bit(false)
        .png_set_decode_animated(false)
        .set_byte_endian(zune_core::bit_depth::ByteEndian::BE);
    let mut decoder = zune_png::PngDecoder::new_with_options(ZCursor::new(&bytes[..]), options);
    // zune-png's messages are written as Debug (quoted, with a newline).
    let zune = |e: zune_png::error::PngDecodeErrors| fail(e.to_string().trim().trim_matches('"').to_string());
    decoder.decode_headers().map_err(zune)?;
    // 16-bit samples decode to twice the bytes of RGBA8: bound what the decoder allocates.
    let decoded = decoder.output_buffer_size().map_or(u64::MAX, |n| n as u64);
    if decoded > MAX_IMAGE_ALLOC {
        return Err(fail(format!("{w}×{h} pixels decode to {decoded} bytes; at most {MAX_IMAGE_ALLOC} allowed")));
    }
    let buf = decoder.decode_raw().map_err(zune)?;
    let channels = decoder.colorspace().map_or(0, |c| c.num_components());
    if !(1..=4).contains(&channels) || buf.len() as u64 != decoded {
        return Err(fail(format!("decoded to {} bytes of {channels} channels, not {decoded}", buf.len())));
    }
    let data = match decoder.depth() {
        Some(BitDepth::Eight) if channels == 4 => buf,
        Some(BitDepth::Eight) => to_rgba(&buf, channels, 1),
        _ => to_rgba(&buf, channels, 2),
    };
    Ok(Rgba8Image { width: w, height: h, data })
}

/// The chunks the decoder reads ([`decode_png`]): the header, palette, transparency, image data
/// and end. Nothing else affects the samples; every other chunk is left out unread, so the
/// decoder never parses (or inflates, or keeps a copy of) a colour profile, text, animation
/// control or anything it might read at another length than the file declares.
const DECODED_CHUNKS: [&[u8; 4]; 5] = [b"IHDR", b"PLTE", b"tRNS", b"IDAT", b"IEND"];

/// The PNG the decoder is given: the signature and the [`DECODED_CHUNKS`] of `bytes`, walked by
/// their declared lengths up to `IEND`, after checking what the decoder takes on trust: a
/// palette of whole RGB entries, at most 256, and a `tRNS` chunk of the length its colour type
/// has (2 bytes for grey, 6 for RGB, at most one a palette entry, none for colour types with
/// alpha). A chunk cut short by the end of the file, a file without `IEND` and an unknown
/// critical chunk (an upper-case first letter: one a decoder must understand) are refused.
fn check_chunks(bytes: &[u8]) -> std::result::Result<Vec<u8>, &'static str> {
    let colour = bytes.get(25).copied().unwrap_or(0);
    let mut palette = 0;
    let mut kept = bytes.get(..8).ok_or("the file ends inside its signature")?.to_vec();
    let mut at = 8;
    loop {
        let head = bytes.get(at..at + 8).ok_or("the file ends before its IEND chunk")?;
        let len = u32::from_be_bytes(head[..4].try_into().expect("4 bytes")) as usize;
        let end = at.saturating_add(len).saturating_add(12);
        if end > bytes.len() {
            return Err("a chunk runs past the end of the file");
        }
        let kind: &[u8; 4] = head[4..].try_into().expect("4 bytes");
        match kind {
            b"PLTE" if len % 3 != 0 || len > 256 * 3 => return Err("a palette must be 1 to 256 RGB entries"),
            b"PLTE" => palette = len / 3,
            b"tRNS" => {
                let fits = match colour {
                    0 => len == 2,
                    2 => len == 6,
                    3 => len <= palette,
                    _ => false,
                };
                if !fits {
                    return Err("a tRNS chunk of the wrong length for its colour type");
                }
            }
            _ => {}
        }
        if DECODED_CHUNKS.contains(&kind) {
            kept.extend_from_slice(&bytes[at..end]);
        } else if kind[0].is_ascii_uppercase() {
            return Err("a critical chunk this decoder does not know");
        }
        if kind == b"IEND" {
            return Ok(kept);
        }
        at = end;
    }
}

/// RGBA8 from expanded samples of `size` bytes (1, or 2 big-endian, rounded as
/// `round(v · 255 / 65535)`), `channels` a pixel (grey, grey and alpha, RGB or RGBA).
fn to_rgba(buf: &[u8], channels: usize, size: usize) -> Vec<u8> {
    let mut out = Vec::with_capacity(buf.len() / (channels * size) * 4);
    for px in buf.chunks_exact(channels * size) {
        let v = |c: usize| match size {
            1 => px[c],
            _ => ((u16::from_be_bytes([px[2 * c], px[2 * c + 1]]) as u32 + 128) / 257) as u8,
        };
        out.extend_from_slice(&match channels {
            1 => [v(0), v(0), v(0), 255],
            2 => [v(0), v(0), v(0), v(1)],
            3 => [v(0), v(1), v(2), 255],
            _ => [v(0), v(1), v(2), v(3)],
        });
    }
    out
}

/// The width and height a PNG declares in its header (IHDR, which the format puts first), read
/// without inflating anything: what a cost plan may know of an image before deciding to
/// decode it. Sides are checked against [`MAX_IMAGE_SIDE`] as [`decode_png`] checks them.
pub fn png_dimensions(name: &str, bytes: &[u8]) -> Result<(u32, u32)> {
    let fail = |reason: &str| Error::image(name, reason.to_string());
    if !bytes.starts_with(b"\x89PNG\r\n\x1a\n") {
        return Err(fail("not a PNG file (bad signature)"));
    }
    let ihdr = bytes.get(8..24).ok_or_else(|| fail("truncated before the end of its header"))?;
    if ihdr[..8] != [0, 0, 0, 13, b'I', b'H', b'D', b'R'] {
        return Err(fail("the first chunk is not a 13-byte IHDR"));
    }
    let side = |at: usize| u32::from_be_bytes(ihdr[at..at + 4].try_into().expect("4 bytes"));
    let (w, h) = (side(8), side(12));
    if w == 0 || h == 0 || w > MAX_IMAGE_SIDE || h > MAX_IMAGE_SIDE {
        return Err(Error::image(name, format!("{w}×{h} pixels; each side must be 1..={MAX_IMAGE_SIDE}")));
    }
    Ok((w, h))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn checker(w: u32, h: u32) -> Rgba8Image {
        let mut img = Rgba8Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let v = if (x + y) % 2 == 0 { 255 } else { 0 };
                img.set_pixel(x, y, [v, x as u8, y as u8, 255]);
            }
        }
        img
    }

    /// A PLTE chunk of `n` bytes in an otherwise valid 1 × 1 indexed PNG.
    fn indexed_with_palette_bytes(n: usize) -> Vec<u8> {
        let chunk = |png: &mut Vec<u8>, kind: &[u8], data: &[u8]| {
            png.extend((data.len() as u32).to_be_bytes());
            let mut body = kind.to_vec();
            body.extend(data);
            png.extend(&body);
            png.extend(crc32fast::hash(&body).to_be_bytes());
        };
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        chunk(&mut png, b"IHDR", &[0, 0, 0, 1, 0, 0, 0, 1, 8, 3, 0, 0, 0]);
        chunk(&mut png, b"PLTE", &vec![7; n]);
        let idat = {
            use std::io::Write;
            let mut z = flate2::write::ZlibEncoder::new(Vec::new(), flate2::Compression::default());
            z.write_all(&[0, 0]).unwrap();
            z.finish().unwrap()
        };
        chunk(&mut png, b"IDAT", &idat);
        chunk(&mut png, b"IEND", &[]);
        png
    }

    /// A palette of partial entries or of more than 256 is refused before the decoder reads it.
    #[test]
    fn refuses_palettes_of_partial_entries() {
        assert_eq!(decode_png("s", &indexed_with_palette_bytes(3)).unwrap().pixel(0, 0), [7, 7, 7, 255]);
        for n in [1, 2, 4, 5, 770] {
            assert!(decode_png("s", &indexed_with_palette_bytes(n)).is_err(), "a palette of {n} bytes was accepted");
        }
    }

    /// `checker`'s PNG with `extra` (type, data) chunks before its IDAT, each CRC right
    /// unless `bad_crc`.
    fn with_chunk_before_idat(kind: &[u8; 4], data: &[u8], bad_crc: bool) -> Vec<u8> {
        let png = checker(4, 4).to_png();
        let idat = png.windows(4).position(|w| w == b"IDAT").expect("an IDAT") - 4;
        let mut body = kind.to_vec();
        body.extend(data);
        let crc = crc32fast::hash(&body) ^ bad_crc as u32;
        let mut out = png[..idat].to_vec();
        out.extend((data.len() as u32).to_be_bytes());
        out.extend(&body);
        out.extend(crc.to_be_bytes());
        out.extend(&png[idat..]);
        out
    }

    /// The CRC of every chunk the decoder reads is checked, the image data's included; an
    /// ancillary chunk is left out unread, whatever its CRC, and an unknown critical one refused.
    #[test]
    fn refuses_a_bad_crc_in_what_is_decoded_and_unknown_critical_chunks() {
        assert!(decode_png("s", &with_chunk_before_idat(b"vtEx", b"data", false)).is_ok());
        assert!(decode_png("s", &with_chunk_before_idat(b"vtEx", b"data", true)).is_ok());
        let err = decode_png("s", &with_chunk_before_idat(b"VTEX", b"data", false)).unwrap_err().to_string();
        assert!(err.contains("critical chunk"), "{err}");
        let mut png = checker(4, 4).to_png();
        let idat = png.windows(4).position(|w| w == b"IDAT").expect("an IDAT");
        let len = u32::from_be_bytes(png[idat - 4..idat].try_into().unwrap()) as usize;
        png[idat + 4 + len] ^= 1;
        assert!(decode_png("s", &png).is_err());
    }

    /// A `tRNS` chunk must have its colour type's length (2 bytes for grey, 6 for RGB, none
    /// with alpha).
    #[test]
    fn refuses_trns_of_the_wrong_length() {
        let err = decode_png("s", &with_chunk_before_idat(b"tRNS", &[0, 1], false)).unwrap_err().to_string();
        assert!(err.contains("tRNS"), "{err}");
    }

    #[test]
    fn png_round_trip() {
        let img = checker(17, 9);
        assert_eq!(decode_png("s", &img.to_png()).unwrap(), img);
    }

    #[test]
    fn refuses_non_png_and_truncated() {
        assert!(matches!(decode_png("s", b"GIF89a"), Err(Error::Image { .. })));
        let png = checker(32, 32).to_png();
        for cut in [8, 20, 40, png.len() - 5] {
            assert!(decode_png("s", &png[..cut]).is_err(), "cut at {cut}");
        }
    }

    #[test]
    fn refuses_lying_dimensions_before_allocating() {
        // Rewrite the IHDR width to 100000: the decoder must refuse from the header alone.
        let mut png = checker(8, 8).to_png();
        png[16..20].copy_from_slice(&100_000u32.to_be_bytes());
        let err = decode_png("sample", &png).unwrap_err().to_string();
        assert!(err.contains("sample"), "{err}");
    }

    /// A PNG whose header declares `w × h` RGBA pixels of `bits` bits (valid CRCs), no pixel data.
    fn header_only(w: u32, h: u32, bits: u8) -> Vec<u8> {
        let mut ihdr = b"IHDR".to_vec();
        ihdr.extend(w.to_be_bytes());
        ihdr.extend(h.to_be_bytes());
        ihdr.extend([bits, 6, 0, 0, 0]);
        let mut png = b"\x89PNG\r\n\x1a\n".to_vec();
        png.extend(13u32.to_be_bytes());
        png.extend(&ihdr);
        png.extend(crc32fast::hash(&ihdr).to_be_bytes());
        for empty in [b"IDAT", b"IEND"] {
            png.extend(0u32.to_be_bytes());
            png.extend(empty);
            png.extend(crc32fast::hash(empty).to_be_bytes());
        }
        png
    }

    #[test]
    fn refuses_sixteen_bit_images_that_decode_past_the_allocation_bound() {
        // 4096² RGBA16 is within the side bound but decodes to 128 MiB.
        let err = decode_png("sample", &header_only(4096, 4096, 16)).unwrap_err().to_string();
        assert!(err.contains("134217728 bytes"), "{err}");
        // The same size in 8 bits passes the bound (and then fails for its missing data).
        let err = decode_png("sample", &header_only(4096, 4096, 8)).unwrap_err().to_string();
        assert!(!err.contains("bytes; at most"), "{err}");
    }

    /// A `w × h` PNG of `colour` at `depth` bits with pseudo-random samples (a full palette
    /// with a partial `tRNS` for indexed images).
    fn encoded(colour: png::ColorType, depth: png::BitDepth, w: u32, h: u32) -> Vec<u8> {
        let bits = depth as usize;
        let row = (w as usize * colour.samples() * bits).div_ceil(8);
        let mut state = 0x9e37_79b9_u32.wrapping_mul(bits as u32 + 7 * colour as u32 + 1);
        let mut next = || {
            state ^= state << 13;
            state ^= state >> 17;
            state ^= state << 5;
            state as u8
        };
        let data: Vec<u8> = (0..row * h as usize).map(|_| next()).collect();
        let mut out = Vec::new();
        let mut enc = png::Encoder::new(&mut out, w, h);
        enc.set_color(colour);
        enc.set_depth(depth);
        if colour == png::ColorType::Indexed {
            enc.set_palette((0..3 << bits).map(|_| next()).collect::<Vec<u8>>());
            enc.set_trns((0..1 << (bits - 1)).map(|_| next()).collect::<Vec<u8>>());
        }
        let mut writer = enc.write_header().unwrap();
        writer.write_image_data(&data).unwrap();
        writer.finish().unwrap();
        out
    }

    /// Every colour type and bit depth decodes to the RGBA8 the `image` crate makes of it.
    #[test]
    fn every_colour_type_and_depth_decodes_as_image_does() {
        use png::{BitDepth::*, ColorType::*};
        let cases = [
            (Grayscale, vec![One, Two, Four, Eight, Sixteen]),
            (GrayscaleAlpha, vec![Eight, Sixteen]),
            (Indexed, vec![One, Two, Four, Eight]),
            (Rgb, vec![Eight, Sixteen]),
            (Rgba, vec![Eight, Sixteen]),
        ];
        for (colour, depths) in cases {
            for depth in depths {
                let png = encoded(colour, depth, 13, 7);
                let want = image::load_from_memory(&png).unwrap().into_rgba8();
                let got = decode_png("s", &png).unwrap();
                assert_eq!((got.width, got.height), (13, 7));
                assert_eq!(got.data, want.into_raw(), "{colour:?} {depth:?}");
            }
        }
        // The conversions themselves: 1-bit white is 255, 16-bit samples round.
        let grey = decode_png("s", &encoded(Grayscale, One, 8, 1)).unwrap();
        assert!(grey
            .data
            .chunks_exact(4)
            .all(|p| p[0] == p[1] && p[1] == p[2] && [0, 255].contains(&p[0]) && p[3] == 255));
    }

    #[test]
    fn crop_and_blit_are_inverse() {
        let img = checker(10, 8);
        let part = img.crop(3, 2, 4, 5);
        let mut back = Rgba8Image::new(10, 8);
        back.blit(&part, 3, 2);
        assert_eq!(back.crop(3, 2, 4, 5), part);
        assert_eq!(part.pixel(0, 0), img.pixel(3, 2));
    }
}
