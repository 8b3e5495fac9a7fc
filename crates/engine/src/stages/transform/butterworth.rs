//! What the Butterworth stage kinds (`highpass`, `bandpass`, `bandstop`)
//! share: the `mode` parameter and the stage that runs a design causally
//! (live) or forward-backward (replay).
//!
//! `mode = "auto"` (the default) resolves when the graph is built: causal
//! when the graph has a live source ([`BuildCtx::live`]: a camera, or a
//! synthetic or file source with `realtime = true`), zero-phase otherwise.
//!
//! - `causal`: the streaming IIR (second-order sections): no look-ahead,
//!   each block leaves as soon as it arrives; the phase lags near the
//!   edges (group delay is printed by `--stats`).
//! - `zero_phase`: forward-backward filtering ([`ZeroPhase`]): the output
//!   is aligned with the input to the sample at every frequency, and the
//!   magnitude is the design's squared, |H|²: -6 dB at the edges instead
//!   of -3 dB, twice the slope. Audio-rate signals are small, so the stage
//!   holds back samples until the backward pass has forgotten where it
//!   started (the impulse response's settling time, up to 2^22 samples,
//!   plus as long again); blocks leave with their own timestamps, later.

use crate::*;
use serde::{Deserialize, Serialize};
use std::collections::VecDeque;
use std::sync::Arc;
use vibroscope_math::iir::{Shape, Sos, ZeroPhase};

/// How a Butterworth stage filters.
#[derive(Deserialize, Serialize, Clone, Copy, PartialEq, Eq, Debug)]
#[serde(rename_all = "snake_case")]
pub enum Mode {
    Auto,
    ZeroPhase,
    Causal,
}

/// The `mode` parameter every Butterworth kind declares.
pub const MODE: ParamSpec = ParamSpec::new(
    "mode",
    ParamType::Choice(&["auto", "zero_phase", "causal"]),
    Def::Str("auto"),
)
.doc("zero_phase: forward-backward (aligned to the sample, magnitude |H|², -6 dB at the edges; holds samples back, for replays); causal: streaming IIR (no look-ahead, phase lags; live); auto: causal when the graph has a live source, else zero_phase");

/// The design of a stage: fixed, or a high-pass whose cutoff follows the
/// stream's rate.
#[derive(Clone, Copy, Debug)]
pub enum Design {
    /// [`vibroscope_math::iir::default_highpass_cutoff_hz`] of the rate.
    DefaultHighpass,
    Fixed(Shape),
}

impl Design {
    fn shape(self, rate_hz: f64) -> Shape {
        match self {
            Design::DefaultHighpass => Shape::Highpass {
                cutoff_hz: vibroscope_math::iir::default_highpass_cutoff_hz(rate_hz),
            },
            Design::Fixed(s) => s,
        }
    }
}

/// A validated Butterworth stage.
pub struct FilterPlan {
    pub kind: &'static str,
    pub order: usize,
    pub design: Design,
    pub mode: Mode,
}

impl Plan for FilterPlan {
    fn build(self: Box<Self>, ctx: &BuildCtx) -> Result<Node, StageError> {
        let zero_phase = match self.mode {
            Mode::ZeroPhase => true,
            Mode::Causal => false,
            Mode::Auto => !ctx.live,
        };
        Ok(Node::Stage(Box::new(Filter {
            kind: self.kind,
            order: self.order,
            design: self.design,
            zero_phase,
            run: None,
            blocks: VecDeque::new(),
            buf: Vec::new(),
            held_max: 0,
        })))
    }
}

enum Run {
    Causal(Sos),
    ZeroPhase(ZeroPhase),
}

struct Filter {
    kind: &'static str,
    order: usize,
    design: Design,
    zero_phase: bool,
    /// The filter for the current rate, the rate and its shape.
    run: Option<(Run, f64, Shape)>,
    /// Blocks pushed into the zero-phase filter and not yet released:
    /// their time and length, so each leaves as it came.
    blocks: VecDeque<(i64, usize)>,
    buf: Vec<f32>,
    /// Most samples held back at once (zero-phase).
    held_max: usize,
}

