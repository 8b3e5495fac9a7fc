//! Edges: one bounded SPSC ring (`ringbuf`) per producer/consumer pair.
//!
//! A full ring is a policy decision, not an error: under [`Policy::Block`]
//! the producer sleeps until the consumer frees a slot (replay: nothing is
//! lost); under [`Policy::DropOldest`] the producer evicts the oldest queued
//! item and counts it (live: the newest frames win, memory stays bounded).
//!
//! Eviction needs the consumer half, so on drop-oldest edges that half sits
//! behind a mutex. The consumer takes it (uncontended) to pop; the producer
//! takes it only when the ring is full. Block edges own their consumer half
//! outright and take no lock at all.

use super::item::Item;
use super::notify::Notify;
use ringbuf::traits::{Consumer, Observer, Producer, Split};
use ringbuf::{HeapCons, HeapProd, HeapRb};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

/// How long a blocked thread sleeps before re-checking stop flags.
const WAIT_SLICE: Duration = Duration::from_millis(50);

#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Policy {
    Block,
    DropOldest,
}

impl Policy {
    pub fn parse(s: &str) -> Option<Policy> {
        match s {
            "block" => Some(Policy::Block),
            "drop_oldest" => Some(Policy::DropOldest),
            _ => None,
        }
    }
    pub fn as_str(&self) -> &'static str {
        match self {
            Policy::Block => "block",
            Policy::DropOldest => "drop_oldest",
        }
    }
}

/// Counters of one edge, shared by both ends and the stats report.
#[derive(Default, Debug)]
pub struct EdgeStats {
    pub pushed: AtomicU64,
    pub popped: AtomicU64,
    pub dropped: AtomicU64,
    pub max_occupancy: AtomicU64,
}

struct Shared {
    policy: Policy,
    capacity: usize,
    /// A producer blocked on a full ring resumes when this many items or
    /// fewer are queued ([`edge_resuming_at_half`]).
    resume: usize,
    /// The consumer polls ([`EdgeRx::recv_polling`]): the producer wakes
    /// it only once the ring is half full, not for every item.
    polled: AtomicBool,
    data: Notify,
    space: Notify,
    producer_done: AtomicBool,
    consumer_gone: AtomicBool,
    stats: Arc<EdgeStats>,
}

impl Shared {
    /// The occupancy at which a polling consumer is woken.
    fn wake_polled_at(&self) -> usize {
        self.capacity.div_ceil(2)
    }
}

enum ConsHalf {
    Owned(HeapCons<Item>),
    Locked(Arc<Mutex<HeapCons<Item>>>),
}

impl ConsHalf {
    fn try_pop(&mut self) -> Option<Item> {
        match self {
            ConsHalf::Owned(c) => c.try_pop(),
            ConsHalf::Locked(m) => m.lock().unwrap_or_else(|e| e.into_inner()).try_pop(),
        }
    }
    fn occupied(&self) -> usize {
        match self {
            ConsHalf::Owned(c) => c.occupied_len(),
            ConsHalf::Locked(m) => m.lock().unwrap_or_else(|e| e.into_inner()).occupied_len(),
        }
    }
}

/// The producing end of an edge.
pub struct EdgeTx {
    prod: HeapProd<Item>,
    evict: Option<Arc<Mutex<HeapCons<Item>>>>,
    shared: Arc<Shared>,
}

/// The consuming end of an edge.
pub struct EdgeRx {
    cons: ConsHalf,
    shared: Arc<Shared>,
}

/// Outcome of [`EdgeTx::send`].
#[derive(Debug, PartialEq, Eq)]
pub enum Sent {
    /// Queued (possibly after evicting `evicted` older items).
    Queued { evicted: u64 },
    /// The consumer has gone away; the item was discarded.
    Gone,
    /// The stop flag was raised while waiting for space.
    Stopped,
}

/// Outcome of [`EdgeRx::recv`].
#[derive(Debug)]
pub enum Recv {
    Item(Item),
    /// The producer finished and the ring is drained.
    Closed,
    /// The stop flag was raised while waiting.
    Stopped,
}

