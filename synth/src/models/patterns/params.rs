//! The encoding's JSON part: a composition of §3 blocks described as data (§4).
//!
//! A texture is a stack of layers composited bottom to top ("over"). Each layer is one of the
//! paper's compositions, chosen by which blocks it plugs in: a `tiling` layer with a virtual
//! choice is the basic aperiodic tiling (Fig. 16); with materials, a (dithered) areas map and
//! transition tiles it is the extended tiling (Fig. 17); a `sparse` layer is the sparse
//! convolution (Fig. 18–19); `sprites` is explicit positioning (texture sprites, Fig. 21d);
//! an `animation` block makes a tiling layer an animated tiling (Fig. 20).

use serde::{Deserialize, Serialize};
use std::collections::BTreeMap;

/// Everything in the manifest's `params`.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct Params {
    /// Level-0 size in pixels; every layer's cell size must divide both (the texture is a torus).
    pub width: u64,
    pub height: u64,
    /// Side S of every pattern, in pixels; a power of two so each pattern has its own mip chain.
    pub pattern_size: u32,
    /// The reference texture packs `reference[0] × reference[1]` patterns (§3.5), row-major.
    pub reference: [u32; 2],
    /// Seed the permutation tables σ were generated from (kept for provenance; the tables
    /// themselves are stored in the `sigma` section).
    pub seed: u64,
    /// Colour under the first layer (straight RGBA8).
    #[serde(default)]
    pub background: [u8; 4],
    pub layers: Vec<LayerParams>,
    /// Texture sprites by name, drawn by `sprites` layers. Kept in params (an object, not a
    /// list) so a JSON merge patch can move one sprite: `{"params":{"sprites":{"ball":{"x":9}}}}`.
    #[serde(default, skip_serializing_if = "BTreeMap::is_empty")]
    pub sprites: BTreeMap<String, SpriteParams>,
    /// Frames per second of animated textures (needed when a layer has an animation map).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub fps: Option<f32>,
}

#[derive(Clone, Copy, Debug, PartialEq, Eq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(rename_all = "lowercase")]
pub enum LayerKind {
    /// One pattern per cell of the virtual tile map (aperiodic tiling).
    Tiling,
    /// Transformed patterns on a transparent background (sparse convolution).
    Sparse,
    /// Patterns at explicit positions (texture sprites).
    Sprites,
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct LayerParams {
    pub kind: LayerKind,
    /// Side of a virtual tile map cell in pixels (the grid is width/cell × height/cell).
    pub cell: u32,
    /// How the pattern of a cell is chosen (tiling and sparse layers).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub choice: Option<Choice>,
    /// Tile transform of sparse layers.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transform: Option<TransformParams>,
    /// Transition tiles between material families (tiling layers).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub transitions: Option<TransitionParams>,
    /// Animation sequence and map (tiling layers).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub animation: Option<AnimationParams>,
}

/// The pattern-choice blocks.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
pub enum Choice {
    /// Virtual indirection map: σ-hashed vectorial pattern index over the whole reference.
    Virtual,
    /// Explicit indirection map: one pattern index per cell (65535 = no pattern); a map
    /// smaller than the grid repeats (maps wrap, §3.1) and must divide it.
    Explicit { map: MapRef },
    /// Materials (probability maps) placed by an optional areas map or pixel map.
    Materials {
        materials: Vec<MaterialParams>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        areas: Option<AreasParams>,
        #[serde(default, skip_serializing_if = "Option::is_none")]
        pixel_map: Option<PixelMapParams>,
    },
}

/// A material: a probability map (pattern indices, duplicated in proportion; -1 = blank)
/// and the family of compatible tiles it belongs to (§3.3).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct MaterialParams {
    pub patterns: Vec<i32>,
    #[serde(default)]
    pub family: u16,
}

/// An areas map: one material index per area; each area covers (grid / size) cells.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct AreasParams {
    pub map: MapRef,
    /// Dithered areas map: materials are interpolated between area centres (Fig. 9).
    #[serde(default)]
    pub dithered: bool,
}

