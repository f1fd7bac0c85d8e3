//! GPU-ready images: BC7, BC1, plain RGBA8 or Basis Universal (UASTC, ETC1S) in a KTX2
//! container (Khronos KTX 2.0), optionally zstd-supercompressed (ETC1S: always BasisLZ), with one
//! mip level or a whole chain.
//!
//! Every byte is a pure function of the pixels and [`Ktx2`]: the block encoder
//! (`block_compression`, a scalar Rust port of Intel's ISPC kernels, used without its GPU
//! path) runs on one thread with IEEE `f32` arithmetic and `sqrt` only — no SIMD dispatch on
//! the CPU it meets, no platform maths library — and zstd is libzstd at a fixed version
//! (vendored by `zstd-sys`, pinned by the lock file), single-threaded, at a fixed level. So a
//! page is the same bytes on every run, thread count, replica and machine; the tests pin them.
//! The prebuilt ISPC encoders on crates.io (Intel's kernels, Binomial's bc7e) are not used for
//! that reason: they choose SSE2, AVX2 or AVX-512 code on the CPU they meet, whose results
//! differ (fused multiply-adds), and bc7e divides by an approximate reciprocal (`rcpps`),
//! whose low bits differ between CPU makers.
//! The Basis Universal codecs are Binomial's C++ encoder, run on the calling thread without its
//! SIMD kernels ([`basis`] says why that makes it a function of the pixels); their bytes are
//! pinned on x86-64, where the C++ compiler contracts no multiply-add.
//!
//! Colours are sRGB-encoded, as the models produce them, so their formats are the `_SRGB` ones
//! and a GPU samples and filters them in linear light; linear data (normals) take the `_UNORM`
//! formats and a linear transfer function ([`Transfer`]).

mod basis;

use block_compression::decode::decompress_blocks_as_rgba8;
use block_compression::{encode::compress_rgba8, BC7Settings, CompressionVariant};
use vtex_synth::Rgba8Image;

/// The texel encoding inside the container.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Codec {
    /// BC7 (BPTC), 16 bytes per 4×4 block: near-lossless colour and alpha ([`encode_bc7`]).
    Bc7,
    /// BC1 (DXT1), 8 bytes per 4×4 block: opaque colour, twice BC7's compression.
    Bc1,
    /// BC5 (RGTC2), 16 bytes per 4×4 block: two independent linear channels, R and G — a
    /// normal's X and Y, Z being √(1 − X² − Y²). Linear data only.
    Bc5,
    /// Uncompressed RGBA8, for GPUs without BC formats (WebGL on most phones).
    Rgba8,
    /// Basis Universal UASTC (LDR 4×4), 16 bytes a block, transcoded by the client to the
    /// GPU's format (ASTC, BC7, ETC2, …) with little loss.
    Uastc,
    /// Basis Universal ETC1S with BasisLZ supercompression: the smallest files, transcoded by
    /// the client to any GPU format, at a visible loss.
    Etc1s,
}

impl Codec {
    pub const EXPECTED: &'static str = "expected bc7, bc1, bc5, rgba8, uastc or etc1s";

    pub fn parse(s: &str) -> Option<Codec> {
        match s {
            "bc7" => Some(Codec::Bc7),
            "bc1" => Some(Codec::Bc1),
            "bc5" => Some(Codec::Bc5),
            "rgba8" => Some(Codec::Rgba8),
            "uastc" => Some(Codec::Uastc),
            "etc1s" => Some(Codec::Etc1s),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Codec::Bc7 => "bc7",
            Codec::Bc1 => "bc1",
            Codec::Bc5 => "bc5",
            Codec::Rgba8 => "rgba8",
            Codec::Uastc => "uastc",
            Codec::Etc1s => "etc1s",
        }
    }

    /// Whether texels come in 4×4 blocks (so an atlas slot must be a multiple of 4).
    pub fn is_block_compressed(self) -> bool {
        self != Codec::Rgba8
    }

    /// Whether the texels are Basis Universal's, which a client transcodes.
    pub fn is_basis(self) -> bool {
        matches!(self, Codec::Uastc | Codec::Etc1s)
    }

