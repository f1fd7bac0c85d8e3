//! An opaque sample as an 8-bit RGB PNG: the pixels `Rgba8Image::to_png` stores, in the bytes
//! another tool writes. Shared by the synth and server tests through `#[path]`.

use vtex_synth::Rgba8Image;

pub fn rgb_png(img: &Rgba8Image) -> Vec<u8> {
    assert!(img.data.chunks_exact(4).all(|p| p[3] == 255), "an RGB PNG holds opaque pixels only");
    let mut out = Vec::new();
    let mut encoder = png::Encoder::new(&mut out, img.width, img.height);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    let mut writer = encoder.write_header().unwrap();
    let rgb: Vec<u8> = img.data.chunks_exact(4).flat_map(|p| [p[0], p[1], p[2]]).collect();
    writer.write_image_data(&rgb).unwrap();
    writer.finish().unwrap();
    out
}
