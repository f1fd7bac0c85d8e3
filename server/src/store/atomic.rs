//! Writes that readers and crashes see whole or not at all.

use super::TEMP_PREFIX;
use std::io::Write;
use std::path::Path;
use std::sync::atomic::{AtomicU64, Ordering};

/// Writes `bytes` to `path` so that readers and crashes see all of it or none of it.
/// The temporary name is unique across processes sharing `dir` — even replicas in containers,
/// which all run as pid 1 — by a random tag drawn once per process.
pub fn write_atomic(dir: &Path, path: &Path, bytes: &[u8]) -> std::io::Result<()> {
    write_whole(dir, path, bytes, true)
}

/// Writes `bytes` to `path` so that readers see all of it or none of it; `durable` also makes
/// it survive a crash (fsync of the file and the directory). Without it a crash may leave the
/// file short or empty: for copies checked when read.
pub(super) fn write_whole(dir: &Path, path: &Path, bytes: &[u8], durable: bool) -> std::io::Result<()> {
    use std::hash::{BuildHasher, RandomState};
    static COUNTER: AtomicU64 = AtomicU64::new(0);
    static PROCESS_TAG: std::sync::OnceLock<u64> = std::sync::OnceLock::new();
    let tag = PROCESS_TAG.get_or_init(|| RandomState::new().hash_one(std::process::id()));
    let n = COUNTER.fetch_add(1, Ordering::Relaxed);
    let file_name = path.file_name().and_then(|s| s.to_str()).unwrap_or("bundle");
    let tmp = dir.join(format!("{TEMP_PREFIX}{tag:016x}-{n}-{file_name}"));
    let result = (|| {
        let mut f = std::fs::OpenOptions::new().write(true).create_new(true).open(&tmp)?;
        f.write_all(bytes)?;
        if durable {
            f.sync_all()?;
        }
        drop(f);
        std::fs::rename(&tmp, path)?;
        if durable {
            sync_dir(dir)?;
        }
        Ok(())
    })();
    if result.is_err() {
        let _ = std::fs::remove_file(&tmp);
    }
    result
}

pub(super) fn sync_dir(dir: &Path) -> std::io::Result<()> {
    std::fs::File::open(dir)?.sync_all()
}

#[cfg(test)]
mod tests {
    use super::*;

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
}
