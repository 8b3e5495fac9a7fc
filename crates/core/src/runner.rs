//! The runner: one thread per stage, one ring per edge.
//!
//! End of stream travels downstream as edges closing: a source returns
//! `None`, its edges close, each stage drains what is queued, calls
//! `finish`, and closes its own outputs. An error in a stage raises the
//! graceful stop (sources end, queues drain) and is reported with the stage
//! id; sinks still finalise what reached them.

use super::edge::{edge, edge_resuming_at_half, EdgeRx, EdgeStats, Recv};
use super::graph::{BuildCtx, Graph};
use super::item::PortType;
use super::latency::{LatencyHist, LatencySummary};
use super::observe::{Counted, Observer, StageLive, Watched};
use super::stage::{Control, EmitError, Emitter, Node, SourceCtx, StageError};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};

/// Options of one run.
#[derive(Clone, Debug, Default)]
pub struct RunOptions {
    /// Count the frames the sources give, for a caller's own progress
    /// display (read it from another thread while the run goes on).
    pub counter: Option<Arc<SourceProgress>>,
    /// Watch the run while it goes on: its stages' counters and the latest
    /// item of each `tap` stage (see [`crate::observe`]).
    pub observer: Option<Arc<Observer>>,
}

/// Frames the sources of a run have given, and how many they will give.
#[derive(Debug, Default)]
pub struct SourceProgress {
    frames: AtomicU64,
    total: AtomicU64,
    unknown: std::sync::atomic::AtomicBool,
}

impl SourceProgress {
    /// Frames given so far.
    pub fn frames(&self) -> u64 {
        self.frames.load(Ordering::Relaxed)
    }

    /// Frames the sources will give, when every source knows its length.
    pub fn total(&self) -> Option<u64> {
        let t = self.total.load(Ordering::Relaxed);
        (!self.unknown.load(Ordering::Relaxed) && t > 0).then_some(t)
    }
}

/// A whole number with thousands separators: `4,452`.
pub fn thousands(n: u64) -> String {
    let s = n.to_string();
    let mut out = String::with_capacity(s.len() + s.len() / 3);
    for (i, c) in s.chars().enumerate() {
        if i > 0 && (s.len() - i).is_multiple_of(3) {
            out.push(',');
        }
        out.push(c);
    }
    out
}

/// What one stage did.
#[derive(Clone, Debug)]
pub struct StageReport {
    pub id: String,
    pub kind: &'static str,
    pub items_in: u64,
    pub items_out: u64,
    /// Items evicted from this stage's input rings (drop-oldest); for a
    /// source, frames the device dropped before delivering them.
    pub dropped: u64,
    /// Highest occupancy seen on any input ring, and that ring's capacity.
    pub max_queue: u64,
    pub queue_capacity: u64,
    /// Time spent inside `process`/`next` (not waiting).
    pub busy: Duration,
    /// Capture-to-arrival latency of what reached this sink (live runs only).
    pub latency: Option<LatencySummary>,
    /// What the stage says about how it ran ([`super::stage::Stage::summary`]).
    pub summary: Option<String>,
}

impl StageReport {
    pub fn us_per_item(&self) -> f64 {
        let n = self.items_in.max(self.items_out).max(1);
        self.busy.as_secs_f64() * 1e6 / n as f64
    }
}

/// A stage failure, with the stage that reported it. The message names the
/// stage only; the failure itself is the error's `source`, so chain printers
/// (`{:#}` of anyhow, [`error_chain`]) show each cause once.
#[derive(Debug, thiserror::Error)]
#[error("stage `{stage}`")]
pub struct RunError {
    pub stage: String,
    #[source]
    pub source: StageError,
}

/// The outcome of a run. Sinks have finalised whatever reached them, even
/// when `errors` is not empty or the run was interrupted.
#[derive(Debug)]
pub struct RunReport {
    pub stages: Vec<StageReport>,
    pub errors: Vec<RunError>,
    pub interrupted: bool,
    pub elapsed: Duration,
}

