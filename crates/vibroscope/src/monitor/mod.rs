//! `vibroscope monitor`: the resonances of many cameras and regions,
//! tracked over time, with alarms when one moves (issue 21).
//!
//! It subscribes (zenoh) to the peak sets that camera nodes publish
//! (`resonances` -> `zenoh_pub`), follows each resonance of each source
//! ([`track`]), and reports as JSON lines: a track found, an alarm (a
//! resonance beyond k standard deviations of its own history, or gone from
//! its gate), an alarm cleared, a source gone quiet (stale) or back, a
//! stream ended, input refused. Everything goes to an SQLite history
//! ([`history`]) that a restarted monitor continues from. The same events
//! are published on `<events key>` for the studio or another subscriber.

pub mod feed;
pub mod history;
pub mod track;

use crate::engine::wire::{self, WireItem};
use crate::engine::PeakSet;
use crate::error::{Error, Result, UsageError};
use history::History;
use serde_json::json;
use std::collections::HashMap;
use std::io::Write;
use std::path::PathBuf;
use std::time::{Duration, Instant};
use track::{Event, SourceTracker, Stats, TrackConfig};
use vibroscope_net::session::{self as net, Endpoints};
use zenoh::handlers::FifoChannel;
use zenoh::sample::SampleKind;
use zenoh::Wait;

/// What `vibroscope monitor` is asked to do.
#[derive(Clone, Debug)]
pub struct MonitorOptions {
    /// Key expression of the peak sets (wildcards allowed).
    pub key: String,
    pub endpoints: Endpoints,
    /// The history file.
    pub db: PathBuf,
    pub track: TrackConfig,
    /// A source with nothing for this long is reported stale.
    pub stale_after: Duration,
    /// Stop after this long (`None`: until interrupted).
    pub run_for: Option<Duration>,
    /// Where events are also published (`None`: not published).
    pub events_key: Option<String>,
}

impl MonitorOptions {
    pub fn check(&self) -> Result<()> {
        let usage = |flag: &'static str, m: String| -> Error { UsageError::new(flag, m).into() };
        net::check_key(&self.key, true).map_err(|m| usage("--key", m))?;
        if self.endpoints.listen.is_empty() && self.endpoints.connect.is_empty() {
            return Err(usage(
                "--listen",
                "give --listen (the cameras connect here) or --connect (to a camera or router), or both".into(),
            ));
        }
        if let Some(k) = &self.events_key {
            net::check_key(k, false).map_err(|m| usage("--events-key", m))?;
        }
        let t = &self.track;
        if !(t.k.is_finite() && t.k > 0.0) {
            return Err(usage("--k", format!("must be a number > 0, got {}", t.k)));
        }
        if t.persist == 0 || t.baseline == 0 || t.window < 2 {
            return Err(usage(
                "--persist",
                "--persist and --baseline must be at least 1 and --window at least 2".into(),
            ));
        }
        if !(t.gate_rel > 0.0 && t.gate_rel < 1.0 && t.cluster_rel > 0.0 && t.cluster_rel < 1.0) {
            return Err(usage(
                "--gate",
                format!("must be a fraction in (0, 1), got {}", t.gate_rel),
            ));
        }
        Ok(())
    }
}

/// What a monitor run saw, printed at the end.
#[derive(Clone, Debug, Default, serde::Serialize)]
pub struct MonitorReport {
    pub db: PathBuf,
    pub sources: usize,
    pub peak_sets: u64,
    pub alarms: u64,
    pub stale: u64,
    pub refused: u64,
    pub rows_written: u64,
}

struct SourceState {
    tracker: SourceTracker,
    last: Instant,
    stale: bool,
    ended: bool,
    refused: HashMap<&'static str, u64>,
}

