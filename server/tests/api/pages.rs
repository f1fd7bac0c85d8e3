//! Virtual-texture pages over a real socket: every pixel of a page, border included, is the
//! texture's pixel at its level coordinates, so borders equal the neighbouring pages' pixels on
//! every side and corner, across a torus's wrap and far out on the plane; pages exist at every
//! level down to 1×1; they are cached, ETagged and batched like tiles; KTX2 pages are the same
//! bytes whatever the run or thread count; bad parameters are 400s naming what is allowed.

use crate::support::*;
use serde_json::json;
use vtex_synth::models::{self, Inputs};

/// RGBA8 pixels of a `w`-wide image.
struct Img {
    w: u32,
    data: Vec<u8>,
}

impl Img {
    fn px(&self, x: u32, y: u32) -> &[u8] {
        let i = (y * self.w + x) as usize * 4;
        &self.data[i..i + 4]
    }
}

fn page_path(id: &str, level: u32, x: u32, y: u32, ext: &str, query: &str) -> String {
    format!("/api/v1/textures/{id}/pages/{level}/{x}/{y}.{ext}?{query}")
}

/// Page (`level`, `x`, `y`) of `size` and `border` as raw RGBA.
async fn page(
    c: &reqwest::Client,
    s: &Server,
    id: &str,
    (level, x, y): (u32, u32, u32),
    (size, border): (u32, u32),
) -> Img {
    let url = s.url(&page_path(id, level, x, y, "rgba", &format!("size={size}&border={border}")));
    let (status, h, data) = get_bytes(c, &url).await;
    assert_eq!(status, 200, "{url}: {}", String::from_utf8_lossy(&data));
    let side = size + 2 * border;
    assert_eq!(
        (h["x-vtex-width"].to_str().unwrap(), h["x-vtex-height"].to_str().unwrap()),
        (&*side.to_string(), &*side.to_string())
    );
    assert_eq!(data.len(), (side * side * 4) as usize);
    Img { w: side, data }
}

/// Region (`x`, `y`, `w`, `h`) of `level` as raw RGBA.
async fn region(c: &reqwest::Client, s: &Server, id: &str, level: u32, (x, y): (i64, i64), (w, h): (u32, u32)) -> Img {
    let url = s.url(&format!("/api/v1/textures/{id}/region?level={level}&x={x}&y={y}&w={w}&h={h}&format=rgba"));
    let (status, _, data) = get_bytes(c, &url).await;
    assert_eq!(status, 200, "{url}");
    Img { w, data }
}

/// A chaos mosaic of `tiles` × 24 px a side: a torus whose sides are no multiple of the pages.
pub(crate) async fn torus(c: &reqwest::Client, s: &Server) -> (String, u32) {
    (put(c, s, &mosaic(24, 10, 5)).await, 240)
}

/// A cascade on the unbounded plane, 100,000² served, with sharp detail at every level.
fn plane() -> vtex_synth::bundle::Bundle {
    let params = json!({"seed": 11, "stages": [{"kernel": {"size": 5, "preset": "gauss", "sigma": 1.0},
        "map": {"kind": "logistic", "r": 3.9}, "iterations": 5}], "palette": "ocean"});
    models::create("cascade", "plane for pages", &params, &Inputs::new()).unwrap()
}

