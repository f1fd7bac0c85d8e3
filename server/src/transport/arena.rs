//! Sealed bodies: encoded tiles copied into whole pages of anonymous mappings that are never
//! written again once shared, so the kernel may keep references to them after a send.
//!
//! Tiles share 2 MiB arenas backed by transparent huge pages where the kernel allows (see
//! [`Arenas`]); bigger bodies, and every body where huge pages are unavailable, get a mapping
//! of their own. An arena is unmapped when the last body in it drops. A registry of live
//! bodies' address ranges lets the connection wrapper tell a sealed slice from heap memory.

use super::PAGE;
use rustix::mm::{self, Advice, MapFlags, MprotectFlags, ProtFlags};
use std::collections::BTreeMap;
use std::sync::atomic::{AtomicUsize, Ordering};
use std::sync::{Arc, Mutex, OnceLock, RwLock};

/// Bodies below this size are copied: the two extra syscalls of a splice cost more than the
/// copy saves.
pub const SEAL_MIN: usize = 16 * 1024;

/// Size and alignment of a shared arena: one transparent huge page on x86-64 and arm64.
pub const ARENA: usize = 2 << 20;
/// Bodies above this get a mapping of their own (an arena would hold too few of them).
pub const ARENA_MAX_BODY: usize = ARENA / 4;
/// Arenas' pages not holding live bodies are kept below 1/`SLACK` of the live bodies.
pub const SLACK: usize = 8;

/// Start address → length of every live sealed body.
static SEALED: RwLock<BTreeMap<usize, usize>> = RwLock::new(BTreeMap::new());

/// Where [`seal`] puts bodies: packed into arenas only where the kernel gives huge pages,
/// since arenas cost memory (see [`may_map_arena`]) and help only as one folio.
static ARENAS: Arenas = Arenas::new(None);
static HUGE_PAGES: OnceLock<bool> = OnceLock::new();

/// Whether `madvise(MADV_HUGEPAGE)` gets transparent huge pages on this system.
fn huge_pages() -> bool {
    *HUGE_PAGES.get_or_init(|| {
        std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled")
            .is_ok_and(|s| s.contains("[always]") || s.contains("[madvise]"))
    })
}

/// Whether a body of `len` bytes is sealed (smaller ones stay on the heap).
pub fn sealable(len: usize) -> bool {
    len >= SEAL_MIN
}

/// `body` in sealed pages, or on the heap when it is small or no mapping can be made.
pub fn seal(body: Vec<u8>) -> bytes::Bytes {
    if sealable(body.len()) {
        if let Some(sealed) = Sealed::new_in(&ARENAS, &body) {
            return bytes::Bytes::from_owner(sealed);
        }
    }
    bytes::Bytes::from(body)
}

/// Bytes mapped for sealed bodies now: their pages, and arena pages not (or no longer)
/// holding one.
pub fn mapped_bytes() -> usize {
    ARENAS.usage().0
}

/// True when `bytes` lies wholly inside one live sealed body.
pub fn registered(bytes: &[u8]) -> bool {
    registered_range(bytes.as_ptr() as usize, bytes.len())
}

pub fn registered_range(start: usize, len: usize) -> bool {
    let map = SEALED.read().unwrap_or_else(|e| e.into_inner());
    map.range(..=start).next_back().is_some_and(|(&s, &l)| start + len <= s + l)
}

/// Whether a new arena may be mapped for a body of `need` bytes while `mapped` bytes are
/// mapped for `live` bytes of bodies. An arena stays mapped while any of its bodies lives, so
/// one long-lived tile can keep an arena's other pages: mappings are held to the live bodies
/// plus 1/[`SLACK`] of them plus four arenas (the tile cache's byte budget then holds for the
/// memory behind it within that); beyond that, bodies get mappings of their own (4 KiB pages,
/// the slower send) until old arenas are freed.
pub fn may_map_arena(mapped: usize, live: usize, need: usize) -> bool {
    let bodies = live + need;
    mapped + ARENA <= bodies + bodies / SLACK + 4 * ARENA
}

/// Sealed bodies packed into 2 MiB arenas, each advised to be one transparent huge page.
///
/// Why: every 4 KiB page handed to a socket has its own `struct page`, whose reference count
/// the server's core writes (vmsplice, the socket's fragment, the pipe) and the receiver's
/// core writes again when it frees the received data — on loopback in the client's kernel
/// time, one cache-line transfer per page. In a huge page all of them share one count. Each
/// body takes whole pages of its own.
pub struct Arenas {
    /// Pack bodies into arenas: `None` = where the system has huge pages.
    pack: Option<bool>,
    /// The arena new bodies go into, and the offset of its first free page.
    current: Mutex<Option<(Arc<Arena>, usize)>>,
    /// Bytes of every mapping alive (arenas and bodies with a mapping of their own).
    mapped: AtomicUsize,
    /// Bytes of live bodies, in whole pages.
    live: AtomicUsize,
}

