//! The same textures through other tools' protocols: Deep Zoom, IIIF Image and Presentation,
//! JSON-LD contexts, TileJSON and XYZ.

pub(in crate::api) mod dzi;
pub(in crate::api) mod iiif;
pub(in crate::api) mod jsonld;
pub(in crate::api) mod presentation;
pub(in crate::api) mod tilejson;
