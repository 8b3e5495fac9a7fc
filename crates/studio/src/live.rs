//! The live view (issue 16, item 5): a pipeline run inside the studio,
//! watched through `tap` stages the studio adds to it.
//!
//! - `frame`: the source's frames, at most 10 a second, copied to 8 bits;
//! - `samples`: what feeds the spectrum (the level meter);
//! - `spectrum`: every sliding spectrum;
//! - `magnified`: every frame of the first `magnify` stage (the magnified
//!   view), whose band and factor the page may change while it runs
//!   (the stage starts its magnifier over at the next frame).
//!
//! The taps never hold the stream up (see `vibroscope::engine::observe`),
//! so the frame path is the same with or without the studio: the server
//! reads the latest of each when it sends an update, and an update the
//! page has not taken yet is replaced by the next (stale ones are dropped,
//! never queued).

use serde_json::{json, Value};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::{Duration, Instant};
use vibroscope::live::{Latest, Observer, Origin, PipelineDecl, PortType, TapFrame, TapSlot};
use vibroscope::live::{MagnifyParams, TapParams, Tuning};
use vibroscope::peaks::{find_peaks, PeakOptions};
use vibroscope::pipeline::{self as pl, PipelineOptions};

/// Largest number of spectrum values sent per update: longer spectra are
/// reduced to this many by keeping each group's largest value (a peak
/// stays visible).
pub const MAX_BINS: usize = 1024;

/// Ring slots on each tap's input.
const TAP_CAPACITY: i64 = 64;

/// The ids the studio gives its tap stages.
const TAP_FRAME: &str = "studio_frame";
const TAP_SAMPLES: &str = "studio_samples";
const TAP_SPECTRUM: &str = "studio_spectrum";
const TAP_HISTORY: &str = "studio_history";
const TAP_MAGNIFIED: &str = "studio_magnified";

/// Seconds of frames kept for a modal image of the live view, and the
/// memory they may take (older frames go first).
pub const HISTORY_S: f64 = 4.0;
const HISTORY_MB: u64 = 256;

/// At least this many frames before a live modal image is made.
pub const MIN_HISTORY_FRAMES: usize = 32;

/// A live pipeline and what watches it.
pub struct Live {
    /// The pipeline as given (a shipped name or a file).
    pub name: String,
    /// It has a spectrum stage the studio taps.
    pub has_spectrum: bool,
    observer: Arc<Observer>,
    frame: Arc<TapSlot>,
    samples: Arc<TapSlot>,
    spectrum: Arc<TapSlot>,
    history: Arc<TapSlot>,
    state: Arc<Mutex<RunState>>,
    thread: Mutex<Option<std::thread::JoinHandle<()>>>,
    /// Updates the server has sent to pages.
    pub sent: AtomicU64,
    /// Peaks of the last spectrum analysed, by its sequence number.
    peaks: Mutex<(u64, Value)>,
    /// [`Live::stop`] was called (the studio stopped it, not a signal).
    stopping: Arc<std::sync::atomic::AtomicBool>,
    /// The magnified view, when the pipeline has a `magnify` stage.
    pub magnify: Option<MagnifyView>,
}

/// The first `magnify` stage of the live pipeline: its frames (every one,
/// the latest kept) and the band and factor the page sets.
pub struct MagnifyView {
    /// The stage's id.
    pub stage: String,
    frames: Arc<TapSlot>,
    tuning: Arc<Tuning>,
    /// The band and factor in force, and the frame they took effect at
    /// (none: since the start); and the last request refused, with why.
    state: Mutex<MagnifyState>,
}

#[derive(Clone, Debug)]
struct MagnifyState {
    lo_hz: f64,
    hi_hz: f64,
    factor: f64,
    since_frame: Option<u64>,
    /// The request waiting for the stage: its version and values.
    pending: Option<(u64, [f64; 3])>,
    refused: Option<String>,
}

