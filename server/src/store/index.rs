//! [`Store`]: the index of the stored bundles, their writes and deletions, and the textures
//! loaded from them. Where the bundles live is [`Bundles`]'s concern.

use super::budget::{Budgeted, Charge};
use super::bundles::Bundles;
use super::dir::DirBundles;
use super::{Entry, Record};
use std::collections::{BTreeMap, HashMap, HashSet};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex, RwLock};
use std::time::Instant;
use vtex_synth::bundle::{id_of, is_valid_id, Bundle};
use vtex_synth::models::{self, Limits};
use vtex_synth::Resources;

/// Age past which a temporary file is a crashed write: a write in progress (of another
/// process sharing the directory) takes seconds.
pub const STALE_TEMP_AGE: std::time::Duration = std::time::Duration::from_secs(15 * 60);
/// How long an id found absent from the store is answered absent without looking again.
pub const ABSENT_TTL: std::time::Duration = std::time::Duration::from_secs(2);
/// Most ids remembered absent; past it the memory starts over.
const ABSENT_MAX: usize = 16_384;

#[derive(Debug, thiserror::Error)]
pub enum StoreError {
    #[error("{0}")]
    Invalid(#[from] vtex_synth::Error),
    /// A cap of the store is reached, or the disk is full: the message names which.
    #[error("{0}")]
    Full(String),
    #[error("storage failure: {0}")]
    Io(#[from] std::io::Error),
    /// The object store did not answer, or failed, within its deadline: worth retrying. The
    /// message is for the log; it may name the endpoint.
    #[error("the object store is unavailable: {0}")]
    Unavailable(String),
}

/// The bounds a serving store keeps.
#[derive(Clone, Copy, Debug)]
pub struct Bounds {
    pub tile_size: u32,
    /// What one texture may cost; `max_resident_bytes` is also the budget of all loaded textures.
    pub limits: Limits,
    pub max_textures: usize,
    /// Bytes of stored bundles.
    pub max_store_bytes: u64,
}

impl Bounds {
    /// No bound but the tile size: for the offline commands.
    pub fn unbounded(tile_size: u32) -> Bounds {
        Bounds { tile_size, limits: Limits::NONE, max_textures: usize::MAX, max_store_bytes: u64::MAX }
    }
}

/// The indexed bundles and the bytes they take in the store.
#[derive(Default)]
struct Index {
    records: BTreeMap<String, Arc<Record>>,
    bytes: u64,
}

/// The stored bundles: every servable one indexed, textures loaded within the budget.
pub struct Store {
    bundles: Bundles,
    bounds: Bounds,
    /// What the loaded textures share: the models' caches and work counters.
    resources: Resources,
    index: RwLock<Index>,
    loaded: Budgeted<Arc<Entry>>,
    loads: AtomicU64,
    /// Held from the last check of the index and the caps to the index holding the new bundle,
    /// so that of identical uploads exactly one is new, and concurrent uploads cannot pass a cap.
    writing: Mutex<()>,
    /// Ids recently found absent from the store, and when.
    absent: Mutex<HashMap<String, Instant>>,
    /// Names listed but refused, with the version refused: read again only once it changes.
    refused: Mutex<HashMap<String, String>>,
}

/// What [`Store::open`] found, for the start-up log.
#[derive(Debug, Default)]
pub struct OpenReport {
    pub indexed: usize,
    pub demos_written: usize,
    pub stale_temp_removed: usize,
    /// Temporary files of crashed writes that could not be removed: left in place, never served.
    pub stale_temp_kept: Vec<(PathBuf, String)>,
    /// Where bundles that are not valid are stored (a path or a URL: wrong name, hash
    /// mismatch, invalid, over the bounds), and why: left alone, not served.
    pub rejected: Vec<(String, String)>,
    /// Demos over the bounds or the caps, by name: not written.
    pub demos_refused: Vec<(String, String)>,
}

/// What is stored under a name, once read and planned.
enum Found {
    Servable(Box<Record>),
    Absent,
    /// Not a servable bundle, and why.
    Refused(String),
}

impl Store {
    /// Opens (creating if needed) the data directory `dir`: removes temporary files of crashed
    /// writes, indexes every bundle within `bounds`, and writes the demos into an empty
    /// directory.
    pub fn open(
        dir: &Path,
        bounds: Bounds,
        resources: Resources,
        write_demos: bool,
    ) -> std::io::Result<(Store, OpenReport)> {
        let (files, cleanup) = DirBundles::open(dir)?;
        let mut report =
            OpenReport { stale_temp_removed: cleanup.removed, stale_temp_kept: cleanup.kept, ..Default::default() };
        let store =
            Store::open_in(Bundles::Dir(files), bounds, resources, write_demos, &mut report).map_err(|e| match e {
                StoreError::Io(e) => e,
                e => std::io::Error::other(e.to_string()),
            })?;
        Ok((store, report))
    }

    /// Indexes every bundle of `bundles` within `bounds`, and writes the demos when there are
    /// none, adding what it found to `report`. Fails when the bundles cannot be listed, or an
    /// object store does not answer.
    pub fn open_in(
        bundles: Bundles,
        bounds: Bounds,
        resources: Resources,
        write_demos: bool,
        report: &mut OpenReport,
    ) -> Result<Store, StoreError> {
        let store = Store {
            bundles,
            bounds,
            resources,
            index: Default::default(),
            loaded: Budgeted::new(bounds.limits.max_resident_bytes),
            loads: AtomicU64::new(0),
            writing: Mutex::new(()),
            absent: Default::default(),
            refused: Default::default(),
        };
        let mut listed = store.bundles.list()?;
        listed.sort_by(|a, b| a.name.cmp(&b.name));
        for item in &listed {
            match store.read_and_plan(&item.name)? {
                Found::Servable(record) => store.insert(Arc::new(*record)),
                Found::Absent => {}
                Found::Refused(why) => {
                    report.rejected.push((store.bundles.name_of(&item.name), why));
                    store.refused.lock().unwrap().insert(item.name.clone(), item.version.clone());
                }
            }
        }
        report.indexed = store.len();
        if listed.is_empty() && write_demos {
            for demo in models::demos() {
                match store.put_made(demo.to_bytes()) {
                    Ok((_, created)) => report.demos_written += created as usize,
                    Err(e @ (StoreError::Io(_) | StoreError::Unavailable(_))) => return Err(e),
                    Err(e @ (StoreError::Full(_) | StoreError::Invalid(vtex_synth::Error::TooCostly { .. }))) => {
                        report.demos_refused.push((demo.manifest.name.clone(), e.to_string()))
                    }
                    Err(StoreError::Invalid(e)) => {
                        return Err(StoreError::Io(std::io::Error::other(format!(
                            "demo `{}` is invalid: {e}",
                            demo.manifest.name
                        ))))
                    }
                }
            }
        }
        Ok(store)
    }

    /// Reads and plans what is stored under `name`, checking the name against the content.
    /// Fails only when the store cannot be reached.
    fn read_and_plan(&self, name: &str) -> Result<Found, StoreError> {
        if !is_valid_id(name) {
            return Ok(Found::Refused("its name is not a bundle id".into()));
        }
        let bytes = match self.bundles.read(name) {
            Ok(Some(bytes)) => bytes,
            Ok(None) => return Ok(Found::Absent),
            Err(e @ StoreError::Unavailable(_)) => return Err(e),
            Err(e) => return Ok(Found::Refused(e.to_string())),
        };
        let bundle = match Bundle::from_bytes(&bytes) {
            Ok(bundle) => bundle,
            Err(e) => return Ok(Found::Refused(e.to_string())),
        };
        let id = id_of(&bytes);
        if id != name {
            return Ok(Found::Refused(format!("content hash {id} does not match the name it is stored under")));
        }
        Ok(match Record::plan(&bundle, id, bytes.len(), self.bounds.tile_size, &self.bounds.limits) {
            Ok(record) => Found::Servable(Box::new(record)),
            Err(e) => Found::Refused(e.to_string()),
        })
    }

    fn insert(&self, record: Arc<Record>) {
        self.absent.lock().unwrap().remove(&record.id);
        let mut index = self.index.write().unwrap();
        index.bytes += record.encoding_bytes;
        if let Some(old) = index.records.insert(record.id.clone(), record) {
            index.bytes -= old.encoding_bytes;
        }
    }

    /// Stops serving `id`: its bundle failed validation when loaded, or vanished.
    fn drop_record(&self, id: &str, why: &dyn std::fmt::Display) {
        tracing::warn!(%id, at = %self.bundles.name_of(id), reason = %why, "the stored bundle cannot be loaded; no longer serving it");
        self.forget(id);
    }

    /// Drops `id` from the index and the loaded textures; true when it was indexed.
    fn forget(&self, id: &str) -> bool {
        let mut index = self.index.write().unwrap();
        let Some(old) = index.records.remove(id) else { return false };
        index.bytes -= old.encoding_bytes;
        drop(index);
        self.loaded.remove(id);
        true
    }

    /// What the store knows of texture `id`, looking in the store when it is not indexed
    /// (another process may have written it): a directory is asked on the caller's thread,
    /// and only a bundle that exists is read and planned on the blocking pool, where an object
    /// store is asked. An id found absent is answered absent for [`ABSENT_TTL`] without
    /// looking again. `id` must be a valid id. Fails when an object store cannot be reached.
    pub async fn find(self: &Arc<Self>, id: &str) -> Result<Option<Arc<Record>>, StoreError> {
        if let Some(record) = self.record(id) {
            return Ok(Some(record));
        }
        if self.known_absent(id) {
            return Ok(None);
        }
        if self.bundles.exists_locally(id) == Some(false) {
            self.remember_absent(id);
            return Ok(None);
        }
        let (store, id) = (self.clone(), id.to_string());
        tokio::task::spawn_blocking(move || store.refresh_id(&id))
            .await
            .map_err(|e| StoreError::Io(std::io::Error::other(format!("looking up the bundle panicked: {e}"))))?
    }

    fn known_absent(&self, id: &str) -> bool {
        let absent = self.absent.lock().unwrap();
        absent.get(id).is_some_and(|since| since.elapsed() < ABSENT_TTL)
    }

    fn remember_absent(&self, id: &str) {
        let mut absent = self.absent.lock().unwrap();
        if absent.len() >= ABSENT_MAX {
            absent.retain(|_, since| since.elapsed() < ABSENT_TTL);
            if absent.len() >= ABSENT_MAX {
                absent.clear();
            }
        }
        absent.insert(id.to_string(), Instant::now());
    }

    /// Brings the index in line with the file at `path` of the data directory (a bundle that
    /// appeared, changed or vanished; anything else is ignored) and returns its record when
    /// it is served: for the directory watch. Blocking.
    pub fn refresh(&self, path: &Path) -> Option<Arc<Record>> {
        let id = DirBundles::id_of_path(path)?;
        self.refresh_id(id).unwrap_or_else(|e| {
            tracing::warn!(%id, error = %e, "cannot look at a bundle of the data directory");
            None
        })
    }

    /// Brings the index in line with what is stored under `id` and returns its record when it
    /// is served. What is not (yet) a valid bundle — a file still being copied in — is not
    /// served until a later refresh finds it whole. Blocking.
    fn refresh_id(&self, id: &str) -> Result<Option<Arc<Record>>, StoreError> {
        if let Some(record) = self.record(id) {
            if self.bundles.exists(id)? {
                return Ok(Some(record));
            }
            if self.forget(id) {
                tracing::info!(%id, "bundle gone from the store; no longer serving it");
            }
            self.remember_absent(id);
            return Ok(None);
        }
        match self.read_and_plan(id)? {
            Found::Servable(record) => Ok(Some(self.admit(*record))),
            Found::Absent => {
                self.remember_absent(id);
                Ok(None)
            }
            Found::Refused(why) => {
                tracing::debug!(%id, at = %self.bundles.name_of(id), reason = %why, "not serving a stored bundle (yet)");
                self.remember_absent(id);
                Ok(None)
            }
        }
    }

    /// Indexes a bundle found in the store.
    fn admit(&self, record: Record) -> Arc<Record> {
        let record = Arc::new(record);
        self.insert(record.clone());
        tracing::info!(id = %record.id, name = %record.name, "bundle found in the store; serving it");
        record
    }

    /// Lists the store again: indexes bundles that appeared and forgets those that are gone
    /// (the object store's poll; the directory watch after it lost events). What was refused
    /// is read again only once its version changes, and reported once per version. Blocking.
    pub fn rescan(&self) -> Result<(), StoreError> {
        // Only what was indexed before the listing can be missing from it: a bundle this
        // process stores meanwhile is not taken for gone.
        let before: Vec<String> = self.index.read().unwrap().records.keys().cloned().collect();
        let listed = self.bundles.list()?;
        let mut present = HashSet::new();
        for item in listed {
            present.insert(item.name.clone());
            if self.record(&item.name).is_some() || self.refused.lock().unwrap().get(&item.name) == Some(&item.version)
            {
                continue;
            }
            match self.read_and_plan(&item.name)? {
                Found::Servable(record) => {
                    self.admit(*record);
                    self.refused.lock().unwrap().remove(&item.name);
                }
                Found::Absent => {}
                Found::Refused(why) => {
                    tracing::warn!(at = %self.bundles.name_of(&item.name), reason = %why, "not serving an invalid bundle of the store");
                    self.refused.lock().unwrap().insert(item.name, item.version);
                }
            }
        }
        for id in before.iter().filter(|id| !present.contains(*id)) {
            if self.forget(id) {
                tracing::info!(%id, "bundle gone from the store; no longer serving it");
            }
            self.remember_absent(id);
        }
        self.refused.lock().unwrap().retain(|name, _| present.contains(name));
        Ok(())
    }

    /// Deletes texture `id`: its bundle leaves the store (durably) and the index; requests in
    /// flight finish with the texture they hold. False when no such bundle is stored.
    /// Blocking.
    pub fn remove(&self, id: &str) -> Result<bool, StoreError> {
        let _writing = self.writing.lock().unwrap();
        let existed = self.bundles.delete(id)?;
        let indexed = self.forget(id);
        self.remember_absent(id);
        Ok(existed || indexed)
    }

    /// Where the bundles live.
    pub fn bundles(&self) -> &Bundles {
        &self.bundles
    }

    pub fn bounds(&self) -> &Bounds {
        &self.bounds
    }

    /// What the store knows of texture `id`, without loading it.
    pub fn record(&self, id: &str) -> Option<Arc<Record>> {
        self.index.read().unwrap().records.get(id).cloned()
    }

    /// Texture `id`, loaded on its first use (on the blocking pool: call from the runtime);
    /// `None` when no such texture is served. A bundle that fails validation when loaded is
    /// dropped from the index and answered with [`StoreError::Invalid`].
    pub async fn get(self: &Arc<Self>, id: &str) -> Result<Option<Arc<Entry>>, StoreError> {
        if let Some(entry) = self.loaded.get(id) {
            return Ok(Some(entry));
        }
        let Some(record) = self.find(id).await? else { return Ok(None) };
        let turn = record.loading.clone().lock_owned().await;
        if let Some(entry) = self.loaded.get(id) {
            return Ok(Some(entry));
        }
        if self.record(id).is_none() {
            // The load this one waited on found the bundle invalid and dropped it.
            return Ok(None);
        }
        let store = self.clone();
        // The turn moves into the load, so that a request dropped while it runs (a client gone)
        // does not let the next one start a second load of the same texture.
        tokio::task::spawn_blocking(move || {
            let _turn = turn;
            store.load(record).map(Some)
        })
        .await
        .map_err(|e| StoreError::Io(std::io::Error::other(format!("loading the texture panicked: {e}"))))?
    }

    /// The bytes of indexed bundle `id` exactly as stored, checked against its id: a bundle
    /// whose content no longer matches is dropped like one that fails to load. Blocking.
    pub fn bytes_of(&self, id: &str) -> Result<Vec<u8>, StoreError> {
        let result = self.read_checked(id);
        self.drop_if_broken(id, &result);
        result
    }

    fn read_checked(&self, id: &str) -> Result<Vec<u8>, StoreError> {
        match self.bundles.read(id)? {
            Some(bytes) if id_of(&bytes) == id => Ok(bytes),
            Some(_) => Err(vtex_synth::Error::bundle("its content no longer matches its id").into()),
            None => Err(std::io::Error::from(std::io::ErrorKind::NotFound).into()),
        }
    }

    /// Drops `id` when `result` says its stored bundle is invalid or gone.
    fn drop_if_broken<T>(&self, id: &str, result: &Result<T, StoreError>) {
        match result {
            Err(StoreError::Invalid(e)) => self.drop_record(id, e),
            Err(StoreError::Io(e)) if e.kind() == std::io::ErrorKind::NotFound => self.drop_record(id, e),
            _ => {}
        }
    }

    /// Reads, validates completely and loads `record`'s texture within the budget. Blocking.
    fn load(&self, record: Arc<Record>) -> Result<Arc<Entry>, StoreError> {
        let id = record.id.clone();
        let result = self.read_checked(&id).and_then(|bytes| {
            let bundle = Bundle::from_bytes(&bytes)?;
            let (entry, charge) = self.load_charged(record, &bundle)?;
            self.loaded.keep(charge, id.clone(), entry.clone());
            Ok(entry)
        });
        self.drop_if_broken(&id, &result);
        result
    }
    /// Loads `bundle`'s texture with its charge reserved against the budget first.
    fn load_charged(
        &self,
        record: Arc<Record>,
        bundle: &Bundle,
    ) -> Result<(Arc<Entry>, Charge<'_, Arc<Entry>>), StoreError> {
        let charge = self.loaded.reserve(record.resident_bytes());
        let texture = models::load_within(bundle, &self.bounds.limits, &self.resources)?;
        self.loads.fetch_add(1, Ordering::Relaxed);
        Ok((Arc::new(Entry { record, texture }), charge))
    }

    /// What the loaded textures share.
    pub fn resources(&self) -> &Resources {
        &self.resources
    }

    /// Textures indexed (servable).
    pub fn len(&self) -> usize {
        self.index.read().unwrap().records.len()
    }

    pub fn is_empty(&self) -> bool {
        self.len() == 0
    }

    /// Bytes of the indexed bundles on disk.
    pub fn stored_bytes(&self) -> u64 {
        self.index.read().unwrap().bytes
    }

    /// Textures loaded now.
    pub fn loaded(&self) -> usize {
        self.loaded.len()
    }

    /// Bytes charged against the texture budget: loaded textures and loads in progress.
    pub fn loaded_bytes(&self) -> u64 {
        self.loaded.charged()
    }

    /// Textures loaded since open (uploads included: each is loaded to be validated).
    pub fn loads(&self) -> u64 {
        self.loads.load(Ordering::Relaxed)
    }

    /// Textures evicted to stay within the budget since open.
    pub fn evictions(&self) -> u64 {
        self.loaded.evictions()
    }

    /// Every texture, sorted by name (then id).
    pub fn list(&self) -> Vec<Arc<Record>> {
        let mut all: Vec<_> = self.index.read().unwrap().records.values().cloned().collect();
        all.sort_by(|a, b| a.name.cmp(&b.name).then_with(|| a.id.cmp(&b.id)));
        all
    }

    /// Refuses `bytes` more of bundles when the store holds its maximum of textures or bytes.
    fn check_caps(&self, bytes: u64) -> Result<(), StoreError> {
        let index = self.index.read().unwrap();
        let b = &self.bounds;
        if index.records.len() >= b.max_textures {
            return Err(StoreError::Full(format!(
                "the store holds its maximum of {} textures (--max-textures)",
                b.max_textures
            )));
        }
        if index.bytes.saturating_add(bytes) > b.max_store_bytes {
            return Err(StoreError::Full(format!(
                "a bundle of {bytes} bytes would take the store past its bound of {} bytes of bundles \
                 (--store-mb); it holds {}",
                b.max_store_bytes, index.bytes
            )));
        }
        Ok(())
    }

    /// Validates bundle bytes from outside (an upload) within the bounds and stores them:
    /// loaded, and what loading takes on trust checked by the model ([`models::verify`], e.g.
    /// a stored calibration measured again), once here rather than on every open. Returns the
    /// record and whether it is new (an identical bundle already stored is not written again);
    /// the texture stays loaded. Blocking: call off the runtime.
    pub fn put(&self, bytes: Vec<u8>) -> Result<(Arc<Record>, bool), StoreError> {
        self.accept(bytes, true)
    }

    /// [`put`](Self::put) for bytes this process's model `create` made from params and inputs
    /// (a multipart upload, a PATCH, the demos): loaded, but not verified again, as `create`
    /// derived what it stored.
    pub fn put_made(&self, bytes: Vec<u8>) -> Result<(Arc<Record>, bool), StoreError> {
        self.accept(bytes, false)
    }

    fn accept(&self, bytes: Vec<u8>, verify: bool) -> Result<(Arc<Record>, bool), StoreError> {
        let bundle = Bundle::from_bytes(&bytes)?;
        let id = id_of(&bytes);
        if let Some(existing) = self.record(&id) {
            return Ok((existing, false));
        }
        let record = Record::plan(&bundle, id, bytes.len(), self.bounds.tile_size, &self.bounds.limits)?;
        self.check_caps(bytes.len() as u64)?;
        let (entry, charge) = self.load_charged(Arc::new(record), &bundle)?;
        if verify {
            models::verify(&bundle)?;
        }
        let _writing = self.writing.lock().unwrap();
        if let Some(existing) = self.record(&entry.id) {
            return Ok((existing, false));
        }
        self.check_caps(bytes.len() as u64)?;
        let created = self.bundles.create(&entry.id, &bytes)?;
        self.insert(entry.record.clone());
        self.loaded.keep(charge, entry.id.clone(), entry.clone());
        Ok((entry.record.clone(), created))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::SystemTime;

    #[test]
    fn open_removes_stale_temps_and_rejects_garbage() {
        let dir = std::env::temp_dir().join(format!("vtex-store-open-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        std::fs::create_dir_all(&dir).unwrap();
        std::fs::write(dir.join(".tmp-1-0-abc.vtex"), b"half a bundle").unwrap();
        let old = SystemTime::now() - STALE_TEMP_AGE - std::time::Duration::from_secs(1);
        std::fs::File::options().write(true).open(dir.join(".tmp-1-0-abc.vtex")).unwrap().set_modified(old).unwrap();
        // A fresh temporary may be another process's write in progress: left alone.
        std::fs::write(dir.join(".tmp-2-0-def.vtex"), b"being written").unwrap();
        let bogus = dir.join(format!("{}.vtex", "ab".repeat(32)));
        std::fs::write(&bogus, b"not a bundle").unwrap();
        let (store, report) = Store::open(&dir, Bounds::unbounded(256), Resources::default(), false).unwrap();
        assert_eq!(report.stale_temp_removed, 1);
        assert!(!dir.join(".tmp-1-0-abc.vtex").exists());
        assert!(dir.join(".tmp-2-0-def.vtex").exists(), "a write in progress was removed");
        assert_eq!(report.rejected.len(), 1);
        assert!(report.rejected[0].1.contains("bad magic"), "{:?}", report.rejected);
        assert!(bogus.exists(), "invalid files are left alone, never deleted");
        assert!(store.is_empty());
        assert!(matches!(store.put(b"junk".to_vec()), Err(StoreError::Invalid(_))));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn bundles_written_by_another_process_are_found_and_forgotten() {
        let dir = std::env::temp_dir().join(format!("vtex-store-shared-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let store = Store::open(&dir, Bounds::unbounded(256), Resources::default(), false).unwrap().0;
        let other = Store::open(&dir, Bounds::unbounded(256), Resources::default(), false).unwrap().0;
        let bundle = models::demos().into_iter().min_by_key(|b| b.to_bytes().len()).unwrap().to_bytes();
        let (record, created) = other.put(bundle).unwrap();
        assert!(created);
        let path = dir.join(format!("{}.vtex", record.id));
        assert!(store.record(&record.id).is_none(), "indexed only at open or on refresh");
        // Refreshing is idempotent and follows the file both ways.
        assert_eq!(store.refresh(&path).unwrap().id, record.id);
        assert_eq!(store.refresh(&path).unwrap().id, record.id);
        assert_eq!((store.len(), store.stored_bytes()), (1, record.encoding_bytes));
        assert!(other.remove(&record.id).unwrap());
        assert!(!other.remove(&record.id).unwrap(), "removed twice");
        assert!(store.refresh(&path).is_none());
        assert_eq!((store.len(), store.stored_bytes()), (0, 0));
        // An id found absent is remembered briefly; indexing it forgets that.
        assert!(store.known_absent(&record.id));
        assert!(!store.known_absent(&"0".repeat(64)));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn the_memory_of_absent_ids_is_bounded() {
        let dir = std::env::temp_dir().join(format!("vtex-store-absent-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let store = Store::open(&dir, Bounds::unbounded(256), Resources::default(), false).unwrap().0;
        for i in 0..ABSENT_MAX + 10 {
            store.remember_absent(&format!("{i:064x}"));
        }
        assert!(store.absent.lock().unwrap().len() <= ABSENT_MAX);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn open_goes_on_past_a_stale_temp_it_cannot_remove() {
        let dir = std::env::temp_dir().join(format!("vtex-store-stuck-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        // A non-empty directory: `remove_file` cannot remove it, even as root.
        let stuck = dir.join(".tmp-1-0-stuck.vtex");
        std::fs::create_dir_all(&stuck).unwrap();
        std::fs::write(stuck.join("inside"), b"x").unwrap();
        std::fs::File::open(&stuck).unwrap().set_modified(SystemTime::now() - STALE_TEMP_AGE * 2).unwrap();
        let (store, report) = Store::open(&dir, Bounds::unbounded(256), Resources::default(), false).unwrap();
        assert_eq!(report.stale_temp_kept.len(), 1, "{report:?}");
        assert_eq!(report.stale_temp_kept[0].0, stuck);
        assert!(store.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn a_rescan_follows_the_store_and_reads_a_refused_bundle_again_only_once_changed() {
        let dir = std::env::temp_dir().join(format!("vtex-store-rescan-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        let store = Store::open(&dir, Bounds::unbounded(256), Resources::default(), false).unwrap().0;
        let other = Store::open(&dir, Bounds::unbounded(256), Resources::default(), false).unwrap().0;
        let bundle = models::demos().into_iter().min_by_key(|b| b.to_bytes().len()).unwrap().to_bytes();
        let (record, _) = other.put(bundle.clone()).unwrap();
        let path = dir.join(format!("{}.vtex", record.id));
        let set = |bytes: &[u8], at: SystemTime| {
            std::fs::write(&path, bytes).unwrap();
            std::fs::File::options().write(true).open(&path).unwrap().set_modified(at).unwrap();
        };
        // Damaged in place (same length, same time): refused, with its version remembered.
        let at = SystemTime::now() - std::time::Duration::from_secs(60);
        let mut damaged = bundle.clone();
        damaged[bundle.len() / 2] ^= 0xff;
        set(&damaged, at);
        store.rescan().unwrap();
        assert!(store.is_empty());
        assert_eq!(store.refused.lock().unwrap().len(), 1);
        // Whole again but of the same version: not read again.
        set(&bundle, at);
        store.rescan().unwrap();
        assert!(store.is_empty(), "an unchanged version was read again");
        // A new version is read, and served.
        set(&bundle, at + std::time::Duration::from_secs(1));
        store.rescan().unwrap();
        assert_eq!(store.list().iter().map(|r| r.id.clone()).collect::<Vec<_>>(), vec![record.id.clone()]);
        assert!(store.refused.lock().unwrap().is_empty());
        // Gone from the store: forgotten.
        assert!(other.remove(&record.id).unwrap());
        store.rescan().unwrap();
        assert!(store.is_empty());
        std::fs::remove_dir_all(&dir).unwrap();
    }
}
