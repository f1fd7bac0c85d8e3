//! The random block sequence R_ε = {B_γ, L_γ} (paper §3.1): which rectangle of the sample is
//! pasted where, in which order.

use super::{catmap, params::Params};
use crate::{hash, Error, Result};

/// Bytes of one block in an explicit sequence: x, y, w−1, h−1 as `u8`, s, t as `u32` LE.
pub const RECORD_BYTES: usize = 12;

/// One random block: the sample rectangle B_γ = (x, y, w, h) pasted with its top-left corner
/// at L_γ = (s, t) on the texture torus.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct Block {
    pub x: u16,
    pub y: u16,
    pub w: u16,
    pub h: u16,
    pub s: u32,
    pub t: u32,
}

/// The block sizes allowed by the area constraint c_λ ≤ wh/A ≤ c_μ for a sample of area A:
/// for each width, the inclusive range of heights. Empty when the sample is too small.
pub struct SizeRule {
    widths: Vec<(u16, u16, u16)>,
}

impl SizeRule {
    pub fn new(sample_w: u32, sample_h: u32, p: &Params) -> Result<Self> {
        let area = sample_w as f64 * sample_h as f64;
        let widths: Vec<(u16, u16, u16)> = (1..=sample_w)
            .filter_map(|w| {
                let lo = ((p.c_lambda * area / w as f64).ceil() as u32).max(1);
                let hi = ((p.c_mu * area / w as f64).floor() as u32).min(sample_h);
                (lo <= hi).then_some((w as u16, lo as u16, hi as u16))
            })
            .collect();
        if widths.is_empty() {
            return Err(Error::param(
                "sample",
                format!(
                    "{sample_w}×{sample_h} is too small: no block satisfies {} ≤ wh/{area} ≤ {}",
                    p.c_lambda, p.c_mu
                ),
            ));
        }
        Ok(Self { widths })
    }

    fn allows(&self, w: u16, h: u16) -> bool {
        self.widths.iter().any(|&(ww, lo, hi)| ww == w && (lo..=hi).contains(&h))
    }
}

/// The sequence of the paper: `blocks_per_tile` blocks per tile (one in the paper), in
/// row-major tile order, each block's size drawn
/// under the area constraint and its position inside the sample uniformly, its tile corner
/// moved by `iterations` steps of the cat map.
pub fn generate(p: &Params, sample_w: u32, sample_h: u32, rule: &SizeRule) -> Vec<Block> {
    let (tex_w, tex_h) = (p.tiles_x as u64 * sample_w as u64, p.tiles_y as u64 * sample_h as u64);
    let map = catmap::CatMap::new(tex_w, tex_h, p.iterations);
    let mut out = Vec::with_capacity(p.tiles_x as usize * p.tiles_y as usize * p.blocks_per_tile as usize);
    for ty in 0..p.tiles_y as i64 {
        for tx in 0..p.tiles_x as i64 {
            for k in 0..p.blocks_per_tile as u64 {
                let draw = |stream: u64| hash::hash4(p.seed, stream + 8 * k, tx, ty);
                let (w, h_lo, h_hi) = rule.widths[hash::below(draw(1), rule.widths.len() as u64) as usize];
                let h = h_lo + hash::below(draw(2), (h_hi - h_lo + 1) as u64) as u16;
                let x = hash::below(draw(3), (sample_w - w as u32 + 1) as u64) as u16;
                let y = hash::below(draw(4), (sample_h - h as u32 + 1) as u64) as u16;
                let x0 = x as u64 + tx as u64 * sample_w as u64;
                let y0 = y as u64 + ty as u64 * sample_h as u64;
                let (s, t) = map.apply(x0, y0);
                out.push(Block { x, y, w, h, s: s as u32, t: t as u32 });
            }
        }
    }
    out
}

/// Packs blocks into 12-byte records.
#[cfg(feature = "create")]
pub fn pack(blocks: &[Block]) -> Vec<u8> {
    let mut out = Vec::with_capacity(blocks.len() * RECORD_BYTES);
    for b in blocks {
        out.extend_from_slice(&[b.x as u8, b.y as u8, (b.w - 1) as u8, (b.h - 1) as u8]);
        out.extend_from_slice(&b.s.to_le_bytes());
        out.extend_from_slice(&b.t.to_le_bytes());
    }
    out
}

/// Unpacks and validates an explicit sequence: each block inside the sample, obeying the
/// area constraint, pasted inside the texture.
pub fn unpack(
    bytes: &[u8],
    sample_w: u32,
    sample_h: u32,
    tex_w: u64,
    tex_h: u64,
    rule: &SizeRule,
) -> Result<Vec<Block>> {
    if bytes.len() % RECORD_BYTES != 0 {
        return Err(Error::bundle(format!(
            "section `blocks` has {} bytes, not a multiple of {RECORD_BYTES}",
            bytes.len()
        )));
    }
    let count = bytes.len() / RECORD_BYTES;
    if count as u64 > super::params::MAX_BLOCKS {
        return Err(Error::bundle(format!("{count} blocks; at most {}", super::params::MAX_BLOCKS)));
    }
    bytes
        .chunks_exact(RECORD_BYTES)
        .enumerate()
        .map(|(i, r)| {
            let b = Block {
                x: r[0] as u16,
                y: r[1] as u16,
                w: r[2] as u16 + 1,
                h: r[3] as u16 + 1,
                s: u32::from_le_bytes(r[4..8].try_into().unwrap()),
                t: u32::from_le_bytes(r[8..12].try_into().unwrap()),
            };
            if b.x as u32 + b.w as u32 > sample_w || b.y as u32 + b.h as u32 > sample_h {
                return Err(Error::bundle(format!(
                    "block {i} ({}, {}, {}×{}) lies outside the {sample_w}×{sample_h} sample",
                    b.x, b.y, b.w, b.h
                )));
            }
            if b.s as u64 >= tex_w || b.t as u64 >= tex_h {
                return Err(Error::bundle(format!(
                    "block {i} is pasted at ({}, {}), outside the {tex_w}×{tex_h} texture",
                    b.s, b.t
                )));
            }
            if !rule.allows(b.w, b.h) {
                return Err(Error::bundle(format!("block {i} ({}×{}) breaks the block area constraint", b.w, b.h)));
            }
            Ok(b)
        })
        .collect()
}