    /// The supercompression a codec takes: ETC1S is always BasisLZ, which no other codec takes.
    pub fn check(self, sc: Supercompression) -> Result<(), String> {
        match (self, sc) {
            (Codec::Etc1s, Supercompression::BasisLz) => Ok(()),
            (Codec::Etc1s, _) => Err(format!(
                "etc1s is always BasisLZ-supercompressed: leave `supercompression` out or give basislz (got {})",
                sc.name()
            )),
            (_, Supercompression::BasisLz) => {
                Err(format!("supercompression basislz applies to codec etc1s only (got codec {})", self.name()))
            }
            _ => Ok(()),
        }
    }

    /// The supercompression a codec takes when none is asked for.
    pub fn default_supercompression(self) -> Supercompression {
        match self {
            Codec::Etc1s => Supercompression::BasisLz,
            _ => Supercompression::None,
        }
    }

    /// `VkFormat` of the container header: `VK_FORMAT_UNDEFINED` for Basis Universal, whose
    /// format the DFD names.
    fn vk_format(self, transfer: Transfer) -> u32 {
        match (self, transfer) {
            (Codec::Bc7, Transfer::Srgb) => 146,    // VK_FORMAT_BC7_SRGB_BLOCK
            (Codec::Bc7, Transfer::Linear) => 145,  // VK_FORMAT_BC7_UNORM_BLOCK
            (Codec::Bc1, Transfer::Srgb) => 132,    // VK_FORMAT_BC1_RGB_SRGB_BLOCK
            (Codec::Bc1, Transfer::Linear) => 131,  // VK_FORMAT_BC1_RGB_UNORM_BLOCK
            (Codec::Bc5, _) => 141,                 // VK_FORMAT_BC5_UNORM_BLOCK (no sRGB form)
            (Codec::Rgba8, Transfer::Srgb) => 43,   // VK_FORMAT_R8G8B8A8_SRGB
            (Codec::Rgba8, Transfer::Linear) => 37, // VK_FORMAT_R8G8B8A8_UNORM
            (Codec::Uastc | Codec::Etc1s, _) => 0,
        }
    }

    /// Bytes of one texel block (4×4 texels, or one texel for RGBA8).
    fn block_bytes(self) -> usize {
        match self {
            Codec::Bc7 | Codec::Bc5 | Codec::Uastc => 16,
            Codec::Bc1 | Codec::Etc1s => 8,
            Codec::Rgba8 => 4,
        }
    }

    /// The bytes of each level, and the supercompression global data: blocks in row-major
    /// order (edge blocks padded by repeating the last column and row, as the format requires
    /// whole blocks), or the pixels themselves; Basis Universal's levels as [`basis`] makes them.
    fn encode_levels(
        self,
        levels: &[Rgba8Image],
        transfer: Transfer,
        rdo: Option<Rdo>,
    ) -> Result<basis::Levels, String> {
        let alpha = false; // only the Basis DFDs depend on it
        let one = |f: fn(&Rgba8Image) -> Vec<u8>| basis::Levels {
            levels: levels.iter().map(f).collect(),
            global: None,
            alpha,
        };
        Ok(match self {
            Codec::Rgba8 => one(|l| l.data.clone()),
            Codec::Bc1 => one(|l| compress(CompressionVariant::BC1, &pad_to_blocks(l))),
            Codec::Bc5 => one(|l| compress(CompressionVariant::BC5, &pad_to_blocks(l))),
            Codec::Bc7 => one(|l| encode_bc7(&pad_to_blocks(l))),
            Codec::Uastc => basis::encode(levels, basis::Mode::Uastc { rdo: rdo.map(Rdo::lambda) }, transfer)?,
            Codec::Etc1s => basis::encode(levels, basis::Mode::Etc1s, transfer)?,
        })
    }
}

/// The blocks of `img` (sides multiples of 4) in `variant`.
fn compress(variant: CompressionVariant, img: &Rgba8Image) -> Vec<u8> {
    let mut out = vec![0u8; variant.blocks_byte_size(img.width, img.height)];
    compress_rgba8(variant, &img.data, &mut out, img.width, img.height, img.width * 4);
    out
}

