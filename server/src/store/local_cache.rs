//! A replica's own copies of bundles kept in an object store: a directory laid out as a data
//! directory, bounded in bytes, least recently used removed first. Copies are checked against
//! their id when read, so a damaged one is fetched again, never served. Best effort: a copy
//! that cannot be written is logged and the bundle served from memory.

use super::atomic::write_whole;
use super::dir::DirBundles;
use crate::byte_lru::ByteLru;
use std::path::Path;
use std::sync::Mutex;
use std::time::SystemTime;
use vtex_synth::bundle::{id_of, is_valid_id};

pub struct LocalCache {
    files: DirBundles,
    budget: u64,
    kept: Mutex<ByteLru<String, ()>>,
}

impl LocalCache {
    /// Opens `dir` and takes the copies already there (from an earlier run), the most recently
    /// modified kept when they exceed `budget`.
    pub fn open(dir: &Path, budget: u64) -> std::io::Result<LocalCache> {
        let (files, _) = DirBundles::open(dir)?;
        let mut found: Vec<(SystemTime, String, u64)> = Vec::new();
        for item in std::fs::read_dir(dir)? {
            let item = item?;
            let path = item.path();
            let Some(id) = DirBundles::id_of_path(&path) else { continue };
            let Ok(meta) = item.metadata() else { continue };
            found.push((meta.modified().unwrap_or(SystemTime::UNIX_EPOCH), id.to_string(), meta.len()));
        }
        found.sort();
        let cache = LocalCache { files, budget, kept: Mutex::default() };
        for (_, id, bytes) in found {
            cache.keep(id, bytes);
        }
        Ok(cache)
    }

    /// The copy of bundle `id`, when one is kept and whole.
    pub fn get(&self, id: &str) -> Option<Vec<u8>> {
        self.kept.lock().unwrap().get(id)?;
        match self.files.read(id) {
            Ok(Some(bytes)) if id_of(&bytes) == id => Some(bytes),
            Ok(Some(_)) => {
                tracing::warn!(%id, path = %self.files.path_of(id).display(), "a local copy of a bundle is damaged; fetching it again");
                self.remove(id);
                None
            }
            _ => {
                self.kept.lock().unwrap().pop(id);
                None
            }
        }
    }

    /// Keeps a copy of bundle `id`, whose content `bytes` was checked against it.
    pub fn put(&self, id: &str, bytes: &[u8]) {
        debug_assert!(is_valid_id(id));
        if bytes.len() as u64 > self.budget {
            return;
        }
        // Not synced: a copy a crash cuts short fails its check when read and is fetched again.
        match write_whole(self.files.dir(), &self.files.path_of(id), bytes, false) {
            Ok(()) => self.keep(id.to_string(), bytes.len() as u64),
            Err(e) => {
                tracing::warn!(%id, error = %e, dir = %self.files.dir().display(), "cannot keep a local copy of a bundle")
            }
        }
    }

    pub fn remove(&self, id: &str) {
        self.kept.lock().unwrap().pop(id);
        let _ = self.files.delete(id);
    }

    fn keep(&self, id: String, bytes: u64) {
        let mut kept = self.kept.lock().unwrap();
        kept.put(id, (), bytes);
        while kept.bytes() > self.budget {
            let Some((old, _)) = kept.pop_lru() else { break };
            let _ = self.files.delete(&old);
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn copies_stay_within_the_budget_and_damaged_ones_are_dropped() {
        let dir = tempdir("bounded");
        let cache = LocalCache::open(&dir, 10).unwrap();
        let (a, b) = (id_of(b"aaaaaa"), id_of(b"bbbbbb"));
        cache.put(&a, b"aaaaaa");
        cache.put(&b, b"bbbbbb");
        assert_eq!(cache.get(&a), None, "the least recently used copy was not removed");
        assert!(!dir.join(format!("{a}.vtex")).exists());
        assert_eq!(cache.get(&b).as_deref(), Some(&b"bbbbbb"[..]));
        assert_eq!(cache.kept.lock().unwrap().bytes(), 6);
        // A copy damaged on disk is not served, and is removed.
        std::fs::write(dir.join(format!("{b}.vtex")), b"bbbbbX").unwrap();
        assert_eq!(cache.get(&b), None);
        assert!(!dir.join(format!("{b}.vtex")).exists());
        assert_eq!(cache.kept.lock().unwrap().bytes(), 0);
        // A bundle larger than the whole budget is not kept at all.
        let big = id_of(b"0123456789ab");
        cache.put(&big, b"0123456789ab");
        assert_eq!(cache.get(&big), None);
        std::fs::remove_dir_all(&dir).unwrap();
    }

    #[test]
    fn copies_of_an_earlier_run_are_taken_newest_first() {
        let dir = tempdir("reopen");
        let (a, b) = (id_of(b"aaaaaa"), id_of(b"bbbbbb"));
        {
            let cache = LocalCache::open(&dir, 100).unwrap();
            cache.put(&a, b"aaaaaa");
            cache.put(&b, b"bbbbbb");
        }
        let old = SystemTime::now() - std::time::Duration::from_secs(60);
        std::fs::File::options().write(true).open(dir.join(format!("{a}.vtex"))).unwrap().set_modified(old).unwrap();
        let cache = LocalCache::open(&dir, 8).unwrap();
        assert_eq!(cache.get(&a), None, "the older copy was kept over the newer");
        assert_eq!(cache.get(&b).as_deref(), Some(&b"bbbbbb"[..]));
        std::fs::remove_dir_all(&dir).unwrap();
    }

    fn tempdir(name: &str) -> std::path::PathBuf {
        let dir = std::env::temp_dir().join(format!("vtex-local-cache-{name}-{}", std::process::id()));
        let _ = std::fs::remove_dir_all(&dir);
        dir
    }
}
