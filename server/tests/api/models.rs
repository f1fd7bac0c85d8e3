//! The model catalogue (`GET /api/v1/models`, `vtex models`): every model listed with its
//! parameters' schema and inputs, and every model's example creating a texture through the
//! multipart upload and through `vtex create`.

use crate::support::*;
use serde_json::Value;

#[tokio::test]
async fn every_model_is_listed_and_its_example_creates_a_texture() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let list: Value = c.get(s.url("/api/v1/models")).send().await.unwrap().json().await.unwrap();
    let docs = list["models"].as_array().unwrap();
    let ids: Vec<&str> = docs.iter().map(|d| d["id"].as_str().unwrap()).collect();
    assert_eq!(ids, vtex_synth::models::ids().collect::<Vec<_>>());
    for doc in docs {
        let id = doc["id"].as_str().unwrap();
        for field in ["title", "paper", "summary"] {
            assert!(!doc[field].as_str().unwrap().is_empty(), "{id}: {field}");
        }
        let schema = &doc["params_schema"];
        assert!(schema["$schema"].as_str().unwrap().contains("json-schema.org"), "{id}: {schema}");
        assert!(schema["properties"].as_object().is_some_and(|p| !p.is_empty()), "{id}: {schema}");
        for input in doc["inputs"].as_array().unwrap() {
            if input["required"].as_bool().unwrap() {
                assert!(doc["example"]["inputs"].get(input["name"].as_str().unwrap()).is_some(), "{id}: {input}");
            }
        }
        // Every property the example sets is one the schema names.
        for key in doc["example"]["params"].as_object().unwrap().keys() {
            assert!(schema["properties"].get(key).is_some(), "{id}: example param `{key}` not in the schema");
        }
        let one: Value = c.get(s.url(&format!("/api/v1/models/{id}"))).send().await.unwrap().json().await.unwrap();
        assert_eq!(&one, doc, "{id}");

        let r = post_example(&c, &s, doc, &format!("{id} example")).await;
        let status = r.status().as_u16();
        let info: Value = r.json().await.unwrap();
        assert_eq!(status, 201, "{id}: {info}");
        assert_eq!(info["model"], id);
        assert!(info["width"].as_u64().unwrap() <= 4096, "{id}: the example is small: {info}");
        let (status, _, png) = get_bytes(&c, &s.tile_url(info["id"].as_str().unwrap(), 0, 0, 0, "png")).await;
        assert_eq!(status, 200, "{id}");
        assert_eq!(image::load_from_memory(&png).unwrap().width(), 256, "{id}");
    }
}

#[tokio::test]
async fn the_catalogue_is_validated_and_unknown_names_are_404s_naming_the_known() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    for path in ["/api/v1/models", "/api/v1/models/lcm", "/api/v1/models/patterns/example/reference.png"] {
        let r = c.get(s.url(path)).send().await.unwrap();
        assert_eq!(r.status(), 200, "{path}");
        assert_eq!(r.headers()["cache-control"], "no-cache", "{path}");
        let tag = r.headers()["etag"].clone();
        let again = c.get(s.url(path)).header("if-none-match", tag.clone()).send().await.unwrap();
        assert_eq!(again.status(), 304, "{path}");
        assert_eq!(again.headers()["etag"], tag, "{path}");
    }
    let known = vtex_synth::models::ids().collect::<Vec<_>>().join(", ");
    let message = expect_error(&c, &s.url("/api/v1/models/voronoi"), 404).await;
    assert!(message.contains("voronoi") && message.contains(&known), "{message}");
    let message = expect_error(&c, &s.url("/api/v1/models/voronoi/example/sample.png"), 404).await;
    assert!(message.contains(&known), "{message}");
    let message = expect_error(&c, &s.url("/api/v1/models/chaos-mosaic/example/reference.png"), 404).await;
    assert!(message.contains("reference") && message.contains("sample"), "{message}");
    let message = expect_error(&c, &s.url("/api/v1/models/cascade/example/control.png"), 404).await;
    assert!(message.contains("none"), "{message}");
    let message = expect_error(&c, &s.url("/api/v1/models?x=1"), 400).await;
    assert!(message.contains("`x`"), "{message}");
}
