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
//! shared [`crate::slots::Slots`].
//!
//! Shutdown stops accepting, lets requests in flight finish within the drain time, stops the
//! renders that would outlast it (their requests get 503), and exits without waiting for
//! anything past it.

use crate::api::{self, AppState};
use crate::config::ServeConfig;
use crate::store::Store;
use crate::transport::Transport;
use hyper_util::rt::{TokioExecutor, TokioTimer};
use hyper_util::server::conn::auto;
use prometheus::IntGauge;
use std::future::Future;
use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::{TcpListener, TcpStream};

/// How long shutdown waits for requests in flight before it gives up on them.
const DRAIN_TIMEOUT: Duration = Duration::from_secs(10);
/// How long before the end of the drain every render still running is stopped: time for the
/// models to reach their next band and for the 503s to be sent.
const STOP_BEFORE_END: Duration = Duration::from_secs(2);

/// `vtex serve`: [`run`] until SIGTERM or Ctrl-C. The runtime is not waited for when the
/// server is done: work still on its blocking pool then (a render that did not stop in the
/// drain time) has nobody left to answer, so the process exits within the drain time.
pub fn main(cfg: ServeConfig) -> anyhow::Result<()> {
    let rt = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
    let result = rt.block_on(run(cfg, shutdown_signal()));
    rt.shutdown_background();
    result
}

/// Runs the server until `shutdown` resolves.
pub async fn run(cfg: ServeConfig, shutdown: impl Future<Output = ()>) -> anyhow::Result<()> {
    cfg.validate().map_err(anyhow::Error::msg)?;
    let t0 = Instant::now();
    let (dir, ts, demos) = (cfg.data_dir.clone(), cfg.tile_size, !cfg.no_demos);
    let (store, report) = tokio::task::spawn_blocking(move || Store::open(&dir, ts, demos)).await??;
    for (path, why) in &report.rejected {
        tracing::warn!(path = %path.display(), reason = %why, "not serving an invalid file in the data directory");
    }
    tracing::info!(
        data_dir = %cfg.data_dir.display(),
        textures = store.len(),
        demos_written = report.demos_written,
        stale_temp_removed = report.stale_temp_removed,
        ms = t0.elapsed().as_millis() as u64,
        "store opened"
    );
    if !cfg.web_dir.join("index.html").is_file() {
        tracing::warn!(web_dir = %cfg.web_dir.display(), "no index.html in the web directory; the viewer is not served");
    }
    let app = AppState::new(Arc::new(store), cfg.clone());
    // Renders in flight at shutdown may finish during the drain; those that would outlast it
    // are stopped shortly before it ends, so their requests are answered 503 rather than cut.
    let shutdown = {
        let app = app.clone();
        async move {
            shutdown.await;
            tokio::spawn(async move {
                tokio::time::sleep(DRAIN_TIMEOUT - STOP_BEFORE_END).await;
                tracing::info!("stopping the syntheses still running");
                app.stop_syntheses();
            });
        }
    };
    let live = |i: usize| app.metrics.connections.with_label_values(&[i.to_string().as_str()]);
    let mut workers: Vec<Worker> = (0..cfg.io_threads()).map(|i| Worker { live: live(i), tx: None }).collect();
    let front = api::Front::new(app);

    let listener = TcpListener::bind(cfg.bind).await?;
    let addr = listener.local_addr()?;
    tracing::info!(%addr, cache_mb = cfg.cache_mb, syntheses = cfg.syntheses(), send = %cfg.send, "serving");
    {
        let mut out = std::io::stdout().lock();
        writeln!(out, "vtex listening on http://{addr}")?;
        out.flush()?;
    }

    // One single-threaded runtime per core, each serving its own connections (nginx's worker
    // model): no cross-thread wake-ups on the hot path. This runtime accepts and hands each
    // connection to the runtime serving the fewest (see `Worker`).
    let mut threads = Vec::new();
    for (i, worker) in workers.iter_mut().enumerate().skip(1) {
        let (tx, rx) = tokio::sync::mpsc::unbounded_channel();
        worker.tx = Some(tx);
        let (live, front, hdr, send) = (worker.live.clone(), front.clone(), cfg.header_timeout(), cfg.send);
        threads.push(std::thread::Builder::new().name(format!("vtex-io-{i}")).spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
            rt.block_on(serve_handed(rx, Conns::new(front, hdr, send, live)));
            // Drained: what its blocking pool still runs answers nobody (see `main`).
            rt.shutdown_background();
            anyhow::Ok(())
        })?);
    }
    let own = Conns::new(front, cfg.header_timeout(), cfg.send, workers[0].live.clone());
    accept_loop(listener, workers, own, shutdown).await;
    for t in threads {
        tokio::task::spawn_blocking(move || t.join())
            .await?
            .map_err(|_| anyhow::anyhow!("an I/O thread panicked"))??;
    }
    Ok(())
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
    front: api::Front,
    builder: auto::Builder<TokioExecutor>,
    send: Transport,
    graceful: hyper_util::server::graceful::GracefulShutdown,
    live: IntGauge,
}

impl Conns {
    fn new(front: api::Front, header_timeout: Duration, send: Transport, live: IntGauge) -> Conns {
        let mut builder = auto::Builder::new(TokioExecutor::new());
        builder.http1().timer(TokioTimer::new()).header_read_timeout(header_timeout);
        builder.http2().timer(TokioTimer::new());
        Conns { front, builder, send, graceful: hyper_util::server::graceful::GracefulShutdown::new(), live }
    }

    /// Serves `stream` on the current runtime until it closes; counted in `live` meanwhile
    /// (the acceptor counted it already).
    fn serve(&self, stream: TcpStream) {
        let _ = stream.set_nodelay(true);
        let conn = self.builder.serve_connection_with_upgrades(self.send.wrap(stream), self.front.clone()).into_owned();
        let conn = self.graceful.watch(conn);
        let live = LiveGuard(self.live.clone());
        tokio::spawn(async move {
            if let Err(e) = conn.await {
                tracing::debug!(error = %e, "connection ended with an error");
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

/// Uncounts a connection when its task ends or is dropped.
struct LiveGuard(IntGauge);

impl Drop for LiveGuard {
    fn drop(&mut self) {
        self.0.dec();
    }
}

/// Accepts connections until `shutdown` resolves, serving each on the runtime of `workers`
/// with the fewest live ones (`workers[0]` is this runtime: `own`); then drains this
/// runtime's connections (closing the channels tells the other runtimes to drain theirs).
async fn accept_loop(listener: TcpListener, workers: Vec<Worker>, own: Conns, shutdown: impl Future<Output = ()>) {
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
                        let sent = stream.into_std().map_err(|e| e.to_string()).and_then(|s| tx.send(s).map_err(|_| "runtime gone".into()));
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
