//! IIIF over real HTTP, rule by rule of the specifications' text: Image API 3 statuses, sizes,
//! `Link` headers and the content negotiation of `info.json`; the Presentation 3 Manifest and
//! Collection. (The size arithmetic is tabled in `server/src/api/iiif.rs`; the official
//! validator runs in `tests/iiif/validate.py`, Mirador in `tests/browser/iiif.test.mjs`.)

use crate::support::*;
use serde_json::Value;

const IMAGE_LD: &str = "application/ld+json;profile=\"http://iiif.io/api/image/3/context.json\"";
const PRESENTATION_LD: &str = "application/ld+json;profile=\"http://iiif.io/api/presentation/3/context.json\"";

fn dimensions(bytes: &[u8]) -> (u32, u32) {
    let img = image::load_from_memory(bytes).unwrap();
    (img.width(), img.height())
}

/// The value of header `name` in a raw HTTP/1.1 response.
fn raw_header<'a>(response: &'a str, name: &str) -> Option<&'a str> {
    response
        .lines()
        .find_map(|l| l.split_once(':').filter(|(n, _)| n.eq_ignore_ascii_case(name)).map(|(_, v)| v.trim()))
}

#[tokio::test]
async fn image_requests_answer_as_the_specification_says() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--max-region-pixels", "1048576"]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 16, 1)).await; // 1024²
    let base = s.url(&format!("/iiif/3/{id}"));

    // §4.2, each size form against a region larger than, equal to and smaller than the size:
    // the image's dimensions, the canonical `Link` (§4.8) and the profile `Link` (§6).
    for (path, size, canonical) in [
        // `!w,h`: "as large as possible but not larger than the extracted region, w or h".
        ("0,0,100,100/!200,200/0/default.png", (100, 100), "0,0,100,100/max/0/default.png"),
        ("0,0,400,200/!200,200/0/default.png", (200, 100), "0,0,400,200/200,100/0/default.png"),
        ("0,0,200,200/!200,200/0/default.png", (200, 200), "0,0,200,200/max/0/default.png"),
        // `^!w,h`: "not larger than w, h, or server-imposed limits".
        ("0,0,100,100/^!200,200/0/default.png", (200, 200), "0,0,100,100/^200,200/0/default.png"),
        // `max`: the region's own size; `^max`: the largest maxArea allows.
        ("full/max/0/default.png", (1024, 1024), "full/max/0/default.png"),
        ("0,0,100,50/^max/0/default.png", (1448, 724), "0,0,100,50/^max/0/default.png"),
        // `w,`, `,h`, `pct:n`, `w,h` within the region; their `^` forms beyond it.
        ("0,0,400,200/200,/0/default.png", (200, 100), "0,0,400,200/200,100/0/default.png"),
        ("0,0,400,200/,50/0/color.png", (100, 50), "0,0,400,200/100,50/0/default.png"),
        ("0,0,400,200/pct:25/0/default.png", (100, 50), "0,0,400,200/100,50/0/default.png"),
        ("0,0,400,200/400,10/0/default.png", (400, 10), "0,0,400,200/400,10/0/default.png"),
        ("0,0,100,100/^200,/0/default.png", (200, 200), "0,0,100,100/^200,200/0/default.png"),
        ("0,0,100,100/^,150/0/default.png", (150, 150), "0,0,100,100/^150,150/0/default.png"),
        ("0,0,100,100/^pct:150/0/default.png", (150, 150), "0,0,100,100/^150,150/0/default.png"),
        ("0,0,100,100/^300,20/0/default.png", (300, 20), "0,0,100,100/^300,20/0/default.png"),
        // Cropped at the image's edge (§4.1), then `max`.
        ("1000,1000,100,100/max/90/default.png", (24, 24), "1000,1000,24,24/max/90/default.png"),
    ] {
        let (st, h, body) = get_bytes(&c, &format!("{base}/{path}")).await;
        assert_eq!(st, 200, "{path}: {}", String::from_utf8_lossy(&body));
        assert_eq!(dimensions(&body), size, "{path}");
        let link = h["link"].to_str().unwrap();
        assert!(link.contains(&format!("<{base}/{canonical}>;rel=\"canonical\"")), "{path}: {link}");
        assert!(link.contains("<http://iiif.io/api/image/3/level2.json>;rel=\"profile\""), "{path}: {link}");
    }

    // Errors, each with a JSON message naming the problem: 400 for what cannot be served
    // (§4.2 sizes over the region without `^`, under a pixel or over the limits; §4.3 an
    // unsupported rotation; §4.4, §4.5 quality and format; §4.1 a region outside).
    for (path, words) in [
        ("0,0,100,100/200,/0/default.png", "upscaling needs the ^ prefix"),
        ("0,0,100,100/,101/0/default.png", "upscaling needs the ^ prefix"),
        ("0,0,100,100/pct:101/0/default.png", "upscaling needs the ^ prefix"),
        ("0,0,100,100/100,101/0/default.png", "upscaling needs the ^ prefix"),
        ("0,0,1000,10/10,/0/default.png", "under one pixel"),
        ("full/^2048,2048/0/default.png", "maxArea"),
        ("full/max/22.5/default.png", "rotation"),
        ("full/max/361/default.png", "rotation"),
        ("full/max/0/sepia.png", "quality"),
        ("full/max/0/default.gif", "png, jpg or webp"),
        ("1024,0,10,10/max/0/default.png", "outside the image"),
        ("0,0,0,10/max/0/default.png", "zero width"),
    ] {
        let msg = expect_error(&c, &format!("{base}/{path}"), 400).await;
        assert!(msg.contains(words), "{path}: {msg}");
    }
}

