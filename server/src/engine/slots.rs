//! Synthesis slots shared fairly between textures.
//!
//! There are `--max-syntheses` slots. A miss that finds none free waits in the queue of its
//! texture; a slot that frees goes to the waiting texture holding the fewest slots (ties: the
//! one whose first waiter came first), so a texture with many misses cannot starve one with a
//! few. One texture holds at most `--max-syntheses-per-texture` slots (all but one by
//! default): however slow its renders, another texture's miss finds a slot.
//!
//! The queue is bounded (`--max-queued`): a miss that would make it longer is refused at once
//! ([`Refused::Full`]) rather than left to wait past its deadline. When the queue is full the
//! texture with the most waiters gives up its newest one, so one texture flooding the server
//! sheds its own misses, not everyone's.
//!
//! Waiting is cancel-safe: a waiter dropped while queued leaves the queue, and one dropped just
//! after it was granted a slot hands the slot on.

use std::collections::{HashMap, VecDeque};
use std::sync::{Arc, Mutex};
use tokio::sync::oneshot;

/// What slots are shared by: the texture a synthesis renders.
pub type Texture = [u8; 32];

/// Why a miss got no slot.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Refused {
    /// The queue was full.
    Full,
    /// The server is shutting down.
    Closed,
}

/// The slots and their queues. [`Slots::acquire`] is the only way in.
pub struct Slots {
    state: Mutex<State>,
    per_texture: usize,
    max_queued: usize,
}

struct State {
    free: usize,
    closed: bool,
    /// Slots held, by texture (textures holding none are absent).
    running: HashMap<Texture, usize>,
    /// Waiters, by texture, oldest first (empty queues are removed).
    queues: HashMap<Texture, VecDeque<Waiter>>,
    queued: usize,
    next_seq: u64,
}

struct Waiter {
    seq: u64,
    wake: oneshot::Sender<Result<(), Refused>>,
}

/// A slot held; dropping it frees the slot.
pub struct Slot {
    slots: Arc<Slots>,
    texture: Texture,
}

impl Drop for Slot {
    fn drop(&mut self) {
        self.slots.state.lock().unwrap().release(self.texture, self.slots.per_texture);
    }
}

/// A waiter's place in the queue, while its future is alive.
struct Queued<'a> {
    slots: &'a Arc<Slots>,
    texture: Texture,
    seq: u64,
    rx: oneshot::Receiver<Result<(), Refused>>,
    /// The answer was received: the queue no longer holds this waiter.
    answered: bool,
}

impl Drop for Queued<'_> {
    fn drop(&mut self) {
        if self.answered {
            return;
        }
        // Granting and refusing happen under this lock, so what the channel holds is final.
        let mut st = self.slots.state.lock().unwrap();
        match self.rx.try_recv() {
            // Granted, but nobody will use it.
            Ok(Ok(())) => st.release(self.texture, self.slots.per_texture),
            Ok(Err(_)) | Err(oneshot::error::TryRecvError::Closed) => {}
            Err(oneshot::error::TryRecvError::Empty) => st.leave(self.texture, self.seq),
        }
    }
}

impl Slots {
    /// `slots` slots, at most `per_texture` of them held by one texture, at most `max_queued`
    /// misses waiting.
    pub fn new(slots: usize, per_texture: usize, max_queued: usize) -> Arc<Slots> {
        assert!(slots > 0 && per_texture > 0, "there is at least one slot, and a texture may hold one");
        let state = State {
            free: slots,
            closed: false,
            running: HashMap::new(),
            queues: HashMap::new(),
            queued: 0,
            next_seq: 0,
        };
        Arc::new(Slots { state: Mutex::new(state), per_texture: per_texture.min(slots), max_queued })
    }

    /// A slot for a synthesis of `texture`: at once when one is free for it, else after
    /// waiting its turn; refused when the queue is full or the slots are closed.
    pub async fn acquire(self: &Arc<Self>, texture: Texture) -> Result<Slot, Refused> {
        let (seq, rx) = {
            let mut st = self.state.lock().unwrap();
            if st.closed {
                return Err(Refused::Closed);
            }
            let (tx, rx) = oneshot::channel();
            let seq = st.next_seq;
            st.next_seq += 1;
            st.queues.entry(texture).or_default().push_back(Waiter { seq, wake: tx });
            st.queued += 1;
            st.dispatch(self.per_texture);
            if st.queued > self.max_queued {
                st.shed();
            }
            (seq, rx)
        };
        let mut queued = Queued { slots: self, texture, seq, rx, answered: false };
        // Senders are never dropped unanswered; were one, the waiter would be refused.
        let answer = (&mut queued.rx).await.unwrap_or(Err(Refused::Closed));
        queued.answered = true;
        answer.map(|()| Slot { slots: self.clone(), texture })
    }

