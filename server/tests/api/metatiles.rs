//! Metatiles of tiles and of bordered pages over a real socket: a block's frames are exactly
//! the tiles or pages a server that never made the block serves, row by row and clipped at the
//! grid's edges; one synthesis makes the block, and the tile or page route and batches then
//! serve its parts from it; the response is immutable with a strong ETag; bad requests are JSON
//! errors naming the problem.

use crate::batch::frames;
use crate::support::*;

async fn syntheses(c: &reqwest::Client, s: &Server) -> f64 {
    metric(&metrics(c, s).await, "vtex_syntheses_total", &[])
}

/// Two servers on one texture: `s`, whose metatiles are checked, and `alone`, which serves its
/// tiles and pages one by one.
struct Pair {
    c: reqwest::Client,
    s: Server,
    alone: Server,
    id: String,
    _dirs: [tempfile::TempDir; 2],
}

/// 640² at tiles of 128: 5 × 5 tiles at level 0, metatiles of 4 × 4 tiles (512²).
async fn pair() -> Pair {
    let args = ["--tile-size", "128"];
    let (dir, alone_dir) = (tempdir(), tempdir());
    let (s, alone) = (Server::start(dir.path(), &args), Server::start(alone_dir.path(), &args));
    let c = client();
    let bundle = mosaic(32, 20, 3);
    let (id, same) = (put(&c, &s, &bundle).await, put(&c, &alone, &bundle).await);
    assert_eq!(id, same);
    Pair { c, s, alone, id, _dirs: [dir, alone_dir] }
}

/// Metatile `path` (relative to the texture, query included) of `level` holds `parts`, row by
/// row, each exactly `part(server, x, y)` as the server that never made the block serves it,
/// and made by one synthesis that also serves the parts alone and the batch `batch(list)`.
async fn check_block(
    p: &Pair,
    path: &str,
    level: u32,
    parts: &[(u32, u32)],
    part: impl Fn(&Server, u32, u32) -> String,
    batch: impl Fn(&str) -> String,
) {
    let (c, s) = (&p.c, &p.s);
    let before = syntheses(c, s).await;
    let url = s.url(&format!("/api/v1/textures/{}/{path}", p.id));
    let (status, h, body) = get_bytes(c, &url).await;
    assert_eq!(status, 200, "{url}");
    assert_eq!(h["content-type"], "application/x-vtex-tile-batch");
    assert_eq!(h["cache-control"], "public, max-age=31536000, immutable");
    assert_eq!(h["x-vtex-cache"], "miss");
    let etag = h["etag"].to_str().unwrap().to_string();
    assert!(etag.starts_with('"') && etag.len() == 34, "a strong ETag: {etag}");
    assert_eq!(syntheses(c, s).await - before, 1.0, "one synthesis for the whole block");

    let got = frames(&body);
    let at: Vec<(u32, u32)> = got.iter().map(|f| (f.x, f.y)).collect();
    assert_eq!(at, parts, "{url}: its parts, row by row");
    for f in &got {
        assert_eq!((f.level, f.status, f.cache), (level, 200, 0), "{url}: no cache state in the bytes");
        let one = part(s, f.x, f.y);
        let (status, th, one_body) = get_bytes(c, &one).await;
        assert_eq!((status, th["x-vtex-cache"].to_str().unwrap()), (200, "hit"), "{one}: from the metatile");
        assert!(one_body == f.body, "{one}: the frame is its bytes");
        let lone = part(&p.alone, f.x, f.y);
        let (_, lh, lone_body) = get_bytes(c, &lone).await;
        assert!(lone_body == f.body, "{one}: the bytes made alone");
        assert_eq!(th["etag"], lh["etag"], "{one}: the ETag made alone");
        let size = |name: &str| lh[name].to_str().unwrap().parse::<u32>().unwrap();
        assert_eq!((f.width, f.height), (size("x-vtex-width"), size("x-vtex-height")));
    }
    let list: Vec<String> = parts.iter().map(|(x, y)| format!("{level}/{x}/{y}")).collect();
    let (_, bh, batch_body) = get_bytes(c, &s.url(&batch(&list.join(",")))).await;
    assert_eq!(bh["cache-control"], "public, max-age=31536000, immutable", "a batch of its parts: all hits");
    assert!(frames(&batch_body).iter().zip(&got).all(|(b, m)| b.body == m.body && b.cache == 1));
    assert_eq!(syntheses(c, s).await - before, 1.0, "its parts cost no other synthesis");

    let (status, again, body_again) = get_bytes(c, &url).await;
    assert_eq!((status, again["x-vtex-cache"].to_str().unwrap()), (200, "hit"));
    assert_eq!(again["etag"], h["etag"]);
    assert!(body_again == body, "the same bytes");
    let r = c.get(&url).header("if-none-match", &etag).send().await.unwrap();
    assert_eq!(r.status(), 304);
}

