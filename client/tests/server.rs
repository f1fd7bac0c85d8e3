//! vtex-client against a real `vtex serve` (the workspace's release or debug build of
//! `vtex-server`, built by the same `cargo test --workspace`), and against a scripted socket for
//! retries.

mod common;

use common::{addrs, scripted, serve, upload};
use std::sync::atomic::Ordering;
use std::time::Duration;
use vtex_client::{Client, PageAddr, PageFormat, PageLayer, PageSpec, Retry};

#[tokio::test]
async fn discovery_pages_alone_or_from_their_metatiles_and_the_cache() {
    let s = serve();
    let id = upload(&s.base).await;
    let client = Client::new(&s.base, 1 << 20);
    let textures = client.textures().await.unwrap();
    let t = textures.iter().find(|t| t.id == id).unwrap();
    assert_eq!((t.width, t.domain, vtex_client::page_levels(t)), (512, vtex_client::Domain::Torus, 10));
    assert_eq!(vtex_client::page_grid(t, 0, 64), (8, 8));
    let spec = PageSpec {
        size: 64,
        border: 4,
        format: PageFormat::Ktx2 { codec: "bc1", zstd: true },
        layer: PageLayer::Color,
    };
    // Pages of 64 come 8 × 8 a metatile: level 0 is one, and 40 of its 64 pages asked for
    // fetch it; 2 of level 1's pages and level 9's one page come alone.
    let level0 = addrs(0, 8);
    let (asked0, others) = level0.split_at(40);
    let alone =
        [PageAddr { level: 1, x: 3, y: 1 }, PageAddr { level: 1, x: 0, y: 0 }, PageAddr { level: 9, x: 0, y: 0 }];
    let want = [asked0, &alone].concat();
    let (pages, stats) = client.pages(&id, &want, &spec).await.unwrap();
    assert_eq!((stats.hits, stats.requested, stats.metatiles), (0, want.len(), 1));
    let http = reqwest::Client::new();
    let single = |a: PageAddr| {
        let url = client.page_url(&id, a, &spec);
        let http = http.clone();
        async move { http.get(url).send().await.unwrap().bytes().await.unwrap() }
    };
    for (a, p) in want.iter().zip(&pages) {
        assert_eq!(p.addr, *a, "pages come in the order asked");
        assert_eq!((p.width, p.height), (72, 72));
        assert_eq!(p.bytes, single(*a).await, "page {a:?}: the single page's bytes");
        assert_eq!(p.etag.is_some(), a.level > 0, "page {a:?}: a validator where it came alone");
    }
    let mut unused = 0;
    for &a in others {
        unused += single(a).await.len() as u64;
    }
    assert_eq!(stats.unused, unused, "level 0's pages not asked for");
    assert_eq!(stats.bytes, pages.iter().map(|p| p.bytes.len() as u64).sum::<u64>() + unused);
    assert_eq!(client.cached_pages(), want.len() + others.len());
    let (again, stats) = client.pages(&id, &[want.clone(), others.to_vec()].concat(), &spec).await.unwrap();
    assert_eq!(
        (stats.hits, stats.requested, stats.bytes),
        (want.len() + others.len(), 0, 0),
        "all from the client's cache"
    );
    assert!(again.iter().zip(&pages).all(|(a, b)| a.bytes == b.bytes));
    let m = client.page_metatile_url(&id, vtex_client::page_metatile(PageAddr { level: 2, x: 9, y: 17 }, 64), &spec);
    let path =
        format!("/api/v1/textures/{id}/page-metatiles/2/1/2.ktx2?size=64&border=4&codec=bc1&supercompression=zstd");
    assert!(m.ends_with(&path), "{m}");
    assert!(client.tile_url(&id, 0, 1, 2, "png").ends_with(&format!("/api/v1/textures/{id}/tiles/0/1/2.png")));
}

#[tokio::test]
async fn the_cache_is_bounded_in_bytes() {
    let s = serve();
    let id = upload(&s.base).await;
    let spec = PageSpec { size: 64, border: 0, format: PageFormat::Rgba, layer: PageLayer::Color };
    let budget = 3 * 64 * 64 * 4;
    let client = Client::new(&s.base, budget);
    let want = addrs(0, 4);
    let (_, stats) = client.pages(&id, &want, &spec).await.unwrap();
    assert_eq!(stats.requested, 16);
    assert_eq!((client.cached_pages(), client.cached_bytes()), (3, budget));
    let (_, stats) = client.pages(&id, &want[13..], &spec).await.unwrap();
    assert_eq!(stats.hits, 3, "the last three pages stayed");
}

