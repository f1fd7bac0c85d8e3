//! The normal layer over a real socket: every pixel of a normal page, border included, is the
//! normal of the level's own luminance height at its wrapped coordinates — computed here from
//! the level's colour region by the documented formula, not by the server's code — so borders
//! equal the neighbouring pages' pixels across the torus's wrap, every level is the normal of
//! its own height (not a downsampled normal map), page metatiles, batches and mip chains hold
//! the same pixels, and KTX2 normal pages are linear.

use crate::pages::torus;
use crate::support::*;
use vtex_synth::layer::RELIEF;

async fn rgba(c: &reqwest::Client, url: &str) -> Vec<u8> {
    let (status, _, data) = get_bytes(c, url).await;
    assert_eq!(status, 200, "{url}: {}", String::from_utf8_lossy(&data));
    data
}

/// The whole of level `level` of a torus of side `side`, as RGBA.
async fn level_colour(c: &reqwest::Client, s: &Server, id: &str, level: u32, side: u32) -> Vec<u8> {
    let n = side.div_ceil(1 << level);
    rgba(c, &s.url(&format!("/api/v1/textures/{id}/region?level={level}&x=0&y=0&w={n}&h={n}&format=rgba"))).await
}

/// The normal map of a whole torus level (`n` a side) from its colour, as the layer's
/// documentation defines it: BT.709 luminance spanning RELIEF level-0 pixels of height,
/// central differences over pixels 2^level apart, +Y towards the first row, (n + 1)·127.5.
fn oracle_normals(colour: &[u8], n: u32, level: u32) -> Vec<[u8; 3]> {
    let lum = |x: i64, y: i64| {
        let (x, y) = (x.rem_euclid(n as i64) as usize, y.rem_euclid(n as i64) as usize);
        let p = &colour[(y * n as usize + x) * 4..][..3];
        (0.2126 * p[0] as f64 + 0.7152 * p[1] as f64 + 0.0722 * p[2] as f64) / 255.0
    };
    let byte = |v: f64| ((v + 1.0) * 127.5).round() as u8;
    let mut out = Vec::with_capacity((n * n) as usize);
    for y in 0..n as i64 {
        for x in 0..n as i64 {
            let slope = RELIEF as f64 / (2.0 * (1u64 << level) as f64);
            let dx = (lum(x + 1, y) - lum(x - 1, y)) * slope;
            let dy_down = (lum(x, y + 1) - lum(x, y - 1)) * slope;
            let len = (dx * dx + dy_down * dy_down + 1.0).sqrt();
            out.push([byte(-dx / len), byte(dy_down / len), byte(1.0 / len)]);
        }
    }
    out
}

/// Pixels further from the oracle than its own rounding (BT.709's exact weights against the
/// layer's weights in 1/256ths) can explain: the largest channel difference.
fn worst_difference(got: &[u8], want: &[[u8; 3]]) -> u8 {
    got.chunks_exact(4).zip(want).map(|(g, w)| (0..3).map(|i| g[i].abs_diff(w[i])).max().unwrap()).max().unwrap()
}

/// Every normal page of levels 0 to 2, border included, is the oracle's normal at its wrapped
/// level coordinates; each border pixel is bit for bit the owning page's interior pixel (across
/// the wrap); and level 1's normals are not level 0's averaged.
#[tokio::test]
async fn normal_pages_are_the_normals_of_their_levels_height_across_borders_and_the_wrap() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, side) = torus(&c, &s).await;
    let (size, border) = (64u32, 8u32);
    let span = size + 2 * border;
    let mut fine_normals = Vec::new();
    for level in 0..3 {
        let n = side.div_ceil(1 << level);
        let oracle = oracle_normals(&level_colour(&c, &s, &id, level, side).await, n, level);
        let pages_a_side = n.div_ceil(size);
        let mut pages = Vec::new();
        for py in 0..pages_a_side {
            for px in 0..pages_a_side {
                let q = format!("size={size}&border={border}&layer=normal");
                pages.push(rgba(&c, &s.url(&format!("/api/v1/textures/{id}/pages/{level}/{px}/{py}.rgba?{q}"))).await);
            }
        }
        let wrap = |v: i64| v.rem_euclid(n as i64) as u32;
        let mut checked = 0;
        for py in 0..pages_a_side {
            for px in 0..pages_a_side {
                let page = &pages[(py * pages_a_side + px) as usize];
                for j in 0..span {
                    for i in 0..span {
                        let (wx, wy) = (
                            wrap((px * size + i) as i64 - border as i64),
                            wrap((py * size + j) as i64 - border as i64),
                        );
                        let got = &page[((j * span + i) * 4) as usize..][..4];
                        let want = oracle[(wy * n + wx) as usize];
                        let off = (0..3).map(|k| got[k].abs_diff(want[k])).max().unwrap();
                        assert!(
                            off <= 1 && got[3] == 255,
                            "level {level} page {px},{py} pixel {i},{j}: {got:?} against {want:?}"
                        );
                        let (ox, oy) = (wx / size, wy / size);
                        let owner = &pages[(oy * pages_a_side + ox) as usize];
                        let at = (((wy - oy * size + border) * span + wx - ox * size + border) * 4) as usize;
                        assert_eq!(
                            got,
                            &owner[at..at + 4],
                            "level {level} page {px},{py} pixel {i},{j} against page {ox},{oy}"
                        );
                        checked += 1;
                    }
                }
            }
        }
        assert_eq!(checked, pages_a_side * pages_a_side * span * span);
        if level == 0 {
            fine_normals = oracle;
        } else if level == 1 {
            // A downsampled normal map would be level 0's normals averaged 2×2; level 1's own
            // height gives other normals (its slopes span twice the distance).
            let averaged: Vec<[u8; 3]> = (0..n * n)
                .map(|i| {
                    let (x, y) = (i % n, i / n);
                    let at = |dx: u32, dy: u32| fine_normals[((2 * y + dy) * side + 2 * x + dx) as usize];
                    let mut sum = [0u32; 3];
                    for p in [at(0, 0), at(1, 0), at(0, 1), at(1, 1)] {
                        (0..3).for_each(|k| sum[k] += p[k] as u32);
                    }
                    sum.map(|v| (v / 4) as u8)
                })
                .collect();
            let own: Vec<u8> = oracle.iter().flat_map(|p| [p[0], p[1], p[2], 255]).collect();
            assert!(worst_difference(&own, &averaged) > 8, "level 1's normals would pass for level 0's averaged");
        }
    }
}

