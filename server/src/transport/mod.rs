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
//! know which one runs. [`Io`] also holds what both transports share: the send bounds (a
//! timeout and a minimum rate, [`SendLimits`]), and the [`Activity`] a connection's idle
//! timeout reads. This is the one module of the crate allowed `unsafe` code (mappings,
//! `vmsplice`, `mallopt`); each use carries a `SAFETY:` comment.

#[cfg(target_os = "linux")]
mod arena;
#[cfg(target_os = "linux")]
mod splice;

use bytes::Bytes;
use hyper::rt::{Read, ReadBufCursor, Write};
use hyper_util::rt::TokioIo;
use std::fmt;
use std::future::Future;
use std::io::{self, IoSlice};
use std::pin::Pin;
use std::str::FromStr;
use std::sync::atomic::{AtomicBool, AtomicU64, AtomicUsize, Ordering};
use std::sync::{Arc, LazyLock};
use std::task::{Context, Poll};
use std::time::Duration;
use tokio::net::TcpStream;
use tokio::time::{Instant, Sleep};

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

    /// A connection ready for hyper, sending through this transport: every byte it moves is
    /// counted in `activity`, and a response that does not keep up with `limits` fails.
    pub fn wrap(self, stream: TcpStream, activity: Arc<Activity>, limits: SendLimits) -> Io {
        let inner = match self {
            Transport::Copy => Inner::Copy(TokioIo::new(stream)),
            #[cfg(target_os = "linux")]
            Transport::Splice => Inner::Splice(splice::SpliceIo::new(stream)),
        };
        Io { inner, activity, send: SendBounds::new(limits) }
    }

    /// Descriptors one connection may hold: its socket, and under `splice` the pipe it sends
    /// sealed bodies through.
    pub fn descriptors_per_connection(self) -> u64 {
        match self {
            Transport::Copy => 1,
            #[cfg(target_os = "linux")]
            Transport::Splice => 3,
        }
    }
}

/// The soft limit on open file descriptors (`RLIMIT_NOFILE`), `None` when unlimited or unknown.
pub fn descriptor_limit() -> Option<u64> {
    #[cfg(target_os = "linux")]
    {
        rustix::process::getrlimit(rustix::process::Resource::Nofile).current
    }
    #[cfg(not(target_os = "linux"))]
    {
        None
    }
}

/// Sends buffers of 64 KiB and more straight to `mmap` on glibc, whatever the transport: for
/// builds without jemalloc (the binary's `jemalloc` feature).
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

/// What a connection's timeouts and the admission of new connections watch: a count of I/O
/// calls that moved bytes (or saw the peer close), the requests started and those in flight —
/// from the moment hyper hands one to the service until its response body is finished or
/// dropped — whether the end of a response is still on its way to the socket (hyper drops a
/// body once it has taken its last chunk, maybe long before the reader has it), and since when
/// none has been in flight.
///
/// A counter rather than a timestamp keeps a clock read off every read and write; the watcher
/// samples it. The clock is read once per request, when it ends.
#[derive(Debug)]
pub struct Activity {
    moved: AtomicU64,
    started: AtomicU64,
    in_flight: AtomicUsize,
    /// The last write left bytes unsent: hyper's buffer or the splice pipe still holds the end
    /// of a response whose body is finished.
    owing: AtomicBool,
    /// When the connection was accepted or its last request in flight ended, as [`stamp`].
    quiet_since: AtomicU64,
}

impl Default for Activity {
    fn default() -> Activity {
        Activity {
            moved: AtomicU64::new(0),
            started: AtomicU64::new(0),
            in_flight: AtomicUsize::new(0),
            owing: AtomicBool::new(false),
            quiet_since: AtomicU64::new(stamp()),
        }
    }
}

/// Nanoseconds since the first call in this process: a clock connections compare by.
fn stamp() -> u64 {
    static EPOCH: LazyLock<std::time::Instant> = LazyLock::new(std::time::Instant::now);
    u64::try_from(EPOCH.elapsed().as_nanos()).unwrap_or(u64::MAX)
}

impl Activity {
    fn touch(&self) {
        self.moved.fetch_add(1, Ordering::Relaxed);
    }

    /// Changes whenever bytes moved (or a request started or ended) since the last call.
    pub fn moved(&self) -> u64 {
        self.moved.load(Ordering::Relaxed)
    }

    /// Requests started on the connection.
    pub fn started(&self) -> u64 {
        self.started.load(Ordering::Relaxed)
    }

    /// Requests whose answer is not finished.
    pub fn in_flight(&self) -> usize {
        self.in_flight.load(Ordering::Relaxed)
    }

    /// Whether closing the connection now loses nothing: no request in flight, and every byte
    /// of the last response handed to the socket.
    pub fn closable(&self) -> bool {
        self.in_flight() == 0 && !self.owing.load(Ordering::Relaxed)
    }