/// Every pixel of every page of a level, border included, is the level's pixel at its
/// wrapped coordinates — and so equals the neighbouring page's own pixel there, whichever
/// page (across the wrap, on all sides and corners) that is.
#[tokio::test]
async fn torus_borders_are_the_neighbours_pixels_across_the_wrap() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, side) = torus(&c, &s).await;
    let (size, border) = (64u32, 8u32);
    let level_img = region(&c, &s, &id, 0, (0, 0), (side, side)).await;
    let n = side.div_ceil(size);
    let mut pages = Vec::new();
    for py in 0..n {
        for px in 0..n {
            pages.push(page(&c, &s, &id, (0, px, py), (size, border)).await);
        }
    }
    let wrap = |v: i64| v.rem_euclid(side as i64) as u32;
    let mut border_pixels = 0;
    for py in 0..n {
        for px in 0..n {
            let p = &pages[(py * n + px) as usize];
            for j in 0..size + 2 * border {
                for i in 0..size + 2 * border {
                    let gx = (px * size + i) as i64 - border as i64;
                    let gy = (py * size + j) as i64 - border as i64;
                    let (wx, wy) = (wrap(gx), wrap(gy));
                    assert_eq!(p.px(i, j), level_img.px(wx, wy), "page {px},{py} pixel {i},{j}");
                    let inside = (border..border + size).contains(&i) && (border..border + size).contains(&j);
                    if inside {
                        continue;
                    }
                    // The page that owns (wx, wy) has it in its interior.
                    let (ox, oy) = (wx / size, wy / size);
                    let owner = &pages[(oy * n + ox) as usize];
                    assert_eq!(
                        p.px(i, j),
                        owner.px(wx - ox * size + border, wy - oy * size + border),
                        "page {px},{py} border pixel {i},{j} against page {ox},{oy}"
                    );
                    border_pixels += 1;
                }
            }
        }
    }
    let ring = (size + 2 * border).pow(2) - size * size;
    assert_eq!(border_pixels, ring * n * n, "every border pixel of every page was compared");
    // The wrap is exercised: page 0's left border is the last column of pages, at level
    // x = side − border.
    let last_col = &pages[(n - 1) as usize];
    assert_eq!(pages[0].px(0, border), last_col.px(side - border - (n - 1) * size + border, border));
}

/// On the unbounded plane, pages near the far corner of the served extent (and their borders,
/// which reach past it) equal the plane's region at the same coordinates, and each border
/// equals the interior of the neighbouring page.
#[tokio::test]
async fn plane_pages_far_out_equal_the_plane_and_their_neighbours() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let id = put(&c, &s, &plane()).await;
    let info: serde_json::Value =
        c.get(s.url(&format!("/api/v1/textures/{id}"))).send().await.unwrap().json().await.unwrap();
    assert_eq!(info["domain"], "plane");
    let (w, h) = (info["width"].as_u64().unwrap(), info["height"].as_u64().unwrap());
    let (size, border) = (128u32, 16u32);
    let (cols, rows) = (w.div_ceil(size as u64) as u32, h.div_ceil(size as u64) as u32);
    let (x0, y0) = (cols - 2, rows - 2);
    let origin = ((x0 * size) as i64 - border as i64, (y0 * size) as i64 - border as i64);
    let whole = region(&c, &s, &id, 0, origin, (2 * size + 2 * border, 2 * size + 2 * border)).await;
    let mut pages = Vec::new();
    for dy in 0..2 {
        for dx in 0..2 {
            pages.push(((dx, dy), page(&c, &s, &id, (0, x0 + dx, y0 + dy), (size, border)).await));
        }
    }
    for ((dx, dy), p) in &pages {
        for j in 0..size + 2 * border {
            for i in 0..size + 2 * border {
                assert_eq!(p.px(i, j), whole.px(dx * size + i, dy * size + j), "page +{dx},+{dy} pixel {i},{j}");
            }
        }
    }
    // The right border of the left pages is the left of the right pages' interiors, and so on.
    let at = |dx: u32, dy: u32| &pages.iter().find(|(d, _)| *d == (dx, dy)).unwrap().1;
    for j in 0..size + 2 * border {
        for i in 0..border {
            assert_eq!(at(0, 0).px(size + border + i, j), at(1, 0).px(border + i, j), "right border, row {j}");
            assert_eq!(at(1, 0).px(i, j), at(0, 0).px(size + i, j), "left border, row {j}");
            assert_eq!(at(0, 0).px(j, size + border + i), at(0, 1).px(j, border + i), "bottom border, column {j}");
        }
    }
    for j in 0..border {
        for i in 0..border {
            assert_eq!(
                at(0, 0).px(size + border + i, size + border + j),
                at(1, 1).px(border + i, border + j),
                "corner"
            );
        }
    }
}