/// What became of a change of band and factor.
#[derive(Debug)]
pub enum Retune {
    /// Taken from this frame on.
    Applied(u64),
    /// The stage kept its settings, for this reason.
    Refused(String),
    /// No frame came within the time waited (the request stays; the
    /// stage takes it at its next frame).
    Pending,
}

impl MagnifyView {
    /// Asks the stage for a new band and factor and waits up to `wait`
    /// for its answer. Values the stage's declaration refuses are refused
    /// here first, with its message.
    pub fn retune(&self, lo_hz: f64, hi_hz: f64, factor: f64, wait: Duration) -> Retune {
        let values = [("lo_hz", lo_hz), ("hi_hz", hi_hz), ("factor", factor)];
        for (k, v) in values {
            if let Err(m) = vibroscope::live::check_magnify_param(k, v) {
                return Retune::Refused(format!("{k} = {v}: {m}"));
            }
        }
        if let Err(m) = vibroscope::live::check_magnify_band(lo_hz, hi_hz) {
            return Retune::Refused(m);
        }
        let version = {
            let mut st = self.state.lock().unwrap_or_else(|p| p.into_inner());
            let v = self
                .tuning
                .request(values.iter().map(|(k, v)| (k.to_string(), *v)).collect());
            st.pending = Some((v, [lo_hz, hi_hz, factor]));
            v
        };
        let t0 = Instant::now();
        loop {
            self.settle();
            if let Some(t) = self.tuning.outcome().filter(|t| t.version == version) {
                return match t.result {
                    Ok(seq) => Retune::Applied(seq),
                    Err(m) => Retune::Refused(m),
                };
            }
            if t0.elapsed() >= wait {
                return Retune::Pending;
            }
            std::thread::sleep(Duration::from_millis(5));
        }
    }

    /// Takes the stage's answer to the pending request into the state.
    fn settle(&self) {
        let mut st = self.state.lock().unwrap_or_else(|p| p.into_inner());
        let Some((version, [lo, hi, factor])) = st.pending else {
            return;
        };
        let Some(t) = self.tuning.outcome().filter(|t| t.version == version) else {
            return;
        };
        st.pending = None;
        match t.result {
            Ok(seq) => {
                (st.lo_hz, st.hi_hz, st.factor) = (lo, hi, factor);
                st.since_frame = Some(seq);
                st.refused = None;
            }
            Err(m) => st.refused = Some(m),
        }
    }

    /// The latest magnified frame and its slot number.
    pub fn latest(&self) -> Option<(u64, TapFrame)> {
        latest_frame(&self.frames)
    }

    /// Frames kept by the slot so far (changes with each new one).
    pub fn seq(&self) -> u64 {
        self.frames.seq()
    }

    fn update(&self) -> Value {
        self.settle();
        let st = self.state.lock().unwrap_or_else(|p| p.into_inner()).clone();
        json!({
            "stage": self.stage,
            "lo_hz": st.lo_hz,
            "hi_hz": st.hi_hz,
            "factor": st.factor,
            "since_frame": st.since_frame,
            "pending": st.pending.is_some(),
            "refused": st.refused,
            "frames": self.frames.seq(),
            "skipped": self.frames.skipped(),
        })
    }
}

#[derive(Clone, Debug)]
enum RunState {
    Running,
    /// How it ended, the run's `--stats` table (drops, latency), and
    /// whether a signal (Ctrl-C) stopped it.
    Finished(String, String, bool),
    Failed(String),
}