/// Squared error of a 4×4 block's decoded texels against its source, all four channels, over
/// which a BC7 block is encoded again with the very fast mode search: 6 × 16 × 4, a mean
/// squared error of 6 a channel (40 dB for the block).
const BC7_RETRY_ERROR: u64 = 6 * 16 * 4;

/// The error over which a block, after the very fast search, is encoded once more with the
/// basic search: a mean squared error of 24 a channel (34 dB for the block). Only blocks of
/// dense, high-contrast detail stay over it (a noisy texture's coarse levels); the basic
/// search adds the three-subset modes and the separate-channel modes, which fit them better.
const BC7_WIDE_RETRY_ERROR: u64 = 24 * 16 * 4;

/// BC7 in up to three passes: every block with the encoder's fastest mode search, then blocks
/// whose error is over [`BC7_RETRY_ERROR`] again with its very fast search, then those still
/// over [`BC7_WIDE_RETRY_ERROR`] with its basic search, each time keeping the better. Most
/// blocks of a texture take the first; those with sharp colour edges the second, which costs
/// far more; the third, slower still, is spent only on the few blocks where the format's
/// richer modes pay (docs/ktx2-quality.md weighs the thresholds). Every pass is a pure
/// function of the pixels.
fn encode_bc7(img: &Rgba8Image) -> Vec<u8> {
    let opaque = img.data.chunks_exact(4).all(|p| p[3] == 255);
    let passes = if opaque {
        [BC7Settings::opaque_ultra_fast(), BC7Settings::opaque_very_fast(), BC7Settings::opaque_basic()]
    } else {
        [BC7Settings::alpha_ultrafast(), BC7Settings::alpha_very_fast(), BC7Settings::alpha_basic()]
    };
    let retries = [(BC7_RETRY_ERROR, passes[1]), (BC7_WIDE_RETRY_ERROR, passes[2])];
    let mut blocks = compress(CompressionVariant::BC7(passes[0]), img);
    let cols = img.width as usize / 4;
    for (i, block) in blocks.chunks_exact_mut(16).enumerate() {
        let src = img.crop((i % cols) as u32 * 4, (i / cols) as u32 * 4, 4, 4);
        let mut err = block_error(block, &src);
        for (threshold, settings) in retries {
            if err <= threshold {
                break;
            }
            let again = compress(CompressionVariant::BC7(settings), &src);
            let again_err = block_error(&again, &src);
            if again_err < err {
                block.copy_from_slice(&again);
                err = again_err;
            }
        }
    }
    blocks
}

/// Squared error of one decoded BC7 block against its 4×4 source.
fn block_error(block: &[u8], src: &Rgba8Image) -> u64 {
    let mut texels = [0u8; 64];
    decompress_blocks_as_rgba8(CompressionVariant::BC7(BC7Settings::opaque_ultra_fast()), 4, 4, block, &mut texels);
    texels.iter().zip(&src.data).map(|(&a, &b)| (a as i64 - b as i64).pow(2) as u64).sum()
}

/// Whether each level's bytes are zstd-compressed (KTX2 supercompression scheme 2), or BasisLZ
/// (scheme 1, ETC1S only, whose codebooks are the file's global data).
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Supercompression {
    None,
    Zstd,
    BasisLz,
}

impl Supercompression {
    pub const EXPECTED: &'static str = "expected none, zstd or basislz (etc1s only)";

    pub fn parse(s: &str) -> Option<Supercompression> {
        match s {
            "none" => Some(Supercompression::None),
            "zstd" => Some(Supercompression::Zstd),
            "basislz" => Some(Supercompression::BasisLz),
            _ => None,
        }
    }

    pub fn name(self) -> &'static str {
        match self {
            Supercompression::None => "none",
            Supercompression::Zstd => "zstd",
            Supercompression::BasisLz => "basislz",
        }
    }

    /// `supercompressionScheme` of the header.
    fn scheme(self) -> u32 {
        match self {
            Supercompression::None => 0,
            Supercompression::BasisLz => 1,
            Supercompression::Zstd => 2,
        }
    }
}