#[tokio::test]
async fn image_information_is_negotiated_json_ld() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 4, 1)).await;
    let path = format!("/iiif/3/{id}/info.json");

    // §5.1: "If the request does not include an Accept header", JSON-LD with the context as
    // its profile. (reqwest always sends one, so this request is written by hand.)
    let raw = raw_request(
        &s.addr,
        format!("GET {path} HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n", s.addr).as_bytes(),
    );
    assert!(raw.starts_with("HTTP/1.1 200"), "{raw}");
    assert_eq!(raw_header(&raw, "content-type"), Some(IMAGE_LD), "{raw}");
    // §6: the profile `Link` "on both Image and Image Information responses".
    assert_eq!(raw_header(&raw, "link"), Some("<http://iiif.io/api/image/3/level2.json>;rel=\"profile\""));

    // "If the server receives a request with an Accept header, it SHOULD respond following the
    // rules of content negotiation"; the answer varies with it.
    for (accept, expected) in [
        ("*/*", IMAGE_LD),
        ("application/ld+json", IMAGE_LD),
        (IMAGE_LD, IMAGE_LD),
        ("application/json", "application/json"),
        ("application/ld+json;q=0.5, application/json", "application/json"),
        (
            "application/ld+json;profile=\"http://iiif.io/api/image/2/context.json\", application/json;q=0.1",
            "application/json",
        ),
    ] {
        let r = c.get(s.url(&path)).header("accept", accept).send().await.unwrap();
        assert_eq!(r.status(), 200, "{accept}");
        assert_eq!(r.headers()["content-type"], expected, "{accept}");
        assert!(r.headers().get_all("vary").iter().any(|v| v
            .to_str()
            .unwrap()
            .to_ascii_lowercase()
            .contains("accept")));
        let info: Value = r.json().await.unwrap();
        assert_eq!(info["@context"], "http://iiif.io/api/image/3/context.json");
    }
    let r = c.get(s.url(&path)).header("accept", "text/html").send().await.unwrap();
    assert_eq!(r.status(), 406);
    let body: Value = r.json().await.unwrap();
    assert!(body["error"].as_str().unwrap().contains("text/html"), "{body}");
}

