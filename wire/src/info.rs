//! A texture as the server describes it, and where it is defined.

use serde::{Deserialize, Serialize};

/// Where a texture is defined.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[serde(rename_all = "lowercase")]
pub enum Domain {
    /// Periodic with the texture's size: it tiles without a seam.
    Torus,
    /// Defined on the whole integer plane; the size is only the extent that is served.
    Plane,
}

/// How an animated texture moves: a request's `frame` counts ticks at `fps`.
#[derive(Clone, Copy, Debug, PartialEq, Serialize, Deserialize)]
pub struct Animation {
    pub fps: f32,
    /// Frames after which the animation repeats exactly; 0 when it never does.
    pub period_frames: u32,
}

/// What clients see of a texture: the items of the texture list and `GET /api/v1/textures/{id}`.
#[derive(Clone, Debug, Serialize, Deserialize, PartialEq)]
#[cfg_attr(feature = "openapi", derive(utoipa::ToSchema))]
pub struct TextureInfo {
    pub id: String,
    pub name: String,
    pub model: String,
    pub width: u64,
    pub height: u64,
    // Levels served as tiles (`levels::tile_levels`); not a doc comment, which the OpenAPI
    // description would show.
    pub levels: u32,
    pub tile_size: u32,
    /// Tiles a side of a metatile (`levels::metatile_tiles`).
    pub metatile: u32,
    pub encoding_bytes: u64,
    /// Bytes of the explicit 24-bit level 0 the encoding stands for.
    pub explicit_bytes: u64,
    pub wraps: bool,
    /// `torus` (wraps) or `plane` (defined everywhere, served over its extent).
    #[cfg_attr(feature = "openapi", schema(value_type = String))]
    pub domain: Domain,
    pub animated: bool,
    /// The animation's period and frame rate, for animated textures.
    #[cfg_attr(feature = "openapi", schema(value_type = Option<Object>))]
    pub animation: Option<Animation>,
    /// The parameters it was created with, as given (its manifest's): posted back to the
    /// upload with its model and input images, they make this very texture again.
    #[cfg_attr(feature = "openapi", schema(value_type = Object))]
    pub params: serde_json::Value,
    /// The parameters its model derived from `params` and the input images where they were
    /// not given (e.g. the cascade's `range`): made again by `create`, not part of the recipe.
    #[cfg_attr(feature = "openapi", schema(value_type = Object))]
    pub derived: serde_json::Map<String, serde_json::Value>,
}

/// Bytes of the explicit 24-bit level 0 of a `width × height` texture: what its encoding
/// stands for.
pub fn explicit_bytes(width: u64, height: u64) -> u64 {
    width.saturating_mul(height).saturating_mul(3)
}
