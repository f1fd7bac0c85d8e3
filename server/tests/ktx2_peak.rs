//! What encoding a KTX2 page or mip chain really holds at its peak. Basis Universal's encoder
//! is C++ and allocates with `malloc`, out of sight of a counting Rust allocator, so this test
//! measures the process's resident memory instead: the kernel's high-water mark
//! (`VmHWM`, reset through `/proc/self/clear_refs`) over the resident set before the encode,
//! with the C heap trimmed so that no freed page is reused unseen. One test in its own binary:
//! nothing else runs while it measures.

use rand::{Rng, SeedableRng};
use vtex_server::api::resources::pages::{MAX_BASIS_CHAIN_SIDE, MAX_CHAIN_SIDE, PAGE_SIZES};
use vtex_server::ktx2::{self, Codec, Ktx2, Rdo, Supercompression, Transfer};
use vtex_synth::texture::MAX_RENDER_WORKING_BYTES;
use vtex_synth::Rgba8Image;

/// The largest page's side: the largest size and its largest border (size / 8) on each side.
const LARGEST_PAGE: u32 = PAGE_SIZES[PAGE_SIZES.len() - 1] * 5 / 4;

fn status_kib(field: &str) -> u64 {
    let status = std::fs::read_to_string("/proc/self/status").expect("reads /proc/self/status");
    let line = status.lines().find(|l| l.starts_with(field)).unwrap_or_else(|| panic!("no {field}"));
    line.split_whitespace().nth(1).and_then(|v| v.parse().ok()).expect("a number of kB")
}

/// Resident bytes at the peak of `run`, over those resident before it.
fn resident_peak(run: impl FnOnce()) -> u64 {
    // Unsafe: a plain call into glibc, which returns the free pages of its arenas to the system.
    #[allow(unsafe_code)]
    unsafe {
        libc::malloc_trim(0);
    }
    std::fs::write("/proc/self/clear_refs", "5").expect("resets the high-water mark");
    let before = status_kib("VmRSS:");
    run();
    (status_kib("VmHWM:").saturating_sub(before)) * 1024
}

/// Noise (which no encoder simplifies) over a chain's levels, `side` the first's.
fn noise_chain(side: u32, levels: usize) -> Vec<Rgba8Image> {
    let mut rng = rand::rngs::StdRng::seed_from_u64(11);
    (0..levels)
        .map(|i| {
            let s = (side >> i).max(1);
            let mut img = Rgba8Image::new(s, s);
            rng.fill(&mut img.data[..]);
            img.data.chunks_exact_mut(4).for_each(|px| px[3] = 255);
            img
        })
        .collect()
}

fn chain_len(side: u32) -> usize {
    (32 - side.leading_zeros()) as usize
}

/// What is measured: each codec and supercompression served, with and without UASTC's RDO, at
/// the largest page and chain. Basis Universal's own memory does not depend on the
/// supercompression that follows it (zstd runs on its output, and has its own term), so UASTC
/// is measured without zstd at the page and with it at the chain. BC7's chain is 1024²: its
/// third search pass takes some 40 s on a 2048² chain of noise, and a chain holds fewer bytes a
/// pixel than the page.
fn cases() -> Vec<(Ktx2, &'static str, u32, usize)> {
    use Codec::*;
    use Supercompression::{BasisLz, None as Plain, Zstd};
    // A case's first level's side and its number of levels.
    let page = || (LARGEST_PAGE, 1);
    let chain = |side: u64| (side as u32, chain_len(side as u32));
    let rdo = Ktx2 { rdo: Rdo::parse("3"), ..Ktx2::new(Uastc, Zstd) };
    let bc5 = |sc| Ktx2 { transfer: Transfer::Linear, ..Ktx2::new(Bc5, sc) };
    let mut all = Vec::new();
    for k in [Ktx2::new(Bc7, Plain), Ktx2::new(Bc7, Zstd), Ktx2::new(Uastc, Plain), rdo, Ktx2::new(Etc1s, BasisLz)] {
        let (side, levels) = page();
        all.push((k, "page", side, levels));
    }
    let (side, levels) = chain(MAX_CHAIN_SIDE / 2);
    all.push((Ktx2::new(Bc7, Plain), "chain", side, levels));
    for k in [
        Ktx2::new(Bc1, Plain),
        Ktx2::new(Bc1, Zstd),
        bc5(Plain),
        bc5(Zstd),
        Ktx2::new(Rgba8, Plain),
        Ktx2::new(Rgba8, Zstd),
    ] {
        let (side, levels) = page();
        all.push((k, "page", side, levels));
        let (side, levels) = chain(MAX_CHAIN_SIDE);
        all.push((k, "chain", side, levels));
    }
    for k in [Ktx2::new(Uastc, Zstd), rdo, Ktx2::new(Etc1s, BasisLz)] {
        let (side, levels) = chain(MAX_BASIS_CHAIN_SIDE);
        all.push((k, "chain", side, levels));
    }
    all
}

/// A page is encoded on its synthesis slot once its render has returned, and the page cache
/// holds its body: the encoding's working memory must fit in what a slot may hold.
#[test]
fn ktx2_encoding_holds_no_more_than_its_bound() {
    // Fixed thresholds: large blocks are mapped and unmapped, the heap's top is returned.
    #[allow(unsafe_code)]
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 128 << 10);
        libc::mallopt(libc::M_TRIM_THRESHOLD, 128 << 10);
    }
    let mut over = Vec::new();
    for (k, what, side, levels) in cases() {
        let images = noise_chain(side, levels);
        // Once small, to fault in the code and the tables built on first use (Basis
        // Universal's are global, made once per process).
        ktx2::encode(&noise_chain(64, 1), k).expect("encodes");
        let pixels: u64 = images.iter().map(|i| i.width as u64 * i.height as u64).sum();
        let held = resident_peak(|| drop(ktx2::encode(&images, k).expect("encodes")));
        let bound = ktx2::working_bytes(k, pixels);
        let rdo = if k.rdo.is_some() { " rdo" } else { "" };
        let name = format!("{} {}{rdo} {what} of {}²", k.codec.name(), k.supercompression.name(), images[0].width);
        println!("{name}: held {held} ({:.1} B/px), bound {bound}", held as f64 / pixels as f64);
        if held > bound {
            over.push(format!("{name}: {held} held > {bound}"));
        }
        if what == "page" && bound > MAX_RENDER_WORKING_BYTES {
            over.push(format!("{name}: a bound of {bound} exceeds a slot's {MAX_RENDER_WORKING_BYTES}"));
        }
    }
    assert!(over.is_empty(), "{over:#?}");
}
