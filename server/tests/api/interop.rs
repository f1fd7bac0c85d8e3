//! The ecosystem's addressing over the same tiles: Deep Zoom and IIIF Image API 3 (the
//! official IIIF validator runs in `tests/iiif/validate.py`; OpenSeadragon in
//! `tests/browser/interop.test.mjs`).

use crate::support::*;
use serde_json::Value;

fn decode(bytes: &[u8]) -> image::RgbaImage {
    image::load_from_memory(bytes).unwrap().into_rgba8()
}

/// A region of the tile API at `level`, `[x, y, w, h]`, decoded.
async fn region(c: &reqwest::Client, s: &Server, id: &str, level: u32, [x, y, w, h]: [i64; 4]) -> image::RgbaImage {
    let url = s.url(&format!("/api/v1/textures/{id}/region?level={level}&x={x}&y={y}&w={w}&h={h}&format=png"));
    let (st, _, body) = get_bytes(c, &url).await;
    assert_eq!(st, 200, "{url}");
    decode(&body)
}

#[tokio::test]
async fn deep_zoom_descriptor_and_tiles() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 16, 1)).await; // 1024², levels 0..=10 down to 1 × 1

    let (st, h, xml) = get_bytes(&c, &s.url(&format!("/dzi/{id}.dzi"))).await;
    assert_eq!(st, 200);
    assert_eq!(h["content-type"], "application/xml");
    let xml = String::from_utf8(xml).unwrap();
    for part in ["Format=\"png\"", "Overlap=\"0\"", "TileSize=\"256\"", "<Size Width=\"1024\" Height=\"1024\"/>"] {
        assert!(xml.contains(part), "{part} in {xml}");
    }
    let xml = String::from_utf8(get_bytes(&c, &s.url(&format!("/dzi/{id}.dzi?overlap=1&format=jpg"))).await.2).unwrap();
    assert!(xml.contains("Overlap=\"1\"") && xml.contains("Format=\"jpg\""), "{xml}");

    // Without overlap, Deep Zoom level 10 − L is the tile API's level L: the same bytes and ETag.
    for (dz, level, x, y, fmt) in [(10, 0, 1, 2, "png"), (9, 1, 1, 0, "webp"), (8, 2, 0, 0, "jpg")] {
        let (st, dh, dzi) = get_bytes(&c, &s.url(&format!("/dzi/{id}_files/{dz}/{x}_{y}.{fmt}"))).await;
        assert_eq!(st, 200);
        let (_, th, tile) = get_bytes(&c, &s.tile_url(&id, level, x, y, fmt)).await;
        assert_eq!(dzi, tile, "Deep Zoom {dz}/{x}_{y} is tile {level}/{x}/{y}");
        assert_eq!(dh["etag"], th["etag"]);
    }
    // Levels coarser than the tile pyramid, down to 1 × 1, are the texture's own mip levels.
    for dz in [0, 1, 5] {
        let (st, _, body) = get_bytes(&c, &s.url(&format!("/dzi/{id}_files/{dz}/0_0.png"))).await;
        assert_eq!(st, 200);
        let side = 1 << dz;
        assert_eq!(decode(&body), region(&c, &s, &id, 10 - dz, [0, 0, side, side]).await, "Deep Zoom level {dz}");
    }
    // With overlap, a tile reaches `overlap` pixels into each neighbour that exists.
    let url = |x: u32, y: u32| s.url(&format!("/dzi/{id}_files/10/{x}_{y}.png?overlap=1"));
    let (_, _, inner) = get_bytes(&c, &url(1, 2)).await;
    assert_eq!(decode(&inner), region(&c, &s, &id, 0, [255, 511, 258, 258]).await);
    let (_, _, corner) = get_bytes(&c, &url(3, 3)).await;
    assert_eq!(decode(&corner), region(&c, &s, &id, 0, [767, 767, 257, 257]).await);
    let (_, _, first) = get_bytes(&c, &url(0, 0)).await;
    assert_eq!(decode(&first), region(&c, &s, &id, 0, [0, 0, 257, 257]).await);

    for (path, status, words) in [
        (format!("/dzi/{id}_files/11/0_0.png"), 404, "level 11 does not exist"),
        (format!("/dzi/{id}_files/10/4_0.png"), 404, "outside Deep Zoom level 10"),
        (format!("/dzi/{id}_files/10/0_0.png?overlap=33"), 400, "at most 32"),
        (format!("/dzi/{id}_files/10/0_0.png?format=jpg"), 400, "differs"),
        (format!("/dzi/{id}_files/10/0-0.png"), 400, "{x}_{y}"),
        (format!("/dzi/{id}_files/10/0_0.gif"), 400, "unknown format"),
        (format!("/dzi/{id}.dzi?format=rgba"), 400, "images"),
        (format!("/dzi/{id}.xml"), 404, "descriptor"),
        (format!("/dzi/{}.dzi", "0".repeat(64)), 404, "no texture"),
        (format!("/dzi/{id}.dzi?zoom=1"), 400, "unknown query parameter"),
    ] {
        let msg = expect_error(&c, &s.url(&path), status).await;
        assert!(msg.contains(words), "{path}: {msg}");
    }
}

