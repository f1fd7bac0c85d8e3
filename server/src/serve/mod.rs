//! `vtex serve`: opens the store, binds, and serves connections until SIGTERM or Ctrl-C.
//!
//! The accept loop is hyper's own (rather than `axum::serve`) so that a client that never
//! finishes its request headers is cut off after `--header-timeout-secs`, and so that
//! shutdown stops accepting, lets requests in flight finish, then exits.
//!
//! Connections are served by one single-threaded tokio runtime per core, each serving its own
//! connections (nginx's worker model); one accepts and hands each new connection to the
//! runtime serving the fewest. One work-stealing runtime would spend more CPU per warm tile
//! and wait on cross-thread wake-ups. Syntheses still run on blocking pools, bounded by the
//! shared [`crate::engine::slots::Slots`].
//!
//! Every connection is bounded in time and number: a response that cannot be sent for
//! `--send-timeout-secs`, or that its reader takes slower than `--min-send-rate`, is abandoned
//! (in [`crate::transport::Io`]), a connection idle for
//! `--idle-timeout-secs` is closed ([`until_idle`]), and beyond `--max-connections` a new
//! connection is answered 503 and closed ([`Refusal`]) rather than left to hold a descriptor.
//!
//! Shutdown stops accepting, lets requests in flight finish within the drain time, stops the
//! renders that would outlast it (their requests get 503), and exits without waiting for
//! anything past it.
//!
//! Each request of a connection ([`connection`]) has its head checked ([`head`]), then takes
//! the fast tile path ([`fast_tile`]) or the router; its access line is written once its body
//! is sent ([`access`]).

mod access;
mod connection;
mod cors;
mod fast_tile;
mod head;

use crate::api::state::AppState;
use crate::config::ServeConfig;
use crate::store::Store;
use crate::transport::{Activity, SendLimits, Transport};
use crate::watch::Watch;
use connection::Front;
use head::MAX_HEAD_BYTES;
use hyper_util::rt::{TokioExecutor, TokioTimer};
use hyper_util::server::conn::auto;
use prometheus::{IntCounter, IntGauge};
use std::future::Future;
use std::io::Write;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::{TcpListener, TcpStream};
use tokio::sync::Semaphore;
use vtex_synth::Resources;

/// How long shutdown waits for requests in flight before it gives up on them.
const DRAIN_TIMEOUT: Duration = Duration::from_secs(10);
/// How long before the end of the drain every render still running is stopped: time for the
/// models to reach their next band and for the 503s to be sent.
const STOP_BEFORE_END: Duration = Duration::from_secs(2);

/// `vtex serve`: [`run`] until SIGTERM or Ctrl-C. The runtime is not waited for when the
/// server is done: work still on its blocking pool then (a render that did not stop in the
/// drain time) has nobody left to answer, so the process exits within the drain time.
///
/// Once it accepts connections it prints `vtex listening on http://ADDR` on stdout, the line
/// scripts and tests wait for.
pub fn main(cfg: ServeConfig) -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    let announce = |addr: SocketAddr| -> anyhow::Result<()> {
        let mut out = std::io::stdout().lock();
        writeln!(out, "vtex listening on http://{addr}")?;
        Ok(out.flush()?)
    };
    let result = rt.block_on(run(cfg, shutdown_signal(), announce));
    rt.shutdown_background();
    result
}

