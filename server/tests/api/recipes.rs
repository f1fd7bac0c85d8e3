//! A texture's params, as its info reports them, are its recipe: posted back they make it again
//! bit for bit, and a PATCH
//! that changes them makes the texture again from them — for every model, over HTTP.

use crate::support::*;
use serde_json::{json, Value};
use vtex_synth::bundle::Bundle;
use vtex_synth::models::{self, lcm, Inputs};
#[path = "../../../synth/tests/support/rgb_png.rs"]
mod rgb_png;
use rgb_png::rgb_png;

async fn encoding(c: &reqwest::Client, s: &Server, id: &str) -> Bundle {
    let (status, _, bytes) = get_bytes(c, &s.url(&format!("/api/v1/textures/{id}/encoding"))).await;
    assert_eq!(status, 200, "{id}");
    Bundle::from_bytes(&bytes).unwrap()
}

/// `POST /api/v1/textures` as a multipart creation; returns (status, body).
async fn post_recipe(
    c: &reqwest::Client,
    s: &Server,
    model: &str,
    name: &str,
    params: &Value,
    inputs: &Inputs,
) -> (u16, Value) {
    let mut form = reqwest::multipart::Form::new()
        .text("model", model.to_string())
        .text("name", name.to_string())
        .text("params", params.to_string());
    for (input, png) in inputs {
        form = form.part(input.clone(), reqwest::multipart::Part::bytes(png.clone()).file_name(format!("{input}.png")));
    }
    let r = c.post(s.url("/api/v1/textures")).multipart(form).send().await.unwrap();
    (r.status().as_u16(), r.json().await.unwrap())
}

async fn patch(c: &reqwest::Client, s: &Server, id: &str, body: Value) -> (u16, Value) {
    let r = c.patch(s.url(&format!("/api/v1/textures/{id}"))).json(&body).send().await.unwrap();
    (r.status().as_u16(), r.json().await.unwrap())
}

async fn tile(c: &reqwest::Client, s: &Server, id: &str) -> Vec<u8> {
    let (status, _, bytes) = get_bytes(c, &s.tile_url(id, 0, 0, 0, "rgba")).await;
    assert_eq!(status, 200, "{id}");
    bytes
}

#[tokio::test]
async fn every_demo_is_made_again_from_the_params_it_reports() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--demos"]);
    let c = client();
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    let all = list["textures"].as_array().unwrap();
    assert_eq!(all.len(), models::demos().len());
    for t in all {
        let id = t["id"].as_str().unwrap();
        let one: Value = c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
        assert_eq!(&one, t, "the list's item is the texture's info");
        // The info's model, name and params, with the input images the bundle holds.
        let (model, name, params) = (t["model"].as_str().unwrap(), t["name"].as_str().unwrap(), &t["params"]);
        let b = encoding(&c, &s, id).await;
        assert_eq!(params, &b.manifest.params, "{name}: the info's params are the manifest's");
        let inputs = models::get(model).unwrap().inputs_of(&b).unwrap();
        let (status, info) = post_recipe(&c, &s, model, name, params, &inputs).await;
        assert_eq!(status, 200, "{name}: {info}");
        assert_eq!(info["id"], id, "{name}: made again, it is another texture");
    }
    assert_eq!(store_files(dir.path()).len(), all.len(), "nothing new was stored");
}

#[tokio::test]
async fn a_patched_seed_makes_the_texture_again_for_every_model() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    for m in models::REGISTRY {
        let b = m.demos().swap_remove(0);
        let id = put(&c, &s, &b).await;
        let seed = b.manifest.params["seed"].as_u64().expect("every model has a seed");
        let (status, info) = patch(&c, &s, &id, json!({"params": {"seed": seed + 1}})).await;
        assert_eq!(status, 201, "{}: {info}", m.id());
        let new_id = info["id"].as_str().unwrap();
        let patched = encoding(&c, &s, new_id).await;
        assert_eq!(patched.manifest.params["seed"], seed + 1);
        // What is stored is what the model makes of the patched params: the data agrees
        // with the manifest.
        let inputs = m.inputs_of(&b).unwrap();
        let made = m.create(&b.manifest.name, &patched.manifest.params, &inputs).unwrap();
        assert!(made == patched, "{}: the patched bundle is not what its params make", m.id());
        assert_ne!(tile(&c, &s, &id).await, tile(&c, &s, new_id).await, "{}: a new seed changed no pixel", m.id());
    }
}

