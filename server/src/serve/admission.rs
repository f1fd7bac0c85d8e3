//! Who holds the server's connections: at most `--max-connections` at once and, when
//! `--max-connections-per-client` is set, that many from one address.
//!
//! At the limit, the connection with no request in flight for longest — one that never sent a
//! request head, or a keep-alive between requests — is closed to admit the new one, as nginx
//! closes its idle keep-alive connections when it runs out of them: a connection that sends
//! nothing cannot then hold a slot a client needs. Only when every connection has a request in
//! flight is the new one refused (503). Over its address's limit a connection is refused (429).
//! A refusal is a complete answer, then a close ([`Refusal`]).

use crate::transport::{Activity, InputProbe};
use prometheus::{IntCounter, IntCounterVec};
use std::collections::HashMap;
use std::net::IpAddr;
use std::sync::{Arc, Mutex};
use std::time::Duration;
use tokio::io::{AsyncReadExt, AsyncWriteExt};
use tokio::net::TcpStream;
use tokio::sync::{Notify, Semaphore};
use tokio::time::Instant;

/// How long the acceptor waits for a connection asked to make room to close (one hop to the
/// runtime serving it, unless that runtime is stalled) before refusing the new one.
const EVICTION_WAIT: Duration = Duration::from_millis(250);

/// The open connections, shared by the acceptor and the runtimes serving them.
pub struct Admission {
    max: usize,
    per_client: Option<usize>,
    open: Mutex<Open>,
    /// Woken whenever a connection closes, or declines to (a request started on it meanwhile).
    changed: Notify,
    evicted: IntCounter,
}

#[derive(Default)]
struct Open {
    next_id: u64,
    conns: HashMap<u64, Slot>,
    by_client: HashMap<IpAddr, usize>,
    /// The connection asked to close to make room, until it closes or declines.
    evicting: Option<u64>,
}

struct Slot {
    client: IpAddr,
    activity: Arc<Activity>,
    evict: Arc<Notify>,
}

/// The acceptor's decision on a new connection.
pub enum Verdict {
    Admitted(Ticket),
    /// At `--max-connections`, every connection with a request in flight.
    Full,
    /// At `--max-connections-per-client` for its address.
    ClientFull,
}

/// What one attempt to admit found, under the lock.
enum Attempt {
    Decided(Verdict),
    /// A connection was asked to make room: wait until it closes or declines.
    Wait,
}

impl Admission {
    pub fn new(max: usize, per_client: Option<usize>, evicted: IntCounter) -> Arc<Admission> {
        let open = Mutex::new(Open::default());
        Arc::new(Admission { max, per_client, open, changed: Notify::new(), evicted })
    }

    /// Admits a connection from `client`, closing the one quiet longest when at the limit.
    pub async fn admit(self: &Arc<Self>, client: IpAddr) -> Verdict {
        loop {
            let changed = self.changed.notified();
            tokio::pin!(changed);
            changed.as_mut().enable();
            match self.attempt(client) {
                Attempt::Decided(verdict) => return verdict,
                Attempt::Wait => {
                    if tokio::time::timeout(EVICTION_WAIT, changed).await.is_err() {
                        return Verdict::Full;
                    }
                }
            }
        }
    }

    fn attempt(self: &Arc<Self>, client: IpAddr) -> Attempt {
        let mut open = self.open.lock().unwrap_or_else(|e| e.into_inner());
        let from_client = open.by_client.get(&client).copied().unwrap_or(0);
        if self.per_client.is_some_and(|limit| from_client >= limit) {
            return Attempt::Decided(Verdict::ClientFull);
        }
        if open.conns.len() < self.max {
            return Attempt::Decided(Verdict::Admitted(self.insert(&mut open, client)));
        }
        if open.evicting.is_some() {
            return Attempt::Wait;
        }
        let quietest = open
            .conns
            .iter()
            .filter(|(_, slot)| slot.activity.closable())
            .min_by_key(|(_, slot)| slot.activity.quiet_since());
        match quietest {
            None => Attempt::Decided(Verdict::Full),
            Some((&id, slot)) => {
                slot.evict.notify_one();
                open.evicting = Some(id);
                Attempt::Wait
            }
        }
    }

    fn insert(self: &Arc<Self>, open: &mut Open, client: IpAddr) -> Ticket {
        let (id, activity, evict) = (open.next_id, Arc::new(Activity::default()), Arc::new(Notify::new()));
        open.next_id += 1;
        let slot = Slot { client, activity: activity.clone(), evict: evict.clone() };
        open.conns.insert(id, slot);
        *open.by_client.entry(client).or_default() += 1;
        Ticket { admission: self.clone(), id, activity, evict, accepted: Instant::now() }
    }

    /// Forgets `id`'s request to close, when it has one.
    fn settle(&self, open: &mut Open, id: u64) {
        if open.evicting == Some(id) {
            open.evicting = None;
        }
    }
}