#[tokio::test]
async fn iiif_info_and_tiles_are_the_tile_api() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 16, 1)).await;
    let base = s.url(&format!("/iiif/3/{id}"));

    let info: Value = c.get(format!("{base}/info.json")).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["id"], base);
    assert_eq!(info["type"], "ImageService3");
    assert_eq!(info["profile"], "level2");
    assert_eq!((info["width"].as_u64(), info["height"].as_u64()), (Some(1024), Some(1024)));
    assert_eq!(info["tiles"][0]["width"], 256);
    assert_eq!(info["tiles"][0]["scaleFactors"], serde_json::json!([1, 2, 4]));
    let ld = c.get(format!("{base}/info.json")).header("accept", "application/ld+json").send().await.unwrap();
    assert!(ld.headers()["content-type"].to_str().unwrap().starts_with("application/ld+json"));

    let r = reqwest::Client::builder().redirect(reqwest::redirect::Policy::none()).build().unwrap();
    let redirect = r.get(&base).send().await.unwrap();
    assert_eq!(redirect.status(), 303);
    assert_eq!(redirect.headers()["location"], format!("{base}/info.json"));

    // What a tiled client asks for: a tile's region at its scale is that tile, bytes and ETag.
    for (path, level, x, y, fmt) in [
        ("256,512,256,256/256,256/0/default.png", 0, 1, 2, "png"),
        ("512,0,512,512/256,/0/color.jpg", 1, 1, 0, "jpg"),
        ("full/256,256/0/default.webp", 2, 0, 0, "webp"),
        ("768,768,256,256/max/0/default.png", 0, 3, 3, "png"),
    ] {
        let (st, ih, img) = get_bytes(&c, &format!("{base}/{path}")).await;
        assert_eq!(st, 200, "{path}");
        let (_, th, tile) = get_bytes(&c, &s.tile_url(&id, level, x, y, fmt)).await;
        assert_eq!(img, tile, "{path} is tile {level}/{x}/{y}");
        assert_eq!(ih["etag"], th["etag"]);
        let link = ih["link"].to_str().unwrap();
        assert!(link.contains("rel=\"profile\"") && link.contains("rel=\"canonical\""), "{link}");
    }

    // Anything else is rendered: a region between levels, resampled from the finer one.
    let (st, _, body) = get_bytes(&c, &format!("{base}/100,200,300,150/200,/0/default.png")).await;
    assert_eq!(st, 200);
    assert_eq!(decode(&body).dimensions(), (200, 100));
    // Rotation and mirroring move pixels; gray makes channels equal.
    let plain = decode(&get_bytes(&c, &format!("{base}/0,0,64,32/max/0/default.png")).await.2);
    let turned = decode(&get_bytes(&c, &format!("{base}/0,0,64,32/max/90/default.png")).await.2);
    let mirrored = decode(&get_bytes(&c, &format!("{base}/0,0,64,32/max/!0/default.png")).await.2);
    let gray = decode(&get_bytes(&c, &format!("{base}/0,0,64,32/max/0/gray.png")).await.2);
    assert_eq!(turned.dimensions(), (32, 64));
    for (x, y) in [(0, 0), (63, 0), (10, 20), (63, 31)] {
        assert_eq!(turned.get_pixel(31 - y, x), plain.get_pixel(x, y), "turned ({x}, {y})");
        assert_eq!(mirrored.get_pixel(63 - x, y), plain.get_pixel(x, y), "mirrored ({x}, {y})");
        let g = gray.get_pixel(x, y);
        assert!(g[0] == g[1] && g[1] == g[2], "gray ({x}, {y}): {g:?}");
    }

    for (path, status, words) in [
        (format!("{base}/full/max/45/default.png"), 400, "a multiple of 90"),
        (format!("{base}/full/max/0/sepia.png"), 400, "quality"),
        (format!("{base}/full/max/0/default.gif"), 400, "png, jpg or webp"),
        (format!("{base}/full/full/0/default.png"), 400, "size"),
        (format!("{base}/full/2048,/0/default.png"), 400, "upscaling needs the ^ prefix"),
        (format!("{base}/5000,0,10,10/max/0/default.png"), 400, "outside the image"),
        (format!("{base}/full/max/0/default.png?x=1"), 400, "unknown query parameter"),
        (s.url(&format!("/iiif/3/{}/info.json", "0".repeat(64))), 404, "no image"),
        (s.url(&format!("/iiif/3/{id};x/info.json")), 404, "no image"),
        (s.url("/iiif/3/a/b/full/max/0/default.jpg"), 404, "no IIIF image"),
    ] {
        let msg = expect_error(&c, &path, status).await;
        assert!(msg.contains(words), "{path}: {msg}");
    }
}