impl Arenas {
    pub const fn new(pack: Option<bool>) -> Arenas {
        Arenas { pack, current: Mutex::new(None), mapped: AtomicUsize::new(0), live: AtomicUsize::new(0) }
    }

    /// (bytes mapped, bytes of live bodies).
    pub fn usage(&self) -> (usize, usize) {
        (self.mapped.load(Ordering::Relaxed), self.live.load(Ordering::Relaxed))
    }

    /// Copies `data` into whole pages never handed out before — the next free pages of the
    /// current arena, of a new one, or a mapping of its own — and returns where.
    ///
    /// Bodies in an arena are copied under the lock, and an arena is made read-only as a whole
    /// once it is full (also under the lock, so no copy into it is under way): making each
    /// body's pages read-only would split the huge page's single page-table entry into 512
    /// and slow vmsplice's page-table walk. Until then the bodies' bytes rest on this function:
    /// each page goes to one body, written once before the body is shared, and only read as
    /// `&[u8]` after.
    fn place(&'static self, data: &[u8]) -> Option<(Arc<Arena>, usize)> {
        let len = data.len().div_ceil(PAGE) * PAGE;
        if len <= ARENA_MAX_BODY && self.pack.unwrap_or_else(huge_pages) {
            let mut current = self.current.lock().unwrap_or_else(|e| e.into_inner());
            let room = current.as_ref().is_some_and(|(arena, next)| next + len <= arena.size);
            if !room {
                let (mapped, live) = self.usage();
                let fresh = if may_map_arena(mapped, live, len) { Arena::map(self, ARENA, true) } else { None };
                if let Some(fresh) = fresh {
                    if let Some((full, _)) = current.replace((Arc::new(fresh), 0)) {
                        full.protect();
                    }
                }
            }
            if let Some((arena, next)) = current.as_mut().filter(|(arena, next)| *next + len <= arena.size) {
                let at = *next;
                *next += len;
                // SAFETY: [at, at + len) lies inside the arena and was never handed out.
                unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), arena.base.add(at), data.len()) };
                return Some((arena.clone(), at));
            }
        }
        let own = Arena::map(self, len, false)?;
        // SAFETY: a fresh mapping of `len >= data.len()` bytes, ours alone.
        unsafe { std::ptr::copy_nonoverlapping(data.as_ptr(), own.base, data.len()) };
        own.protect();
        Some((Arc::new(own), 0))
    }
}

/// An anonymous mapping holding sealed bodies; unmapped when the last one is dropped.
struct Arena {
    base: *mut u8,
    size: usize,
    owner: &'static Arenas,
}

// SAFETY: the mapping is owned by this value alone; a body in it is written only by
// `Arenas::place`, under its lock, before the body is shared.
unsafe impl Send for Arena {}
unsafe impl Sync for Arena {}

impl Arena {
    /// A fresh read-write mapping of `size` bytes; with `huge`, aligned to `ARENA` and advised
    /// to be backed by huge pages (kernels without them ignore the advice).
    ///
    /// Raw `mmap` rather than `memmap2`: the arena must start on a huge-page boundary (map
    /// more, unmap the unaligned ends) and be made read-only in place while bodies in it are
    /// shared, neither of which `memmap2`'s owned maps allow.
    fn map(owner: &'static Arenas, size: usize, huge: bool) -> Option<Arena> {
        let span = if huge { size + ARENA } else { size };
        let rw = ProtFlags::READ | ProtFlags::WRITE;
        // SAFETY: a fresh private anonymous mapping at an address the kernel picks.
        let ptr = unsafe { mm::mmap_anonymous(std::ptr::null_mut(), span, rw, MapFlags::PRIVATE) }.ok()?;
        let start = ptr as usize;
        let base = if huge { start.next_multiple_of(ARENA) } else { start };
        let tail = start + span - (base + size);
        // SAFETY: the trimming unmaps only parts of this fresh mapping outside
        // [base, base + size), and the advice concerns exactly that range. Failures leave
        // a larger mapping or 4 KiB pages, both still correct.
        unsafe {
            if base > start {
                let _ = mm::munmap(ptr, base - start);
            }
            if tail > 0 {
                let _ = mm::munmap((base + size) as *mut _, tail);
            }
            if huge {
                let _ = mm::madvise(base as *mut _, size, Advice::LinuxHugepage);
            }
        }
        owner.mapped.fetch_add(size, Ordering::Relaxed);
        Some(Arena { base: base as *mut u8, size, owner })
    }

