//! `vtex serve`: opens the store, binds, and serves connections until SIGTERM or Ctrl-C.
//!
//! The accept loop is hyper's own (rather than `axum::serve`) so that a client that never
//! finishes its request headers is cut off after `--header-timeout-secs`, and so that
//! shutdown stops accepting, lets requests in flight finish, then exits.
//!
//! Connections are served by one single-threaded tokio runtime per core, all accepting from
//! the same socket, each serving the connections it accepted (nginx's worker model). With one
//! work-stealing runtime instead, a warm tile cost more CPU and waited on cross-thread
//! wake-ups (BENCHMARKS.md). Syntheses still run on blocking pools, bounded by one semaphore.

use crate::api::{self, AppState};
use crate::config::ServeConfig;
use crate::store::Store;
use crate::zerocopy::SpliceIo;
use hyper_util::rt::{TokioExecutor, TokioTimer};
use hyper_util::server::conn::auto;
use std::future::Future;
use std::io::Write;
use std::sync::Arc;
use std::time::{Duration, Instant};
use tokio::net::TcpListener;

/// How long shutdown waits for requests in flight before it gives up on them.
const DRAIN_TIMEOUT: Duration = Duration::from_secs(10);

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
    let front = api::Front::new(app);

    let listener = TcpListener::bind(cfg.bind).await?;
    let addr = listener.local_addr()?;
    {
        let mut out = std::io::stdout().lock();
        writeln!(out, "vtex listening on http://{addr}")?;
        out.flush()?;
    }
    tracing::info!(%addr, cache_mb = cfg.cache_mb, syntheses = cfg.syntheses(), "serving");

    // One single-threaded runtime per core, each accepting from the same socket and serving
    // its own connections (nginx's worker model): no cross-thread wake-ups on the hot path.
    let (stop_tx, stop_rx) = tokio::sync::watch::channel(false);
    let listener = listener.into_std()?;
    let mut threads = Vec::new();
    for i in 1..cfg.io_threads() {
        let (l, front, rx, hdr) = (listener.try_clone()?, front.clone(), stop_rx.clone(), cfg.header_timeout());
        threads.push(std::thread::Builder::new().name(format!("vtex-io-{i}")).spawn(move || {
            let rt = tokio::runtime::Builder::new_current_thread().enable_all().build()?;
            rt.block_on(async move {
                let l = TcpListener::from_std(l)?;
                accept_loop(l, front, hdr, stopped(rx)).await;
                anyhow::Ok(())
            })
        })?);
    }
    let stop = async move {
        shutdown.await;
        let _ = stop_tx.send(true);
    };
    accept_loop(TcpListener::from_std(listener)?, front, cfg.header_timeout(), stop).await;
    for t in threads {
        tokio::task::spawn_blocking(move || t.join())
            .await?
            .map_err(|_| anyhow::anyhow!("an I/O thread panicked"))??;
    }
    Ok(())
}

async fn stopped(mut rx: tokio::sync::watch::Receiver<bool>) {
    let _ = rx.wait_for(|stop| *stop).await;
}

/// Accepts and serves connections until `shutdown` resolves, then drains them.
async fn accept_loop(
    listener: TcpListener,
    front: api::Front,
    header_timeout: Duration,
    shutdown: impl Future<Output = ()>,
) {
    let mut builder = auto::Builder::new(TokioExecutor::new());
    builder.http1().timer(TokioTimer::new()).header_read_timeout(header_timeout);
    builder.http2().timer(TokioTimer::new());
    let graceful = hyper_util::server::graceful::GracefulShutdown::new();
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
                let _ = stream.set_nodelay(true);
                let conn = builder.serve_connection_with_upgrades(SpliceIo::new(stream), front.clone()).into_owned();
                let conn = graceful.watch(conn);
                tokio::spawn(async move {
                    if let Err(e) = conn.await {
                        tracing::debug!(error = %e, "connection ended with an error");
                    }
                });
            }
            () = &mut shutdown => break,
        }
    }
    drop(listener);
    tracing::info!("shutting down: draining requests in flight");
    tokio::select! {
        () = graceful.shutdown() => tracing::info!("all connections closed"),
        () = tokio::time::sleep(DRAIN_TIMEOUT) => tracing::warn!("drain timed out; exiting with connections open"),
    }
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
