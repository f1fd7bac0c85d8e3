//! vtex-wire: what the vtex server, its Rust client (`vtex-client`) and its WebAssembly module
//! (`vtex-synth-wasm`) exchange, declared once.
//!
//! * [`info`] — a texture as the server describes it, and where it is defined
//!   ([`Domain`], [`Animation`]).
//! * [`levels`] — the mip arithmetic every side agrees on.
//! * [`frame`] — the tile batch body (`application/x-vtex-tile-batch`): frames of a 32-byte
//!   header and an item's bytes.
//! * [`urls`] — the URL templates of tiles, pages and batches.
//!
//! No I/O, no clocks: it builds for `wasm32-unknown-unknown`. The golden files in `fixtures/`
//! are written by the server's tests and read by the client's and the viewer's, so every
//! reader is held to the same bytes.

pub mod frame;
pub mod info;
pub mod levels;
pub mod urls;

pub use info::{Animation, Domain, TextureInfo};
