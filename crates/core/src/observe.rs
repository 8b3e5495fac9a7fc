//! Watching a run from outside while it goes on (the studio's live view):
//! the latest item of each `tap` stage, and each stage's counters.
//!
//! An [`Observer`] is handed to [`crate::run`] through
//! [`crate::RunOptions::observer`]. The run registers its stages' counters
//! with it, and every `tap` stage publishes into the observer's slot of its
//! `name`. Publishing never waits: a tap keeps only the latest item, and
//! when a reader is copying it out at that moment the new item is skipped
//! and counted, so a slow reader costs the frame path nothing. Frames are
//! copied (8-bit grey) into a buffer the slot reuses, so a tap never holds
//! a pooled frame buffer.

use crate::frame::PixelsRef;
use crate::item::{AudioBlock, Item, SampleBlock, Spectrum};
use crate::stage::Control;
use std::collections::{HashMap, VecDeque};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Condvar, Mutex, TryLockError};
use std::time::Instant;

/// The live state of one run, readable from any thread.
#[derive(Default)]
pub struct Observer {
    slots: Mutex<HashMap<String, Arc<TapSlot>>>,
    tunings: Mutex<HashMap<String, Arc<Tuning>>>,
    stages: Mutex<Vec<Watched>>,
    /// The run's control, and whether [`Observer::stop`] was called.
    control: Mutex<(Option<Arc<Control>>, bool)>,
}

impl std::fmt::Debug for Observer {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Observer").finish_non_exhaustive()
    }
}

/// A stage's counters, as the runner keeps them.
pub(crate) trait Counted: Send + Sync {
    /// The counts now.
    fn live(&self, id: &str, kind: &'static str) -> StageLive;
}

/// A stage's counters, shared with the runner.
pub(crate) struct Watched {
    pub id: String,
    pub kind: &'static str,
    pub counters: Arc<dyn Counted>,
}

/// One stage as it runs.
#[derive(Clone, Debug, PartialEq, serde::Serialize)]
pub struct StageLive {
    pub id: String,
    pub kind: &'static str,
    pub items_in: u64,
    pub items_out: u64,
    /// Items evicted from its input rings, plus (a source) frames the
    /// device dropped.
    pub dropped: u64,
    /// Items queued on its input rings now, and their largest capacity.
    pub queued: u64,
    pub queue_capacity: u64,
    /// Seconds spent working (not waiting).
    pub busy_s: f64,
}

impl Observer {
    pub fn new() -> Arc<Observer> {
        Arc::new(Observer::default())
    }

    /// The slot a `tap` stage of this name publishes into (made on first use).
    pub fn slot(&self, name: &str) -> Arc<TapSlot> {
        let mut m = self.slots.lock().unwrap_or_else(|e| e.into_inner());
        Arc::clone(m.entry(name.to_owned()).or_default())
    }

    /// The settings a watcher changes on the stage `id` while the run goes
    /// on (made on first use; a stage that reads them takes the slot of
    /// its own id when it is built).
    pub fn tuning(&self, id: &str) -> Arc<Tuning> {
        let mut m = self.tunings.lock().unwrap_or_else(|e| e.into_inner());
        Arc::clone(m.entry(id.to_owned()).or_default())
    }

    /// Every stage of the run, in the graph's order (empty before it starts).
    pub fn stages(&self) -> Vec<StageLive> {
        let w = self.stages.lock().unwrap_or_else(|e| e.into_inner());
        w.iter().map(|w| w.counters.live(&w.id, w.kind)).collect()
    }

    /// Nanoseconds on the run's clock (the one live capture times use);
    /// none before the run starts.
    pub fn now_ns(&self) -> Option<i64> {
        self.control().map(|c| c.now_ns())
    }

    /// The instant the run's capture times count from.
    pub fn epoch(&self) -> Option<Instant> {
        self.control().map(|c| c.epoch())
    }

    /// Stops the run gracefully (sources end, queues drain, sinks finalise);
    /// a run not started yet stops as soon as it starts. Returns false when
    /// no run had started.
    pub fn stop(&self) -> bool {
        let mut g = self.control.lock().unwrap_or_else(|e| e.into_inner());
        g.1 = true;
        g.0.as_ref().map(|c| c.stop()).is_some()
    }

    fn control(&self) -> Option<Arc<Control>> {
        self.control
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .0
            .clone()
    }