/// Pages exist at every level down to 1×1 (further than tiles go), each equal to the region
/// it covers; a level past 1×1 is a 400 naming the levels, a page past the grid a 404.
#[tokio::test]
async fn pages_at_every_level_down_to_one_pixel() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, side) = torus(&c, &s).await;
    let levels = vtex_synth::texture::level_count(side as u64, side as u64);
    let (size, border) = (64u32, 4u32);
    for level in 0..levels {
        let (lw, _) = vtex_synth::texture::level_size(side as u64, side as u64, level);
        let last = (lw as u32).div_ceil(size) - 1;
        for p in [0, last] {
            let got = page(&c, &s, &id, (level, p, p), (size, border)).await;
            let at = (p * size) as i64 - border as i64;
            let want = region(&c, &s, &id, level, (at, at), (size + 2 * border, size + 2 * border)).await;
            assert!(got.data == want.data, "level {level} page {p},{p}");
        }
        if level == levels - 1 {
            assert_eq!(lw, 1);
            let one = page(&c, &s, &id, (level, 0, 0), (size, border)).await;
            assert!(one.data.chunks(4).all(|px| px == one.px(0, 0)), "a 1×1 torus level fills its page");
        }
    }
    let msg = expect_error(&c, &s.url(&page_path(&id, levels, 0, 0, "png", "")), 400).await;
    assert!(msg.contains(&format!("pages are served at levels 0..={}", levels - 1)), "{msg}");
    let msg = expect_error(&c, &s.url(&page_path(&id, 0, 2, 4, "png", "size=64")), 404).await;
    assert!(msg.contains("outside level 0, which has 4×4 pages of 64²"), "{msg}");
}

/// Pages are cached and ETagged like tiles: the second request is a hit with the same bytes
/// and ETag, `If-None-Match` is a 304, every parameter is part of the ETag, and a tile's ETag
/// is not a page's.
#[tokio::test]
async fn pages_are_cached_etagged_and_immutable() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, _) = torus(&c, &s).await;
    let url = s.url(&page_path(&id, 1, 1, 0, "ktx2", "size=64&border=4&codec=bc1"));
    let (st, h1, b1) = get_bytes(&c, &url).await;
    assert_eq!(st, 200);
    assert_eq!(h1["content-type"], "image/ktx2");
    assert_eq!(h1["x-vtex-cache"], "miss");
    assert_eq!(h1["cache-control"], "public, max-age=31536000, immutable");
    let (_, h2, b2) = get_bytes(&c, &url).await;
    assert_eq!(h2["x-vtex-cache"], "hit");
    assert_eq!((b1, &h1["etag"]), (b2, &h2["etag"]));
    let r = c.get(&url).header("if-none-match", h1["etag"].clone()).send().await.unwrap();
    assert_eq!(r.status(), 304);
    let mut tags = std::collections::HashSet::new();
    for q in [
        "size=64&border=4&codec=bc1",
        "size=64&border=4&codec=bc7",
        "size=64&border=4&codec=bc1&supercompression=zstd",
        "size=64&border=6&codec=bc1",
        "size=128&border=4&codec=bc1",
        "size=64&border=4&codec=bc1&layer=normal",
    ] {
        let (st, h, _) = get_bytes(&c, &s.url(&page_path(&id, 1, 0, 0, "ktx2", q))).await;
        assert_eq!(st, 200, "{q}");
        assert!(tags.insert(h["etag"].to_str().unwrap().to_string()), "{q} has an ETag of its own");
    }
    let (_, hp, _) = get_bytes(&c, &s.url(&page_path(&id, 0, 0, 0, "png", "size=256&border=0"))).await;
    let (_, ht, _) = get_bytes(&c, &s.tile_url(&id, 0, 0, 0, "png")).await;
    assert_ne!(hp["etag"], ht["etag"], "a page is not the tile at the same address");
}

