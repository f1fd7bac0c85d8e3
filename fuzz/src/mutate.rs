//! Mutations. Byte-level changes come from `mutatis` (its `Vec<u8>` mutator: insert, remove,
//! change); on top of them are the structure-aware ones no crate knows: JSON values, PNG chunks
//! (lengths, types, CRCs, zlib streams) and the bundle container's length fields.

use rand::rngs::StdRng;
use rand::seq::IndexedRandom;
use rand::Rng;
use serde_json::Value;
use std::sync::LazyLock;

/// Largest input a mutation makes: the bundle container's own bound.
pub const MAX_INPUT: usize = vtex_synth::bundle::MAX_BUNDLE_BYTES;

/// Values that sit on edges of integer parsers and size checks.
const INTERESTING: [u64; 16] = [
    0,
    1,
    2,
    7,
    0x7f,
    0x80,
    0xff,
    0x100,
    0xffff,
    0x1_0000,
    4096,
    4097,
    0x7fff_ffff,
    0x8000_0000,
    0xffff_ffff,
    u64::MAX,
];

/// Changes a few bytes of `data` in one random window, with `mutatis`; sometimes writes an
/// interesting integer, repeats a span or truncates.
pub fn bytes(rng: &mut StdRng, session: &mut mutatis::Session, data: &mut Vec<u8>) {
    match rng.random_range(0..8) {
        0 if !data.is_empty() => {
            let at = rng.random_range(0..data.len());
            let width = *[1usize, 2, 4, 8].choose(rng).unwrap();
            let v = *INTERESTING.choose(rng).unwrap();
            let b = if rng.random_bool(0.5) { v.to_le_bytes() } else { v.to_be_bytes() };
            let src = if rng.random_bool(0.5) { &b[..width] } else { &b[8 - width..] };
            for (i, &x) in src.iter().enumerate() {
                if let Some(d) = data.get_mut(at + i) {
                    *d = x;
                }
            }
        }
        1 if !data.is_empty() => {
            let from = rng.random_range(0..data.len());
            let len = rng.random_range(1..=(data.len() - from).min(256));
            let span = data[from..from + len].to_vec();
            let at = rng.random_range(0..=data.len());
            for _ in 0..rng.random_range(1..=8) {
                if data.len() + span.len() > MAX_INPUT {
                    break;
                }
                data.splice(at..at, span.iter().copied());
            }
        }
        2 if !data.is_empty() => data.truncate(rng.random_range(0..data.len())),
        _ => {
            let start = rng.random_range(0..=data.len());
            let end = (start + rng.random_range(0..=16)).min(data.len());
            let mut window: Vec<u8> = data[start..end].to_vec();
            for _ in 0..rng.random_range(1..=3) {
                let _ = session.mutate(&mut window);
            }
            data.splice(start..end, window);
        }
    }
}

/// Changes one node of a JSON document: a number to an edge value, a string's bytes, an
/// array's length, an object's keys, or a node's type.
pub fn json(rng: &mut StdRng, session: &mut mutatis::Session, doc: &mut Value) {
    let mut count = 0usize;
    visit(doc, &mut |_| count += 1);
    let Some(node) = nth_mut(doc, &mut rng.random_range(0..count)) else { return };
    if rng.random_ratio(1, 8) {
        *node = any_value(rng);
        return;
    }
    match node {
        Value::Number(n) => *node = number(rng, session, n.as_f64().unwrap_or(0.0)),
        Value::String(s) => {
            let mut b = s.clone().into_bytes();
            bytes(rng, session, &mut b);
            *s = String::from_utf8_lossy(&b).into_owned();
        }
        Value::Array(a) => match rng.random_range(0..3) {
            0 if !a.is_empty() => {
                let i = rng.random_range(0..a.len());
                let copies = *[1usize, 2, 15, 16, 17, 64, 255, 1000].choose(rng).unwrap();
                let item = a[i].clone();
                a.extend(std::iter::repeat_n(item, copies));
            }
            1 if !a.is_empty() => {
                a.remove(rng.random_range(0..a.len()));
            }
            _ => a.reverse(),
        },
        Value::Object(o) => match rng.random_range(0..3) {
            0 if !o.is_empty() => {
                let k = o.keys().nth(rng.random_range(0..o.len())).unwrap().clone();
                o.remove(&k);
            }
            1 => {
                o.insert("unknown".into(), any_value(rng));
            }
            _ => *node = any_value(rng),
        },
        Value::Bool(b) => *b = !*b,
        Value::Null => *node = any_value(rng),
    }
}