/// Runs until interrupted (or `run_for`), printing JSON lines to `out`.
pub fn run(opts: &MonitorOptions, out: &mut dyn Write) -> Result<MonitorReport> {
    opts.check()?;
    let _steps = crate::pipeline::Steps::begin();
    let mut hist = History::open(&opts.db).map_err(|e| Error::Input {
        path: e.path.clone(),
        message: e.message.clone(),
    })?;
    let loaded = hist.load(&opts.track).map_err(|e| Error::Input {
        path: e.path.clone(),
        message: e.message.clone(),
    })?;
    let now = Instant::now();
    let mut sources: HashMap<String, SourceState> = loaded
        .into_iter()
        .map(|(k, tracker)| {
            (
                k,
                SourceState {
                    tracker,
                    last: now,
                    stale: false,
                    ended: false,
                    refused: HashMap::new(),
                },
            )
        })
        .collect();
    let session = net::open_session_plain(&opts.endpoints).map_err(Error::Device)?;
    let sub = session
        .declare_subscriber(opts.key.clone())
        .with(FifoChannel::new(1024))
        .wait()
        .map_err(|e| Error::Device(format!("cannot subscribe to {}: {e}", opts.key)))?;
    let events_pub = match &opts.events_key {
        Some(k) => Some(
            session
                .declare_publisher(k.clone())
                .wait()
                .map_err(|e| Error::Device(format!("cannot publish on {k}: {e}")))?,
        ),
        None => None,
    };
    let mut report = MonitorReport {
        db: opts.db.clone(),
        ..Default::default()
    };
    let mut emit = |hist: &mut History,
                    source: &str,
                    track: Option<u32>,
                    kind: &'static str,
                    mut v: serde_json::Value| {
        v["event"] = json!(kind);
        v["source"] = json!(source);
        if let Some(t) = track {
            v["track"] = json!(t);
        }
        let line = v.to_string();
        // stdout closed (a pipe reader gone) must not stop the monitor.
        let _ = writeln!(out, "{line}").and_then(|_| out.flush());
        if let Some(p) = &events_pub {
            let _ = p.put(line.as_bytes()).wait();
        }
        hist.event(source, track, kind, line);
    };
    let tracks_total: usize = sources.values().map(|s| s.tracker.tracks.len()).sum();
    emit(
        &mut hist,
        "",
        None,
        "start",
        json!({"db": opts.db, "key": opts.key, "sources": sources.len(), "tracks": tracks_total,
               "k": opts.track.k, "persist": opts.track.persist}),
    );
    let started = Instant::now();
    let mut db_error: Option<String> = None;
    let result = loop {
        if let Err(e) = crate::pipeline::check_interrupt() {
            break Err(e);
        }
        if opts.run_for.is_some_and(|d| started.elapsed() >= d) {
            break Ok(());
        }
        let sample = match sub.recv_timeout(Duration::from_millis(100)) {
            Ok(s) => s,
            Err(e) => {
                break Err(Error::Device(format!(
                    "zenoh subscriber on {}: {e}",
                    opts.key
                )))
            }
        };
        if let Some(sample) = sample {
            let source = sample.key_expr().as_str().to_string();
            let st = sources
                .entry(source.clone())
                .or_insert_with(|| SourceState {
                    tracker: SourceTracker::new(opts.track.clone()),
                    last: Instant::now(),
                    stale: false,
                    ended: false,
                    refused: HashMap::new(),
                });
            st.last = Instant::now();
            if st.stale || st.ended {
                let was = if st.stale { "stale" } else { "ended" };
                st.stale = false;
                st.ended = false;
                if sample.kind() == SampleKind::Put {
                    emit(&mut hist, &source, None, "resumed", json!({"was": was}));
                }
            }
            if sample.kind() == SampleKind::Delete {
                st.ended = true;
                emit(
                    &mut hist,
                    &source,
                    None,
                    "ended",
                    json!({"items": net::read_seq(sample.attachment())}),
                );
            } else {
                let bytes = sample.payload().to_bytes();
                match wire::decode(&bytes) {
                    Ok(WireItem::Peaks(set)) => {
                        report.peak_sets += 1;
                        observe(&mut hist, &mut emit, &source, st, &set, &mut report);
                    }
                    Ok(other) => {
                        let kind = match other {
                            WireItem::Audio(_) => "audio",
                            WireItem::Samples(_) => "samples",
                            WireItem::Spectrum(_) => "spectrum",
                            WireItem::Frame(_) => "frames",
                            WireItem::Peaks(_) => "peaks",
                        };
                        refuse(
                            &mut hist,
                            &mut emit,
                            &source,
                            st,
                            "type",
                            format!("carries {kind}, not peak sets"),
                            &mut report,
                        );
                    }
                    Err(e) => {
                        let why = match e {
                            wire::WireError::UnknownVersion { .. } => "version",
                            _ => "garbage",
                        };
                        refuse(
                            &mut hist,
                            &mut emit,
                            &source,
                            st,
                            why,
                            format!("{} bytes: {e}", bytes.len()),
                            &mut report,
                        );
                    }
                }
            }
        }
        for (source, st) in sources.iter_mut() {
            if !st.stale && !st.ended && st.last.elapsed() >= opts.stale_after {
                st.stale = true;
                report.stale += 1;
                emit(
                    &mut hist,
                    source,
                    None,
                    "stale",
                    json!({"silent_s": st.last.elapsed().as_secs_f64()}),
                );
            }
        }
        match hist.maybe_commit() {
            Ok(()) => db_error = None,
            Err(e) => {
                // Keep monitoring; say so once per distinct failure.
                let m = e.to_string();
                if db_error.as_deref() != Some(&m) {
                    tracing::error!("{m}");
                    emit(&mut hist, "", None, "history_error", json!({"message": &m}));
                    db_error = Some(m);
                }
            }
        }
    };
    for (source, st) in &sources {
        for tr in &st.tracker.tracks {
            let s = tr.stats();
            emit(
                &mut hist,
                source,
                Some(tr.id),
                "summary",
                stats_json(&s, tr.alarmed),
            );
        }
    }
    report.sources = sources.len();
    let committed = hist.commit();
    report.rows_written = hist.written;
    drop(sub);
    let _ = session.close().wait();
    committed.map_err(|e| Error::Input {
        path: e.path.clone(),
        message: e.message.clone(),
    })?;
    result.map(|_| report)
}