/// Pages of KTX2 and raw RGBA through the batch endpoint: each frame is exactly the single
/// page's bytes; a batch takes tiles or pages, not both, and page parameters only with pages.
#[tokio::test]
async fn the_batch_endpoint_takes_pages() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, _) = torus(&c, &s).await;
    for (ext, q) in [("ktx2", "size=64&border=8&codec=bc7&supercompression=zstd"), ("rgba", "size=128&border=16")] {
        let list = "0/0/0,0/1/0,2/0/0,7/0/0";
        let url = s.url(&format!("/api/v1/textures/{id}/tiles?pages={list}&format={ext}&{q}"));
        let (st, h, body) = get_bytes(&c, &url).await;
        assert_eq!(st, 200, "{}", String::from_utf8_lossy(&body));
        assert_eq!(h["content-type"], "application/x-vtex-tile-batch");
        let mut rest = &body[..];
        let mut seen = 0;
        while !rest.is_empty() {
            let u32_at = |i: usize| u32::from_le_bytes(rest[i..i + 4].try_into().unwrap());
            let (level, x, y, len) = (u32_at(4), u32_at(8), u32_at(12), u32_at(28) as usize);
            assert_eq!(u16::from_le_bytes([rest[16], rest[17]]), 200);
            let (_, _, single) = get_bytes(&c, &s.url(&page_path(&id, level, x, y, ext, q))).await;
            assert!(rest[32..32 + len] == single[..], "page {level}/{x}/{y}.{ext} in a batch");
            rest = &rest[32 + len..];
            seen += 1;
        }
        assert_eq!(seen, 4);
    }
    let base = format!("/api/v1/textures/{id}/tiles");
    for (q, words) in [
        ("tiles=0/0/0&pages=0/0/0&format=png", "exactly one of `tiles` and `pages`"),
        ("format=png", "exactly one of `tiles` and `pages`"),
        ("tiles=0/0/0&format=png&size=64", "`size` applies to pages only"),
        ("tiles=0/0/0&format=ktx2", "ktx2 is served for pages only"),
        ("pages=0/0/0&format=png&size=100", "must be one of 64, 128, 256 or 512"),
        ("pages=0/9/0&format=png&size=64", "outside level 0"),
    ] {
        let status = if words.starts_with("outside") { 404 } else { 400 };
        let msg = expect_error(&c, &s.url(&format!("{base}?{q}")), status).await;
        assert!(msg.contains(words), "{q}: {msg}");
    }
}

/// Bad size, border, codec, supercompression or format: a 400 naming the allowed values.
#[tokio::test]
async fn bad_page_parameters_name_the_allowed_values() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, _) = torus(&c, &s).await;
    for (file, q, words) in [
        ("0.png", "size=100", "`size` must be one of 64, 128, 256 or 512 (got 100)"),
        ("0.png", "size=1024", "`size` must be one of 64, 128, 256 or 512 (got 1024)"),
        ("0.png", "size=128&border=17", "`border` must be at most size / 8 = 16 for size 128 (got 17)"),
        ("0.png", "size=64&border=9", "at most size / 8 = 8 for size 64 (got 9)"),
        ("0.png", "border=-1", "`border` must not be negative"),
        ("0.ktx2", "codec=etc2", "`codec` names unknown codec `etc2`; expected bc7, bc1, bc5, rgba8, uastc or etc1s"),
        ("0.ktx2", "codec=etc1s&supercompression=zstd", "etc1s is always BasisLZ-supercompressed"),
        ("0.ktx2", "codec=uastc&supercompression=basislz", "basislz applies to codec etc1s only"),
        ("0.ktx2", "supercompression=lz4", "unknown scheme `lz4`; expected none, zstd or basislz (etc1s only)"),
        ("0.ktx2", "border=3", "`border` must be even for bc7 pages (got 3)"),
        ("0.ktx2", "rdo=1", "`rdo` applies to codec uastc only (got codec bc7)"),
        ("0.ktx2", "codec=uastc&rdo=20", "`rdo` must be a number from 0.1 to 10 (got `20`)"),
        ("0.ktx2", "codec=uastc&rdo=NaN", "`rdo` must be a number from 0.1 to 10 (got `NaN`)"),
        ("0.png", "rdo=1", "`rdo` applies to ktx2 pages only; this page is png"),
        ("0.ktx2", "codec=rgba8&border=3&size=64", ""),
        ("0.png", "codec=bc7", "`codec` applies to ktx2 pages only; this page is png"),
        ("0.gif", "", "unknown format `gif`; expected png, webp, jpg, rgba or ktx2"),
        ("0", "", "has no format extension; expected png, webp, jpg, rgba or ktx2"),
        ("x.png", "", "`y` must be an integer"),
        (
            "0.png",
            "gutter=2",
            "unknown query parameter `gutter`; expected size, border, layer, codec, supercompression, rdo, frame",
        ),
    ] {
        let url = s.url(&format!("/api/v1/textures/{id}/pages/0/0/{file}?{q}"));
        if words.is_empty() {
            assert_eq!(get_bytes(&c, &url).await.0, 200, "{file}?{q}: an odd border is fine uncompressed");
            continue;
        }
        let msg = expect_error(&c, &url, 400).await;
        assert!(msg.contains(words), "{file}?{q}: {msg}");
    }
}