impl Filter {
    fn design(&self, rate_hz: f64) -> Result<(Run, f64, Shape), StageError> {
        let shape = self.design.shape(rate_hz);
        let nyq = 0.5 * rate_hz;
        let bad = |field: &'static str, v: f64| {
            StageError::config(
                field,
                format!("{v} Hz is not below the Nyquist frequency {nyq} Hz of this {rate_hz} Hz stream"),
            )
        };
        match shape {
            Shape::Highpass { cutoff_hz } if cutoff_hz >= nyq => {
                return Err(bad("cutoff_hz", cutoff_hz))
            }
            Shape::Bandpass { hi_hz, .. } | Shape::Bandstop { hi_hz, .. } if hi_hz >= nyq => {
                return Err(bad("hi_hz", hi_hz))
            }
            _ => {}
        }
        let sos = Sos::butterworth(self.order, shape, rate_hz)
            .map_err(|e| StageError::dsp(format!("{}: {e}", self.kind)))?;
        tracing::info!(
            kind = self.kind,
            ?shape,
            order = self.order,
            rate_hz,
            zero_phase = self.zero_phase,
            "Butterworth designed"
        );
        let run = if self.zero_phase {
            Run::ZeroPhase(ZeroPhase::new(sos))
        } else {
            Run::Causal(sos)
        };
        Ok((run, rate_hz, shape))
    }

    /// Releases whole blocks the zero-phase filter can give (all at `end`).
    fn release(&mut self, end: bool, out: &mut Emitter) {
        let Some((Run::ZeroPhase(zp), rate, _)) = self.run.as_mut() else {
            return;
        };
        let ready = if end { zp.held() } else { zp.ready() };
        let mut n = 0;
        let mut count = 0;
        for &(_, len) in &self.blocks {
            if n + len > ready {
                break;
            }
            n += len;
            count += 1;
        }
        if count == 0 {
            return;
        }
        self.buf.clear();
        zp.release(n, end && count == self.blocks.len(), &mut self.buf);
        let mut at = 0;
        for (t0_ns, len) in self.blocks.drain(..count) {
            let _ = out.emit(Item::Audio(AudioBlock {
                t0_ns,
                rate_hz: *rate,
                samples: Arc::from(&self.buf[at..at + len]),
            }));
            at += len;
        }
    }

    /// Where a stage of this design passes: a frequency for the group delay.
    fn pass_hz(shape: Shape, rate_hz: f64) -> f64 {
        match shape {
            Shape::Highpass { cutoff_hz } => (2.0 * cutoff_hz).min(0.45 * rate_hz),
            Shape::Bandpass { lo_hz, hi_hz } => (lo_hz * hi_hz).sqrt(),
            Shape::Bandstop { hi_hz, .. } => (2.0 * hi_hz).min(0.45 * rate_hz),
        }
    }
}

/// Edges of a shape, for messages.
fn edges(shape: Shape) -> String {
    match shape {
        Shape::Highpass { cutoff_hz } => format!("high-pass at {cutoff_hz:.1} Hz"),
        Shape::Bandpass { lo_hz, hi_hz } => format!("band-pass {lo_hz:.1}-{hi_hz:.1} Hz"),
        Shape::Bandstop { lo_hz, hi_hz } => format!("band-stop {lo_hz:.1}-{hi_hz:.1} Hz"),
    }
}

impl Stage for Filter {
    fn process(&mut self, _: usize, item: Item, out: &mut Emitter) -> Result<(), StageError> {
        let Item::Audio(a) = item else {
            return Err(StageError::expected("audio"));
        };
        if self.run.as_ref().is_none_or(|r| r.1 != a.rate_hz) {
            // A new rate: what the old design holds leaves first.
            self.release(true, out);
            self.run = Some(self.design(a.rate_hz)?);
        }
        let Some((run, _, _)) = self.run.as_mut() else {
            return Ok(());
        };
        match run {
            Run::Causal(f) => {
                self.buf.clear();
                self.buf
                    .extend(a.samples.iter().map(|&x| f.step(f64::from(x)) as f32));
                let _ = out.emit(Item::Audio(AudioBlock {
                    t0_ns: a.t0_ns,
                    rate_hz: a.rate_hz,
                    samples: Arc::from(&self.buf[..]),
                }));
            }
            Run::ZeroPhase(zp) => {
                if a.samples.is_empty() {
                    return Ok(());
                }
                zp.push(&a.samples);
                self.held_max = self.held_max.max(zp.held());
                self.blocks.push_back((a.t0_ns, a.samples.len()));
                self.release(false, out);
            }
        }
        Ok(())
    }

    fn finish(&mut self, out: &mut Emitter) -> Result<(), StageError> {
        self.release(true, out);
        Ok(())
    }

    fn summary(&self) -> Option<String> {
        let (run, rate, shape) = self.run.as_ref()?;
        Some(match run {
            Run::Causal(f) => {
                let fp = Self::pass_hz(*shape, *rate);
                let gd = group_delay_s(f, fp, *rate);
                format!(
                    "causal Butterworth {}, order {}, -3 dB at the edges: no look-ahead (each block leaves as it arrives); group delay {:.2} ms at {fp:.1} Hz",
                    edges(*shape),
                    self.order,
                    gd * 1e3
                )
            }
            Run::ZeroPhase(zp) => format!(
                "zero-phase Butterworth {} (forward-backward, order {} run twice: |H|², -6 dB at the edges): output aligned with its input (0 samples of delay in its timestamps); samples held back up to {} ({:.3} s; look-ahead {})",
                edges(*shape),
                self.order,
                self.held_max,
                self.held_max as f64 / rate,
                zp.tail()
            ),
        })
    }
}