/// Creates an edge of `capacity` slots (at least 1). A producer blocked on
/// the full ring resumes as soon as one slot is free.
pub fn edge(capacity: usize, policy: Policy) -> (EdgeTx, EdgeRx, Arc<EdgeStats>) {
    let capacity = capacity.max(1);
    make_edge(capacity, policy, capacity - 1)
}

/// [`edge`], but a producer blocked on the full ring resumes only when it
/// is half empty (on rings of 3 slots or more): one wake-up of the
/// producer per half a ring instead of one per item, whose thread would
/// otherwise take a core from the consumer for every item it frees (on a
/// 2-core machine, 4% of `magnify`'s time). Only for a consumer with no
/// other input: one that waits on another input while this ring is more
/// than half full would never free what the producer waits for, if that
/// producer also feeds the other input.
pub fn edge_resuming_at_half(capacity: usize, policy: Policy) -> (EdgeTx, EdgeRx, Arc<EdgeStats>) {
    let capacity = capacity.max(1);
    let resume = if capacity <= 2 {
        capacity - 1
    } else {
        capacity / 2
    };
    make_edge(capacity, policy, resume)
}

fn make_edge(capacity: usize, policy: Policy, resume: usize) -> (EdgeTx, EdgeRx, Arc<EdgeStats>) {
    let (prod, cons) = HeapRb::<Item>::new(capacity).split();
    let stats = Arc::new(EdgeStats::default());
    let shared = Arc::new(Shared {
        policy,
        capacity,
        resume,
        polled: AtomicBool::new(false),
        data: Notify::new(),
        space: Notify::new(),
        producer_done: AtomicBool::new(false),
        consumer_gone: AtomicBool::new(false),
        stats: Arc::clone(&stats),
    });
    let (cons, evict) = match policy {
        Policy::Block => (ConsHalf::Owned(cons), None),
        Policy::DropOldest => {
            let m = Arc::new(Mutex::new(cons));
            (ConsHalf::Locked(Arc::clone(&m)), Some(m))
        }
    };
    (
        EdgeTx {
            prod,
            evict,
            shared: Arc::clone(&shared),
        },
        EdgeRx { cons, shared },
        stats,
    )
}

impl EdgeTx {
    pub fn policy(&self) -> Policy {
        self.shared.policy
    }

    pub fn capacity(&self) -> usize {
        self.shared.capacity
    }

    pub fn consumer_gone(&self) -> bool {
        self.shared.consumer_gone.load(Ordering::Acquire)
    }

    /// Queues `item` according to the edge policy. Waiting (block policy)
    /// ends early when `stop` is raised.
    pub fn send(&mut self, item: Item, stop: &AtomicBool) -> Sent {
        let mut item = item;
        let mut evicted = 0u64;
        // Once the ring was found full, the producer waits for the resume
        // level (one free slot on a plain edge), wake-up or not.
        let mut waited = false;
        loop {
            if self.consumer_gone() {
                return Sent::Gone;
            }
            if !waited || self.prod.occupied_len() <= self.shared.resume {
                match self.prod.try_push(item) {
                    Ok(()) => {
                        let st = &self.shared.stats;
                        st.pushed.fetch_add(1, Ordering::Relaxed);
                        let occ = self.prod.occupied_len();
                        st.max_occupancy.fetch_max(occ as u64, Ordering::Relaxed);
                        if occ >= self.shared.wake_polled_at()
                            || !self.shared.polled.load(Ordering::Relaxed)
                        {
                            self.shared.data.notify();
                        }
                        return Sent::Queued { evicted };
                    }
                    Err(back) => item = back,
                }
            }
            if let Some(m) = &self.evict {
                // Drop-oldest: evict the head, count it, then retry the push.
                let old = m.lock().unwrap_or_else(|e| e.into_inner()).try_pop();
                if old.is_some() {
                    evicted += 1;
                    self.shared.stats.dropped.fetch_add(1, Ordering::Relaxed);
                }
                drop(old);
                continue;
            }
            if stop.load(Ordering::Acquire) {
                return Sent::Stopped;
            }
            waited = true;
            let prod = &self.prod;
            let shared = &self.shared;
            shared.space.wait_until(WAIT_SLICE, || {
                prod.occupied_len() <= shared.resume || shared.consumer_gone.load(Ordering::Acquire)
            });
        }
    }
}