impl RunReport {
    /// A fixed-width summary table (for `--stats`).
    pub fn table(&self) -> String {
        let mut s = format!(
            "{:<16} {:<14} {:>10} {:>10} {:>9} {:>11} {:>12}\n",
            "stage", "kind", "in", "out", "dropped", "queue max", "us/item"
        );
        for r in &self.stages {
            let q = if r.queue_capacity > 0 {
                format!("{}/{}", r.max_queue, r.queue_capacity)
            } else {
                "-".into()
            };
            s += &format!(
                "{:<16} {:<14} {:>10} {:>10} {:>9} {:>11} {:>12.2}\n",
                r.id,
                r.kind,
                r.items_in,
                r.items_out,
                r.dropped,
                q,
                r.us_per_item()
            );
        }
        for r in &self.stages {
            if let Some(m) = &r.summary {
                s += &format!("{}: {m}\n", r.id);
            }
        }
        for r in &self.stages {
            if let Some(l) = r.latency {
                s += &format!(
                    "latency capture -> {}: p50 {:.2} ms, p99 {:.2} ms, max {:.2} ms ({} samples)\n",
                    r.id, l.p50_ms, l.p99_ms, l.max_ms, l.count
                );
            }
        }
        s += &format!("elapsed {:.3} s", self.elapsed.as_secs_f64());
        if let Some(rss) = peak_rss_bytes() {
            s += &format!(", peak RSS {:.1} MiB", rss as f64 / (1024.0 * 1024.0));
        }
        s.push('\n');
        s
    }
}

/// An error and its causes on one line, `a: b: c`.
pub fn error_chain(e: &dyn std::error::Error) -> String {
    let mut s = e.to_string();
    let mut cur = e.source();
    while let Some(c) = cur {
        s.push_str(": ");
        s.push_str(&c.to_string());
        cur = c.source();
    }
    s
}

/// Peak resident memory of this process in bytes (Linux `VmHWM`), if known.
pub fn peak_rss_bytes() -> Option<u64> {
    let s = std::fs::read_to_string("/proc/self/status").ok()?;
    let line = s.lines().find(|l| l.starts_with("VmHWM:"))?;
    let kb: u64 = line.split_whitespace().nth(1)?.parse().ok()?;
    Some(kb * 1024)
}

struct Counters {
    items_in: AtomicU64,
    items_out: Arc<AtomicU64>,
    busy_ns: AtomicU64,
    /// The stage's own threads' working time ([`BuildCtx::worker_busy_ns`]).
    worker_busy_ns: Arc<AtomicU64>,
    /// Frames a source reports lost upstream of it (camera sequence gaps).
    source_dropped: AtomicU64,
    inputs: Vec<Arc<EdgeStats>>,
    capacity: u64,
    /// Sinks of live runs measure capture-to-arrival latency.
    latency: Option<Mutex<LatencyHist>>,
    /// The stage's own summary, taken after `finish`.
    summary: Mutex<Option<String>>,
}

impl Counted for Counters {
    fn live(&self, id: &str, kind: &'static str) -> StageLive {
        let edge = |f: fn(&EdgeStats) -> &AtomicU64| -> u64 {
            self.inputs
                .iter()
                .map(|e| f(e).load(Ordering::Relaxed))
                .sum()
        };
        let pushed = edge(|e| &e.pushed);
        let popped = edge(|e| &e.popped);
        let evicted = edge(|e| &e.dropped);
        StageLive {
            id: id.to_owned(),
            kind,
            items_in: self.items_in.load(Ordering::Relaxed),
            items_out: self.items_out.load(Ordering::Relaxed),
            dropped: evicted + self.source_dropped.load(Ordering::Relaxed),
            queued: pushed.saturating_sub(popped + evicted),
            queue_capacity: self.capacity,
            busy_s: self.busy().as_secs_f64(),
        }
    }
}

impl Counters {
    /// The stage thread's time inside `process`/`next`, or its own
    /// workers' working time when larger.
    fn busy(&self) -> Duration {
        let own = self.busy_ns.load(Ordering::Relaxed);
        Duration::from_nanos(own.max(self.worker_busy_ns.load(Ordering::Relaxed)))
    }
}