/// Runs the server until `shutdown` resolves, calling `listening` with its address once it
/// accepts connections.
pub async fn run(
    mut cfg: ServeConfig,
    shutdown: impl Future<Output = ()>,
    listening: impl FnOnce(SocketAddr) -> anyhow::Result<()>,
) -> anyhow::Result<()> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    cfg.resolve_write_token().map_err(anyhow::Error::msg)?;
    // Nothing is written before the server can run: the address is bound and the data
    // directory checked before the demos are written into it.
    let listener = TcpListener::bind(cfg.bind)
        .await
        .map_err(|e| anyhow::anyhow!("cannot listen on {}: {}", cfg.bind, io_message(&e)))?;
    let t0 = Instant::now();
    let (dir, bounds, watch, write) = (cfg.data_dir.clone(), cfg.store_bounds(), cfg.watch, !cfg.read_only);
    let resources = Resources::new(cfg.synth_cache_bytes());
    let demos = write && !cfg.no_demos;
    // The watch starts before the store lists the directory, so nothing added meanwhile is missed.
    let (store, report, watch) = tokio::task::spawn_blocking(move || {
        check_data_dir(&dir, write)?;
        let watch = Watch::start(&dir, watch).map_err(anyhow::Error::msg)?;
        let (store, report) = Store::open(&dir, bounds, resources, demos)
            .map_err(|e| anyhow::anyhow!("cannot open data directory {}: {}", dir.display(), io_message(&e)))?;
        anyhow::Ok((Arc::new(store), report, watch))
    })
    .await??;
    for (path, why) in &report.rejected {
        tracing::warn!(path = %path.display(), reason = %why, "not serving an invalid file in the data directory");
    }
    for (path, why) in &report.stale_temp_kept {
        tracing::warn!(path = %path.display(), reason = %why, "could not remove a stale temporary file; left in place");
    }
    for (name, why) in &report.demos_refused {
        tracing::warn!(demo = %name, reason = %why, "demo not written: over the store's bounds");
    }
    tracing::info!(
        data_dir = %cfg.data_dir.display(),
        textures = store.len(),
        demos_written = report.demos_written,
        stale_temp_removed = report.stale_temp_removed,
        watch = watch.as_ref().map_or("off", |w| w.how),
        ms = t0.elapsed().as_millis() as u64,
        "store opened"
    );
    if let Some(watch) = watch {
        watch.follow(store.clone())?;
    }
    match &cfg.web_dir {
        Some(dir) if !dir.join("index.html").is_file() => {
            tracing::warn!(web_dir = %dir.display(), "no index.html in the web directory; the viewer is not served")
        }
        None if crate::api::Web::embedded().is_none() => {
            tracing::warn!("this binary was built without the viewer (client-web/dist); it is not served")
        }
        _ => {}
    }
    let app = AppState::new(store, cfg.clone());
    app.writes.announce();
    // Renders in flight at shutdown may finish during the drain; those that would outlast it
    // are stopped shortly before it ends, so their requests are answered 503 rather than cut.
    let shutdown = {
        let app = app.clone();
        async move {
            shutdown.await;
            app.draining.store(true, std::sync::atomic::Ordering::Relaxed);
            tokio::spawn(async move {
                tokio::time::sleep(DRAIN_TIMEOUT - STOP_BEFORE_END).await;
                tracing::info!("stopping the syntheses still running");
                app.engine.stop_syntheses();
            });
        }
    };
    let live = |i: usize| app.metrics.connections.with_label_values(&[i.to_string().as_str()]);
    let mut workers: Vec<Worker> = (0..cfg.io_threads()).map(|i| Worker { live: live(i), tx: None }).collect();
    let max_connections = cfg.max_connections();
    app.metrics.connections_max.set(i64::try_from(max_connections).unwrap_or(i64::MAX));
    let refusal = Refusal::new(max_connections, app.metrics.connections_refused.clone());
    let front = Front::new(app);

    let addr = listener.local_addr()?;
    tracing::info!(
        %addr,
        cache_mb = cfg.cache_mb,
        syntheses = cfg.syntheses(),
        send = %cfg.send,
        max_connections,
        "serving"
    );
    listening(addr)?;

    // One single-threaded runtime per core, each serving its own connections (nginx's worker
    // model): no cross-thread wake-ups on the hot path. This runtime accepts and hands each
    // connection to the runtime serving the fewest (see `Worker`).
    let mut threads = Vec::new();
    for (i, worker) in workers.iter_mut().enumerate().skip(1) {
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        worker.tx = Some(tx);
        let conns = Conns::new(front.clone(), &cfg, worker.live.clone());
        threads.push(std::thread::Builder::new().name(format!("vtex-io-{i}")).spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
            rt.block_on(serve_handed(rx, conns));
            // Drained: what its blocking pool still runs answers nobody (see `main`).
            rt.shutdown_background();
            anyhow::Ok(())
        })?);
    }
    let own = Conns::new(front, &cfg, workers[0].live.clone());
    accept_loop(listener, workers, own, refusal, shutdown).await;
    for t in threads {
        tokio::task::spawn_blocking(move || t.join())
            .await?
            .map_err(|_| anyhow::anyhow!("an I/O thread panicked"))??;
    }
    Ok(())
}