/// KTX2 pages are the same bytes from servers with different slot counts, requested one at a
/// time or all at once, and match pinned hashes, so replicas on other machines serve them too.
#[tokio::test]
async fn ktx2_pages_are_the_same_bytes_on_every_run_and_thread_count() {
    let dir_a = tempdir();
    let dir_b = tempdir();
    let a = Server::start(dir_a.path(), &["--max-syntheses", "1", "--io-threads", "1"]);
    let b = Server::start(dir_b.path(), &["--max-syntheses", "2", "--max-syntheses-per-texture", "2"]);
    let c = client();
    let (id, _) = torus(&c, &a).await;
    assert_eq!(torus(&c, &b).await.0, id);
    // Sharp detail: BC7's second pass re-encodes many of its blocks, its third some.
    let sharp = put(&c, &a, &plane()).await;
    assert_eq!(put(&c, &b, &plane()).await, sharp);
    let queries = [
        "size=64&border=4&codec=bc7",
        "size=64&border=4&codec=bc1",
        "size=64&border=4&codec=bc7&supercompression=zstd",
        "size=128&border=8&codec=bc1&supercompression=zstd",
    ];
    let mut hashes = Vec::new();
    let cases = queries.iter().map(|q| (id.as_str(), *q)).chain([(sharp.as_str(), "size=128&border=4&codec=bc7")]);
    for (id, q) in cases {
        let list = "0/0/0,0/1/1,1/0/0,3/0/0";
        let from_b =
            get_bytes(&c, &b.url(&format!("/api/v1/textures/{id}/tiles?pages={list}&format=ktx2&{q}"))).await.2;
        let mut h = blake3::Hasher::new();
        for p in list.split(',') {
            let v: Vec<u32> = p.split('/').map(|n| n.parse().unwrap()).collect();
            let (st, _, one) = get_bytes(&c, &a.url(&page_path(id, v[0], v[1], v[2], "ktx2", q))).await;
            assert_eq!(st, 200);
            let needle = &one[..];
            assert!(from_b.windows(needle.len()).any(|w| w == needle), "{q}: page {p} differs between the servers");
            h.update(&one);
        }
        hashes.push(h.finalize().to_hex()[..16].to_string());
    }
    // Pinned: a deliberate change of the encoder, its settings or the container changes these.
    assert_eq!(
        hashes,
        ["e2e278c92fe79a32", "2f20ab8efc9f0006", "96d79d551abb9276", "61c8f008dad1e29c", "4600b83872a553b5"],
        "KTX2 page bytes changed"
    );
}