/// A normal page metatile's frames, a batch's normal pages and the normal mip chain's levels
/// hold the single pages' pixels; colour and normal pages have ETags of their own.
#[tokio::test]
async fn metatiles_batches_and_chains_carry_the_layer() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, side) = torus(&c, &s).await;
    let q = "size=64&border=4&layer=normal";
    let page = |x: u32, y: u32| s.url(&format!("/api/v1/textures/{id}/pages/0/{x}/{y}.rgba?{q}"));
    let block = rgba(&c, &s.url(&format!("/api/v1/textures/{id}/page-metatiles/0/0/0.rgba?{q}"))).await;
    let frames = vtex_wire::frame::frames(&block).expect("a body of frames");
    assert_eq!(frames.len(), 16, "4 × 4 pages of 64");
    for (header, bytes) in frames {
        let single = rgba(&c, &page(header.tile.x, header.tile.y)).await;
        assert!(single == block[bytes], "page {:?} in the metatile", header.tile);
    }
    let url = s.url(&format!("/api/v1/textures/{id}/tiles?pages=0/1/2,0/3/3&format=rgba&{q}"));
    let body = rgba(&c, &url).await;
    let frames = vtex_wire::frame::frames(&body).expect("a body of frames");
    assert_eq!(frames.len(), 2);
    for (header, bytes) in frames {
        assert!(rgba(&c, &page(header.tile.x, header.tile.y)).await == body[bytes], "batch page {:?}", header.tile);
    }
    // The chain of level 2 (60² down to 1²), uncompressed: level i holds level 2 + i's normals
    // (the top left of the level the GPU's halving sizes cover).
    let chain = rgba(&c, &s.url(&format!("/api/v1/textures/{id}/mips.ktx2?level=2&codec=rgba8&layer=normal"))).await;
    let reader = ktx2::Reader::new(&chain[..]).expect("a KTX2 file");
    for (i, level) in reader.levels().enumerate() {
        let l = 2 + i as u32;
        let (n, w) = (side.div_ceil(1 << l), (60u32 >> i).max(1));
        let oracle = oracle_normals(&level_colour(&c, &s, &id, l, side).await, n, l);
        let want: Vec<[u8; 3]> = (0..w * w).map(|p| oracle[((p / w) * n + p % w) as usize]).collect();
        assert!(worst_difference(level.data, &want) <= 1, "chain level {i} (vtex level {l})");
    }
    let etag = |q: &'static str| {
        let url = s.url(&format!("/api/v1/textures/{id}/pages/0/0/0.png?size=64&border=4{q}"));
        let c = c.clone();
        async move { get_bytes(&c, &url).await.1["etag"].to_str().unwrap().to_string() }
    };
    assert_ne!(etag("").await, etag("&layer=normal").await);
    assert_eq!(etag("").await, etag("&layer=color").await, "colour is the default layer");
}

/// An unknown layer is a 400 naming the layers; normals in ETC1S a 400 naming the codecs that
/// hold them; colour in BC5 a 400.
#[tokio::test]
async fn an_unknown_layer_or_a_codec_that_cannot_hold_it_is_refused() {
    let dir = tempdir();
    let s = Server::start(dir.path(), &[]);
    let c = client();
    let (id, _) = torus(&c, &s).await;
    for (path, words) in [
        ("pages/0/0/0.png?layer=height", "unknown layer `height`; expected color or normal"),
        ("mips.ktx2?layer=Normal", "unknown layer `Normal`; expected color or normal"),
        ("pages/0/0/0.ktx2?layer=normal&codec=etc1s", "for layer normal use bc5, uastc, bc7, bc1 or rgba8"),
        ("pages/0/0/0.ktx2?codec=bc5", "bc5 holds two channels, a normal's X and Y: it serves layer normal only"),
        ("mips.ktx2?layer=normal&codec=etc1s", "etc1s cannot hold normals"),
    ] {
        let msg = expect_error(&c, &s.url(&format!("/api/v1/textures/{id}/{path}")), 400).await;
        assert!(msg.contains(words), "{path}: {msg}");
    }
}