impl Drop for EdgeTx {
    fn drop(&mut self) {
        self.shared.producer_done.store(true, Ordering::Release);
        self.shared.data.notify();
    }
}

impl EdgeRx {
    pub fn capacity(&self) -> usize {
        self.shared.capacity
    }

    pub fn stats(&self) -> &Arc<EdgeStats> {
        &self.shared.stats
    }

    /// Items queued now.
    pub fn occupancy(&self) -> usize {
        self.cons.occupied()
    }

    /// Takes the next item without waiting.
    pub fn try_recv(&mut self) -> Option<Item> {
        let it = self.cons.try_pop();
        if it.is_some() {
            self.shared.stats.popped.fetch_add(1, Ordering::Relaxed);
            // (Always, on an edge that resumes at one free slot.)
            if self.cons.occupied() <= self.shared.resume {
                self.shared.space.notify();
            }
        }
        it
    }

    /// Waits (sleeping, not spinning) for the next item, the end of the
    /// stream, or `stop`.
    pub fn recv(&mut self, stop: &AtomicBool) -> Recv {
        self.recv_with(stop, |rx| {
            let shared = Arc::clone(&rx.shared);
            let cons = &rx.cons;
            shared.data.wait_until(WAIT_SLICE, || {
                cons.occupied() > 0 || shared.producer_done.load(Ordering::Acquire)
            });
        })
    }

    /// [`EdgeRx::recv`] for a consumer that does not want to be woken per
    /// item: when the ring is empty it sleeps up to `period` and looks
    /// again, and the producer wakes it only when the ring is half full
    /// (a cheap watcher of a fast stream costs the producer nothing but the
    /// push; a writer of small frames, whose ring fills within the period,
    /// does not hold its producer up for the rest of it).
    pub fn recv_polling(&mut self, stop: &AtomicBool, period: std::time::Duration) -> Recv {
        self.shared.polled.store(true, Ordering::Relaxed);
        self.recv_with(stop, |rx| {
            let shared = Arc::clone(&rx.shared);
            let cons = &rx.cons;
            let half = shared.wake_polled_at();
            shared.data.wait_until(period, || {
                cons.occupied() >= half || shared.producer_done.load(Ordering::Acquire)
            });
        })
    }

    /// The next item, the end of the stream or `stop`, calling `wait`
    /// whenever the ring is empty.
    fn recv_with(&mut self, stop: &AtomicBool, wait: impl Fn(&EdgeRx)) -> Recv {
        loop {
            if let Some(it) = self.try_recv() {
                return Recv::Item(it);
            }
            if self.shared.producer_done.load(Ordering::Acquire) {
                // The producer may have pushed just before finishing.
                return match self.try_recv() {
                    Some(it) => Recv::Item(it),
                    None => Recv::Closed,
                };
            }
            if stop.load(Ordering::Acquire) {
                return Recv::Stopped;
            }
            wait(self);
        }
    }
}

