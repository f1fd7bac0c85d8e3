//! PNG decoding inflates nothing it does not need. Valid PNGs whose ancillary chunks hold a
//! zlib stream of a GiB of zeros (a colour profile, compressed text) decode with the heap
//! growing by less than a small bound, measured by the counting allocator of this test binary;
//! so do headers declaring more pixel bytes than allowed, which are refused.
//!
//! `cargo test --release -p vtex-synth --test png_bombs`

use flate2::{Compress, Compression, FlushCompress};
use std::alloc::{GlobalAlloc, Layout, System};
use std::sync::atomic::{AtomicUsize, Ordering};
use vtex_synth::pixels::decode_png;
use vtex_synth::Rgba8Image;

/// Heap bytes in use, and the most in use since the last [`peak_growth`].
static CURRENT: AtomicUsize = AtomicUsize::new(0);
static PEAK: AtomicUsize = AtomicUsize::new(0);

struct Counting;

fn grew(n: usize) {
    let now = CURRENT.fetch_add(n, Ordering::SeqCst) + n;
    PEAK.fetch_max(now, Ordering::SeqCst);
}

// SAFETY: every call is forwarded to the system allocator unchanged; only sizes are counted.
unsafe impl GlobalAlloc for Counting {
    unsafe fn alloc(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn alloc_zeroed(&self, layout: Layout) -> *mut u8 {
        let p = unsafe { System.alloc_zeroed(layout) };
        if !p.is_null() {
            grew(layout.size());
        }
        p
    }
    unsafe fn dealloc(&self, p: *mut u8, layout: Layout) {
        unsafe { System.dealloc(p, layout) };
        CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
    }
    unsafe fn realloc(&self, p: *mut u8, layout: Layout, size: usize) -> *mut u8 {
        let q = unsafe { System.realloc(p, layout, size) };
        if !q.is_null() {
            CURRENT.fetch_sub(layout.size(), Ordering::SeqCst);
            grew(size);
        }
        q
    }
}

#[global_allocator]
static ALLOCATOR: Counting = Counting;

/// Runs `f` and returns its result and the most the heap grew while it ran.
fn peak_growth<T>(f: impl FnOnce() -> T) -> (T, usize) {
    let base = CURRENT.load(Ordering::SeqCst);
    PEAK.store(base, Ordering::SeqCst);
    let out = f();
    (out, PEAK.load(Ordering::SeqCst) - base)
}

/// What a bomb may make the heap grow by: the decoder's own buffers, a few hundred KiB.
const BOUND: usize = 2 << 20;

/// A zlib stream of `mib` MiB of zeros in about `mib` KiB: one deflate block of a MiB of zeros,
/// made once and repeated (each copy refers back only to zeros), then an empty final block and
/// the Adler-32 of the whole.
fn zeros_zlib(mib: usize) -> Vec<u8> {
    let mut block = Vec::with_capacity(64 << 10);
    let mut deflate = Compress::new(Compression::best(), false);
    deflate.compress_vec(&vec![0; 1 << 20], &mut block, FlushCompress::Sync).unwrap();
    let mut z = vec![0x78, 0xda];
    for _ in 0..mib {
        z.extend_from_slice(&block);
    }
    z.extend_from_slice(&[0x03, 0x00]);
    // Adler-32 of n zeros: a = 1, b = n mod 65521.
    let b = ((mib as u64) << 20) % 65521;
    z.extend_from_slice(&((b << 16 | 1) as u32).to_be_bytes());
    z
}

/// A chunk: length, type, data, CRC.
fn chunk(kind: &[u8; 4], data: &[u8]) -> Vec<u8> {
    let mut c = (data.len() as u32).to_be_bytes().to_vec();
    c.extend_from_slice(kind);
    c.extend_from_slice(data);
    let mut crc = crc32fast::Hasher::new();
    crc.update(kind);
    crc.update(data);
    c.extend_from_slice(&crc.finalize().to_be_bytes());
    c
}

/// A valid 2 × 2 PNG with `extra` chunks between its header and its pixels.
fn with_chunks(image: &Rgba8Image, extra: &[Vec<u8>]) -> Vec<u8> {
    let png = image.to_png();
    // Signature (8) and IHDR (25): the chunks go right after.
    let mut out = png[..33].to_vec();
    extra.iter().for_each(|c| out.extend_from_slice(c));
    out.extend_from_slice(&png[33..]);
    out
}

/// A PNG's signature and header followed by `extra` alone, as a file cut short in it.
fn png_prefix_with_chunk(image: &Rgba8Image, extra: &[u8]) -> Vec<u8> {
    [&image.to_png()[..33], extra].concat()
}

#[test]
fn inflating_chunks_and_oversized_headers_stay_within_the_bound() {
    let image = Rgba8Image::from_raw(2, 2, (0..16).map(|i| i * 13).collect()).unwrap();
    let gib = zeros_zlib(1024);
    assert!(gib.len() < 4 << 20, "the bomb is {} bytes", gib.len());
    let profile = [b"icc\0\0".as_slice(), &gib].concat();
    let ztxt = [b"Comment\0\0".as_slice(), &gib].concat();
    let itxt = [b"Comment\0\x01\0\0\0".as_slice(), &gib].concat();
    let bombs = [
        ("iCCP", with_chunks(&image, &[chunk(b"iCCP", &profile)])),
        ("zTXt", with_chunks(&image, &vec![chunk(b"zTXt", &ztxt); 4])),
        ("iTXt", with_chunks(&image, &vec![chunk(b"iTXt", &itxt); 4])),
        ("tEXt", with_chunks(&image, &vec![chunk(b"tEXt", &[b"Comment\0".as_slice(), &gib].concat()); 4])),
    ];
    for (what, png) in &bombs {
        let (decoded, growth) = peak_growth(|| decode_png("sample", png));
        assert_eq!(decoded.as_ref().ok(), Some(&image), "{what}: {decoded:?}");
        assert!(growth < BOUND, "{what}: the heap grew by {growth} bytes decoding {} bytes", png.len());
    }
    // A bomb cut short by the end of the file (its chunk's length runs past it) is refused,
    // not handed to the decoder, which would inflate the part that is there.
    let mut cut = png_prefix_with_chunk(&image, &chunk(b"iCCP", &profile));
    cut.truncate(cut.len() - 1000);
    let (decoded, growth) = peak_growth(|| decode_png("sample", &cut));
    assert!(decoded.unwrap_err().to_string().contains("runs past the end"), "a cut-short iCCP");
    assert!(growth < BOUND, "a cut-short iCCP: the heap grew by {growth} bytes");
    // Headers declaring 4096² RGBA at 16 bits (128 MiB decoded) are refused before allocating.
    let mut big = with_chunks(&image, &[]);
    let ihdr = [4096u32.to_be_bytes(), 4096u32.to_be_bytes()].concat();
    big.splice(8..33, chunk(b"IHDR", &[ihdr.as_slice(), &[16, 6, 0, 0, 0]].concat()));
    let (decoded, growth) = peak_growth(|| decode_png("sample", &big));
    assert!(decoded.unwrap_err().to_string().contains("134217728 bytes"));
    assert!(growth < BOUND, "oversized header: the heap grew by {growth} bytes");
}
