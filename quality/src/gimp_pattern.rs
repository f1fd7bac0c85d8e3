//! Reader for GIMP's pattern format (`.pat`), the format of the Debian `gimp-data` patterns
//! the quality report is run on.
//!
//! Layout (GIMP's `devel-docs/pat.txt`), all integers 32-bit big-endian:
//! header size (24 + name bytes), version (1), width, height, bytes per pixel (1 grey,
//! 2 grey + alpha, 3 RGB, 4 RGBA), magic `GPAT`, the UTF-8 name (NUL-terminated, filling the
//! header), then width × height pixels, row-major, 8 bits a channel.

use vtex_synth::{pixels::MAX_IMAGE_SIDE, Error, Result, Rgba8Image};

/// A decoded pattern: its display name and its pixels as RGBA8.
#[derive(Clone, Debug, PartialEq, Eq)]
pub struct GimpPattern {
    pub name: String,
    pub image: Rgba8Image,
}

/// Parses a `.pat` file. `file` names it in errors. Every field is checked against the file's
/// length before pixel memory is allocated; trailing bytes are refused (a `.pat` holds one
/// pattern).
pub fn parse(file: &str, bytes: &[u8]) -> Result<GimpPattern> {
    let fail = |reason: String| Error::image(file, format!("GIMP pattern: {reason}"));
    if bytes.len() < 24 {
        return Err(fail(format!("{} bytes, shorter than the 24-byte header", bytes.len())));
    }
    let word = |i: usize| u32::from_be_bytes([bytes[4 * i], bytes[4 * i + 1], bytes[4 * i + 2], bytes[4 * i + 3]]);
    let (header, version, width, height, depth) = (word(0), word(1), word(2), word(3), word(4));
    if &bytes[20..24] != b"GPAT" {
        return Err(fail("bad magic (expected `GPAT` at byte 20)".into()));
    }
    if version != 1 {
        return Err(fail(format!("version {version}; only version 1 exists")));
    }
    if header < 24 || header as usize > bytes.len() {
        return Err(fail(format!("header size {header} outside 24..={}", bytes.len())));
    }
    if width == 0 || height == 0 || width > MAX_IMAGE_SIDE || height > MAX_IMAGE_SIDE {
        return Err(fail(format!("{width}×{height} pixels; each side must be 1..={MAX_IMAGE_SIDE}")));
    }
    if !(1..=4).contains(&depth) {
        return Err(fail(format!("{depth} bytes per pixel; must be 1 to 4")));
    }
    let pixels = &bytes[header as usize..];
    let need = width as usize * height as usize * depth as usize;
    if pixels.len() != need {
        return Err(fail(format!(
            "{} bytes of pixels for {width}×{height} at {depth} bytes per pixel, which needs {need}",
            pixels.len()
        )));
    }
    let name_bytes = &bytes[24..header as usize];
    let name_bytes = &name_bytes[..name_bytes.iter().position(|&b| b == 0).unwrap_or(name_bytes.len())];
    let name = String::from_utf8_lossy(name_bytes).into_owned();
    let mut data = Vec::with_capacity(width as usize * height as usize * 4);
    for p in pixels.chunks_exact(depth as usize) {
        data.extend(match *p {
            [v] => [v, v, v, 255],
            [v, a] => [v, v, v, a],
            [r, g, b] => [r, g, b, 255],
            [r, g, b, a] => [r, g, b, a],
            _ => unreachable!("depth checked to be 1..=4"),
        });
    }
    Ok(GimpPattern { name, image: Rgba8Image::from_raw(width, height, data)? })
}

#[cfg(test)]
mod tests {
    use super::*;

    /// A `.pat` file as GIMP writes it.
    fn encode(name: &str, w: u32, h: u32, depth: u32, pixels: &[u8]) -> Vec<u8> {
        let header = 24 + name.len() as u32 + 1;
        let mut out = Vec::new();
        for v in [header, 1, w, h, depth] {
            out.extend(v.to_be_bytes());
        }
        out.extend(b"GPAT");
        out.extend(name.as_bytes());
        out.push(0);
        out.extend(pixels);
        out
    }

    #[test]
    fn reads_every_depth() {
        let grey = parse("g.pat", &encode("Grey", 2, 1, 1, &[10, 200])).unwrap();
        assert_eq!(grey.name, "Grey");
        assert_eq!(grey.image.data, vec![10, 10, 10, 255, 200, 200, 200, 255]);
        let ga = parse("ga.pat", &encode("", 1, 1, 2, &[7, 9])).unwrap();
        assert_eq!((ga.name.as_str(), ga.image.pixel(0, 0)), ("", [7, 7, 7, 9]));
        let rgb = parse("rgb.pat", &encode("Bricks", 1, 2, 3, &[1, 2, 3, 4, 5, 6])).unwrap();
        assert_eq!((rgb.image.width, rgb.image.height), (1, 2));
        assert_eq!(rgb.image.pixel(0, 1), [4, 5, 6, 255]);
        let rgba = parse("rgba.pat", &encode("Stripes Fine", 1, 1, 4, &[1, 2, 3, 4])).unwrap();
        assert_eq!((rgba.name.as_str(), rgba.image.pixel(0, 0)), ("Stripes Fine", [1, 2, 3, 4]));
    }

    #[test]
    fn refuses_malformed_files_naming_the_problem() {
        let good = encode("P", 2, 2, 3, &[0; 12]);
        let cases: Vec<(Vec<u8>, &str)> = vec![
            (good[..10].to_vec(), "header"),
            (good[..good.len() - 1].to_vec(), "needs 12"),
            ([good.clone(), vec![0]].concat(), "needs 12"),
            (
                {
                    let mut b = good.clone();
                    b[20] = b'X';
                    b
                },
                "magic",
            ),
            (
                {
                    let mut b = good.clone();
                    b[7] = 2;
                    b
                },
                "version 2",
            ),
            (
                {
                    let mut b = good.clone();
                    b[19] = 5;
                    b
                },
                "5 bytes per pixel",
            ),
            (
                {
                    let mut b = good.clone();
                    b[11] = 0;
                    b
                },
                "0×2",
            ),
            (
                {
                    let mut b = good.clone();
                    b[8..12].copy_from_slice(&100_000u32.to_be_bytes());
                    b
                },
                "100000×2",
            ),
            (
                {
                    let mut b = good.clone();
                    b[0..4].copy_from_slice(&9999u32.to_be_bytes());
                    b
                },
                "header size 9999",
            ),
            (
                {
                    let mut b = good.clone();
                    b[0..4].copy_from_slice(&3u32.to_be_bytes());
                    b
                },
                "header size 3",
            ),
        ];
        for (bytes, expect) in cases {
            let err = parse("bad.pat", &bytes).unwrap_err().to_string();
            assert!(err.contains("bad.pat") && err.contains(expect), "{err} (expected {expect})");
        }
        assert!(parse("good.pat", &good).is_ok());
    }

    #[test]
    fn survives_every_truncation() {
        let good = encode("Name", 3, 2, 4, &[9; 24]);
        for cut in 0..good.len() {
            assert!(parse("t.pat", &good[..cut]).is_err(), "cut at {cut}");
        }
    }
}
