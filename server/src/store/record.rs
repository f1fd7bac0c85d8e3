//! What the store knows of a bundle without loading it ([`Record`], and the API's
//! [`TextureInfo`] made from it), and a loaded texture ([`Entry`]).

use std::ops::Deref;
use std::sync::Arc;
use vtex_synth::bundle::{id_of, Bundle};
use vtex_synth::models::{self, Limits, Plan};
use vtex_synth::{Domain, Texture};

pub use vtex_wire::TextureInfo;

/// What the store knows of a stored bundle without loading its texture: its manifest and plan.
pub struct Record {
    pub id: String,
    /// The id as 32 raw bytes: the compact form used in cache keys.
    pub key: [u8; 32],
    pub name: String,
    pub model: String,
    /// The manifest's `params` and `derived` as compact JSON text, parsed for [`Record::info`]:
    /// the index holds a record for every stored texture, and a parsed tree takes several
    /// times the memory.
    params_json: Box<str>,
    derived_json: Box<str>,
    pub plan: Plan,
    pub encoding_bytes: u64,
    pub levels: u32,
    pub tile_size: u32,
    /// Tiles a side of its metatiles.
    pub metatile: u32,
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
            name: bundle.manifest.name.clone(),
            model: bundle.manifest.model.clone(),
            params_json: compact(&bundle.manifest.params),
            derived_json: compact(&bundle.manifest.derived),
            levels: vtex_wire::levels::tile_levels(plan.width, plan.height, tile_size),
            plan,
            encoding_bytes: encoding_bytes as u64,
            tile_size,
            metatile: vtex_wire::levels::metatile_tiles(tile_size),
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
            name: self.name.clone(),
            model: self.model.clone(),
            width: p.width,
            height: p.height,
            levels: self.levels,
            tile_size: self.tile_size,
            metatile: self.metatile,
            encoding_bytes: self.encoding_bytes,
            explicit_bytes: vtex_wire::info::explicit_bytes(p.width, p.height),
            wraps: p.domain == Domain::Torus,
            domain: p.domain,
            animated: p.animation.is_some(),
            animation: p.animation,
            params: serde_json::from_str(&self.params_json).expect("written by `compact`"),
            derived: serde_json::from_str(&self.derived_json).expect("written by `compact`"),
        }
    }

    /// Tiles across and down at `level`.
    pub fn tiles_at(&self, level: u32) -> (u64, u64) {
        vtex_wire::levels::grid(self.plan.width, self.plan.height, level, self.tile_size)
    }
}

fn compact(value: &impl serde::Serialize) -> Box<str> {
    serde_json::to_string(value).expect("JSON values serialize").into()
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
