//! The client's page cache on disk: pages kept across runs in one directory, bounded in bytes,
//! the least recently used evicted first.
//!
//! One file a page, named by the BLAKE3 hash of its key (texture, page and format: a page URL
//! without its host, immutable per texture id). A file holds a header (magic, the key itself,
//! the page's size, its `ETag`, until when it is fresh), the page's bytes and the BLAKE3 hash
//! of all of that: a file whose hash, length or key does not match (torn by a crash, cut,
//! flipped on disk, or another key's) is removed and never served. Writes go to a temporary
//! file in the same directory, then a rename: a reader sees a whole entry or none. Temporary
//! files left by a crash are removed on [`DiskCache::open`].
//!
//! Recency survives a restart through the files' modification times: [`DiskCache::get`]
//! touches the file it serves, and `open` orders the entries by them.
//!
//! The file system calls are blocking: pages are small (tens of kilobytes) and a page read
//! from the disk replaces a network round trip; an engine that cannot block a runtime thread
//! at all calls the client from its own.
//!
//! No crate fitted: `cacache` checks integrity and writes atomically but has no byte bound or
//! eviction; the format here is one small module over `blake3`, which the workspace already
//! builds.

use crate::{Page, PageAddr, PageKey};
use lru::LruCache;
use std::fs;
use std::io::{self, Write};
use std::path::{Path, PathBuf};
use std::sync::atomic::{AtomicU64, Ordering};
use std::time::{SystemTime, UNIX_EPOCH};

const MAGIC: &[u8; 8] = b"vtexpg01";
const EXT: &str = "page";
const TMP: &str = "tmp";

/// A page read from the disk, and whether it is still fresh (else it is revalidated with its
/// `ETag` before use, or fetched again without one).
#[derive(Clone, Debug)]
pub struct DiskEntry {
    pub page: Page,
    /// Seconds since the Unix epoch until which the server said the page is fresh
    /// (`Cache-Control: max-age`); 0: revalidate on every reuse.
    pub fresh_until: u64,
}

impl DiskEntry {
    pub fn is_fresh(&self) -> bool {
        self.fresh_until > now()
    }
}

/// Seconds since the Unix epoch.
pub fn now() -> u64 {
    SystemTime::now().duration_since(UNIX_EPOCH).map_or(0, |d| d.as_secs())
}

/// The bounded directory of pages.
pub struct DiskCache {
    dir: PathBuf,
    /// File name → its length, least recently used first.
    lru: LruCache<String, u64>,
    bytes: u64,
    budget: u64,
}

/// The text a page's file is named by and holds (checked on read).
fn key_text(key: &PageKey) -> String {
    let PageAddr { level, x, y } = key.addr;
    format!("{}/{level}/{x}/{y}.{}?{}", key.texture, key.spec.ext(), key.spec.query())
}

fn file_name(key: &PageKey) -> String {
    format!("{}.{EXT}", blake3::hash(key_text(key).as_bytes()).to_hex())
}

/// A page's file: magic, the key, width, height, freshness, `ETag`, the bytes, the hash of all
/// before it.
fn encode(key: &PageKey, page: &Page, fresh_until: u64) -> Vec<u8> {
    let key = key_text(key);
    let etag = page.etag.as_deref().unwrap_or("");
    let mut out = Vec::with_capacity(page.bytes.len() + key.len() + etag.len() + 80);
    out.extend_from_slice(MAGIC);
    out.extend_from_slice(&(key.len() as u32).to_le_bytes());
    out.extend_from_slice(key.as_bytes());
    out.extend_from_slice(&page.width.to_le_bytes());
    out.extend_from_slice(&page.height.to_le_bytes());
    out.extend_from_slice(&fresh_until.to_le_bytes());
    out.push(page.etag.is_some() as u8);
    out.extend_from_slice(&(etag.len() as u32).to_le_bytes());
    out.extend_from_slice(etag.as_bytes());
    out.extend_from_slice(&(page.bytes.len() as u64).to_le_bytes());
    out.extend_from_slice(&page.bytes);
    let hash = blake3::hash(&out);
    out.extend_from_slice(hash.as_bytes());
    out
}

/// The entry of `key` in a file's bytes, or `None` when anything does not check.
fn decode(key: &PageKey, file: &[u8]) -> Option<DiskEntry> {
    let (content, hash) = file.split_at_checked(file.len().checked_sub(32)?)?;
    if blake3::hash(content).as_bytes() != hash {
        return None;
    }
    let mut r = Reader(content);
    if r.take(8)? != MAGIC {
        return None;
    }
    let n = r.u32()? as usize;
    if r.take(n)? != key_text(key).as_bytes() {
        return None;
    }
    let (width, height, fresh_until) = (r.u32()?, r.u32()?, r.u64()?);
    let has_etag = r.take(1)?[0] == 1;
    let n = r.u32()? as usize;
    let etag = String::from_utf8(r.take(n)?.to_vec()).ok()?;
    let n = usize::try_from(r.u64()?).ok()?;
    let bytes = r.take(n)?.to_vec().into();
    if !r.0.is_empty() {
        return None;
    }
    let page = Page { addr: key.addr, width, height, bytes, etag: has_etag.then_some(etag) };
    Some(DiskEntry { page, fresh_until })
}

