//! Bundles as files `<id>.vtex` of a data directory, written atomically.

use super::atomic::{sync_dir, write_atomic};
use super::bundles::Listed;
use super::{StoreError, BUNDLE_EXT, STALE_TEMP_AGE, TEMP_PREFIX};
use std::path::{Path, PathBuf};
use std::time::SystemTime;
use vtex_synth::bundle::is_valid_id;

pub struct DirBundles {
    dir: PathBuf,
}

/// What opening a directory cleaned up: temporaries of crashed writes.
#[derive(Debug, Default)]
pub struct Cleanup {
    pub removed: usize,
    /// Those that could not be removed: left in place, never served.
    pub kept: Vec<(PathBuf, String)>,
}

/// A full disk is a full store, not a failure of the server.
fn write_error(e: std::io::Error) -> StoreError {
    use std::io::ErrorKind::{QuotaExceeded, StorageFull};
    match e.kind() {
        StorageFull | QuotaExceeded => StoreError::Full("the disk holding the store is full".into()),
        _ => StoreError::Io(e),
    }
}

impl DirBundles {
    /// Opens (creating if needed) `dir` and removes the temporaries of crashed writes: those
    /// older than [`STALE_TEMP_AGE`], since a fresh one may be another process's write in
    /// progress.
    pub fn open(dir: &Path) -> std::io::Result<(DirBundles, Cleanup)> {
        std::fs::create_dir_all(dir)?;
        let mut cleanup = Cleanup::default();
        for item in std::fs::read_dir(dir)? {
            let item = item?;
            if !item.file_name().to_string_lossy().starts_with(TEMP_PREFIX) {
                continue;
            }
            let age = item.metadata().and_then(|m| m.modified()).map(|t| SystemTime::now().duration_since(t));
            if !matches!(age, Ok(Ok(age)) if age >= STALE_TEMP_AGE) {
                continue;
            }
            match std::fs::remove_file(item.path()) {
                Ok(()) => cleanup.removed += 1,
                Err(e) => cleanup.kept.push((item.path(), e.to_string())),
            }
        }
        if cleanup.removed > 0 {
            sync_dir(dir)?;
        }
        Ok((DirBundles { dir: dir.to_path_buf() }, cleanup))
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    pub fn path_of(&self, id: &str) -> PathBuf {
        self.dir.join(format!("{id}.{BUNDLE_EXT}"))
    }

    /// The bundles of the directory, by name (content is checked when read); the version is
    /// the file's length and modification time.
    pub fn list(&self) -> Result<Vec<Listed>, StoreError> {
        let mut listed = Vec::new();
        for item in std::fs::read_dir(&self.dir)? {
            let item = item?;
            let name = item.file_name().to_string_lossy().into_owned();
            let Some(stem) = name.strip_suffix(&format!(".{BUNDLE_EXT}")) else { continue };
            if name.starts_with(TEMP_PREFIX) {
                continue;
            }
            let version = item.metadata().map(|m| format!("{}-{:?}", m.len(), m.modified().ok())).unwrap_or_default();
            listed.push(Listed { name: stem.to_string(), version });
        }
        Ok(listed)
    }

    /// Cheap: no read.
    pub fn exists(&self, id: &str) -> bool {
        self.path_of(id).is_file()
    }

    pub fn read(&self, id: &str) -> Result<Option<Vec<u8>>, StoreError> {
        match std::fs::read(self.path_of(id)) {
            Ok(bytes) => Ok(Some(bytes)),
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(None),
            Err(e) => Err(e.into()),
        }
    }

    /// Writes bundle `id` (whose content is `bytes`) atomically and durably.
    pub fn create(&self, id: &str, bytes: &[u8]) -> Result<(), StoreError> {
        write_atomic(&self.dir, &self.path_of(id), bytes).map_err(write_error)
    }

    /// Removes bundle `id` durably; false when there was none.
    pub fn delete(&self, id: &str) -> Result<bool, StoreError> {
        match std::fs::remove_file(self.path_of(id)) {
            Ok(()) => {
                sync_dir(&self.dir)?;
                Ok(true)
            }
            Err(e) if e.kind() == std::io::ErrorKind::NotFound => Ok(false),
            Err(e) => Err(e.into()),
        }
    }

    /// The id a path of the directory names, when it names a bundle.
    pub fn id_of_path(path: &Path) -> Option<&str> {
        let name = path.file_name()?.to_str()?;
        name.strip_suffix(&format!(".{BUNDLE_EXT}")).filter(|id| is_valid_id(id))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_full_disk_is_a_full_store() {
        for kind in [std::io::ErrorKind::StorageFull, std::io::ErrorKind::QuotaExceeded] {
            let e = write_error(std::io::Error::from(kind));
            assert!(matches!(&e, StoreError::Full(m) if m.contains("disk")), "{kind:?}: {e:?}");
        }
        let e = write_error(std::io::Error::from(std::io::ErrorKind::PermissionDenied));
        assert!(matches!(e, StoreError::Io(_)), "{e:?}");
    }
}
