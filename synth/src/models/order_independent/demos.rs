//! Demo encodings over 64² exemplars drawn by the project's own generators
//! ([`crate::samples`]), so tiles are fast and nothing is downloaded.

use super::create;
use crate::bundle::Bundle;
use crate::models::Inputs;
use crate::pixels::Rgba8Image;
use crate::samples;
use serde_json::json;

fn bundle(name: &str, sample: Rgba8Image, params: serde_json::Value) -> Bundle {
    let mut inputs = Inputs::new();
    inputs.insert("sample".into(), sample.to_png());
    create(name, &params, &inputs).unwrap_or_else(|e| panic!("demo `{name}` is invalid: {e}"))
}

/// The demo encodings: three 100k²-class textures, each a sample of 64² plus a short manifest.
pub fn demos() -> Vec<Bundle> {
    vec![
        bundle("Order-independent A — lichen", samples::lichen(64, 21), json!({"seed": 31, "exemplar_wrap": true})),
        bundle("Order-independent B — pebbles", samples::pebbles(64, 9, 22, false), json!({"seed": 32})),
        bundle(
            "Order-independent C — pebble torus",
            samples::pebbles(64, 12, 23, true),
            json!({"seed": 33, "width": 1u64 << 17, "height": 1u64 << 17, "domain": "torus", "exemplar_wrap": true}),
        ),
    ]
}

/// A 4096² texture from a 64² lichen exemplar, the paper's defaults otherwise.
pub fn example() -> crate::models::Example {
    crate::models::Example {
        params: json!({"seed": 1, "width": 4096, "height": 4096, "exemplar_wrap": true}),
        inputs: vec![crate::models::ExampleInput {
            name: "sample".into(),
            what: "a 64 × 64 seamless lichen exemplar, drawn by vtex (samples::lichen)".into(),
            png: samples::lichen(64, 21).to_png(),
        }],
    }
}
