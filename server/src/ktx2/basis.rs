//! Basis Universal levels for KTX2: UASTC 4×4 blocks and ETC1S slices with their BasisLZ global
//! data, encoded by Binomial's basisu (the `basis-universal` crate builds it from source).
//!
//! The encoder writes `.basis` files only, so this module takes what a KTX2 file holds out of
//! one: each level's slices (UASTC: 16-byte blocks; ETC1S: a colour slice and, with alpha, an
//! alpha slice) and, for ETC1S, the codebooks and Huffman tables that the KTX 2.0 specification's
//! BasisLZ global data carries (section 3.11: a header, one image descriptor per level, then
//! endpoints, selectors, tables and extended data, in that order).
//!
//! Determinism: the encoder runs on the calling thread (a job pool of one), its SSE kernels
//! are not compiled (the crate leaves `BASISU_SUPPORT_SSE` off), the caller gives every mip
//! level (no resampling by the encoder) and nothing it does reads a clock or a random source.
//! So a level's bytes are a function of its pixels and the codec; `ktx2`'s tests pin them.

use super::Transfer;
use basis_universal::{BasisTextureFormat, ColorSpace, Compressor, CompressorParams};
use vtex_synth::Rgba8Image;

/// UASTC's pack level: 1 of 0 (fastest) … 4 (very slow), one under basisu's default. Other
/// levels are not measured yet; this one costs some 1.2 s a 256² page (docs/ktx2-quality.md).
const UASTC_LEVEL: u32 = 1;
/// ETC1S's quality (1 … 255, the size of its codebooks): basisu's default.
const ETC1S_QUALITY: u32 = 128;

/// Which Basis Universal format to encode.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Mode {
    Uastc,
    Etc1s,
}

/// What a KTX2 file needs of an encoding: each level's bytes (level 0 first) and, for ETC1S,
/// the BasisLZ global data.
pub struct Levels {
    pub levels: Vec<Vec<u8>>,
    pub global: Option<Vec<u8>>,
    /// Whether a level has a texel of alpha below 255 (UASTC RGBA, ETC1S alpha slices).
    pub alpha: bool,
}

/// Encodes a mip chain (level 0 first, each the size of the one before halved).
#[allow(unsafe_code)]
pub fn encode(levels: &[Rgba8Image], mode: Mode, transfer: Transfer) -> Result<Levels, String> {
    let alpha = levels.iter().any(|l| l.data.chunks_exact(4).any(|p| p[3] != 255));
    let mut params = CompressorParams::new();
    params.set_print_status_to_stdout(false);
    // The colour space sets basisu's error metric: perceptual for colour, plain RGB for data.
    let space = match transfer {
        Transfer::Srgb => ColorSpace::Srgb,
        Transfer::Linear => ColorSpace::Linear,
    };
    params.set_color_space(space);
    params.set_mip_color_space(space);
    params.set_generate_mipmaps(false);
    match mode {
        Mode::Uastc => {
            params.set_basis_format(BasisTextureFormat::UASTC4x4);
            params.set_uastc_quality_level(UASTC_LEVEL);
            params.set_rdo_uastc(None);
        }
        Mode::Etc1s => {
            params.set_basis_format(BasisTextureFormat::ETC1S);
            params.set_etc1s_quality_level(ETC1S_QUALITY);
        }
    }
    for (i, l) in levels.iter().enumerate() {
        let mut img = if i == 0 { params.source_image_mut(0) } else { params.source_mipmap_image_mut(0, i as u32 - 1) };
        img.init(&l.data, l.width, l.height, 4);
    }
    let mut c = Compressor::new(1);
    // SAFETY: the parameters are the crate's setters' within their checked ranges, one source
    // image with its mip levels of the sizes basisu requires (`ktx2::encode` checks them).
    unsafe {
        if !c.init(&params) {
            return Err("the Basis Universal encoder refused its parameters".into());
        }
        c.process().map_err(|e| format!("Basis Universal encoding failed: {e:?}"))?;
    }
    let file = BasisFile::parse(c.basis_file())?;
    let want_uastc = mode == Mode::Uastc;
    if file.uastc != want_uastc {
        return Err("the .basis file is not of the format asked for".into());
    }
    if file.has_alpha_slices != alpha && !want_uastc {
        return Err("the .basis file's alpha slices disagree with the pixels".into());
    }
    let n = levels.len();
    let mut out = vec![Vec::new(); n];
    // Per level: (offset, length) of the colour slice and of the alpha slice in its bytes.
    let mut descs = vec![[(0u32, 0u32); 2]; n];
    for s in &file.slices {
        let level = s.level as usize;
        let l = levels.get(level).ok_or("the .basis file has a level more than was given")?;
        if s.image != 0 || (s.width, s.height) != (l.width, l.height) {
            return Err(format!("the .basis slice of level {level} is not that level"));
        }
        let bytes = file.bytes.get(s.offset..s.offset + s.len).ok_or("a .basis slice runs past its file")?;
        if want_uastc && bytes.len() != l.width.div_ceil(4) as usize * l.height.div_ceil(4) as usize * 16 {
            return Err(format!("the UASTC slice of level {level} is not one block per 4×4 texels"));
        }
        let which = usize::from(s.alpha);
        descs[level][which] = (out[level].len() as u32, bytes.len() as u32);
        out[level].extend_from_slice(bytes);
    }
    if out.iter().any(Vec::is_empty) {
        return Err("the .basis file lacks a level".into());
    }
    let global = (!want_uastc).then(|| {
        let (endpoints, selectors, tables) =
            (file.section(file.endpoints), file.section(file.selectors), file.section(file.tables));
        let mut g = Vec::with_capacity(20 + 20 * n + endpoints.len() + selectors.len() + tables.len());
        g.extend_from_slice(&file.endpoint_count.to_le_bytes());
        g.extend_from_slice(&file.selector_count.to_le_bytes());
        for len in [endpoints.len(), selectors.len(), tables.len(), 0] {
            g.extend_from_slice(&(len as u32).to_le_bytes());
        }
        for [(rgb_off, rgb_len), (a_off, a_len)] in &descs {
            // imageFlags 0: no P-frames outside video.
            for v in [0, *rgb_off, *rgb_len, *a_off, *a_len] {
                g.extend_from_slice(&v.to_le_bytes());
            }
        }
        g.extend_from_slice(endpoints);
        g.extend_from_slice(selectors);
        g.extend_from_slice(tables);
        g
    });
    Ok(Levels { levels: out, global, alpha })
}