/// The pipeline with the studio's taps, or why it cannot be watched: taps
/// on the source's frames, on what feeds the first spectrum stage (or, with
/// none, on the last stage giving samples or audio: the level meter), and
/// on that spectrum stage's output when there is one.
///
/// With `replay`, the pipeline's source becomes that recording played at
/// its own pace (a live source: the edges drop as they would live).
pub fn prepare(
    pipeline: &str,
    set: &[String],
    replay: Option<&std::path::Path>,
) -> Result<PipelineDecl, String> {
    let mut decl = pl::prepare(&PipelineOptions {
        pipeline: pipeline.to_owned(),
        set: set.to_vec(),
        ..PipelineOptions::default()
    })
    .map_err(|e| e.to_string())?;
    if let Some(path) = replay {
        if !path.is_file() {
            return Err(format!("--replay {}: no such file", path.display()));
        }
        pl::apply_live_replay(&mut decl, path).map_err(|e| e.to_string())?;
    }
    // The user's pipeline first: errors name its own stages and fields.
    let g = pl::validate(&decl).map_err(|e| e.to_string())?;
    let id = |i: usize| g.nodes[i].id.clone();
    let source = g
        .nodes
        .iter()
        .position(|n| n.inputs.is_empty())
        .map(id)
        .ok_or_else(|| format!("{}: the pipeline has no source stage", decl.file))?;
    let spectrum = g
        .nodes
        .iter()
        .position(|n| n.output == Some(PortType::Spectrum));
    let feeds = match spectrum {
        Some(i) => g.nodes[i].inputs.first().map(|inp| id(inp.from)),
        None => g
            .nodes
            .iter()
            .rposition(|n| matches!(n.output, Some(PortType::Samples | PortType::Audio)))
            .map(id),
    };
    let spectrum_id = spectrum.map(id);
    drop(g);
    let magnify_id = decl
        .stages
        .iter()
        .find(|s| s.is::<MagnifyParams>())
        .map(|s| s.id.clone());
    for id in [
        TAP_FRAME,
        TAP_SAMPLES,
        TAP_SPECTRUM,
        TAP_HISTORY,
        TAP_MAGNIFIED,
    ] {
        if decl.stages.iter().any(|s| s.id == id) {
            return Err(format!(
                "{}: a stage is called `{id}`, the name the studio gives its own",
                decl.file
            ));
        }
    }
    let origin = Origin::Builtin("vibroscope studio's live view".into());
    // A tap never waits, but its thread can be descheduled for a while on
    // a busy machine: its ring holds more than a plain stage's.
    let tap = |id: &str, from: &str, name: &str, every_ms: f64| {
        let mut st = pl::new_stage::<TapParams>(id, &[from], origin.clone());
        st.capacity = Some((TAP_CAPACITY, origin.clone()));
        pl::put(&mut st, TapParams::name, name.to_string(), origin.clone())?;
        pl::put(&mut st, TapParams::every_ms, every_ms, origin.clone())?;
        Ok::<_, vibroscope::Error>(st)
    };
    let mut taps = vec![tap(TAP_FRAME, &source, "frame", 100.0)];
    if let Some(f) = &feeds {
        taps.push(tap(TAP_SAMPLES, f, "samples", 40.0));
    }
    if let Some(sp) = &spectrum_id {
        taps.push(tap(TAP_SPECTRUM, sp, "spectrum", 0.0));
        // Every frame of the last seconds, for a clicked peak's modal image.
        let history = tap(TAP_HISTORY, &source, "history", 0.0).and_then(|mut st| {
            pl::put(&mut st, TapParams::history_s, HISTORY_S, origin.clone())?;
            pl::put(&mut st, TapParams::history_mb, HISTORY_MB, origin.clone())?;
            Ok(st)
        });
        taps.push(history);
    }
    if let Some(m) = &magnify_id {
        // Every magnified frame (the latest kept: a slow page gets fewer).
        taps.push(tap(TAP_MAGNIFIED, m, "magnified", 0.0));
    }
    for st in taps {
        decl.stages.push(st.map_err(|e| e.to_string())?);
    }
    // Errors naming the user's stages and fields, before anything runs.
    pl::validate(&decl).map_err(|e| e.to_string())?;
    Ok(decl)
}