struct Reader<'a>(&'a [u8]);

impl<'a> Reader<'a> {
    fn take(&mut self, n: usize) -> Option<&'a [u8]> {
        let (head, rest) = self.0.split_at_checked(n)?;
        self.0 = rest;
        Some(head)
    }
    fn u32(&mut self) -> Option<u32> {
        Some(u32::from_le_bytes(self.take(4)?.try_into().ok()?))
    }
    fn u64(&mut self) -> Option<u64> {
        Some(u64::from_le_bytes(self.take(8)?.try_into().ok()?))
    }
}

/// Temporary files of this process are told apart by a counter.
static TMP_COUNTER: AtomicU64 = AtomicU64::new(0);

impl DiskCache {
    /// The cache in `dir` (created if need be), bounded to `budget` bytes of files: the files
    /// there are indexed by modification time (oldest first), those over the budget evicted,
    /// temporary files removed. Entries are checked when read, not here.
    pub fn open(dir: impl AsRef<Path>, budget: u64) -> io::Result<DiskCache> {
        let dir = dir.as_ref().to_path_buf();
        fs::create_dir_all(&dir)?;
        let mut found = Vec::new();
        for entry in fs::read_dir(&dir)? {
            let entry = entry?;
            let name = entry.file_name().to_string_lossy().into_owned();
            let meta = entry.metadata()?;
            if !meta.is_file() {
                continue;
            }
            if name.ends_with(&format!(".{TMP}")) {
                let _ = fs::remove_file(entry.path());
            } else if name.ends_with(&format!(".{EXT}")) {
                found.push((meta.modified().unwrap_or(UNIX_EPOCH), name, meta.len()));
            }
        }
        found.sort();
        let mut cache = DiskCache { dir, lru: LruCache::unbounded(), bytes: 0, budget };
        for (_, name, len) in found {
            cache.bytes += len;
            cache.lru.put(name, len);
        }
        cache.evict();
        Ok(cache)
    }

    /// The entry of `key`, made the most recently used; a file that does not check is removed.
    pub fn get(&mut self, key: &PageKey) -> Option<DiskEntry> {
        let name = file_name(key);
        self.lru.get(&name)?;
        let path = self.dir.join(&name);
        match fs::read(&path).ok().and_then(|bytes| decode(key, &bytes)) {
            Some(entry) => {
                if let Ok(f) = fs::File::options().write(true).open(&path) {
                    let _ = f.set_modified(SystemTime::now());
                }
                Some(entry)
            }
            None => {
                self.forget(&name);
                None
            }
        }
    }

    /// Writes `page` under `key` (temporary file, then rename), evicting the least recently
    /// used files until the budget holds. A page larger than the whole budget is not kept.
    pub fn put(&mut self, key: &PageKey, page: &Page, fresh_until: u64) -> io::Result<()> {
        let bytes = encode(key, page, fresh_until);
        let len = bytes.len() as u64;
        if len > self.budget {
            return Ok(());
        }
        let name = file_name(key);
        let n = TMP_COUNTER.fetch_add(1, Ordering::Relaxed);
        let tmp = self.dir.join(format!("{name}.{}.{n}.{TMP}", std::process::id()));
        let written = fs::File::create(&tmp).and_then(|mut f| f.write_all(&bytes));
        if let Err(e) = written.and_then(|()| fs::rename(&tmp, self.dir.join(&name))) {
            let _ = fs::remove_file(&tmp);
            return Err(e);
        }
        if let Some(old) = self.lru.put(name, len) {
            self.bytes -= old;
        }
        self.bytes += len;
        self.evict();
        Ok(())
    }

    fn forget(&mut self, name: &str) {
        if let Some(len) = self.lru.pop(name) {
            self.bytes -= len;
        }
        let _ = fs::remove_file(self.dir.join(name));
    }

    fn evict(&mut self) {
        while self.bytes > self.budget {
            let Some((name, len)) = self.lru.pop_lru() else { break };
            self.bytes -= len;
            let _ = fs::remove_file(self.dir.join(name));
        }
    }

