//! Pages per second through `vtex-client`: [`Client::pages`] (a block of pages, so whole page
//! metatiles) beside a baseline from the same run, one request per page to the single-page endpoint on
//! one keep-alive connection. Each is measured cold (pages the server has never made: a block
//! of level-0 pages of its own) and warm (the same block again, from the server's cache); every
//! run starts with an empty client cache, so every page crosses the network.
//!
//! ```sh
//! cargo run --release -p vtex-client --example page_rate -- http://127.0.0.1:8080 [pages] [name]
//! ```

use std::time::Instant;
use vtex_client::{Client, PageAddr, PageSpec};

/// A `side`² block of level-0 pages whose top-left page is (`x`, `y`).
fn block(x: u32, y: u32, side: u32) -> Vec<PageAddr> {
    (0..side * side).map(|i| PageAddr { level: 0, x: x + i % side, y: y + i / side }).collect()
}

/// Fetches `addrs` one request each, in order; returns the bytes received.
async fn one_by_one(
    http: &reqwest::Client,
    client: &Client,
    texture: &str,
    addrs: &[PageAddr],
    spec: &PageSpec,
) -> Result<u64, Box<dyn std::error::Error>> {
    let mut bytes = 0;
    for &a in addrs {
        let r = http.get(client.page_url(texture, a, spec)).send().await?.error_for_status()?;
        bytes += r.bytes().await?.len() as u64;
    }
    Ok(bytes)
}

#[tokio::main]
async fn main() -> Result<(), Box<dyn std::error::Error>> {
    let args: Vec<String> = std::env::args().collect();
    let base = args.get(1).map_or("http://127.0.0.1:8080", String::as_str);
    let pages: u32 = args.get(2).map_or(Ok(512), |s| s.parse())?;
    let name = args.get(3).map_or("Pebbles — chaos mosaic 100k", String::as_str);
    let side = (pages as f64).sqrt().ceil() as u32;
    let tex = Client::new(base, 0).textures().await?.into_iter().find(|t| t.name == name);
    let tex = tex.ok_or_else(|| format!("no texture named {name}"))?;
    let spec = PageSpec::default();
    let http = reqwest::Client::new();
    println!(
        "{}: {} level-0 pages a run ({side}² block), 128² + 4 px borders, BC7 KTX2, a fresh client cache each run",
        tex.name,
        side * side
    );
    println!("{:<34} {:>9} {:>9} {:>9}", "run", "seconds", "pages/s", "MB/s");
    // Blocks far apart, so the two cold runs share no page.
    for (temperature, offset) in [("cold", 100), ("warm", 100)] {
        let blocked = block(offset, offset, side);
        let single = block(offset + 2 * side, offset, side);
        for (how, addrs) in [("Client::pages (metatiles)", &blocked), ("one request per page", &single)] {
            let client = Client::new(base, 1 << 30);
            let t0 = Instant::now();
            let bytes = if how.starts_with("Client") {
                client.pages(&tex.id, addrs, &spec).await?.1.bytes
            } else {
                one_by_one(&http, &client, &tex.id, addrs, &spec).await?
            };
            let s = t0.elapsed().as_secs_f64();
            println!(
                "{:<34} {s:>9.2} {:>9.0} {:>9.1}",
                format!("{how}, {temperature}"),
                addrs.len() as f64 / s,
                bytes as f64 / 1e6 / s
            );
        }
    }
    Ok(())
}
