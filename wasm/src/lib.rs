//! vtex-synth compiled to WebAssembly with a minimal raw ABI (no bindings generator), so a
//! browser or Node can synthesize tiles from an encoding, and so tests can prove that the
//! WebAssembly build renders exactly the bytes of the native one.
//!
//! The same probe ([`probe::regions`] of every demo texture, each reduced to a BLAKE3 hash)
//! runs natively (`cargo run -p vtex-synth-wasm --bin parity`) and in WebAssembly
//! (`tests/wasm/parity.test.mjs`); the two lists must be equal.

// `deny`, not `forbid`: the exported entry point needs `#[no_mangle]`, which the lint counts
// as unsafe; it is the crate's one allowed exception.
#![deny(unsafe_code)]

pub mod probe;

use vtex_synth::models;

/// [`probe::hashes`] of every demo, in demo order.
pub fn probe() -> Vec<String> {
    models::demos().iter().flat_map(|bundle| probe::hashes(&*models::load(bundle).expect("demos load"))).collect()
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