impl Drop for EdgeRx {
    fn drop(&mut self) {
        self.shared.consumer_gone.store(true, Ordering::Release);
        // Return queued frames to their pool now rather than when the
        // producer finishes.
        while self.cons.try_pop().is_some() {}
        self.shared.space.notify();
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::item::AudioBlock;

    fn audio(i: i64) -> Item {
        Item::Audio(AudioBlock {
            t0_ns: i,
            rate_hz: 1.0,
            samples: Arc::from(vec![i as f32]),
        })
    }

    #[test]
    fn drop_oldest_keeps_newest() {
        let stop = AtomicBool::new(false);
        let (mut tx, mut rx, stats) = edge(3, Policy::DropOldest);
        for i in 0..10 {
            tx.send(audio(i), &stop);
        }
        drop(tx);
        let mut got = vec![];
        while let Recv::Item(it) = rx.recv(&stop) {
            got.push(it.t_ns());
        }
        assert_eq!(got, vec![7, 8, 9]);
        assert_eq!(stats.dropped.load(Ordering::Relaxed), 7);
    }

    #[test]
    fn block_delivers_everything_in_order_across_threads() {
        let stop = Arc::new(AtomicBool::new(false));
        let (mut tx, mut rx, _) = edge(2, Policy::Block);
        let s2 = Arc::clone(&stop);
        let h = std::thread::spawn(move || {
            for i in 0..1000 {
                assert_eq!(tx.send(audio(i), &s2), Sent::Queued { evicted: 0 });
            }
        });
        let mut next = 0;
        while let Recv::Item(it) = rx.recv(&stop) {
            assert_eq!(it.t_ns(), next);
            next += 1;
        }
        h.join().unwrap();
        assert_eq!(next, 1000);
    }

    /// A producer blocked on a full ring resumes at one free slot on a
    /// plain edge, and only at half the ring on one that resumes at half;
    /// either way nothing is lost and the order holds.
    #[test]
    fn a_blocked_producer_resumes_at_one_slot_or_at_half_the_ring() {
        type Make = fn(usize, Policy) -> (EdgeTx, EdgeRx, Arc<EdgeStats>);
        for (make, resume) in [(edge as Make, 7usize), (edge_resuming_at_half as Make, 4)] {
            let stop = Arc::new(AtomicBool::new(false));
            let (mut tx, mut rx, stats) = make(8, Policy::Block);
            for i in 0..8 {
                assert_eq!(tx.send(audio(i), &stop), Sent::Queued { evicted: 0 });
            }
            let s2 = Arc::clone(&stop);
            let h = std::thread::spawn(move || tx.send(audio(8), &s2));
            // (It finds the ring full and waits.)
            std::thread::sleep(Duration::from_millis(50));
            let pushed = || stats.pushed.load(Ordering::SeqCst);
            let mut next = 0;
            let mut pop = |rx: &mut EdgeRx| {
                let Some(it) = rx.try_recv() else {
                    panic!("an item was expected")
                };
                assert_eq!(it.t_ns(), next);
                next += 1;
            };
            for _ in 0..8 - resume - 1 {
                pop(&mut rx);
            }
            std::thread::sleep(Duration::from_millis(120));
            assert_eq!(pushed(), 8, "resumed above {resume} queued");
            pop(&mut rx);
            let t = std::time::Instant::now();
            while pushed() < 9 && t.elapsed() < Duration::from_secs(5) {
                std::thread::sleep(Duration::from_millis(1));
            }
            // Woken, not found by a re-check after a wait slice.
            assert!(t.elapsed() < WAIT_SLICE, "resumed after {:?}", t.elapsed());
            assert_eq!(h.join().unwrap(), Sent::Queued { evicted: 0 });
            while let Some(it) = rx.try_recv() {
                assert_eq!(it.t_ns(), next);
                next += 1;
            }
            assert_eq!(next, 9);
        }
    }

    /// A polling consumer is woken when its ring is half full and at the
    /// end of the stream, not only when its period (an hour here) ends:
    /// a producer of small items is not held up for the rest of it.
    #[test]
    fn a_polling_consumer_is_woken_at_half_the_ring() {
        let stop = Arc::new(AtomicBool::new(false));
        let (mut tx, mut rx, _) = edge(8, Policy::Block);
        let s2 = Arc::clone(&stop);
        let producer = std::thread::spawn(move || {
            for i in 0..101 {
                assert_eq!(tx.send(audio(i), &s2), Sent::Queued { evicted: 0 });
            }
        });
        let (done, got) = std::sync::mpsc::channel();
        let s3 = Arc::clone(&stop);
        std::thread::spawn(move || {
            let mut next = 0;
            while let Recv::Item(it) = rx.recv_polling(&s3, Duration::from_secs(3600)) {
                assert_eq!(it.t_ns(), next);
                next += 1;
            }
            let _ = done.send(next);
        });
        // (Each wait would otherwise last the hour.)
        let received = got.recv_timeout(Duration::from_secs(60));
        assert_eq!(received, Ok(101), "the polling consumer was not woken");
        producer.join().unwrap();
    }

    #[test]
    fn send_to_gone_consumer_does_not_block() {
        let stop = AtomicBool::new(false);
        let (mut tx, rx, _) = edge(1, Policy::Block);
        tx.send(audio(0), &stop);
        drop(rx);
        assert_eq!(tx.send(audio(1), &stop), Sent::Gone);
    }
}
