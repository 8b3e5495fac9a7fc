//! `zenoh_sub`: receives the items a `zenoh_pub` publishes in another
//! process or on another host, and hands them on with their capture times
//! ([`crate::session`]). `type` says what the key carries; an item of another
//! type, bytes that are not a vibroscope item or an encoding version this
//! build does not read are reported (the first of each, then a count) and
//! skipped: the stream goes on.
//!
//! Replay (`live = false`, the default): a blocking queue, so a slow
//! pipeline holds the publisher up and nothing is lost; the run ends when
//! `ends` publishers have sent their end marker (and says so if items
//! were missing). Live (`live = true`): a ring that keeps the newest
//! `capacity` items and drops the oldest; every item lost on the way (the
//! ring or the network) is counted from the sequence numbers, as a
//! camera's dropped frames are.

use crate::session::{self as net, Endpoints};
use std::collections::HashMap;
use std::time::Instant;
use vibroscope_core::frame::{FrameMut, PixelsMut};
use vibroscope_core::wire::{self, WireItem, WirePixels};
use vibroscope_core::*;
use zenoh::handlers::{FifoChannel, FifoChannelHandler, RingChannel, RingChannelHandler};
use zenoh::sample::{Sample, SampleKind};
use zenoh::Wait;

const TYPES: &[&str] = &["audio", "samples", "spectrum", "peaks", "frames"];

params! {
    /// `zenoh_sub`'s parameters.
    pub struct ZenohSubParams for "zenoh_sub" {
        key: String = ParamSpec::of(ParamType::Str, Def::Required)
            .doc("zenoh key expression to receive (wildcards allowed: vibroscope/site/*/spectrum)"),
        // The parameter `type` (a keyword): its name must come out as
        // "type", not "r#type" (serde already unraws it).
        r#type: String = ParamSpec::of(ParamType::Choice(TYPES), Def::Str("spectrum"))
            .doc("what the key carries (the output's type)"),
        connect: String = ParamSpec::of(ParamType::Str, Def::Str(""))
            .doc("zenoh endpoints to connect to, comma-separated (\"tcp/10.0.0.1:7447\"); retried until they answer"),
        listen: String = ParamSpec::of(ParamType::Str, Def::Str(""))
            .doc("zenoh endpoints to listen on, comma-separated (\"tcp/0.0.0.0:7447\")"),
        live: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("a live stream: keep the newest `capacity` items, drop (and count) the oldest; false = replay, lose nothing"),
        capacity: usize = ParamSpec::of(ParamType::Int, Def::Int(64))
            .ints(1, 1 << 20)
            .unit("items")
            .doc("items queued between the network and the pipeline"),
        ends: u64 = ParamSpec::of(ParamType::Int, Def::Int(1))
            .ints(0, 1 << 20)
            .doc("end markers (one per publisher) that end the run; 0 = run until stopped or idle"),
        idle_s: Option<f64> = ParamSpec::of(ParamType::Float, Def::Optional)
            .floats(0.001, 1e6)
            .unit("s")
            .doc("end the run after this long with nothing received; default: wait for ever (a publisher killed before its end marker then holds a replay receiver until stopped)"),
    }
}

type P = ZenohSubParams;

pub const KIND: KindSpec = KindSpec {
    name: "zenoh_sub",
    summary: "receives what a zenoh_pub publishes (another process or host): audio, samples, spectra, peak sets or frames, capture times kept",
    inputs: NO_INPUTS,
    outputs: &[OutPort {
        name: "out",
        ty: OutType::FromParam("type"),
    }],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        let ep = net::endpoints(p, &v.connect, &v.listen)?;
        net::check_key(&v.key, true).map_err(|m| p.error("key", m))?;
        if v.ends == 0 && v.idle_s.is_none() && !v.live {
            return Err(p.error(
                "ends",
                "a replay receiver with ends = 0 and no idle_s would never finish; set one",
            ));
        }
        let ty = PortType::from_name(&v.r#type).unwrap_or(PortType::Spectrum);
        Ok(Box::new(SubPlan { p: v, ep, ty }))
    },
};