fn number(rng: &mut StdRng, session: &mut mutatis::Session, old: f64) -> Value {
    let v: f64 = match rng.random_range(0..6) {
        0 => *INTERESTING.choose(rng).unwrap() as f64,
        1 => -(*INTERESTING.choose(rng).unwrap() as f64),
        2 => old * *[2.0, 10.0, 1000.0, 0.5, -1.0, 1e6].choose(rng).unwrap(),
        3 => old + *[1.0, -1.0, 0.5, -0.5].choose(rng).unwrap(),
        4 => *[1e300, -1e300, f64::MIN_POSITIVE, 1e-300, 0.1, 4.5e15, 9.007_199_254_740_993e15].choose(rng).unwrap(),
        _ => {
            let mut x = old as i64;
            let _ = session.mutate(&mut x);
            x as f64
        }
    };
    if v.fract() == 0.0 && v.abs() < 1.8e19 {
        if v >= 0.0 {
            return Value::from(v as u64);
        }
        if v >= i64::MIN as f64 {
            return Value::from(v as i64);
        }
    }
    serde_json::Number::from_f64(v).map(Value::Number).unwrap_or(Value::Null)
}

fn any_value(rng: &mut StdRng) -> Value {
    match rng.random_range(0..7) {
        0 => Value::Null,
        1 => Value::Bool(rng.random()),
        2 => Value::from(*INTERESTING.choose(rng).unwrap()),
        3 => Value::from(-1),
        4 => Value::from(*["", "x", "gauss", "explicit", "logistic", "\u{0}", "é"].choose(rng).unwrap()),
        5 => Value::Array(vec![]),
        _ => Value::Object(Default::default()),
    }
}

fn visit(v: &Value, f: &mut impl FnMut(&Value)) {
    f(v);
    match v {
        Value::Array(a) => a.iter().for_each(|x| visit(x, f)),
        Value::Object(o) => o.values().for_each(|x| visit(x, f)),
        _ => {}
    }
}

/// The `n`th node of `v` in pre-order.
fn nth_mut<'a>(v: &'a mut Value, n: &mut usize) -> Option<&'a mut Value> {
    if *n == 0 {
        return Some(v);
    }
    *n -= 1;
    match v {
        Value::Array(a) => a.iter_mut().find_map(|x| nth_mut(x, n)),
        Value::Object(o) => o.values_mut().find_map(|x| nth_mut(x, n)),
        _ => None,
    }
}

pub const PNG_SIGNATURE: &[u8; 8] = b"\x89PNG\r\n\x1a\n";

/// One PNG chunk; `crc` is recomputed on writing unless set.
#[derive(Clone, Debug)]
pub struct Chunk {
    pub ty: [u8; 4],
    pub data: Vec<u8>,
    pub crc: Option<u32>,
}

impl Chunk {
    pub fn new(ty: &[u8; 4], data: Vec<u8>) -> Chunk {
        Chunk { ty: *ty, data, crc: None }
    }
}

/// Splits a PNG into chunks; `None` when it is not one (then it is mutated as bytes).
pub fn png_chunks(bytes: &[u8]) -> Option<Vec<Chunk>> {
    let mut rest = bytes.strip_prefix(PNG_SIGNATURE)?;
    let mut chunks = Vec::new();
    while !rest.is_empty() {
        let len = u32::from_be_bytes(rest.get(..4)?.try_into().ok()?) as usize;
        let body = rest.get(4..8 + len + 4)?;
        let ty: [u8; 4] = body[..4].try_into().ok()?;
        chunks.push(Chunk::new(&ty, body[4..4 + len].to_vec()));
        rest = &rest[12 + len..];
    }
    Some(chunks)
}

