//! The directory watch: tells the store of bundles that other processes sharing the data
//! directory (replicas, an operator copying files in) add or delete, so that the texture list
//! of every replica follows the directory; and its counterpart for an object store, a poll
//! ([`poll`]). Lookups by id do not wait for either: the store also looks on a miss
//! ([`crate::store::Store::find`]).

use crate::store::Store;
use notify::{Event, PollWatcher, RecommendedWatcher, RecursiveMode, Watcher};
use std::path::Path;
use std::sync::mpsc::{channel, Receiver};
use std::sync::Arc;
use std::time::Duration;

/// How often the polling watch lists the directory.
pub const POLL_INTERVAL: Duration = Duration::from_secs(2);

/// How the store follows changes other processes make to the data directory (`--watch`).
#[derive(Clone, Copy, Debug, PartialEq, Eq, clap::ValueEnum)]
pub enum WatchMode {
    /// Kernel events (inotify), else polling when they cannot be had.
    Events,
    /// Lists the directory every [`POLL_INTERVAL`]: for filesystems without events (NFS).
    #[value(
        help = format!("Lists the directory every {} s: for filesystems without events (NFS)", POLL_INTERVAL.as_secs()),
    )]
    Poll,
    /// No watch: a new bundle is found when its id is first asked for; the list does not follow.
    Off,
}

impl std::fmt::Display for WatchMode {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            WatchMode::Events => "events",
            WatchMode::Poll => "poll",
            WatchMode::Off => "off",
        })
    }
}

/// A watch of the data directory whose events wait until [`Watch::follow`] hands them to the
/// store. It is started before the store lists the directory, so that nothing added between
/// that listing and the store being ready is missed.
pub struct Watch {
    _watcher: Box<dyn Watcher + Send>,
    events: Receiver<notify::Result<Event>>,
    pub how: &'static str,
}

impl Watch {
    /// Watches `dir` (which must exist) as `mode` says; `None` for [`WatchMode::Off`].
    pub fn start(dir: &Path, mode: WatchMode) -> notify::Result<Option<Watch>> {
        let (tx, events) = channel();
        let poll = |tx| PollWatcher::new(tx, notify::Config::default().with_poll_interval(POLL_INTERVAL));
        let (mut watcher, how): (Box<dyn Watcher + Send>, _) = match mode {
            WatchMode::Off => return Ok(None),
            WatchMode::Events => match RecommendedWatcher::new(tx.clone(), notify::Config::default()) {
                Ok(w) => (Box::new(w), "events"),
                Err(e) => {
                    tracing::warn!(error = %e, "no file-system events for the data directory; polling it instead");
                    (Box::new(poll(tx)?), "poll")
                }
            },
            WatchMode::Poll => (Box::new(poll(tx)?), "poll"),
        };
        watcher.watch(dir, RecursiveMode::NonRecursive)?;
        Ok(Some(Watch { _watcher: watcher, events, how }))
    }

    /// Hands every event, from now on and those already waiting, to `store` on a thread of its
    /// own, for as long as the process lives.
    pub fn follow(self, store: Arc<Store>) -> std::io::Result<()> {
        std::thread::Builder::new().name("vtex-watch".into()).spawn(move || {
            let _watcher = self._watcher;
            for event in self.events {
                match event {
                    Ok(event) if !event.need_rescan() => {
                        for path in &event.paths {
                            store.refresh(path);
                        }
                    }
                    Ok(_) | Err(_) => {
                        // Events were lost (a queue overflow) or the watch failed: list again.
                        if let Err(e) = store.rescan() {
                            tracing::warn!(error = %e, "listing the data directory again failed");
                        }
                    }
                }
            }
        })?;
        Ok(())
    }
}

/// Lists the object store every `every` on a thread of its own, for as long as the process
/// lives, so that the texture list follows what other replicas store and delete. A listing
/// that fails leaves the list as it was.
pub fn poll(store: Arc<Store>, every: Duration) -> std::io::Result<()> {
    std::thread::Builder::new().name("vtex-store-poll".into()).spawn(move || loop {
        std::thread::sleep(every);
        if let Err(e) = store.rescan() {
            tracing::debug!(error = %e, "listing the object store failed");
        }
    })?;
    Ok(())
}