/// Basis Universal pages and chains (UASTC with and without zstd, ETC1S) are the same bytes from
/// servers with different slot counts, one at a time or batched, and match pinned hashes: basisu
/// runs single-threaded, so neither the run nor the thread changes a byte.
#[tokio::test]
async fn basis_pages_and_chains_are_the_same_bytes_on_every_run_and_thread_count() {
    let dir_a = tempdir();
    let dir_b = tempdir();
    let a = Server::start(dir_a.path(), &["--max-syntheses", "1", "--io-threads", "1"]);
    let b = Server::start(dir_b.path(), &["--max-syntheses", "2", "--max-syntheses-per-texture", "2"]);
    let c = client();
    let (id, _) = torus(&c, &a).await;
    assert_eq!(torus(&c, &b).await.0, id);
    let (mut hashes, mut bytes) = (Vec::new(), Vec::new());
    let variants = [
        "codec=uastc",
        "codec=uastc&supercompression=zstd",
        "codec=etc1s",
        "codec=uastc&supercompression=zstd&rdo=2",
        "codec=uastc&layer=normal",
    ];
    for q in variants {
        let q = format!("size=64&border=4&{q}");
        let list = "0/0/0,0/1/1,3/0/0";
        let from_b =
            get_bytes(&c, &b.url(&format!("/api/v1/textures/{id}/tiles?pages={list}&format=ktx2&{q}"))).await.2;
        let mut h = blake3::Hasher::new();
        for p in list.split(',') {
            let v: Vec<u32> = p.split('/').map(|n| n.parse().unwrap()).collect();
            let (st, _, one) = get_bytes(&c, &a.url(&page_path(&id, v[0], v[1], v[2], "ktx2", &q))).await;
            assert_eq!(st, 200, "{q}: {}", String::from_utf8_lossy(&one));
            assert!(from_b.windows(one.len()).any(|w| w == &one[..]), "{q}: page {p} differs between the servers");
            h.update(&one);
            bytes.push((q.clone(), one.len()));
        }
        let chain = q.replace("size=64&border=4&", "level=1&");
        let (st, _, one) = get_bytes(&c, &a.url(&format!("/api/v1/textures/{id}/mips.ktx2?{chain}"))).await;
        assert_eq!(st, 200, "{chain}: {}", String::from_utf8_lossy(&one));
        let (_, _, two) = get_bytes(&c, &b.url(&format!("/api/v1/textures/{id}/mips.ktx2?{chain}"))).await;
        assert!(one == two, "{chain}: the chain differs between the servers");
        h.update(&one);
        hashes.push(h.finalize().to_hex()[..16].to_string());
    }
    // Pinned: a deliberate change of the encoder, its settings or the container changes these.
    assert_eq!(
        hashes,
        ["49a37a83e22e20c3", "825f9ad0870d7f15", "a382a51c87421e31", "825be60159596db3", "6168ec2363ed4eaa"],
        "Basis Universal KTX2 bytes changed"
    );
    let total = |q: &str| bytes.iter().filter(|(v, _)| v.ends_with(q)).map(|(_, n)| n).sum::<usize>();
    assert!(total(variants[3]) < total(variants[1]), "RDO makes zstd's pages smaller");
}

/// A whole mip chain in one KTX2: levels sized as a GPU's chain (⌊w / 2^i⌋), each the top-left
/// of the texture's own level (checked exactly with the uncompressed codec); a level too large
/// to upload whole is a 400 naming the first that fits.
#[tokio::test]
async fn a_mip_chain_holds_every_level_to_one_pixel() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, side) = torus(&c, &s).await;
    let url = s.url(&format!("/api/v1/textures/{id}/mips.ktx2?codec=rgba8&level=1"));
    let (st, h, f) = get_bytes(&c, &url).await;
    assert_eq!(st, 200, "{}", String::from_utf8_lossy(&f));
    assert_eq!(h["content-type"], "image/ktx2");
    let u32_at = |i: usize| u32::from_le_bytes(f[i..i + 4].try_into().unwrap());
    let u64_at = |i: usize| u64::from_le_bytes(f[i..i + 8].try_into().unwrap()) as usize;
    let base = side / 2;
    assert_eq!((u32_at(20), u32_at(24)), (base, base));
    let count = u32_at(40);
    assert_eq!(count, 32 - base.leading_zeros(), "down to 1×1");
    for i in 0..count {
        let e = 80 + 24 * i as usize;
        let (off, len) = (u64_at(e), u64_at(e + 8));
        let w = (base >> i).max(1);
        let want = region(&c, &s, &id, 1 + i, (0, 0), (w, w)).await;
        assert!(f[off..off + len] == want.data[..], "chain level {i} ({w}×{w}) is the top-left of level {}", 1 + i);
    }
    let big = put(&c, &s, &mosaic(32, 80, 6)).await; // 2560² at level 0
    let msg = expect_error(&c, &s.url(&format!("/api/v1/textures/{big}/mips.ktx2?level=0")), 400).await;
    assert!(
        msg.contains("level 0 is 2560×2560; a bc7 mip chain starts at a level of at most 2048 a side (level 1"),
        "{msg}"
    );
    // Basis Universal chains start at 512 at most: basisu's encoding takes seconds a chain.
    let msg = expect_error(&c, &s.url(&format!("/api/v1/textures/{big}/mips.ktx2?level=2&codec=uastc")), 400).await;
    assert!(msg.contains("a uastc mip chain starts at a level of at most 512 a side (level 3"), "{msg}");
}