pub fn png_bytes(chunks: &[Chunk]) -> Vec<u8> {
    let mut out = PNG_SIGNATURE.to_vec();
    for c in chunks {
        out.extend_from_slice(&(c.data.len() as u32).to_be_bytes());
        out.extend_from_slice(&c.ty);
        out.extend_from_slice(&c.data);
        let mut h = crc32fast::Hasher::new();
        h.update(&c.ty);
        h.update(&c.data);
        out.extend_from_slice(&c.crc.unwrap_or_else(|| h.finalize()).to_be_bytes());
    }
    out
}

/// Chunk types a decoder reads or must skip, including the compressed ancillary ones.
const CHUNK_TYPES: [&[u8; 4]; 18] = [
    b"IHDR", b"PLTE", b"IDAT", b"IEND", b"tRNS", b"iCCP", b"zTXt", b"iTXt", b"tEXt", b"gAMA", b"sRGB", b"cHRM",
    b"bKGD", b"pHYs", b"acTL", b"fcTL", b"fdAT", b"eXIf",
];

/// A zlib stream of `n` zero bytes.
fn zeros_stream(n: usize) -> Vec<u8> {
    miniz_oxide::deflate::compress_to_vec_zlib(&vec![0u8; n], 6)
}

/// Zlib streams for compressed chunks: small, truncated, not zlib, and ones that inflate past
/// every image bound.
static STREAMS: LazyLock<Vec<Vec<u8>>> = LazyLock::new(|| {
    let small = miniz_oxide::deflate::compress_to_vec_zlib(b"vtex fuzz text", 6);
    let bomb = zeros_stream((vtex_synth::pixels::MAX_IMAGE_ALLOC as usize) * 2);
    vec![small.clone(), small[..small.len() / 2].to_vec(), b"not zlib".to_vec(), zeros_stream(1 << 20), bomb]
});

/// A compressed ancillary chunk (iCCP, zTXt, iTXt) around one of [`STREAMS`].
fn compressed_chunk(rng: &mut StdRng) -> Chunk {
    let stream = STREAMS.choose(rng).unwrap().clone();
    match rng.random_range(0..3) {
        0 => Chunk::new(b"iCCP", [b"icc\0\0".as_slice(), &stream].concat()),
        1 => Chunk::new(b"zTXt", [b"Comment\0\0".as_slice(), &stream].concat()),
        _ => Chunk::new(b"iTXt", [b"Comment\0\x01\0en\0Comment\0".as_slice(), &stream].concat()),
    }
}

/// One chunk-aware change to a PNG: chunk data (CRC fixed), a wrong CRC, a lying length, a
/// chunk's type, chunk order, a compressed ancillary chunk, IHDR fields, or the image data
/// re-inflated, changed and re-deflated (sometimes split over several IDATs).
pub fn png(rng: &mut StdRng, session: &mut mutatis::Session, bytes: &mut Vec<u8>) {
    let Some(mut chunks) = png_chunks(bytes).filter(|c| !c.is_empty()) else {
        return self::bytes(rng, session, bytes);
    };
    let i = rng.random_range(0..chunks.len());
    match rng.random_range(0..11) {
        0 => self::bytes(rng, session, &mut chunks[i].data),
        1 => chunks[i].crc = Some(rng.random()),
        2 => {
            // A length field that disagrees with the data that follows.
            let mut out = png_bytes(&chunks);
            let at = 8 + chunks[..i].iter().map(|c| 12 + c.data.len()).sum::<usize>();
            let len = *INTERESTING.choose(rng).unwrap() as u32;
            out[at..at + 4].copy_from_slice(&len.to_be_bytes());
            *bytes = out;
            return;
        }
        3 => chunks[i].ty = **CHUNK_TYPES.choose(rng).unwrap(),
        4 => {
            let c = chunks.remove(i);
            if rng.random_bool(0.5) {
                let j = rng.random_range(0..=chunks.len());
                chunks.insert(j, c.clone());
                chunks.insert(rng.random_range(0..=chunks.len()), c);
            }
        }
        5 | 6 => {
            let c = compressed_chunk(rng);
            chunks.insert(rng.random_range(1.min(chunks.len())..=chunks.len()), c);
        }
        7 if chunks[i].ty == *b"IHDR" && chunks[i].data.len() == 13 => {
            let d = &mut chunks[i].data;
            match rng.random_range(0..4) {
                0 | 1 => {
                    let at = if rng.random_bool(0.5) { 0 } else { 4 };
                    let v = *INTERESTING.choose(rng).unwrap() as u32;
                    d[at..at + 4].copy_from_slice(&v.to_be_bytes());
                }
                2 => d[8] = *[0u8, 1, 2, 3, 4, 8, 16, 32].choose(rng).unwrap(),
                _ => d[9 + rng.random_range(0..4)] = *[0u8, 1, 2, 3, 4, 6, 7].choose(rng).unwrap(),
            }
        }
        8..=10 => idat(rng, session, &mut chunks),
        _ => self::bytes(rng, session, &mut chunks[i].data),
    }
    *bytes = png_bytes(&chunks);
}

