//! Zero-copy sends of cached tile bodies.
//!
//! A warm tile request is dominated by copying the tile's bytes into the kernel: writing a
//! 150 KB PNG with `writev` spent 29 % of the server's CPU in `_copy_from_iter` (perf,
//! BENCHMARKS.md). nginx avoids that copy for static files with `sendfile`: the socket
//! references page-cache pages. This module gives the tile cache the same property:
//!
//! * [`seal`] moves an encoded tile into its own anonymous mapping, made read-only, and
//!   records its address range. The mapping is unmapped when the last `Bytes` handle drops.
//! * [`SpliceIo`] wraps a connection's `TcpStream` for hyper. When hyper writes a slice that
//!   lies inside a sealed range, the slice's pages are handed to the socket by reference
//!   (`vmsplice` into a per-connection pipe, then `splice` into the socket); every other
//!   write is a plain `writev`. Headers before a spliced body cork the socket (TCP_CORK) until
//!   hyper flushes the response, so it leaves in full-sized segments (see `SpliceIo::cork`).
//!
//! Why this is safe: the kernel keeps its own references to the pages it was handed, and a
//! sealed page is never written after sealing (it is read-only, then unmapped, never reused
//! by an allocator), so bytes in flight cannot change. Memory that is not sealed (headers,
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
    use std::sync::RwLock;
    use std::task::{ready, Context, Poll};
    use tokio::io::Interest;
    use tokio::net::TcpStream;

    /// Start address → length of every live sealed mapping.
    static SEALED: RwLock<BTreeMap<usize, usize>> = RwLock::new(BTreeMap::new());

    /// Pipe capacity asked for: one 256² PNG tile (60–250 KB) in one or two rounds.
    const PIPE_BYTES: libc::c_int = 256 * 1024;

    pub(super) fn registered(bytes: &[u8]) -> bool {
        registered_range(bytes.as_ptr() as usize, bytes.len())
    }

    pub(super) fn registered_range(start: usize, len: usize) -> bool {
        let map = SEALED.read().unwrap_or_else(|e| e.into_inner());
        map.range(..=start).next_back().is_some_and(|(&s, &l)| start + len <= s + l)
    }

    /// A read-only private anonymous mapping holding one body; unmapped on drop.
    pub(super) struct Sealed {
        ptr: *mut u8,
        len: usize,
        mapped: usize,
    }

    // SAFETY: the mapping is immutable after construction and owned by this value alone.
    unsafe impl Send for Sealed {}
    unsafe impl Sync for Sealed {}

    impl Sealed {
        pub(super) fn new(data: &[u8]) -> Option<Sealed> {
            let mapped = data.len().div_ceil(PAGE) * PAGE;
            // SAFETY: a fresh private anonymous mapping; we write only inside it, then
            // make it read-only. Failure is reported as MAP_FAILED and handled.
            unsafe {
                let ptr = libc::mmap(
                    std::ptr::null_mut(),
                    mapped,
                    libc::PROT_READ | libc::PROT_WRITE,
                    libc::MAP_PRIVATE | libc::MAP_ANONYMOUS,
                    -1,
                    0,
                );
                if ptr == libc::MAP_FAILED {
                    return None;
                }
                std::ptr::copy_nonoverlapping(data.as_ptr(), ptr as *mut u8, data.len());
                if libc::mprotect(ptr, mapped, libc::PROT_READ) != 0 {
                    libc::munmap(ptr, mapped);
                    return None;
                }
                let sealed = Sealed { ptr: ptr as *mut u8, len: data.len(), mapped };
                SEALED.write().unwrap_or_else(|e| e.into_inner()).insert(ptr as usize, data.len());
                Some(sealed)
            }
        }
    }

    impl AsRef<[u8]> for Sealed {
        fn as_ref(&self) -> &[u8] {
            // SAFETY: `ptr` maps `mapped >= len` readable bytes until drop.
            unsafe { std::slice::from_raw_parts(self.ptr, self.len) }
        }
    }

    impl Drop for Sealed {
        fn drop(&mut self) {
            // Unregister first: no new splice may start from this range once it is unmapped.
            // Splices already done hold their own page references.
            SEALED.write().unwrap_or_else(|e| e.into_inner()).remove(&(self.ptr as usize));
            // SAFETY: unmaps exactly the mapping created in `new`; no slice outlives `self`.
            unsafe {
                libc::munmap(self.ptr as *mut libc::c_void, self.mapped);
            }
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
        let head = b"HTTP/1.1 200 OK\r\ncontent-length: 3000000\r\n\r\n".to_vec();
        let body = seal(pattern(3_000_000));
        let tail = pattern(50_000);
        let mut expected = head.clone();
        expected.extend_from_slice(&body);
        expected.extend_from_slice(&tail);

        let (mut h, mut b, mut t) = (&head[..], &body[..], &tail[..]);
        while !(h.is_empty() && b.is_empty() && t.is_empty()) {
            let bufs: Vec<IoSlice<'_>> = [h, b, t].iter().filter(|s| !s.is_empty()).map(|s| IoSlice::new(s)).collect();
            let mut n = poll_fn(|cx| Pin::new(&mut io).poll_write_vectored(cx, &bufs)).await.unwrap();
            assert!(n > 0);
            for s in [&mut h, &mut b, &mut t] {
                let k = n.min(s.len());
                *s = &s[k..];
                n -= k;
            }
        }
        poll_fn(|cx| Pin::new(&mut io).poll_shutdown(cx)).await.unwrap();
        drop(body); // unmapped while the reader may still be receiving: pages stay intact
        let got = reader.await.unwrap();
        assert_eq!(got.len(), expected.len());
        assert!(got == expected, "bytes differ");
    }
}