    /// Since when no request has been in flight (meaningful while none is): comparable between
    /// connections, smaller is longer.
    pub fn quiet_since(&self) -> u64 {
        self.quiet_since.load(Ordering::Relaxed)
    }

    /// Counts a request in flight until the guard is dropped.
    pub fn start(self: &Arc<Self>) -> InFlight {
        self.in_flight.fetch_add(1, Ordering::Relaxed);
        self.started.fetch_add(1, Ordering::Relaxed);
        self.touch();
        InFlight(self.clone())
    }
}

/// Looks at a connection's socket for bytes the runtime has not yet seen: a request head that
/// arrived just as the connection was chosen to make room (its readiness is delivered to the
/// connection only when the runtime next polls its I/O driver, which a yield does not ensure).
#[derive(Clone, Copy, Debug)]
pub struct InputProbe {
    #[cfg(target_os = "linux")]
    fd: std::os::fd::RawFd,
}

impl InputProbe {
    pub fn of(stream: &TcpStream) -> InputProbe {
        InputProbe {
            #[cfg(target_os = "linux")]
            fd: std::os::fd::AsRawFd::as_raw_fd(stream),
        }
    }

    /// Whether bytes wait to be read (a peek that never blocks); always false off Linux, where
    /// the yield before the check is all there is. Call it only while the probed stream is open.
    pub fn input_waiting(&self) -> bool {
        #[cfg(target_os = "linux")]
        {
            use rustix::net::{recv, RecvFlags};
            // SAFETY: the probe is used by its connection's own task, before that task drops the
            // connection owning the stream: the descriptor is open and is this socket.
            let fd = unsafe { std::os::fd::BorrowedFd::borrow_raw(self.fd) };
            matches!(recv(fd, &mut [0u8; 1], RecvFlags::PEEK | RecvFlags::DONTWAIT), Ok((_, n)) if n > 0)
        }
        #[cfg(not(target_os = "linux"))]
        false
    }
}

/// One request in flight on a connection (see [`Activity::start`]).
#[derive(Debug)]
pub struct InFlight(Arc<Activity>);

impl Drop for InFlight {
    fn drop(&mut self) {
        if self.0.in_flight.fetch_sub(1, Ordering::Relaxed) == 1 {
            self.0.quiet_since.store(stamp(), Ordering::Relaxed);
        }
        self.0.touch();
    }
}

/// What a response being sent must keep up with, in both transports: the send timeout and the
/// minimum send rate (`--send-timeout-secs`, `--min-send-rate`).
#[derive(Clone, Copy, Debug)]
pub struct SendLimits {
    /// Longest wait without a byte reaching the socket.
    pub timeout: Duration,
    /// Fewest bytes a second while waiting for the reader, averaged over each `timeout` of
    /// waiting; 0 for no such bound.
    pub min_rate: u64,
}

/// The send bounds of one connection.
///
/// A *wait* begins when a write-side call has to wait for the socket and ends at the next call
/// that moves bytes into it. A wait of [`SendLimits::timeout`] fails the call (a client that
/// stopped reading). Waits also add up in a window, from the first: once they total `timeout`,
/// the bytes moved in the window must reach `min_rate` × `timeout`, or the call fails (a client
/// that reads a trickle, resetting the timeout with every few bytes); otherwise a new window
/// begins. Time not spent waiting (a render, an idle keep-alive) never counts, so only a reader
/// that holds a response back is measured. A failed call makes hyper drop the connection and
/// the response it was sending, which frees what it held; the connection is reset. A call that
/// returns without moving anything (a flush with nothing buffered, which hyper makes whenever
/// its task wakes) leaves a wait running.
struct SendBounds {
    limits: SendLimits,
    /// Made on the first wait, then reset: most connections never need it.
    sleep: Option<Pin<Box<Sleep>>>,
    /// When the current wait began.
    waiting_since: Option<Instant>,
    /// Up to when the current wait is added to `waited`.
    counted_to: Instant,
    /// Time waited, and bytes moved, in the current window.
    waited: Duration,
    moved: u64,
}

impl SendBounds {
    fn new(limits: SendLimits) -> SendBounds {
        let now = Instant::now();
        SendBounds { limits, sleep: None, waiting_since: None, counted_to: now, waited: Duration::ZERO, moved: 0 }
    }

