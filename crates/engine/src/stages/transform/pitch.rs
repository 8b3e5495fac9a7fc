//! `pitch`: the pitch of an audio stream as it comes (YIN, thesis 4.6 and
//! Fig. 4-11), for live use: the same tracker as `vibroscope pitch`
//! ([`vibroscope_math::pitch::Tracker`]), fed block by block.
//!
//! Output: samples, one row per YIN frame (every `hop_s`), three channels:
//! the pitch in Hz, the confidence (1 − YIN's aperiodicity) and voiced
//! (1 or 0). A row's time is its window's centre on the input's clock.
//!
//! A signal under 8 kHz is interpolated first (an integer factor up to at
//! least 8 kHz, with the `resample` stage's delay-compensated 256-tap sinc),
//! because YIN at a few samples a period makes octave errors. `vibroscope
//! pitch` interpolates its whole file through the FFT instead; both keep
//! the band and the timing, so their pitch differs by a small fraction of
//! a percent.
//!
//! Where causality makes it differ from `vibroscope pitch`: a frame is
//! silent when its RMS is `silence_db` under the loudest frame *so far*
//! (the file command compares with the loudest of the whole file), so a
//! quiet start may be called voiced before anything louder has come.
//!
//! Latency: a frame is out once its window and the longest lag are in,
//! `2/fmin_hz` after its first sample, plus the interpolator's delay under
//! 8 kHz (128 input samples: 58 ms at 2200 Hz); the run's summary gives
//! both.
//!
//! A gap in the input's timestamps (a live source dropped frames) restarts
//! the tracker at the gap: no frame spans it.

use super::resample::Aligned;
use crate::*;
use std::sync::Arc;
use vibroscope_math::pitch::{self, PitchError, PitchFrame, Silence, Tracker, YinParams};

params! {
    /// `pitch`'s parameters.
    pub struct PitchParams for "pitch" {
        fmin_hz: f64 = ParamSpec::of(ParamType::Float, Def::Float(60.0))
            .floats(1.0, 20_000.0)
            .unit("Hz")
            .doc("lowest pitch searched: sets the window (one period of it) and the latency (2/fmin_hz)"),
        fmax_hz: f64 = ParamSpec::of(ParamType::Float, Def::Float(500.0))
            .floats(2.0, 100_000.0)
            .unit("Hz")
            .doc("highest pitch searched; above fmin_hz and at most a quarter of the input's rate"),
        threshold: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.15))
            .floats(0.01, 0.99)
            .doc("YIN's absolute threshold on the normalised difference (the paper's 0.1; 0.1-0.2 for noisy input): a frame whose dip stays above it is unvoiced"),
        hop_s: f64 = ParamSpec::of(ParamType::Float, Def::Float(0.01))
            .floats(1e-4, 10.0)
            .unit("s")
            .doc("time between frames (the output's sample period)"),
        silence_db: f64 = ParamSpec::of(ParamType::Float, Def::Float(40.0))
            .floats(1.0, 200.0)
            .unit("dB")
            .doc("a frame this far under the loudest frame so far is silent (unvoiced)"),
    }
}

type P = PitchParams;

pub const KIND: KindSpec = KindSpec {
    name: "pitch",
    summary: "YIN pitch of an audio stream, live: samples with channels f0 Hz, confidence, voiced (1/0), a row every hop_s",
    inputs: &[InPort::one(&[PortType::Audio])],
    outputs: &[OutPort::out(PortType::Samples)],
    params: P::PARAMS,
    plan: |p| {
        let v: P = p.resolve_typed()?;
        if v.fmax_hz <= v.fmin_hz {
            return Err(p.error(
                "fmax_hz",
                format!("must be above fmin_hz ({} Hz), got {} Hz", v.fmin_hz, v.fmax_hz),
            ));
        }
        Ok(Box::new(PitchPlan(YinParams {
            fmin_hz: v.fmin_hz,
            fmax_hz: v.fmax_hz,
            threshold: v.threshold,
            hop_s: v.hop_s,
            silence_db: v.silence_db,
        })))
    },
};

struct PitchPlan(YinParams);