impl Live {
    /// Starts `decl` (from [`prepare`]) on a thread of its own.
    pub fn start(name: &str, decl: PipelineDecl) -> Result<Arc<Live>, String> {
        let observer = Observer::new();
        let has_spectrum = decl.stages.iter().any(|s| s.id == TAP_SPECTRUM);
        let magnify = decl
            .stages
            .iter()
            .find(|s| s.id == TAP_MAGNIFIED)
            .and_then(|t| t.inputs.first())
            .and_then(|i| decl.stages.iter().find(|s| s.id == i.from))
            .map(|m| MagnifyView {
                stage: m.id.clone(),
                frames: observer.slot("magnified"),
                tuning: observer.tuning(&m.id),
                state: Mutex::new(MagnifyState {
                    lo_hz: m.get(MagnifyParams::lo_hz).unwrap_or(f64::NAN),
                    hi_hz: m.get(MagnifyParams::hi_hz).unwrap_or(f64::NAN),
                    factor: m.get(MagnifyParams::factor).unwrap_or(f64::NAN),
                    since_frame: None,
                    pending: None,
                    refused: None,
                }),
            });
        let state = Arc::new(Mutex::new(RunState::Running));
        let stopping = Arc::new(std::sync::atomic::AtomicBool::new(false));
        let by_studio = Arc::clone(&stopping);
        let live = Arc::new(Live {
            name: name.to_owned(),
            has_spectrum,
            frame: observer.slot("frame"),
            samples: observer.slot("samples"),
            spectrum: observer.slot("spectrum"),
            history: observer.slot("history"),
            observer: Arc::clone(&observer),
            state: Arc::clone(&state),
            thread: Mutex::new(None),
            sent: AtomicU64::new(0),
            peaks: Mutex::new((0, Value::Array(Vec::new()))),
            stopping,
            magnify,
        });
        let t = std::thread::Builder::new()
            .name("studio-live".into())
            .spawn(move || {
                let r = pl::run_observed(&decl, &observer);
                let next = match r {
                    Ok(rep) => RunState::Finished(
                        format!(
                            "the pipeline {} after {:.1} s",
                            if rep.interrupted {
                                "was stopped"
                            } else {
                                "ended"
                            },
                            rep.elapsed.as_secs_f64()
                        ),
                        rep.table(),
                        rep.interrupted && !by_studio.load(Ordering::SeqCst),
                    ),
                    Err(e) => RunState::Failed(e.to_string()),
                };
                *state.lock().unwrap_or_else(|p| p.into_inner()) = next;
            })
            .map_err(|e| format!("cannot start the live pipeline's thread: {e}"))?;
        *live.thread.lock().unwrap_or_else(|p| p.into_inner()) = Some(t);
        Ok(live)
    }

    /// Stops the pipeline (its sinks finalise) and waits for it.
    pub fn stop(&self) {
        self.stopping.store(true, Ordering::SeqCst);
        self.observer.stop();
        let t = self.thread.lock().unwrap_or_else(|p| p.into_inner()).take();
        if let Some(t) = t {
            let _ = t.join();
        }
    }

    /// Sequence numbers of the three taps: the server sends an update when
    /// they change.
    pub fn version(&self) -> (u64, u64, u64, bool) {
        let running = matches!(
            *self.state.lock().unwrap_or_else(|p| p.into_inner()),
            RunState::Running
        );
        (
            self.spectrum.seq(),
            self.frame.seq(),
            self.samples.seq(),
            running,
        )
    }

    /// The run ended because a signal (Ctrl-C) stopped it: its outputs are
    /// finalised and the process should exit.
    pub fn interrupted(&self) -> bool {
        matches!(
            *self.state.lock().unwrap_or_else(|p| p.into_inner()),
            RunState::Finished(_, _, true)
        )
    }