#[tokio::test]
async fn iiif_work_is_bounded_by_the_output() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--max-region-pixels", "1048576"]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 1563, 1)).await; // 100,032²
    let base = s.url(&format!("/iiif/3/{id}"));
    let info: Value = c.get(format!("{base}/info.json")).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["maxArea"], 1048576);
    // `max` of the whole 100k texture is confined to maxArea, rendered from a coarse level.
    let (st, _, body) = get_bytes(&c, &format!("{base}/full/max/0/default.png")).await;
    assert_eq!(st, 200);
    assert_eq!(decode(&body).dimensions(), (1024, 1024));
    // A view stretched far in one direction reads a coarser level instead of a huge rectangle.
    let (st, _, body) = get_bytes(&c, &format!("{base}/0,0,100000,16/1000,16/0/default.png")).await;
    assert_eq!(st, 200);
    assert_eq!(decode(&body).dimensions(), (1000, 16));
    for size in ["^20000,", "^2048,2048", "pct:5", "100000,1"] {
        let msg = expect_error(&c, &format!("{base}/full/{size}/0/default.png"), 400).await;
        assert!(msg.contains("maxArea") || msg.contains("limits"), "{size}: {msg}");
    }
}

#[tokio::test]
async fn iiif_and_deep_zoom_serve_animation_frames() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let animated = vtex_synth::models::demos()
        .into_iter()
        .find(|b| vtex_synth::models::plan(b).unwrap().animation.is_some_and(|a| a.period_frames != 1))
        .expect("a demo is animated");
    let id = put(&c, &s, &animated).await;
    let (_, _, f0) = get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "png")).await;
    let (_, _, f3) = get_bytes(&c, &format!("{}?frame=3", s.tile_url(&id, 0, 0, 0, "png"))).await;
    assert_ne!(f0, f3, "the demo moves between frames 0 and 3");
    let iiif = |ident: &str| s.url(&format!("/iiif/3/{ident}/0,0,256,256/256,256/0/default.png"));
    assert_eq!(get_bytes(&c, &iiif(&format!("{id};3"))).await.2, f3);
    assert_eq!(get_bytes(&c, &iiif(&id)).await.2, f0);
    let info: Value = c.get(s.url(&format!("/iiif/3/{id};3/info.json"))).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["id"], s.url(&format!("/iiif/3/{id}%3B3")), "the service's id names its frame");
    let info: Value = c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
    let (w, h) = (info["width"].as_u64().unwrap(), info["height"].as_u64().unwrap());
    let top = vtex_synth::texture::level_count(w, h) - 1;
    let dz = get_bytes(&c, &s.url(&format!("/dzi/{id}_files/{top}/0_0.png?frame=3"))).await.2;
    assert_eq!(dz, f3);
}