/// An `lcm` demo of one 1 × 1 event table per layer, one byte a mask point.
fn cheese() -> Bundle {
    let (name, mut p) = lcm::demos::all_params().swap_remove(1);
    assert_eq!(name, "LCM cheese");
    p.mask_coding = lcm::packing::MaskCoding::Raw;
    lcm::demos::make(name, &p).unwrap()
}

#[tokio::test]
async fn a_patched_event_table_redraws_the_mask() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let b = cheese();
    let id = put(&c, &s, &b).await;
    let mut layers = b.manifest.params["layers"].clone();
    layers[0]["table"]["cells"][0]["sign"] = json!([0.5, 0.0, 0.5]);
    let (status, info) = patch(&c, &s, &id, json!({"params": {"layers": layers}})).await;
    assert_eq!(status, 201, "{info}");
    let patched = encoding(&c, &s, info["id"].as_str().unwrap()).await;
    let holes = |b: &Bundle| b.section("lcm.0").unwrap().iter().filter(|&&e| e != 0).count();
    let points = b.section("lcm.0").unwrap().len() as f64;
    assert!((holes(&b) as f64 / points - 0.08).abs() < 0.03, "{}", holes(&b));
    assert!((holes(&patched) as f64 / points - 0.5).abs() < 0.05, "{}", holes(&patched));
    assert_eq!(patched.section("lcm.1").unwrap(), b.section("lcm.1").unwrap(), "layer 1 kept its table");
}

#[tokio::test]
async fn a_patch_the_model_cannot_remake_is_refused_naming_the_field() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    // A hand-edited mask: a valid event code where the table drew none.
    let mut b = cheese();
    let lcm0 = b.sections.iter_mut().find(|s| s.name == "lcm.0").unwrap();
    let at = lcm0.data.iter().position(|&e| e == 0).unwrap();
    lcm0.data[at] = 1;
    let id = put(&c, &s, &b).await;
    let before = store_files(dir.path());
    let (status, e) = patch(&c, &s, &id, json!({"params": {"seed": 6}})).await;
    assert_eq!(status, 400, "{e}");
    let msg = e["error"].as_str().unwrap();
    assert!(msg.contains("`seed`") && msg.contains("section `lcm.0`"), "{msg}");
    assert_eq!(store_files(dir.path()), before);
    // A rename changes nothing the params derive: allowed, the sections kept.
    let (status, info) = patch(&c, &s, &id, json!({"name": "edited cheese"})).await;
    assert_eq!(status, 201, "{info}");
    let renamed = encoding(&c, &s, info["id"].as_str().unwrap()).await;
    assert_eq!((renamed.manifest.name.as_str(), &renamed.sections), ("edited cheese", &b.sections));
    // A mask uploaded without its table cannot be redrawn either.
    let mut b = cheese();
    b.manifest.params["layers"][0].as_object_mut().unwrap().remove("table");
    let id = put(&c, &s, &b).await;
    let (status, e) = patch(&c, &s, &id, json!({"params": {"seed": 6}})).await;
    assert_eq!(status, 400, "{e}");
    let msg = e["error"].as_str().unwrap();
    assert!(msg.contains("`seed`") && msg.contains("layers[0].table"), "{msg}");
}

/// Luma standard deviation of raw RGBA8 bytes.
fn luma_sigma(rgba: &[u8]) -> f64 {
    let luma: Vec<f64> =
        rgba.chunks_exact(4).map(|p| 0.299 * p[0] as f64 + 0.587 * p[1] as f64 + 0.114 * p[2] as f64).collect();
    let mean = luma.iter().sum::<f64>() / luma.len() as f64;
    (luma.iter().map(|l| (l - mean).powi(2)).sum::<f64>() / luma.len() as f64).sqrt()
}