    /// The last [`HISTORY_S`] seconds of frames written to `path` as an
    /// 8-bit Y4M (each frame's capture time in it), with the rate they came
    /// at: (frames, seconds spanned, frame rate). `Err((false, why))`:
    /// there are none to use yet; `Err((true, why))`: the file could not
    /// be written.
    pub fn history_video(
        &self,
        path: &std::path::Path,
    ) -> Result<(usize, f64, f64), (bool, String)> {
        let h = self.history.history();
        let n = h.frames.len();
        if n < MIN_HISTORY_FRAMES {
            return Err((false, format!(
                "the live view holds {n} frames so far; a modal image needs at least {MIN_HISTORY_FRAMES} (wait a moment)"
            )));
        }
        let (first, last) = (&h.frames[0], &h.frames[n - 1]);
        let span_s = (last.t_ns - first.t_ns) as f64 * 1e-9;
        if span_s.is_nan() || span_s <= 0.0 {
            return Err((
                false,
                "the live frames carry no increasing capture times".into(),
            ));
        }
        let fps = (n - 1) as f64 / span_s;
        let write = || -> std::io::Result<()> {
            let file = std::io::BufWriter::new(std::fs::File::create(path)?);
            let mut w = vibroscope::files::Y4mWriter::new(
                file,
                first.width,
                first.height,
                vibroscope::files::Depth::U8,
                fps,
            )?;
            for f in &h.frames {
                w.write_frame(
                    vibroscope::files::FrameDestRef::U8(&f.gray),
                    Some(f.t_ns - first.t_ns),
                )?;
            }
            w.finish()?;
            Ok(())
        };
        write().map_err(|e| {
            (
                true,
                format!("the live frames' scratch video {}: {e}", path.display()),
            )
        })?;
        Ok((n, span_s, fps))
    }

    /// The latest frame (8-bit grey), if one came.
    pub fn latest_frame(&self) -> Option<TapFrame> {
        latest_frame(&self.frame).map(|(_, f)| f)
    }

    /// One update: the latest spectrum (dB) and its peaks, the level, the
    /// latest frame's number, and every stage's counters.
    pub fn update(&self) -> Value {
        let epoch = self.observer.epoch();
        let age_ms = |arrived: Instant, t_ns: i64| -> Option<f64> {
            let captured = epoch? + Duration::from_nanos(u64::try_from(t_ns).ok()?);
            Some(arrived.saturating_duration_since(captured).as_secs_f64() * 1e3)
        };
        let (state, message, report) = match &*self.state.lock().unwrap_or_else(|p| p.into_inner())
        {
            RunState::Running => ("running", Value::Null, Value::Null),
            RunState::Finished(m, t, _) => ("finished", json!(m), json!(t)),
            RunState::Failed(m) => ("failed", json!(m), Value::Null),
        };
        let spectrum = self.spectrum.snapshot().and_then(|s| match s.latest {
            Latest::Spectrum(sp) => {
                // The window's last sample: how old the newest data is.
                let end_ns = sp.t_ns + (sp.window as f64 / sp.rate_hz * 0.5e9) as i64;
                let peaks = self.peaks_of(s.seq, &sp);
                let (db, step) = reduce_db(&sp.power);
                Some(json!({
                    "seq": s.seq,
                    "t_s": sp.t_ns as f64 * 1e-9,
                    "f0_hz": sp.f0_hz,
                    "resolution_hz": sp.resolution_hz,
                    "bin_hz": sp.resolution_hz * step as f64,
                    "rate_hz": sp.rate_hz,
                    "window": sp.window,
                    "segments": sp.segments,
                    "db": db,
                    "peaks": peaks,
                    "age_ms": age_ms(s.arrived, end_ns),
                }))
            }
            _ => None,
        });
        let level = self.samples.snapshot().and_then(|s| {
            let data: &[f32] = match &s.latest {
                Latest::Samples(b) => &b.data,
                Latest::Audio(a) => &a.samples,
                _ => return None,
            };
            let (n, sum, peak) = data
                .iter()
                .filter(|v| v.is_finite())
                .fold((0usize, 0.0f64, 0.0f32), |(n, sum, peak), &v| {
                    (n + 1, sum + f64::from(v) * f64::from(v), peak.max(v.abs()))
                });
            let ms = sum / n.max(1) as f64;
            Some(json!({
                "seq": s.seq,
                "rms": ms.sqrt(),
                "db": 10.0 * ms.max(1e-30).log10(),
                "peak": peak,
            }))
        });
        let frame = self.frame.snapshot().and_then(|s| match &s.latest {
            Latest::Frame(f) => Some(json!({
                "seq": s.seq,
                "frame": f.seq,
                "t_s": f.t_ns as f64 * 1e-9,
                "width": f.width,
                "height": f.height,
                "age_ms": age_ms(s.arrived, f.t_ns),
            })),
            _ => None,
        });
        json!({
            "pipeline": self.name,
            "has_spectrum": self.has_spectrum,
            "state": state,
            "message": message,
            "report": report,
            "now_s": self.observer.now_ns().map(|t| t as f64 * 1e-9),
            "spectrum": spectrum,
            "level": level,
            "frame": frame,
            "stages": self.observer.stages(),
            "magnify": self.magnify.as_ref().map(|m| m.update()),
            "skipped": {
                "spectrum": self.spectrum.skipped(),
                "frame": self.frame.skipped(),
                "samples": self.samples.skipped(),
            },
            "sent": self.sent.load(Ordering::Relaxed),
        })
    }

