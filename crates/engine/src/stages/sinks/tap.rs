//! `tap`: keeps the latest item for a program watching the run (the
//! studio's live view reads it; see [`crate::observe`]).
//!
//! It never holds the stream up: it is not woken per item (it looks at its
//! ring every 5 ms, so give its input a ring that holds 5 ms of items and
//! some: the studio gives 64 slots), it keeps at most one item per `every_ms`
//! of capture time, skips (and counts) an item that arrives while the
//! reader is copying the last one, and copies frames into its own 8-bit
//! buffer instead of holding a pooled one. In a run that nobody watches
//! (`vibroscope run`), it discards what it receives.
//!
//! With `history_s`, a tap on frames keeps instead the last `history_s`
//! seconds of them (8-bit, at most `history_mb`), consecutive: the studio
//! computes a modal image from them when a peak of the live spectrum is
//! clicked. While the watcher copies them out, frames wait in a buffer of
//! an eighth of that memory; if more come, the history starts over.
//!
//! With `queue`, it hands every item to the watcher in order instead
//! (frames copied as 8-bit), is woken per item, and waits while `queue`
//! items wait unread: a replay is never thinned, and a live source drops
//! by its edges' policy; after the last item the watcher is told the end
//! (the Python package's `vibroscope.items` reads a tap this way).
//!
//! ```toml
//! [[stage]]
//! id = "live"
//! kind = "tap"
//! input = "spectrum"
//! name = "spectrum"   # the slot the watcher reads
//! every_ms = 40       # at most 25 items a second
//! ```

use crate::observe::{HistoryLimits, Pending, TapSlot};
use crate::*;
use std::sync::Arc;

params! {
    /// `tap`'s parameters.
    pub struct TapParams for "tap" {
        name: String = ParamSpec::of(ParamType::Str, Def::Required).doc(
            "the slot a watching program reads (the studio reads `frame`, `samples` and `spectrum`)",
        ),
        every_ms: f64 = ParamSpec::of(ParamType::Float, Def::Float(40.0))
            .floats(0.0, 60_000.0)
            .unit("ms")
            .doc("keep at most one item per this much capture time (0: every item)"),
        history_s: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.0))
            .floats(0.0, 3600.0)
            .unit("s")
            .doc("keep the last this many seconds of frames (8-bit), every one, instead of the latest item (0: the latest only; other items are then ignored)"),
        history_mb: u64 = ParamSpec::of(ParamType::Int, Def::Int(256))
            .ints(1, 65_536)
            .unit("MiB")
            .doc("at most this much memory for the history (older frames go first)"),
        queue: u64 = ParamSpec::of(ParamType::Int, Def::Int(0))
            .ints(0, 65_536)
            .unit("items")
            .doc("hand every item to the watcher in order instead of the latest (frames as 8-bit), waiting while this many wait unread (0: the latest only); the Python package's pipeline iterator reads them"),
    }
}

type P = TapParams;

pub const KIND: KindSpec = KindSpec {
    name: "tap",
    summary: "keeps the latest item for a program watching the run (the studio's live view); never holds the stream up",
    inputs: &[InPort::one(&[
        PortType::Frames,
        PortType::Samples,
        PortType::Audio,
        PortType::Spectrum,
    ])],
    outputs: NO_OUTPUTS,
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        if v.name.trim().is_empty() {
            return Err(p.error("name", "must not be empty"));
        }
        Ok(Box::new(TapPlan(v)))
    },
};

/// How often a tap looks at its input ring (it is never woken per item).
const POLL: std::time::Duration = std::time::Duration::from_millis(5);

struct TapPlan(P);

impl Plan for TapPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let slot = ctx.observer.as_ref().map(|o| o.slot(&self.0.name));
        let history = (self.0.history_s > 0.0).then(|| HistoryLimits {
            span_ns: (self.0.history_s * 1e9) as i64,
            max_bytes: (self.0.history_mb as usize).saturating_mul(1 << 20),
        });
        Ok(Node::Stage(Box::new(Tap {
            slot,
            queue: self.0.queue as usize,
            every_ns: (self.0.every_ms * 1e6) as i64,
            last_ns: None,
            kept: 0,
            seen: 0,
            history,
            pending: Pending::default(),
        })))
    }
}

struct Tap {
    slot: Option<Arc<TapSlot>>,
    /// Every item in order, at most this many unread (0: the latest only).
    queue: usize,
    every_ns: i64,
    last_ns: Option<i64>,
    kept: u64,
    seen: u64,
    /// Keep the last frames instead of the latest item.
    history: Option<HistoryLimits>,
    pending: Pending,
}

impl Stage for Tap {
    fn process(&mut self, _: usize, item: Item, _: &mut Emitter) -> Result<(), StageError> {
        self.seen += 1;
        let Some(slot) = &self.slot else {
            return Ok(());
        };
        if self.queue > 0 {
            if slot.push(&item, self.queue) {
                self.kept += 1;
            }
            return Ok(());
        }
        if let Some(lim) = self.history {
            if let Item::Frame(f) = &item {
                slot.record(f, lim, &mut self.pending);
                self.kept += 1;
            }
            return Ok(());
        }
        let t = item.t_ns();
        if let Some(last) = self.last_ns {
            if t >= last && t - last < self.every_ns {
                slot.count_skip();
                return Ok(());
            }
        }
        if slot.publish(&item) {
            self.last_ns = Some(t);
            self.kept += 1;
        }
        Ok(())
    }

    /// Not woken per item: at 2200 frames a second, a wake-up per frame
    /// cost the source measurable time; looking every 5 ms costs nothing
    /// upstream (the ring holds what arrives meanwhile).
    fn poll_period(&self) -> Option<std::time::Duration> {
        // A reader of every item is woken per item.
        (self.queue == 0).then_some(POLL)
    }

    /// The reader of a queue gets the end after the last item.
    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        if let Some(s) = &self.slot {
            s.close();
        }
        Ok(())
    }

    fn summary(&self) -> Option<String> {
        Some(match &self.slot {
            Some(_) if self.queue > 0 => format!(
                "handed {} of {} items to the watcher in order",
                self.kept, self.seen
            ),
            Some(s) if self.history.is_some() => format!(
                "recorded {} frames of {} items into the watcher's history (started over {} times)",
                self.kept,
                self.seen,
                s.history_restarts()
            ),
            Some(s) => format!(
                "kept {} of {} items for the watcher ({} skipped)",
                self.kept,
                self.seen,
                s.skipped()
            ),
            None => format!("nobody watches this run: {} items discarded", self.seen),
        })
    }
}