/// The zstd level: near the best ratio on block-compressed data at a few ms a page.
const ZSTD_LEVEL: i32 = 9;

/// What zstd's context holds at [`ZSTD_LEVEL`], whatever the input's size (its tables are
/// sized by the level and capped by its window).
const ZSTD_CONTEXT_BYTES: u64 = 12 << 20;

/// Headroom over [`working_bytes`]' multiples: headers, the level index, allocator rounding.
const WORKING_SLACK: u64 = 1 << 20;

/// Most bytes [`encode`] holds at once besides the pixels it is given, for `pixels` pixels over
/// all levels of `k`: the encoder's own state (Basis Universal's block candidates and, for
/// ETC1S, its codebooks' clustering), each level's blocks, the file they are assembled into
/// and, with zstd, its context and output. Measured on noise, which no encoder simplifies, at
/// the largest page and chain of each codec (`tests/ktx2_peak.rs`, resident memory, for
/// basisu allocates outside Rust's allocator).
pub fn working_bytes(k: Ktx2, pixels: u64) -> u64 {
    let per_pixel: u64 = match k.codec {
        Codec::Bc7 | Codec::Bc1 | Codec::Bc5 => 6,
        Codec::Rgba8 => 10,
        // RDO's search after the encoding holds more besides.
        Codec::Uastc if k.rdo.is_some() => 34,
        Codec::Uastc => 26,
        Codec::Etc1s => 68,
    };
    // The levels' bytes, zstd's input and at most (plus a few bytes) its output.
    let level_bytes = match k.codec {
        Codec::Rgba8 => pixels * 4,
        c => pixels * c.block_bytes() as u64 / 16,
    };
    let zstd = match k.supercompression {
        Supercompression::Zstd => ZSTD_CONTEXT_BYTES + level_bytes,
        Supercompression::None | Supercompression::BasisLz => 0,
    };
    per_pixel * pixels + zstd + WORKING_SLACK
}

/// A KTX2 encoding: its codec, supercompression and transfer function, and for UASTC its
/// rate-distortion optimisation.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Ktx2 {
    pub codec: Codec,
    pub supercompression: Supercompression,
    pub transfer: Transfer,
    pub rdo: Option<Rdo>,
}

impl Ktx2 {
    /// sRGB colour in `codec` and `supercompression`, without RDO.
    pub fn new(codec: Codec, supercompression: Supercompression) -> Ktx2 {
        Ktx2 { codec, supercompression, transfer: Transfer::Srgb, rdo: None }
    }

    /// Whether the codec takes this supercompression, transfer and RDO; the error says which
    /// does not fit.
    pub fn check(self) -> Result<(), String> {
        self.codec.check(self.supercompression)?;
        if self.rdo.is_some() && self.codec != Codec::Uastc {
            return Err(format!("`rdo` applies to codec uastc only (got codec {})", self.codec.name()));
        }
        if self.codec == Codec::Bc5 && self.transfer != Transfer::Linear {
            return Err("bc5 holds two linear channels, not sRGB colour".into());
        }
        Ok(())
    }
}

/// UASTC's rate-distortion optimisation: basisu re-chooses blocks so that zstd compresses them
/// better, trading at most about λ times more error (its quality scalar) for fewer bytes. Held
/// in thousandths so that it can key caches and ETags.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub struct Rdo {
    milli: u32,
}

impl Rdo {
    /// λ from 0.1 (near the plain encoding) to 10 (basisu's strongest useful setting).
    pub const EXPECTED: &'static str = "a number from 0.1 to 10";

    pub fn parse(s: &str) -> Option<Rdo> {
        let v: f64 = s.parse().ok()?;
        (0.1..=10.0).contains(&v).then(|| Rdo { milli: (v * 1000.0).round() as u32 })
    }

    /// basisu's quality scalar.
    pub fn lambda(self) -> f32 {
        self.milli as f32 / 1000.0
    }

