//! The encoding store: a data directory of content-addressed bundles, `<id>.vtex`.
//!
//! A bundle is validated completely (container and model) before it is written or served.
//! Writes are atomic — a temporary file in the same directory, fsync, rename, fsync of the
//! directory — so a crash leaves either the whole bundle or nothing but a temporary file,
//! which the next start removes. Bundles are immutable: an edit is a new bundle, a new id.

use serde::Serialize;
use std::collections::BTreeMap;
use std::io::Write;
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, RwLock};
use vtex_synth::bundle::{id_of, is_valid_id, Bundle, Manifest};
use vtex_synth::texture::level_size;
use vtex_synth::{models, Animation, Domain, Texture};

pub const BUNDLE_EXT: &str = "vtex";
/// Prefix of temporary files; anything carrying it at start-up is a crashed write.
pub const TEMP_PREFIX: &str = ".tmp-";

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

/// What clients see of a texture: the items of the texture list and `GET /api/v1/textures/{id}`.
#[derive(Clone, Debug, Serialize, serde::Deserialize, PartialEq)]
pub struct TextureInfo {
    pub id: String,
    pub name: String,
    pub model: String,
    pub width: u64,
    pub height: u64,
    pub levels: u32,
    pub tile_size: u32,
    pub encoding_bytes: u64,
    /// Bytes of the explicit 24-bit level 0 the encoding stands for.
    pub explicit_bytes: u64,
    pub wraps: bool,
    pub domain: Domain,
    pub animated: bool,
    pub animation: Option<Animation>,
}

/// A stored, validated texture, ready to render.
pub struct Entry {
    pub id: String,
    /// The id as 32 raw bytes: the compact form used in cache keys.
    pub key: [u8; 32],
    pub manifest: Manifest,
    pub texture: Arc<dyn Texture>,
    pub encoding_bytes: u64,
    pub levels: u32,
    pub tile_size: u32,
}

impl Entry {
    /// Validates bundle bytes completely and prepares the texture. The id is computed here.
    pub fn from_bytes(bytes: &[u8], tile_size: u32) -> Result<Entry, vtex_synth::Error> {
        let bundle = Bundle::from_bytes(bytes)?;
        let texture = models::load(&bundle)?;
        let id = id_of(bytes);
        let key = blake3::Hash::from_hex(&id).expect("id_of gives hex").into();
        let levels = served_levels(texture.width(), texture.height(), tile_size);
        Ok(Entry { id, key, manifest: bundle.manifest, texture, encoding_bytes: bytes.len() as u64, levels, tile_size })
    }

    pub fn info(&self) -> TextureInfo {
        let t = &self.texture;
        let animation = t.animation();
        TextureInfo {
            id: self.id.clone(),
            name: self.manifest.name.clone(),
            model: self.manifest.model.clone(),
            width: t.width(),
            height: t.height(),
            levels: self.levels,
            tile_size: self.tile_size,
            encoding_bytes: self.encoding_bytes,
            explicit_bytes: t.width().saturating_mul(t.height()).saturating_mul(3),
            wraps: t.domain() == Domain::Torus,
            domain: t.domain(),
            animated: animation.is_some(),
            animation,
        }
    }

    /// Tiles across and down at `level`.
    pub fn tiles_at(&self, level: u32) -> (u64, u64) {
        let (w, h) = level_size(self.texture.width(), self.texture.height(), level);
        let ts = self.tile_size as u64;
        (w.div_ceil(ts), h.div_ceil(ts))
    }
}