struct SubPlan {
    p: P,
    ep: Endpoints,
    ty: PortType,
}

/// The subscription and its queue (the subscriber derefs to its handler).
enum Queue {
    Fifo(zenoh::pubsub::Subscriber<FifoChannelHandler<Sample>>),
    Ring(zenoh::pubsub::Subscriber<RingChannelHandler<Sample>>),
}

impl Queue {
    fn recv(&self) -> Result<Option<Sample>, String> {
        match self {
            Queue::Fifo(q) => q.recv_timeout(net::POLL),
            Queue::Ring(q) => q.recv_timeout(net::POLL),
        }
        .map_err(|e| e.to_string())
    }
}

impl Plan for SubPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let session = net::open_session(&self.ep)?;
        let key = self.p.key.clone();
        let builder = session.declare_subscriber(key.clone());
        let err = |e: zenoh::Error| {
            StageError::device("zenoh", format!("cannot subscribe to {key}: {e}"))
        };
        let queue = if self.p.live {
            Queue::Ring(
                builder
                    .with(RingChannel::new(self.p.capacity))
                    .wait()
                    .map_err(err)?,
            )
        } else {
            Queue::Fifo(
                builder
                    .with(FifoChannel::new(self.p.capacity))
                    .wait()
                    .map_err(err)?,
            )
        };
        Ok(Node::Source(Box::new(Sub {
            key: self.p.key,
            ty: self.ty,
            live: self.p.live,
            ends: self.p.ends,
            idle: self.p.idle_s.map(std::time::Duration::from_secs_f64),
            pool_frames: ctx.pool_frames.max(2),
            queue,
            session,
            next_seq: HashMap::new(),
            ended: 0,
            received: 0,
            missing: 0,
            rejected: HashMap::new(),
            pool: None,
            last: Instant::now(),
        })))
    }
    fn is_live(&self) -> bool {
        self.p.live
    }
}

struct Sub {
    key: String,
    ty: PortType,
    live: bool,
    ends: u64,
    idle: Option<std::time::Duration>,
    pool_frames: usize,
    queue: Queue,
    session: zenoh::Session,
    /// Next sequence number expected, per publishing key.
    next_seq: HashMap<String, u64>,
    ended: u64,
    received: u64,
    /// Items lost between publisher and here (sequence gaps, short ends).
    missing: u64,
    /// What was refused, by reason: (count, first message).
    rejected: HashMap<&'static str, (u64, String)>,
    pool: Option<FramePool>,
    last: Instant,
}

impl Sub {
    fn reject(&mut self, why: &'static str, msg: String) {
        let e = self.rejected.entry(why).or_insert((0, String::new()));
        if e.0 == 0 {
            tracing::warn!(key = %self.key, "skipped: {msg} (further ones are counted)");
            e.1 = msg;
        }
        e.0 += 1;
    }

    /// Accounts for `seq` from `from`: the items missing before it are
    /// counted as lost (and as dropped in the run's statistics).
    fn gap(&mut self, from: &str, seq: u64, ctx: &SourceCtx<'_>) {
        let next = self.next_seq.entry(from.to_string()).or_insert(0);
        let lost = seq.saturating_sub(*next);
        *next = (*next).max(seq + 1);
        if lost > 0 {
            self.missing += lost;
            ctx.count_dropped(lost);
        }
    }

