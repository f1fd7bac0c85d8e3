//! What the store knows of a bundle without loading it ([`Record`], and the API's
//! [`TextureInfo`] made from it), and a loaded texture ([`Entry`]).

use std::ops::Deref;
use std::sync::Arc;
use vtex_synth::bundle::{id_of, Bundle, Manifest};
use vtex_synth::models::{self, Limits, Plan};
use vtex_synth::texture::level_size;
use vtex_synth::{Domain, Texture};

/// Number of served levels: 0..n-1, where level n-1 is the first that fits in one tile.
pub fn served_levels(width: u64, height: u64, tile_size: u32) -> u32 {
    let ts = tile_size as u64;
    let mut level = 0;
    loop {
        let (w, h) = level_size(width, height, level);
        if w <= ts && h <= ts {
            return level + 1;
        }
        level += 1;
    }
}

pub use vtex_wire::TextureInfo;

/// What the store knows of a stored bundle without loading its texture: its manifest and plan.
pub struct Record {
    pub id: String,
    /// The id as 32 raw bytes: the compact form used in cache keys.
    pub key: [u8; 32],
    pub manifest: Manifest,
    pub plan: Plan,
    pub encoding_bytes: u64,
    pub levels: u32,
    pub tile_size: u32,
    /// Held while the texture loads, so that concurrent first uses share one load.
    pub(super) loading: Arc<tokio::sync::Mutex<()>>,
}

impl Record {
    /// Plans `bundle`, stored as `encoding_bytes` bytes whose hash is `id`, and checks the plan
    /// against `limits`; the texture is not built.
    pub(super) fn plan(
        bundle: &Bundle,
        id: String,
        encoding_bytes: usize,
        tile_size: u32,
        limits: &Limits,
    ) -> Result<Record, vtex_synth::Error> {
        let plan = models::plan(bundle)?;
        limits.check(&bundle.manifest.model, &plan)?;
        let key = blake3::Hash::from_hex(&id).expect("id_of gives hex").into();
        Ok(Record {
            id,
            key,
            manifest: bundle.manifest.clone(),
            levels: served_levels(plan.width, plan.height, tile_size),
            plan,
            encoding_bytes: encoding_bytes as u64,
            tile_size,
            loading: Default::default(),
        })
    }

    /// Bytes the loaded texture is charged against the budget: what its plan says it holds.
    pub fn resident_bytes(&self) -> u64 {
        self.plan.cost.resident_bytes.value
    }

    pub fn info(&self) -> TextureInfo {
        let p = &self.plan;
        TextureInfo {
            id: self.id.clone(),
            name: self.manifest.name.clone(),
            model: self.manifest.model.clone(),
            width: p.width,
            height: p.height,
            levels: self.levels,
            tile_size: self.tile_size,
            encoding_bytes: self.encoding_bytes,
            explicit_bytes: p.width.saturating_mul(p.height).saturating_mul(3),
            wraps: p.domain == Domain::Torus,
            domain: p.domain,
            animated: p.animation.is_some(),
            animation: p.animation,
            params: self.manifest.params.clone(),
            derived: self.manifest.derived.clone(),
        }
    }

    /// Tiles across and down at `level`.
    pub fn tiles_at(&self, level: u32) -> (u64, u64) {
        let (w, h) = level_size(self.plan.width, self.plan.height, level);
        let ts = self.tile_size as u64;
        (w.div_ceil(ts), h.div_ceil(ts))
    }
}

/// A loaded texture, ready to render, with its record.
pub struct Entry {
    pub record: Arc<Record>,
    pub texture: Arc<dyn Texture>,
}

impl Deref for Entry {
    type Target = Record;
    fn deref(&self) -> &Record {
        &self.record
    }
}

impl Entry {
    /// Validates bundle bytes completely and loads the texture, within no bound: for the
    /// offline commands, which run what they are given.
    pub fn from_bytes(bytes: &[u8], tile_size: u32) -> Result<Entry, vtex_synth::Error> {
        let bundle = Bundle::from_bytes(bytes)?;
        let record = Record::plan(&bundle, id_of(bytes), bytes.len(), tile_size, &Limits::NONE)?;
        let texture = models::load(&bundle)?;
        Ok(Entry { record: Arc::new(record), texture })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn served_levels_stop_at_one_tile() {
        assert_eq!(served_levels(256, 256, 256), 1);
        assert_eq!(served_levels(257, 10, 256), 2);
        assert_eq!(served_levels(100_000, 100_000, 256), 10); // 100000/2^9 = 196 ≤ 256
        assert_eq!(served_levels(1, 1, 256), 1);
        assert_eq!(served_levels(100_000, 3, 256), 10);
    }
}
