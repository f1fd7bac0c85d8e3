//! How response bytes reach the socket, and everything else platform-specific in the server.
//!
//! Two transports, chosen with `vtex serve --send` (or `VTEX_SEND`):
//!
//! * [`Transport::Copy`], everywhere: tile bodies are ordinary heap [`Bytes`] and connections
//!   plain tokio `TcpStream`s; every response is copied into the kernel by `writev`.
//! * [`Transport::Splice`], Linux only: cached tile bodies are *sealed* — copied once into whole
//!   pages of huge-page arenas that are never written again ([`arena`]) — and connections are
//!   wrapped so that a sealed body is handed to the socket by page reference (`vmsplice` +
//!   `splice`, with TCP_CORK around the response) instead of copied, as nginx sends static
//!   files with `sendfile` ([`splice`]).
//!
//! The rest of the server calls only [`Transport`]'s methods and [`Io`], so it never needs to
//! know which one runs. This is the one module of the crate allowed `unsafe` code (mappings,
//! `vmsplice`, `mallopt`); each use carries a `SAFETY:` comment.

#[cfg(target_os = "linux")]
mod arena;
#[cfg(target_os = "linux")]
mod splice;

use bytes::Bytes;
use hyper::rt::{Read, ReadBufCursor, Write};
use hyper_util::rt::TokioIo;
use std::fmt;
use std::io::{self, IoSlice};
use std::pin::Pin;
use std::str::FromStr;
use std::task::{Context, Poll};
use tokio::net::TcpStream;

#[cfg(target_os = "linux")]
const PAGE: usize = 4096;

/// How tile bodies are held and sent: the value of `--send`.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Transport {
    /// Heap bodies, copied into the socket (portable).
    Copy,
    /// Sealed bodies spliced into the socket by page reference (Linux).
    #[cfg(target_os = "linux")]
    Splice,
}

impl Default for Transport {
    /// Splice where the platform has it: warm tiles then reach the socket without a copy.
    fn default() -> Transport {
        #[cfg(target_os = "linux")]
        {
            Transport::Splice
        }
        #[cfg(not(target_os = "linux"))]
        {
            Transport::Copy
        }
    }
}

impl FromStr for Transport {
    type Err = String;

    fn from_str(s: &str) -> Result<Transport, String> {
        match s {
            "copy" => Ok(Transport::Copy),
            #[cfg(target_os = "linux")]
            "splice" => Ok(Transport::Splice),
            #[cfg(not(target_os = "linux"))]
            "splice" => Err("`splice` needs Linux (vmsplice and splice); use `copy` on this system".into()),
            other => Err(format!("unknown transport `{other}`: expected `copy` or `splice`")),
        }
    }
}

impl fmt::Display for Transport {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Transport::Copy => "copy",
            #[cfg(target_os = "linux")]
            Transport::Splice => "splice",
        })
    }
}

impl Transport {
    /// An encoded tile body as this transport sends it best: sealed under `splice` (when large
    /// enough and a mapping can be made), the heap buffer itself under `copy`.
    pub fn seal(self, body: Vec<u8>) -> Bytes {
        match self {
            Transport::Copy => Bytes::from(body),
            #[cfg(target_os = "linux")]
            Transport::Splice => arena::seal(body),
        }
    }

    /// Bytes of memory a body of `len` bytes occupies once [`Self::seal`]ed (sealed bodies take
    /// whole pages); what the tile cache charges against its budget.
    pub fn footprint(self, len: usize) -> usize {
        match self {
            Transport::Copy => len,
            #[cfg(target_os = "linux")]
            Transport::Splice if arena::sealable(len) => len.div_ceil(PAGE) * PAGE,
            #[cfg(target_os = "linux")]
            Transport::Splice => len,
        }
    }

    /// Bytes mapped for sealed bodies now, arena pages between them included (none under
    /// `copy`, whose bodies are ordinary heap memory).
    pub fn mapped_bytes(self) -> usize {
        match self {
            Transport::Copy => 0,
            #[cfg(target_os = "linux")]
            Transport::Splice => arena::mapped_bytes(),
        }
    }

