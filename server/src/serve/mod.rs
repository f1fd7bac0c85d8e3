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
//! (in [`crate::transport::Io`]); a connection that sends no request head within
//! `--header-timeout-secs` of its accept, or is idle for `--idle-timeout-secs`, is closed
//! ([`lifetime`]); at `--max-connections` the connection with no request in flight for longest
//! makes room for a new one, which is refused (503) only when every connection has a request in
//! flight, and `--max-connections-per-client` bounds one address's ([`admission`]).
//!
//! Shutdown stops accepting, lets requests in flight finish within the drain time, stops the
//! renders that would outlast it (their requests get 503), and exits without waiting for
//! anything past it.
//!
//! Each request of a connection ([`connection`]) has its head checked ([`head`]), then takes
//! the fast tile path ([`fast_tile`]) or the router; its access line is written once its body
//! is sent ([`access`]).

mod access;
mod admission;
mod connection;
mod cors;
mod fast_tile;
mod head;
mod lifetime;

use crate::api::state::AppState;
use crate::config::ServeConfig;
use crate::store::{Bundles, Location, ObjectBundles, OpenReport, Store};
use crate::transport::{InputProbe, SendLimits, Transport};
use crate::watch::Watch;
use admission::{Admission, Refusal, Ticket, Verdict};
use connection::Front;
use head::MAX_HEAD_BYTES;
use hyper_util::rt::{TokioExecutor, TokioTimer};
use hyper_util::server::conn::auto;
use prometheus::IntGauge;
use std::future::Future;
use std::io::Write;
use std::net::SocketAddr;
use std::path::Path;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::{TcpListener, TcpStream};
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
    let opening = cfg.clone();
    let (store, report, follow) = tokio::task::spawn_blocking(move || open_store(&opening)).await??;
    for (at, why) in &report.rejected {
        tracing::warn!(%at, reason = %why, "not serving an invalid bundle of the store");
    }
    for (path, why) in &report.stale_temp_kept {
        tracing::warn!(path = %path.display(), reason = %why, "could not remove a stale temporary file; left in place");
    }
    for (name, why) in &report.demos_refused {
        tracing::warn!(demo = %name, reason = %why, "demo not written: over the store's bounds");
    }
    tracing::info!(
        store = %store.bundles(),
        textures = store.len(),
        demos_written = report.demos_written,
        stale_temp_removed = report.stale_temp_removed,
        follow = %follow,
        ms = t0.elapsed().as_millis() as u64,
        "store opened"
    );
    match follow {
        Follow::Watch(Some(watch)) => watch.follow(store.clone())?,
        Follow::Watch(None) => {}
        Follow::Poll(every) => crate::watch::poll(store.clone(), every)?,
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
    let per_client = cfg.max_connections_per_client;
    let admission = Admission::new(max_connections, per_client, app.metrics.connections_evicted.clone());
    let refusal = Refusal::new(max_connections, per_client, app.metrics.connections_refused.clone());
    let front = Front::new(app);

    let addr = listener.local_addr()?;
    tracing::info!(
        %addr,
        cache_mb = cfg.cache_mb,
        syntheses = cfg.syntheses(),
        send = %cfg.send,
        max_connections,
        max_connections_per_client = per_client,
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
    accept_loop(listener, workers, own, (admission, refusal), shutdown).await;
    for t in threads {
        tokio::task::spawn_blocking(move || t.join())
            .await?
            .map_err(|_| anyhow::anyhow!("an I/O thread panicked"))??;
    }
    Ok(())
}

/// How the store follows what other processes store and delete.
enum Follow {
    /// The data directory's watch (`None`: `--watch off`).
    Watch(Option<Watch>),
    /// The object store's listing, this often.
    Poll(Duration),
}

impl std::fmt::Display for Follow {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Follow::Watch(watch) => f.write_str(watch.as_ref().map_or("off", |w| w.how)),
            Follow::Poll(every) => write!(f, "listing every {} s", every.as_secs_f64()),
        }
    }
}

/// Opens the store `cfg` names, and how it follows other processes: checks the data
/// directory (the bundles' or the local copies'), then indexes the bundles and writes the
/// demos. Blocking.
fn open_store(cfg: &ServeConfig) -> anyhow::Result<(Arc<Store>, OpenReport, Follow)> {
    let write = !cfg.read_only;
    let demos = write && !cfg.no_demos;
    let resources = Resources::new(cfg.synth_cache_bytes());
    let mut report = OpenReport::default();
    let (store, follow) = match cfg.location() {
        Location::S3 { bucket, prefix } => {
            let settings = cfg.object_settings(bucket, prefix);
            // The local copies are written whatever `--read-only` says.
            check_data_dir(&settings.cache_dir, true)?;
            let bundles = ObjectBundles::open(&settings).map_err(anyhow::Error::msg)?;
            let url = bundles.url().to_string();
            let store =
                Store::open_in(Bundles::Object(Box::new(bundles)), cfg.store_bounds(), resources, demos, &mut report)
                    .map_err(|e| anyhow::anyhow!("cannot open the object store {url}: {e}"))?;
            (store, Follow::Poll(cfg.store_poll()))
        }
        Location::Dir(dir) => {
            check_data_dir(&dir, write)?;
            // The watch starts before the store lists the directory, so nothing added meanwhile is missed.
            let watch = Watch::start(&dir, cfg.watch).map_err(anyhow::Error::msg)?;
            let (store, opened) = Store::open(&dir, cfg.store_bounds(), resources, demos)
                .map_err(|e| anyhow::anyhow!("cannot open data directory {}: {}", dir.display(), io_message(&e)))?;
            report = opened;
            (store, Follow::Watch(watch))
        }
    };
    Ok((Arc::new(store), report, follow))
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
    tx: Option<tokio::sync::mpsc::UnboundedSender<Handed>>,
}