    /// What ETags hash.
    pub fn id(self) -> u64 {
        self.milli as u64
    }
}

/// How texel values map to light: sRGB-encoded colour, or linear data such as normals.
#[derive(Clone, Copy, Debug, PartialEq, Eq, Hash)]
pub enum Transfer {
    Srgb,
    Linear,
}

impl Transfer {
    /// `KHR_DF_TRANSFER_SRGB` or `KHR_DF_TRANSFER_LINEAR`.
    fn dfd_value(self) -> u8 {
        match self {
            Transfer::Srgb => 2,
            Transfer::Linear => 1,
        }
    }
}

/// The image `img` padded to whole 4×4 blocks by repeating its last column and row.
fn pad_to_blocks(img: &Rgba8Image) -> Rgba8Image {
    let (w, h) = (img.width.next_multiple_of(4), img.height.next_multiple_of(4));
    if (w, h) == (img.width, img.height) {
        return img.clone();
    }
    let mut out = Rgba8Image::new(w, h);
    for y in 0..h {
        for x in 0..w {
            out.set_pixel(x, y, img.pixel(x.min(img.width - 1), y.min(img.height - 1)));
        }
    }
    out
}

/// The file's first bytes, «KTX 20».
const IDENTIFIER: [u8; 12] = [0xAB, 0x4B, 0x54, 0x58, 0x20, 0x32, 0x30, 0xBB, 0x0D, 0x0A, 0x1A, 0x0A];
/// Identifier, header (9 × u32) and index (4 × u32 + 2 × u64).
const HEADER_BYTES: usize = 12 + 36 + 32;
const LEVEL_INDEX_ENTRY: usize = 24;
const WRITER: &[u8] = b"KTXwriter\0vtex\0";

/// One sample of a descriptor: bit offset, bit length − 1, channel with its qualifier bits,
/// upper value.
type Sample = (u16, u8, u8, u32);

/// The Data Format Descriptor (Khronos Data Format 1.3, one basic block) of `codec` with
/// `transfer`, BT.709 primaries, straight alpha; for Basis Universal, with or without `alpha`,
/// as the KTX 2.0 specification and basisu's writer describe them.
fn dfd(codec: Codec, alpha: bool, transfer: Transfer) -> Vec<u8> {
    // Alpha is linear whatever the colour's transfer: under sRGB its sample says so (0x10).
    let rgba8_alpha = match transfer {
        Transfer::Srgb => 0x1F,
        Transfer::Linear => 0x0F,
    };
    // Colour model, block dimensions − 1, bytes per plane 0, samples.
    let (model, dim, plane, samples): (u8, u8, u8, &[Sample]) = match codec {
        Codec::Bc7 => (134, 3, 16, &[(0, 127, 0, u32::MAX)]),
        Codec::Bc1 => (128, 3, 8, &[(0, 63, 0, u32::MAX)]),
        // KHR_DF_MODEL_BC5: a 64-bit red sample, then a 64-bit green one.
        Codec::Bc5 => (132, 3, 16, &[(0, 63, 0, u32::MAX), (64, 63, 1, u32::MAX)]),
        // R, G, B, then alpha.
        Codec::Rgba8 => (1, 0, 4, &[(0, 7, 0, 255), (8, 7, 1, 255), (16, 7, 2, 255), (24, 7, rgba8_alpha, 255)]),
        // KHR_DF_MODEL_UASTC, one 128-bit sample: KHR_DF_CHANNEL_UASTC_RGBA (3) or _RGB (0).
        // bytesPlane0 16 with zstd too, as for the other codecs: Khronos settled that a
        // variable-rate scheme leaves it set (basisu 1.16 still writes 0 there).
        Codec::Uastc => (166, 3, 16, if alpha { &[(0, 127, 3, u32::MAX)] } else { &[(0, 127, 0, u32::MAX)] }),
        // KHR_DF_MODEL_ETC1S: a 64-bit KHR_DF_CHANNEL_ETC1S_RGB (0) sample, then with alpha a
        // second one, KHR_DF_CHANNEL_ETC1S_AAA (15), for the alpha slice; bytesPlane0 0, as
        // BasisLZ's slices have no fixed size.
        Codec::Etc1s => {
            (163, 3, 0, if alpha { &[(0, 63, 0, u32::MAX), (64, 63, 15, u32::MAX)] } else { &[(0, 63, 0, u32::MAX)] })
        }
    };
    let block_size = 24 + 16 * samples.len();
    let mut d = Vec::with_capacity(4 + block_size);
    d.extend_from_slice(&((4 + block_size) as u32).to_le_bytes());
    d.extend_from_slice(&0u32.to_le_bytes()); // vendor 0 (Khronos), descriptor type 0
    d.extend_from_slice(&2u16.to_le_bytes()); // version 1.3
    d.extend_from_slice(&(block_size as u16).to_le_bytes());
    d.extend_from_slice(&[model, 1, transfer.dfd_value(), 0]); // model, BT.709, transfer, straight alpha
    d.extend_from_slice(&[dim, dim, 0, 0]);
    d.extend_from_slice(&[plane, 0, 0, 0, 0, 0, 0, 0]);
    for &(offset, len, channel, upper) in samples {
        d.extend_from_slice(&offset.to_le_bytes());
        d.extend_from_slice(&[len, channel]);
        d.extend_from_slice(&[0, 0, 0, 0]); // sample position
        d.extend_from_slice(&0u32.to_le_bytes()); // lower
        d.extend_from_slice(&upper.to_le_bytes());
    }
    d
}

