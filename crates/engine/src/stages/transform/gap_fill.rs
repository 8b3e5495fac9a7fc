//! `gap_fill`: per-row samples (from `rows`) onto a uniform grid at 1/d,
//! with the frame-delay gaps filled (thesis ch. 4.5, after Janssen,
//! Veldhuis & Vries 1986; see [`vibroscope_math::ar_interp`]).
//!
//! The grid is t_k = t_first + k·d, where t_first is the capture time of
//! the first row seen and d = 1/rate_hz of the incoming blocks. Each row
//! sample sits at its own capture time (`times_ns`); grid points inside a
//! frame are read off the rows by linear interpolation in time (exact when
//! the frame period is a whole number of line delays; otherwise a shift of
//! less than one row, negligible at audio frequencies at 1/d). Grid points
//! between frames are missing and filled by `method = "ar"` (default) or
//! `"linear"`.
//!
//! Streaming with one frame of look-ahead: when frame n arrives, the gap
//! before it is filled (its right-hand context is frame n) and the gap and
//! frame n's rows leave together as one audio block. Gaps longer than
//! `max_gap_s` (dropped frames) are not bridged: the next block starts at
//! its own time.
//!
//! With `report_latency = true`, `finish` prints how late the oldest sample
//! of each block left, on the wall clock, relative to the earliest
//! delivery seen (live runs; see the README).

use crate::*;
use serde::{Deserialize, Serialize};
use std::sync::Arc;
use std::time::Instant;
use vibroscope_math::ar_interp::{linear_fill, ArInterpolator};

#[derive(Deserialize, Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "lowercase")]
pub enum FillMethod {
    Ar,
    Linear,
}

params! {
    /// `gap_fill`'s parameters.
    pub struct GapFillParams for "gap_fill" {
        method: FillMethod = ParamSpec::of(
            ParamType::Choice(&["ar", "linear"]),
            Def::Str("ar"),
        )
        .doc("fill gaps by AR interpolation (Janssen et al. 1986) or linearly"),
        order: usize = ParamSpec::of(ParamType::Int, Def::Int(128))
            .ints(1, 1024)
            .doc("AR model order"),
        iterations: usize = ParamSpec::of(ParamType::Int, Def::Int(2))
            .ints(1, 16)
            .doc("rounds of estimate-then-interpolate"),
        decimate: usize = ParamSpec::of(ParamType::Int, Def::Int(8))
            .ints(1, 64)
            .doc("bridge gaps at 1/decimate of the row rate (1 = at the row rate)"),
        context: usize = ParamSpec::of(ParamType::Int, Def::Int(2048))
            .ints(2, 1 << 20)
            .unit("samples")
            .doc("known samples used on each side of a gap"),
        max_gap_s: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.1))
            .above_upto(0.0, 10.0)
            .unit("s")
            .doc("longest gap bridged"),
        report_latency: bool = ParamSpec::of(ParamType::Bool, Def::Bool(false))
            .doc("print the output's wall-clock latency at the end (live runs)"),
    }
}

type P = GapFillParams;

pub const KIND: KindSpec = KindSpec {
    name: "gap_fill",
    summary: "rolling shutter: row samples onto a uniform grid at 1/d, frame-delay gaps filled (AR, Janssen et al. 1986, or linear)",
    inputs: &[InPort::one(&[PortType::Samples])],
    outputs: &[OutPort::out(PortType::Audio)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        Ok(Box::new(FillPlan(v)))
    },
};

struct FillPlan(P);

impl Plan for FillPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        let v = self.0;
        Ok(Node::Stage(Box::new(GapFill {
            ar: ArInterpolator::new(v.order, v.iterations).with_decimation(v.decimate),
            p: v,
            grid: None,
            hist: Vec::new(),
            cur: Vec::new(),
            win: Vec::new(),
            out: Vec::new(),
            lat: LatencyMeter::default(),
            frame_period_ns: 0.0,
            last_t0: None,
        })))
    }
}

/// The uniform output grid.
#[derive(Clone, Copy)]
struct Grid {
    base_ns: i64,
    d_ns: f64,
    rate_hz: f64,
    /// Next grid index to emit.
    next_k: i64,
}