/// Checks the data directory before anything is written to it: a directory (created if
/// missing) that can be read, and written unless `write` is false. The error names the path.
fn check_data_dir(dir: &Path, write: bool) -> anyhow::Result<()> {
    let fail = |what: &str, e: std::io::Error| {
        anyhow::anyhow!("cannot {what} data directory {}: {}", dir.display(), io_message(&e))
    };
    match std::fs::metadata(dir) {
        Ok(m) if !m.is_dir() => anyhow::bail!("data directory {} is not a directory", dir.display()),
        Ok(_) => {}
        Err(e) if e.kind() == std::io::ErrorKind::NotFound => {
            std::fs::create_dir_all(dir).map_err(|e| fail("create", e))?
        }
        Err(e) => return Err(fail("reach", e)),
    }
    std::fs::read_dir(dir).map_err(|e| fail("read", e))?;
    if write {
        // A temporary name: a probe left by a crash is removed at a later start, never served.
        let probe = dir.join(format!("{}probe-{}", crate::store::TEMP_PREFIX, std::process::id()));
        let created = std::fs::File::options().write(true).create_new(true).open(&probe);
        created.and_then(|_| std::fs::remove_file(&probe)).map_err(|e| {
            anyhow::anyhow!(
                "cannot write to data directory {}: {} (--read-only serves it without writing)",
                dir.display(),
                io_message(&e)
            )
        })?;
    }
    Ok(())
}

/// An I/O error as a person reads it: the system's words without the `(os error N)` code,
/// starting lower-case to follow the colon that introduces it.
fn io_message(e: &std::io::Error) -> String {
    let text = e.to_string();
    let text = match text.find(" (os error ") {
        Some(at) if text.ends_with(')') => &text[..at],
        _ => text.as_str(),
    };
    let mut chars = text.chars();
    chars.next().map(|c| c.to_lowercase().chain(chars).collect()).unwrap_or_default()
}

/// One runtime serving connections: how many it serves now, and (for the other runtimes) the
/// channel the acceptor hands it new ones through.
///
/// Why one acceptor: when every runtime accepted from the shared socket, whichever was awake
/// took the whole burst of a load generator's connections (all 64 on one runtime in one run,
/// half the throughput). Handing each new connection to the runtime with the fewest live ones
/// splits them evenly whatever the timing; the cost is one cross-thread wake-up per connection,
/// not per request.
struct Worker {
    /// The `vtex_http_connections` series of this runtime.
    live: IntGauge,
    /// `None` for the accepting runtime itself.
    tx: Option<tokio::sync::mpsc::UnboundedSender<std::net::TcpStream>>,
}

/// How one runtime serves its connections: hyper's settings, graceful shutdown, and the count
/// of connections it serves (shared with the acceptor).
struct Conns {
    front: Front,
    builder: auto::Builder<TokioExecutor>,
    send: Transport,
    send_limits: SendLimits,
    idle_timeout: Duration,
    graceful: hyper_util::server::graceful::GracefulShutdown,
    live: IntGauge,
}

impl Conns {
    fn new(front: Front, cfg: &ServeConfig, live: IntGauge) -> Conns {
        let mut builder = auto::Builder::new(TokioExecutor::new());
        builder.http1().timer(TokioTimer::new()).header_read_timeout(cfg.header_timeout()).max_buf_size(MAX_HEAD_BYTES);
        let head = u32::try_from(MAX_HEAD_BYTES).expect("the head bound fits HTTP/2's setting");
        builder.http2().timer(TokioTimer::new()).max_header_list_size(head);
        Conns {
            front,
            builder,
            send: cfg.send,
            send_limits: cfg.send_limits(),
            idle_timeout: cfg.idle_timeout(),
            graceful: hyper_util::server::graceful::GracefulShutdown::new(),
            live,
        }
    }

