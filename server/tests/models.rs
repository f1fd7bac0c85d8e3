//! The model catalogue (`GET /api/v1/models`, `vtex models`): every model listed with its
//! parameters' schema and inputs, and every model's example creating a texture through the
//! multipart upload and through `vtex create`.

mod common;
use common::*;
use serde_json::Value;
use std::process::Command;

/// The multipart upload of a model's example (from its document), named `name`, with the
/// input images fetched from the server.
async fn post_example(c: &reqwest::Client, s: &Server, doc: &Value, name: &str) -> reqwest::Response {
    let mut form = reqwest::multipart::Form::new()
        .text("model", doc["id"].as_str().unwrap().to_string())
        .text("name", name.to_string())
        .text("params", doc["example"]["params"].to_string());
    for (input, how) in doc["example"]["inputs"].as_object().unwrap() {
        let href = how["href"].as_str().unwrap();
        assert!(href.starts_with(&s.url("/api/v1/models/")), "an absolute URL on this server: {href}");
        let (status, headers, png) = get_bytes(c, href).await;
        assert_eq!(status, 200, "{input} of {}", doc["id"]);
        assert_eq!(headers["content-type"], "image/png");
        assert!(!how["what"].as_str().unwrap().is_empty());
        form = form.part(input.clone(), reqwest::multipart::Part::bytes(png).file_name(format!("{input}.png")));
    }
    c.post(s.url("/api/v1/textures")).multipart(form).send().await.unwrap()
}

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

fn vtex(args: &[&str]) -> String {
    let out = Command::new(BIN).args(args).output().unwrap();
    assert!(out.status.success(), "vtex {args:?}: {}", String::from_utf8_lossy(&out.stderr));
    String::from_utf8(out.stdout).unwrap()
}

/// `vtex models --json` is the server's document; the human listing's example commands, run
/// as printed, make the very textures the multipart upload of the same example makes (same
/// ids: an id is the hash of the bundle); `vtex create --help` names every model.
#[tokio::test]
async fn the_cli_lists_the_same_models_and_its_example_commands_create_them() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let served: Value = c.get(s.url("/api/v1/models")).send().await.unwrap().json().await.unwrap();
    // Over HTTP the example images' links are absolute; the CLI, with no request, prints paths.
    let as_paths: Value = serde_json::from_str(&served.to_string().replace(&s.url(""), "")).unwrap();
    let printed: Value = serde_json::from_str(&vtex(&["models", "--json"])).unwrap();
    assert_eq!(printed, as_paths);
    let one: Value = serde_json::from_str(&vtex(&["models", "--json", "chaos-mosaic"])).unwrap();
    assert_eq!(Some(&one), as_paths["models"].as_array().unwrap().iter().find(|d| d["id"] == "chaos-mosaic"));

    let help = vtex(&["create", "--help"]);
    for id in vtex_synth::models::ids() {
        assert!(help.contains(id), "`vtex create --help` does not name {id}: {help}");
    }
    assert!(help.contains("vtex models"), "{help}");

    let work = tempdir();
    let images = work.path().join("examples");
    let listing = vtex(&["models", "--example-dir", images.to_str().unwrap()]);
    let commands: Vec<&str> = listing.lines().filter_map(|l| l.trim().strip_prefix("example: ")).collect();
    assert_eq!(commands.len(), served["models"].as_array().unwrap().len(), "{listing}");
    let data = work.path().join("data");
    let bin_dir = std::path::Path::new(BIN).parent().unwrap();
    for (command, doc) in commands.iter().zip(served["models"].as_array().unwrap()) {
        let out = Command::new("sh")
            .arg("-c")
            .arg(format!("{command} --data-dir {}", data.display()))
            .env("PATH", format!("{}:{}", bin_dir.display(), std::env::var("PATH").unwrap_or_default()))
            .output()
            .unwrap();
        assert!(out.status.success(), "{command}: {}", String::from_utf8_lossy(&out.stderr));
        let cli_id = String::from_utf8(out.stdout).unwrap().trim().to_string();
        let id = doc["id"].as_str().unwrap();
        let r = post_example(&c, &s, doc, &format!("{id} example")).await;
        let info: Value = r.json().await.unwrap();
        assert_eq!(info["id"], cli_id, "{id}: the CLI's example and the upload's differ");
    }
}
