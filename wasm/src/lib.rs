//! vtex-synth compiled to WebAssembly with a minimal raw ABI (no bindings generator), so a
//! browser or Node can synthesize tiles from an encoding, and so tests can prove that the
//! WebAssembly build renders exactly the bytes of the native one (DESIGN §3.1).
//!
//! The same probe — a fixed list of regions of every demo texture, each reduced to a BLAKE3
//! hash — runs natively (`cargo run -p vtex-synth-wasm --bin parity`) and in WebAssembly
//! (`tests/wasm/parity.test.mjs`); the two lists must be equal.

// `deny`, not `forbid`: the exported entry point needs `#[no_mangle]`, which the lint counts
// as unsafe; it is the crate's one allowed exception.
#![deny(unsafe_code)]

use vtex_synth::{models, texture, Region};

/// The regions probed on every demo: several levels, far from the origin and across the
/// torus wrap, and a later animation frame.
pub fn probe_regions() -> Vec<Region> {
    vec![
        Region::new(0, 0, 0, 64, 64),
        Region::new(0, 70_001, 40_993, 48, 40),
        Region::new(0, -20, -9, 40, 30),
        Region::new(1, 333, 77, 32, 32),
        Region::new(3, 5, 9, 32, 24),
        Region::new(6, 0, 0, 16, 16),
        Region::new(0, 128, 64, 32, 32).at_frame(37),
    ]
}

/// BLAKE3 hashes (hex) of every probe region of every demo, in demo order; a region a demo
/// cannot render (a level it does not have) hashes its error message instead.
pub fn probe() -> Vec<String> {
    let mut out = Vec::new();
    for bundle in models::demos() {
        let tex = models::load(&bundle).expect("demos load");
        for region in probe_regions() {
            let bytes = match texture::render_image(&*tex, &region) {
                Ok(img) => img.data,
                Err(e) => e.to_string().into_bytes(),
            };
            out.push(blake3::hash(&bytes).to_hex().to_string());
        }
    }
    out
}

/// Runs [`probe`] and returns the hashes, newline-separated, as a pointer to a NUL-terminated
/// UTF-8 string owned by the module (leaked: one call per instance).
#[allow(unsafe_code)] // an unmangled export: its name must not clash with another symbol
#[no_mangle]
pub extern "C" fn vtex_probe() -> *const u8 {
    let mut text = probe().join("\n").into_bytes();
    text.push(0);
    Box::leak(text.into_boxed_slice()).as_ptr()
}