    /// Bytes of the files held; never above the budget.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    pub fn len(&self) -> usize {
        self.lru.len()
    }

    pub fn is_empty(&self) -> bool {
        self.lru.is_empty()
    }

    pub fn dir(&self) -> &Path {
        &self.dir
    }

    /// The file `key` is (or would be) kept in.
    pub fn path_of(&self, key: &PageKey) -> PathBuf {
        self.dir.join(file_name(key))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::PageSpec;

    fn page(x: u32, n: usize) -> (PageKey, Page) {
        let addr = PageAddr { level: 1, x, y: 2 };
        let key = PageKey { texture: "abc".into(), addr, spec: PageSpec::default() };
        let bytes: Vec<u8> = (0..n).map(|i| (i * 7 + x as usize) as u8).collect();
        (key, Page { addr, width: 136, height: 136, bytes: bytes.into(), etag: Some(format!("\"e{x}\"")) })
    }

    fn size(n: usize) -> u64 {
        let (k, p) = page(0, n);
        encode(&k, &p, 0).len() as u64
    }

    #[test]
    fn entries_survive_a_reopen_whole() {
        let dir = tempfile::tempdir().unwrap();
        let (k, p) = page(3, 1000);
        DiskCache::open(dir.path(), 1 << 20).unwrap().put(&k, &p, 42).unwrap();
        let mut c = DiskCache::open(dir.path(), 1 << 20).unwrap();
        assert_eq!((c.len(), c.bytes()), (1, size(1000)));
        let e = c.get(&k).unwrap();
        assert!(!e.is_fresh(), "1970 is past");
        assert_eq!((e.page.bytes, e.page.etag, e.page.width, e.fresh_until), (p.bytes, p.etag, 136, 42));
        let other = PageKey { texture: "abd".into(), ..k };
        assert!(c.get(&other).is_none());
        let names: Vec<_> = fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().file_name()).collect();
        assert_eq!(names.len(), 1, "no temporary file left: {names:?}");
    }

    /// Any byte flipped, the file cut anywhere or grown, or another key's file in its place:
    /// never served, and removed.
    #[test]
    fn a_damaged_entry_is_removed_and_never_served() {
        let dir = tempfile::tempdir().unwrap();
        let (k, p) = page(1, 300);
        let good = encode(&k, &p, 0);
        let mut damaged: Vec<Vec<u8>> = Vec::new();
        for at in [0, 9, 20, 60, good.len() / 2, good.len() - 40, good.len() - 1] {
            let mut d = good.clone();
            d[at] ^= 0x10;
            damaged.push(d);
        }
        for cut in [0, 1, 31, 32, 100, good.len() - 33, good.len() - 1] {
            damaged.push(good[..cut].to_vec());
        }
        damaged.push([good.clone(), vec![0]].concat());
        let (k2, p2) = page(2, 300);
        damaged.push(encode(&k2, &p2, 0));
        for (i, bytes) in damaged.iter().enumerate() {
            let mut c = DiskCache::open(dir.path(), 1 << 20).unwrap();
            c.put(&k, &p, 0).unwrap();
            fs::write(c.path_of(&k), bytes).unwrap();
            assert!(c.get(&k).is_none(), "damage {i} served");
            assert!(!c.path_of(&k).exists(), "damage {i} kept");
            assert_eq!((c.len(), c.bytes()), (0, 0));
        }
        let mut c = DiskCache::open(dir.path(), 1 << 20).unwrap();
        c.put(&k, &p, 0).unwrap();
        assert_eq!(c.get(&k).unwrap().page.bytes, p.bytes, "the undamaged file reads");
    }

    #[test]
    fn the_budget_holds_least_recently_used_first_across_runs() {
        let dir = tempfile::tempdir().unwrap();
        let one = size(1000);
        let mut c = DiskCache::open(dir.path(), 3 * one).unwrap();
        for x in 0..3 {
            c.put(&page(x, 1000).0, &page(x, 1000).1, 0).unwrap();
            std::thread::sleep(std::time::Duration::from_millis(20));
        }
        assert!(c.get(&page(0, 1000).0).is_some(), "0 is now the most recent");
        std::thread::sleep(std::time::Duration::from_millis(20));
        c.put(&page(3, 1000).0, &page(3, 1000).1, 0).unwrap();
        assert_eq!((c.len(), c.bytes()), (3, 3 * one));
        assert!(!c.path_of(&page(1, 1000).0).exists(), "1 was the least recent");
        drop(c);
        // Reopened with room for two: the order of use survives in the files' times.
        let mut c = DiskCache::open(dir.path(), 2 * one).unwrap();
        assert_eq!((c.len(), c.bytes()), (2, 2 * one));
        assert!(c.get(&page(2, 1000).0).is_none(), "2 was the least recent left");
        assert!(c.get(&page(0, 1000).0).is_some() && c.get(&page(3, 1000).0).is_some());
        c.put(&page(9, 5000).0, &page(9, 5000).1, 0).unwrap();
        assert!(c.get(&page(9, 5000).0).is_none(), "larger than the budget: not kept");
        let total: u64 = fs::read_dir(dir.path()).unwrap().map(|e| e.unwrap().metadata().unwrap().len()).sum();
        assert_eq!(total, c.bytes());
    }

    #[test]
    fn temporary_files_of_a_crash_are_removed_on_open() {
        let dir = tempfile::tempdir().unwrap();
        fs::write(dir.path().join(format!("x.1.2.{TMP}")), b"half").unwrap();
        let c = DiskCache::open(dir.path(), 1 << 20).unwrap();
        assert!(c.is_empty());
        assert_eq!(fs::read_dir(dir.path()).unwrap().count(), 0);
    }
}