    /// The peaks of spectrum `seq` (computed once per spectrum).
    fn peaks_of(&self, seq: u64, sp: &vibroscope::live::Spectrum) -> Value {
        let mut g = self.peaks.lock().unwrap_or_else(|p| p.into_inner());
        if g.0 != seq {
            let power: Vec<f64> = sp.power.iter().map(|&v| f64::from(v)).collect();
            let o = PeakOptions {
                max_peaks: 5,
                segments: sp.segments.max(1),
                ..PeakOptions::default()
            };
            let peaks = find_peaks(&power, sp.f0_hz, sp.resolution_hz, &o);
            let v = peaks
                .iter()
                .map(|p| {
                    json!({
                        "frequency_hz": p.frequency_hz,
                        "frequency_std_hz": p.frequency_std_hz,
                        "power_db": p.power_db,
                        "prominence_db": p.prominence_db,
                        "damping_ratio": p.damping_ratio,
                        "damping_ratio_std": p.damping_ratio_std,
                    })
                })
                .collect();
            *g = (seq, Value::Array(v));
        }
        g.1.clone()
    }
}

impl Drop for Live {
    fn drop(&mut self) {
        self.stop();
    }
}

/// The latest frame a tap's slot holds, with the slot's number for it.
fn latest_frame(slot: &TapSlot) -> Option<(u64, TapFrame)> {
    let s = slot.snapshot()?;
    match s.latest {
        Latest::Frame(f) => Some((s.seq, f)),
        _ => None,
    }
}