/// One slice of a `.basis` file.
struct Slice {
    image: u32,
    level: u8,
    alpha: bool,
    width: u32,
    height: u32,
    offset: usize,
    len: usize,
}

/// The parts of a `.basis` file (Binomial's format description, version 0x13) a KTX2 file
/// carries over.
struct BasisFile<'a> {
    bytes: &'a [u8],
    uastc: bool,
    has_alpha_slices: bool,
    endpoint_count: u16,
    selector_count: u16,
    /// (offset, length) of the endpoint codebook, the selector codebook, the Huffman tables.
    endpoints: (usize, usize),
    selectors: (usize, usize),
    tables: (usize, usize),
    slices: Vec<Slice>,
}

/// Little-endian unsigned integer of `n` bytes at `at`.
fn uint(b: &[u8], at: usize, n: usize) -> Result<u64, String> {
    let s = b.get(at..at + n).ok_or("the .basis file is truncated")?;
    Ok(s.iter().rev().fold(0u64, |v, &x| v << 8 | x as u64))
}

impl<'a> BasisFile<'a> {
    /// The fixed header's size: the sum of its fields' widths.
    const HEADER: usize = 77;
    const SLICE: usize = 23;

    fn parse(b: &'a [u8]) -> Result<Self, String> {
        let u = |at, n| uint(b, at, n);
        if u(0, 2)? != u64::from(u16::from_be_bytes(*b"Bs")) || u(4, 2)? as usize != Self::HEADER {
            return Err("not a .basis file of the known header".into());
        }
        let total_slices = u(14, 3)? as usize;
        let tex_format = u(20, 1)?;
        let flags = u(21, 2)?;
        let section = |at| -> Result<(usize, usize), String> { Ok((u(at, 4)? as usize, u(at + 4, 3)? as usize)) };
        let f = BasisFile {
            bytes: b,
            uastc: tex_format == 1,
            has_alpha_slices: flags & 4 != 0,
            endpoint_count: u(39, 2)? as u16,
            endpoints: section(41)?,
            selector_count: u(48, 2)? as u16,
            selectors: section(50)?,
            tables: (u(57, 4)? as usize, u(61, 4)? as usize),
            slices: Vec::with_capacity(total_slices),
        };
        let slice_descs = u(65, 4)? as usize;
        let mut f = f;
        for i in 0..total_slices {
            let at = slice_descs + i * Self::SLICE;
            f.slices.push(Slice {
                image: u(at, 3)? as u32,
                level: u(at + 3, 1)? as u8,
                alpha: u(at + 4, 1)? & 1 != 0,
                width: u(at + 5, 2)? as u32,
                height: u(at + 7, 2)? as u32,
                offset: u(at + 13, 4)? as usize,
                len: u(at + 17, 4)? as usize,
            });
        }
        for (o, l) in [f.endpoints, f.selectors, f.tables] {
            if o.checked_add(l).is_none_or(|e| e > b.len()) {
                return Err("a .basis section runs past its file".into());
            }
        }
        Ok(f)
    }

    fn section(&self, (offset, len): (usize, usize)) -> &'a [u8] {
        &self.bytes[offset..offset + len]
    }
}