#[tokio::test]
async fn revalidation_keeps_the_held_page_on_304() {
    let s = serve();
    let id = upload(&s.base).await;
    let client = Client::new(&s.base, 1 << 20);
    let spec = PageSpec::default();
    let a = PageAddr { level: 1, x: 0, y: 0 };
    let (first, not_modified) = client.revalidate(&id, a, &spec).await.unwrap();
    assert!(!not_modified);
    assert!(first.etag.is_some());
    assert_eq!(&first.bytes[..12], &[0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A]);
    let (second, not_modified) = client.revalidate(&id, a, &spec).await.unwrap();
    assert!(not_modified, "the server answered 304");
    assert_eq!(second.bytes, first.bytes);
}

#[tokio::test]
async fn retries_back_off_on_503_and_never_on_404() {
    let retry = Retry { attempts: 4, first_delay: Duration::from_millis(5), max_delay: Duration::from_millis(20) };
    let spec = PageSpec { size: 64, border: 0, format: PageFormat::Rgba, layer: PageLayer::Color };
    let one = [PageAddr { level: 0, x: 0, y: 0 }];
    let (base, count) = scripted(2, 503);
    let (pages, _) = Client::new(&base, 1 << 20).with_retry(retry).pages("t", &one, &spec).await.unwrap();
    assert_eq!((count.load(Ordering::SeqCst), &pages[0].bytes[..]), (3, &[1u8, 2, 3, 4][..]));
    let (base, count) = scripted(10, 503);
    let err = Client::new(&base, 1 << 20).with_retry(retry).pages("t", &one, &spec).await.unwrap_err();
    assert_eq!(count.load(Ordering::SeqCst), 4, "attempts run out: {err}");
    let (base, count) = scripted(10, 404);
    let err = Client::new(&base, 1 << 20).with_retry(retry).pages("t", &one, &spec).await.unwrap_err();
    assert_eq!(count.load(Ordering::SeqCst), 1, "a 404 is not retried: {err}");
    assert!(err.to_string().contains("404: try later"), "{err}");
}