impl Plan for PitchPlan {
    fn build(self: Box<Self>, _: &BuildCtx) -> Result<Node, StageError> {
        Ok(Node::Stage(Box::new(PitchStage {
            params: self.0,
            run: None,
            up: Vec::new(),
            x: Vec::new(),
            rows: Vec::new(),
            frames: 0,
            voiced: Vec::new(),
            restarts: 0,
        })))
    }
}

/// The tracker of one unbroken stretch of input.
struct Run {
    rate_in: f64,
    /// The interpolator to the tracker's rate (none at 8 kHz and above).
    interp: Option<Aligned>,
    tracker: Tracker,
    /// Time of the stretch's first input sample, ns.
    t0_ns: i64,
    /// Input samples taken in this stretch.
    n_in: u64,
}

struct PitchStage {
    params: YinParams,
    run: Option<Run>,
    /// Scratch: the interpolated block, the block as f64, the rows.
    up: Vec<f32>,
    x: Vec<f64>,
    rows: Vec<f32>,
    /// Frames given, and the pitch of the voiced ones (for the summary).
    frames: u64,
    voiced: Vec<f32>,
    /// Gaps in the input that restarted the tracker.
    restarts: u64,
}

fn pitch_error(e: PitchError) -> StageError {
    match e {
        PitchError::Invalid { field, message } => StageError::config(
            match field {
                "fmin" => "fmin_hz",
                "fmax" => "fmax_hz",
                "hop" => "hop_s",
                "silence" => "silence_db",
                other => other,
            },
            message,
        ),
        other => StageError::dsp(other.to_string()),
    }
}

impl PitchStage {
    fn start(&self, a: &AudioBlock) -> Result<Run, StageError> {
        pitch::check(&self.params, a.rate_hz).map_err(pitch_error)?;
        let k = pitch::upsampling(a.rate_hz);
        let rate = a.rate_hz * k as f64;
        let interp = if k > 1 {
            Some(Aligned::new(a.rate_hz, rate).map_err(StageError::dsp)?)
        } else {
            None
        };
        let tracker = Tracker::new(&self.params, rate, Silence::SoFar).map_err(pitch_error)?;
        Ok(Run {
            rate_in: a.rate_hz,
            interp,
            tracker,
            t0_ns: a.t0_ns,
            n_in: 0,
        })
    }

    /// Runs `self.x` through the tracker and emits the rows it completes.
    fn track(&mut self, out: &mut Emitter) {
        let Some(run) = self.run.as_mut() else {
            return;
        };
        self.rows.clear();
        let mut first: Option<f64> = None;
        let (rows, voiced, frames) = (&mut self.rows, &mut self.voiced, &mut self.frames);
        run.tracker.push(&self.x, |f: PitchFrame| {
            first.get_or_insert(f.time_s);
            *frames += 1;
            if f.voiced && voiced.len() < 1 << 20 {
                voiced.push(f.f0_hz as f32);
            }
            rows.extend_from_slice(&[
                f.f0_hz as f32,
                f.confidence as f32,
                f32::from(u8::from(f.voiced)),
            ]);
        });
        let Some(t) = first else {
            return;
        };
        let _ = out.emit(Item::Samples(SampleBlock {
            t0_ns: run.t0_ns + (t * 1e9).round() as i64,
            rate_hz: run.tracker.rate_hz() / run.tracker.hop() as f64,
            channels: 3,
            data: Arc::from(&self.rows[..]),
            times_ns: None,
        }));
    }

    /// Interpolates (or copies) `samples` into `self.x`.
    fn feed(&mut self, samples: &[f32], last: bool) -> Result<(), StageError> {
        let Some(run) = self.run.as_mut() else {
            return Ok(());
        };
        self.x.clear();
        match run.interp.as_mut() {
            Some(a) => {
                self.up.clear();
                a.push(samples, &mut self.up).map_err(StageError::dsp)?;
                if last {
                    a.finish(&mut self.up).map_err(StageError::dsp)?;
                }
                self.x.extend(self.up.iter().map(|&v| f64::from(v)));
            }
            None => self.x.extend(samples.iter().map(|&v| f64::from(v))),
        }
        Ok(())
    }
}