/// Group delay (s) of `f` at `f_hz`: -dphi/domega by a central difference.
fn group_delay_s(f: &Sos, f_hz: f64, rate_hz: f64) -> f64 {
    let df = 1e-3 * rate_hz;
    let ph = |x: f64| f.response_at(x, rate_hz).arg();
    let mut d = ph(f_hz + df) - ph(f_hz - df);
    while d > std::f64::consts::PI {
        d -= 2.0 * std::f64::consts::PI;
    }
    while d < -std::f64::consts::PI {
        d += 2.0 * std::f64::consts::PI;
    }
    -d / (2.0 * std::f64::consts::PI * 2.0 * df)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Runs a tone at `f` through a Butterworth stage built for a replay
    /// (`live = false`) or a live graph, in 16-sample blocks; returns the
    /// output and the blocks' times.
    fn run(plan: FilterPlan, live: bool, f: f64, fs: f64, n: usize) -> (Vec<f32>, Vec<i64>) {
        let x: Vec<f32> = (0..n)
            .map(|i| (2.0 * PI * f * i as f64 / fs).sin() as f32)
            .collect();
        let (mut y, mut t) = (Vec::new(), Vec::new());
        for a in crate::test_support::run_audio_stage(Box::new(plan), live, &x, fs, 16, 0) {
            y.extend_from_slice(&a.samples);
            t.push(a.t0_ns);
        }
        (y, t)
    }

    /// Gain and phase (degrees) against the unit sine, middle half.
    fn fit(y: &[f32], f: f64, fs: f64) -> (f64, f64) {
        let (g, ph) = vibroscope_math::numeric::fit_tone(y, f, fs, y.len() / 4..3 * y.len() / 4);
        (g, ph.to_degrees())
    }

    /// The three kinds on a replay: every block leaves with its own time,
    /// the output is in phase with the input (within 1 degree where the
    /// filter passes) and its gain is the analytic Butterworth magnitude
    /// squared within 0.1 dB; live, the same stage is the causal design
    /// (gain |H| within 0.1 dB, the phase of the IIR).
    #[test]
    fn replay_is_zero_phase_and_live_is_causal() {
        let fs = 2200.0;
        let (hp, bp, bs) = (
            Shape::Highpass { cutoff_hz: 40.0 },
            Shape::Bandpass {
                lo_hz: 200.0,
                hi_hz: 700.0,
            },
            Shape::Bandstop {
                lo_hz: 100.0,
                hi_hz: 130.0,
            },
        );
        let designs = [(2, hp), (3, bp), (2, bs)];
        for (order, shape) in designs {
            let design = Design::Fixed(shape);
            for f in [30.0, 55.0, 100.0, 150.0, 250.0, 400.0, 600.0, 900.0] {
                let plan = |mode| FilterPlan {
                    kind: "test",
                    order,
                    design,
                    mode,
                };
                let h = shape.magnitude(order, f, fs);
                let (y, t) = run(plan(Mode::Auto), false, f, fs, 22_000);
                assert_eq!(y.len(), 22_000);
                let want_t: Vec<i64> = (0..t.len())
                    .map(|k| (k as f64 * 16.0 * 1e9 / fs).round() as i64)
                    .collect();
                assert_eq!(t, want_t, "block times changed");
                let (g, ph) = fit(&y, f, fs);
                if h * h > 1e-6 {
                    let db = 20.0 * (g / (h * h)).log10();
                    assert!(
                        db.abs() < 0.1,
                        "{shape:?} {f} Hz replay: {db:.4} dB off |H|²"
                    );
                }
                if h * h > 0.5 {
                    assert!(ph.abs() < 1.0, "{shape:?} {f} Hz replay: phase {ph:.3} deg");
                }
                let (y, _) = run(plan(Mode::Auto), true, f, fs, 22_000);
                let (g, ph) = fit(&y, f, fs);
                if h > 1e-3 {
                    let db = 20.0 * (g / h).log10();
                    assert!(db.abs() < 0.1, "{shape:?} {f} Hz live: {db:.4} dB off |H|");
                }
                let sos = Sos::butterworth(order, shape, fs).unwrap();
                let want_ph = sos.response_at(f, fs).arg().to_degrees();
                if h > 0.1 {
                    let d = (ph - want_ph + 540.0).rem_euclid(360.0) - 180.0;
                    assert!(
                        d.abs() < 1.0,
                        "{shape:?} {f} Hz live: phase {ph:.2} vs IIR {want_ph:.2}"
                    );
                }
            }
        }
    }
}
