//! vtex-synth compiled to WebAssembly with a minimal raw ABI (no bindings generator), so a
//! browser or Node can synthesize tiles from an encoding, and so tests can prove that the
//! WebAssembly build renders exactly the bytes of the native one.
//!
//! Browsers load one module per model (`scripts/build-wasm`: this crate built with
//! `--no-default-features --features model-<id>`, `vtex_synth_<id>.wasm`), holding only that
//! model's loading and rendering; natively (the default feature `all`) every model is in.
//!
//! - [`client`]: open a bundle within a page's bounds, its info, regions and server tiles;
//!   [`api`] exports it (wrapped for JavaScript by `client-web/src/shared/vtex-synth.js`).
//! - [`probe`]: the regions of a texture every build must render identically. The native
//!   reference (`cargo run -p vtex-synth-wasm --bin reference -- DIR`) writes every demo's
//!   bundle and the native bytes of its probe and of a few tiles; `tests/wasm/api.test.mjs`
//!   renders them through the module and the JavaScript wrapper and compares.

// `deny`, not `forbid`: the exported entry points (`api`) need `#[no_mangle]`, which the
// lint counts as unsafe; they are the crate's one allowed exception.
#![deny(unsafe_code)]

pub mod api;
pub mod client;
pub mod probe;

#[cfg(test)]
mod tests {
    /// `scripts/build-wasm` builds a module for each `model-*` feature of this crate: one for
    /// every model of vtex, none for a model that does not exist.
    #[test]
    fn there_is_a_module_feature_for_every_model() {
        let features: Vec<&str> = include_str!("../Cargo.toml")
            .lines()
            .filter_map(|line| line.strip_prefix("model-")?.split(' ').next())
            .collect();
        assert_eq!(features, vtex_synth::models::ALL);
    }
}
