//! The random block sequence R_ε = {B_γ, L_γ} (paper §3.1): which rectangle of the sample is
//! pasted where, in which order.

use super::{catmap, params::Params};
use crate::{hash, Error, Result};

/// Bytes of one block in an explicit sequence: x, y, w−1, h−1 as `u8`, s, t as `u32` LE.
pub const RECORD_BYTES: usize = 12;

/// One random block: the sample rectangle B_γ = (x, y, w, h) pasted with its top-left corner
/// at L_γ = (s, t) on the texture torus.
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq, PartialOrd, Ord)]
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

/// A block with its sequence number (its place in paste order).
#[derive(Clone, Copy, Debug, Default, PartialEq, Eq)]
pub struct Numbered {
    pub block: Block,
    pub id: u32,
}

/// The sequence of the paper, drawn from the seed: `blocks_per_tile` blocks per tile (one in
/// the paper), in row-major tile order, each block's size drawn under the area constraint and
/// its position inside the sample uniformly, its tile corner moved by `iterations` steps of
/// the cat map. Any block can be drawn alone, so the blocks landing in one part of the texture
/// can be found without drawing the others ([`landing_in`](Self::landing_in)).
pub struct Generator {
    params: Params,
    sample: (u32, u32),
    rule: SizeRule,
    map: catmap::CatMap,
    /// The largest offsets of a block's corner in its tile (for the smallest width and height).
    reach: (u32, u32),
}

impl Generator {
    pub fn new(params: &Params, sample_w: u32, sample_h: u32, rule: SizeRule) -> Self {
        let (tex_w, tex_h) = (params.tiles_x as u64 * sample_w as u64, params.tiles_y as u64 * sample_h as u64);
        let map = catmap::CatMap::new(tex_w, tex_h, params.iterations);
        let narrowest = rule.widths.iter().map(|&(w, _, _)| w).min().unwrap_or(1) as u32;
        let shortest = rule.widths.iter().map(|&(_, lo, _)| lo).min().unwrap_or(1) as u32;
        let reach = (sample_w - narrowest, sample_h - shortest);
        Self { params: params.clone(), sample: (sample_w, sample_h), rule, map, reach }
    }

    /// The number of blocks in the sequence.
    pub fn len(&self) -> u64 {
        self.params.tiles_x as u64 * self.params.tiles_y as u64 * self.params.blocks_per_tile as u64
    }

    /// Every block, in sequence order.
    pub fn all(&self) -> Vec<Block> {
        let p = &self.params;
        let mut out = Vec::with_capacity(self.len() as usize);
        for ty in 0..p.tiles_y {
            for tx in 0..p.tiles_x {
                for k in 0..p.blocks_per_tile {
                    let (x, y, w, h) = self.draw(tx, ty, k);
                    out.push(self.paste(tx, ty, (x, y, w, h)));
                }
            }
        }
        out
    }

    /// The blocks whose pasted corner lies in `[x0, x0 + w) × [y0, y0 + h)` (inside the
    /// texture), in sequence order: each point of the rectangle is taken back by the cat map to
    /// the point it comes from, which is a block's corner when its tile's draws put one there.
    pub fn landing_in(&self, at: (u64, u64), size: (u64, u64)) -> Vec<Numbered> {
        let (sw, sh) = (self.sample.0 as u64, self.sample.1 as u64);
        let mut out = Vec::new();
        self.map.preimages(at, size, |cx, cy| {
            let (x, y) = ((cx % sw) as u32, (cy % sh) as u32);
            if x > self.reach.0 || y > self.reach.1 {
                return;
            }
            let (tx, ty) = ((cx / sw) as u32, (cy / sh) as u32);
            for k in 0..self.params.blocks_per_tile {
                if let Some(drawn) = self.draw_at(tx, ty, k, (x, y)) {
                    let id = (ty as u64 * self.params.tiles_x as u64 + tx as u64) * self.params.blocks_per_tile as u64;
                    out.push(Numbered { block: self.paste(tx, ty, drawn), id: (id + k as u64) as u32 });
                }
            }
        });
        out.sort_unstable_by_key(|n| n.id);
        out
    }

    /// The points [`landing_in`](Self::landing_in) visits for a `w × h` rectangle.
    pub fn points_for(&self, w: u64, h: u64) -> u64 {
        let (sx, sy) = self.map.scale();
        w * sx * h * sy
    }

    /// Hash `stream` of block `k` of tile (tx, ty).
    fn hash(&self, stream: u64, tx: u32, ty: u32, k: u32) -> u64 {
        hash::hash4(self.params.seed, stream + 8 * k as u64, tx as i64, ty as i64)
    }

    /// Block `k` of tile (tx, ty): its rectangle (x, y, w, h) in the sample.
    fn draw(&self, tx: u32, ty: u32, k: u32) -> (u16, u16, u16, u16) {
        let (sw, sh) = self.sample;
        let (w, h_lo, h_hi) = self.width(tx, ty, k);
        let h = h_lo + hash::below(self.hash(2, tx, ty, k), (h_hi - h_lo + 1) as u64) as u16;
        let x = hash::below(self.hash(3, tx, ty, k), (sw - w as u32 + 1) as u64) as u16;
        let y = hash::below(self.hash(4, tx, ty, k), (sh - h as u32 + 1) as u64) as u16;
        (x, y, w, h)
    }

    /// [`draw`](Self::draw) when block `k` of tile (tx, ty) is cut at (x, y) of the sample,
    /// drawing no more than it takes to tell.
    fn draw_at(&self, tx: u32, ty: u32, k: u32, (x, y): (u32, u32)) -> Option<(u16, u16, u16, u16)> {
        let (sw, _) = self.sample;
        let (w, _, _) = self.width(tx, ty, k);
        let fits = x + w as u32 <= sw && hash::below(self.hash(3, tx, ty, k), (sw - w as u32 + 1) as u64) == x as u64;
        let drawn = fits.then(|| self.draw(tx, ty, k))?;
        (drawn.1 as u32 == y).then_some(drawn)
    }

    /// The width of block `k` of tile (tx, ty) with the range of heights allowed for it.
    fn width(&self, tx: u32, ty: u32, k: u32) -> (u16, u16, u16) {
        self.rule.widths[hash::below(self.hash(1, tx, ty, k), self.rule.widths.len() as u64) as usize]
    }

    /// The block cut at `(x, y, w, h)` of the sample for tile (tx, ty), its corner moved by the
    /// cat map.
    fn paste(&self, tx: u32, ty: u32, (x, y, w, h): (u16, u16, u16, u16)) -> Block {
        let x0 = x as u64 + tx as u64 * self.sample.0 as u64;
        let y0 = y as u64 + ty as u64 * self.sample.1 as u64;
        let (s, t) = self.map.apply(x0, y0);
        Block { x, y, w, h, s: s as u32, t: t as u32 }
    }
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
