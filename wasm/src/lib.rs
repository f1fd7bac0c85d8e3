//! vtex-synth compiled to WebAssembly with a minimal raw ABI (no bindings generator), so a
//! browser or Node can synthesize tiles from an encoding, and so tests can prove that the
//! WebAssembly build renders exactly the bytes of the native one.
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