impl Stage for PitchStage {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        if let Some(run) = &self.run {
            if (a.rate_hz - run.rate_in).abs() > 1e-9 * run.rate_in {
                return Err(StageError::format(format!(
                    "the sample rate changed from {} Hz to {} Hz mid-stream",
                    run.rate_in, a.rate_hz
                )));
            }
            // Where the block should start if nothing was lost.
            let expect = run.t0_ns as f64 + run.n_in as f64 * 1e9 / run.rate_in;
            if (a.t0_ns as f64 - expect).abs() > 0.5e9 / run.rate_in {
                // The stretch so far is finished as at the end of a stream.
                self.feed(&[], true)?;
                self.track(out);
                self.run = None;
                self.restarts += 1;
            }
        }
        if self.run.is_none() {
            self.run = Some(self.start(&a)?);
        }
        if let Some(run) = self.run.as_mut() {
            run.n_in += a.samples.len() as u64;
        }
        self.feed(&a.samples, false)?;
        self.track(out);
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.feed(&[], true)?;
        self.track(out);
        Ok(())
    }

    fn summary(&self) -> Option<String> {
        let run = self.run.as_ref()?;
        let mut v = self.voiced.clone();
        v.sort_by(f32::total_cmp);
        let median = v
            .get(v.len() / 2)
            .map_or("-".to_string(), |m| format!("{m:.1} Hz"));
        let interp = match &run.interp {
            Some(a) => format!(
                "{} Hz interpolated to {} Hz (256-tap sinc, delay compensated)",
                a.rate_in, a.rate_out
            ),
            None => format!("{} Hz", run.rate_in),
        };
        let rate = run.tracker.rate_hz();
        let span_ms = run.tracker.span() as f64 * 1e3 / rate;
        let interp_ms = run
            .interp
            .as_ref()
            .map_or(0.0, |a| a.delay() as f64 * 1e3 / rate);
        Some(format!(
            "YIN {}-{} Hz on {interp}: {} frames, {} voiced (median {median}); a frame is out {:.1} ms after its first sample (window and longest lag {span_ms:.1} ms, interpolator {interp_ms:.1} ms), {:.1} ms after the time it reports; silence judged against the loudest frame so far{}",
            self.params.fmin_hz,
            self.params.fmax_hz,
            self.frames,
            self.voiced.len(),
            span_ms + interp_ms,
            span_ms + interp_ms - run.tracker.centre() * 1e3 / rate,
            if self.restarts > 0 {
                format!("; restarted at {} gaps in the input", self.restarts)
            } else {
                String::new()
            }
        ))
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::edge::{edge, Policy};
    use std::f64::consts::PI;

    /// A voice-like signal with pitch `f0(t)`, 10 harmonics.
    fn voice(rate: f64, secs: f64, f0: impl Fn(f64) -> f64) -> Vec<f32> {
        pitch::voice(rate, secs, 10, f0)
            .into_iter()
            .map(|v| v as f32)
            .collect()
    }

    /// A stage with the default settings, as a graph builds it.
    fn stage() -> Box<dyn Stage> {
        let ctx = BuildCtx {
            id: "pitch".into(),
            held_downstream: 0,
            pool_frames: 0,
            input_types: vec![PortType::Audio],
            live: true,
            observer: None,
            worker_busy_ns: Default::default(),
        };
        let Ok(Node::Stage(st)) = Box::new(PitchPlan(YinParams::default())).build(&ctx) else {
            panic!("pitch builds a stage");
        };
        st
    }

    /// Runs `st` on stretches of signal (first sample's time, samples),
    /// each cut into blocks of the given sizes (cycled); returns its rows.
    fn drive(
        st: &mut dyn Stage,
        stretches: &[(i64, &[f32])],
        rate: f64,
        sizes: &[usize],
    ) -> Result<Vec<SampleBlock>, StageError> {
        let (tx, mut rx, _) = edge(1 << 16, Policy::Block);
        let mut out = Emitter::new(vec![tx], Control::new(), Arc::default());
        for (t0_ns, x) in stretches {
            let (mut i, mut k) = (0, 0);
            while i < x.len() {
                let n = sizes[k % sizes.len()].min(x.len() - i);
                let a = AudioBlock {
                    t0_ns: t0_ns + (i as f64 * 1e9 / rate).round() as i64,
                    rate_hz: rate,
                    samples: Arc::from(&x[i..i + n]),
                };
                st.process(0, Item::Audio(a), &mut out)?;
                i += n;
                k += 1;
            }
        }
        st.finish(&mut out)?;
        let mut got = Vec::new();
        while let Some(it) = rx.try_recv() {
            let Item::Samples(s) = it else {
                panic!("samples expected");
            };
            got.push(s);
        }
        Ok(got)
    }

    /// Rows as (time ns, [f0, confidence, voiced]).
    fn rows(blocks: &[SampleBlock]) -> Vec<(i64, [f32; 3])> {
        blocks
            .iter()
            .flat_map(|b| {
                b.data.chunks(3).enumerate().map(move |(i, r)| {
                    (
                        b.t0_ns + (i as f64 * 1e9 / b.rate_hz).round() as i64,
                        [r[0], r[1], r[2]],
                    )
                })
            })
            .collect()
    }

    /// The stream's rows, whatever the block sizes, are the file command's
    /// frames: the same count and times, the pitch within 0.1% (the two
    /// interpolate differently) and the same voicing; and the pitch
    /// follows the truth within 1%.
    #[test]
    fn the_stream_tracks_what_the_whole_file_tracks() {
        let rate = 2200.0;
        let f0 = |t: f64| 140.0 + 80.0 * t + 6.0 * (2.0 * PI * 4.0 * t).sin();
        let x = voice(rate, 1.5, f0);
        let t0 = 3_000_000_000;
        let got = drive(&mut *stage(), &[(t0, &x)], rate, &[7, 64, 1, 300, 33]).unwrap();
        let xd: Vec<f64> = x.iter().map(|&v| f64::from(v)).collect();
        let whole = pitch::track(&xd, rate, &YinParams::default()).unwrap();
        let rows = rows(&got);
        assert_eq!(rows.len(), whole.len(), "one row a frame");
        let mut diffs = Vec::new();
        for ((t, r), f) in rows.iter().zip(&whole) {
            let tf = t0 as f64 + f.time_s * 1e9;
            assert!((*t as f64 - tf).abs() < 1e3, "{t} against {tf}");
            diffs.push((f64::from(r[0]) / f.f0_hz - 1.0).abs());
            assert_eq!(r[2] == 1.0, f.voiced, "voicing at {}", f.time_s);
            let truth = f0(f.time_s);
            assert!(
                (f64::from(r[0]) / truth - 1.0).abs() < 0.01,
                "{} against {truth}",
                r[0]
            );
        }
        let worst = diffs.iter().copied().fold(0.0, f64::max);
        let at = diffs.iter().position(|d| *d == worst).unwrap_or(0);
        diffs.sort_by(f64::total_cmp);
        let median = diffs[diffs.len() / 2];
        eprintln!(
            "stream against file: pitch difference median {:.4}%, worst {:.4}% (frame {at} of {})",
            100.0 * median,
            100.0 * worst,
            diffs.len()
        );
        assert!(median < 1e-3, "{median}");
        assert!(worst < 5e-3, "{worst}");
    }

    /// A gap in the timestamps restarts the tracker: what comes out is
    /// what two separate runs on the two stretches give.
    #[test]
    fn a_gap_restarts_the_tracker() {
        let rate = 8000.0;
        let x = voice(rate, 0.5, |_| 200.0);
        let gap_ns = 2_000_000_000;
        let mut apart = drive(&mut *stage(), &[(0, &x)], rate, &[400]).unwrap();
        apart.extend(drive(&mut *stage(), &[(gap_ns, &x)], rate, &[400]).unwrap());
        let mut st = stage();
        let joined = drive(&mut *st, &[(0, &x), (gap_ns, &x)], rate, &[400]).unwrap();
        assert_eq!(rows(&joined), rows(&apart));
        assert!(!joined.is_empty());
        let summary = st.summary().unwrap();
        assert!(summary.contains("restarted at 1 gaps"), "{summary}");
    }

    /// Settings the input's rate cannot carry are a config error naming
    /// the field.
    #[test]
    fn a_rate_too_low_for_fmax_names_it() {
        let e = drive(&mut *stage(), &[(0, &[0.0f32; 64])], 600.0, &[64]).unwrap_err();
        assert!(
            matches!(
                e,
                StageError::Config {
                    field: "fmax_hz",
                    ..
                }
            ),
            "{e}"
        );
    }
}
