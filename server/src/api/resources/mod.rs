//! The API's own resources: textures and their uploads, edits and deletion, tiles, metatiles, pages and
//! batches of them, and the model catalogue.

pub mod batch;
pub(in crate::api) mod deletion;
pub(in crate::api) mod metatiles;
pub mod models;
pub mod pages;
pub(in crate::api) mod textures;
pub mod tiles;
