//! What runs the service rather than serves textures: health and readiness, and the viewer's files.

pub(in crate::api) mod health;
pub(in crate::api) mod web;