    /// Checks a write-side call that moved `sent` bytes into the socket and returned `polled`:
    /// `polled` when within the bounds, else why the response is abandoned.
    fn check<T>(
        &mut self,
        cx: &mut Context<'_>,
        polled: Poll<io::Result<T>>,
        sent: usize,
    ) -> io::Result<Poll<io::Result<T>>> {
        if sent > 0 {
            self.moved += sent as u64;
            if self.waiting_since.take().is_some() {
                self.count_wait(Instant::now())?;
            }
        }
        if polled.is_ready() {
            return Ok(polled);
        }
        if self.waiting_since.is_none() {
            let now = Instant::now();
            (self.waiting_since, self.counted_to) = (Some(now), now);
            if self.waited.is_zero() {
                // A window begins with its first wait: what a reader took at once before it
                // held anything back is no credit for what follows.
                self.moved = 0;
            }
            let deadline = self.deadline();
            match &mut self.sleep {
                Some(s) => s.as_mut().reset(deadline),
                None => self.sleep = Some(Box::pin(tokio::time::sleep_until(deadline))),
            }
        }
        loop {
            let sleep = self.sleep.as_mut().expect("a wait has its sleep");
            if sleep.as_mut().poll(cx).is_pending() {
                return Ok(Poll::Pending);
            }
            let (now, since) = (Instant::now(), self.waiting_since.expect("polled only while waiting"));
            if now - since >= self.limits.timeout {
                return Err(io::Error::new(
                    io::ErrorKind::TimedOut,
                    format!("no bytes could be sent for {} s (send timeout)", self.limits.timeout.as_secs_f64()),
                ));
            }
            self.count_wait(now)?;
            let deadline = self.deadline();
            self.sleep.as_mut().expect("a wait has its sleep").as_mut().reset(deadline);
        }
    }

    /// When the current wait fails the send timeout or fills the window, whichever is first.
    fn deadline(&self) -> Instant {
        let since = self.waiting_since.expect("only a wait has a deadline");
        let window_full = self.counted_to + self.limits.timeout.saturating_sub(self.waited);
        (since + self.limits.timeout).min(window_full)
    }

    /// Adds the current wait up to `now` to the window; once the window is full, fails if too
    /// few bytes moved in it, or begins the next one.
    fn count_wait(&mut self, now: Instant) -> io::Result<()> {
        self.waited += now - self.counted_to;
        self.counted_to = now;
        if self.waited < self.limits.timeout {
            return Ok(());
        }
        let window = self.waited.as_secs_f64();
        if (self.moved as f64) < self.limits.min_rate as f64 * window {
            return Err(io::Error::new(
                io::ErrorKind::TimedOut,
                format!(
                    "{} bytes sent in {window:.1} s of waiting for the reader, below the minimum send rate of {} B/s",
                    self.moved, self.limits.min_rate
                ),
            ));
        }
        (self.waited, self.moved) = (Duration::ZERO, 0);
        Ok(())
    }
}

/// One served connection, as [`Transport::wrap`] made it.
pub struct Io {
    inner: Inner,
    activity: Arc<Activity>,
    send: SendBounds,
}

enum Inner {
    Copy(TokioIo<TcpStream>),
    #[cfg(target_os = "linux")]
    Splice(splice::SpliceIo),
}

/// Calls `$method` on whichever transport `$io` holds.
macro_rules! each {
    ($io:expr, $inner:ident => $call:expr) => {
        match $io {
            Inner::Copy($inner) => $call,
            #[cfg(target_os = "linux")]
            Inner::Splice($inner) => $call,
        }
    };
}

impl Inner {
    fn stream(&self) -> &TcpStream {
        match self {
            Inner::Copy(io) => io.inner(),
            #[cfg(target_os = "linux")]
            Inner::Splice(io) => io.stream(),
        }
    }

    /// Bytes accepted from hyper but not yet in the socket (the splice pipe's).
    fn unsent(&self) -> usize {
        match self {
            Inner::Copy(_) => 0,
            #[cfg(target_os = "linux")]
            Inner::Splice(io) => io.unsent(),
        }
    }
}

impl Io {
    /// A write-side call under the send bounds. The bytes it moved into the socket are those it
    /// accepted (`wrote`) and those it drained from the splice pipe, less those it left in the
    /// pipe; writing counts as activity.
    fn sending<T>(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        call: impl FnOnce(&mut Inner, &mut Context<'_>) -> Poll<io::Result<T>>,
        wrote: impl FnOnce(&T) -> usize,
    ) -> Poll<io::Result<T>> {
        let this = self.get_mut();
        let unsent = this.inner.unsent();
        let polled = call(&mut this.inner, cx);
        let accepted = match &polled {
            Poll::Ready(Ok(v)) => wrote(v),
            _ => 0,
        };
        let sent = (accepted + unsent).saturating_sub(this.inner.unsent());
        if accepted > 0 || sent > 0 {
            this.activity.touch();
        }
        this.activity.owing.store(polled.is_pending() || this.inner.unsent() > 0, Ordering::Relaxed);
        this.send.check(cx, polled, sent).unwrap_or_else(|abandoned| {
            // Reset rather than close, so the kernel drops what it still holds for this reader
            // too (as nginx's `reset_timedout_connection`).
            let _ = this.inner.stream().set_zero_linger();
            Poll::Ready(Err(abandoned))
        })
    }
}

impl Read for Io {
    /// A read that completes moved bytes or saw the peer close (a socket with nothing to read
    /// stays pending): activity either way.
    fn poll_read(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: ReadBufCursor<'_>) -> Poll<io::Result<()>> {
        let this = self.get_mut();
        let polled = each!(&mut this.inner, io => Pin::new(io).poll_read(cx, buf));
        if polled.is_ready() {
            this.activity.touch();
        }
        polled
    }
}

impl Write for Io {
    fn poll_write(self: Pin<&mut Self>, cx: &mut Context<'_>, buf: &[u8]) -> Poll<io::Result<usize>> {
        self.sending(cx, |inner, cx| each!(inner, io => Pin::new(io).poll_write(cx, buf)), |&n| n)
    }