    /// Makes the whole mapping read-only: nothing is written into it any more. (Failure only
    /// loses that protection; the bytes stay as they are.)
    fn protect(&self) {
        // SAFETY: changes the protection of exactly this mapping, into which nothing more is
        // written.
        let _ = unsafe { mm::mprotect(self.base as *mut _, self.size, MprotectFlags::READ) };
    }
}

impl Drop for Arena {
    fn drop(&mut self) {
        // SAFETY: unmaps exactly the mapping made in `map`; its bodies are all dropped.
        let _ = unsafe { mm::munmap(self.base as *mut _, self.size) };
        self.owner.mapped.fetch_sub(self.size, Ordering::Relaxed);
    }
}

/// One body: whole pages of an arena (or of its own mapping), never written again.
pub struct Sealed {
    arena: Arc<Arena>,
    ptr: *mut u8,
    len: usize,
    pages: usize,
}

// SAFETY: the body's pages are immutable after construction.
unsafe impl Send for Sealed {}
unsafe impl Sync for Sealed {}

impl Sealed {
    pub fn new_in(arenas: &'static Arenas, data: &[u8]) -> Option<Sealed> {
        let pages = data.len().div_ceil(PAGE) * PAGE;
        let (arena, offset) = arenas.place(data)?;
        // SAFETY: `place` put `data` at this offset, inside the arena.
        let ptr = unsafe { arena.base.add(offset) };
        arenas.live.fetch_add(pages, Ordering::Relaxed);
        SEALED.write().unwrap_or_else(|e| e.into_inner()).insert(ptr as usize, data.len());
        Some(Sealed { arena, ptr, len: data.len(), pages })
    }
}

impl AsRef<[u8]> for Sealed {
    fn as_ref(&self) -> &[u8] {
        // SAFETY: `ptr` has `pages >= len` readable bytes while `arena` is held.
        unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
    }
}

