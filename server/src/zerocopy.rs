//! Zero-copy sends of cached tile bodies.
//!
//! A warm tile request is dominated by copying the tile's bytes into the kernel: writing a
//! 150 KB PNG with `writev` spent 29 % of the server's CPU in `_copy_from_iter` (perf,
//! BENCHMARKS.md). nginx avoids that copy for static files with `sendfile`: the socket
//! references page-cache pages. This module gives the tile cache the same property:
//!
//! * [`seal`] copies an encoded tile into whole pages of an anonymous mapping (read-only once
//!   nothing more is written into it) and records their address range. Tiles share 2 MiB arenas backed by
//!   transparent huge pages where the kernel allows: the receiver then frees one huge page's
//!   references instead of ~38 pages' (see `Arenas`). An arena is unmapped when the last
//!   `Bytes` handle of its last tile drops.
//! * [`SpliceIo`] wraps a connection's `TcpStream` for hyper. When hyper writes a slice that
//!   lies inside a sealed range, the slice's pages are handed to the socket by reference
//!   (`vmsplice` into a per-connection pipe, then `splice` into the socket); every other
//!   write is a plain `writev`. Headers before a spliced body cork the socket (TCP_CORK) until
//!   hyper flushes the response, so it leaves in full-sized segments (see `SpliceIo::cork`).
//!
//! Why this is safe: the kernel keeps its own references to the pages it was handed, and a
//! sealed page is never written after sealing (an arena hands each page to one body only,
//! which is copied in before it is shared; the arena is made read-only when full, unmapped
//! with its last body, never reused by an allocator), so bytes in flight cannot change. Memory that is not sealed (headers,
//! JSON, HTTP/2 frames, anything from the heap) is never spliced, because the heap reuses
//! freed memory while the kernel might still hold it.
//!
//! Everything degrades to copying: on other systems, for small bodies, when a mapping or a
//! pipe cannot be created, or when the kernel refuses a splice before any byte moved.

use bytes::Bytes;

/// Bodies below this size are copied: two extra syscalls cost more than the copy saves.
pub const SEAL_MIN: usize = 16 * 1024;

const PAGE: usize = 4096;

/// Bytes a body of `len` bytes occupies once sealed (sealed bodies take whole pages).
pub fn footprint(len: usize) -> usize {
    if sealable(len) {
        len.div_ceil(PAGE) * PAGE
    } else {
        len
    }
}

fn sealable(len: usize) -> bool {
    cfg!(target_os = "linux") && len >= SEAL_MIN
}

/// `body` as immutable bytes that [`SpliceIo`] can send without copying (see the module
/// docs). Small bodies, other systems and failed mappings give ordinary `Bytes`.
pub fn seal(body: Vec<u8>) -> Bytes {
    #[cfg(target_os = "linux")]
    if sealable(body.len()) {
        if let Some(sealed) = linux::Sealed::new(&body) {
            return Bytes::from_owner(sealed);
        }
    }
    Bytes::from(body)
}

/// Bytes of memory mapped for sealed bodies now: their pages and the arenas' pages not (or no
/// longer) holding one (the memory behind the tile cache's budget; see `may_map_arena`).
pub fn mapped_bytes() -> usize {
    #[cfg(target_os = "linux")]
    {
        linux::mapped_bytes()
    }
    #[cfg(not(target_os = "linux"))]
    {
        0
    }
}

/// True when `bytes` lies wholly inside one sealed mapping (for tests and assertions).
pub fn is_sealed(bytes: &[u8]) -> bool {
    #[cfg(target_os = "linux")]
    {
        linux::registered(bytes)
    }
    #[cfg(not(target_os = "linux"))]
    {
        let _ = bytes;
        false
    }
}

#[cfg(target_os = "linux")]
pub use linux::SpliceIo;

/// Without splice, connections use tokio's stream as hyper expects it.
#[cfg(not(target_os = "linux"))]
pub type SpliceIo = hyper_util::rt::TokioIo<tokio::net::TcpStream>;

