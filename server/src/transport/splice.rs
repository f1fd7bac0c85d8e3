//! The connection side of `--send splice`: sealed slices handed to the socket by reference.
//!
//! When hyper writes a slice that lies inside a sealed body (see [`super::arena`]), its pages
//! go to the socket by reference (`vmsplice` into a per-connection pipe, then `splice` into
//! the socket); every other write is a plain `writev`. Headers before a spliced body cork the
//! socket (TCP_CORK) until hyper flushes the response, so it leaves in full-sized segments.
//!
//! Why this is sound: the kernel keeps its own references to the pages it was handed, and a
//! sealed page is never written after sealing, so bytes in flight cannot change. Memory that is
//! not sealed (headers, JSON, HTTP/2 frames, anything from the heap) is never spliced, because
//! the heap reuses freed memory while the kernel might still hold it.

use super::arena::{registered, SEAL_MIN};
use hyper::rt::{Read, ReadBufCursor, Write};
use hyper_util::rt::TokioIo;
use rustix::net::{sendmsg, sockopt, SendAncillaryBuffer, SendFlags};
use rustix::pipe::{self, IoSliceRaw, PipeFlags, SpliceFlags};
use std::io::{self, IoSlice};
use std::os::fd::OwnedFd;
use std::pin::Pin;
use std::task::{ready, Context, Poll};
use tokio::io::Interest;
use tokio::net::TcpStream;

/// Pipe capacity asked for: one 256² PNG tile in one or two rounds.
const PIPE_BYTES: usize = 256 * 1024;

struct Pipe {
    read: OwnedFd,
    write: OwnedFd,
}

impl Pipe {
    fn new() -> io::Result<Pipe> {
        let (read, write) = pipe::pipe_with(PipeFlags::CLOEXEC | PipeFlags::NONBLOCK)?;
        // A larger pipe means fewer rounds per tile; the default 64 KiB also works.
        let _ = pipe::fcntl_setpipe_size(&write, PIPE_BYTES);
        Ok(Pipe { read, write })
    }
}

