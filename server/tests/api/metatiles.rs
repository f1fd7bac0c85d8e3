//! Metatiles over a real socket: a block's frames are exactly the tiles a server that never
//! made the block serves, row by row and clipped at the level's edges; one synthesis makes the
//! block, and the tile route and batches then serve its tiles from it; the response is
//! immutable with a strong ETag; bad requests are JSON errors naming the problem.

use crate::batch::frames;
use crate::support::*;

fn metatile_url(s: &Server, id: &str, level: u32, x: u32, y: u32, fmt: &str) -> String {
    s.url(&format!("/api/v1/textures/{id}/metatiles/{level}/{x}/{y}.{fmt}"))
}

async fn syntheses(c: &reqwest::Client, s: &Server) -> f64 {
    metric(&metrics(c, s).await, "vtex_syntheses_total", &[])
}

#[tokio::test]
async fn a_metatile_is_its_tiles_made_once_and_shared_with_the_tile_routes() {
    // 640² at tiles of 128: 5 × 5 tiles at level 0, metatiles of 4 × 4 tiles (512²).
    let args = ["--tile-size", "128"];
    let (dir, alone_dir) = (tempdir(), tempdir());
    let (s, alone) = (Server::start(dir.path(), &args), Server::start(alone_dir.path(), &args));
    let c = client();
    let bundle = mosaic(32, 20, 3);
    let (id, same) = (put(&c, &s, &bundle).await, put(&c, &alone, &bundle).await);
    assert_eq!(id, same);
    let info: serde_json::Value =
        c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["metatile"], 4);

    // (level, metatile x, y) → the tiles it holds, row by row.
    let blocks = [
        (0, 0, 0, (0..4).flat_map(|y| (0..4).map(move |x| (x, y))).collect::<Vec<_>>()),
        (0, 1, 0, (0..4).map(|y| (4, y)).collect()),
        (0, 1, 1, vec![(4, 4)]),
        (1, 0, 0, (0..3).flat_map(|y| (0..3).map(move |x| (x, y))).collect()),
    ];
    for fmt in ["png", "rgba"] {
        for (level, mx, my, tiles) in &blocks {
            let before = syntheses(&c, &s).await;
            let url = metatile_url(&s, &id, *level, *mx, *my, fmt);
            let (status, h, body) = get_bytes(&c, &url).await;
            assert_eq!(status, 200, "{url}");
            assert_eq!(h["content-type"], "application/x-vtex-tile-batch");
            assert_eq!(h["cache-control"], "public, max-age=31536000, immutable");
            assert_eq!(h["x-vtex-cache"], "miss");
            let etag = h["etag"].to_str().unwrap().to_string();
            assert!(etag.starts_with('"') && etag.len() == 34, "a strong ETag: {etag}");
            assert_eq!(syntheses(&c, &s).await - before, 1.0, "one synthesis for the whole block");

            let got = frames(&body);
            let at: Vec<(u32, u32)> = got.iter().map(|f| (f.x, f.y)).collect();
            assert_eq!(&at, tiles, "{url}: its tiles, row by row");
            for f in &got {
                assert_eq!((f.level, f.status, f.cache), (*level, 200, 0), "{url}: no cache state in the bytes");
                let tile = s.tile_url(&id, *level, f.x, f.y, fmt);
                let (status, th, tile_body) = get_bytes(&c, &tile).await;
                assert_eq!((status, th["x-vtex-cache"].to_str().unwrap()), (200, "hit"), "{tile}: from the metatile");
                assert!(tile_body == f.body, "{tile}: the frame is the tile's bytes");
                let lone = alone.tile_url(&id, *level, f.x, f.y, fmt);
                let (_, lh, lone_body) = get_bytes(&c, &lone).await;
                assert!(lone_body == f.body, "{tile}: the bytes of a tile made alone");
                assert_eq!(th["etag"], lh["etag"], "{tile}: the ETag of the tile made alone");
                let size = |name: &str| lh[name].to_str().unwrap().parse::<u32>().unwrap();
                assert_eq!((f.width, f.height), (size("x-vtex-width"), size("x-vtex-height")));
            }
            let list: Vec<String> = tiles.iter().map(|(x, y)| format!("{level}/{x}/{y}")).collect();
            let batch = s.url(&format!("/api/v1/textures/{id}/tiles?format={fmt}&tiles={}", list.join(",")));
            let (_, bh, batch_body) = get_bytes(&c, &batch).await;
            assert_eq!(bh["cache-control"], "public, max-age=31536000, immutable", "a batch of its tiles: all hits");
            assert!(frames(&batch_body).iter().zip(&got).all(|(b, m)| b.body == m.body && b.cache == 1));
            assert_eq!(syntheses(&c, &s).await - before, 1.0, "its tiles cost no other synthesis");

            let (status, again, body_again) = get_bytes(&c, &url).await;
            assert_eq!((status, again["x-vtex-cache"].to_str().unwrap()), (200, "hit"));
            assert_eq!(again["etag"], h["etag"]);
            assert!(body_again == body, "the same bytes");
            let r = c.get(&url).header("if-none-match", &etag).send().await.unwrap();
            assert_eq!(r.status(), 304);
        }
    }
}

#[tokio::test]
async fn bad_metatile_requests_name_the_problem() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &["--tile-size", "128"]);
    let c = client();
    let id = put(&c, &s, &mosaic(32, 20, 3)).await;
    let url = |path: &str| s.url(&format!("/api/v1/textures/{id}/metatiles/{path}"));
    let cases = [
        ("0/2/0.png", 404, "metatile 0/2/0 is outside level 0, which has 2×2 metatiles of 4×4 tiles"),
        ("9/0/0.png", 400, "level 9 does not exist"),
        ("0/0/0", 400, "has no format extension"),
        ("0/0/0.ktx2", 400, "format"),
        ("0/0/x.png", 400, "`y`"),
        ("0/0/0.png?frame=-1", 400, "frame"),
        ("0/0/0.png?size=64", 400, "size"),
    ];
    for (path, status, says) in cases {
        let msg = expect_error(&c, &url(path), status).await;
        assert!(msg.contains(says), "{path}: {msg}");
    }
}