impl Drop for Sealed {
    fn drop(&mut self) {
        // Unregister first: no new splice may start from this range once it can be unmapped.
        // Splices already done hold their own page references. The pages are never written
        // again; the arena is unmapped with its last body.
        SEALED.write().unwrap_or_else(|e| e.into_inner()).remove(&(self.ptr as usize));
        self.arena.owner.live.fetch_sub(self.pages, Ordering::Relaxed);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::tests::pattern;

    fn footprint(len: usize) -> usize {
        crate::transport::Transport::Splice.footprint(len)
    }

    #[test]
    fn sealing_keeps_the_bytes_and_tracks_the_range() {
        let data = pattern(100_000);
        let sealed = seal(data.clone());
        assert_eq!(&sealed[..], &data[..]);
        assert!(registered(&sealed));
        assert!(registered(&sealed[10..5000]));
        // Clones share the mapping; it outlives the original handle.
        let clone = sealed.clone();
        drop(sealed);
        assert_eq!(&clone[..], &data[..]);
        let start = clone.as_ptr() as usize;
        assert!(registered_range(start, 1));
        drop(clone);
        assert!(!registered_range(start, 1), "the registry forgets an unmapped body");
    }

    #[test]
    fn small_bodies_and_heap_memory_are_not_sealed() {
        let small = seal(pattern(SEAL_MIN - 1));
        assert!(!registered(&small));
        let heap = pattern(200_000);
        assert!(!registered(&heap));
    }

    /// The permissions of the mapping holding `addr`, from /proc/self/maps.
    fn protection(addr: usize) -> String {
        let maps = std::fs::read_to_string("/proc/self/maps").unwrap();
        for line in maps.lines() {
            let mut f = line.split_whitespace();
            let (range, perms) = (f.next().unwrap(), f.next().unwrap());
            let (a, b) = range.split_once('-').unwrap();
            let (a, b) = (usize::from_str_radix(a, 16).unwrap(), usize::from_str_radix(b, 16).unwrap());
            if (a..b).contains(&addr) {
                return perms.to_string();
            }
        }
        panic!("{addr:#x} is not mapped")
    }

    /// Bodies fill whole pages of one 2 MiB-aligned arena in turn; the arena outlives any of
    /// its bodies and is unmapped with the last one; big bodies get mappings of their own.
    #[test]
    fn bodies_share_arenas_until_the_last_one_drops() {
        let arenas: &'static Arenas = Box::leak(Box::new(Arenas::new(Some(true))));
        let body = |i: usize| pattern(150_000 + i);
        let addr = |s: &Sealed| s.as_ref().as_ptr() as usize;

        let a = Sealed::new_in(arenas, &body(0)).unwrap();
        let b = Sealed::new_in(arenas, &body(1)).unwrap();
        let c = Sealed::new_in(arenas, &body(2)).unwrap();
        let base = addr(&a);
        assert_eq!(base % ARENA, 0, "an arena starts on a huge-page boundary");
        assert_eq!(addr(&b), base + footprint(150_000));
        assert_eq!(addr(&c), addr(&b) + footprint(150_001));
        let held = footprint(150_000) + footprint(150_001) + footprint(150_002);
        assert_eq!(arenas.usage(), (ARENA, held));
        assert!(registered(a.as_ref()) && registered(c.as_ref()));

        drop(b);
        assert_eq!(arenas.usage(), (ARENA, held - footprint(150_001)), "the arena stays");
        assert!(a.as_ref() == &body(0)[..] && c.as_ref() == &body(2)[..], "neighbours intact");

        // Fill the first arena; the next body opens a second one.
        let mut rest = Vec::new();
        while rest.last().is_none_or(|s: &Sealed| addr(s) / ARENA == base / ARENA) {
            rest.push(Sealed::new_in(arenas, &body(3 + rest.len())).unwrap());
        }
        assert_eq!(arenas.usage().0, 2 * ARENA);
        assert_eq!(protection(base), "r--p", "a full arena is read-only");
        assert_eq!(protection(base + ARENA - 1), "r--p", "as a whole");
        let last = rest.pop().unwrap();
        drop((a, c, rest));
        assert_eq!(arenas.usage(), (ARENA, footprint(last.as_ref().len())), "the first arena is unmapped");
        assert!(!registered_range(base, 1));

        let big = Sealed::new_in(arenas, &pattern(ARENA_MAX_BODY + 1)).unwrap();
        assert_eq!(arenas.usage().0, ARENA + footprint(ARENA_MAX_BODY + 1), "a mapping of its own");
        assert!(big.as_ref() == &pattern(ARENA_MAX_BODY + 1)[..]);
        drop((big, last));
        assert_eq!(arenas.usage(), (ARENA, 0), "the current arena waits for the next body");
    }

    /// Without packing (systems without transparent huge pages) every body gets its own
    /// mapping, freed with it.
    #[test]
    fn without_packing_each_body_has_its_own_mapping() {
        let arenas: &'static Arenas = Box::leak(Box::new(Arenas::new(Some(false))));
        let a = Sealed::new_in(arenas, &pattern(150_000)).unwrap();
        let b = Sealed::new_in(arenas, &pattern(150_001)).unwrap();
        let both = footprint(150_000) + footprint(150_001);
        assert_eq!(arenas.usage(), (both, both));
        assert_eq!(protection(b.as_ref().as_ptr() as usize), "r--p");
        drop(a);
        assert_eq!(arenas.usage(), (footprint(150_001), footprint(150_001)));
        assert!(b.as_ref() == &pattern(150_001)[..]);
    }

    /// When long-lived bodies keep mostly empty arenas alive, new bodies stop opening arenas:
    /// mapped memory stays within 1.125 × the live bodies plus a few arenas.
    #[test]
    fn arenas_held_by_few_bodies_stop_new_arenas() {
        assert!(may_map_arena(0, 0, 150_000));
        assert!(may_map_arena(17 << 20, 10 << 20, 150_000));
        assert!(!may_map_arena(18 << 20, 10 << 20, 150_000));

        let arenas: &'static Arenas = Box::leak(Box::new(Arenas::new(Some(true))));
        let mut kept: Vec<Sealed> = Vec::new();
        for i in 0..400 {
            let s = Sealed::new_in(arenas, &pattern(150_000)).unwrap();
            // Keep one body per 2 MiB block: the worst case for the arenas' other pages.
            let block = s.as_ref().as_ptr() as usize / ARENA;
            if kept.iter().all(|k| k.as_ref().as_ptr() as usize / ARENA != block) || i % 50 == 0 {
                kept.push(s);
            }
            let (mapped, live) = arenas.usage();
            assert!(mapped <= live + live / SLACK + 5 * ARENA + 2 * footprint(150_000), "{mapped} for {live} live");
        }
        assert!(kept.iter().all(|k| k.as_ref() == &pattern(150_000)[..]));
    }
}