#[cfg(target_os = "linux")]
mod linux {
    use super::{PAGE, SEAL_MIN};
    use hyper::rt::{Read, ReadBufCursor, Write};
    use hyper_util::rt::TokioIo;
    use std::collections::BTreeMap;
    use std::io::{self, IoSlice};
    use std::os::fd::{AsRawFd, FromRawFd, OwnedFd};
    use std::pin::Pin;
    use std::sync::atomic::{AtomicUsize, Ordering};
    use std::sync::{Arc, Mutex, OnceLock, RwLock};
    use std::task::{ready, Context, Poll};
    use tokio::io::Interest;
    use tokio::net::TcpStream;

    /// Start address → length of every live sealed body.
    static SEALED: RwLock<BTreeMap<usize, usize>> = RwLock::new(BTreeMap::new());

    /// Pipe capacity asked for: one 256² PNG tile (60–250 KB) in one or two rounds.
    const PIPE_BYTES: libc::c_int = 256 * 1024;

    /// Size and alignment of a shared arena: one transparent huge page on x86-64 and arm64.
    pub(super) const ARENA: usize = 2 << 20;
    /// Bodies above this get a mapping of their own (an arena would hold too few of them).
    pub(super) const ARENA_MAX_BODY: usize = ARENA / 4;

    /// Where [`super::seal`] puts bodies: packed into arenas only where the kernel gives
    /// huge pages, since arenas cost memory (see [`may_map_arena`]) and help only as one folio.
    static ARENAS: Arenas = Arenas::new(None);
    static HUGE_PAGES: OnceLock<bool> = OnceLock::new();

    /// Whether `madvise(MADV_HUGEPAGE)` gets transparent huge pages on this system.
    fn huge_pages() -> bool {
        *HUGE_PAGES.get_or_init(|| {
            std::fs::read_to_string("/sys/kernel/mm/transparent_hugepage/enabled")
                .is_ok_and(|s| s.contains("[always]") || s.contains("[madvise]"))
        })
    }

    pub(super) fn mapped_bytes() -> usize {
        ARENAS.usage().0
    }

    pub(super) fn registered(bytes: &[u8]) -> bool {
        registered_range(bytes.as_ptr() as usize, bytes.len())
    }

    pub(super) fn registered_range(start: usize, len: usize) -> bool {
        let map = SEALED.read().unwrap_or_else(|e| e.into_inner());
        map.range(..=start).next_back().is_some_and(|(&s, &l)| start + len <= s + l)
    }

    /// Whether a new arena may be mapped for a body of `need` bytes while `mapped` bytes are
    /// mapped for `live` bytes of bodies. An arena stays mapped while any of its bodies lives,
    /// so one long-lived tile can keep an arena's other pages: mappings are held to the live
    /// bodies plus 1/[`SLACK`] of them plus four arenas (the tile cache's byte budget then
    /// holds for the memory behind it within that); beyond that, bodies get mappings of their
    /// own (4 KiB pages, the slower send) until old arenas are freed.
    pub(super) fn may_map_arena(mapped: usize, live: usize, need: usize) -> bool {
        let bodies = live + need;
        mapped + ARENA <= bodies + bodies / SLACK + 4 * ARENA
    }

    /// Arenas' pages not holding live bodies are kept below 1/`SLACK` of the live bodies.
    pub(super) const SLACK: usize = 8;

    /// Sealed bodies packed into 2 MiB arenas, each advised to be one transparent huge page.
    ///
    /// Why: every 4 KiB page handed to a socket has its own `struct page`, whose reference
    /// count the server's core writes (vmsplice, the socket's fragment, the pipe) and the
    /// receiver's core writes again when it frees the received data — on loopback, in the
    /// client's kernel time, one cache-line transfer per page: ~38 per 150 KB tile. In a huge
    /// page all of them share the huge page's count (BENCHMARKS.md, "Warm tiles": wrk spent
    /// 2–3 µs more kernel time per tile against bodies in 4 KiB pages; nginx's files sit in
    /// the page cache partly in large folios). Each body takes whole pages of its own.
    pub(super) struct Arenas {
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
        pub(super) const fn new(pack: Option<bool>) -> Arenas {
            Arenas { pack, current: Mutex::new(None), mapped: AtomicUsize::new(0), live: AtomicUsize::new(0) }
        }

        /// (bytes mapped, bytes of live bodies).
        pub(super) fn usage(&self) -> (usize, usize) {
            (self.mapped.load(Ordering::Relaxed), self.live.load(Ordering::Relaxed))
        }