/// A server connection for hyper: tokio's `TcpStream`, with sealed slices spliced.
///
/// Bytes moved into the pipe count as written for hyper; they reach the socket before anything
/// written after them, and before a flush or shutdown completes.
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

    /// Bytes in the pipe not yet in the socket.
    pub fn unsent(&self) -> usize {
        self.queued
    }

    pub fn stream(&self) -> &TcpStream {
        self.io.inner()
    }

    /// Moves queued pipe bytes into the socket; Ready once the pipe is empty.
    fn poll_drain(&mut self, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        while self.queued > 0 {
            let pipe = self.pipe.as_ref().expect("bytes are queued only in an existing pipe");
            ready!(self.stream().poll_write_ready(cx))?;
            let flags = SpliceFlags::MOVE | SpliceFlags::NONBLOCK;
            let moved = self.stream().try_io(Interest::WRITABLE, || {
                Ok(pipe::splice(&pipe.read, None, self.stream(), None, self.queued, flags)?)
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
        // SAFETY: `buf` is sealed: alive for this call (hyper holds its `Bytes`) and never
        // written again, so the kernel may keep references to its pages after we return; the
        // descriptor is the pipe's write end, so the kernel only reads `buf`.
        let put = unsafe { pipe::vmsplice(&pipe.write, &[IoSliceRaw::from_slice(buf)], SpliceFlags::NONBLOCK) };
        let n = match put {
            Ok(n) if n > 0 => n,
            _ => {
                // The pipe is empty here, so this is a refusal (e.g. a sandbox), not a full
                // pipe: copy instead, on this connection from now on.
                self.pipe = None;
                self.no_pipe = true;
                return None;
            }
        };
        self.queued = n;
        // Start moving it now; if the socket is full the waker is registered and the bytes go
        // out on the next write or flush.
        match self.poll_drain(cx) {
            Poll::Ready(Err(e)) => Some(Err(e)),
            _ => Some(Ok(n)),
        }
    }

    /// Holds partial segments back (TCP_CORK) until [`Self::uncork`]: headers and a spliced
    /// body then leave in full segments, as nginx sends with `sendfile` and `tcp_nopush`.
    ///
    /// Why it matters on loopback: without it the last segments of each response are smaller
    /// than the peer's MSS, the receiver's RTT estimate (taken from full-sized segments)
    /// collapses, its receive-buffer autotuning never grows the window, and every response
    /// arrives in more, smaller segments: more wake-ups and ACKs for the client. Costs two
    /// `setsockopt` calls per response with a sealed body.
    fn cork(&mut self) {
        if !self.corked {
            self.corked = sockopt::set_tcp_cork(self.stream(), true).is_ok();
        }
    }

    /// Sends what the cork held back; called once hyper flushes (the response is written).
    fn uncork(&mut self) -> io::Result<()> {
        if self.corked {
            self.corked = false;
            sockopt::set_tcp_cork(self.stream(), false)?;
        }
        Ok(())
    }

    /// Writes leading unsealed slices with MSG_MORE: the sealed body follows at once, so the
    /// headers need not go out as a packet of their own.
    fn poll_send_more(&self, cx: &mut Context<'_>, bufs: &[IoSlice<'_>]) -> Poll<io::Result<usize>> {
        let flags = SendFlags::MORE | SendFlags::NOSIGNAL | SendFlags::DONTWAIT;
        loop {
            ready!(self.stream().poll_write_ready(cx))?;
            let sent = self.stream().try_io(Interest::WRITABLE, || {
                Ok(sendmsg(self.stream(), bufs, &mut SendAncillaryBuffer::default(), flags)?)
            });
            match sent {
                Err(e) if e.kind() == io::ErrorKind::WouldBlock => continue,
                r => return Poll::Ready(r),
            }
        }
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

#[cfg(test)]
mod tests {
    use super::*;
    use crate::transport::arena::seal;
    use crate::transport::tests::{pattern, write_all};
    use tokio::io::AsyncReadExt;

    /// Headers before a sealed body cork the socket; hyper's flush uncorks it, so nothing is
    /// held back once a response is written. The reader gets the response without the
    /// connection closing.
    #[tokio::test]
    async fn the_cork_is_released_on_flush() {
        use std::future::poll_fn;
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let stream = TcpStream::connect(listener.local_addr().unwrap()).await.unwrap();
        let (mut peer, _) = listener.accept().await.unwrap();
        let probe = stream.into_std().unwrap();
        let stream = TcpStream::from_std(probe.try_clone().unwrap()).unwrap();
        let corked = || sockopt::tcp_cork(&probe).unwrap();
        let mut io = SpliceIo::new(stream);
        let head = b"HTTP/1.1 200 OK\r\ncontent-length: 100000\r\n\r\n".to_vec();
        let body = seal(pattern(100_000));
        assert!(!corked());
        write_all(&mut io, &[&head, &body]).await;
        assert!(corked(), "headers followed by a sealed body cork the socket");
        poll_fn(|cx| Pin::new(&mut io).poll_flush(cx)).await.unwrap();
        assert!(!corked(), "a flush uncorks it");
        let mut got = vec![0; head.len() + body.len()];
        let read = tokio::time::timeout(std::time::Duration::from_secs(30), peer.read_exact(&mut got));
        read.await.expect("the whole response arrives").unwrap();
        assert_eq!(&got[..head.len()], &head[..]);
        assert!(got[head.len()..] == body[..]);
    }

    /// A sealed body goes through the pipe (it is spliced, not copied); an unsealed one of the
    /// same size does not open a pipe at all.
    #[tokio::test]
    async fn only_sealed_bodies_are_spliced() {
        let listener = tokio::net::TcpListener::bind("127.0.0.1:0").await.unwrap();
        let addr = listener.local_addr().unwrap();
        let reader = tokio::spawn(async move {
            let (mut s, _) = listener.accept().await.unwrap();
            let mut all = Vec::new();
            s.read_to_end(&mut all).await.unwrap();
            all
        });
        let mut io = SpliceIo::new(TcpStream::connect(addr).await.unwrap());
        let heap = pattern(100_000);
        write_all(&mut io, &[&heap]).await;
        assert!(io.pipe.is_none() && !io.no_pipe, "heap memory is copied");
        let sealed = seal(pattern(100_000));
        write_all(&mut io, &[&sealed]).await;
        assert!(io.pipe.is_some(), "a sealed body is spliced");
        std::future::poll_fn(|cx| Pin::new(&mut io).poll_shutdown(cx)).await.unwrap();
        let got = reader.await.unwrap();
        assert!(got[..100_000] == heap[..] && got[100_000..] == sealed[..]);
    }
}
