//! The Pixel Map block (§3.3): a material mask at (up to) texture resolution with sharp,
//! pixel-level transitions, compressed with the indirection mechanism of Kraus & Ertl: a coarse
//! grid whose entries are either a uniform material or the index of a stored block, so only
//! blocks crossed by an area boundary cost memory.
//!
//! Section layout: (w / block) × (h / block) u16 LE entries (< 0x8000: uniform material,
//! otherwise 0x8000 + block index), then the block pool, block² bytes per block.

use super::params::PixelMapParams;
use crate::{bundle::Bundle, Error, Result};

const BLOCK_FLAG: u16 = 0x8000;

pub struct PixelMap {
    scale_shift: u32,
    block_shift: u32,
    w: u32,
    h: u32,
    bw: u32,
    top: Vec<u16>,
    pool: Vec<u8>,
}

impl PixelMap {
    pub fn load(p: &PixelMapParams, bundle: &Bundle, texture: (u64, u64), materials: usize) -> Result<Self> {
        let err = |m: String| Error::param("pixel_map", m);
        let [w, h] = p.size;
        if !p.scale.is_power_of_two() || !p.block.is_power_of_two() || p.block > 256 {
            return Err(err(format!("scale {} and block {} must be powers of two (block ≤ 256)", p.scale, p.block)));
        }
        if w as u64 * p.scale as u64 != texture.0 || h as u64 * p.scale as u64 != texture.1 {
            return Err(err(format!(
                "{w}×{h} map pixels × scale {} do not cover the {}×{} texture",
                p.scale, texture.0, texture.1
            )));
        }
        if w % p.block != 0 || h % p.block != 0 {
            return Err(err(format!("block {} does not divide the map size {w}×{h}", p.block)));
        }
        let (bw, bh) = (w / p.block, h / p.block);
        let data = bundle.section(&p.section)?;
        let top_bytes = (bw as usize * bh as usize) * 2;
        let b2 = (p.block * p.block) as usize;
        if data.len() < top_bytes || (data.len() - top_bytes) % b2 != 0 {
            return Err(err(format!(
                "section `{}` has {} bytes; not a {bw}×{bh} grid plus {b2}-byte blocks",
                p.section,
                data.len()
            )));
        }
        let top: Vec<u16> = data[..top_bytes].chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).collect();
        let pool = data[top_bytes..].to_vec();
        let blocks = pool.len() / b2;
        for &e in &top {
            let ok = if e & BLOCK_FLAG != 0 { ((e & !BLOCK_FLAG) as usize) < blocks } else { (e as usize) < materials };
            if !ok {
                return Err(err(format!("entry {e:#06x} names a missing block or material")));
            }
        }
        if let Some(v) = pool.iter().find(|&&v| v as usize >= materials) {
            return Err(err(format!("material {v} does not exist ({materials} materials)")));
        }
        Ok(Self { scale_shift: p.scale.trailing_zeros(), block_shift: p.block.trailing_zeros(), w, h, bw, top, pool })
    }

    /// Material at level-0 texture pixel (x, y), wrapping.
    #[inline]
    pub fn at(&self, x: u64, y: u64) -> u16 {
        let mx = (x >> self.scale_shift) as u32 % self.w;
        let my = (y >> self.scale_shift) as u32 % self.h;
        let e = self.top[((my >> self.block_shift) * self.bw + (mx >> self.block_shift)) as usize];
        if e & BLOCK_FLAG == 0 {
            return e;
        }
        let b = 1u32 << self.block_shift;
        let local = (my & (b - 1)) * b + (mx & (b - 1));
        self.pool[(e & !BLOCK_FLAG) as usize * (b * b) as usize + local as usize] as u16
    }
}

/// Compresses a `w × h` material image (row-major, one byte a pixel) into the section layout.
pub fn encode(w: u32, h: u32, block: u32, materials: &[u8]) -> Vec<u8> {
    assert!(w % block == 0 && h % block == 0 && materials.len() == (w * h) as usize);
    let (bw, bh) = (w / block, h / block);
    let mut top = Vec::new();
    let mut pool = Vec::new();
    let mut nblocks = 0u16;
    for by in 0..bh {
        for bx in 0..bw {
            let cells: Vec<u8> = (0..block)
                .flat_map(|y| (0..block).map(move |x| ((by * block + y) * w + bx * block + x) as usize))
                .map(|i| materials[i])
                .collect();
            if cells.iter().all(|&c| c == cells[0]) {
                top.extend_from_slice(&(cells[0] as u16).to_le_bytes());
            } else {
                top.extend_from_slice(&(BLOCK_FLAG | nblocks).to_le_bytes());
                nblocks += 1;
                pool.extend_from_slice(&cells);
            }
        }
    }
    top.extend_from_slice(&pool);
    top
}

/// The `w × h` material image (row-major, one byte a pixel) a section of [`encode`] holds.
pub fn decode(w: u32, h: u32, block: u32, data: &[u8]) -> Result<Vec<u8>> {
    let bad = || Error::param("pixel_map", format!("section is no {w}×{h} map of {block}-pixel blocks"));
    if block == 0 || w % block != 0 || h % block != 0 {
        return Err(bad());
    }
    let (bw, bh, b) = (w / block, h / block, block as usize);
    let top_bytes = (bw * bh) as usize * 2;
    let (top, pool) = (data.get(..top_bytes).ok_or_else(bad)?, &data[top_bytes..]);
    let mut out = vec![0u8; (w * h) as usize];
    for (i, e) in top.chunks_exact(2).map(|c| u16::from_le_bytes([c[0], c[1]])).enumerate() {
        let (bx, by) = (i % bw as usize, i / bw as usize);
        for y in 0..b {
            let row = (by * b + y) * w as usize + bx * b;
            let dst = &mut out[row..row + b];
            if e & BLOCK_FLAG == 0 {
                dst.fill(u8::try_from(e).map_err(|_| bad())?);
            } else {
                let at = (e & !BLOCK_FLAG) as usize * b * b + y * b;
                dst.copy_from_slice(pool.get(at..at + b).ok_or_else(bad)?);
            }
        }
    }
    Ok(out)
}