    /// Refuses every waiter and every later miss; slots held are freed as usual.
    pub fn close(&self) {
        let mut st = self.state.lock().unwrap();
        st.closed = true;
        for w in st.queues.drain().flat_map(|(_, q)| q) {
            let _ = w.wake.send(Err(Refused::Closed));
        }
        st.queued = 0;
    }

    /// Misses waiting for a slot now.
    pub fn queued(&self) -> usize {
        self.state.lock().unwrap().queued
    }
}

impl State {
    /// Hands free slots to waiters: each to the texture holding the fewest slots among those
    /// under `per_texture`, oldest first among equals.
    fn dispatch(&mut self, per_texture: usize) {
        while self.free > 0 {
            let next = self
                .queues
                .iter()
                .map(|(t, q)| (self.running.get(t).copied().unwrap_or(0), q.front().map_or(u64::MAX, |w| w.seq), *t))
                .filter(|&(held, _, _)| held < per_texture)
                .min();
            let Some((_, _, texture)) = next else { return };
            let waiter = self.pop(texture, |q| q.pop_front());
            self.free -= 1;
            *self.running.entry(texture).or_default() += 1;
            // The receiver is alive: a dropped waiter leaves the queue under this lock first.
            let _ = waiter.wake.send(Ok(()));
        }
    }

    /// Refuses the newest waiter of the texture with the most waiters (the most recent one
    /// among equals), bringing the queue back to its bound.
    fn shed(&mut self) {
        let longest = self
            .queues
            .iter()
            .map(|(t, q)| (q.len(), q.back().map_or(0, |w| w.seq), *t))
            .max()
            .map(|(_, _, t)| t)
            .expect("a queue over its bound holds a waiter");
        let waiter = self.pop(longest, |q| q.pop_back());
        let _ = waiter.wake.send(Err(Refused::Full));
    }

    /// Takes a waiter off `texture`'s queue (which holds one) with `take`.
    fn pop(&mut self, texture: Texture, take: impl FnOnce(&mut VecDeque<Waiter>) -> Option<Waiter>) -> Waiter {
        let q = self.queues.get_mut(&texture).expect("the texture has waiters");
        let w = take(q).expect("queues in the map are not empty");
        if q.is_empty() {
            self.queues.remove(&texture);
        }
        self.queued -= 1;
        w
    }

    /// Removes waiter `seq` of `texture`, which left before it was answered.
    fn leave(&mut self, texture: Texture, seq: u64) {
        if let Some(q) = self.queues.get_mut(&texture) {
            if let Some(i) = q.iter().position(|w| w.seq == seq) {
                q.remove(i);
                self.queued -= 1;
            }
            if q.is_empty() {
                self.queues.remove(&texture);
            }
        }
    }