    /// Serves `stream` on the current runtime until it closes or idles; counted in `live`
    /// meanwhile (the acceptor counted it already).
    fn serve(&self, stream: TcpStream) {
        let _ = stream.set_nodelay(true);
        // A socket already closed has no peer: unspecified, so never taken for loopback.
        let peer = stream.peer_addr().unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
        let activity = Arc::new(Activity::default());
        let io = self.send.wrap(stream, activity.clone(), self.send_limits);
        let service = self.front.connection(activity.clone(), peer);
        let conn = self.builder.serve_connection_with_upgrades(io, service).into_owned();
        let conn = self.graceful.watch(conn);
        let (live, idle) = (LiveGuard(self.live.clone()), self.idle_timeout);
        tokio::spawn(async move {
            // Dropping an idle connection loses nothing: no request is in flight on it.
            tokio::select! {
                ended = conn => if let Err(e) = ended {
                    tracing::debug!(error = %e, "connection ended with an error");
                },
                () = until_idle(&activity, idle) => tracing::debug!("closed an idle connection"),
            }
            drop(live);
        });
    }

    /// Lets requests in flight finish (up to [`DRAIN_TIMEOUT`]).
    async fn drain(self) {
        tokio::select! {
            () = self.graceful.shutdown() => tracing::debug!("all connections closed"),
            () = tokio::time::sleep(DRAIN_TIMEOUT) => tracing::warn!("drain timed out; exiting with connections open"),
        }
    }
}

/// Resolves once `activity` has shown no bytes moving and no request in flight for `idle`.
///
/// Sampled at quarters of `idle`, so a connection closes between one and one and a quarter
/// idle times after its last byte, at the cost of four timer wake-ups per idle time.
async fn until_idle(activity: &Activity, idle: Duration) {
    const SAMPLES: u32 = 4;
    let period = idle / SAMPLES;
    let mut ticks = tokio::time::interval_at(tokio::time::Instant::now() + period, period);
    ticks.set_missed_tick_behavior(tokio::time::MissedTickBehavior::Delay);
    let (mut seen, mut quiet) = (activity.moved(), 0);
    loop {
        ticks.tick().await;
        let now = activity.moved();
        if now != seen || activity.in_flight() > 0 {
            (seen, quiet) = (now, 0);
        } else {
            quiet += 1;
            if quiet == SAMPLES {
                return;
            }
        }
    }
}

/// How a connection over `--max-connections` is turned away: a complete `503` naming the limit,
/// then a close — a clear answer where waiting in the backlog or a reset would tell the
/// client nothing.
struct Refusal {
    max: usize,
    answer: bytes::Bytes,
    /// Refusals being answered at once; each holds a descriptor from [`FD_RESERVE`].
    ///
    /// [`FD_RESERVE`]: crate::config::FD_RESERVE
    answering: Arc<Semaphore>,
    refused: IntCounter,
}

/// Refusals answered at once, their descriptors taken from the reserve; beyond it a refusal
/// writes what the socket takes at once and closes.
const REFUSALS_AT_ONCE: usize = 16;
/// How long a refusal may take, waiting for the client to read it and close.
const REFUSAL_TIME: Duration = Duration::from_secs(2);
/// Most request bytes a refusal reads (and discards) while it waits for the client to close.
const REFUSAL_DRAIN_BYTES: usize = 64 * 1024;

impl Refusal {
    fn new(max: usize, refused: IntCounter) -> Refusal {
        let body = serde_json::json!({
            "error": format!("the server is serving its limit of {max} connections; retry later")
        })
        .to_string();
        let answer = format!(
            "HTTP/1.1 503 Service Unavailable\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\
             retry-after: 1\r\nconnection: close\r\naccess-control-allow-origin: *\r\n\r\n{body}",
            body.len()
        );
        Refusal { max, answer: answer.into(), answering: Arc::new(Semaphore::new(REFUSALS_AT_ONCE)), refused }
    }

    /// Whether a new connection would exceed the limit, with `open` served now.
    fn full(&self, open: i64) -> bool {
        usize::try_from(open).is_ok_and(|open| open >= self.max)
    }