        /// Copies `data` into whole pages never handed out before — the next free pages of the
        /// current arena, of a new one, or a mapping of its own — and returns where.
        ///
        /// Bodies in an arena are copied under the lock, and an arena is made read-only as a
        /// whole once it is full (also under the lock, so no copy into it is under way):
        /// making each body's pages read-only would split the huge page's single page-table
        /// entry into 512, and vmsplice's page-table walk cost 0.8 µs more per tile with them.
        /// Until then the bodies' bytes rest on this function: each page goes to one body,
        /// written once before the body is shared, and only read as `&[u8]` after.
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
        /// A fresh read-write mapping of `size` bytes; with `huge`, aligned to `ARENA` and
        /// advised to be backed by huge pages (kernels without them ignore the advice).
        fn map(owner: &'static Arenas, size: usize, huge: bool) -> Option<Arena> {
            let span = if huge { size + ARENA } else { size };
            // SAFETY: a fresh private anonymous mapping; failure is MAP_FAILED and handled.
            // The trimming unmaps only parts of this mapping outside [base, base + size).
            unsafe {
                let ptr = libc::mmap(
                    std::ptr::null_mut(),
                    span,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                    -1,
                    0,
                );
                if ptr == libc::MAP_FAILED {
                    return None;
                }
                let start = ptr as usize;
                let base = if huge { start.next_multiple_of(ARENA) } else { start };
                if base > start {
                    libc::munmap(ptr, base - start);
                }
                let tail = start + span - (base + size);
                if tail > 0 {
                    libc::munmap((base + size) as *mut libc::c_void, tail);
                }
                if huge {
                    libc::madvise(base as *mut libc::c_void, size, libc::MADV_HUGEPAGE);
                }
                owner.mapped.fetch_add(size, Ordering::Relaxed);
                Some(Arena { base: base as *mut u8, size, owner })
            }
        }
    }

    impl Arena {
        /// Makes the whole mapping read-only: nothing is written into it any more. (Failure
        /// only loses that protection; the bytes stay as they are.)
        fn protect(&self) {
            // SAFETY: changes the protection of exactly this mapping.
            unsafe { libc::mprotect(self.base as *mut libc::c_void, self.size, libc::PROT_READ) };
        }
    }

    impl Drop for Arena {
        fn drop(&mut self) {
            // SAFETY: unmaps exactly the mapping made in `map`; its bodies are all dropped.
            unsafe { libc::munmap(self.base as *mut libc::c_void, self.size) };
            self.owner.mapped.fetch_sub(self.size, Ordering::Relaxed);
        }
    }

    /// One body: whole pages of an arena (or of its own mapping), never written again.
    pub(super) struct Sealed {
        arena: Arc<Arena>,
        ptr: *mut u8,
        len: usize,
        pages: usize,
    }

    // SAFETY: the body's pages are immutable after construction.
    unsafe impl Send for Sealed {}
    unsafe impl Sync for Sealed {}

    impl Sealed {
        pub(super) fn new(data: &[u8]) -> Option<Sealed> {
            Self::new_in(&ARENAS, data)
        }

        pub(super) fn new_in(arenas: &'static Arenas, data: &[u8]) -> Option<Sealed> {
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
            // Unregister first: no new splice may start from this range once it can be
            // unmapped. Splices already done hold their own page references. The pages are
            // never written again; the arena is unmapped with its last body.
            SEALED.write().unwrap_or_else(|e| e.into_inner()).remove(&(self.ptr as usize));
            self.arena.owner.live.fetch_sub(self.pages, Ordering::Relaxed);
        }
    }

    struct Pipe {
        read: OwnedFd,
        write: OwnedFd,
    }

    impl Pipe {
        fn new() -> io::Result<Pipe> {
            let mut fds = [0 as libc::c_int; 2];
            // SAFETY: pipe2 fills `fds` on success; we own both descriptors afterwards.
            if unsafe { libc::pipe2(fds.as_mut_ptr(), libc::O_CLOEXEC | libc::O_NONBLOCK) } != 0 {
                return Err(io::Error::last_os_error());
            }
            let pipe = unsafe { Pipe { read: OwnedFd::from_raw_fd(fds[0]), write: OwnedFd::from_raw_fd(fds[1]) } };
            // A larger pipe means fewer rounds per tile; the default 64 KiB also works.
            // SAFETY: fcntl on a descriptor we own.
            unsafe { libc::fcntl(pipe.write.as_raw_fd(), libc::F_SETPIPE_SZ, PIPE_BYTES) };
            Ok(pipe)
        }
    }