#[tokio::test]
async fn presentation_manifest_and_collection() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let a = put(&c, &s, &mosaic(64, 4, 1)).await; // 256²
    let b = put(&c, &s, &mosaic(32, 5, 2)).await; // 160²

    let manifest_url = s.url(&format!("/iiif/presentation/3/{a}/manifest.json"));
    let r = c.get(&manifest_url).send().await.unwrap();
    assert_eq!(r.status(), 200);
    assert_eq!(r.headers()["content-type"], PRESENTATION_LD);
    let m: Value = r.json().await.unwrap();
    // §5.2: the Manifest's id dereferences to it; §3.1 a label; §5.3 one Canvas with a size.
    assert_eq!(m["@context"], "http://iiif.io/api/presentation/3/context.json");
    assert_eq!((m["type"].as_str(), m["id"].as_str()), (Some("Manifest"), Some(manifest_url.as_str())));
    assert_eq!(m["label"], serde_json::json!({"none": ["test mosaic 64×4 #1"]}));
    let canvases = m["items"].as_array().unwrap();
    assert_eq!(canvases.len(), 1);
    let canvas = &canvases[0];
    assert_eq!(canvas["type"], "Canvas");
    assert_eq!((canvas["width"].as_u64(), canvas["height"].as_u64()), (Some(256), Some(256)));
    // §5.5, §5.6: one AnnotationPage of one painting Annotation targeting the Canvas, whose body
    // (§5.7) is an Image with its Image API 3 service.
    let page = &canvas["items"][0];
    assert_eq!(page["type"], "AnnotationPage");
    let anno = &page["items"][0];
    assert_eq!((anno["type"].as_str(), anno["motivation"].as_str()), (Some("Annotation"), Some("painting")));
    assert_eq!(anno["target"], canvas["id"]);
    let body = &anno["body"];
    assert_eq!((body["type"].as_str(), body["format"].as_str()), (Some("Image"), Some("image/png")));
    let service = &body["service"][0];
    assert_eq!((service["type"].as_str(), service["profile"].as_str()), (Some("ImageService3"), Some("level2")));
    let service_id = service["id"].as_str().unwrap();
    let info: Value = c.get(format!("{service_id}/info.json")).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["id"], service_id, "the service's info.json names the same service");
    // The body's id is "a complete URI to any particular representation supported by the Image
    // Service ... MUST NOT be just the URI of the IIIF Image service": it answers an image.
    let body_id = body["id"].as_str().unwrap();
    assert!(body_id.starts_with(&format!("{service_id}/")));
    let (st, _, image) = get_bytes(&c, body_id).await;
    assert_eq!((st, dimensions(&image)), (200, (256, 256)));
    let (st, _, thumb) = get_bytes(&c, m["thumbnail"][0]["id"].as_str().unwrap()).await;
    assert_eq!((st, dimensions(&thumb)), (200, (256, 256)));

    // §5.1: a Collection whose items are each Manifest's id, type and label.
    let collection_url = s.url("/iiif/presentation/3/collection.json");
    let col: Value = c.get(&collection_url).send().await.unwrap().json().await.unwrap();
    assert_eq!((col["type"].as_str(), col["id"].as_str()), (Some("Collection"), Some(collection_url.as_str())));
    let items = col["items"].as_array().unwrap();
    assert_eq!(items.len(), 2);
    // By name: "test mosaic 32×5 #2" first.
    for (item, id) in items.iter().zip([&b, &a]) {
        assert_eq!(item["type"], "Manifest");
        let url = item["id"].as_str().unwrap();
        let m: Value = c.get(url).send().await.unwrap().json().await.unwrap();
        assert_eq!(m["id"], url);
        assert_eq!(item["label"], m["label"]);
        assert!(url.contains(id.as_str()));
    }

    // §6.3: negotiated like info.json.
    let r = c.get(&manifest_url).header("accept", "application/json").send().await.unwrap();
    assert_eq!(r.headers()["content-type"], "application/json");
    let raw = raw_request(
        &s.addr,
        format!("GET /iiif/presentation/3/collection.json HTTP/1.1\r\nHost: {}\r\nConnection: close\r\n\r\n", s.addr)
            .as_bytes(),
    );
    assert_eq!(raw_header(&raw, "content-type"), Some(PRESENTATION_LD), "{raw}");

    for (path, status, words) in [
        (format!("/iiif/presentation/3/{}/manifest.json", "0".repeat(64)), 404, "no texture"),
        ("/iiif/presentation/3/nope/manifest.json".to_string(), 400, "invalid texture id"),
        (format!("/iiif/presentation/3/{a}/manifest.json?x=1"), 400, "unknown query parameter"),
        ("/iiif/presentation/3/nope.json".to_string(), 404, "no IIIF image or service"),
    ] {
        let msg = expect_error(&c, &s.url(&path), status).await;
        assert!(msg.contains(words), "{path}: {msg}");
    }
}