/// A KTX2 file of `levels`, level 0 (the largest) first, each half the size of the one before
/// (`max(1, w >> i)`), as a GPU's mip chain is.
pub fn encode(levels: &[Rgba8Image], k: Ktx2) -> Result<Vec<u8>, String> {
    let base = levels.first().ok_or("a KTX2 file needs at least one level")?;
    for (i, l) in levels.iter().enumerate() {
        let want = ((base.width >> i).max(1), (base.height >> i).max(1));
        if (l.width, l.height) != want {
            return Err(format!("mip level {i} is {}×{}, expected {}×{}", l.width, l.height, want.0, want.1));
        }
    }
    k.check()?;
    let encoded = k.codec.encode_levels(levels, k.transfer, k.rdo)?;
    // Each level's bytes, and what they decompress to (0 for BasisLZ, which the transcoder
    // undoes with the global data).
    let mut data: Vec<(Vec<u8>, usize)> = Vec::with_capacity(levels.len());
    for raw in encoded.levels {
        let n = raw.len();
        data.push(match k.supercompression {
            Supercompression::None => (raw, n),
            Supercompression::BasisLz => (raw, 0),
            Supercompression::Zstd => {
                (zstd::bulk::compress(&raw, ZSTD_LEVEL).map_err(|e| format!("zstd compression failed: {e}"))?, n)
            }
        });
    }
    let dfd = dfd(k.codec, encoded.alpha, k.transfer);
    let dfd_offset = HEADER_BYTES + LEVEL_INDEX_ENTRY * levels.len();
    let kvd_offset = dfd_offset + dfd.len();
    // One key/value pair, its length field and its valuePadding to 4 bytes: the padding is part
    // of kvdByteLength.
    let kvd_len = (4 + WRITER.len()).next_multiple_of(4);
    // The supercompression global data, aligned to 8 bytes.
    let global = encoded.global.unwrap_or_default();
    let sgd_offset = if global.is_empty() { 0 } else { (kvd_offset + kvd_len).next_multiple_of(8) };
    // Levels are stored smallest first, each aligned to lcm(block bytes, 4) unless
    // supercompressed (then 1).
    let align = match k.supercompression {
        Supercompression::None => k.codec.block_bytes().max(4),
        Supercompression::Zstd | Supercompression::BasisLz => 1,
    };
    let mut offsets = vec![0usize; levels.len()];
    let mut end = (kvd_offset + kvd_len).max(sgd_offset + global.len());
    for i in (0..levels.len()).rev() {
        end = end.next_multiple_of(align);
        offsets[i] = end;
        end += data[i].0.len();
    }
    let mut out = Vec::with_capacity(end);
    out.extend_from_slice(&IDENTIFIER);
    let scheme = k.supercompression.scheme();
    let header = [k.codec.vk_format(k.transfer), 1, base.width, base.height, 0, 0, 1, levels.len() as u32, scheme];
    for v in header {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [dfd_offset as u32, dfd.len() as u32, kvd_offset as u32, kvd_len as u32] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for v in [sgd_offset as u64, global.len() as u64] {
        out.extend_from_slice(&v.to_le_bytes());
    }
    for (i, (bytes, raw_len)) in data.iter().enumerate() {
        for v in [offsets[i] as u64, bytes.len() as u64, *raw_len as u64] {
            out.extend_from_slice(&v.to_le_bytes());
        }
    }
    out.extend_from_slice(&dfd);
    out.extend_from_slice(&(WRITER.len() as u32).to_le_bytes());
    out.extend_from_slice(WRITER);
    out.resize(kvd_offset + kvd_len, 0);
    if !global.is_empty() {
        out.resize(sgd_offset, 0);
        out.extend_from_slice(&global);
    }
    for i in (0..levels.len()).rev() {
        out.resize(offsets[i], 0);
        out.extend_from_slice(&data[i].0);
    }
    Ok(out)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn noise(w: u32, h: u32, seed: u32) -> Rgba8Image {
        let mut img = Rgba8Image::new(w, h);
        for y in 0..h {
            for x in 0..w {
                let v = (x.wrapping_mul(2654435761) ^ y.wrapping_mul(40503) ^ seed).wrapping_mul(2246822519);
                img.set_pixel(x, y, [(v >> 24) as u8, (v >> 16) as u8, (x * 4) as u8, 255]);
            }
        }
        img
    }

    fn u32_at(b: &[u8], i: usize) -> u32 {
        u32::from_le_bytes(b[i..i + 4].try_into().unwrap())
    }

    fn u64_at(b: &[u8], i: usize) -> u64 {
        u64::from_le_bytes(b[i..i + 8].try_into().unwrap())
    }

    #[test]
    fn header_and_level_index_describe_the_data() {
        let chain = [noise(8, 6, 1), noise(4, 3, 2), noise(2, 1, 3), noise(1, 1, 4)];
        for codec in [Codec::Bc7, Codec::Bc1, Codec::Rgba8, Codec::Uastc] {
            for sc in [Supercompression::None, Supercompression::Zstd] {
                let f = encode(&chain, Ktx2::new(codec, sc)).unwrap();
                assert_eq!(f[..12], IDENTIFIER);
                assert_eq!(u32_at(&f, 12), codec.vk_format(Transfer::Srgb));
                assert_eq!((u32_at(&f, 20), u32_at(&f, 24), u32_at(&f, 40)), (8, 6, 4));
                let mut end = 0;
                for (i, level) in chain.iter().enumerate() {
                    let e = HEADER_BYTES + 24 * i;
                    let (off, len, raw) = (u64_at(&f, e) as usize, u64_at(&f, e + 8), u64_at(&f, e + 16));
                    let (w, h) = (level.width, level.height);
                    let want_raw = match codec {
                        Codec::Rgba8 => w * h * 4,
                        _ => w.div_ceil(4) * h.div_ceil(4) * codec.block_bytes() as u32,
                    };
                    assert_eq!(raw, want_raw as u64, "{codec:?} level {i}");
                    if sc == Supercompression::None {
                        assert_eq!(len, raw);
                        assert_eq!(off % codec.block_bytes().max(4), 0);
                    }
                    end = end.max(off + len as usize);
                }
                assert_eq!(end, f.len(), "the smallest level comes first, the largest last");
            }
        }
    }

    /// ETC1S: BasisLZ, no block-sized levels; the global data has one image descriptor a level,
    /// each slice inside its level, and the codebooks the descriptors' header counts.
    #[test]
    fn etc1s_carries_its_global_data() {
        let chain = [noise(8, 6, 1), noise(4, 3, 2), noise(2, 1, 3), noise(1, 1, 4)];
        let mut with_alpha = chain.clone();
        with_alpha[0].set_pixel(1, 1, [9, 9, 9, 7]);
        for (levels, alpha) in [(&chain, false), (&with_alpha, true)] {
            let f = encode(levels, Ktx2::new(Codec::Etc1s, Supercompression::BasisLz)).unwrap();
            assert_eq!((u32_at(&f, 12), u32_at(&f, 44)), (0, 1), "VK_FORMAT_UNDEFINED, BasisLZ");
            let dfd = u32_at(&f, 48) as usize;
            assert_eq!(f[dfd + 12], 163, "KHR_DF_MODEL_ETC1S");
            assert_eq!(f[dfd + 14], 2, "sRGB");
            assert_eq!(u32_at(&f, dfd) as usize, if alpha { 60 } else { 44 });
            let (sgd, sgd_len) = (u64_at(&f, 64) as usize, u64_at(&f, 72) as usize);
            assert_eq!(sgd % 8, 0);
            let g = &f[sgd..sgd + sgd_len];
            let lens: Vec<usize> = (0..4).map(|i| u32_at(g, 4 + 4 * i) as usize).collect();
            assert_eq!(20 + 20 * chain.len() + lens.iter().sum::<usize>(), sgd_len);
            for i in 0..chain.len() {
                let e = HEADER_BYTES + 24 * i;
                let (len, raw) = (u64_at(&f, e + 8) as usize, u64_at(&f, e + 16));
                assert_eq!(raw, 0, "BasisLZ levels have no uncompressed length");
                let d = 20 + 20 * i;
                let (rgb, rgb_len, a, a_len) =
                    (u32_at(g, d + 4), u32_at(g, d + 8), u32_at(g, d + 12), u32_at(g, d + 16));
                assert_eq!(rgb, 0);
                assert!(rgb_len > 0);
                if alpha {
                    assert_eq!((a as usize, (a + a_len) as usize), (rgb_len as usize, len));
                } else {
                    assert_eq!((a, a_len, rgb_len as usize), (0, 0, len));
                }
            }
        }
    }

    #[test]
    fn a_basis_codec_takes_only_its_supercompression() {
        let img = [noise(8, 8, 1)];
        for (codec, sc) in [
            (Codec::Etc1s, Supercompression::None),
            (Codec::Etc1s, Supercompression::Zstd),
            (Codec::Uastc, Supercompression::BasisLz),
            (Codec::Bc7, Supercompression::BasisLz),
        ] {
            assert!(encode(&img, Ktx2::new(codec, sc)).is_err(), "{codec:?} {sc:?}");
        }
    }

    #[test]
    fn a_chain_must_halve() {
        let e = encode(&[noise(8, 8, 1), noise(3, 4, 1)], Ktx2::new(Codec::Bc1, Supercompression::None));
        assert!(e.unwrap_err().contains("mip level 1 is 3×4, expected 4×4"));
    }

    #[test]
    fn same_bytes_on_every_thread() {
        let img = noise(136, 136, 9);
        let chain = [noise(64, 64, 3), noise(32, 32, 4), noise(16, 16, 5), noise(8, 8, 6), noise(4, 4, 7)];
        for (codec, sc) in [
            (Codec::Bc7, Supercompression::Zstd),
            (Codec::Uastc, Supercompression::None),
            (Codec::Uastc, Supercompression::Zstd),
            (Codec::Etc1s, Supercompression::BasisLz),
        ] {
            let k = Ktx2::new(codec, sc);
            for levels in [std::slice::from_ref(&img), &chain[..]] {
                let first = encode(levels, k).unwrap();
                let others: Vec<Vec<u8>> = std::thread::scope(|s| {
                    let hs: Vec<_> = (0..4).map(|_| s.spawn(|| encode(levels, k).unwrap())).collect();
                    hs.into_iter().map(|h| h.join().unwrap()).collect()
                });
                assert!(others.iter().all(|o| *o == first), "{codec:?} {sc:?}");
            }
        }
    }
}