#[tokio::test]
async fn tilejson_and_xyz_tiles() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &mosaic(64, 16, 1)).await; // 1024²: levels 0..=2, so zooms 0..=2
    let tj: Value =
        c.get(s.url(&format!("/api/v1/textures/{id}/tilejson.json"))).send().await.unwrap().json().await.unwrap();
    assert_eq!(tj["tilejson"], "3.0.0");
    assert_eq!(tj["scheme"], "xyz");
    assert_eq!(tj["tiles"][0], s.url(&format!("/api/v1/textures/{id}/xyz/{{z}}/{{x}}/{{y}}.png")));
    assert_eq!((tj["minzoom"].as_u64(), tj["maxzoom"].as_u64()), (Some(0), Some(2)));
    assert_eq!(tj["tileSize"], 256, "MapLibre reads `tileSize` and assumes 512 without it");
    let bounds: Vec<f64> = tj["bounds"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    // 1024 texels are the whole 4 × 256 px world at zoom 2.
    for (got, want) in bounds.iter().zip([-180.0, -85.0511287798066, 180.0, 85.0511287798066]) {
        assert!((got - want).abs() < 1e-9, "{bounds:?}");
    }
    let tj: Value = c
        .get(s.url(&format!("/api/v1/textures/{id}/tilejson.json?format=webp&frame=3")))
        .send()
        .await
        .unwrap()
        .json()
        .await
        .unwrap();
    assert!(tj["tiles"][0].as_str().unwrap().ends_with("{y}.webp?frame=3"), "{tj}");

    for (z, x, y, level, fmt) in [(0, 0, 0, 2, "png"), (1, 1, 0, 1, "webp"), (2, 3, 1, 0, "jpg")] {
        let (st, xh, xyz) = get_bytes(&c, &s.url(&format!("/api/v1/textures/{id}/xyz/{z}/{x}/{y}.{fmt}"))).await;
        assert_eq!(st, 200);
        let (_, th, tile) = get_bytes(&c, &s.tile_url(&id, level, x, y, fmt)).await;
        assert_eq!(xyz, tile, "XYZ {z}/{x}/{y} is tile {level}/{x}/{y}");
        assert_eq!(xh["etag"], th["etag"]);
    }
    for (path, status, words) in [
        (format!("/api/v1/textures/{id}/xyz/3/0/0.png"), 404, "zooms 0..=2"),
        (format!("/api/v1/textures/{id}/xyz/2/4/0.png"), 404, "outside the texture"),
        (format!("/api/v1/textures/{id}/xyz/0/0/0.gif"), 400, "unknown format"),
        (format!("/api/v1/textures/{id}/xyz/0/0/0.png?zoom=1"), 400, "unknown query parameter"),
        (format!("/api/v1/textures/{id}/tilejson.json?format=rgba"), 400, "images"),
        (format!("/api/v1/textures/{}/tilejson.json", "0".repeat(64)), 404, "no texture"),
    ] {
        let msg = expect_error(&c, &s.url(&path), status).await;
        assert!(msg.contains(words), "{path}: {msg}");
    }
}

/// Web Mercator's y of latitude `lat` (degrees): 0 at the world's top, 1 at its bottom, as map
/// clients compute it.
fn mercator_y(lat: f64) -> f64 {
    let phi = lat.to_radians();
    (1.0 - (phi.tan() + 1.0 / phi.cos()).ln() / std::f64::consts::PI) / 2.0
}

/// Mean absolute difference of `img`'s colour channels from `truth`'s, over `truth`'s extent.
fn mean_error(img: &image::RgbaImage, truth: &image::RgbaImage) -> f64 {
    let sum: u64 = truth
        .enumerate_pixels()
        .map(|(x, y, t)| (0..3).map(|c| img.get_pixel(x, y)[c].abs_diff(t[c]) as u64).sum::<u64>())
        .sum();
    sum as f64 / (3 * truth.width() * truth.height()) as f64
}

