//! The budget of bodies in flight: memory the server builds for an answer and that no other
//! budget counts — a region's pixels and encoding while it renders and its body until it is
//! sent, a downloaded bundle, a tile batch's frames — and the body of an upload while it is read
//! and stored (its declared length, or `--max-upload-mb` when it declares none).
//!
//! Why: synthesis slots bound how many renders run at once, but a finished body waits for its
//! reader, so without a budget many slow readers of large regions hold many bodies. A response
//! reserves its bytes before it builds anything ([`Inflight::reserve`]); when the budget is spent
//! it is answered `503` at once. Cached tiles are not charged: their bodies are the tile
//! cache's, which counts them under `--cache-mb`, and a response sends them without a copy.
//!
//! A reservation is a semaphore permit of whole KiB. Put into the body it pays for
//! ([`Reservation::hold`]), it is returned when the last reference to the body drops: sent, or
//! dropped with its connection (a send timeout, a reader below the minimum send rate).

use crate::api::error::ApiError;
use bytes::Bytes;
use std::sync::Arc;
use tokio::sync::{OwnedSemaphorePermit, Semaphore};

const KIB: u64 = 1024;

/// The shared budget (`--inflight-mb`).
pub struct Inflight {
    permits: Arc<Semaphore>,
    budget_kib: u32,
}

/// Bytes reserved from an [`Inflight`] budget; returned when dropped.
pub struct Reservation(OwnedSemaphorePermit);

/// KiB that hold `bytes`.
fn kib(bytes: u64) -> u32 {
    u32::try_from(bytes.div_ceil(KIB)).unwrap_or(u32::MAX)
}

impl Inflight {
    /// A budget of `bytes` (rounded up to whole KiB).
    pub fn new(bytes: u64) -> Inflight {
        let budget_kib = kib(bytes);
        Inflight { permits: Arc::new(Semaphore::new(budget_kib as usize)), budget_kib }
    }

    pub fn budget_bytes(&self) -> u64 {
        self.budget_kib as u64 * KIB
    }

    /// Bytes reserved now.
    pub fn reserved_bytes(&self) -> u64 {
        (self.budget_kib as u64 - self.permits.available_permits() as u64) * KIB
    }

    /// Reserves `bytes`, or answers the `503` of a spent budget — or a `400` when the whole
    /// budget could never hold them (a large region in a format whose encoder holds several
    /// copies of it), which no retry would change.
    pub fn reserve(&self, bytes: u64) -> Result<Reservation, ApiError> {
        if kib(bytes) > self.budget_kib {
            return Err(ApiError::bad_request(format!(
                "this response holds up to {:.1} MiB while it is made, more than the whole budget of bodies in \
                 flight (--inflight-mb, {} MiB): ask for a smaller one",
                bytes as f64 / (1 << 20) as f64,
                self.budget_kib / 1024
            )));
        }
        self.permits.clone().try_acquire_many_owned(kib(bytes)).map(Reservation).map_err(|_| self.spent())
    }

    /// The answer when the budget cannot hold a response.
    fn spent(&self) -> ApiError {
        ApiError::Unavailable(format!(
            "the budget of bodies in flight (--inflight-mb, {} MiB) is spent; retry shortly",
            self.budget_kib / 1024
        ))
    }

    /// Resizes `r` to `bytes`: a shrink always succeeds, growing needs the budget.
    pub fn resize(&self, r: &mut Reservation, bytes: u64) -> Result<(), ApiError> {
        let (now, want) = (r.0.num_permits(), kib(bytes) as usize);
        if want < now {
            drop(r.0.split(now - want));
        } else if want > now {
            let more = self.permits.clone().try_acquire_many_owned((want - now) as u32).map_err(|_| self.spent())?;
            r.0.merge(more);
        }
        Ok(())
    }
}

impl Reservation {
    /// `body` as a response body that keeps this reservation until its last reference drops.
    pub fn hold(self, body: Vec<u8>) -> Bytes {
        Bytes::from_owner(Held { body, _reservation: self })
    }
}

/// A body and the reservation that pays for it.
struct Held {
    body: Vec<u8>,
    _reservation: Reservation,
}

impl AsRef<[u8]> for Held {
    fn as_ref(&self) -> &[u8] {
        &self.body
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reservations_are_returned_when_their_bodies_drop() {
        let budget = Inflight::new(10 * KIB);
        let a = budget.reserve(4 * KIB).unwrap();
        let b = budget.reserve(4 * KIB + 1).unwrap();
        assert_eq!(budget.reserved_bytes(), 9 * KIB, "whole KiB");
        let refused = budget.reserve(2 * KIB).err().expect("the budget is spent");
        assert_eq!(refused.status(), axum::http::StatusCode::SERVICE_UNAVAILABLE);
        assert!(refused.to_string().contains("--inflight-mb"), "{refused}");
        drop(a);
        let body = b.hold(vec![7; 4000]);
        let sent = body.slice(10..20);
        drop(body);
        assert_eq!(budget.reserved_bytes(), 5 * KIB, "a slice still holds the body");
        drop(sent);
        assert_eq!(budget.reserved_bytes(), 0);
    }

    #[test]
    fn resizing_shrinks_freely_and_grows_within_the_budget() {
        let budget = Inflight::new(8 * KIB);
        let mut r = budget.reserve(6 * KIB).unwrap();
        budget.resize(&mut r, 2 * KIB).unwrap();
        assert_eq!(budget.reserved_bytes(), 2 * KIB);
        budget.resize(&mut r, 8 * KIB).unwrap();
        assert_eq!(budget.reserved_bytes(), 8 * KIB);
        let _other = {
            budget.resize(&mut r, KIB).unwrap();
            budget.reserve(7 * KIB).unwrap()
        };
        assert!(budget.resize(&mut r, 2 * KIB).is_err(), "growing past the budget is refused");
        assert_eq!(budget.reserved_bytes(), 8 * KIB, "and keeps what it had");
    }
}