/// A high-resolution material mask stored as an adaptive (indirection-compressed) map.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct PixelMapParams {
    /// Section holding the compressed map (see `pixel_map.rs`).
    pub section: String,
    /// Map size in map pixels; one map pixel covers `scale × scale` texture pixels.
    pub size: [u32; 2],
    pub scale: u32,
    /// Side of the compressed blocks, a power of two.
    pub block: u32,
}

/// A map: `size` values given inline or in a bundle section (`depth` bytes each, LE).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct MapRef {
    pub size: [u32; 2],
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub values: Option<Vec<u16>>,
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub section: Option<String>,
    /// Bytes per value in `section`: 1 or 2.
    #[serde(default = "one", skip_serializing_if = "is_one")]
    pub depth: u8,
}

fn one() -> u8 {
    1
}
fn is_one(v: &u8) -> bool {
    *v == 1
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct TransformParams {
    /// Scale range relative to the cell: s = min + r (max − min).
    pub scale: [f32; 2],
    /// Random rotation in [0, 2π).
    #[serde(default)]
    pub rotate: bool,
    /// Let patterns overflow into neighbouring cells (Fig. 4 right, 5); otherwise they are
    /// shrunk and translated so they stay strictly inside their cell (Fig. 4 middle).
    #[serde(default)]
    pub overflow: bool,
}

/// Transition tiles: for every family f ≥ 1, 14 pattern indices drawn with a transparent
/// background, indexed by the 4-bit mask (1..=14) of the corners that belong to f.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct TransitionParams {
    pub tiles: Vec<Vec<u32>>,
}

/// Animation sequence + animation map + temporal transitions (§3.4), driven by time or by
/// the distance to target sprites (Fig. 21a).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct AnimationParams {
    /// Pattern indices of the sequence; the first is the rest state; -1 = blank (sparse
    /// layers only).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sequence: Vec<i32>,
    /// Several animated patterns instead of `sequence`, one chosen per cell by the virtual
    /// random map (the aperiodic animated tiling, Fig. 20).
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub sequences: Vec<Vec<i32>>,
    /// A probability map over `sequences` (their indices, duplicated in proportion; any
    /// size); each sequence equally likely when empty.
    #[serde(default, skip_serializing_if = "Vec::is_empty")]
    pub probabilities: Vec<u32>,
    /// Global rate a (density of animation): the rest time of a cell is ⌊a Z⌋ frames.
    #[serde(default)]
    pub a: f64,
    #[serde(default)]
    pub phi: ValueParams,
    #[serde(default)]
    pub z: ValueParams,
    /// Parameters before a temporal transition at frame `t0`, or before each of several (a
    /// list in increasing `t0`, at least 2n frames apart: a density ramp).
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub previous: Option<Previous>,
    /// The sequence is driven by the distance to target sprites instead of time.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub distance: Option<DistanceParams>,
}

impl AnimationParams {
    /// The earlier parameter sets, in increasing `t0`.
    pub fn schedule(&self) -> &[PreviousParams] {
        match &self.previous {
            None => &[],
            Some(Previous::One(p)) => std::slice::from_ref(p),
            Some(Previous::Many(v)) => v,
        }
    }

    /// Every per-cell value it reads: φ, Z and the earlier Zs.
    pub fn values(&self) -> impl Iterator<Item = &ValueParams> {
        [&self.phi, &self.z].into_iter().chain(self.schedule().iter().map(|q| &q.z))
    }

    /// The integer ranges it draws at random (for the range tables).
    pub fn ranges(&self) -> Vec<u32> {
        let choice = if self.probabilities.is_empty() { self.sequences.len() } else { self.probabilities.len() };
        self.values().map(|v| v.random).chain([choice as u32]).filter(|&m| m > 1).collect()
    }
}