/// The planner against a real server: a camera low over the 512² torus needs pages of several
/// levels; its plan (every needed page and ancestor, coarsest first) fetched, every page the
/// view needs is held and the next plan is empty; within a budget of 8 a frame, the first
/// frame brings the level that is one page, and the view is complete after as many frames as
/// the budget makes it take.
#[tokio::test]
async fn the_planner_plans_what_a_camera_needs_and_the_server_serves_it() {
    use std::collections::BTreeSet;
    use vtex_client::planner::{self, Surface, View};
    let s = serve();
    let id = upload(&s.base).await;
    let client = Client::new(&s.base, 64 << 20);
    let t = client.textures().await.unwrap().into_iter().find(|t| t.id == id).unwrap();
    let spec = PageSpec {
        size: 64,
        border: 4,
        format: PageFormat::Ktx2 { codec: "bc1", zstd: true },
        layer: PageLayer::Color,
    };
    let surface = Surface { origin: [0.0; 3], u_axis: [512.0, 0.0, 0.0], v_axis: [0.0, 512.0, 0.0], repeat: true };
    let proj = planner::perspective(std::f64::consts::FRAC_PI_3, 16.0 / 9.0, 0.5, 1e5);
    let eye = planner::look_at([256.0, 256.0, 12.0], [330.0, 290.0, 0.0], [0.0, 0.0, 1.0]);
    let view = View { view_proj: planner::mul(&proj, &eye), width: 640, height: 360, step: 4, lod_bias: 0.0 };
    let feedback = planner::from_camera(&view, &surface, &t, spec.size);
    let levels: BTreeSet<u32> = feedback.keys().map(|a| a.level).collect();
    assert!(levels.len() >= 3 && levels.contains(&0), "near and far: {levels:?}");
    let top = planner::top_level(&t, spec.size);
    assert_eq!(top, 3);

    let all = planner::plan(&feedback, &t, spec.size, |_| false, usize::MAX);
    assert_eq!(all[0].addr, PageAddr { level: top, x: 0, y: 0 }, "the one page of the top level first");
    assert!(all.windows(2).all(|w| w[0].addr.level >= w[1].addr.level), "coarsest first");
    let want: Vec<PageAddr> = all.iter().map(|r| r.addr).collect();
    let (pages, _) = client.pages(&id, &want, &spec).await.unwrap();
    assert!(pages.iter().all(|p| !p.bytes.is_empty() && p.width == 72));
    let resident: BTreeSet<PageAddr> = pages.iter().map(|p| p.addr).collect();
    assert!(feedback.keys().all(|a| resident.contains(a)), "every page the view needs is held");
    for &a in feedback.keys() {
        for level in a.level..=top {
            assert!(resident.contains(&planner::ancestor(a, level)), "{a:?}'s ancestor at level {level} is held");
        }
    }
    assert!(planner::plan(&feedback, &t, spec.size, |a| resident.contains(&a), usize::MAX).is_empty());

    // Close above the ground, looking straight down, the view needs level 0 alone: the plan
    // adds the ancestors up to the top level, the top first, and they are all served.
    let down = planner::look_at([100.0, 100.0, 20.0], [100.0, 100.0, 0.0], [0.0, 1.0, 0.0]);
    let close = View { view_proj: planner::mul(&proj, &down), ..view };
    let near = planner::from_camera(&close, &surface, &t, spec.size);
    assert!(!near.is_empty() && near.keys().all(|a| a.level == 0), "{near:?}");
    let plan = planner::plan(&near, &t, spec.size, |_| false, usize::MAX);
    assert_eq!(plan[0].addr, PageAddr { level: top, x: 0, y: 0 });
    let want: Vec<PageAddr> = plan.iter().map(|r| r.addr).collect();
    let (pages, _) = client.pages(&id, &want, &spec).await.unwrap();
    for &a in near.keys() {
        for level in 0..=top {
            let up = planner::ancestor(a, level);
            assert!(pages.iter().any(|p| p.addr == up), "{a:?}'s ancestor at level {level} is fetched");
        }
    }

    // Frame by frame within a budget, as an engine would: held pages are resident.
    let fresh = Client::new(&s.base, 64 << 20);
    let mut frames = 0;
    loop {
        let batch = planner::plan(&feedback, &t, spec.size, |a| fresh.is_cached(&id, a, &spec), 8);
        if batch.is_empty() {
            break;
        }
        if frames == 0 {
            assert_eq!(batch[0].addr.level, top);
        }
        let addrs: Vec<PageAddr> = batch.iter().map(|r| r.addr).collect();
        fresh.pages(&id, &addrs, &spec).await.unwrap();
        frames += 1;
    }
    // Page metatiles bring neighbours too, so it may take fewer frames, never more.
    assert!(frames <= all.len().div_ceil(8), "{frames} frames for {} pages", all.len());
    assert!(feedback.keys().all(|&a| fresh.is_cached(&id, a, &spec)));
}

#[tokio::test]
async fn normal_pages_are_cached_beside_the_colour_pages() {
    let s = serve();
    let id = upload(&s.base).await;
    let client = Client::new(&s.base, 1 << 20);
    let colour = PageSpec { size: 64, border: 4, format: PageFormat::Png, layer: PageLayer::Color };
    let normal = PageSpec { layer: PageLayer::Normal, ..colour };
    let want = [PageAddr { level: 1, x: 1, y: 2 }];
    let (c, _) = client.pages(&id, &want, &colour).await.unwrap();
    let (n, stats) = client.pages(&id, &want, &normal).await.unwrap();
    assert_eq!((stats.hits, stats.requested), (0, 1), "a normal page is not its colour page");
    assert_ne!(c[0].bytes, n[0].bytes);
    let url = client.page_url(&id, want[0], &normal);
    assert!(url.contains("layer=normal"), "{url}");
    let direct = reqwest::get(url).await.unwrap().bytes().await.unwrap();
    assert_eq!(n[0].bytes, direct);
    let (_, stats) = client.pages(&id, &want, &normal).await.unwrap();
    assert_eq!(stats.hits, 1);
}