/// A PATCH gives the very texture (the same id) that uploading the user's params, patched,
/// with the same input images gives: Cascade demo A's map moved from r = 3.9 to 3.3 (whose
/// automatic `range` must follow, or the texture goes flat), an `lcm` element made larger and
/// a layer added (fields the user never wrote, `k` and `stored_resolutions`, follow), and a
/// new seed for a mosaic uploaded as a bundle the user assembled, sample in their own PNG.
#[tokio::test]
async fn a_patch_gives_what_uploading_the_patched_params_gives() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let cascade_a = json!({"seed": 11, "stages": [{"kernel": {"size": 5, "preset": "gauss", "sigma": 1.0},
                           "map": {"kind": "logistic", "r": 3.9}, "iterations": 5}], "palette": "ocean"});
    let mut stages = cascade_a["stages"].clone();
    stages[0]["map"]["r"] = json!(3.3);
    let brick = models::get("lcm").unwrap().example().params;
    let mut layers = brick["layers"].clone();
    let noise = serde_json::to_value(lcm::demos::table_noise()).unwrap();
    layers.as_array_mut().unwrap().push(json!({"layer": 2, "weight": 0.2, "lcm": [20, 20], "table": noise}));
    let cases = [
        ("cascade", cascade_a, json!({"stages": stages})),
        ("lcm", brick.clone(), json!({"element": {"k": 6}})),
        ("lcm", brick, json!({"layers": layers})),
    ];
    for (model, user, edit) in cases {
        let (status, made) = post_recipe(&c, &s, model, model, &user, &Inputs::new()).await;
        assert!(status == 201 || status == 200, "{made}");
        let (status, patched) = patch(&c, &s, made["id"].as_str().unwrap(), json!({"params": edit})).await;
        assert_eq!(status, 201, "{model} {edit}: {patched}");
        let mut edited = user.clone();
        models::merge_patch(&mut edited, &edit);
        let (status, fresh) = post_recipe(&c, &s, model, model, &edited, &Inputs::new()).await;
        assert_eq!((status, &fresh["id"]), (200, &patched["id"]), "{model} {edit}: not the fresh texture");
        assert_eq!(patched["params"], fresh["params"]);
        assert_eq!(patched["derived"], fresh["derived"]);
    }
    // Demo A at r = 3.3 is mapped by its own range, not 3.9's: a texture, not a flat colour.
    let (_, a) =
        post_recipe(&c, &s, "cascade", "a", &json!({"seed": 11, "stages": stages, "palette": "ocean"}), &Inputs::new())
            .await;
    assert!(a["params"].get("range").is_none() && a["derived"]["range"].is_array(), "{a}");
    let sigma = luma_sigma(&tile(&c, &s, a["id"].as_str().unwrap()).await);
    assert!(sigma > 20.0, "luma σ {sigma:.1}");

    let sample = rgb_png(&vtex_synth::samples::pebbles(64, 10, 3, true));
    let user = json!({"tiles_x": 16, "tiles_y": 16, "seed": 1, "seamless": true});
    let uploaded = Bundle::new("chaos-mosaic", "uploaded", user.clone()).with_section("sample.png", sample.clone());
    let id = put(&c, &s, &uploaded).await;
    let (status, patched) = patch(&c, &s, &id, json!({"params": {"seed": 2}})).await;
    assert_eq!(status, 201, "{patched}");
    let inputs = Inputs::from([("sample".to_string(), sample)]);
    let (status, fresh) = post_recipe(
        &c,
        &s,
        "chaos-mosaic",
        "uploaded",
        &json!({"tiles_x": 16, "tiles_y": 16, "seed": 2, "seamless": true}),
        &inputs,
    )
    .await;
    assert_eq!((status, &fresh["id"]), (200, &patched["id"]), "the uploaded mosaic, reseeded: {fresh}");
}