#[tokio::test]
async fn xyz_edge_tiles_are_whole_squares_transparent_beyond_the_texture() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    // 1000 × 450 texels: neither square nor a power of two. Zooms 0..=2; at zoom 2 the world is
    // 4 × 256 = 1024 texels across, and the texture its north-west 1000 × 450.
    let sample = vtex_synth::samples::pebbles(50, 12, 3, true).to_png();
    let inputs = vtex_synth::models::Inputs::from([("sample".to_string(), sample)]);
    let params = serde_json::json!({"tiles_x": 20, "tiles_y": 9, "iterations": 10, "seed": 3});
    let id = put(&c, &s, &vtex_synth::models::create("chaos-mosaic", "1000 × 450", &params, &inputs).unwrap()).await;
    let tj: Value =
        c.get(s.url(&format!("/api/v1/textures/{id}/tilejson.json"))).send().await.unwrap().json().await.unwrap();
    assert_eq!((tj["maxzoom"].as_u64(), tj["tileSize"].as_u64()), (Some(2), Some(256)), "{tj}");
    assert_eq!(tj["attribution"], "synthesized by vtex (chaos-mosaic model)");
    let b: Vec<f64> = tj["bounds"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let world = 1024.0;
    let (west, east) = ((b[0] + 180.0) / 360.0 * world, (b[2] + 180.0) / 360.0 * world);
    let (north, south) = (mercator_y(b[3]) * world, mercator_y(b[1]) * world);
    for (got, want) in [(west, 0.0), (north, 0.0), (east, 1000.0), (south, 450.0)] {
        assert!((got - want).abs() < 1e-6, "bounds {b:?} end at texel {got}, not {want}");
    }
    // TileJSON 3.0.0 §3.6: the centre inside the bounds, its zoom an integer within the zooms.
    let ctr: Vec<f64> = tj["center"].as_array().unwrap().iter().map(|v| v.as_f64().unwrap()).collect();
    let inside = b[0] <= ctr[0] && ctr[0] <= b[2] && b[1] <= ctr[1] && ctr[1] <= b[3];
    assert!(inside && ctr[2].fract() == 0.0 && (0.0..=2.0).contains(&ctr[2]), "{tj}");

    // Every tile the texture's edge cuts, against the tile API's clipped tile of its level.
    for (z, x, y) in [(0, 0, 0), (1, 1, 0), (2, 3, 0), (2, 0, 1), (2, 3, 1)] {
        let level = 2 - z;
        let (_, th, tile) = get_bytes(&c, &s.tile_url(&id, level, x, y, "png")).await;
        let tile = decode(&tile);
        for fmt in ["png", "webp", "jpg"] {
            let url = s.url(&format!("/api/v1/textures/{id}/xyz/{z}/{x}/{y}.{fmt}"));
            let (st, h, body) = get_bytes(&c, &url).await;
            assert_eq!(st, 200, "{url}");
            let img = decode(&body);
            assert_eq!(img.dimensions(), (256, 256), "{url}: clients stretch every tile to a square");
            assert!(h["x-vtex-width"] == "256" && h["x-vtex-height"] == "256", "{url}");
            assert_eq!(h["cache-control"], th["cache-control"], "{url}");
            assert_ne!(h["etag"], th["etag"], "{url}: not the clipped tile's bytes");
            let (_, again, same) = get_bytes(&c, &url).await;
            assert_eq!((&again["etag"], &same), (&h["etag"], &body), "{url}: the same bytes every time");
            let r = c.get(&url).header("if-none-match", h["etag"].clone()).send().await.unwrap();
            assert_eq!(r.status(), 304, "{url}");
            // JPEG has no alpha, so black beyond the texture; and it is lossy, so its pixels are
            // checked against the tile API's own JPEG of the tile: no worse for the padding.
            let mut darkest = 0u8;
            for (px, py, p) in img.enumerate_pixels() {
                let texel = (px < tile.width() && py < tile.height()).then(|| tile.get_pixel(px, py).0);
                match (fmt, texel) {
                    ("jpg", Some(_)) => {}
                    ("jpg", None) => darkest = darkest.max(p[0].max(p[1]).max(p[2])),
                    (_, Some(t)) => assert_eq!(p.0, t, "{url}: pixel ({px}, {py})"),
                    (_, None) => assert_eq!(p.0, [0; 4], "{url}: pixel ({px}, {py}) beyond the texture"),
                }
            }
            if fmt == "jpg" {
                assert!(darkest <= 24, "{url}: beyond the texture, a channel is {darkest}, not black");
                let own = decode(&get_bytes(&c, &s.tile_url(&id, level, x, y, "jpg")).await.2);
                let (xyz_error, own_error) = (mean_error(&img, &tile), mean_error(&own, &tile));
                assert!(
                    xyz_error <= 1.25 * own_error,
                    "{url}: mean error {xyz_error}, the tile API's JPEG {own_error}"
                );
            }
        }
    }
}