/// One earlier parameter set, or several.
#[derive(Clone, Debug, PartialEq, Serialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(untagged)]
pub enum Previous {
    One(PreviousParams),
    Many(Vec<PreviousParams>),
}

#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct PreviousParams {
    pub a: f64,
    pub z: ValueParams,
    pub t0: u32,
}

/// The sequence parameter is the distance from a cell's centre to the nearest target: the
/// last pattern at distance 0, the rest state at `radius` and beyond (Fig. 21a).
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct DistanceParams {
    /// Names in `params.sprites`: their centres (moving with them) are the targets.
    pub targets: Vec<String>,
    /// Level-0 pixels.
    pub radius: f64,
}

/// A per-cell integer: an explicit map (per cell, wrapping) plus a virtual random value in
/// `0..random` (drawn without the bias of Fig. 2.2: from σ when it divides 256, else from a
/// range table).
#[derive(Clone, Debug, Default, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct ValueParams {
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub map: Option<MapRef>,
    #[serde(default)]
    pub random: u32,
}

/// A texture sprite: pattern `pattern` with its top-left corner at (x, y) level-0 pixels,
/// drawn by one sprites layer (each layer is one positioning map: n grids for n patterns in
/// a cell, §3.2), then transformed about its centre (the Tile Transform plugged after the
/// Explicit Positioning) and, when it has a velocity, moving with time.
#[derive(Clone, Debug, PartialEq, Serialize, Deserialize)]
#[cfg_attr(feature = "create", derive(schemars::JsonSchema))]
#[serde(deny_unknown_fields)]
pub struct SpriteParams {
    pub pattern: u32,
    pub x: i64,
    pub y: i64,
    /// Index in `layers` of the sprites layer that draws it; the first sprites layer if absent.
    #[serde(default, skip_serializing_if = "Option::is_none")]
    pub layer: Option<usize>,
    /// Scale about the sprite's centre (1 = the pattern's own size), in (0, 4].
    #[serde(default = "unit_scale", skip_serializing_if = "is_unit_scale")]
    pub scale: f32,
    /// Rotation about the sprite's centre, degrees (clockwise on screen).
    #[serde(default, skip_serializing_if = "is_zero_f32")]
    pub rotation: f32,
    /// Level-0 pixels per frame: the sprite is at (x, y) + t · velocity at frame t (wrapping).
    #[serde(default, skip_serializing_if = "is_still")]
    pub velocity: [i64; 2],
}

impl SpriteParams {
    /// Pattern `pattern` at (x, y), untransformed and still, on the first sprites layer.
    pub fn at(pattern: u32, x: i64, y: i64) -> Self {
        SpriteParams { pattern, x, y, layer: None, scale: 1.0, rotation: 0.0, velocity: [0, 0] }
    }
}

fn unit_scale() -> f32 {
    1.0
}
fn is_unit_scale(v: &f32) -> bool {
    *v == 1.0
}
fn is_zero_f32(v: &f32) -> bool {
    *v == 0.0
}
fn is_still(v: &[i64; 2]) -> bool {
    *v == [0, 0]
}

// `Choice` and `Previous` are read as JSON values and their variants from those values, as
// the derives of `#[serde(tag)]` and `#[serde(untagged)]` would, but without their buffered
// `Content`: every type below the enums is then deserialized by serde_json's value
// deserializer only, which keeps the WebAssembly modules small.