/// Wall-clock latency of a stage's output (live runs): how late the oldest
/// sample of each emitted block leaves, against its capture time. Capture
/// times are on the source's clock; the offset between the two clocks is
/// taken as the smallest (arrival - newest capture time) seen, i.e. the
/// fastest delivery counts as instantaneous, so the figure is a lower bound
/// by that delivery time (a few ms here). Only reporting reads the clock;
/// the output does not depend on it.
#[derive(Default)]
pub struct LatencyMeter {
    epoch: Option<Instant>,
    min_offset: f64,
    max_age: f64,
    sum_age: f64,
    blocks: u64,
}

impl LatencyMeter {
    fn ns(&mut self, t: Instant) -> f64 {
        let e = *self.epoch.get_or_insert(t);
        t.duration_since(e).as_nanos() as f64
    }

    /// A block arrived at `now`; its newest sample was captured at `newest_ns`.
    pub fn arrived(&mut self, now: Instant, newest_ns: i64) {
        let off = self.ns(now) - newest_ns as f64;
        self.min_offset = if self.blocks == 0 {
            off
        } else {
            self.min_offset.min(off)
        };
    }

    /// A block whose oldest sample was captured at `oldest_ns` is leaving now.
    pub fn emitted(&mut self, oldest_ns: i64) {
        let age = self.ns(Instant::now()) - oldest_ns as f64;
        self.max_age = if self.blocks == 0 {
            age
        } else {
            self.max_age.max(age)
        };
        self.sum_age += age;
        self.blocks += 1;
    }

    /// (max, mean) latency in ms, if anything was emitted.
    pub fn summary_ms(&self) -> Option<(f64, f64)> {
        (self.blocks > 0).then(|| {
            (
                (self.max_age - self.min_offset) * 1e-6,
                (self.sum_age / self.blocks as f64 - self.min_offset) * 1e-6,
            )
        })
    }

    pub fn blocks(&self) -> u64 {
        self.blocks
    }
}

struct GapFill {
    p: P,
    ar: ArInterpolator,
    grid: Option<Grid>,
    /// The last `context` samples emitted (known and filled).
    hist: Vec<f64>,
    cur: Vec<f64>,
    win: Vec<f64>,
    out: Vec<f32>,
    lat: LatencyMeter,
    frame_period_ns: f64,
    last_t0: Option<i64>,
}

impl GapFill {
    /// Reads the rows of one block onto grid points; returns the first grid index.
    fn place(&mut self, g: &Grid, values: &[f32], times: &[i64]) -> i64 {
        self.cur.clear();
        let pos = |t: i64| (t - g.base_ns) as f64 / g.d_ns;
        let (p0, p1) = (pos(times[0]), pos(times[times.len() - 1]));
        let k0 = (p0 - 1e-6).ceil() as i64;
        let k1 = (p1 + 1e-6).floor() as i64;
        let mut i = 0;
        for k in k0..=k1 {
            let kf = k as f64;
            while i + 1 < times.len() && pos(times[i + 1]) < kf {
                i += 1;
            }
            let v = if i + 1 < times.len() {
                let (a, b) = (pos(times[i]), pos(times[i + 1]));
                let w = if b > a {
                    ((kf - a) / (b - a)).clamp(0.0, 1.0)
                } else {
                    0.0
                };
                values[i] as f64 * (1.0 - w) + values[i + 1] as f64 * w
            } else {
                values[i] as f64
            };
            self.cur.push(v);
        }
        k0
    }
}

