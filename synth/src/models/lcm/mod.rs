//! `lcm`: multi-scaled stochastic textures rendered with Layer Control Masks
//! (paper `layer-control-masks.txt`).
//!
//! A texture is scaled, rotated, mirrored, signed copies of one small base element, dropped
//! at half-element spacing on layers of decreasing resolution. Every replication point's
//! event is drawn once from an event table and stored as one byte in the layer's control
//! mask, so any pixel is evaluated alone from at most four LCM entries per layer. Mip level L
//! shifts every layer down L resolutions (§2.4), so coarse levels are native and prefiltered.
//!
//! * [`event`] — the one-byte event code of §5.
//! * [`table`] — event tables and the seeded drawing of LCMs.
//! * [`element`] (+ [`haar`]) — the base element and its scaled, oriented copies.
//! * [`layer`] — evaluation of one layer from its LCM, native or prefiltered.
//! * [`render`] — the texture: layers, order, background, colour; operation counting.
//! * [`period`] — the period that LCM sizes give the texture.
//! * [`colour`] — palette or per-channel planes.
//! * [`encoding`] — parameters, sections, `create` and `load`.
//! * [`elements`], [`demos`] — project-made base elements and the paper's §3 examples.

pub mod colour;
pub mod demos;
pub mod element;
pub mod elements;
pub mod encoding;
pub mod event;
pub mod haar;
pub mod layer;
pub mod period;
pub mod render;
pub mod table;

pub use demos::demos;
pub use encoding::{create, load, CreateParams, Params};
pub use render::{LcmTexture, OpCount};

/// The model id.
pub const MODEL: &str = "lcm";