/// A connection's slot among the open ones, and what it counts; the slot is freed when the
/// ticket drops.
pub struct Ticket {
    admission: Arc<Admission>,
    id: u64,
    activity: Arc<Activity>,
    evict: Arc<Notify>,
    accepted: Instant,
}

impl Ticket {
    /// When the connection was admitted, just after its accept.
    pub fn accepted(&self) -> Instant {
        self.accepted
    }

    /// The connection's activity, which its timeouts and the choice of whom to evict read.
    pub fn activity(&self) -> &Arc<Activity> {
        &self.activity
    }

    /// Resolves when the acceptor asks this connection to make room and no request is in flight
    /// on it: it is then closed without losing anything. A request started since it was chosen
    /// keeps it open; the acceptor then chooses again.
    ///
    /// Its connection must be polled before it (a biased `select!`): the yield lets the runtime
    /// read the socket's readiness first, so a request whose head has already arrived starts
    /// before the check rather than being lost with the connection; bytes that arrived but are
    /// not yet seen (`socket`) keep it open too.
    pub async fn evicted(&self, socket: InputProbe) {
        loop {
            self.evict.notified().await;
            tokio::task::yield_now().await;
            if self.activity.closable() && !socket.input_waiting() {
                self.admission.evicted.inc();
                return;
            }
            let mut open = self.admission.open.lock().unwrap_or_else(|e| e.into_inner());
            self.admission.settle(&mut open, self.id);
            drop(open);
            self.admission.changed.notify_waiters();
        }
    }
}

impl Drop for Ticket {
    fn drop(&mut self) {
        let mut open = self.admission.open.lock().unwrap_or_else(|e| e.into_inner());
        if let Some(slot) = open.conns.remove(&self.id) {
            if let Some(n) = open.by_client.get_mut(&slot.client) {
                *n -= 1;
                if *n == 0 {
                    open.by_client.remove(&slot.client);
                }
            }
        }
        self.admission.settle(&mut open, self.id);
        drop(open);
        self.admission.changed.notify_waiters();
    }
}

/// How a connection turned away at a limit is answered: a complete response naming the limit,
/// then a close — a clear answer where waiting in the backlog or a reset would tell the client
/// nothing.
pub struct Refusal {
    full: bytes::Bytes,
    client_full: bytes::Bytes,
    /// Refusals being answered at once; each holds a descriptor from [`FD_RESERVE`].
    ///
    /// [`FD_RESERVE`]: crate::config::FD_RESERVE
    answering: Arc<Semaphore>,
    refused: IntCounterVec,
}

/// Refusals answered at once, their descriptors taken from the reserve; beyond it a refusal
/// writes what the socket takes at once and closes.
const REFUSALS_AT_ONCE: usize = 16;
/// How long a refusal may take, waiting for the client to read it and close.
const REFUSAL_TIME: Duration = Duration::from_secs(2);
/// Most request bytes a refusal reads (and discards) while it waits for the client to close.
const REFUSAL_DRAIN_BYTES: usize = 64 * 1024;

/// The `limit` label of [`Refusal`]'s counter for each verdict.
const FULL: &str = "max-connections";
const CLIENT_FULL: &str = "max-connections-per-client";

impl Refusal {
    pub fn new(max: usize, per_client: Option<usize>, refused: IntCounterVec) -> Refusal {
        for limit in [FULL, CLIENT_FULL] {
            refused.with_label_values(&[limit]);
        }
        let full = answer(
            "503 Service Unavailable",
            &format!(
                "the server is serving its limit of {max} connections, each with a request in flight; retry later"
            ),
        );
        let client_full = answer(
            "429 Too Many Requests",
            &format!(
                "this client address has its limit of {} connections open (--max-connections-per-client); \
                 reuse them, or retry once one closes",
                per_client.unwrap_or(0)
            ),
        );
        let answering = Arc::new(Semaphore::new(REFUSALS_AT_ONCE));
        Refusal { full, client_full, answering, refused }
    }

    /// Answers `stream` for `verdict` and closes it, on the current runtime.
    pub fn refuse(&self, mut stream: TcpStream, verdict: &Verdict) {
        let (answer, limit) = match verdict {
            Verdict::ClientFull => (self.client_full.clone(), CLIENT_FULL),
            _ => (self.full.clone(), FULL),
        };
        self.refused.with_label_values(&[limit]).inc();
        let Ok(permit) = self.answering.clone().try_acquire_owned() else {
            let _ = stream.try_write(&answer);
            return;
        };
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

/// A complete HTTP/1.1 response of `status` with a JSON error body saying `why`, closing.
fn answer(status: &str, why: &str) -> bytes::Bytes {
    let body = serde_json::json!({ "error": why }).to_string();
    format!(
        "HTTP/1.1 {status}\r\ncontent-type: application/json\r\ncontent-length: {}\r\n\
         retry-after: 1\r\nconnection: close\r\naccess-control-allow-origin: *\r\n\r\n{body}",
        body.len()
    )
    .into()
}