impl Stage for GapFill {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Samples(s) = item else {
            return Err(StageError::expected("samples"));
        };
        if s.channels != 1 {
            return Err(StageError::format(format!(
                "expected one channel of row samples (from `rows`), got {}",
                s.channels
            )));
        }
        if s.data.is_empty() {
            return Ok(());
        }
        if !(s.rate_hz.is_finite() && s.rate_hz > 0.0) {
            return Err(StageError::format(format!("bad row rate {} Hz", s.rate_hz)));
        }
        let now = Instant::now();
        let nominal: Vec<i64>;
        let times: &[i64] = match &s.times_ns {
            Some(t) if t.len() == s.data.len() => t,
            Some(t) => {
                return Err(StageError::format(format!(
                    "{} times for {} samples",
                    t.len(),
                    s.data.len()
                )))
            }
            None => {
                // Uniform blocks: time follows t0 and the rate (the documented contract).
                nominal = (0..s.data.len())
                    .map(|i| s.t0_ns + (i as f64 * 1e9 / s.rate_hz).round() as i64)
                    .collect();
                &nominal
            }
        };
        let fresh = match self.grid {
            Some(g) => (g.rate_hz - s.rate_hz).abs() > 1e-9 * s.rate_hz,
            None => true,
        };
        if fresh {
            self.grid = Some(Grid {
                base_ns: times[0],
                d_ns: 1e9 / s.rate_hz,
                rate_hz: s.rate_hz,
                next_k: 0,
            });
            self.hist.clear();
        }
        let Some(mut g) = self.grid else {
            return Ok(());
        };
        let k0 = self.place(&g, &s.data, times);
        if fresh {
            g.next_k = k0;
        }
        let mut gap = k0 - g.next_k;
        let max_gap = (self.p.max_gap_s * g.rate_hz).ceil() as i64;
        if gap > max_gap {
            tracing::warn!(
                missing = gap,
                "gap too long to bridge; the next block starts at its own time"
            );
            self.hist.clear();
            g.next_k = k0;
            gap = 0;
        }
        // Rows overlapping samples already emitted are dropped.
        let skip = (-gap).max(0) as usize;
        let gap = gap.max(0) as usize;
        let cur = &self.cur[skip.min(self.cur.len())..];
        self.out.clear();
        if gap > 0 {
            let left = self.hist.len().min(self.p.context);
            let right = cur.len().min(self.p.context);
            self.win.clear();
            self.win
                .extend_from_slice(&self.hist[self.hist.len() - left..]);
            self.win.resize(left + gap, 0.0);
            self.win.extend_from_slice(&cur[..right]);
            match self.p.method {
                FillMethod::Ar => self.ar.fill(&mut self.win, left, gap),
                FillMethod::Linear => linear_fill(&mut self.win, left, gap),
            }
            self.out
                .extend(self.win[left..left + gap].iter().map(|&v| v as f32));
        }
        self.out.extend(cur.iter().map(|&v| v as f32));
        if self.out.is_empty() {
            return Ok(());
        }
        // History for the next gap: the emitted samples, newest last.
        self.hist.extend(self.out.iter().map(|&v| v as f64));
        if self.hist.len() > self.p.context {
            let extra = self.hist.len() - self.p.context;
            self.hist.drain(..extra);
        }
        let t0 = g.base_ns + (g.next_k as f64 * g.d_ns).round() as i64;
        g.next_k += self.out.len() as i64;
        self.grid = Some(g);
        let _ = out.emit(Item::Audio(AudioBlock {
            t0_ns: t0,
            rate_hz: g.rate_hz,
            samples: Arc::from(&self.out[..]),
        }));
        if self.p.report_latency {
            self.lat.arrived(now, times[times.len() - 1]);
            self.lat.emitted(t0);
            if let Some(p) = self.last_t0 {
                self.frame_period_ns = (s.t0_ns - p) as f64;
            }
            self.last_t0 = Some(s.t0_ns);
        }
        Ok(())
    }

    fn finish(&mut self, _: &mut Emitter) -> Result<(), StageError> {
        if let (true, Some((max, mean))) = (self.p.report_latency, self.lat.summary_ms()) {
            let period = self.frame_period_ns * 1e-6;
            eprintln!(
                "gap_fill latency (oldest sample of each block, capture to emission): max {max:.2} ms, mean {mean:.2} ms over {} blocks; frame period {period:.2} ms ({:.2} periods at most)",
                self.lat.blocks(),
                if period > 0.0 { max / period } else { f64::NAN }
            );
        }
        Ok(())
    }
}
