//! Invariant 1 (consistency) and the cache's promises: one synthesis per cold key, a byte
//! budget that holds under load. Everything here holds under either transport (`VTEX_SEND`),
//! and the transport is chosen the way every other setting is.

use crate::support::*;
use rand::seq::SliceRandom;
use rand::SeedableRng;
use std::collections::BTreeMap;

type Key = (u32, u32, u32, &'static str);

/// Every tile of every level of a texture, in all four formats.
fn all_keys(levels: &[(u32, u32)]) -> Vec<Key> {
    let mut keys = Vec::new();
    for (level, &(cols, rows)) in levels.iter().enumerate() {
        for y in 0..rows {
            for x in 0..cols {
                for f in ["png", "webp", "jpg", "rgba"] {
                    keys.push((level as u32, x, y, f));
                }
            }
        }
    }
    keys
}

/// Every tile of `keys`: its ETag and its bytes.
async fn fetch_all(c: &reqwest::Client, s: &Server, id: &str, keys: &[Key]) -> BTreeMap<Key, (String, Vec<u8>)> {
    let mut out = BTreeMap::new();
    for &(l, x, y, f) in keys {
        let (status, headers, body) = get_bytes(c, &s.tile_url(id, l, x, y, f)).await;
        assert_eq!(status, 200);
        let etag = headers["etag"].to_str().unwrap().to_string();
        out.insert((l, x, y, f), (etag, body));
    }
    out
}

#[tokio::test]
async fn identical_bytes_across_order_cache_state_eviction_and_restart() {
    let dir = tempdir();
    let c = client();
    let b = mosaic(48, 20, 11); // 960²: levels 4×4, 2×2, 1×1 tiles
    let keys = all_keys(&[(4, 4), (2, 2), (1, 1)]);

    // Reference: cold, in order, generous cache.
    let s = Server::start(dir.path(), &[]);
    let id = put(&c, &s, &b).await;
    let cold = fetch_all(&c, &s, &id, &keys).await;
    // Warm: everything from the cache now.
    let warm = fetch_all(&c, &s, &id, &keys).await;
    assert_eq!(warm, cold, "warm bytes or ETags differ from cold");
    let etags: std::collections::BTreeSet<_> = cold.values().map(|(etag, _)| etag).collect();
    assert_eq!(etags.len(), keys.len(), "every tile has an ETag of its own");
    let m = metrics(&c, &s).await;
    assert_eq!(metric(&m, "vtex_tile_cache_hits_total", &[]), keys.len() as f64);
    assert_eq!(metric(&m, "vtex_tile_cache_misses_total", &[]), keys.len() as f64);
    drop(s);

    // Restart, shuffled order, a cache far too small to hold the set: tiles are evicted
    // and synthesized again, and still identical.
    let s = Server::start(dir.path(), &["--cache-mb", "0.5"]);
    let mut rng = rand::rngs::StdRng::seed_from_u64(42);
    for round in 0..2 {
        let mut shuffled = keys.clone();
        shuffled.shuffle(&mut rng);
        let got = fetch_all(&c, &s, &id, &shuffled).await;
        assert_eq!(got, cold, "round {round} after restart/eviction differs (bytes or ETags)");
    }
    let m = metrics(&c, &s).await;
    assert!(metric(&m, "vtex_tile_cache_evictions_total", &[]) > 0.0, "the small cache evicted");
    assert!(metric(&m, "vtex_syntheses_total", &[]) > keys.len() as f64, "evicted tiles were synthesized again");

    // Concurrently, from many connections, in another order: same bytes.
    let mut shuffled = keys.clone();
    shuffled.shuffle(&mut rng);
    let tasks: Vec<_> = shuffled
        .chunks(8)
        .map(|chunk| {
            let (c, url_base, chunk) = (c.clone(), s.base.clone(), chunk.to_vec());
            let id = id.clone();
            tokio::spawn(async move {
                let mut out = Vec::new();
                for (l, x, y, f) in chunk {
                    let url = format!("{url_base}/api/v1/textures/{id}/tiles/{l}/{x}/{y}.{f}");
                    out.push(((l, x, y, f), c.get(url).send().await.unwrap().bytes().await.unwrap().to_vec()));
                }
                out
            })
        })
        .collect();
    for t in tasks {
        for (k, body) in t.await.unwrap() {
            assert_eq!(&body, &cold[&k].1, "{k:?} differs under concurrency");
        }
    }
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn concurrent_misses_on_one_tile_synthesize_once() {
    let dir = tempdir();
    let c = client();
    let s = Server::start(dir.path(), &[]);
    let id = put(&c, &s, &mosaic(64, 40, 12)).await;
    let before = metric(&metrics(&c, &s).await, "vtex_syntheses_total", &[]);
    assert_eq!(before, 0.0);
    let url = s.tile_url(&id, 0, 3, 5, "png");
    let requests: Vec<_> = (0..64)
        .map(|_| {
            let (c, url) = (c.clone(), url.clone());
            tokio::spawn(async move { c.get(url).send().await.unwrap().bytes().await.unwrap() })
        })
        .collect();
    let mut bodies = Vec::new();
    for r in requests {
        bodies.push(r.await.unwrap());
    }
    assert!(bodies.windows(2).all(|w| w[0] == w[1]));
    let m = metrics(&c, &s).await;
    assert_eq!(metric(&m, "vtex_syntheses_total", &[]), 1.0, "64 concurrent requests, one synthesis");
    assert_eq!(metric(&m, "vtex_synthesis_seconds_count", &[("model", "chaos-mosaic")]), 1.0, "timed under its model");
    assert_eq!(
        metric(&m, "vtex_tile_cache_hits_total", &[("level", "0")])
            + metric(&m, "vtex_tile_cache_misses_total", &[("level", "0")]),
        64.0
    );
    assert_eq!(metric(&m, "vtex_syntheses_in_flight", &[]), 0.0);
}

#[tokio::test(flavor = "multi_thread", worker_threads = 4)]
async fn cache_budget_holds_after_filling_it_many_times_over() {
    let dir = tempdir();
    let c = client();
    let s = Server::start(dir.path(), &["--cache-mb", "2"]);
    let id = put(&c, &s, &mosaic(64, 64, 13)).await; // 4096²: 16×16 tiles at level 0
    let budget = metric(&metrics(&c, &s).await, "vtex_tile_cache_budget_bytes", &[]);
    assert_eq!(budget, 2.0 * 1024.0 * 1024.0);
    // 256 raw tiles of 256 KiB each = 64 MiB through a 2 MiB cache, 8 connections at once,
    // checking the budget while the load runs.
    let mut peak = 0.0f64;
    let keys: Vec<(u32, u32)> = (0..16).flat_map(|y| (0..16).map(move |x| (x, y))).collect();
    let (_, first_headers, first) = get_bytes(&c, &s.tile_url(&id, 0, keys[0].0, keys[0].1, "rgba")).await;
    for wave in keys.chunks(32) {
        let tasks: Vec<_> = wave
            .iter()
            .map(|&(x, y)| {
                let (c, url) = (c.clone(), s.tile_url(&id, 0, x, y, "rgba"));
                tokio::spawn(async move { c.get(url).send().await.unwrap().bytes().await.unwrap().len() })
            })
            .collect();
        let m = metrics(&c, &s).await;
        peak = peak.max(metric(&m, "vtex_tile_cache_bytes", &[]));
        for t in tasks {
            assert_eq!(t.await.unwrap(), 256 * 256 * 4);
        }
        let m = metrics(&c, &s).await;
        peak = peak.max(metric(&m, "vtex_tile_cache_bytes", &[]));
    }
    assert!(peak <= budget, "cache held {peak} bytes over a budget of {budget}");
    // The cache held less while evicted tiles were still being sent (engine/cache.rs tests
    // that); once none is, the whole budget is its own again.
    for &(x, y) in &keys[1..9] {
        get_bytes(&c, &s.tile_url(&id, 0, x, y, "rgba")).await;
    }
    let m = metrics(&c, &s).await;
    let held = metric(&m, "vtex_tile_cache_bytes", &[]);
    assert!(held > budget / 2.0, "the cache is in use: {held}");
    assert!(metric(&m, "vtex_tile_cache_evictions_total", &[]) >= 240.0);
    // The first tile, long evicted, is synthesized again, then served from the cache: the same
    // bytes and ETag each time as before the load.
    let (x, y) = keys[0];
    let (_, evicted, resynthesized) = get_bytes(&c, &s.tile_url(&id, 0, x, y, "rgba")).await;
    let hits = metric(&metrics(&c, &s).await, "vtex_tile_cache_hits_total", &[]);
    let (_, cached, hit) = get_bytes(&c, &s.tile_url(&id, 0, x, y, "rgba")).await;
    assert_eq!(metric(&metrics(&c, &s).await, "vtex_tile_cache_hits_total", &[]), hits + 1.0, "a hit");
    assert!(resynthesized == first && hit == first, "the tile's bytes changed through eviction and the cache");
    assert_eq!((&evicted["etag"], &cached["etag"]), (&first_headers["etag"], &first_headers["etag"]));
}
