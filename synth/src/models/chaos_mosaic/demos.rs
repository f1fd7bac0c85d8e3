//! Demo encodings, from samples the project generates itself ([`crate::samples`]).

use super::MODEL;
use crate::{bundle::Bundle, models::Inputs, samples};
use serde_json::json;

/// A 100,000 × 100,000 mosaic of pebbles (seed-derived sequence, a few hundred bytes of
/// structure), the paper's 5120² storage example from a 128² sample with the explicit
/// 12-byte sequence, its plain tiling for comparison, and a non-seamless sample whose tile
/// edges are filtered too.
pub fn demos() -> Vec<Bundle> {
    let make = |name: &str, sample: crate::Rgba8Image, params: serde_json::Value| {
        let inputs = Inputs::from([("sample".to_string(), sample.to_png())]);
        super::create(name, &params, &inputs).expect("demo parameters are valid")
    };
    vec![
        make(
            "Pebbles — chaos mosaic 100k",
            samples::pebbles(160, 24, 11, true),
            json!({"tiles_x": 625, "tiles_y": 625, "seed": 2000, "blocks_per_tile": 2}),
        ),
        make(
            "Lichen — chaos mosaic 5120 (explicit blocks)",
            samples::lichen(128, 7),
            json!({"tiles_x": 40, "tiles_y": 40, "seed": 7, "sequence": "explicit"}),
        ),
        make(
            "Pebbles — plain tiling 5120",
            samples::pebbles(128, 18, 5, true),
            json!({"tiles_x": 40, "tiles_y": 40, "iterations": 0, "seed": 5}),
        ),
        make(
            "Cobbles — chaos mosaic 8192 (non-seamless sample)",
            samples::pebbles(128, 18, 21, false),
            json!({"tiles_x": 64, "tiles_y": 64, "seed": 21}),
        ),
    ]
    .into_iter()
    .inspect(|b| debug_assert_eq!(b.manifest.model, MODEL))
    .collect()
}

/// A 1024² mosaic of a 64² pebble sample: 16 × 16 tiles, the paper's defaults otherwise.
pub fn example() -> crate::models::Example {
    crate::models::Example {
        params: json!({"tiles_x": 16, "tiles_y": 16, "seed": 1}),
        inputs: vec![crate::models::ExampleInput {
            name: "sample".into(),
            what: "a 64 × 64 seamless pebble sample, drawn by vtex (samples::pebbles)".into(),
            png: samples::pebbles(64, 10, 3, true).to_png(),
        }],
    }
}
