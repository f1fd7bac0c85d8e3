//! When a connection with no request in flight is closed — which loses nothing — whatever
//! protocol it speaks:
//!
//! * no request head within `--header-timeout-secs` of its accept: a socket that stays silent,
//!   sends a head a byte at a time, or sends HTTP/2's preface and nothing more. hyper's own
//!   header timeout starts only once the protocol is known (at the first bytes), and covers
//!   HTTP/1.1 alone; it still bounds each later head of a keep-alive connection, from the
//!   previous response;
//! * no byte moved for `--idle-timeout-secs` ([`until_idle`]);
//! * chosen to make room for a new connection at the limit ([`Ticket::evicted`]).

use super::admission::Ticket;
use crate::transport::{Activity, InputProbe};
use std::time::Duration;
use tokio::time::Instant;

/// Resolves, naming why, once the connection of `ticket` is to be closed.
pub async fn until_closable(
    ticket: &Ticket,
    socket: InputProbe,
    header_timeout: Duration,
    idle: Duration,
) -> &'static str {
    let activity = ticket.activity();
    tokio::select! {
        () = no_head_by(activity, ticket.accepted() + header_timeout) => "no request head within the header timeout of its accept",
        () = until_idle(activity, idle) => "idle",
        () = ticket.evicted(socket) => "closed to admit a new connection at the connection limit",
    }
}

/// Resolves at `deadline` if no request started on the connection by then; never otherwise.
async fn no_head_by(activity: &Activity, deadline: Instant) {
    tokio::time::sleep_until(deadline).await;
    if activity.started() > 0 {
        std::future::pending::<()>().await;
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
        if now != seen || !activity.closable() {
            (seen, quiet) = (now, 0);
        } else {
            quiet += 1;
            if quiet == SAMPLES {
                return;
            }
        }
    }
}