/// Why a bundle was not stored.
#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{0}")]
    Invalid(#[from] vtex_synth::Error),
    #[error("storage failure: {0}")]
    Io(#[from] std::io::Error),
}

/// The data directory and every valid texture in it.
pub struct Store {
    dir: PathBuf,
    tile_size: u32,
    entries: RwLock<BTreeMap<String, Arc<Entry>>>,
}

/// What [`Store::open`] found, for the start-up log.
#[derive(Debug, Default)]
pub struct OpenReport {
    pub loaded: usize,
    pub demos_written: usize,
    pub stale_temp_removed: usize,
    /// Files that are not valid bundles (wrong name, hash mismatch, invalid): left alone, not served.
    pub rejected: Vec<(PathBuf, String)>,
}

impl Store {
    /// Opens (creating if needed) the data directory: removes temporary files of crashed
    /// writes, validates and loads every bundle, and writes the demos into an empty directory.
    pub fn open(dir: &Path, tile_size: u32, write_demos: bool) -> std::io::Result<(Store, OpenReport)> {
        std::fs::create_dir_all(dir)?;
        let store = Store { dir: dir.to_path_buf(), tile_size, entries: RwLock::new(BTreeMap::new()) };
        let mut report = OpenReport::default();
        let mut bundles = Vec::new();
        for item in std::fs::read_dir(dir)? {
            let item = item?;
            let name = item.file_name().to_string_lossy().into_owned();
            if name.starts_with(TEMP_PREFIX) {
                std::fs::remove_file(item.path())?;
                report.stale_temp_removed += 1;
            } else if name.ends_with(&format!(".{BUNDLE_EXT}")) {
                bundles.push(item.path());
            }
        }
        if report.stale_temp_removed > 0 {
            sync_dir(dir)?;
        }
        bundles.sort();
        for path in &bundles {
            match store.load_file(path) {
                Ok(entry) => {
                    store.entries.write().unwrap().insert(entry.id.clone(), Arc::new(entry));
                    report.loaded += 1;
                }
                Err(why) => report.rejected.push((path.clone(), why)),
            }
        }
        if bundles.is_empty() && write_demos {
            for demo in models::demos() {
                let (_, created) = store.put(demo.to_bytes()).map_err(|e| match e {
                    StoreError::Io(e) => e,
                    StoreError::Invalid(e) => {
                        std::io::Error::other(format!("demo `{}` is invalid: {e}", demo.manifest.name))
                    }
                })?;
                report.demos_written += created as usize;
            }
        }
        Ok((store, report))
    }

    fn load_file(&self, path: &Path) -> Result<Entry, String> {
        let stem = path.file_stem().and_then(|s| s.to_str()).unwrap_or("");
        if !is_valid_id(stem) {
            return Err("file name is not a bundle id".into());
        }
        let bytes = std::fs::read(path).map_err(|e| e.to_string())?;
        let entry = Entry::from_bytes(&bytes, self.tile_size).map_err(|e| e.to_string())?;
        if entry.id != stem {
            return Err(format!("content hash {} does not match the file name", entry.id));
        }
        Ok(entry)
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn get(&self, id: &str) -> Option<Arc<Entry>> {
        self.entries.read().unwrap().get(id).cloned()
    }

    pub fn len(&self) -> usize {
        self.entries.read().unwrap().len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Every texture, sorted by name (then id).
    pub fn list(&self) -> Vec<Arc<Entry>> {
        let mut all: Vec<_> = self.entries.read().unwrap().values().cloned().collect();
        all.sort_by(|a, b| a.manifest.name.cmp(&b.manifest.name).then_with(|| a.id.cmp(&b.id)));
        all
    }

    pub fn path_of(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.{BUNDLE_EXT}"))
    }

    /// Validates and stores bundle bytes. Returns the entry and whether it is new (an
    /// identical bundle already stored is not written again). Blocking: call off the runtime.
    pub fn put(&self, bytes: Vec<u8>) -> Result<(Arc<Entry>, bool), StoreError> {
        let entry = Entry::from_bytes(&bytes, self.tile_size)?;
        if let Some(existing) = self.get(&entry.id) {
            return Ok((existing, false));
        }
        write_atomic(&self.dir, &self.path_of(&entry.id), &bytes)?;
        let entry = Arc::new(entry);
        let mut map = self.entries.write().unwrap();
        let stored = map.entry(entry.id.clone()).or_insert_with(|| entry.clone()).clone();
        Ok((stored, true))
    }
}

/// Writes `bytes` to `path` so that readers and crashes see all of it or none of it.
pub fn write_atomic(dir: &Path, path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let file_name = path.file_name().and_then(|s| s.to_str()).unwrap_or("bundle");
    let tmp = dir.join(format!("{TEMP_PREFIX}{}-{n}-{file_name}", std::process::id()));
    let result = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        f.sync_all()?;
        drop(f);
        std::fs::rename(&tmp, path)?;
        sync_dir(dir)
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

fn sync_dir(dir: &Path) -> std::io::Result<()> {
    std::fs::File::open(dir)?.sync_all()
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

    #[test]
    fn atomic_write_leaves_no_temp() {
        let dir = std::env::temp_dir().join(format!("vtex-store-unit-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        let path = dir.join("x.vtex");
        write_atomic(&dir, &path, b"hello").unwrap();
        assert_eq!(std::fs::read(&path).unwrap(), b"hello");
        let names: Vec<_> = std::fs::read_dir(&dir).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names, vec![std::ffi::OsString::from("x.vtex")]);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn open_removes_stale_temps_and_rejects_garbage() {
        let dir = std::env::temp_dir().join(format!("vtex-store-open-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(".tmp-1-0-abc.vtex"), b"half a bundle").unwrap();
        let bogus = dir.join(format!("{}.vtex", "ab".repeat(32)));
        std::fs::write(&bogus, b"not a bundle").unwrap();
        let (store, report) = Store::open(&dir, 256, false).unwrap();
        assert_eq!(report.stale_temp_removed, 1);
        assert!(!dir.join(".tmp-1-0-abc.vtex").exists());
        assert_eq!(report.rejected.len(), 1);
        assert!(report.rejected[0].1.contains("bad magic"), "{:?}", report.rejected);
        assert!(bogus.exists(), "invalid files are left alone, never deleted");
        assert!(store.is_empty());
        assert!(matches!(store.put(b"junk".to_vec()), Err(StoreError::Invalid(_))));
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