    /// A connection ready for hyper, sending through this transport.
    pub fn wrap(self, stream: TcpStream) -> Io {
        match self {
            Transport::Copy => Io::Copy(TokioIo::new(stream)),
            #[cfg(target_os = "linux")]
            Transport::Splice => Io::Splice(splice::SpliceIo::new(stream)),
        }
    }
}

/// Sends buffers of 64 KiB and more straight to `mmap` on glibc, whatever the transport.
///
/// Why: encoding makes buffers of that size (pixels, the encoded tile before it is sealed or
/// cached); taken from glibc's heap they fragment it, and a long pan leaves the process holding
/// far more memory than the tile cache's budget. Mapped, each returns to the system when freed.
pub fn tune_allocator() {
    #[cfg(all(target_os = "linux", target_env = "gnu"))]
    // SAFETY: mallopt only sets a parameter of glibc's allocator; it takes the allocator's own
    // locks, so any thread may call it at any time.
    unsafe {
        libc::mallopt(libc::M_MMAP_THRESHOLD, 64 * 1024);
    }
}

/// One served connection, as [`Transport::wrap`] made it.
pub enum Io {
    Copy(TokioIo<TcpStream>),
    #[cfg(target_os = "linux")]
    Splice(splice::SpliceIo),
}

/// Calls `$method` on whichever transport `$io` holds.
macro_rules! each {
    ($io:expr, $inner:ident => $call:expr) => {
        match $io {
            Io::Copy($inner) => $call,
            #[cfg(target_os = "linux")]
            Io::Splice($inner) => $call,
        }
    };
}

impl Read for Io {
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: ReadBufCursor<'_>) -> Poll<io::Result<()>> {
        each!(self.get_mut(), io => Pin::new(io).poll_read(cx, buf))
    }
}