/// Builds every stage (opening files and devices), then runs the graph to
/// completion. Errors while building are returned before any thread starts.
pub fn run(graph: Graph, control: Arc<Control>, opts: &RunOptions) -> Result<RunReport, RunError> {
    let start = Instant::now();
    let n = graph.nodes.len();
    let live = graph.is_live();
    let has_consumer: Vec<bool> = {
        let mut v = vec![false; n];
        for node in &graph.nodes {
            for inp in &node.inputs {
                v[inp.from] = true;
            }
        }
        v
    };
    // A source's pool covers every ring frames can sit in, plus what each
    // stage holds while working, plus slack.
    let mut frame_slots = 8usize;
    for node in &graph.nodes {
        let mut takes_frames = false;
        for inp in &node.inputs {
            if inp.port_type == PortType::Frames {
                frame_slots += inp.capacity;
                takes_frames = true;
            }
        }
        if takes_frames {
            frame_slots += 2 + node.plan.frames_held();
        }
    }
    // What each node's output can have in flight: every edge's ring plus
    // what its consumer holds while working.
    let mut held_downstream = vec![0usize; n];
    for node in &graph.nodes {
        for inp in &node.inputs {
            held_downstream[inp.from] += inp.capacity + 2 + node.plan.frames_held();
        }
    }
    // Edges, in node order then input order, so fan-out order is stable.
    let mut outs: Vec<Vec<_>> = (0..n).map(|_| Vec::new()).collect();
    let mut ins: Vec<Vec<EdgeRx>> = (0..n).map(|_| Vec::new()).collect();
    let mut counters = Vec::with_capacity(n);
    for (i, node) in graph.nodes.iter().enumerate() {
        let mut stats = Vec::new();
        let mut cap = 0;
        let single = node.inputs.len() == 1;
        for inp in &node.inputs {
            // A stage with one input drains it whenever it can, so its
            // producer can wait for half the ring (one wake-up per half).
            let (tx, rx, st) = if single {
                edge_resuming_at_half(inp.capacity, inp.policy)
            } else {
                edge(inp.capacity, inp.policy)
            };
            outs[inp.from].push(tx);
            ins[i].push(rx);
            stats.push(st);
            cap = cap.max(inp.capacity as u64);
        }
        counters.push(Arc::new(Counters {
            items_in: AtomicU64::new(0),
            items_out: Arc::new(AtomicU64::new(0)),
            busy_ns: AtomicU64::new(0),
            worker_busy_ns: Arc::default(),
            source_dropped: AtomicU64::new(0),
            inputs: stats,
            capacity: cap,
            latency: (live && !has_consumer[i] && !node.inputs.is_empty())
                .then(|| Mutex::new(LatencyHist::new())),
            summary: Mutex::new(None),
        }));
    }
    // Build (opens files); nothing runs yet.
    let mut built = Vec::with_capacity(n);
    let mut ids = Vec::with_capacity(n);
    let mut kinds = Vec::with_capacity(n);
    for (i, node) in graph.nodes.into_iter().enumerate() {
        let ctx = BuildCtx {
            id: node.id.clone(),
            pool_frames: frame_slots,
            held_downstream: held_downstream[i],
            input_types: node.inputs.iter().map(|inp| inp.port_type).collect(),
            live,
            observer: opts.observer.clone(),
            worker_busy_ns: Arc::clone(&counters[i].worker_busy_ns),
        };
        let built_node = node.plan.build(&ctx).map_err(|e| RunError {
            stage: node.id.clone(),
            source: e,
        })?;
        built.push(built_node);
        ids.push(node.id);
        kinds.push(node.kind.name);
    }
    let errors: Arc<Mutex<Vec<RunError>>> = Arc::new(Mutex::new(Vec::new()));
    // Live capture times count from here.
    control.start_clock();
    if let Some(o) = &opts.observer {
        let watched = ids
            .iter()
            .zip(&kinds)
            .zip(&counters)
            .map(|((id, kind), c)| Watched {
                id: id.clone(),
                kind,
                counters: Arc::clone(c) as Arc<dyn Counted>,
            })
            .collect();
        o.attach(&control, watched);
    }
    let mut handles = Vec::with_capacity(n);
    for (i, ((node, outs), ins)) in built.into_iter().zip(outs).zip(ins).enumerate() {
        let ctl = Arc::clone(&control);
        let errors = Arc::clone(&errors);
        let counters = Arc::clone(&counters[i]);
        let id = ids[i].clone();
        let counter = opts.counter.clone();
        let h = std::thread::Builder::new()
            .name(format!("stage-{id}"))
            .spawn(move || {
                let emitter = Emitter::new(outs, Arc::clone(&ctl), Arc::clone(&counters.items_out));
                let res = match node {
                    Node::Source(src) => {
                        run_source(src, emitter, &ctl, &counters, counter.as_deref())
                    }
                    Node::Stage(st) => run_stage(st, emitter, ins, &ctl, &counters),
                };
                if let Err(e) = res {
                    // Reported to the caller in the RunReport; only traced here.
                    tracing::debug!(stage = %id, error = %e, "stage failed");
                    ctl.stop();
                    errors
                        .lock()
                        .unwrap_or_else(|e| e.into_inner())
                        .push(RunError {
                            stage: id,
                            source: e,
                        });
                }
            });
        match h {
            Ok(h) => handles.push(h),
            Err(e) => {
                control.abort();
                for h in handles {
                    let _ = h.join();
                }
                return Err(RunError {
                    stage: ids[i].clone(),
                    source: StageError::thread("the stage thread", e),
                });
            }
        }
    }
    for (h, id) in handles.into_iter().zip(&ids) {
        if h.join().is_err() {
            errors
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push(RunError {
                    stage: id.clone(),
                    source: StageError::Panicked,
                });
        }
    }
    let stages = ids
        .into_iter()
        .zip(kinds)
        .zip(&counters)
        .map(|((id, kind), c)| StageReport {
            id,
            kind,
            items_in: c.items_in.load(Ordering::Relaxed),
            items_out: c.items_out.load(Ordering::Relaxed),
            dropped: c
                .inputs
                .iter()
                .map(|s| s.dropped.load(Ordering::Relaxed))
                .sum::<u64>()
                + c.source_dropped.load(Ordering::Relaxed),
            max_queue: c
                .inputs
                .iter()
                .map(|s| s.max_occupancy.load(Ordering::Relaxed))
                .max()
                .unwrap_or(0),
            queue_capacity: c.capacity,
            busy: c.busy(),
            latency: c
                .latency
                .as_ref()
                .and_then(|h| h.lock().unwrap_or_else(|e| e.into_inner()).summary()),
            summary: c.summary.lock().unwrap_or_else(|e| e.into_inner()).take(),
        })
        .collect::<Vec<_>>();
    for r in &stages {
        tracing::info!(stage = %r.id, kind = r.kind, items_in = r.items_in, items_out = r.items_out, dropped = r.dropped, max_queue = r.max_queue, us_per_item = r.us_per_item(), "stage finished");
    }
    let errors = std::mem::take(&mut *errors.lock().unwrap_or_else(|e| e.into_inner()));
    let interrupted = control.sources_should_stop() && errors.is_empty();
    Ok(RunReport {
        stages,
        errors,
        interrupted,
        elapsed: start.elapsed(),
    })
}