    fn poll_write_vectored(
        self: Pin<&mut Self>,
        cx: &mut Context<'_>,
        bufs: &[IoSlice<'_>],
    ) -> Poll<io::Result<usize>> {
        self.sending(cx, |inner, cx| each!(inner, io => Pin::new(io).poll_write_vectored(cx, bufs)), |&n| n)
    }

    fn is_write_vectored(&self) -> bool {
        each!(&self.inner, io => io.is_write_vectored())
    }

    fn poll_flush(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        self.sending(cx, |inner, cx| each!(inner, io => Pin::new(io).poll_flush(cx)), |()| 0)
    }

    fn poll_shutdown(self: Pin<&mut Self>, cx: &mut Context<'_>) -> Poll<io::Result<()>> {
        self.sending(cx, |inner, cx| each!(inner, io => Pin::new(io).poll_shutdown(cx)), |()| 0)
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
            let limits = SendLimits { timeout: std::time::Duration::from_secs(30), min_rate: 0 };
            let mut io = t.wrap(small().connect(addr).await.unwrap(), Arc::default(), limits);
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

    /// Drives `bounds` through `rounds` of a reader that lets `per_round` bytes through after
    /// each wait of `wait`; returns the round whose call was refused, if any.
    fn reader(bounds: &mut SendBounds, rounds: usize, wait: std::time::Duration, per_round: usize) -> Option<usize> {
        let mut cx = Context::from_waker(std::task::Waker::noop());
        (0..rounds).find(|_| {
            assert!(bounds.check::<usize>(&mut cx, Poll::Pending, 0).unwrap().is_pending());
            std::thread::sleep(wait);
            bounds.check(&mut cx, Poll::Ready(Ok(per_round)), per_round).is_err()
        })
    }

    const LIMITS: SendLimits = SendLimits { timeout: std::time::Duration::from_millis(300), min_rate: 1000 };

    /// A reader that lets 10 bytes through every 50 ms of waiting restarts the send timeout
    /// every time, but is refused once its waits fill a window (300 ms) with fewer than 300
    /// bytes, though it took a megabyte at once before its first wait.
    #[tokio::test]
    async fn a_trickle_is_refused_at_the_end_of_its_first_window() {
        let mut bounds = SendBounds::new(LIMITS);
        let mut cx = Context::from_waker(std::task::Waker::noop());
        assert!(bounds.check(&mut cx, Poll::Ready(Ok(1 << 20)), 1 << 20).is_ok());
        let refused = reader(&mut bounds, 8, std::time::Duration::from_millis(50), 10);
        assert!(refused.is_some_and(|round| round < 7), "refused in round {refused:?}");
    }

    /// A reader that keeps up with the rate is never refused, however long it waits in all.
    #[tokio::test]
    async fn a_reader_at_the_rate_is_served() {
        let mut bounds = SendBounds::new(LIMITS);
        assert_eq!(reader(&mut bounds, 20, std::time::Duration::from_millis(50), 1000), None);
    }

    /// One wait as long as the send timeout is refused, whatever moved before.
    #[tokio::test]
    async fn a_stalled_reader_meets_the_send_timeout() {
        let mut bounds = SendBounds::new(SendLimits { min_rate: 0, ..LIMITS });
        let mut cx = Context::from_waker(std::task::Waker::noop());
        assert!(bounds.check(&mut cx, Poll::Ready(Ok(1 << 20)), 1 << 20).is_ok());
        assert!(bounds.check::<usize>(&mut cx, Poll::Pending, 0).unwrap().is_pending());
        // Yielding to the runtime, so that its timer fires the bound's sleep.
        tokio::time::sleep(std::time::Duration::from_millis(350)).await;
        let refused = bounds.check::<usize>(&mut cx, Poll::Pending, 0).unwrap_err();
        assert!(refused.to_string().contains("send timeout"), "{refused}");
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