    pub(crate) fn attach(&self, control: &Arc<Control>, stages: Vec<Watched>) {
        *self.stages.lock().unwrap_or_else(|e| e.into_inner()) = stages;
        let mut g = self.control.lock().unwrap_or_else(|e| e.into_inner());
        g.0 = Some(Arc::clone(control));
        if g.1 {
            control.stop();
        }
    }
}

/// Parameters of one stage that a watcher changes while the run goes on
/// (the studio's magnified view sets a `magnify` stage's band and factor).
/// The watcher [`Tuning::request`]s values; the stage looks at the
/// version once per item (an atomic load), applies a new request at its
/// next item and [`Tuning::answer`]s with the item's number, or why it
/// kept its settings.
#[derive(Default)]
pub struct Tuning {
    version: AtomicU64,
    values: Mutex<Vec<(String, f64)>>,
    outcome: Mutex<Option<Tuned>>,
}

/// How a stage took a [`Tuning::request`].
#[derive(Clone, Debug, PartialEq)]
pub struct Tuned {
    /// The request's version.
    pub version: u64,
    /// The number (`seq`) of the first item processed with the new
    /// values, or why the stage kept the ones it had.
    pub result: Result<u64, String>,
}

impl Tuning {
    /// Asks the stage to take `values` (parameter name, value) at its next
    /// item; returns the request's version (see [`Tuning::outcome`]).
    pub fn request(&self, values: Vec<(String, f64)>) -> u64 {
        let mut v = self.values.lock().unwrap_or_else(|e| e.into_inner());
        *v = values;
        self.version.fetch_add(1, Ordering::AcqRel) + 1
    }

    /// The latest request's version (0: none yet).
    pub fn version(&self) -> u64 {
        self.version.load(Ordering::Acquire)
    }

    /// The latest request: its version and values.
    pub fn values(&self) -> (u64, Vec<(String, f64)>) {
        let v = self.values.lock().unwrap_or_else(|e| e.into_inner());
        (self.version(), v.clone())
    }

    /// The stage's answer to request `version`.
    pub fn answer(&self, version: u64, result: Result<u64, String>) {
        *self.outcome.lock().unwrap_or_else(|e| e.into_inner()) = Some(Tuned { version, result });
    }

    /// The last answer, if any.
    pub fn outcome(&self) -> Option<Tuned> {
        self.outcome
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .clone()
    }
}

/// The latest item a tap saw, as a reader gets it.
#[derive(Clone, Debug)]
pub enum Latest {
    Spectrum(Spectrum),
    Samples(SampleBlock),
    Audio(AudioBlock),
    Frame(TapFrame),
}

/// A frame copied out of the pool: 8-bit grey, row-major.
#[derive(Clone, Debug, Default)]
pub struct TapFrame {
    pub t_ns: i64,
    pub seq: u64,
    pub width: u32,
    pub height: u32,
    pub gray: Vec<u8>,
}

/// What one slot holds: the latest item, its number, when it arrived.
#[derive(Default)]
struct Held {
    latest: Option<Latest>,
    /// Items published into this slot so far (0: none yet).
    seq: u64,
    arrived: Option<Instant>,
}

/// The latest item of one `tap` stage (and, for a tap with `history_s`,
/// its last frames).
#[derive(Default)]
pub struct TapSlot {
    held: Mutex<Held>,
    /// Items the tap saw but did not keep: a reader held the slot, or the
    /// item came sooner than the tap's interval after the last one kept.
    skipped: AtomicU64,
    history: Mutex<History>,
    /// Every item, in order, for a tap with `queue` (a reader of all of
    /// them); `ready` wakes the reader, `room` the tap.
    queue: Mutex<Queue>,
    ready: Condvar,
    room: Condvar,
}

/// The items a tap with `queue` handed over and the reader has not taken.
#[derive(Default)]
struct Queue {
    items: VecDeque<Latest>,
    /// The tap has finished: no item will follow those queued.
    closed: bool,
    /// The reader has gone: items are discarded, the tap never waits.
    abandoned: bool,
}

/// What [`TapSlot::next`] found.
#[derive(Debug)]
pub enum Next {
    Item(Latest),
    /// Nothing yet within the time given.
    Wait,
    /// The tap has finished and every item was taken.
    End,
}

/// The last frames of a stream, oldest first, contiguous (after a gap the
/// history starts over).
#[derive(Default)]
struct History {
    frames: VecDeque<TapFrame>,
    bytes: usize,
    /// Times the history started over after frames were lost.
    restarts: u64,
}

/// What a history keeps: this much capture time, in this much memory.
#[derive(Clone, Copy, Debug)]
pub struct HistoryLimits {
    pub span_ns: i64,
    pub max_bytes: usize,
}

/// The tap's side of a history: frames that came while a reader held it
/// (handed over at the next frame), and buffers to reuse.
#[derive(Default)]
pub struct Pending {
    frames: VecDeque<TapFrame>,
    bytes: usize,
    free: Vec<TapFrame>,
    /// Frames were lost (more came than `Pending` holds while a reader
    /// held the history): it starts over.
    gap: bool,
}

/// A reader's copy of a history.
#[derive(Clone, Debug, Default)]
pub struct FrameHistory {
    /// Oldest first, consecutive frames of the stream.
    pub frames: Vec<TapFrame>,
    /// Times the history started over because frames were lost.
    pub restarts: u64,
}

/// Copies `f` into `tf` as 8-bit grey, reusing its buffer.
fn copy_frame(f: &crate::frame::Frame, tf: &mut TapFrame) {
    tf.t_ns = f.meta().t_ns;
    tf.seq = f.meta().seq;
    tf.width = f.width() as u32;
    tf.height = f.height() as u32;
    let n = f.width() * f.height();
    tf.gray.resize(n, 0);
    match f.pixels() {
        PixelsRef::U8(p) => tf.gray.copy_from_slice(&p[..n]),
        PixelsRef::U16(p) => vibroscope_io::image::gray8_from_u16(p, f.format().bits, &mut tf.gray),
    }
}

/// A reader's copy of a slot.
#[derive(Clone, Debug)]
pub struct Snapshot {
    pub latest: Latest,
    /// Items kept by the slot so far, this one included.
    pub seq: u64,
    /// When the tap stage received it.
    pub arrived: Instant,
}

impl TapSlot {
    /// A copy of the latest item, if any (the tap skips what arrives
    /// while this copies).
    pub fn snapshot(&self) -> Option<Snapshot> {
        let h = self.held.lock().unwrap_or_else(|e| e.into_inner());
        Some(Snapshot {
            latest: h.latest.clone()?,
            seq: h.seq,
            arrived: h.arrived?,
        })
    }