/// Power in dB (10 log10), reduced to at most [`MAX_BINS`] values by the
/// largest of each group of `step` bins; returns the values and `step`.
pub fn reduce_db(power: &[f32]) -> (Vec<f32>, usize) {
    let step = power.len().div_ceil(MAX_BINS).max(1);
    let db = power
        .chunks(step)
        .map(|c| {
            let m = c
                .iter()
                .copied()
                .filter(|v| v.is_finite())
                .fold(0.0f32, f32::max);
            if m > 0.0 {
                10.0 * m.log10()
            } else {
                -300.0
            }
        })
        .collect();
    (db, step)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn reduction_keeps_each_groups_largest_value() {
        let mut p = vec![1.0f32; 4096];
        p[1001] = 100.0;
        let (db, step) = reduce_db(&p);
        assert_eq!((db.len(), step), (1024, 4));
        assert_eq!(db[250], 20.0);
        assert_eq!(db[0], 0.0);
        let (db, step) = reduce_db(&[0.0, 10.0]);
        assert_eq!((db, step), (vec![-300.0, 10.0], 1));
    }

    #[test]
    fn taps_go_on_the_source_the_signal_the_spectrum_and_the_history() {
        let taps = |d: &PipelineDecl| -> Vec<(String, String)> {
            d.stages
                .iter()
                .filter(|s| s.kind == "tap")
                .map(|s| (s.id.clone(), s.inputs[0].from.clone()))
                .collect()
        };
        let d = prepare("live-spectrum", &[], None).expect("the shipped live pipeline");
        let want = |v: &[(&str, &str)]| -> Vec<(String, String)> {
            v.iter()
                .map(|(a, b)| (a.to_string(), b.to_string()))
                .collect()
        };
        assert_eq!(
            taps(&d),
            want(&[
                (TAP_FRAME, "src"),
                (TAP_SAMPLES, "phase"),
                (TAP_SPECTRUM, "spectrum"),
                (TAP_HISTORY, "src")
            ])
        );
        // Only the history tap keeps every frame, for the last seconds.
        let h = d
            .stages
            .iter()
            .find(|s| s.id == TAP_HISTORY)
            .expect("history");
        let hs = h.params().iter().find(|p| p.key == "history_s");
        assert_eq!(hs.and_then(|p| p.value.as_float()), Some(HISTORY_S));
        // No spectrum: the level comes from the last stage giving audio.
        let d = prepare("live-microphone", &[], None).expect("the shipped live microphone");
        let t = taps(&d);
        assert_eq!(t.len(), 2, "{t:?}");
        assert_eq!(t[0], (TAP_FRAME.to_string(), "cam".to_string()));
        assert_eq!(t[1], (TAP_SAMPLES.to_string(), "highpass".to_string()));
        // The user's errors come first, naming the user's stage.
        let e = prepare("live-spectrum", &["spectrum.hop=0".to_owned()], None).unwrap_err();
        assert!(e.contains("hop"), "{e}");
        let e = prepare("no-such-pipeline", &[], None).unwrap_err();
        assert!(e.contains("no such file"), "{e}");
        // A magnify stage: every frame it makes is tapped.
        let d = prepare("live-magnify", &[], None).expect("the shipped live magnifier");
        let t = taps(&d);
        assert!(
            t.contains(&(TAP_MAGNIFIED.to_string(), "mag".to_string())),
            "{t:?}"
        );
        let m = d
            .stages
            .iter()
            .find(|s| s.id == TAP_MAGNIFIED)
            .expect("tap");
        let every = m.params().iter().find(|p| p.key == "every_ms");
        assert_eq!(every.and_then(|p| p.value.as_float()), Some(0.0));
        // A replay plays a file as the camera, at its own pace.
        let e = prepare(
            "live-magnify",
            &[],
            Some(std::path::Path::new("/no/such.y4m")),
        )
        .unwrap_err();
        assert!(
            e.contains("/no/such.y4m") && e.contains("no such file"),
            "{e}"
        );
        let clip = std::env::temp_dir().join(format!("studio-replay-{}.y4m", std::process::id()));
        std::fs::write(&clip, b"YUV4MPEG2 W8 H8 F60:1 Cmono\n").expect("a scratch file");
        let d = prepare("live-magnify", &[], Some(&clip));
        let _ = std::fs::remove_file(&clip);
        let d = d.expect("live-magnify on a replay");
        let cam = d.stages.iter().find(|s| s.id == "cam").expect("the source");
        assert_eq!(cam.kind, "file");
        let realtime = cam.params().iter().find(|p| p.key == "realtime");
        assert_eq!(realtime.and_then(|p| p.value.as_bool()), Some(true));
    }
}