    fn item_of(&mut self, w: WireItem, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError> {
        Ok(Some(match w {
            WireItem::Audio(a) => Item::Audio(a),
            WireItem::Samples(s) => Item::Samples(s),
            WireItem::Spectrum(s) => Item::Spectrum(s),
            WireItem::Peaks(p) => Item::Peaks(p),
            WireItem::Frame(f) => {
                if self.pool.as_ref().is_some_and(|p| p.format() != &f.format) {
                    return Err(StageError::format(format!(
                        "{}: the frames changed format mid-stream ({}x{} {}-bit at {} fps)",
                        self.key, f.format.width, f.format.height, f.format.bits, f.format.fps
                    )));
                }
                let pool = self
                    .pool
                    .get_or_insert_with(|| FramePool::new(f.format, self.pool_frames));
                let Some(mut out) = ctx.acquire(pool) else {
                    return Ok(None);
                };
                copy_pixels(&mut out, &f.pixels);
                *out.meta_mut() = f.meta;
                Item::Frame(out.freeze())
            }
        }))
    }
}

fn copy_pixels(out: &mut FrameMut, px: &WirePixels) {
    match (out.pixels_mut(), px) {
        (PixelsMut::U8(d), WirePixels::U8(s)) => d.copy_from_slice(s),
        (PixelsMut::U16(d), WirePixels::U16(s)) => d.copy_from_slice(s),
        // The pool was made from this frame's format, so depths agree.
        _ => {}
    }
}

impl Source for Sub {
    fn next(&mut self, ctx: &SourceCtx<'_>) -> Result<Option<Item>, StageError> {
        loop {
            if ctx.should_stop() {
                return Ok(None);
            }
            if self.ends > 0 && self.ended >= self.ends {
                return Ok(None);
            }
            let sample = match self.queue.recv() {
                Ok(Some(s)) => s,
                Ok(None) => {
                    if self.idle.is_some_and(|d| self.last.elapsed() >= d) {
                        tracing::info!(key = %self.key, "nothing received for {:?}: ending", self.idle.unwrap_or_default());
                        return Ok(None);
                    }
                    continue;
                }
                Err(e) => {
                    return Err(StageError::device("zenoh", format!("{}: {e}", self.key)));
                }
            };
            self.last = Instant::now();
            let from = sample.key_expr().as_str().to_string();
            let Some(seq) = net::read_seq(sample.attachment()) else {
                self.reject(
                    "no-seq",
                    format!("a sample on {from} has no sequence number: not from zenoh_pub"),
                );
                continue;
            };
            if sample.kind() == SampleKind::Delete {
                // The end marker: `seq` is how many items were sent.
                let got = self.next_seq.get(&from).copied().unwrap_or(0);
                if got < seq {
                    self.missing += seq - got;
                    ctx.count_dropped(seq - got);
                }
                self.next_seq.remove(&from);
                self.ended += 1;
                continue;
            }
            let bytes = sample.payload().to_bytes();
            let w = match wire::decode(&bytes) {
                Ok(w) => w,
                Err(e) => {
                    let why = match e {
                        wire::WireError::UnknownVersion { .. } => "version",
                        _ => "garbage",
                    };
                    self.reject(why, format!("{} bytes on {from}: {e}", bytes.len()));
                    // It took a sequence number (skipped, not lost); what
                    // was missing before it was lost.
                    self.gap(&from, seq, ctx);
                    continue;
                }
            };
            self.gap(&from, seq, ctx);
            let wt = match &w {
                WireItem::Audio(_) => PortType::Audio,
                WireItem::Samples(_) => PortType::Samples,
                WireItem::Spectrum(_) => PortType::Spectrum,
                WireItem::Peaks(_) => PortType::Peaks,
                WireItem::Frame(_) => PortType::Frames,
            };
            if wt != self.ty {
                self.reject(
                    "type",
                    format!("{from} carries {wt}, this source receives {}", self.ty),
                );
                continue;
            }
            self.received += 1;
            return self.item_of(w, ctx);
        }
    }

    fn is_live(&self) -> bool {
        self.live
    }
}

impl Drop for Sub {
    fn drop(&mut self) {
        let mut parts = vec![format!("{} items received", self.received)];
        if self.missing > 0 {
            parts.push(format!("{} lost on the way", self.missing));
        }
        for (why, (n, first)) in &self.rejected {
            parts.push(format!("{n} skipped ({why}; first: {first})"));
        }
        tracing::info!(key = %self.key, "{}", parts.join(", "));
        let _ = self.session.close().wait();
    }
}