    /// A server connection for hyper: tokio's `TcpStream`, with sealed slices spliced.
    ///
    /// Bytes moved into the pipe count as written for hyper; they reach the socket before
    /// anything written after them, and before a flush or shutdown completes.
    pub struct SpliceIo {
        io: TokioIo<TcpStream>,
        pipe: Option<Pipe>,
        /// Set when a pipe could not be made (descriptor limit): copy from then on.
        no_pipe: bool,
        /// Bytes in the pipe not yet in the socket.
        queued: usize,
        /// TCP_CORK is set: from a response's headers until hyper flushes it.
        corked: bool,
    }

    impl SpliceIo {
        pub fn new(stream: TcpStream) -> SpliceIo {
            SpliceIo { io: TokioIo::new(stream), pipe: None, no_pipe: false, queued: 0, corked: false }
        }

        fn stream(&self) -> &TcpStream {
            self.io.inner()
        }

        /// Moves queued pipe bytes into the socket; Ready once the pipe is empty.
        fn poll_drain(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
            while self.queued > 0 {
                let pipe = self.pipe.as_ref().expect("bytes are queued only in an existing pipe");
                ready!(self.stream().poll_write_ready(cx))?;
                let (from, to, len) = (pipe.read.as_raw_fd(), self.stream().as_raw_fd(), self.queued);
                let moved = self.stream().try_io(Interest::WRITABLE, || {
                    // SAFETY: splice between two descriptors we own; no user memory involved.
                    let n = unsafe {
                        libc::splice(
                            from,
                            std::ptr::null_mut(),
                            to,
                            std::ptr::null_mut(),
                            len,
                            libc::SPLICE_F_MOVE | libc::SPLICE_F_NONBLOCK,
                        )
                    };
                    if n < 0 {
                        Err(io::Error::last_os_error())
                    } else {
                        Ok(n as usize)
                    }
                });
                match moved {
                    Ok(0) => return Poll::Ready(Err(io::ErrorKind::WriteZero.into())),
                    Ok(n) => self.queued -= n,
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => continue,
                    Err(e) => return Poll::Ready(Err(e)),
                }
            }
            Poll::Ready(Ok(()))
        }

        /// Hands up to a pipe's worth of the sealed slice `buf` to the kernel by reference.
        /// `None` when splicing is unavailable; the caller then copies.
        fn splice_sealed(&mut self, cx: &mut Context<'_>, buf: &[u8]) -> Option<io::Result<usize>> {
            if self.pipe.is_none() && !self.no_pipe {
                match Pipe::new() {
                    Ok(p) => self.pipe = Some(p),
                    Err(e) => {
                        tracing::warn!(error = %e, "no pipe for zero-copy sends; copying on this connection");
                        self.no_pipe = true;
                    }
                }
            }
            let pipe = self.pipe.as_ref()?;
            let iov = libc::iovec { iov_base: buf.as_ptr() as *mut libc::c_void, iov_len: buf.len() };
            // SAFETY: `buf` is sealed: alive for this call (hyper holds its `Bytes`) and never
            // written again, so the kernel may keep references to its pages after we return.
            let n = unsafe { libc::vmsplice(pipe.write.as_raw_fd(), &iov, 1, libc::SPLICE_F_NONBLOCK) };
            if n <= 0 {
                // The pipe is empty here, so this is a refusal (e.g. a sandbox), not a full
                // pipe: copy instead, on this connection from now on.
                self.pipe = None;
                self.no_pipe = true;
                return None;
            }
            self.queued = n as usize;
            // Start moving it now; if the socket is full the waker is registered and the
            // bytes go out on the next write or flush.
            match self.poll_drain(cx) {
                Poll::Ready(Err(e)) => Some(Err(e)),
                _ => Some(Ok(n as usize)),
            }
        }

