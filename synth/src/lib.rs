//! vtex-synth: the texture models of vtex and everything they share.
//!
//! A virtual texture is never stored: a model turns a compact encoding (a [`bundle::Bundle`])
//! into any rectangle of any mip level, as RGBA8, identically every time. This crate is pure —
//! no I/O, no threads, no clocks — so the same code runs in the server and in WebAssembly.
//!
//! * [`texture`] — the interface every model implements, and region validation.
//! * [`bundle`] — the on-disk/on-wire encoding container and its content id.
//! * [`models`] — the models, and the registry that loads or creates any of them by name.
//! * [`hash`] — counter-based hashing, the only source of randomness in the pixel path.
//! * [`pixels`] — RGBA8 buffers and bounded PNG decoding of untrusted samples.
//! * [`resources`] — the caches and work counters that the textures of one owner share.
//! * [`layer`] — material layers derived from the colour (tangent-space normals).
//! * [`mip`] — the exact 2×2 box downsample that every model's prefiltered levels are held to.
//! * [`simd`] — hot integer loops compiled for the CPU's widest vector unit, chosen at run time
//!   (the crate's only `unsafe`).

#![deny(unsafe_code)]

pub mod bundle;
pub mod error;
pub mod hash;
pub mod layer;
pub mod mip;
pub mod models;
pub mod pixels;
pub mod resources;
#[cfg(feature = "create")]
pub mod samples;
#[cfg(feature = "model-order-independent")]
pub mod simd;
pub mod texture;

pub use error::{Error, Result};
pub use pixels::Rgba8Image;
pub use resources::Resources;
pub use texture::{Animation, Domain, Never, Region, Stop, Texture};
