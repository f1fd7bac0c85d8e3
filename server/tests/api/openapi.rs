//! The OpenAPI description (`GET /api/v1/openapi.json`) is valid OpenAPI 3 and complete
//! against the route table: every route of the table is described, every path described
//! answers on a live server with the demo textures, and every method a path does not describe
//! is a 405.

use crate::support::*;
use serde_json::Value;
use std::path::PathBuf;

const METHODS: [&str; 5] = ["get", "post", "put", "patch", "delete"];

async fn document(c: &reqwest::Client, s: &Server) -> Value {
    let r = c.get(s.url("/api/v1/openapi.json")).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], "application/json");
    r.json().await.unwrap()
}

/// The Python of the venv `scripts/test` installs `openapi-spec-validator` into.
fn validator_python() -> Option<PathBuf> {
    let venv = PathBuf::from(env!("CARGO_MANIFEST_DIR")).join("../target/openapi-venv/bin/python");
    venv.is_file().then_some(venv)
}

#[tokio::test]
async fn the_description_is_valid_openapi_3() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let doc = document(&c, &s).await;
    assert!(doc["openapi"].as_str().unwrap().starts_with("3."), "{}", doc["openapi"]);
    assert_eq!(doc["info"]["version"], env!("CARGO_PKG_VERSION"));
    // Every schema a response names is in the components.
    let text = doc.to_string();
    for reference in text.split("\"$ref\":\"#/components/schemas/").skip(1) {
        let name = &reference[..reference.find('"').unwrap()];
        assert!(doc["components"]["schemas"].get(name).is_some(), "dangling reference to {name}");
    }
    let Some(python) = validator_python() else {
        assert!(std::env::var_os("CI").is_none(), "CI must validate: scripts/test installs target/openapi-venv");
        eprintln!("openapi-spec-validator not installed (scripts/test installs it): validated the structure only");
        return;
    };
    let file = dir.path().join("openapi.json");
    std::fs::write(&file, &text).unwrap();
    let out = std::process::Command::new(python).args(["-m", "openapi_spec_validator"]).arg(&file).output().unwrap();
    let said = format!("{}{}", String::from_utf8_lossy(&out.stdout), String::from_utf8_lossy(&out.stderr));
    assert!(out.status.success(), "openapi-spec-validator: {said}");
    assert!(said.contains("OK"), "{said}");
}

/// A value for each path parameter, from the texture `id` (a demo with several levels).
fn fill(path: &str, id: &str) -> String {
    let file = if path.starts_with("/dzi/{dir}") {
        "0_0.png".to_string()
    } else if path.starts_with("/dzi/") {
        format!("{id}.dzi")
    } else if path.starts_with("/iiif/") {
        "default.png".to_string()
    } else if path.starts_with("/api/v1/models") {
        "sample.png".to_string()
    } else {
        "0.png".to_string()
    };
    let model = if path.starts_with("/api/v1/models") { "chaos-mosaic" } else { id };
    path.replace("{id}", model)
        .replace("{ident}", id)
        .replace("{dir}", &format!("{id}_files"))
        .replace("{level}", "0")
        .replace("{x}", "0")
        .replace("{z}", "0")
        .replace("{region}", "full")
        .replace("{size}", "max")
        .replace("{rotation}", "0")
        .replace("{file}", &file)
}

/// Required query parameters: each described one given a value.
fn query(op: &Value) -> String {
    let value = |name: &str| match name {
        "format" => "png",
        "tiles" => "0/0/0",
        "w" | "h" => "16",
        _ => "0",
    };
    let required = op["parameters"]
        .as_array()
        .into_iter()
        .flatten()
        .filter(|p| p["in"] == "query" && p["required"].as_bool().unwrap_or(false));
    let pairs: Vec<String> =
        required.map(|p| p["name"].as_str().unwrap()).map(|n| format!("{n}={}", value(n))).collect();
    if pairs.is_empty() {
        String::new()
    } else {
        format!("?{}", pairs.join("&"))
    }
}

/// Every described operation answers on a live server with the demos (not 404 or 405; writes
/// on a texture uploaded for them, deleted last), and every method a path does not describe is
/// a 405.
#[tokio::test]
async fn every_described_path_answers() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--demos"]);
    // Redirects are answers (IIIF's base URI): not followed.
    let c = reqwest::Client::builder().redirect(reqwest::redirect::Policy::none()).no_gzip().build().unwrap();
    let doc = document(&c, &s).await;
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    let id = list["textures"].as_array().unwrap()[0]["id"].as_str().unwrap().to_string();
    let own = put(&c, &s, &mosaic(32, 4, 9)).await;
    let mut deletes = Vec::new();
    for (path, item) in doc["paths"].as_object().unwrap() {
        for method in METHODS {
            let Some(op) = item.get(method) else {
                let url = s.url(&fill(path, &id));
                let r = c.request(method.to_uppercase().parse().unwrap(), &url).send().await.unwrap();
                assert_eq!(r.status(), 405, "{method} {url} is answered but not described");
                continue;
            };
            let url = s.url(&format!("{}{}", fill(path, if method == "get" { &id } else { &own }), query(op)));
            let r = match method {
                "get" => c.get(&url).send().await.unwrap(),
                "post" => c
                    .post(&url)
                    .header("content-type", "application/octet-stream")
                    .body(mosaic(32, 4, 10).to_bytes())
                    .send()
                    .await
                    .unwrap(),
                "patch" => c.patch(&url).json(&serde_json::json!({"name": "renamed"})).send().await.unwrap(),
                "delete" => {
                    deletes.push(url);
                    continue;
                }
                other => panic!("{other} {path} is described; add a request for it here"),
            };
            let status = r.status().as_u16();
            let documented: Vec<&String> = op["responses"].as_object().unwrap().keys().collect();
            assert!(status != 404 && status != 405, "{method} {url}: {status} {}", r.text().await.unwrap());
            assert!(
                documented.iter().any(|k| k.as_str() == status.to_string()),
                "{method} {url}: {status} is not among the described responses {documented:?}"
            );
        }
    }
    for url in deletes {
        let status = c.delete(&url).send().await.unwrap().status().as_u16();
        assert_eq!(status, 204, "DELETE {url}");
    }
}
