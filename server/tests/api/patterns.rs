//! The `patterns` model's texture sprites over a real socket: the collision error's advice
//! ("draw it on another sprites layer") followed through PATCH gives a texture drawing both
//! sprites, tile for tile what the model renders.

use crate::support::*;
use serde_json::{json, Value};
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, patterns::demos};
use vtex_synth::{texture::render_image, Region};

#[tokio::test]
async fn a_second_sprites_layer_takes_a_colliding_sprite() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let original = demos::sprites();
    let id = put(&c, &s, &original).await;
    let url = s.url(&format!("/api/v1/textures/{id}"));

    // `clash` shares maple's positioning cells: refused, naming the way out.
    let clash = json!({"pattern": 17, "x": 720, "y": 410});
    let r = c.patch(&url).json(&json!({"params": {"sprites": {"clash": clash}}})).send().await.unwrap();
    assert_eq!(r.status(), 400);
    let e: Value = r.json().await.unwrap();
    let msg = e["error"].as_str().unwrap();
    assert!(msg.contains("maple") && msg.contains("\"layer\""), "{msg}");

    // The advice: one more sprites layer (a merge patch replaces the list), clash on it.
    let mut layers = original.manifest.params["layers"].as_array().unwrap().clone();
    layers.push(layers[1].clone());
    let mut clash = clash;
    clash["layer"] = 2.into();
    let patch = json!({"params": {"layers": layers, "sprites": {"clash": clash}}});
    let r = c.patch(&url).json(&patch).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let info: Value = r.json().await.unwrap();
    let new_id = info["id"].as_str().unwrap();

    // Tile (2, 1) of level 0 holds both sprites: what the model renders from the stored
    // encoding, and not the original tile.
    let (_, _, bytes) = get_bytes(&c, &s.url(&format!("/api/v1/textures/{new_id}/encoding"))).await;
    let stored = Bundle::from_bytes(&bytes).unwrap();
    assert_eq!(stored.manifest.params["sprites"]["clash"]["layer"], 2);
    let expected = render_image(&*models::load(&stored).unwrap(), &Region::new(0, 512, 256, 256, 256)).unwrap();
    let (status, _, tile) = get_bytes(&c, &s.tile_url(new_id, 0, 2, 1, "rgba")).await;
    assert_eq!(status, 200);
    assert_eq!(tile, expected.data);
    let (_, _, before) = get_bytes(&c, &s.tile_url(&id, 0, 2, 1, "rgba")).await;
    assert_ne!(tile, before, "the clashing sprite is drawn");

    // Naming a layer that is not a sprites layer is a 400 naming the field.
    let r = c.patch(&url).json(&json!({"params": {"sprites": {"maple": {"layer": 0}}}})).send().await.unwrap();
    assert_eq!(r.status(), 400);
    let e: Value = r.json().await.unwrap();
    assert!(e["error"].as_str().unwrap().contains("sprites.maple.layer"), "{e}");
}