/// A connection handed to another runtime, with its slot.
type Handed = (std::net::TcpStream, Ticket);

/// How one runtime serves its connections: hyper's settings, graceful shutdown, and the count
/// of connections it serves (shared with the acceptor).
struct Conns {
    front: Front,
    builder: auto::Builder<TokioExecutor>,
    send: Transport,
    send_limits: SendLimits,
    header_timeout: Duration,
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
            header_timeout: cfg.header_timeout(),
            idle_timeout: cfg.idle_timeout(),
            graceful: hyper_util::server::graceful::GracefulShutdown::new(),
            live,
        }
    }

    /// Serves `stream` on the current runtime until it closes or is closed with no request in
    /// flight ([`lifetime`]); counted in `live` meanwhile (the acceptor counted it already).
    fn serve(&self, stream: TcpStream, ticket: Ticket) {
        let _ = stream.set_nodelay(true);
        // A socket already closed has no peer: unspecified, so never taken for loopback.
        let peer = stream.peer_addr().unwrap_or_else(|_| SocketAddr::from(([0, 0, 0, 0], 0)));
        let activity = ticket.activity().clone();
        let socket = InputProbe::of(&stream);
        let io = self.send.wrap(stream, activity.clone(), self.send_limits);
        let service = self.front.connection(activity, peer);
        let conn = self.builder.serve_connection_with_upgrades(io, service).into_owned();
        let conn = self.graceful.watch(conn);
        let live = LiveGuard(self.live.clone());
        let (header_timeout, idle) = (self.header_timeout, self.idle_timeout);
        tokio::spawn(async move {
            // Dropping the connection when it is closable loses nothing: no request is in flight.
            // The connection is polled first, so a request whose head has arrived starts (and
            // keeps the connection open) before the connection is judged closable.
            tokio::select! {
                biased;
                ended = conn => if let Err(e) = ended {
                    tracing::debug!(error = %e, "connection ended with an error");
                },
                why = lifetime::until_closable(&ticket, socket, header_timeout, idle) => {
                    tracing::debug!(reason = why, "closed a connection with no request in flight");
                }
            }
            drop((live, ticket));
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

/// Uncounts a connection when its task ends or is dropped.
struct LiveGuard(IntGauge);

impl Drop for LiveGuard {
    fn drop(&mut self) {
        self.0.dec();
    }
}

/// Accepts connections until `shutdown` resolves, serving each on the runtime of `workers`
/// with the fewest live ones (`workers[0]` is this runtime: `own`) once admitted, or refusing
/// it; then drains this runtime's connections (closing the channels tells the other runtimes to
/// drain theirs).
async fn accept_loop(
    listener: TcpListener,
    workers: Vec<Worker>,
    own: Conns,
    (admission, refusal): (Arc<Admission>, Refusal),
    shutdown: impl Future<Output = ()>,
) {
    let mut next = 0;
    tokio::pin!(shutdown);
    loop {
        tokio::select! {
            accepted = listener.accept() => {
                let (stream, peer) = match accepted {
                    Ok(c) => c,
                    Err(e) => {
                        // Out of file descriptors and the like: back off instead of spinning.
                        tracing::warn!(error = %e, "accept failed");
                        tokio::time::sleep(Duration::from_millis(50)).await;
                        continue;
                    }
                };
                let ticket = match admission.admit(peer.ip()).await {
                    Verdict::Admitted(ticket) => ticket,
                    refused => {
                        refusal.refuse(stream, &refused);
                        continue;
                    }
                };
                // The least-loaded runtime; ties go round-robin.
                let n = workers.len();
                let k = (0..n).map(|i| (next + i) % n).min_by_key(|&k| workers[k].live.get()).unwrap_or(0);
                next = (k + 1) % n;
                let w = &workers[k];
                w.live.inc();
                match &w.tx {
                    None => own.serve(stream, ticket),
                    Some(tx) => {
                        // Deregistered here, registered again on the receiving runtime.
                        let sent = stream
                            .into_std()
                            .map_err(|e| e.to_string())
                            .and_then(|s| tx.send((s, ticket)).map_err(|_| "runtime gone".into()));
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
async fn serve_handed(mut rx: tokio::sync::mpsc::UnboundedReceiver<Handed>, conns: Conns) {
    while let Some((stream, ticket)) = rx.recv().await {
        match TcpStream::from_std(stream) {
            Ok(s) => conns.serve(s, ticket),
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