/// The tag of [`Choice`], read as serde reads a variant name.
#[derive(Deserialize)]
#[serde(variant_identifier, rename_all = "snake_case")]
enum ChoiceKind {
    Virtual,
    Explicit,
    Materials,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct ExplicitFields {
    map: MapRef,
}

#[derive(Deserialize)]
#[serde(deny_unknown_fields)]
struct MaterialsFields {
    materials: Vec<MaterialParams>,
    #[serde(default)]
    areas: Option<AreasParams>,
    #[serde(default)]
    pixel_map: Option<PixelMapParams>,
}

impl<'de> Deserialize<'de> for Choice {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        use serde::de::Error;
        let (kind, fields) = crate::bundle::tagged(d, "kind", "internally tagged enum Choice")?;
        let choice = match kind {
            // As the derive: a unit variant ignores whatever else is there.
            ChoiceKind::Virtual => Ok(Choice::Virtual),
            ChoiceKind::Explicit => {
                serde_json::from_value(fields).map(|f: ExplicitFields| Choice::Explicit { map: f.map })
            }
            ChoiceKind::Materials => serde_json::from_value(fields).map(|f: MaterialsFields| Choice::Materials {
                materials: f.materials,
                areas: f.areas,
                pixel_map: f.pixel_map,
            }),
        };
        choice.map_err(D::Error::custom)
    }
}

impl<'de> Deserialize<'de> for Previous {
    fn deserialize<D: serde::Deserializer<'de>>(d: D) -> Result<Self, D::Error> {
        let value = serde_json::Value::deserialize(d)?;
        if let Ok(one) = serde_json::from_value(value.clone()) {
            return Ok(Previous::One(one));
        }
        serde_json::from_value(value)
            .map(Previous::Many)
            .map_err(|_| serde::de::Error::custom("data did not match any variant of untagged enum Previous"))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::bundle::read_both_ways;
    use serde_json::json;

    /// `Choice` and `Previous` as serde's derives read them (of the same names, which
    /// serde's messages hold).
    #[allow(dead_code)] // read through Debug only
    mod derived {
        use super::super::*;

        #[derive(Debug, Deserialize)]
        #[serde(tag = "kind", rename_all = "snake_case", deny_unknown_fields)]
        pub enum Choice {
            Virtual,
            Explicit {
                map: MapRef,
            },
            Materials {
                materials: Vec<MaterialParams>,
                #[serde(default)]
                areas: Option<AreasParams>,
                #[serde(default)]
                pixel_map: Option<PixelMapParams>,
            },
        }

        #[derive(Debug, Deserialize)]
        #[serde(untagged)]
        pub enum Previous {
            One(PreviousParams),
            Many(Vec<PreviousParams>),
        }
    }

    #[test]
    fn choice_and_previous_read_as_the_derives_do() {
        let map = json!({"size": [2, 2], "values": [1, 2, 3, 4]});
        let choices = [
            json!({"kind": "virtual"}),
            json!({"kind": "virtual", "map": 1}),
            json!({"kind": "explicit", "map": map}),
            json!({"map": map, "kind": "explicit"}),
            json!({"kind": "explicit"}),
            json!({"kind": "explicit", "map": map, "extra": true}),
            json!({"kind": "explicit", "map": {"size": [2, "2"]}}),
            json!({"kind": "materials", "materials": [{"patterns": [1, -1], "family": 2}]}),
            json!({"kind": "materials", "materials": [], "areas": {"map": map, "dithered": true}}),
            json!({"kind": "materials", "materials": [], "pixel_map": {"section": "s", "size": [1, 1], "scale": 2, "block": 4}}),
            json!({"kind": "materials", "materials": [{"patterns": [1.5]}]}),
            json!({"kind": "tiles"}),
            json!({"kind": 1, "map": map}),
            json!({"kind": null}),
            json!({}),
            json!("virtual"),
            json!(["explicit", map]),
            json!(7),
        ];
        for v in &choices {
            assert_eq!(read_both_ways::<Choice>(v), read_both_ways::<derived::Choice>(v), "{v}");
        }
        let p = json!({"a": 0.5, "z": {"random": 3}, "t0": 10});
        let previous = [
            p.clone(),
            json!([p, p]),
            json!([]),
            json!([0.5, {"random": 3}, 10]),
            json!({"a": 0.5, "z": {}, "t0": 10, "x": 1}),
            json!({"a": 0.5}),
            json!([p, 3]),
            json!("p"),
            json!(null),
        ];
        for v in &previous {
            assert_eq!(read_both_ways::<Previous>(v), read_both_ways::<derived::Previous>(v), "{v}");
        }
    }
}