#[tokio::test]
async fn a_metatile_is_its_tiles_made_once_and_shared_with_the_tile_routes() {
    let p = pair().await;
    let info: serde_json::Value =
        p.c.get(p.s.url(&format!("/api/v1/textures/{}", p.id))).send().await.unwrap().json().await.unwrap();
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
            let id = p.id.clone();
            check_block(
                &p,
                &format!("metatiles/{level}/{mx}/{my}.{fmt}"),
                *level,
                tiles,
                |s, x, y| s.tile_url(&p.id, *level, x, y, fmt),
                |list| format!("/api/v1/textures/{id}/tiles?format={fmt}&tiles={list}"),
            )
            .await;
        }
    }
}

#[tokio::test]
async fn a_page_metatile_is_its_bordered_pages_made_once_and_shared_with_the_page_routes() {
    let p = pair().await;
    // Pages of 128 + 4: metatiles of 4 × 4 pages; level 0 has 5 × 5 pages, level 1 3 × 3, and
    // level 3 (80²) one page that runs past the level's edge.
    let blocks = [
        (0, 0, 0, (0..4).flat_map(|y| (0..4).map(move |x| (x, y))).collect::<Vec<_>>()),
        (0, 1, 0, (0..4).map(|y| (4, y)).collect()),
        (0, 1, 1, vec![(4, 4)]),
        (1, 0, 0, (0..3).flat_map(|y| (0..3).map(move |x| (x, y))).collect()),
        (3, 0, 0, vec![(0, 0)]),
    ];
    for (ext, query) in
        [("rgba", "size=128&border=4"), ("ktx2", "size=128&border=4&codec=bc7"), ("png", "size=256&border=2")]
    {
        for (level, mx, my, pages) in &blocks {
            // Pages of 256 come 2 × 2 a metatile: only level 0's first block is whole then.
            let pages: Vec<(u32, u32)> = match query.contains("256") {
                true if *level > 0 || (*mx, *my) != (0, 0) => continue,
                true => vec![(0, 0), (1, 0), (0, 1), (1, 1)],
                false => pages.clone(),
            };
            let id = p.id.clone();
            check_block(
                &p,
                &format!("page-metatiles/{level}/{mx}/{my}.{ext}?{query}"),
                *level,
                &pages,
                |s, x, y| s.url(&format!("/api/v1/textures/{}/pages/{level}/{x}/{y}.{ext}?{query}", p.id)),
                |list| format!("/api/v1/textures/{id}/tiles?pages={list}&format={ext}&{query}"),
            )
            .await;
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
    let url = |path: &str| s.url(&format!("/api/v1/textures/{id}/page-metatiles/{path}"));
    let cases = [
        ("0/2/0.rgba", 404, "metatile 0/2/0 is outside level 0, which has 2×2 metatiles of 4×4 pages of 128²"),
        ("0/0/2.rgba?size=512", 404, "which has 2×2 metatiles of 1×1 pages of 512²"),
        ("11/0/0.rgba", 400, "level 11 does not exist; this texture serves levels 0..=10"),
        ("0/0/0", 400, "page metatile `0` has no format extension"),
        ("0/0/0.ktx2?border=3", 400, "`border` must be even"),
        ("0/0/0.png?codec=bc7", 400, "applies to ktx2 pages only"),
        ("0/0/0.png?size=100", 400, "`size` must be one of"),
        ("0/0/0.png?tile=1", 400, "tile"),
    ];
    for (path, status, says) in cases {
        let msg = expect_error(&c, &url(path), status).await;
        assert!(msg.contains(says), "{path}: {msg}");
    }
}
