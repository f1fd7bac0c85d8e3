//! Protected writes over real sockets: the write token, read-only mode, DELETE, the CORS
//! policy of writes, and readiness beside liveness.

mod common;
use common::*;
use serde_json::{json, Value};

const TOKEN: &str = "s3cret-Token_42";

async fn error_of(r: reqwest::Response, status: u16) -> String {
    assert_eq!(r.status().as_u16(), status);
    assert_eq!(r.headers()["content-type"], "application/json");
    let v: Value = r.json().await.unwrap();
    v["error"].as_str().unwrap_or_else(|| panic!("no error message in {v}")).to_string()
}

fn post_bundle(c: &reqwest::Client, s: &Server, bytes: Vec<u8>) -> reqwest::RequestBuilder {
    c.post(s.url("/api/v1/textures")).header("content-type", "application/octet-stream").body(bytes)
}

#[tokio::test]
async fn writes_need_the_token_when_one_is_set() {
    let dir = tempdir();
    let s = Server::start_env(dir.path(), &[], &[("VTEX_WRITE_TOKEN", TOKEN)]);
    let c = client();
    let bundle = mosaic(32, 8, 1).to_bytes();

    let r = post_bundle(&c, &s, bundle.clone()).send().await.unwrap();
    assert!(r.headers()["www-authenticate"].to_str().unwrap().starts_with("Bearer"));
    let msg = error_of(r, 401).await;
    assert!(msg.contains("write token") && msg.contains("Bearer"), "{msg}");
    for wrong in ["Bearer nope", "Basic czNjcmV0", &format!("Bearer {TOKEN}x"), TOKEN] {
        let r = post_bundle(&c, &s, bundle.clone()).header("authorization", wrong).send().await.unwrap();
        assert!(error_of(r, 401).await.contains("wrong"), "{wrong}");
    }
    assert!(store_files(dir.path()).is_empty(), "a refused write stored something");

    let r = post_bundle(&c, &s, bundle.clone()).bearer_auth(TOKEN).send().await.unwrap();
    assert_eq!(r.status(), 201);
    let id = r.json::<Value>().await.unwrap()["id"].as_str().unwrap().to_string();
    // Reads need no token.
    let (status, _, _) = get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "png")).await;
    assert_eq!(status, 200);

    let texture = s.url(&format!("/api/v1/textures/{id}"));
    let r = c.patch(&texture).json(&json!({"name": "renamed"})).send().await.unwrap();
    error_of(r, 401).await;
    let r = c.delete(&texture).send().await.unwrap();
    error_of(r, 401).await;
    let r = c.patch(&texture).bearer_auth(TOKEN).json(&json!({"name": "renamed"})).send().await.unwrap();
    assert_eq!(r.status(), 201);
}

#[tokio::test]
async fn the_token_can_come_from_a_file() {
    let dir = tempdir();
    let file = dir.path().with_extension("token");
    std::fs::write(&file, format!("{TOKEN}\n")).unwrap();
    let s = Server::start(dir.path(), &["--write-token-file", file.to_str().unwrap()]);
    let c = client();
    let r = post_bundle(&c, &s, mosaic(32, 8, 1).to_bytes()).send().await.unwrap();
    error_of(r, 401).await;
    let r = post_bundle(&c, &s, mosaic(32, 8, 1).to_bytes()).bearer_auth(TOKEN).send().await.unwrap();
    assert_eq!(r.status(), 201);
    drop(s);
    std::fs::remove_file(&file).unwrap();
}

#[tokio::test]
async fn delete_removes_the_texture_for_good() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(32, 8, 2)).await;
    let keep = put(&c, &s, &mosaic(32, 8, 3)).await;
    let tile = s.tile_url(&id, 0, 0, 0, "png");
    assert_eq!(get_bytes(&c, &tile).await.0, 200, "the texture is loaded and its tile cached");

    let r = c.delete(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(store_files(dir.path()), vec![format!("{keep}.vtex")]);
    for path in
        ["", "/encoding", "/tiles/0/0/0.png", "/tiles?format=png&tiles=0/0/0", "/region?level=0&x=0&y=0&w=8&h=8"]
    {
        let msg = expect_error(&c, &s.url(&format!("/api/v1/textures/{id}{path}")), 404).await;
        assert!(msg.contains(&id), "{path}: {msg}");
    }
    let list: Value = c.get(s.url("/api/v1/textures")).send().await.unwrap().json().await.unwrap();
    let ids: Vec<&str> = list["textures"].as_array().unwrap().iter().map(|t| t["id"].as_str().unwrap()).collect();
    assert_eq!(ids, vec![keep.as_str()]);
    let again = c.delete(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap();
    assert!(error_of(again, 404).await.contains(&id));
    let bad = c.delete(s.url("/api/v1/textures/not-an-id")).send().await.unwrap();
    assert!(error_of(bad, 400).await.contains("invalid texture id"));
    // Deleted, then uploaded again: served again.
    assert_eq!(put(&c, &s, &mosaic(32, 8, 2)).await, id);
    assert_eq!(get_bytes(&c, &tile).await.0, 200);
}

#[tokio::test]
async fn read_only_refuses_every_write_naming_the_mode() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let id = put(&client(), &s, &mosaic(32, 8, 4)).await;
    drop(s);
    let s = Server::start_env(dir.path(), &["--read-only"], &[("VTEX_WRITE_TOKEN", TOKEN)]);
    let c = client();
    let texture = s.url(&format!("/api/v1/textures/{id}"));
    let refused = [
        post_bundle(&c, &s, mosaic(32, 8, 5).to_bytes()).bearer_auth(TOKEN),
        c.patch(&texture).bearer_auth(TOKEN).json(&json!({"name": "x"})),
        c.delete(&texture).bearer_auth(TOKEN),
    ];
    for req in refused {
        let msg = error_of(req.send().await.unwrap(), 403).await;
        assert!(msg.contains("read-only"), "{msg}");
    }
    assert_eq!(store_files(dir.path()), vec![format!("{id}.vtex")]);
    assert_eq!(get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "png")).await.0, 200);
}