    /// Items kept so far (changes when a new one arrives).
    pub fn seq(&self) -> u64 {
        self.held.lock().unwrap_or_else(|e| e.into_inner()).seq
    }

    /// Items seen and not kept.
    pub fn skipped(&self) -> u64 {
        self.skipped.load(Ordering::Relaxed)
    }

    pub fn count_skip(&self) {
        self.skipped.fetch_add(1, Ordering::Relaxed);
    }

    /// Keeps `item` unless a reader holds the slot (then counts it
    /// skipped). Never waits. Frames are copied into the slot's own buffer.
    pub fn publish(&self, item: &Item) -> bool {
        let mut h = match self.held.try_lock() {
            Ok(h) => h,
            Err(TryLockError::Poisoned(p)) => p.into_inner(),
            Err(TryLockError::WouldBlock) => {
                self.count_skip();
                return false;
            }
        };
        let next = match item {
            Item::Spectrum(s) => Latest::Spectrum(s.clone()),
            Item::Samples(s) => Latest::Samples(s.clone()),
            Item::Audio(a) => Latest::Audio(a.clone()),
            Item::Frame(f) => {
                // Reuse the buffer of the frame held before.
                let mut tf = match h.latest.take() {
                    Some(Latest::Frame(tf)) => tf,
                    _ => TapFrame::default(),
                };
                copy_frame(f, &mut tf);
                Latest::Frame(tf)
            }
            Item::Pyramid(_) | Item::Peaks(_) => {
                self.count_skip();
                return false;
            }
        };
        h.latest = Some(next);
        h.seq += 1;
        h.arrived = Some(Instant::now());
        true
    }
}

impl TapSlot {
    /// Hands `item` (a frame copied as 8-bit grey) to the reader, after
    /// those before it, waiting while `cap` items wait unread: a stream
    /// read this way is never thinned (a live source upstream drops by
    /// its edges' policy, a replay waits). Returns false, the item
    /// discarded, once the reader has gone ([`TapSlot::abandon`]).
    pub fn push(&self, item: &Item, cap: usize) -> bool {
        let next = match item {
            Item::Spectrum(s) => Latest::Spectrum(s.clone()),
            Item::Samples(s) => Latest::Samples(s.clone()),
            Item::Audio(a) => Latest::Audio(a.clone()),
            Item::Frame(f) => {
                let mut tf = TapFrame::default();
                copy_frame(f, &mut tf);
                Latest::Frame(tf)
            }
            Item::Pyramid(_) | Item::Peaks(_) => {
                self.count_skip();
                return false;
            }
        };
        let mut q = self.queue.lock().unwrap_or_else(|e| e.into_inner());
        while !q.abandoned && q.items.len() >= cap.max(1) {
            q = self
                .room
                .wait_timeout(q, std::time::Duration::from_millis(50))
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        if q.abandoned {
            return false;
        }
        q.items.push_back(next);
        self.ready.notify_all();
        true
    }

    /// The tap has finished: the reader gets what is queued, then the end.
    pub fn close(&self) {
        self.queue.lock().unwrap_or_else(|e| e.into_inner()).closed = true;
        self.ready.notify_all();
    }

    /// The reader goes: what is queued is dropped, and the tap discards
    /// what comes instead of waiting for room.
    pub fn abandon(&self) {
        let mut q = self.queue.lock().unwrap_or_else(|e| e.into_inner());
        q.abandoned = true;
        q.items.clear();
        self.room.notify_all();
    }

    /// The next item handed over by [`TapSlot::push`], waiting at most
    /// `timeout` for one.
    pub fn next(&self, timeout: std::time::Duration) -> Next {
        let mut q = self.queue.lock().unwrap_or_else(|e| e.into_inner());
        if q.items.is_empty() && !q.closed {
            q = self
                .ready
                .wait_timeout(q, timeout)
                .unwrap_or_else(|e| e.into_inner())
                .0;
        }
        match q.items.pop_front() {
            Some(item) => {
                self.room.notify_all();
                Next::Item(item)
            }
            None if q.closed => Next::End,
            None => Next::Wait,
        }
    }

    /// A copy of the frames kept by a tap with `history_s` (empty for
    /// others). The tap does not wait while this copies: what arrives
    /// meanwhile is handed over at its next frame.
    pub fn history(&self) -> FrameHistory {
        let h = self.history.lock().unwrap_or_else(|e| e.into_inner());
        FrameHistory {
            frames: h.frames.iter().cloned().collect(),
            restarts: h.restarts,
        }
    }

    /// Times the history started over because frames were lost.
    pub fn history_restarts(&self) -> u64 {
        self.history
            .lock()
            .unwrap_or_else(|e| e.into_inner())
            .restarts
    }

    /// Adds `f` to the history, trimmed to `lim`. Never waits: while a
    /// reader holds the history, frames wait in `pending` (up to an eighth
    /// of the history's memory; past that the history starts over).
    pub fn record(&self, f: &crate::frame::Frame, lim: HistoryLimits, pending: &mut Pending) {
        let mut h = match self.history.try_lock() {
            Ok(h) => h,
            Err(TryLockError::Poisoned(p)) => p.into_inner(),
            Err(TryLockError::WouldBlock) => {
                let size = f.width() * f.height();
                if pending.bytes + size > lim.max_bytes / 8 {
                    pending.gap = true;
                    pending.bytes = 0;
                    let lost = std::mem::take(&mut pending.frames);
                    pending.free.extend(lost);
                    return;
                }
                let mut tf = pending.free.pop().unwrap_or_default();
                copy_frame(f, &mut tf);
                pending.bytes += tf.gray.len();
                pending.frames.push_back(tf);
                return;
            }
        };
        if std::mem::take(&mut pending.gap) {
            h.restarts += 1;
            pending.free.extend(h.frames.drain(..));
            h.bytes = 0;
        }
        pending.bytes = 0;
        while let Some(tf) = pending.frames.pop_front() {
            h.push(tf, lim, &mut pending.free);
        }
        let mut tf = pending.free.pop().unwrap_or_default();
        copy_frame(f, &mut tf);
        h.push(tf, lim, &mut pending.free);
    }
}

impl History {
    /// Appends `tf`; drops (into `free`) the frames older than the span or
    /// over the memory, and everything before a change of frame size.
    fn push(&mut self, tf: TapFrame, lim: HistoryLimits, free: &mut Vec<TapFrame>) {
        if self
            .frames
            .back()
            .is_some_and(|b| (b.width, b.height) != (tf.width, tf.height) || tf.t_ns < b.t_ns)
        {
            free.extend(self.frames.drain(..));
            self.bytes = 0;
        }
        self.bytes += tf.gray.len();
        let newest = tf.t_ns;
        self.frames.push_back(tf);
        while self.frames.len() > 1
            && (self.bytes > lim.max_bytes
                || self
                    .frames
                    .front()
                    .is_some_and(|f| newest - f.t_ns > lim.span_ns))
        {
            if let Some(old) = self.frames.pop_front() {
                self.bytes -= old.gray.len();
                free.push(old);
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::item::Taper;

    fn spectrum(t_ns: i64) -> Item {
        Item::Spectrum(Spectrum {
            t_ns,
            f0_hz: 0.0,
            resolution_hz: 1.0,
            rate_hz: 100.0,
            window: 100,
            taper: Taper::Hann,
            segments: 1,
            power: vec![1.0f32; 51].into(),
        })
    }

    /// Frame `seq` at `seq` ms, 4x2, its pixels all `seq`.
    fn frame(pool: &crate::frame::FramePool, seq: u64) -> crate::frame::Frame {
        let mut f = pool.try_acquire().expect("a frame");
        f.meta_mut().seq = seq;
        f.meta_mut().t_ns = seq as i64 * 1_000_000;
        if let crate::frame::PixelsMut::U8(p) = f.pixels_mut() {
            p.fill(seq as u8);
        }
        f.freeze()
    }

    /// A history keeps the last span of frames, consecutive: frames that
    /// come while a reader holds it are handed over at the next frame; when
    /// more come than the tap can hold meanwhile, it starts over.
    #[test]
    fn a_history_keeps_the_last_frames_and_never_waits() {
        use crate::frame::{Depth, FrameFormat, FramePool};
        let pool = FramePool::new(
            FrameFormat {
                width: 4,
                height: 2,
                depth: Depth::U8,
                bits: 8,
                fps: 1000.0,
                row_timing: None,
            },
            2,
        );
        let s = Observer::new().slot("history");
        // 10 ms of frames, in memory for 64 of them (8 while a reader holds it).
        let lim = HistoryLimits {
            span_ns: 10_000_000,
            max_bytes: 64 * 8,
        };
        let mut pending = Pending::default();
        for k in 0..30 {
            s.record(&frame(&pool, k), lim, &mut pending);
        }
        let seqs = |s: &TapSlot| -> Vec<u64> { s.history().frames.iter().map(|f| f.seq).collect() };
        assert_eq!(seqs(&s), (19..30).collect::<Vec<_>>());
        assert!(s
            .history()
            .frames
            .iter()
            .all(|f| f.gray == vec![f.seq as u8; 8]));
        // A reader holds it for 5 frames: they wait, then join in order.
        let guard = s.history.lock().unwrap();
        for k in 30..35 {
            s.record(&frame(&pool, k), lim, &mut pending);
        }
        drop(guard);
        assert_eq!(seqs(&s), (19..30).collect::<Vec<_>>());
        s.record(&frame(&pool, 35), lim, &mut pending);
        assert_eq!(seqs(&s), (25..36).collect::<Vec<_>>());
        assert_eq!(s.history().restarts, 0);
        // Held for 20 frames: more than the tap holds meanwhile; the
        // history starts over with what came after the loss.
        let guard = s.history.lock().unwrap();
        for k in 36..56 {
            s.record(&frame(&pool, k), lim, &mut pending);
        }
        drop(guard);
        s.record(&frame(&pool, 56), lim, &mut pending);
        let after = seqs(&s);
        assert_eq!(s.history().restarts, 1);
        assert!(after.windows(2).all(|w| w[1] == w[0] + 1), "{after:?}");
        assert_eq!(after.last(), Some(&56));
        assert!(after[0] > 36, "{after:?}");
        // Memory bounds it too: 4 frames' worth.
        let small = HistoryLimits {
            span_ns: i64::MAX,
            max_bytes: 4 * 8,
        };
        let s2 = Observer::new().slot("h2");
        let mut p2 = Pending::default();
        for k in 0..10 {
            s2.record(&frame(&pool, k), small, &mut p2);
        }
        assert_eq!(seqs(&s2), vec![6, 7, 8, 9]);
    }

    #[test]
    fn a_slot_keeps_the_latest_and_skips_while_read() {
        let o = Observer::new();
        let s = o.slot("live");
        assert!(s.snapshot().is_none());
        assert!(s.publish(&spectrum(1)));
        assert!(s.publish(&spectrum(2)));
        let got = s.snapshot().expect("an item");
        assert!(matches!(got.latest, Latest::Spectrum(ref sp) if sp.t_ns == 2));
        assert_eq!(got.seq, 2);
        // A reader holding the slot: the tap skips rather than waits.
        let guard = s.held.lock().unwrap();
        assert!(!s.publish(&spectrum(3)));
        drop(guard);
        assert_eq!(s.skipped(), 1);
        assert_eq!(s.seq(), 2);
        // The same name is the same slot.
        assert!(Arc::ptr_eq(&s, &o.slot("live")));
        assert!(o.stages().is_empty() && o.now_ns().is_none() && !o.stop());
    }
}