fn stats_json(s: &Stats, alarmed: bool) -> serde_json::Value {
    json!({
        "frequency_hz": s.frequency_hz, "sigma_hz": s.sigma_hz,
        "damping_ratio": s.damping_ratio, "damping_sigma": s.damping_sigma,
        "power_db": s.power_db, "power_sigma_db": s.power_sigma_db,
        "observations": s.n, "alarmed": alarmed,
    })
}

type Emit<'a> = dyn FnMut(&mut History, &str, Option<u32>, &'static str, serde_json::Value) + 'a;

fn refuse(
    hist: &mut History,
    emit: &mut Emit<'_>,
    source: &str,
    st: &mut SourceState,
    why: &'static str,
    message: String,
    report: &mut MonitorReport,
) {
    report.refused += 1;
    let n = st.refused.entry(why).or_insert(0);
    *n += 1;
    // The first of each reason, then every 1000th: a garbage flood stays readable.
    if *n == 1 || n.is_multiple_of(1000) {
        emit(
            hist,
            source,
            None,
            "refused",
            json!({"reason": why, "message": message, "count": *n}),
        );
    }
}

fn observe(
    hist: &mut History,
    emit: &mut Emit<'_>,
    source: &str,
    st: &mut SourceState,
    set: &PeakSet,
    report: &mut MonitorReport,
) {
    hist.peak_set(source, set);
    let was_established = st.tracker.established;
    let (obs, events) = st.tracker.observe(set);
    for (track, o) in obs {
        hist.observation(source, track, o);
    }
    if !was_established && st.tracker.established {
        emit(
            hist,
            source,
            None,
            "baseline",
            json!({"tracks": st.tracker.tracks.len(), "t_s": set.t_ns as f64 * 1e-9}),
        );
    }
    for e in events {
        match e {
            Event::Track { track, stats } => {
                hist.track(source, track, stats.frequency_hz);
                emit(
                    hist,
                    source,
                    Some(track),
                    "track",
                    stats_json(&stats, false),
                );
            }
            Event::Alarm {
                track,
                t_ns,
                since_ns,
                frequency_hz,
                z,
                stats,
            } => {
                report.alarms += 1;
                let mut v = stats_json(&stats, true);
                v["t_s"] = json!(t_ns as f64 * 1e-9);
                v["since_s"] = json!(since_ns as f64 * 1e-9);
                v["observed_hz"] = json!(frequency_hz);
                v["z"] = json!(z);
                emit(hist, source, Some(track), "alarm", v);
            }
            Event::Lost {
                track,
                t_ns,
                since_ns,
                stats,
            } => {
                report.alarms += 1;
                let mut v = stats_json(&stats, true);
                v["t_s"] = json!(t_ns as f64 * 1e-9);
                v["since_s"] = json!(since_ns as f64 * 1e-9);
                emit(hist, source, Some(track), "lost", v);
            }
            Event::Cleared {
                track,
                t_ns,
                frequency_hz,
                stats,
            } => {
                let mut v = stats_json(&stats, false);
                v["t_s"] = json!(t_ns as f64 * 1e-9);
                v["observed_hz"] = json!(frequency_hz);
                emit(hist, source, Some(track), "cleared", v);
            }
        }
    }
}