fn run_source(
    mut src: Box<dyn super::stage::Source>,
    mut out: Emitter,
    control: &Control,
    c: &Counters,
    counter: Option<&SourceProgress>,
) -> Result<(), StageError> {
    if let Some(k) = counter {
        match src.total_hint() {
            Some(t) => {
                k.total.fetch_add(t, Ordering::Relaxed);
            }
            None => k.unknown.store(true, Ordering::Relaxed),
        }
    }
    let ctx = SourceCtx {
        control,
        dropped: &c.source_dropped,
    };
    loop {
        if control.sources_should_stop() {
            break Ok(());
        }
        let t = Instant::now();
        let item = src.next(&ctx);
        c.busy_ns
            .fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
        match item {
            Ok(Some(item)) => match out.emit(item) {
                Ok(()) => {
                    if let Some(k) = counter {
                        k.frames.fetch_add(1, Ordering::Relaxed);
                    }
                }
                Err(EmitError::Disconnected) | Err(EmitError::Stopped) => break Ok(()),
            },
            Ok(None) => break Ok(()),
            Err(e) => break Err(e),
        }
    }
}

fn run_stage(
    mut st: Box<dyn super::stage::Stage>,
    mut out: Emitter,
    mut ins: Vec<EdgeRx>,
    control: &Control,
    c: &Counters,
) -> Result<(), StageError> {
    // Round-robin over open inputs, one item each in port order: the merge
    // order depends only on the data, never on thread timing.
    let mut open: Vec<bool> = vec![true; ins.len()];
    let mut port = 0usize;
    let mut result = Ok(());
    // Only this thread records; the lock is uncontended until the report.
    let mut latency = c
        .latency
        .as_ref()
        .map(|h| h.lock().unwrap_or_else(|e| e.into_inner()));
    let poll = st.poll_period();
    'outer: while open.iter().any(|&o| o) {
        if !open[port] {
            port = (port + 1) % ins.len();
            continue;
        }
        let got = match poll {
            Some(period) => ins[port].recv_polling(&control.hard_stop, period),
            None => ins[port].recv(&control.hard_stop),
        };
        match got {
            Recv::Item(item) => {
                c.items_in.fetch_add(1, Ordering::Relaxed);
                if let Some(h) = latency.as_mut() {
                    h.record_item(&item, control.now_ns());
                }
                let t = Instant::now();
                let r = st.process(port, item, &mut out);
                c.busy_ns
                    .fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
                if let Err(e) = r {
                    result = Err(e);
                    break 'outer;
                }
            }
            Recv::Closed => open[port] = false,
            Recv::Stopped => break 'outer,
        }
        port = (port + 1) % ins.len();
    }
    drop(latency);
    // Stop listening before finishing so upstream is not held up by us.
    drop(std::mem::take(&mut ins));
    let t = Instant::now();
    let fin = st.finish(&mut out);
    c.busy_ns
        .fetch_add(t.elapsed().as_nanos() as u64, Ordering::Relaxed);
    *c.summary.lock().unwrap_or_else(|e| e.into_inner()) = st.summary();
    result.and(fin)
}