/// Re-inflates the image data, changes it (filter bytes included) and writes it back as one or
/// several IDAT chunks.
fn idat(rng: &mut StdRng, session: &mut mutatis::Session, chunks: &mut Vec<Chunk>) {
    let Some(first) = chunks.iter().position(|c| c.ty == *b"IDAT") else { return };
    let stream: Vec<u8> = chunks.iter().filter(|c| c.ty == *b"IDAT").flat_map(|c| c.data.iter().copied()).collect();
    let Ok(mut raw) = miniz_oxide::inflate::decompress_to_vec_zlib_with_limit(&stream, 64 << 20) else { return };
    match rng.random_range(0..3) {
        0 => bytes(rng, session, &mut raw),
        1 => raw.truncate(rng.random_range(0..=raw.len())),
        _ => raw.extend(std::iter::repeat_n(rng.random::<u8>(), rng.random_range(1..4096))),
    }
    let data = miniz_oxide::deflate::compress_to_vec_zlib(&raw, 1);
    chunks.retain(|c| c.ty != *b"IDAT");
    let parts = rng.random_range(1..=4usize);
    let step = data.len().div_ceil(parts).max(1);
    for (k, part) in data.chunks(step).enumerate() {
        chunks.insert((first + k).min(chunks.len()), Chunk::new(b"IDAT", part.to_vec()));
    }
}

/// Offsets and widths of the bundle container's integer fields (version, manifest length,
/// section count, each section's name length and data length), as far as the bytes go.
pub fn bundle_fields(b: &[u8]) -> Vec<(usize, usize)> {
    let mut fields = vec![(8, 4), (12, 4)];
    let u32_at = |at: usize| b.get(at..at + 4).map(|s| u32::from_le_bytes(s.try_into().unwrap()) as usize);
    let Some(mlen) = u32_at(12) else { return fields };
    let mut at = 16 + mlen;
    fields.push((at, 4));
    let Some(count) = u32_at(at) else { return fields };
    at += 4;
    for _ in 0..count.min(64) {
        let Some(&nlen) = b.get(at) else { break };
        fields.push((at, 1));
        at += 1 + nlen as usize;
        fields.push((at, 8));
        let Some(len) = b.get(at..at + 8).map(|s| u64::from_le_bytes(s.try_into().unwrap())) else { break };
        at = at.saturating_add(8).saturating_add(len as usize);
    }
    fields
}

/// Overwrites one container field with an interesting value.
pub fn bundle_field(rng: &mut StdRng, bytes: &mut [u8]) {
    let fields = bundle_fields(bytes);
    let &(at, width) = fields.choose(rng).unwrap();
    let v = *INTERESTING.choose(rng).unwrap();
    let v = if rng.random_bool(0.3) { v.wrapping_add(rng.random_range(0..3)).wrapping_sub(1) } else { v };
    for (i, b) in v.to_le_bytes()[..width].iter().enumerate() {
        if let Some(d) = bytes.get_mut(at + i) {
            *d = *b;
        }
    }
}