        /// Holds partial segments back (TCP_CORK) until [`Self::uncork`]: headers and a spliced
        /// body then leave in full segments, as nginx sends with `sendfile` and `tcp_nopush`.
        ///
        /// Why it matters on loopback: without it the last segments of each response were
        /// smaller than the peer's MSS, the receiver's RTT estimate (taken from full-sized
        /// segments) collapsed to microseconds, its receive-buffer autotuning never grew the
        /// window (~100 KB against nginx's MBs), and every response arrived in more, smaller
        /// segments: more wake-ups and ACKs for the client (wrk: 35 vs 20 ACKs per MB,
        /// BENCHMARKS.md). Costs two `setsockopt` calls per response with a sealed body.
        fn cork(&mut self) {
            if !self.corked {
                self.corked = set_cork(self.stream(), true).is_ok();
            }
        }

        /// Sends what the cork held back; called once hyper flushes (the response is written).
        fn uncork(&mut self) -> io::Result<()> {
            if self.corked {
                self.corked = false;
                set_cork(self.stream(), false)?;
            }
            Ok(())
        }

        /// Writes leading unsealed slices with MSG_MORE: the sealed body follows at once,
        /// so the headers need not go out as a packet of their own.
        fn poll_send_more(&self, cx: &mut Context<'_>, bufs: &[IoSlice<'_>]) -> Poll<io::Result<usize>> {
            loop {
                ready!(self.stream().poll_write_ready(cx))?;
                let sent = self.stream().try_io(Interest::WRITABLE, || {
                    // SAFETY: a msghdr over the caller's live slices (IoSlice is ABI-compatible
                    // with iovec on Unix); sendmsg only reads them.
                    let mut msg: libc::msghdr = unsafe { std::mem::zeroed() };
                    msg.msg_iov = bufs.as_ptr() as *mut libc::iovec;
                    msg.msg_iovlen = bufs.len() as _;
                    let flags = libc::MSG_MORE | libc::MSG_NOSIGNAL | libc::MSG_DONTWAIT;
                    let n = unsafe { libc::sendmsg(self.stream().as_raw_fd(), &msg, flags) };
                    if n < 0 {
                        Err(io::Error::last_os_error())
                    } else {
                        Ok(n as usize)
                    }
                });
                match sent {
                    Err(e) if e.kind() == io::ErrorKind::WouldBlock => continue,
                    r => return Poll::Ready(r),
                }
            }
        }
    }

    fn set_cork(stream: &TcpStream, on: bool) -> io::Result<()> {
        let v: libc::c_int = on.into();
        // SAFETY: setsockopt reads one c_int from a live local; the descriptor is ours.
        let r = unsafe {
            libc::setsockopt(
                stream.as_raw_fd(),
                libc::IPPROTO_TCP,
                libc::TCP_CORK,
                &v as *const libc::c_int as *const libc::c_void,
                std::mem::size_of::<libc::c_int>() as libc::socklen_t,
            )
        };
        if r == 0 {
            Ok(())
        } else {
            Err(io::Error::last_os_error())
        }
    }

    fn spliceable(b: &[u8]) -> bool {
        b.len() >= SEAL_MIN && registered(b)
    }

    impl Read for SpliceIo {
        fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: ReadBufCursor<'_>) -> Poll<io::Result<()>> {
            Pin::new(&mut self.get_mut().io).poll_read(cx, buf)
        }
    }

    impl Write for SpliceIo {
        fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
            self.poll_write_vectored(cx, &[IoSlice::new(buf)])
        }

        fn poll_write_vectored(
            self: Pin<&mut Self>,
            cx: &mut Context<'_>,
            bufs: &[IoSlice<'_>],
        ) -> Poll<io::Result<usize>> {
            let this = self.get_mut();
            ready!(this.poll_drain(cx))?;
            if !this.no_pipe {
                match bufs.iter().position(|b| spliceable(b)) {
                    Some(0) => {
                        if let Some(r) = this.splice_sealed(cx, &bufs[0]) {
                            return Poll::Ready(r);
                        }
                    }
                    Some(k) => {
                        this.cork();
                        return this.poll_send_more(cx, &bufs[..k]);
                    }
                    None => {}
                }
            }
            Pin::new(&mut this.io).poll_write_vectored(cx, bufs)
        }

        fn is_write_vectored(&self) -> bool {
            true
        }

        fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
            let this = self.get_mut();
            ready!(this.poll_drain(cx))?;
            this.uncork()?;
            Pin::new(&mut this.io).poll_flush(cx)
        }

        fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
            let this = self.get_mut();
            ready!(this.poll_drain(cx))?;
            this.uncork()?;
            Pin::new(&mut this.io).poll_shutdown(cx)
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn pattern(n: usize) -> Vec<u8> {
        (0..n).map(|i| (i * 7 + i / 251) as u8).collect()
    }

    #[test]
    fn sealing_keeps_the_bytes_and_tracks_the_range() {
        let data = pattern(100_000);
        let sealed = seal(data.clone());
        assert_eq!(&sealed[..], &data[..]);
        assert_eq!(is_sealed(&sealed), cfg!(target_os = "linux"));
        assert_eq!(is_sealed(&sealed[10..5000]), cfg!(target_os = "linux"));
        // Clones share the mapping; it outlives the original handle.
        let clone = sealed.clone();
        drop(sealed);
        assert_eq!(&clone[..], &data[..]);
        #[cfg(target_os = "linux")]
        {
            let start = clone.as_ptr() as usize;
            assert!(linux::registered_range(start, 1));
            drop(clone);
            assert!(!linux::registered_range(start, 1), "the registry forgets an unmapped body");
        }
    }

    #[test]
    fn small_bodies_and_heap_memory_are_not_sealed() {
        let small = seal(pattern(SEAL_MIN - 1));
        assert!(!is_sealed(&small));
        let heap = pattern(200_000);
        assert!(!is_sealed(&heap));
        assert_eq!(footprint(SEAL_MIN - 1), SEAL_MIN - 1);
    }

    #[test]
    fn footprint_counts_whole_pages() {
        if cfg!(target_os = "linux") {
            assert_eq!(footprint(SEAL_MIN), SEAL_MIN);
            assert_eq!(footprint(SEAL_MIN + 1), SEAL_MIN + PAGE);
        }
    }

    /// The permissions of the mapping holding `addr`, from /proc/self/maps.
    #[cfg(target_os = "linux")]
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
    #[cfg(target_os = "linux")]
    #[test]
    fn bodies_share_arenas_until_the_last_one_drops() {
        use linux::{Arenas, Sealed, ARENA, ARENA_MAX_BODY};
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
        assert!(is_sealed(a.as_ref()) && is_sealed(c.as_ref()));

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
        assert!(!linux::registered_range(base, 1));

        let big = Sealed::new_in(arenas, &pattern(ARENA_MAX_BODY + 1)).unwrap();
        assert_eq!(arenas.usage().0, ARENA + footprint(ARENA_MAX_BODY + 1), "a mapping of its own");
        assert!(big.as_ref() == &pattern(ARENA_MAX_BODY + 1)[..]);
        drop((big, last));
        assert_eq!(arenas.usage(), (ARENA, 0), "the current arena waits for the next body");
    }

    /// Without packing (systems without transparent huge pages) every body gets its own
    /// mapping, freed with it.
    #[cfg(target_os = "linux")]
    #[test]
    fn without_packing_each_body_has_its_own_mapping() {
        use linux::{Arenas, Sealed};
        let arenas: &'static Arenas = Box::leak(Box::new(Arenas::new(Some(false))));
        let a = Sealed::new_in(arenas, &pattern(150_000)).unwrap();
        let b = Sealed::new_in(arenas, &pattern(150_001)).unwrap();
        assert_eq!(arenas.usage(), (footprint(150_000) + footprint(150_001), footprint(150_000) + footprint(150_001)));
        assert_eq!(protection(b.as_ref().as_ptr() as usize), "r--p");
        drop(a);
        assert_eq!(arenas.usage(), (footprint(150_001), footprint(150_001)));
        assert!(b.as_ref() == &pattern(150_001)[..]);
    }

    /// When long-lived bodies keep mostly empty arenas alive, new bodies stop opening arenas:
    /// mapped memory stays within 1.125 × the live bodies plus a few arenas.
    #[cfg(target_os = "linux")]
    #[test]
    fn arenas_held_by_few_bodies_stop_new_arenas() {
        use linux::{may_map_arena, Arenas, Sealed, ARENA, SLACK};
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

    /// Headers before a sealed body cork the socket; hyper's flush uncorks it, so nothing is
    /// held back once a response is written. The reader gets the response without the
    /// connection closing.
    #[cfg(target_os = "linux")]
    #[tokio::test]
    async fn the_cork_is_released_on_flush() {
        use hyper::rt::Write;
        use std::future::poll_fn;
        use std::io::IoSlice;
        use std::os::fd::AsRawFd;
        use std::pin::Pin;
        use tokio::io::AsyncReadExt;

        fn corked(fd: i32) -> bool {
            let mut v: libc::c_int = -1;
            let mut len = std::mem::size_of::<libc::c_int>() as libc::socklen_t;
            // SAFETY: getsockopt writes one c_int into a live local.
            let r = unsafe {
                libc::getsockopt(fd, libc::IPPROTO_TCP, libc::TCP_CORK, &mut v as *mut _ as *mut libc::c_void, &mut len)
            };
            assert_eq!(r, 0);
            v != 0
        }

        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
        let (mut peer, _) = listener.accept().await.unwrap();
        let fd = stream.as_raw_fd();
        let mut io = SpliceIo::new(stream);
        let head = b"HTTP/1.1 200 OK\r\ncontent-length: 100000\r\n\r\n".to_vec();
        let body = seal(pattern(100_000));
        let (mut h, mut b) = (&head[..], &body[..]);
        assert!(!corked(fd));
        while !(h.is_empty() && b.is_empty()) {
            let bufs: Vec<IoSlice<'_>> = [h, b].iter().filter(|s| !s.is_empty()).map(|s| IoSlice::new(s)).collect();
            let mut n = poll_fn(|cx| Pin::new(&mut io).poll_write_vectored(cx, &bufs)).await.unwrap();
            for s in [&mut h, &mut b] {
                let k = n.min(s.len());
                *s = &s[k..];
                n -= k;
            }
        }
        assert!(corked(fd), "headers followed by a sealed body cork the socket");
        poll_fn(|cx| Pin::new(&mut io).poll_flush(cx)).await.unwrap();
        assert!(!corked(fd), "a flush uncorks it");
        let mut got = vec![0; head.len() + body.len()];
        peer.read_exact(&mut got).await.unwrap();
        assert_eq!(&got[..head.len()], &head[..]);
        assert!(got[head.len()..] == body[..]);
    }

    /// Headers, then a sealed body several pipes long, then a heap body, to a reader that
    /// is slow at first (so the socket fills and splices wait): every byte arrives in order.
    #[cfg(target_os = "linux")]
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn spliced_writes_arrive_in_order() {
        use hyper::rt::Write;
        use std::future::poll_fn;
        use std::io::IoSlice;
        use std::pin::Pin;
        use tokio::io::AsyncReadExt;

        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let reader = tokio::spawn(async move {
            let (mut s, _) = listener.accept().await.unwrap();
            tokio::time::sleep(std::time::Duration::from_millis(100)).await;
            let mut all = Vec::new();
            s.read_to_end(&mut all).await.unwrap();
            all
        });
        let stream = tokio::net::TcpStream::connect(addr).await.unwrap();
        let mut io = SpliceIo::new(stream);
        let head = b"HTTP/1.1 200 OK\r\ncontent-length: 3150000\r\n\r\n".to_vec();
        let small = seal(pattern(150_000)); // in an arena
        let body = seal(pattern(3_000_000)); // a mapping of its own
        let tail = pattern(50_000);
        let mut expected = head.clone();
        expected.extend_from_slice(&small);
        expected.extend_from_slice(&body);
        expected.extend_from_slice(&tail);

        let (mut h, mut m, mut b, mut t) = (&head[..], &small[..], &body[..], &tail[..]);
        while !(h.is_empty() && m.is_empty() && b.is_empty() && t.is_empty()) {
            let bufs: Vec<IoSlice<'_>> =
                [h, m, b, t].iter().filter(|s| !s.is_empty()).map(|s| IoSlice::new(s)).collect();
            let mut n = poll_fn(|cx| Pin::new(&mut io).poll_write_vectored(cx, &bufs)).await.unwrap();
            assert!(n > 0);
            for s in [&mut h, &mut m, &mut b, &mut t] {
                let k = n.min(s.len());
                *s = &s[k..];
                n -= k;
            }
        }
        poll_fn(|cx| Pin::new(&mut io).poll_shutdown(cx)).await.unwrap();
        drop((small, body)); // unmapped while the reader may still be receiving: pages stay intact
        let got = reader.await.unwrap();
        assert_eq!(got.len(), expected.len());
        assert!(got == expected, "bytes differ");
    }
}