#[tokio::test]
async fn cors_allows_writes_only_from_configured_origins() {
    let dir = tempdir();
    let good = "https://editor.example";
    let s = Server::start(dir.path(), &["--cors-write-origins", &format!("{good},https://other.example")]);
    let c = client();
    let preflight = |origin: &str, method: &str| {
        c.request(reqwest::Method::OPTIONS, s.url("/api/v1/textures"))
            .header("origin", origin)
            .header("access-control-request-method", method)
            .header("access-control-request-headers", "authorization, content-type")
            .send()
    };
    // A write preflight from a page of another origin is refused: the browser never writes.
    for method in ["POST", "PATCH", "DELETE"] {
        let r = preflight("https://evil.example", method).await.unwrap();
        let allowed = r.headers().get("access-control-allow-methods").map(|v| v.to_str().unwrap().to_string());
        assert!(allowed.as_ref().is_none_or(|m| !m.contains(method)), "{method}: {allowed:?}");
        assert!(error_of(r, 403).await.contains("https://evil.example"));
    }
    let r = preflight(good, "POST").await.unwrap();
    assert_eq!(r.status(), 204);
    assert_eq!(r.headers()["access-control-allow-origin"], good);
    assert!(r.headers()["access-control-allow-methods"].to_str().unwrap().contains("POST"));
    assert!(r.headers()["access-control-allow-headers"].to_str().unwrap().contains("authorization"));
    // Reads stay open to every origin.
    let r = preflight("https://evil.example", "GET").await.unwrap();
    assert!(r.status().is_success());
    assert_eq!(r.headers()["access-control-allow-origin"], "*");

    // A write sent without a preflight (a form POST) from another origin is refused too;
    // from a configured origin, the server's own pages or a client without Origin it passes.
    let bundle = |seed| mosaic(32, 8, seed).to_bytes();
    let r = post_bundle(&c, &s, bundle(6)).header("origin", "https://evil.example").send().await.unwrap();
    assert!(error_of(r, 403).await.contains("--cors-write-origins"));
    assert!(store_files(dir.path()).is_empty());
    let own = format!("http://{}", s.addr);
    for (seed, origin) in [(6, Some(good)), (7, Some(own.as_str())), (8, None)] {
        let mut req = post_bundle(&c, &s, bundle(seed));
        if let Some(origin) = origin {
            req = req.header("origin", origin);
        }
        assert_eq!(req.send().await.unwrap().status(), 201, "{origin:?}");
    }
}

#[tokio::test]
async fn without_configured_origins_no_cross_origin_write_is_allowed() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let r = c
        .request(reqwest::Method::OPTIONS, s.url("/api/v1/textures"))
        .header("origin", "https://anywhere.example")
        .header("access-control-request-method", "POST")
        .send()
        .await
        .unwrap();
    error_of(r, 403).await;
    let r = post_bundle(&c, &s, mosaic(32, 8, 9).to_bytes()).header("origin", "null").send().await.unwrap();
    error_of(r, 403).await;
}

#[tokio::test]
async fn readiness_follows_the_data_directory_and_liveness_does_not() {
    let dir = tempdir();
    let data = dir.path().join("data");
    let s = Server::start(&data, &[]);
    let c = client();
    put(&c, &s, &mosaic(32, 8, 10)).await;
    let ready: Value = c.get(s.url("/readyz")).send().await.unwrap().json().await.unwrap();
    assert_eq!(ready, json!({"status": "ready", "textures": 1}));
    std::fs::rename(&data, dir.path().join("moved")).unwrap();
    let msg = error_of(c.get(s.url("/readyz")).send().await.unwrap(), 503).await;
    assert!(msg.contains("data directory"), "{msg}");
    assert_eq!(c.get(s.url("/healthz")).send().await.unwrap().status(), 200, "alive all the same");
    std::fs::rename(dir.path().join("moved"), &data).unwrap();
    assert_eq!(c.get(s.url("/readyz")).send().await.unwrap().status(), 200);
}
