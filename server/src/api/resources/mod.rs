//! The API's own resources: textures and their uploads, edits and deletion, tiles, pages and
//! batches of them, and the model catalogue.

pub mod batch;
pub(in crate::api) mod deletion;
pub mod models;
pub mod pages;
pub(in crate::api) mod textures;
pub mod tiles;