impl Write for Io {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        each!(self.get_mut(), io => Pin::new(io).poll_write(cx, buf))
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        each!(self.get_mut(), io => Pin::new(io).poll_write_vectored(cx, bufs))
    }

    fn is_write_vectored(&self) -> bool {
        each!(self, io => io.is_write_vectored())
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        each!(self.get_mut(), io => Pin::new(io).poll_flush(cx))
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        each!(self.get_mut(), io => Pin::new(io).poll_shutdown(cx))
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use std::future::poll_fn;
    use tokio::io::AsyncReadExt;

    pub(crate) fn pattern(n: usize) -> Vec<u8> {
        (0..n).map(|i| (i * 7 + i / 251) as u8).collect()
    }

    /// Writes `parts` as hyper does: the unwritten rest of every part in one vectored write,
    /// again after each short write. Returns how many writes were short.
    pub(crate) async fn write_all(io: &mut (impl Write + Unpin), parts: &[&[u8]]) -> usize {
        let mut rest: Vec<&[u8]> = parts.to_vec();
        let mut short = 0;
        while rest.iter().any(|s| !s.is_empty()) {
            let bufs: Vec<IoSlice<'_>> = rest.iter().filter(|s| !s.is_empty()).map(|s| IoSlice::new(s)).collect();
            let want: usize = bufs.iter().map(|b| b.len()).sum();
            let mut n = poll_fn(|cx| Pin::new(&mut *io).poll_write_vectored(cx, &bufs)).await.unwrap();
            assert!(n > 0 && n <= want);
            short += usize::from(n < want);
            for s in rest.iter_mut() {
                let k = n.min(s.len());
                *s = &s[k..];
                n -= k;
            }
        }
        short
    }

    /// Every transport this system has.
    fn transports() -> Vec<Transport> {
        ["copy", "splice"].iter().filter_map(|s| s.parse().ok()).collect()
    }

    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn copy_sends_every_byte_in_order() {
        bytes_out_equal_bytes_in(Transport::Copy).await;
    }

    #[cfg(target_os = "linux")]
    #[tokio::test(flavor = "multi_thread", worker_threads = 2)]
    async fn splice_sends_every_byte_in_order() {
        bytes_out_equal_bytes_in(Transport::Splice).await;
    }

    /// Headers, a sealed tile, a body several pipes long, a small sealed body (kept on the
    /// heap) and a heap body, to a reader that is slow at first (so the socket fills and writes
    /// come back short): through `t`, every byte arrives in order, also when the bodies are
    /// dropped while the reader may still be receiving.
    async fn bytes_out_equal_bytes_in(t: Transport) {
        {
            // Small socket buffers on both ends, so the bodies cannot all fit in the kernel.
            let small = || {
                let s = tokio::net::TcpSocket::new_v4().unwrap();
                s.set_send_buffer_size(64 * 1024).unwrap();
                s.set_recv_buffer_size(64 * 1024).unwrap();
                s
            };
            let listener = small();
            listener.bind("127.0.0.1:0".parse().unwrap()).unwrap();
            let addr = listener.local_addr().unwrap();
            let listener = listener.listen(1).unwrap();
            let reader = tokio::spawn(async move {
                let (mut s, _) = listener.accept().await.unwrap();
                tokio::time::sleep(std::time::Duration::from_millis(100)).await;
                let mut all = Vec::new();
                s.read_to_end(&mut all).await.unwrap();
                all
            });
            let mut io = t.wrap(small().connect(addr).await.unwrap());
            let head = b"HTTP/1.1 200 OK\r\ncontent-length: 3210000\r\n\r\n".to_vec();
            let tile = t.seal(pattern(150_000));
            let big = t.seal(pattern(3_000_000));
            let small = t.seal(pattern(10_000));
            let heap = pattern(50_000);
            let parts: [&[u8]; 5] = [&head, &tile, &big, &small, &heap];
            let expected = parts.concat();
            let writes = tokio::time::timeout(std::time::Duration::from_secs(30), write_all(&mut io, &parts));
            let short = writes.await.unwrap_or_else(|_| panic!("{t}: writes stalled"));
            assert!(short > 0, "{t}: the slow reader made some writes short");
            poll_fn(|cx| Pin::new(&mut io).poll_shutdown(cx)).await.unwrap();
            drop((tile, big, small));
            let got = tokio::time::timeout(std::time::Duration::from_secs(30), reader).await;
            let got = got.unwrap_or_else(|_| panic!("{t}: the reader stalled")).unwrap();
            assert_eq!(got.len(), expected.len(), "{t}");
            assert!(got == expected, "{t}: bytes differ");
        }
    }

    #[test]
    fn copy_keeps_bodies_on_the_heap() {
        let body = Transport::Copy.seal(pattern(200_000));
        assert!(body == pattern(200_000));
        assert_eq!(Transport::Copy.footprint(200_001), 200_001);
        #[cfg(target_os = "linux")]
        assert!(!arena::registered(&body), "copy never seals");
    }

    #[cfg(target_os = "linux")]
    #[test]
    fn splice_footprint_counts_whole_pages_of_sealed_bodies() {
        let t = Transport::Splice;
        assert_eq!(t.footprint(arena::SEAL_MIN - 1), arena::SEAL_MIN - 1);
        assert_eq!(t.footprint(arena::SEAL_MIN), arena::SEAL_MIN);
        assert_eq!(t.footprint(arena::SEAL_MIN + 1), arena::SEAL_MIN + PAGE);
    }

    #[test]
    fn names_parse_and_print_back() {
        for t in transports() {
            assert_eq!(t.to_string().parse::<Transport>(), Ok(t));
        }
        assert_eq!("copy".parse::<Transport>(), Ok(Transport::Copy));
        let splice = "splice".parse::<Transport>();
        if cfg!(target_os = "linux") {
            assert!(splice.is_ok());
        } else {
            assert!(splice.unwrap_err().contains("needs Linux"));
        }
        assert!("sendfile".parse::<Transport>().unwrap_err().contains("expected `copy` or `splice`"));
    }
}