    /// Frees a slot `texture` held and hands it on.
    fn release(&mut self, texture: Texture, per_texture: usize) {
        match self.running.get_mut(&texture) {
            Some(n) if *n > 1 => *n -= 1,
            _ => {
                self.running.remove(&texture);
            }
        }
        self.free += 1;
        self.dispatch(per_texture);
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::future::Future;
    use std::pin::pin;
    use std::task::{Context, Poll, Waker};

    const A: Texture = [1; 32];
    const B: Texture = [2; 32];
    const C: Texture = [3; 32];

    /// Polls `f` once: its output if it is ready.
    fn now<F: Future>(f: std::pin::Pin<&mut F>) -> Option<F::Output> {
        match f.poll(&mut Context::from_waker(Waker::noop())) {
            Poll::Ready(v) => Some(v),
            Poll::Pending => None,
        }
    }

    #[test]
    fn free_slots_are_taken_at_once_up_to_the_share_of_a_texture() {
        let s = Slots::new(3, 2, 8);
        let a1 = now(pin!(s.acquire(A))).unwrap().unwrap();
        let _a2 = now(pin!(s.acquire(A))).unwrap().unwrap();
        let mut a3 = pin!(s.acquire(A));
        assert!(now(a3.as_mut()).is_none(), "a texture holds at most its share");
        let _b = now(pin!(s.acquire(B))).unwrap().unwrap();
        assert_eq!(s.queued(), 1);
        drop(a1);
        assert!(now(a3.as_mut()).unwrap().is_ok(), "a freed slot goes to the waiter");
        assert_eq!(s.queued(), 0);
    }

    #[test]
    fn a_freed_slot_goes_to_the_texture_holding_fewest() {
        let s = Slots::new(2, 2, 8);
        let a1 = now(pin!(s.acquire(A))).unwrap().unwrap();
        let _a2 = now(pin!(s.acquire(A))).unwrap().unwrap();
        // A asks first, then B, then C: A holds two, B and C none.
        let mut a3 = pin!(s.acquire(A));
        let mut b = pin!(s.acquire(B));
        let mut c = pin!(s.acquire(C));
        assert!(now(a3.as_mut()).is_none() && now(b.as_mut()).is_none() && now(c.as_mut()).is_none());
        drop(a1);
        let _b = now(b.as_mut()).unwrap().expect("B holds none and waited longest of those");
        assert!(now(a3.as_mut()).is_none() && now(c.as_mut()).is_none());
        assert_eq!(s.queued(), 2);
    }

    #[test]
    fn ties_go_to_the_oldest_waiter() {
        let s = Slots::new(1, 1, 8);
        let held = now(pin!(s.acquire(C))).unwrap().unwrap();
        let mut b = pin!(s.acquire(B));
        let mut a = pin!(s.acquire(A));
        assert!(now(b.as_mut()).is_none() && now(a.as_mut()).is_none());
        drop(held);
        let _b = now(b.as_mut()).unwrap().expect("B came first");
        assert!(now(a.as_mut()).is_none());
    }

    #[test]
    fn a_full_queue_sheds_the_newest_waiter_of_the_longest_queue() {
        let s = Slots::new(1, 1, 2);
        let _held = now(pin!(s.acquire(A))).unwrap().unwrap();
        let mut a2 = pin!(s.acquire(A));
        let mut a3 = pin!(s.acquire(A));
        assert!(now(a2.as_mut()).is_none() && now(a3.as_mut()).is_none());
        // A third waiter of A is over the bound: refused at once.
        assert!(matches!(now(pin!(s.acquire(A))), Some(Err(Refused::Full))));
        // B's waiter is admitted; A, with the longest queue, gives up its newest.
        let mut b = pin!(s.acquire(B));
        assert!(now(b.as_mut()).is_none(), "B waits");
        assert!(matches!(now(a3.as_mut()), Some(Err(Refused::Full))));
        assert!(now(a2.as_mut()).is_none(), "A's older waiter keeps its place");
        assert_eq!(s.queued(), 2);
    }

    #[test]
    fn no_queue_means_misses_without_a_free_slot_are_refused() {
        let s = Slots::new(1, 1, 0);
        let held = now(pin!(s.acquire(A))).unwrap().unwrap();
        assert!(matches!(now(pin!(s.acquire(B))), Some(Err(Refused::Full))));
        drop(held);
        assert!(now(pin!(s.acquire(B))).unwrap().is_ok());
    }

    #[test]
    fn a_waiter_dropped_leaves_the_queue_and_a_grant_dropped_is_handed_on() {
        let s = Slots::new(1, 1, 8);
        let held = now(pin!(s.acquire(A))).unwrap().unwrap();
        {
            let mut gone = pin!(s.acquire(B));
            assert!(now(gone.as_mut()).is_none());
            assert_eq!(s.queued(), 1);
        }
        assert_eq!(s.queued(), 0, "a dropped waiter leaves the queue");
        let mut granted_then_dropped = Box::pin(s.acquire(B));
        let mut c = pin!(s.acquire(C));
        assert!(now(granted_then_dropped.as_mut()).is_none() && now(c.as_mut()).is_none());
        drop(held);
        // B was granted the slot but never took it: dropping it hands the slot to C.
        drop(granted_then_dropped);
        assert!(now(c.as_mut()).unwrap().is_ok());
    }

    #[test]
    fn closing_refuses_waiters_and_later_misses() {
        let s = Slots::new(1, 1, 8);
        let held = now(pin!(s.acquire(A))).unwrap().unwrap();
        let mut b = pin!(s.acquire(B));
        assert!(now(b.as_mut()).is_none());
        s.close();
        assert!(matches!(now(b.as_mut()), Some(Err(Refused::Closed))));
        assert!(matches!(now(pin!(s.acquire(C))), Some(Err(Refused::Closed))));
        drop(held);
        assert_eq!(s.queued(), 0);
    }

    /// Many tasks on many threads contending: never more running than slots, never more of
    /// one texture than its share, and every slot back at the end.
    #[tokio::test(flavor = "multi_thread", worker_threads = 4)]
    async fn bounds_hold_under_contention() {
        use std::sync::atomic::{AtomicUsize, Ordering::SeqCst};
        let s = Slots::new(3, 2, 1000);
        let running = Arc::new([AtomicUsize::new(0), AtomicUsize::new(0), AtomicUsize::new(0)]);
        let total = Arc::new(AtomicUsize::new(0));
        let mut tasks = Vec::new();
        for i in 0..300usize {
            let (s, running, total) = (s.clone(), running.clone(), total.clone());
            tasks.push(tokio::spawn(async move {
                let t = i % 3;
                let slot = s.acquire([t as u8; 32]).await.unwrap();
                assert!(running[t].fetch_add(1, SeqCst) < 2, "over the share of a texture");
                assert!(total.fetch_add(1, SeqCst) < 3, "over the slots");
                tokio::task::yield_now().await;
                total.fetch_sub(1, SeqCst);
                running[t].fetch_sub(1, SeqCst);
                drop(slot);
            }));
        }
        for t in tasks {
            t.await.unwrap();
        }
        let st = s.state.lock().unwrap();
        assert_eq!((st.free, st.queued, st.running.len(), st.queues.len()), (3, 0, 0, 0));
    }
}