    /// Answers `stream` 503 and closes it, on the current runtime.
    fn refuse(&self, mut stream: TcpStream) {
        self.refused.inc();
        let Ok(permit) = self.answering.clone().try_acquire_owned() else {
            let _ = stream.try_write(&self.answer);
            return;
        };
        let answer = self.answer.clone();
        tokio::spawn(async move {
            let exchange = async {
                stream.write_all(&answer).await?;
                stream.shutdown().await?;
                // Closing with the request unread would reset the connection, and a reset
                // may discard the answer before the client reads it: read until it closes.
                let mut sink = [0u8; 4096];
                let mut left = REFUSAL_DRAIN_BYTES;
                while left > 0 {
                    match stream.read(&mut sink).await? {
                        0 => break,
                        n => left = left.saturating_sub(n),
                    }
                }
                std::io::Result::Ok(())
            };
            let _ = tokio::time::timeout(REFUSAL_TIME, exchange).await;
            drop(permit);
        });
    }
}

/// Uncounts a connection when its task ends or is dropped.
struct LiveGuard(IntGauge);

impl Drop for LiveGuard {
    fn drop(&mut self) {
        self.0.dec();
    }
}

/// Accepts connections until `shutdown` resolves, serving each on the runtime of `workers`
/// with the fewest live ones (`workers[0]` is this runtime: `own`), or refusing it when they
/// serve the limit already; then drains this
/// runtime's connections (closing the channels tells the other runtimes to drain theirs).
async fn accept_loop(
    listener: TcpListener,
    workers: Vec<Worker>,
    own: Conns,
    refusal: Refusal,
    shutdown: impl Future<Output = ()>,
) {
    let mut next = 0;
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            accepted = listener.accept() => {
                let (stream, _) = match accepted {
                    Ok(c) => c,
                    Err(e) => {
                        // Out of file descriptors and the like: back off instead of spinning.
                        tracing::warn!(error = %e, "accept failed");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    }
                };
                if refusal.full(workers.iter().map(|w| w.live.get()).sum()) {
                    refusal.refuse(stream);
                    continue;
                }
                // The least-loaded runtime; ties go round-robin.
                let n = workers.len();
                let k = (0..n).map(|i| (next + i) % n).min_by_key(|&k| workers[k].live.get()).unwrap_or(0);
                next = (k + 1) % n;
                let w = &workers[k];
                w.live.inc();
                match &w.tx {
                    None => own.serve(stream),
                    Some(tx) => {
                        // Deregistered here, registered again on the receiving runtime.
                        let sent = stream
                            .into_std()
                            .map_err(|e| e.to_string())
                            .and_then(|s| tx.send(s).map_err(|_| "runtime gone".into()));
                        if let Err(e) = sent {
                            w.live.dec();
                            tracing::warn!(error = %e, "could not hand a connection to its runtime");
                        }
                    }
                }
            }
            () = &mut shutdown => break,
        }
    }
    drop(listener);
    drop(workers);
    tracing::info!("shutting down: draining requests in flight");
    own.drain().await;
}

/// Serves the connections the acceptor hands this runtime until it stops (closes the channel),
/// then drains them.
async fn serve_handed(mut rx: tokio::sync::mpsc::UnboundedReceiver<std::net::TcpStream>, conns: Conns) {
    while let Some(stream) = rx.recv().await {
        match TcpStream::from_std(stream) {
            Ok(s) => conns.serve(s),
            Err(e) => {
                conns.live.dec();
                tracing::warn!(error = %e, "cannot register a handed connection");
            }
        }
    }
    conns.drain().await;
}

/// Resolves on SIGTERM or Ctrl-C.
pub async fn shutdown_signal() {
    let ctrl_c = async {
        let _ = tokio::signal::ctrl_c().await;
    };
    #[cfg(unix)]
    let term = async {
        match tokio::signal::unix::signal(tokio::signal::unix::SignalKind::terminate()) {
            Ok(mut s) => {
                s.recv().await;
            }
            Err(_) => std::future::pending::<()>().await,
        }
    };
    #[cfg(not(unix))]
    let term = std::future::pending::<()>();
    tokio::select! {
        () = ctrl_c => {}
        () = term => {}
    }
    tracing::info!("shutdown signal received");
}
