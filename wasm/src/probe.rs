//! The probe of one texture that every build must render identically: a fixed list of
//! regions reduced to BLAKE3 hashes. The native parity binary, the WebAssembly module and
//! the conformance suite's pinned hashes (`synth/tests/conformance.rs`) all use this file.

use vtex_synth::texture::{level_count, render_image};
use vtex_synth::{Region, Texture};

/// The regions probed on a texture: level 0 at the origin, far from it in both directions
/// and across the torus wrap; levels 1, 3 and 6; the coarsest level; and a later animation
/// frame (ignored by still textures).
pub fn regions(tex: &dyn Texture) -> Vec<Region> {
    vec![
        Region::new(0, 0, 0, 64, 64),
        Region::new(0, 70_001, 40_993, 48, 40),
        Region::new(0, -(1 << 33) - 5, (1 << 35) + 3, 40, 24),
        Region::new(0, -20, -9, 40, 30),
        Region::new(1, 333, 77, 32, 32),
        Region::new(3, 5, 9, 32, 24),
        Region::new(6, 0, 0, 16, 16),
        Region::new(level_count(tex.width(), tex.height()) - 1, 0, 0, 1, 1),
        Region::new(0, 128, 64, 32, 32).at_frame(37),
    ]
}

/// BLAKE3 hashes (hex) of [`regions`] of `tex`; a region it cannot render (a level it does
/// not have) hashes the error message instead.
pub fn hashes(tex: &dyn Texture) -> Vec<String> {
    regions(tex)
        .iter()
        .map(|region| {
            let bytes = match render_image(tex, region) {
                Ok(img) => img.data,
                Err(e) => e.to_string().into_bytes(),
            };
            blake3::hash(&bytes).to_hex().to_string()
        })
        .collect()
}
