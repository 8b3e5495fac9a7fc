//! Calibration against a known sound (issue 6): compare what a visual
//! microphone recovered with what was played, fit the plain linear model
//! (delay, gain), then try a catalog of effects the model lacks, keeping an
//! effect only if it lowers the error on a held-out part of the recording,
//! and describe the residual that no accepted effect explains.
//!
//! # Model
//! The recovery `y[n]` (rate `fs`, the declared frame rate) is compared with
//! the *target* `T[n] = HP(r(n / fs - τ))`: the reference `r` (rate `fr`)
//! point-sampled at the frame times by band-limited interpolation (a camera
//! samples the motion without an anti-alias filter), then high-passed like
//! the recovery (the listen pipeline's Butterworth; part of the known
//! processing). The plain linear model is `y ≈ g T` with a fractional delay
//! `τ` and a gain `g`, both fitted on the fit part.
//!
//! Every effect is a *correction* applied to the recovery (so the corrected
//! recovery can be written out and the same correction reused on a new
//! recording of the same object and camera). The catalog: time-base
//! error, dropped or duplicated frames, exposure, narrowband interference
//! lines, object transfer function, soft saturation. Acceptance is
//! greedy, best first: each round fits every effect not yet kept on the
//! current corrected recovery and keeps the one that gains most on the
//! held-out part. Each is fitted on the fit part of the recording (blocks of
//! about 0.1 s: blocks 0, 2 and 4 of every five, 60%; interleaved so that
//! both parts see every frequency of a sweep), the linear model is refitted
//! on that part, and the effect is kept when the SNR on the held-out part
//! (blocks 1 and 3 of every five, 40%) rises by at least
//! [`Options::min_gain_db`]. Exception: dropped or duplicated frames are
//! events, not properties; their positions are found on the whole recording
//! with a per-event penalty (a likelihood-ratio test), and the held-out
//! gain is then measured as for the others.
//!
//! Interference lines are subtracted from the recovery as delivered,
//! before every other correction (their frequencies are on the declared
//! time base). When more than one effect is kept, each one's reported gain
//! is what the held-out SNR loses without it.
//!
//! Errors are on the held-out part: SNR and segmental SNR
//! ([`crate::metrics`]) and the log-spectral distance (dB, STFT frames
//! where the target has energy, bins above the high-pass cutoff).
//! Uncertainties are one standard deviation by the Δχ² = 1 rule on the
//! fit-part squared error, with the residual variance taken as white noise
//! (residuals are coloured in practice, so these are lower bounds).

use crate::metrics;
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use serde_json::{json, Value};
use std::f64::consts::PI;

/// Options of [`calibrate`].
#[derive(Clone, Debug)]
pub struct Options {
    /// Least held-out SNR gain (dB) for an effect to be kept.
    pub min_gain_db: f64,
    /// Largest delay searched between reference and recovery (seconds).
    pub max_lag_s: f64,
    /// The recovery's high-pass: `(order, cutoff_hz)`, applied to the
    /// target too; `None` for none.
    pub highpass: Option<(usize, f64)>,
    /// The catalog, in the order effects are tried.
    pub effects: Vec<EffectKind>,
}

impl Options {
    /// The defaults for a recovery at `fs` by the listen pipeline: its
    /// 4th-order high-pass at fs/40 (20-100 Hz), the whole catalog.
    pub fn for_rate(fs: f64) -> Options {
        Options {
            min_gain_db: 0.5,
            max_lag_s: 0.5,
            highpass: Some((4, crate::iir::default_highpass_cutoff_hz(fs))),
            effects: CATALOG.to_vec(),
        }
    }
}

/// The effects calibrate knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EffectKind {
    /// (b) The camera's true frame rate differs from the declared one.
    TimeBase,
    /// (d) Frames the camera dropped or delivered twice.
    Frames,
    /// (c) The exposure's boxcar low-pass.
    Exposure,
    /// (e) Narrowband lines not in the reference.
    Interference,
    /// (a) The object's transfer function (thesis ch. 4.3.3).
    Transfer,
    /// (f) The response saturates softly (`L tanh(x / L)`): a nonlinear
    /// object or loudspeaker driven hard. Added by the worked example in
    /// the README's "Closing the loop".
    SoftClip,
}

/// The catalog in the order it is tried: time base, then frames, then the
/// spectral effects, then saturation.
pub const CATALOG: [EffectKind; 6] = [
    EffectKind::TimeBase,
    EffectKind::Frames,
    EffectKind::Exposure,
    EffectKind::Interference,
    EffectKind::Transfer,
    EffectKind::SoftClip,
];

impl EffectKind {
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::TimeBase => "time_base",
            EffectKind::Frames => "dropped_frames",
            EffectKind::Exposure => "exposure",
            EffectKind::Interference => "interference",
            EffectKind::Transfer => "transfer_function",
            EffectKind::SoftClip => "soft_clip",
        }
    }
}

/// Errors of a recovery against the target on a span of samples.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Errors {
    pub snr_db: f64,
    pub ssnr_db: f64,
    pub lsd_db: f64,
}

/// One accepted effect, as reported.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EffectReport {
    pub name: String,
    pub parameters: Value,
    pub uncertainty: Value,
    pub snr_gain_db: f64,
}

/// What `calibrate` found: `REPORT.json` is this, serialised.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    pub before: Errors,
    pub effects: Vec<EffectReport>,
    pub after: Errors,
    pub unexplained: Vec<Value>,
}

/// A candidate that was fitted but not kept (for logs).
#[derive(Clone, Debug)]
pub struct Rejected {
    pub name: &'static str,
    pub parameters: Value,
    pub snr_gain_db: f64,
}

/// The result of [`calibrate`].
#[derive(Clone, Debug)]
pub struct Calibration {
    pub report: Report,
    /// The accepted corrections, in the order they apply.
    pub corrections: Vec<Correction>,
    pub rejected: Vec<Rejected>,
    /// The corrected recovery at `fs`, divided by the gain, on the capture grid.
    pub corrected: Vec<f64>,
    /// Delay (s) and gain of the final linear model.
    pub delay_s: f64,
    pub gain: f64,
}

/// Why calibration cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalError {
    #[error("{0}")]
    Input(String),
}

// ---------------------------------------------------------------------------
// Corrections
// ---------------------------------------------------------------------------

/// A narrowband line: `a cos(2π f n / fs) + b sin(2π f n / fs)`.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Line {
    pub freq_hz: f64,
    pub a: f64,
    pub b: f64,
}

/// A frame event at delivered sample `index`: `+1` a capture was lost
/// before it, `-1` it repeats the previous capture.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub struct FrameEvent {
    pub index: usize,
    pub delta: i32,
}

/// One fitted correction, applied to a recovery at the frame rate.
#[derive(Clone, Debug, PartialEq)]
pub enum Correction {
    /// Resample from the true rate `fs (1 + ppm 1e-6)` onto the declared grid.
    TimeBase { ppm: f64 },
    /// Put samples back on the capture grid: fill lost ones (AR
    /// interpolation), merge repeated ones.
    Frames { events: Vec<FrameEvent> },
    /// Inverse boxcar of `exposure_s` (at most 12 dB of boost).
    Exposure { exposure_s: f64 },
    /// Subtract lines (recovery units; phase from sample 0; applied first,
    /// to the recovery as delivered).
    Interference { lines: Vec<Line> },
    /// Equalise by `coefficient^-k` (coefficients in dB at frequencies;
    /// 0 dB outside the table), at most ±30 dB, and undo the phase of the
    /// response (degrees at the same frequencies).
    Transfer {
        freqs_hz: Vec<f64>,
        coef_db: Vec<f64>,
        phase_deg: Vec<f64>,
        k: f64,
    },
    /// Undo a soft saturation: `u + a3 u³ + a5 u⁵` (recovery units) on
    /// `u`, the recovery with its high-pass undone, then high-passed again
    /// (the saturation acts on the motion, before the pipeline's
    /// high-pass; after it, the high-pass's phase has moved each harmonic
    /// against its fundamental and no memoryless inverse fits).
    SoftClip {
        a3: f64,
        a5: f64,
        /// The saturation level `L` of `L tanh(x / L)` in the reference's
        /// units, fitted by the forward model (reported, not applied).
        level: f64,
        highpass: Option<(usize, f64)>,
    },
}

/// Most boost the exposure inverse applies (the `exposure` stage's -12 dB floor).
const EXPOSURE_MAX_GAIN: f64 = 4.0;
/// Most boost or cut the transfer equaliser applies, dB.
const TRANSFER_MAX_DB: f64 = 30.0;

impl Correction {
    pub fn kind(&self) -> EffectKind {
        match self {
            Correction::TimeBase { .. } => EffectKind::TimeBase,
            Correction::Frames { .. } => EffectKind::Frames,
            Correction::Exposure { .. } => EffectKind::Exposure,
            Correction::Interference { .. } => EffectKind::Interference,
            Correction::Transfer { .. } => EffectKind::Transfer,
            Correction::SoftClip { .. } => EffectKind::SoftClip,
        }
    }

    /// A property of object and camera (worth reusing on a new recording),
    /// rather than of one recording.
    pub fn reusable(&self) -> bool {
        matches!(
            self,
            Correction::TimeBase { .. } | Correction::Exposure { .. } | Correction::Transfer { .. }
        )
    }

    /// Applies the correction to `z`, sampled at `fs`.
    pub fn apply(&self, z: &[f64], fs: f64) -> Vec<f64> {
        match self {
            Correction::TimeBase { ppm } => {
                let s = 1.0 + ppm * 1e-6;
                let last = (z.len().saturating_sub(1)) as f64;
                let m = (last / s).floor() as usize + 1;
                sample_at(z, 1.0, (0..m.min(z.len() * 2)).map(|k| k as f64 * s))
            }
            Correction::Frames { events } => apply_frames(z, events),
            Correction::SoftClip {
                a3, a5, highpass, ..
            } => {
                let u = undo_highpass(z, fs, *highpass);
                let p: Vec<f64> = u
                    .iter()
                    .map(|&v| {
                        let v2 = v * v;
                        v * (1.0 + v2 * (a3 + v2 * a5))
                    })
                    .collect();
                redo_highpass(&p, fs, *highpass)
            }
            Correction::Exposure { .. } | Correction::Transfer { .. } => equalize(z, fs, |f| {
                self.response(f).unwrap_or(Complex::new(1.0, 0.0))
            }),
            Correction::Interference { lines } => {
                let mut out = z.to_vec();
                for l in lines {
                    let w = 2.0 * PI * l.freq_hz / fs;
                    for (n, v) in out.iter_mut().enumerate() {
                        let p = w * n as f64;
                        *v -= l.a * p.cos() + l.b * p.sin();
                    }
                }
                out
            }
        }
    }

    /// The complex gain at `f` of a correction that is a linear filter
    /// (exposure, transfer function); `None` for the others.
    pub fn response(&self, f: f64) -> Option<Complex<f64>> {
        match self {
            Correction::Exposure { exposure_s } => {
                let g = (1.0 / crate::exposure::boxcar_gain(f, *exposure_s).max(1e-9))
                    .min(EXPOSURE_MAX_GAIN);
                Some(Complex::new(g, 0.0))
            }
            Correction::Transfer {
                freqs_hz,
                coef_db,
                phase_deg,
                k,
            } => {
                let c = interp_table(freqs_hz, coef_db, f);
                let ph = interp_table(freqs_hz, phase_deg, f).to_radians();
                let g = 10f64.powf((-k * c).clamp(-TRANSFER_MAX_DB, TRANSFER_MAX_DB) / 20.0);
                Some(Complex::from_polar(g, -ph))
            }
            _ => None,
        }
    }

    /// A line seen after the corrections `upstream` (applied in order) as
    /// it is in the recovery before them: a time-base correction scales
    /// frequencies by its rate ratio, a filter scales the line's phasor
    /// `a - ib` by its gain; frame events are ignored (the phase jump
    /// they cause is lost).
    fn line_before(line: Line, upstream: &[Correction], fs: f64) -> Line {
        let mut l = line;
        for c in upstream.iter().rev() {
            if let Correction::TimeBase { ppm } = c {
                l.freq_hz /= 1.0 + ppm * 1e-6;
            } else if let Some(g) = c.response(l.freq_hz.abs().min(fs / 2.0)) {
                let p = Complex::new(l.a, -l.b)
                    / if g.norm() > 0.0 {
                        g
                    } else {
                        Complex::new(1.0, 0.0)
                    };
                (l.a, l.b) = (p.re, -p.im);
            }
        }
        l
    }

    /// The parameters as reported (and read back by [`Correction::from_json`]).
    pub fn parameters(&self, fs: f64, gain: f64) -> Value {
        match self {
            Correction::TimeBase { ppm } => json!({
                "clock_error_ppm": ppm,
                "true_fps": fs * (1.0 + ppm * 1e-6),
                "declared_fps": fs,
            }),
            Correction::Frames { events } => json!({
                "events": events.iter().map(|e| json!({
                    "frame": e.index,
                    "kind": if e.delta > 0 { "dropped" } else { "duplicated" },
                    "count": e.delta.unsigned_abs(),
                })).collect::<Vec<_>>(),
            }),
            Correction::Exposure { exposure_s } => json!({
                "exposure_us": exposure_s * 1e6,
                "fraction_of_frame": exposure_s * fs,
            }),
            Correction::Interference { lines } => json!({
                "lines": lines.iter().map(|l| json!({
                    "freq_hz": l.freq_hz,
                    "amplitude": l.a.hypot(l.b) / gain.abs().max(1e-300),
                })).collect::<Vec<_>>(),
            }),
            Correction::Transfer {
                freqs_hz,
                coef_db,
                phase_deg,
                k,
            } => json!({
                "k": k,
                "frequencies_hz": freqs_hz,
                "coefficients_db": coef_db,
                "phase_deg": phase_deg,
            }),
            Correction::SoftClip { a3, a5, level, .. } => json!({
                "level_in_reference_units": level,
                "a3": a3,
                "a5": a5,
            }),
        }
    }

    /// A reusable correction back from a report's effect entry; `None` for
    /// per-recording effects (frames, interference). Errors name the field.
    pub fn from_json(name: &str, p: &Value) -> Result<Option<Correction>, String> {
        let num = |key: &str| {
            p.get(key)
                .and_then(Value::as_f64)
                .filter(|v| v.is_finite())
                .ok_or_else(|| format!("effect `{name}`: parameters.{key} must be a finite number"))
        };
        let list = |key: &str| -> Result<Vec<f64>, String> {
            p.get(key)
                .and_then(Value::as_array)
                .and_then(|a| a.iter().map(Value::as_f64).collect::<Option<Vec<_>>>())
                .filter(|v| v.iter().all(|x| x.is_finite()))
                .ok_or_else(|| {
                    format!("effect `{name}`: parameters.{key} must be a list of numbers")
                })
        };
        Ok(match name {
            "time_base" => Some(Correction::TimeBase {
                ppm: num("clock_error_ppm")?,
            }),
            "exposure" => {
                let e = num("exposure_us")?;
                if e <= 0.0 {
                    return Err(format!(
                        "effect `exposure`: parameters.exposure_us must be > 0, got {e}"
                    ));
                }
                Some(Correction::Exposure {
                    exposure_s: e * 1e-6,
                })
            }
            "transfer_function" => {
                let (f, c) = (list("frequencies_hz")?, list("coefficients_db")?);
                if f.len() != c.len() || f.windows(2).any(|w| w[1] <= w[0]) {
                    return Err(format!(
                        "effect `{name}`: frequencies_hz ({}) must increase and match coefficients_db ({})",
                        f.len(),
                        c.len()
                    ));
                }
                let phase = match p.get("phase_deg") {
                    None => vec![0.0; f.len()],
                    Some(_) => list("phase_deg")?,
                };
                if phase.len() != f.len() {
                    return Err(format!(
                        "effect `{name}`: phase_deg has {} entries, frequencies_hz {}",
                        phase.len(),
                        f.len()
                    ));
                }
                Some(Correction::Transfer {
                    freqs_hz: f,
                    coef_db: c,
                    phase_deg: phase,
                    k: num("k")?,
                })
            }
            // Per recording: the level is in the recovery's units, which
            // depend on the texture and region as much as on the object.
            "dropped_frames" | "interference" | "soft_clip" => None,
            other => return Err(format!("unknown effect `{other}`")),
        })
    }
}

/// Linear interpolation in a table; 0 outside it.
fn interp_table(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    match xs.iter().position(|&v| v >= x) {
        None => 0.0,
        Some(0) if xs.first() == Some(&x) => ys[0],
        Some(0) => 0.0,
        Some(i) => {
            let t = (x - xs[i - 1]) / (xs[i] - xs[i - 1]);
            ys[i - 1] + t * (ys[i] - ys[i - 1])
        }
    }
}

fn apply_frames(z: &[f64], events: &[FrameEvent]) -> Vec<f64> {
    let mut out: Vec<f64> = Vec::with_capacity(z.len() + events.len());
    let mut gaps: Vec<(usize, usize)> = Vec::new();
    let mut ev = events.iter().peekable();
    let mut merge = 0usize;
    for (n, &v) in z.iter().enumerate() {
        while let Some(e) = ev.peek().filter(|e| e.index == n) {
            if e.delta > 0 {
                let d = e.delta as usize;
                gaps.push((out.len(), d));
                out.extend(std::iter::repeat_n(0.0, d));
            } else {
                merge += e.delta.unsigned_abs() as usize;
            }
            ev.next();
        }
        if merge > 0 && !out.is_empty() {
            // A repeat of the previous capture: average the two readings.
            merge -= 1;
            if let Some(last) = out.last_mut() {
                *last = 0.5 * (*last + v);
            }
        } else {
            out.push(v);
        }
    }
    let mut ar = crate::ar_interp::ArInterpolator::new(16, 2);
    for (left, missing) in gaps {
        let lo = left.saturating_sub(256);
        let hi = (left + missing + 256).min(out.len());
        ar.fill(&mut out[lo..hi], left - lo, missing);
    }
    out
}

// ---------------------------------------------------------------------------
// Signal tools
// ---------------------------------------------------------------------------

/// Half-width of the band-limited interpolator, in input samples.
const SINC_HALF: isize = 32;

fn bessel_i0(x: f64) -> f64 {
    let (mut sum, mut term, mut k) = (1.0, 1.0, 1.0);
    while term > 1e-12 * sum {
        term *= (x / (2.0 * k)) * (x / (2.0 * k));
        sum += term;
        k += 1.0;
    }
    sum
}

/// `x` (sampled at `rate`) at arbitrary `times` (seconds; sample `i` is at
/// `i / rate`), by a Kaiser-windowed sinc at `x`'s own Nyquist frequency
/// (exact at sample instants); zero outside `x`.
pub fn sample_at(x: &[f64], rate: f64, times: impl Iterator<Item = f64>) -> Vec<f64> {
    const BETA: f64 = 8.0;
    let i0b = bessel_i0(BETA);
    let n = x.len() as isize;
    times
        .map(|t| {
            let p = t * rate;
            if !p.is_finite() || p < -(SINC_HALF as f64) || p > (n + SINC_HALF) as f64 {
                return 0.0;
            }
            let c = p.floor() as isize;
            let frac = p - c as f64;
            if frac == 0.0 {
                return if (0..n).contains(&c) {
                    x[c as usize]
                } else {
                    0.0
                };
            }
            let mut acc = 0.0;
            for i in (c - SINC_HALF + 1)..=(c + SINC_HALF) {
                if !(0..n).contains(&i) {
                    continue;
                }
                let d = p - i as f64;
                let r = d / SINC_HALF as f64;
                let w = bessel_i0(BETA * (1.0 - r * r).max(0.0).sqrt()) / i0b;
                let s = (PI * d).sin() / (PI * d);
                acc += x[i as usize] * s * w;
            }
            acc
        })
        .collect()
}

/// STFT length for a rate: about 0.1 s, a power of two in 64..=4096.
pub fn stft_len(fs: f64) -> usize {
    ((0.1 * fs).max(64.0) as usize)
        .next_power_of_two()
        .clamp(64, 4096)
}

/// Periodic sqrt-Hann frames, hop N/2, zero-phase gain `gain(f)` per bin,
/// weighted overlap-add (perfect reconstruction for gain 1).
pub fn equalize(x: &[f64], fs: f64, gain: impl Fn(f64) -> Complex<f64>) -> Vec<f64> {
    let nfft = stft_len(fs);
    let hop = nfft / 2;
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(nfft);
    let inv = planner.plan_fft_inverse(nfft);
    let win: Vec<f64> = (0..nfft)
        .map(|i| (0.5 - 0.5 * (2.0 * PI * i as f64 / nfft as f64).cos()).sqrt())
        .collect();
    let g: Vec<Complex<f64>> = (0..=nfft / 2)
        .map(|k| gain(k as f64 * fs / nfft as f64))
        .collect();
    // Padded by one frame on each side.
    let len = x.len() + 2 * nfft;
    let mut padded = vec![0.0; len];
    padded[nfft..nfft + x.len()].copy_from_slice(x);
    let mut out = vec![0.0; len];
    let mut buf = fwd.make_input_vec();
    let mut spec = fwd.make_output_vec();
    let mut s = 0;
    while s + nfft <= len {
        for i in 0..nfft {
            buf[i] = padded[s + i] * win[i];
        }
        let _ = fwd.process(&mut buf, &mut spec);
        for (c, gk) in spec.iter_mut().zip(&g) {
            *c *= *gk;
        }
        if let Some(c) = spec.first_mut() {
            c.im = 0.0;
        }
        if let Some(c) = spec.last_mut() {
            c.im = 0.0;
        }
        let _ = inv.process(&mut spec, &mut buf);
        for i in 0..nfft {
            out[s + i] += buf[i] * win[i] / nfft as f64;
        }
        s += hop;
    }
    out[nfft..nfft + x.len()].to_vec()
}

/// Hann-windowed STFT frames (hop N/2) of `x`: one spectrum per frame.
fn stft(x: &[f64], nfft: usize) -> Vec<Vec<Complex<f64>>> {
    let hop = nfft / 2;
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(nfft);
    let win: Vec<f64> = (0..nfft)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / nfft as f64).cos())
        .collect();
    let mut frames = Vec::new();
    let mut buf = fwd.make_input_vec();
    let mut s = 0;
    while s + nfft <= x.len() {
        for i in 0..nfft {
            buf[i] = x[s + i] * win[i];
        }
        let mut spec = fwd.make_output_vec();
        let _ = fwd.process(&mut buf, &mut spec);
        frames.push(spec);
        s += hop;
    }
    frames
}

/// Welch power spectrum (mean of |STFT|²) with `nfft`.
fn welch(x: &[f64], nfft: usize) -> Vec<f64> {
    let frames = stft(x, nfft);
    let mut p = vec![0.0; nfft / 2 + 1];
    for f in &frames {
        for (a, c) in p.iter_mut().zip(f) {
            *a += c.norm_sqr();
        }
    }
    let k = frames.len().max(1) as f64;
    p.iter_mut().for_each(|v| *v /= k);
    p
}

/// Golden-section minimisation of `f` on `[a, b]`; returns `(x, f(x))`.
fn golden(mut f: impl FnMut(f64) -> f64, mut a: f64, mut b: f64, iters: usize) -> (f64, f64) {
    let r = 0.5 * (5f64.sqrt() - 1.0);
    let mut c = b - r * (b - a);
    let mut d = a + r * (b - a);
    let (mut fc, mut fd) = (f(c), f(d));
    for _ in 0..iters {
        if fc < fd {
            b = d;
            d = c;
            fd = fc;
            c = b - r * (b - a);
            fc = f(c);
        } else {
            a = c;
            c = d;
            fc = fd;
            d = a + r * (b - a);
            fd = f(d);
        }
    }
    if fc < fd {
        (c, fc)
    } else {
        (d, fd)
    }
}

/// One standard deviation of a parameter at a minimum `x` of `sse` by the
/// Δχ² = 1 rule: the curvature of `sse` by central differences with step
/// `h`, residual variance `sigma2`.
fn curvature_sigma(mut sse: impl FnMut(f64) -> f64, x: f64, h: f64, sigma2: f64) -> f64 {
    let (a, b, c) = (sse(x - h), sse(x), sse(x + h));
    let curv = (a + c - 2.0 * b) / (h * h);
    if curv > 0.0 {
        (2.0 * sigma2 / curv).sqrt()
    } else {
        f64::INFINITY
    }
}

/// Least-squares gain of `z ≈ g t` and the squared error left.
fn gain_sse(t: &[f64], z: &[f64]) -> (f64, f64) {
    let tt: f64 = t.iter().map(|v| v * v).sum();
    let tz: f64 = t.iter().zip(z).map(|(a, b)| a * b).sum();
    let zz: f64 = z.iter().map(|v| v * v).sum();
    if tt <= 0.0 {
        return (0.0, zz);
    }
    let g = tz / tt;
    (g, (zz - g * tz).max(0.0))
}

/// Alias of frequency `f` sampled at `fs`, folded into `[0, fs/2]`.
pub fn alias(f: f64, fs: f64) -> f64 {
    let m = f.rem_euclid(fs);
    if m > fs / 2.0 {
        fs - m
    } else {
        m
    }
}

// ---------------------------------------------------------------------------
// The model
// ---------------------------------------------------------------------------

struct Model<'a> {
    r: &'a [f64],
    fr: f64,
    fs: f64,
    opts: &'a Options,
}

/// The linear model on a recovery.
#[derive(Clone, Debug)]
struct Fit {
    tau: f64,
    g: f64,
    /// The target at `tau` for every sample of the recovery.
    t: Vec<f64>,
}

impl Model<'_> {
    /// `T[n]` for `n` in `-pre..len`: reference at `n / (fs (1 + ppm)) - tau`,
    /// high-passed from `n = -pre`.
    fn target(&self, len: usize, pre: usize, tau: f64, ppm: f64) -> Vec<f64> {
        self.target_about(len, pre, tau, ppm, 0.0)
    }

    /// [`Model::target`] with the rate error applied about sample `centre`
    /// (which stays at `centre / fs - tau`).
    fn target_about(&self, len: usize, pre: usize, tau: f64, ppm: f64, centre: f64) -> Vec<f64> {
        let rate = self.fs * (1.0 + ppm * 1e-6);
        let c = centre / self.fs;
        let t = sample_at(
            self.r,
            self.fr,
            (0..len + pre).map(|i| (i as f64 - pre as f64 - centre) / rate + c - tau),
        );
        redo_highpass(&t, self.fs, self.opts.highpass)
    }

    /// The reference at `n / fs - tau` for `n` in `0..len`, not high-passed.
    fn unfiltered_target(&self, len: usize, tau: f64) -> Vec<f64> {
        sample_at(self.r, self.fr, (0..len).map(|i| i as f64 / self.fs - tau))
    }

    /// Whether sample `i` is in the fit part: blocks of one STFT length
    /// (about 0.1 s), blocks 0, 2 and 4 of every five fitted, 1 and 3 held
    /// out (60% / 40%, interleaved, so both parts see every frequency of a
    /// sweep and every stretch of a drift).
    fn is_fit(&self, i: usize) -> bool {
        !matches!((i / stft_len(self.fs)) % 5, 1 | 3)
    }

    /// `x` with the held-out samples set to zero.
    fn masked(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .enumerate()
            .map(|(i, &v)| if self.is_fit(i) { v } else { 0.0 })
            .collect()
    }

    /// The held-out samples of `x`, in order.
    fn held(&self, x: &[f64]) -> Vec<f64> {
        x.iter()
            .enumerate()
            .filter(|(i, _)| !self.is_fit(*i))
            .map(|(_, &v)| v)
            .collect()
    }

    /// Number of fit samples among the first `len`.
    fn nfit(&self, len: usize) -> usize {
        (0..len).filter(|&i| self.is_fit(i)).count().max(1)
    }

    /// Delay (integer by cross-correlation, then fractional by golden
    /// section) and gain, on the fit part.
    fn fit_linear(&self, z: &[f64]) -> Fit {
        let n = z.len();
        let zm = self.masked(z);
        let t0 = self.target(n, 0, 0.0, 0.0);
        let max_lag = (self.opts.max_lag_s * self.fs).round() as usize;
        let (lag, _) = metrics::best_lag_gain(&t0, &zm, max_lag.min(n / 2));
        let sse = |tau: f64| gain_sse(&self.masked(&self.target(n, 0, tau, 0.0)), &zm).1;
        let c = lag as f64 / self.fs;
        let (tau, _) = golden(sse, c - 1.0 / self.fs, c + 1.0 / self.fs, 24);
        let t = self.target(z.len(), 0, tau, 0.0);
        let (g, _) = gain_sse(&self.masked(&t), &zm);
        Fit { tau, g, t }
    }

    fn errors(&self, z: &[f64], fit: &Fit) -> Errors {
        let g = if fit.g != 0.0 { fit.g } else { 1.0 };
        let zh: Vec<f64> = self.held(z).iter().map(|v| v / g).collect();
        let t = &self.held(&fit.t);
        Errors {
            snr_db: metrics::snr_db(t, &zh),
            ssnr_db: metrics::segmental_snr_db(t, &zh, self.fs),
            lsd_db: self.lsd_db(t, &zh),
        }
    }

    /// Log-spectral distance: RMS of the dB difference over the bins above
    /// the high-pass cutoff where the target is within 40 dB of its peak in
    /// that frame, averaged over frames where the target has energy (within
    /// 40 dB of its loudest frame).
    fn lsd_db(&self, t: &[f64], z: &[f64]) -> f64 {
        let nfft = stft_len(self.fs)
            .min(t.len().max(2).next_power_of_two() / 2)
            .max(16);
        let (ft, fz) = (stft(t, nfft), stft(z, nfft));
        let lo = self
            .opts
            .highpass
            .map_or(1, |(_, c)| (c * nfft as f64 / self.fs).ceil() as usize + 1);
        let e: Vec<f64> = ft
            .iter()
            .map(|f| f.iter().map(|c| c.norm_sqr()).sum())
            .collect();
        let emax = e.iter().cloned().fold(0.0, f64::max);
        let pmax = ft
            .iter()
            .flat_map(|f| f.iter().map(|c| c.norm_sqr()))
            .fold(0.0, f64::max);
        let floor = pmax * 1e-6 + 1e-300;
        let mut acc = 0.0;
        let mut count = 0usize;
        for (i, (a, b)) in ft.iter().zip(&fz).enumerate() {
            if e[i] < emax * 1e-4 || a.len() <= lo {
                continue;
            }
            let peak = a[lo..].iter().map(|c| c.norm_sqr()).fold(0.0, f64::max);
            let (mut d, mut bins) = (0.0, 0usize);
            for (x, y) in a[lo..].iter().zip(&b[lo..]) {
                if x.norm_sqr() < 1e-4 * peak {
                    continue;
                }
                let v = 10.0 * ((x.norm_sqr() + floor) / (y.norm_sqr() + floor)).log10();
                d += v * v;
                bins += 1;
            }
            if bins > 0 {
                acc += (d / bins as f64).sqrt();
                count += 1;
            }
        }
        if count == 0 {
            f64::NAN
        } else {
            acc / count as f64
        }
    }
}

// ---------------------------------------------------------------------------
// Fitting each effect
// ---------------------------------------------------------------------------

/// A fitted correction with its uncertainty.
struct Candidate {
    correction: Correction,
    uncertainty: Value,
}

/// Local lags (samples, `z[n] ≈ g T[n - lag]`) in windows over
/// `[0, end)`: `(centre, lag, correlation)` for windows that correlate.
fn local_lags(
    z: &[f64],
    t_ext: &[f64],
    pre: usize,
    g: f64,
    end: usize,
    fs: f64,
) -> Vec<(f64, f64, f64)> {
    let w = ((0.2 * fs) as usize).next_power_of_two().clamp(64, 1024);
    let m = (w / 4) as isize;
    let mut out = Vec::new();
    let mut s = 0usize;
    while s + w <= end {
        let seg = &z[s..s + w];
        let zz: f64 = seg.iter().map(|v| v * v).sum();
        let xc = |l: isize| -> f64 {
            let mut acc = 0.0;
            for (i, v) in seg.iter().enumerate() {
                let k = (s + i + pre) as isize - l;
                if k >= 0 && (k as usize) < t_ext.len() {
                    acc += v * t_ext[k as usize];
                }
            }
            acc * g.signum()
        };
        let vals: Vec<f64> = (-m..=m).map(xc).collect();
        let (bi, &bv) = vals
            .iter()
            .enumerate()
            .max_by(|a, b| a.1.total_cmp(b.1))
            .unwrap_or((0, &0.0));
        let tt: f64 = {
            let lag = bi as isize - m;
            (0..w)
                .map(|i| {
                    let k = (s + i + pre) as isize - lag;
                    if k >= 0 && (k as usize) < t_ext.len() {
                        t_ext[k as usize].powi(2)
                    } else {
                        0.0
                    }
                })
                .sum()
        };
        let rho = if zz > 0.0 && tt > 0.0 {
            bv / (zz * tt).sqrt()
        } else {
            0.0
        };
        if bi > 0 && bi + 1 < vals.len() && rho > 0.5 {
            let (a, b, c) = (vals[bi - 1], vals[bi], vals[bi + 1]);
            let den = a - 2.0 * b + c;
            let d = if den < 0.0 { 0.5 * (a - c) / den } else { 0.0 };
            out.push((s as f64 + w as f64 / 2.0, (bi as isize - m) as f64 + d, rho));
        }
        s += w / 2;
    }
    out
}

/// Theil-Sen slope and intercept of `(x, y)` points.
fn theil_sen(p: &[(f64, f64)]) -> Option<(f64, f64)> {
    let mut slopes = Vec::new();
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            if p[j].0 != p[i].0 {
                slopes.push((p[j].1 - p[i].1) / (p[j].0 - p[i].0));
            }
        }
    }
    if slopes.is_empty() {
        return None;
    }
    let s = median(&mut slopes);
    let mut ints: Vec<f64> = p.iter().map(|(x, y)| y - s * x).collect();
    Some((s, median(&mut ints)))
}

fn median(v: &mut [f64]) -> f64 {
    if v.is_empty() {
        return f64::NAN;
    }
    v.sort_by(|a, b| a.total_cmp(b));
    let n = v.len();
    if n % 2 == 1 {
        v[n / 2]
    } else {
        0.5 * (v[n / 2 - 1] + v[n / 2])
    }
}

/// Normalised correlation of `z` with `t` at integer lags `-k..=k`
/// (`z[n] ≈ g t[n - l]`), the peak of its magnitude refined by a
/// parabola: `(lag, |value|)`.
fn corr_peak(z: &[f64], t: &[f64], k: usize) -> (f64, f64) {
    let n = z.len().min(t.len());
    let zz: f64 = z[..n].iter().map(|v| v * v).sum();
    let tt: f64 = t[..n].iter().map(|v| v * v).sum();
    let norm = (zz * tt).sqrt().max(1e-300);
    let ki = k as isize;
    let vals: Vec<f64> = (-ki..=ki)
        .map(|l| {
            let mut acc = 0.0;
            for i in k..n.saturating_sub(k) {
                acc += z[i] * t[(i as isize - l) as usize];
            }
            acc / norm
        })
        .collect();
    let (bi, _) = vals
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .unwrap_or((0, &0.0));
    let sign = if vals.get(bi).is_some_and(|v| *v < 0.0) {
        -1.0
    } else {
        1.0
    };
    let vals: Vec<f64> = vals.iter().map(|v| v * sign).collect();
    let (bi, &bv) = vals
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((0, &0.0));
    // The correlation of band-limited signals is band-limited: refine the
    // peak by interpolating it, in twentieths of a sample. (A parabola
    // through integer lags misreads a correlation that oscillates every two
    // or three samples, as a chirp's does near fs/2, by up to a third of
    // its height depending on the fractional lag: enough to rank a wrong
    // rate above the right one.)
    let fine = sample_at(&vals, 1.0, (-20..=20).map(|j| bi as f64 + j as f64 / 20.0));
    let (j, &v) = fine
        .iter()
        .enumerate()
        .max_by(|a, b| a.1.total_cmp(b.1))
        .unwrap_or((20, &bv));
    ((bi as isize - ki) as f64 + (j as f64 - 20.0) / 20.0, v)
}

/// The rate error: a grid over ±1% in steps that keep the drift over the
/// fit part under half a sample, each point scored by the best correlation
/// within ±32 samples of lag (the rate is warped about the fit part's
/// centre; for a chirp a delay mimics a rate error, so both are searched
/// together), then a nested golden-section search on rate and fractional
/// delay.
fn fit_time_base(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let n = z.len();
    let nf = m.nfit(n);
    let zm = m.masked(z);
    let centre = n as f64 / 2.0;
    let step = 0.5 / n as f64;
    let steps = (0.01 / step).ceil() as i64;
    let score = |e: f64| {
        let t = m.target_about(n, 0, fit.tau, e * 1e6, centre);
        corr_peak(&zm, &t, 32)
    };
    let (mut best, mut best_v, mut best_lag) = (0.0, f64::NEG_INFINITY, 0.0);
    for i in -steps..=steps {
        let e = i as f64 * step;
        let (lag, v) = score(e);
        if v > best_v {
            (best, best_v, best_lag) = (e, v, lag);
        }
    }
    let tau0 = fit.tau + best_lag / m.fs;
    let sse_at = |e: f64| -> f64 {
        golden(
            |t| gain_sse(&m.masked(&m.target_about(n, 0, t, e * 1e6, centre)), &zm).1,
            tau0 - 0.6 / m.fs,
            tau0 + 0.6 / m.fs,
            16,
        )
        .1
    };
    let (e, sse) = golden(sse_at, best - step, best + step, 16);
    let sigma2 = sse / nf as f64;
    let sd = curvature_sigma(sse_at, e, 0.05 / n as f64, sigma2);
    Some(Candidate {
        correction: Correction::TimeBase { ppm: e * 1e6 },
        uncertainty: json!({ "clock_error_ppm": sd * 1e6 }),
    })
}

/// Opposite frame events closer than this (samples) cancel.
const MIN_EVENT_GAP: usize = 32;

fn fit_frames(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    const D: usize = 3;
    let n = z.len();
    if n < 16 {
        return None;
    }
    let g = fit.g;
    // The fractional delay common to all segments: per block of 64
    // samples the best integer offset, summed (blind to where events are).
    let blocks = |tau: f64| -> f64 {
        let t = m.target(n + 2 * D, D, tau, 0.0);
        z.chunks(64)
            .enumerate()
            .map(|(b, c)| {
                (0..2 * D + 1)
                    .map(|j| {
                        c.iter()
                            .enumerate()
                            .map(|(i, v)| (v - g * t[b * 64 + i + j]).powi(2))
                            .sum::<f64>()
                    })
                    .fold(f64::INFINITY, f64::min)
            })
            .sum()
    };
    let (tau, _) = golden(blocks, fit.tau - 0.5 / m.fs, fit.tau + 0.5 / m.fs, 16);
    let t = m.target(n + 2 * D, D, tau, 0.0);
    let nd = 2 * D + 1;
    // Cost of offset d (index d + D) at sample i: (z[i] - g T[i + d])².
    let full = |i: usize, j: usize| -> f64 {
        let v = z[i] - g * t[i + j];
        v * v
    };
    // The path is found on the fit part only (held-out samples cost
    // nothing); each event is then placed within the stretch the path left
    // open by the whole recording.
    let cost = |i: usize, j: usize| -> f64 {
        if m.is_fit(i) {
            full(i, j)
        } else {
            0.0
        }
    };
    // Noise from the median error of the current alignment (the model's
    // residual, coloured noise included); not below -40 dB of the
    // recovery's power (a residual that small is model error, not noise).
    let mut cur: Vec<f64> = (0..n)
        .filter(|&i| m.is_fit(i))
        .map(|i| full(i, D))
        .collect();
    let power = z.iter().map(|v| v * v).sum::<f64>() / n as f64;
    let sigma2 = (median(&mut cur) / 0.455).max(1e-4 * power).max(1e-300);
    let lambda = 3.0 * (n as f64).ln() * sigma2;
    // Viterbi over offsets, steps of ±1.
    let mut acc: Vec<f64> = (0..nd)
        .map(|j| lambda * (j as f64 - D as f64).abs() + cost(0, j))
        .collect();
    let mut back = vec![0u8; n * nd];
    let mut next = vec![0.0; nd];
    for i in 1..n {
        for j in 0..nd {
            let mut bj = j;
            let mut bv = acc[j];
            for k in [j.wrapping_sub(1), j + 1] {
                if k < nd && acc[k] + lambda < bv {
                    bv = acc[k] + lambda;
                    bj = k;
                }
            }
            back[i * nd + j] = bj as u8;
            next[j] = bv + cost(i, j);
        }
        std::mem::swap(&mut acc, &mut next);
    }
    let mut j = (0..nd).min_by(|&a, &b| acc[a].total_cmp(&acc[b]))?;
    let mut path = vec![0usize; n];
    for i in (0..n).rev() {
        path[i] = j;
        if i > 0 {
            j = back[i * nd + j] as usize;
        }
    }
    let mut events: Vec<FrameEvent> = (1..n)
        .filter(|&i| path[i] != path[i - 1])
        .map(|i| FrameEvent {
            index: i,
            delta: path[i] as i32 - path[i - 1] as i32,
        })
        .collect();
    // A drop and a repeat within a few frames of each other are a local
    // wiggle of the lag (a phase error the model lacks), not two camera
    // faults: remove such opposite pairs.
    let mut k = 0;
    while k + 1 < events.len() {
        let (a, b) = (events[k], events[k + 1]);
        if a.delta == -b.delta && b.index - a.index < MIN_EVENT_GAP {
            for i in a.index..b.index {
                path[i] = path[a.index - 1];
            }
            events.drain(k..k + 2);
            k = k.saturating_sub(1);
        } else {
            k += 1;
        }
    }
    if events.is_empty() {
        return None;
    }
    // Place each event within the held-out stretch around it by the whole
    // recording; uncertainty: positions whose cost is within σ² of the best,
    // between the neighbouring events.
    let mut pos_sd = Vec::new();
    for k in 0..events.len() {
        let e = events[k];
        let (jb, ja) = (path[e.index - 1], path[e.index]);
        let open_lo = (1..e.index)
            .rev()
            .find(|&i| m.is_fit(i))
            .map_or(1, |i| i + 1);
        let open_hi = (e.index..n).find(|&i| m.is_fit(i)).unwrap_or(n - 1);
        let lo = if k > 0 { events[k - 1].index + 1 } else { 1 };
        let hi = events.get(k + 1).map_or(n - 1, |x| x.index - 1);
        // cost(p) = Σ_{i<p} c(i, jb) + Σ_{i>=p} c(i, ja), relative.
        let mut c = 0.0;
        let mut costs = vec![0.0; hi + 1 - lo];
        for (p, slot) in (lo..=hi).zip(costs.iter_mut()) {
            if p > lo {
                c += full(p - 1, jb) - full(p - 1, ja);
            }
            *slot = c;
        }
        let cmin = costs.iter().cloned().fold(f64::INFINITY, f64::min);
        let within: Vec<usize> = costs
            .iter()
            .enumerate()
            .filter(|(_, &v)| v <= cmin + sigma2)
            .map(|(i, _)| i)
            .collect();
        let spread = match (within.first(), within.last()) {
            (Some(a), Some(b)) => (b - a) as f64 / 2.0,
            _ => 0.0,
        };
        pos_sd.push(spread.max(0.5));
        let (a, b) = (open_lo.max(lo), open_hi.min(hi));
        if a <= b {
            if let Some(p) = (a..=b).min_by(|&x, &y| costs[x - lo].total_cmp(&costs[y - lo])) {
                events[k].index = p;
            }
        }
    }
    Some(Candidate {
        correction: Correction::Frames { events },
        uncertainty: json!({ "frame": pos_sd }),
    })
}

/// Fit-part squared error after a zero-phase equaliser, gain refitted.
fn eq_sse(m: &Model, z: &[f64], fit: &Fit, c: &Correction) -> f64 {
    let y = c.apply(z, m.fs);
    gain_sse(&m.masked(&fit.t), &m.masked(&y)).1
}

fn fit_exposure(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let period = 1.0 / m.fs;
    let corr = |e: f64| Correction::Exposure { exposure_s: e };
    let steps = 20;
    let grid: Vec<(f64, f64)> = (0..=steps)
        .map(|i| {
            let e = period * i as f64 / steps as f64;
            let s = if i == 0 {
                gain_sse(&m.masked(&fit.t), &m.masked(z)).1
            } else {
                eq_sse(m, z, fit, &corr(e))
            };
            (e, s)
        })
        .collect();
    let (bi, _) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    if bi == 0 {
        return None;
    }
    let step = period / steps as f64;
    let lo = (grid[bi].0 - step).max(step * 0.1);
    let hi = (grid[bi].0 + step).min(period);
    let (e, sse) = golden(|e| eq_sse(m, z, fit, &corr(e)), lo, hi, 16);
    let nf = m.nfit(z.len());
    let sd = curvature_sigma(
        |x| eq_sse(m, z, fit, &corr(x)),
        e,
        0.02 * period,
        sse / nf as f64,
    );
    Some(Candidate {
        correction: corr(e),
        uncertainty: json!({ "exposure_us": sd * 1e6 }),
    })
}

/// Frequencies of the reference's tonal peaks (at most 3): bins 10 dB
/// above the local median of its spectrum.
fn tonal_peaks(p: &[f64], df: f64) -> Vec<f64> {
    let mut peaks: Vec<(f64, f64)> = local_prominent(p, 10.0, 8)
        .into_iter()
        .map(|k| (k as f64 * df, p[k]))
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    peaks.truncate(3);
    peaks.into_iter().map(|(f, _)| f).collect()
}

/// Local maxima at least `ratio` (power) above the median of the `half`
/// bins on each side.
fn local_prominent(p: &[f64], ratio: f64, half: usize) -> Vec<usize> {
    let mut out = Vec::new();
    for k in 1..p.len().saturating_sub(1) {
        if !(p[k] >= p[k - 1] && p[k] > p[k + 1]) {
            continue;
        }
        // Above the median on each side (the edge of a band is not a peak).
        let (a, b) = (k.saturating_sub(half), (k + half + 1).min(p.len()));
        let mut left: Vec<f64> = p[a..k].to_vec();
        let mut right: Vec<f64> = p[k + 1..b].to_vec();
        let (ml, mr) = (median(&mut left), median(&mut right));
        if p[k] > 0.0 && p[k] >= ratio * ml && p[k] >= ratio * mr {
            out.push(k);
        }
    }
    out
}

/// Whether `f` is (within `tol`) an alias of a harmonic or an
/// intermodulation product of order <= 5 of the tones `tones`.
fn is_product(f: f64, tones: &[f64], fs: f64, tol: f64) -> bool {
    let near = |x: f64| (alias(x, fs) - f).abs() <= tol;
    for (i, &a) in tones.iter().enumerate() {
        for h in 1..=5 {
            if near(h as f64 * a) {
                return true;
            }
        }
        for &b in &tones[i + 1..] {
            for p in 1..=4i32 {
                for q in 1..=(5 - p) {
                    let (fp, fq) = (p as f64 * a, q as f64 * b);
                    if near(fp + fq) || near((fp - fq).abs()) {
                        return true;
                    }
                }
            }
        }
    }
    false
}

fn fit_interference(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let n = z.len();
    let nf = m.nfit(n);
    // Frames of one block (the fit part's unit).
    let nfft = stft_len(m.fs);
    let df = m.fs / nfft as f64;
    let res: Vec<f64> = m.masked(&(0..n).map(|i| z[i] - fit.g * fit.t[i]).collect::<Vec<_>>());
    let gt: Vec<f64> = m.masked(&fit.t.iter().map(|v| v * fit.g).collect::<Vec<_>>());
    let (pr, pt) = (welch(&res, nfft), welch(&gt, nfft));
    let tones = tonal_peaks(&pt, df);
    let half = 8;
    let lo_bin = m.opts.highpass.map_or(1, |(_, c)| (c / df).ceil() as usize);
    let mut cands: Vec<usize> = local_prominent(&pr, 10.0, half)
        .into_iter()
        .filter(|&k| k >= lo_bin)
        .filter(|&k| !is_product(k as f64 * df, &tones, m.fs, 2.0 * df))
        .collect();
    cands.sort_by(|&a, &b| pr[b].total_cmp(&pr[a]));
    cands.truncate(4);
    if cands.is_empty() {
        return None;
    }
    let mut lines = Vec::new();
    let mut uncertainty = Vec::new();
    let mut r = res.clone();
    for k in cands {
        let power = |f: f64| {
            let w = 2.0 * PI * f / m.fs;
            let (mut c, mut s) = (0.0, 0.0);
            for (n, v) in r.iter().enumerate() {
                c += v * (w * n as f64).cos();
                s += v * (w * n as f64).sin();
            }
            -(c * c + s * s)
        };
        let f0 = k as f64 * df;
        // A fine grid over the bin (the periodogram of the whole recording
        // has side lobes every 1/T), then golden section.
        let fine = 0.25 * m.fs / n as f64;
        let (mut fb, mut pb) = (f0, f64::INFINITY);
        let mut f = f0 - df;
        while f <= f0 + df {
            let p = power(f);
            if p < pb {
                (fb, pb) = (f, p);
            }
            f += fine;
        }
        let (f, _) = golden(power, fb - fine, fb + fine, 20);
        // Least-squares amplitude and phase.
        let w = 2.0 * PI * f / m.fs;
        let (mut cc, mut ss, mut cs, mut rc, mut rs) = (0.0, 0.0, 0.0, 0.0, 0.0);
        for (n, v) in r.iter().enumerate() {
            if !m.is_fit(n) {
                continue;
            }
            let (s, c) = (w * n as f64).sin_cos();
            cc += c * c;
            ss += s * s;
            cs += c * s;
            rc += v * c;
            rs += v * s;
        }
        let det = cc * ss - cs * cs;
        if det <= 0.0 {
            continue;
        }
        let a = (rc * ss - rs * cs) / det;
        let b = (rs * cc - rc * cs) / det;
        for (n, v) in r.iter_mut().enumerate() {
            if m.is_fit(n) {
                let p = w * n as f64;
                *v -= a * p.cos() + b * p.sin();
            }
        }
        lines.push(Line { freq_hz: f, a, b });
        uncertainty.push(f);
    }
    if lines.is_empty() {
        return None;
    }
    // Cramér-Rao bound on each frequency, σ² from what is left.
    let sigma2 = r.iter().map(|v| v * v).sum::<f64>() / nf as f64;
    let sd: Vec<Value> = lines
        .iter()
        .map(|l| {
            let amp2 = l.a * l.a + l.b * l.b;
            let n3 = (nf as f64).powi(3);
            json!({ "freq_hz": m.fs / (2.0 * PI) * (12.0 * sigma2 / (amp2 * n3)).sqrt() })
        })
        .collect();
    Some(Candidate {
        correction: Correction::Interference { lines },
        uncertainty: json!({ "lines": sd }),
    })
}

/// Transfer coefficients (thesis ch. 4.3.3): per STFT bin, the average of
/// the recovery's magnitude over time weighted by the reference's short-
/// time power, over the same average of the reference's magnitude; in dB
/// relative to the linear gain, smoothed over three bins; bins where the
/// reference has little energy are left out (coefficient 1, 0 dB). Also
/// the phase of the response: the angle of the cross-spectrum (recovery
/// times the conjugate reference, sign of the gain removed) summed over the
/// same frames, smoothed over three bins. The thesis' coefficients are
/// magnitudes; without the phase, a resonance leaves a lag that changes
/// with frequency, which other effects then try to explain.
fn transfer_coefficients(m: &Model, z: &[f64], fit: &Fit) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let nfft = stft_len(m.fs);
    let (fz, ft) = (stft(z, nfft), stft(&fit.t, nfft));
    let nb = nfft / 2 + 1;
    let (mut num, mut den, mut wsum) = (vec![0.0; nb], vec![0.0; nb], vec![0.0; nb]);
    let mut cross = vec![Complex::new(0.0, 0.0); nb];
    for (i, (a, b)) in fz.iter().zip(&ft).enumerate() {
        // Frames centred in the fit part.
        if !m.is_fit(i * nfft / 2 + nfft / 2) {
            continue;
        }
        for k in 0..nb {
            let px = b[k].norm_sqr();
            num[k] += a[k].norm() * px;
            den[k] += b[k].norm() * px;
            wsum[k] += px;
            cross[k] += a[k] * b[k].conj() * fit.g.signum();
        }
    }
    let wmax = wsum.iter().cloned().fold(0.0, f64::max);
    let lo = m.opts.highpass.map_or(0.0, |(_, c)| 1.5 * c);
    let g = fit.g.abs().max(1e-300);
    let valid: Vec<usize> = (1..nb)
        .filter(|&k| wsum[k] > 1e-3 * wmax && den[k] > 0.0 && k as f64 * m.fs / nfft as f64 >= lo)
        .collect();
    let raw: Vec<f64> = valid
        .iter()
        .map(|&k| 20.0 * (num[k] / den[k] / g).max(1e-12).log10())
        .collect();
    let smooth: Vec<f64> = (0..raw.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 2).min(raw.len()));
            raw[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect();
    let phase: Vec<f64> = (0..valid.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 2).min(valid.len()));
            let c: Complex<f64> = valid[a..b]
                .iter()
                .map(|&k| cross[k] / cross[k].norm().max(1e-300))
                .sum();
            c.arg().to_degrees()
        })
        .collect();
    let freqs = valid
        .iter()
        .map(|&k| k as f64 * m.fs / nfft as f64)
        .collect();
    (freqs, smooth, phase)
}

fn fit_transfer(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let (freqs, coef, phase) = transfer_coefficients(m, z, fit);
    if freqs.len() < 3 {
        return None;
    }
    let corr = |k: f64| Correction::Transfer {
        freqs_hz: freqs.clone(),
        coef_db: coef.clone(),
        phase_deg: phase.clone(),
        k,
    };
    let grid: Vec<(f64, f64)> = (0..=12)
        .map(|i| {
            let k = i as f64 * 0.25;
            (k, eq_sse(m, z, fit, &corr(k)))
        })
        .collect();
    let (bi, _) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    let (lo, hi) = (grid[bi].0 - 0.25, grid[bi].0 + 0.25);
    let (k, sse) = golden(|k| eq_sse(m, z, fit, &corr(k)), lo.max(0.0), hi, 16);
    let nf = m.nfit(z.len());
    let sd = curvature_sigma(|k| eq_sse(m, z, fit, &corr(k)), k, 0.02, sse / nf as f64);
    Some(Candidate {
        correction: corr(k),
        uncertainty: json!({ "k": sd }),
    })
}

/// The odd-order inverse of a saturation, by linear least squares on the
/// fit part: with `u` the recovery with its high-pass undone,
/// `T ≈ HP(b1 u + b3 u³ + b5 u⁵)`, so `a3 = b3 / b1`, `a5 = b5 / b1` (the
/// quintic term is dropped when it is negative or would make the inverse
/// fold back within the recovery's range). A polynomial rather than
/// `L atanh(u / L)`: the exact inverse amplifies the noise at the peaks by
/// `1 / (1 - (u / L)²)`, which at this effect's levels costs more than the harmonics it
/// removes; least squares picks the trade-off. `None` unless the inverse
/// expands (`a3 > 0`), as undoing a saturation must.
fn fit_soft_clip(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let hp = m.opts.highpass;
    let u = undo_highpass(z, m.fs, hp);
    let peak = u.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if peak.is_nan() || peak <= 0.0 {
        return None;
    }
    // Columns u, u³, u⁵ (scaled to the peak for conditioning), each
    // high-passed as the target is.
    let col = |k: i32| {
        redo_highpass(
            &u.iter().map(|v| (v / peak).powi(k)).collect::<Vec<_>>(),
            m.fs,
            hp,
        )
    };
    let (c1, c3, c5) = (col(1), col(3), col(5));
    let cols = |p: usize| -> Vec<[f64; 3]> {
        (0..u.len())
            .map(|i| [c1[i], c3[i], if p == 5 { c5[i] } else { 0.0 }])
            .collect()
    };
    let solve = |p: usize| -> Option<([f64; 3], [f64; 3], f64)> {
        let x = cols(p);
        let dim = if p == 5 { 3 } else { 2 };
        let mut a = [[0.0; 3]; 3];
        let mut rhs = [0.0; 3];
        for (i, row) in x.iter().enumerate() {
            if !m.is_fit(i) {
                continue;
            }
            for r in 0..dim {
                rhs[r] += row[r] * fit.t[i];
                for c in 0..dim {
                    a[r][c] += row[r] * row[c];
                }
            }
        }
        let inv = invert(&a, dim)?;
        let mut b = [0.0; 3];
        for r in 0..dim {
            b[r] = (0..dim).map(|c| inv[r][c] * rhs[c]).sum();
        }
        let sse: f64 = x
            .iter()
            .enumerate()
            .filter(|(i, _)| m.is_fit(*i))
            .map(|(i, row)| (fit.t[i] - (0..dim).map(|c| b[c] * row[c]).sum::<f64>()).powi(2))
            .sum();
        let sigma2 = sse / m.nfit(z.len()) as f64;
        let var = [inv[0][0] * sigma2, inv[1][1] * sigma2, inv[2][2] * sigma2];
        Some((b, var, sse))
    };
    // Monotonic on |u| <= 1: 1 + 3 a3 u² + 5 a5 u⁴ > 0.
    let monotonic = |a3: f64, a5: f64| {
        (0..=100).all(|i| {
            let w = (i as f64 / 100.0).powi(2);
            1.0 + 3.0 * a3 * w + 5.0 * a5 * w * w > 0.0
        })
    };
    let (b, var, _) = match solve(5) {
        // The inverse of a saturation expands: atanh's series has every
        // odd term positive; a negative quintic is something else.
        Some((b, v, e))
            if b[0] != 0.0 && b[2] / b[0] >= 0.0 && monotonic(b[1] / b[0], b[2] / b[0]) =>
        {
            (b, v, e)
        }
        _ => solve(3)?,
    };
    if b[0] == 0.0 {
        return None;
    }
    let (a3, a5) = (b[1] / b[0], b[2] / b[0]);
    if a3.is_nan() || a3 <= 0.0 {
        return None;
    }
    // The level itself by the forward model, which the recovery's noise
    // does not bias (the polynomial's trade-off with the noise does):
    // `z ≈ g HP(L tanh(r / L))` on the fit part, L on a geometric grid from
    // a quarter to four times the reference's peak, then golden section.
    let rpk = m.r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let zm = m.masked(z);
    let raw = m.unfiltered_target(z.len(), fit.tau);
    let sse = |l: f64| {
        let t = redo_highpass(
            &raw.iter().map(|v| l * (v / l).tanh()).collect::<Vec<_>>(),
            m.fs,
            hp,
        );
        gain_sse(&m.masked(&t), &zm).1
    };
    let level_at = |i: usize| 0.25 * rpk * 16f64.powf(i as f64 / 32.0);
    let grid: Vec<f64> = (0..=32).map(|i| sse(level_at(i))).collect();
    let (bi, _) = grid.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    let (level, best) = golden(
        sse,
        level_at(bi.saturating_sub(1)),
        level_at((bi + 1).min(32)),
        20,
    );
    let nf = m.nfit(z.len());
    let level_sd = curvature_sigma(sse, level, 0.01 * level, best / nf as f64);
    Some(Candidate {
        correction: Correction::SoftClip {
            a3: a3 / peak.powi(2),
            a5: a5 / peak.powi(4),
            level,
            highpass: hp,
        },
        uncertainty: json!({
            "a3": var[1].sqrt() / b[0].abs() / peak.powi(2),
            "a5": var[2].sqrt() / b[0].abs() / peak.powi(4),
            "level_in_reference_units": level_sd,
        }),
    })
}

/// `x` with the recovery's high-pass undone where it passes more than half
/// the amplitude (below that, the band is left out: it holds drift and
/// noise the inverse would lift).
fn undo_highpass(x: &[f64], fs: f64, hp: Option<(usize, f64)>) -> Vec<f64> {
    let Some(sos) = hp.and_then(|(o, c)| crate::iir::Sos::butterworth_highpass(o, c, fs).ok())
    else {
        return x.to_vec();
    };
    equalize(x, fs, |f| {
        let h = sos.response_at(f, fs);
        if h.norm() > 0.5 {
            h.inv()
        } else {
            Complex::new(0.0, 0.0)
        }
    })
}

/// `x` through the recovery's high-pass (the pipeline's IIR filter).
fn redo_highpass(x: &[f64], fs: f64, hp: Option<(usize, f64)>) -> Vec<f64> {
    match hp.and_then(|(o, c)| crate::iir::Sos::butterworth_highpass(o, c, fs).ok()) {
        Some(mut sos) => x.iter().map(|&v| sos.step(v)).collect(),
        None => x.to_vec(),
    }
}

/// Inverse of the leading `dim` x `dim` block of `a` (Gauss-Jordan with
/// partial pivoting); `None` when singular.
fn invert(a: &[[f64; 3]; 3], dim: usize) -> Option<[[f64; 3]; 3]> {
    let mut m = *a;
    let mut inv = [[0.0; 3]; 3];
    for (i, row) in inv.iter_mut().enumerate().take(dim) {
        row[i] = 1.0;
    }
    for c in 0..dim {
        let p = (c..dim).max_by(|&x, &y| m[x][c].abs().total_cmp(&m[y][c].abs()))?;
        if m[p][c].abs() < 1e-300 {
            return None;
        }
        m.swap(c, p);
        inv.swap(c, p);
        let d = m[c][c];
        for k in 0..dim {
            m[c][k] /= d;
            inv[c][k] /= d;
        }
        for r in 0..dim {
            if r != c {
                let f = m[r][c];
                for k in 0..dim {
                    m[r][k] -= f * m[c][k];
                    inv[r][k] -= f * inv[c][k];
                }
            }
        }
    }
    Some(inv)
}

// ---------------------------------------------------------------------------
// The residual no effect explains
// ---------------------------------------------------------------------------

/// Share of the residual's energy a structure must hold to be reported.
const NOTABLE: f64 = 0.05;

fn round_to(v: f64, step: f64) -> f64 {
    (v / step).round() * step
}

/// Describes what is left of `z / g - T`: energy at harmonics of the
/// reference, coherent energy where the reference has none (each reported
/// when it holds at least 5% of the residual's energy), a lag that changes
/// with frequency, a lag that changes over time.
fn unexplained(m: &Model, z: &[f64], fit: &Fit) -> Vec<Value> {
    let mut out = Vec::new();
    let g = if fit.g != 0.0 { fit.g } else { 1.0 };
    let zh: Vec<f64> = z.iter().map(|v| v / g).collect();
    let t = &fit.t;
    let res: Vec<f64> = zh.iter().zip(t).map(|(a, b)| a - b).collect();
    let nfft = stft_len(m.fs);
    let df = m.fs / nfft as f64;
    let (fr, ftg, fz) = (stft(&res, nfft), stft(t, nfft), stft(&zh, nfft));
    if fr.is_empty() {
        return out;
    }
    let nb = nfft / 2 + 1;
    let lo_bin = m
        .opts
        .highpass
        .map_or(1, |(_, c)| (1.5 * c / df).ceil() as usize);
    let signal: f64 = ftg
        .iter()
        .flat_map(|f| f.iter().map(|c| c.norm_sqr()))
        .sum::<f64>()
        .max(1e-300);

    let residual: f64 = fr
        .iter()
        .flat_map(|f| f.iter().map(|c| c.norm_sqr()))
        .sum::<f64>()
        .max(1e-300);
    // Per-bin noise floor of the residual: median over frames.
    let floor: Vec<f64> = (0..nb)
        .map(|k| {
            let mut v: Vec<f64> = fr.iter().map(|f| f[k].norm_sqr()).collect();
            median(&mut v)
        })
        .collect();
    let frame_e: Vec<f64> = ftg
        .iter()
        .map(|f| f.iter().map(|c| c.norm_sqr()).sum())
        .collect();
    let emax = frame_e.iter().cloned().fold(0.0, f64::max);
    // Excess cells: residual 10 dB over its floor where the target is 30 dB
    // below its own peak in that frame.
    let mut harm: Vec<(f64, Vec<f64>, Vec<f64>)> = (2..=5).map(|_| (0.0, vec![], vec![])).collect();
    let mut other = vec![0.0; nb];
    for (i, (a, b)) in fr.iter().zip(&ftg).enumerate() {
        if frame_e[i] < 1e-3 * emax {
            continue;
        }
        let (kref, pref) = b
            .iter()
            .enumerate()
            .map(|(k, c)| (k, c.norm_sqr()))
            .max_by(|x, y| x.1.total_cmp(&y.1))
            .unwrap_or((0, 0.0));
        // Dominant reference frequency (parabolic refinement).
        let fref = if kref > 0 && kref + 1 < nb {
            let (l, c, r) = (
                b[kref - 1].norm_sqr().max(1e-300).ln(),
                pref.max(1e-300).ln(),
                b[kref + 1].norm_sqr().max(1e-300).ln(),
            );
            let den = l - 2.0 * c + r;
            (kref as f64 + if den < 0.0 { 0.5 * (l - r) / den } else { 0.0 }) * df
        } else {
            kref as f64 * df
        };
        for k in lo_bin..nb {
            let p = a[k].norm_sqr();
            if b[k].norm_sqr() > 1e-3 * pref || p < 10.0 * floor[k] {
                continue;
            }
            let f = k as f64 * df;
            let excess = p - floor[k];
            match (2..=5).find(|&h| (alias(h as f64 * fref, m.fs) - f).abs() <= 1.5 * df) {
                Some(h) => {
                    let e = &mut harm[h - 2];
                    e.0 += excess;
                    e.1.push(fref);
                    e.2.push(f);
                }
                None => other[k] += excess,
            }
        }
    }
    for (i, (e, refs, fs_)) in harm.iter_mut().enumerate() {
        let h = i + 2;
        let level = 10.0 * (*e / signal).log10();
        if refs.len() < 3 || *e < NOTABLE * residual {
            continue;
        }
        let (rlo, rhi) = (
            refs.iter().cloned().fold(f64::INFINITY, f64::min),
            refs.iter().cloned().fold(0.0, f64::max),
        );
        let mut fl: Vec<f64> = fs_.iter().map(|f| round_to(*f, df)).collect();
        fl.sort_by(|a, b| a.total_cmp(b));
        fl.dedup();
        out.push(json!({
            "kind": "harmonics",
            "order": h,
            "level_db": level,
            "reference_hz": [rlo, rhi],
            "frequencies_hz": fl,
            "description": format!(
                "energy at {h}x the reference's frequency ({:.0}-{:.0} Hz played, heard at {}), {:.1} dB relative to the signal: a nonlinear response of the object or the loudspeaker (or clipping); lower the level, or model it",
                rlo, rhi,
                if h as f64 * rhi > m.fs / 2.0 { "its aliases below fs/2" } else { "those multiples" },
                level
            ),
        }));
    }
    // Coherent energy with no reference: bands of excess energy.
    let total_other: f64 = other.iter().sum();
    if total_other > NOTABLE * residual {
        let mut idx: Vec<usize> = (0..nb).filter(|&k| other[k] > 0.0).collect();
        idx.sort_by(|&a, &b| other[b].total_cmp(&other[a]));
        let mut picked: Vec<usize> = Vec::new();
        for k in idx {
            if picked.iter().all(|&p| p.abs_diff(k) > 2) {
                picked.push(k);
            }
            if picked.len() == 5 {
                break;
            }
        }
        let freqs: Vec<f64> = picked.iter().map(|&k| k as f64 * df).collect();
        out.push(json!({
            "kind": "coherent_without_reference",
            "level_db": 10.0 * (total_other / signal).log10(),
            "frequencies_hz": freqs,
            "description": format!(
                "energy 10 dB above the residual floor where the reference has none, strongest at {} Hz: vibration from another source (a machine, camera shake, a light's flicker) or aliases of content above fs/2",
                freqs.iter().map(|f| format!("{f:.0}")).collect::<Vec<_>>().join(", ")
            ),
        }));
    }
    // Lag against frequency: cross-spectral phase where coherent.
    let (mut sxy, mut sxx, mut syy) = (
        vec![Complex::new(0.0, 0.0); nb],
        vec![0.0; nb],
        vec![0.0; nb],
    );
    for (a, b) in fz.iter().zip(&ftg) {
        for k in 0..nb {
            sxy[k] += a[k] * b[k].conj();
            sxx[k] += b[k].norm_sqr();
            syy[k] += a[k].norm_sqr();
        }
    }
    let xmax = sxx.iter().cloned().fold(0.0, f64::max);
    let mut bad: Vec<(f64, f64)> = Vec::new();
    for k in lo_bin..nb.saturating_sub(1) {
        let coh = sxy[k].norm_sqr() / (sxx[k] * syy[k]).max(1e-300);
        if sxx[k] < 1e-3 * xmax || coh < 0.5 {
            continue;
        }
        let ph = sxy[k].arg().to_degrees();
        if ph.abs() > 20.0 {
            bad.push((k as f64 * df, ph));
        }
    }
    if bad.len() >= 2 {
        let worst = bad
            .iter()
            .cloned()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .unwrap_or((0.0, 0.0));
        let (flo, fhi) = (bad[0].0, bad[bad.len() - 1].0);
        out.push(json!({
            "kind": "lag_vs_frequency",
            "frequencies_hz": [flo, fhi],
            "max_phase_deg": worst.1,
            "at_hz": worst.0,
            "lag_samples_at": worst.1 / 360.0 * m.fs / worst.0.max(1e-9),
            "description": format!(
                "phase error beyond 20 degrees at {:.0}-{:.0} Hz (worst {:.0} deg at {:.0} Hz): the delay changes with frequency, as across a resonance; a magnitude equaliser does not undo it (a complex transfer function or a minimum-phase model would)",
                flo, fhi, worst.1, worst.0
            ),
        }));
    }
    // Lag over time.
    let pre = 512;
    let t_ext = m.target(z.len() + pre, pre, fit.tau, 0.0);
    let lags = local_lags(z, &t_ext, pre, fit.g, z.len(), m.fs);
    if lags.len() >= 3 {
        let lo = lags.iter().map(|l| l.1).fold(f64::INFINITY, f64::min);
        let hi = lags.iter().map(|l| l.1).fold(f64::NEG_INFINITY, f64::max);
        if hi - lo > 0.3 {
            let pts: Vec<(f64, f64)> = lags.iter().map(|&(c, l, _)| (c, l)).collect();
            let slope = theil_sen(&pts).map_or(0.0, |p| p.0);
            out.push(json!({
                "kind": "lag_over_time",
                "lag_range_samples": [lo, hi],
                "drift_ppm": slope * 1e6,
                "frequencies_hz": [],
                "description": format!(
                    "the delay moves by {:.2} samples over the recording (trend {:.0} ppm): a clock error, dropped frames or a changing path",
                    hi - lo, slope * 1e6
                ),
            }));
        }
    }
    out
}

// ---------------------------------------------------------------------------
// The loop
// ---------------------------------------------------------------------------

/// Calibrates the recovery `y` (at `fs`, the declared frame rate) against
/// the reference `r` (at `fr`): see the module docs.
pub fn calibrate(
    y: &[f64],
    fs: f64,
    r: &[f64],
    fr: f64,
    opts: &Options,
) -> Result<Calibration, CalError> {
    if !(fs.is_finite() && fs > 0.0 && fr.is_finite() && fr > 0.0) {
        return Err(CalError::Input(format!(
            "rates must be > 0 (recovery {fs} Hz, reference {fr} Hz)"
        )));
    }
    let min_len = 4 * stft_len(fs);
    if y.len() < min_len {
        return Err(CalError::Input(format!(
            "the recovery has {} samples; calibration needs at least {min_len} ({:.2} s)",
            y.len(),
            min_len as f64 / fs
        )));
    }
    if y.iter().chain(r).any(|v| !v.is_finite()) {
        return Err(CalError::Input("non-finite samples".into()));
    }
    let m = Model { r, fr, fs, opts };
    let fit0 = m.fit_linear(y);
    let before = m.errors(y, &fit0);
    let mut kept: Vec<Kept> = Vec::new();
    let mut rejected = Vec::new();
    // Greedy, best first: each round fits every effect not yet kept (in
    // catalog order) on the current corrected recovery and keeps the one
    // with the largest held-out gain, if it reaches `min_gain_db`.
    let mut left: Vec<EffectKind> = opts.effects.clone();
    let (mut z, mut fit, mut cur) = (y.to_vec(), fit0, before);
    loop {
        let mut round: Vec<Tried> = Vec::new();
        for &kind in &left {
            let Some(c) = fit_effect(kind, &m, &z, &fit) else {
                continue;
            };
            let z2 = c.correction.apply(&z, fs);
            let fit2 = m.fit_linear(&z2);
            let e2 = m.errors(&z2, &fit2);
            let gain = e2.snr_db - cur.snr_db;
            tracing::info!(effect = kind.name(), gain_db = gain, "candidate");
            round.push(Tried { kind, c, gain });
        }
        let best = round
            .iter()
            .enumerate()
            .filter(|(_, r)| r.gain.is_finite() && r.gain >= opts.min_gain_db)
            .max_by(|a, b| a.1.gain.total_cmp(&b.1.gain))
            .map(|(i, _)| i);
        let Some(bi) = best else {
            for t in round {
                rejected.push(Rejected {
                    name: t.kind.name(),
                    parameters: t.c.correction.parameters(fs, fit.g),
                    snr_gain_db: t.gain,
                });
            }
            break;
        };
        let mut t = round.swap_remove(bi);
        left.retain(|&k| k != t.kind);
        // Lines are subtracted first, from the recovery as delivered.
        if let Correction::Interference { lines } = &mut t.c.correction {
            let up = chain(&kept);
            for l in lines.iter_mut() {
                *l = Correction::line_before(*l, &up, fs);
            }
        }
        kept.push(Kept {
            c: t.c,
            gain: t.gain,
        });
        z = apply_all(&chain(&kept), y, fs);
        fit = m.fit_linear(&z);
        cur = m.errors(&z, &fit);
    }
    let corrections = chain(&kept);
    let effects = corrections
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let k = kept
                .iter()
                .find(|k| k.c.correction.kind() == c.kind())
                .expect("every correction comes from a kept effect");
            // With more than one kept: what the held-out SNR loses without
            // this one (the others as fitted).
            let gain = if corrections.len() > 1 {
                let mut others = corrections.clone();
                others.remove(i);
                let w = apply_all(&others, y, fs);
                cur.snr_db - m.errors(&w, &m.fit_linear(&w)).snr_db
            } else {
                k.gain
            };
            EffectReport {
                name: c.kind().name().to_string(),
                parameters: c.parameters(fs, fit.g),
                uncertainty: k.c.uncertainty.clone(),
                snr_gain_db: gain,
            }
        })
        .collect();
    let unexplained = unexplained(&m, &z, &fit);
    let g = if fit.g != 0.0 { fit.g } else { 1.0 };
    Ok(Calibration {
        report: Report {
            before,
            effects,
            after: cur,
            unexplained,
        },
        corrections,
        rejected,
        corrected: z.iter().map(|v| v / g).collect(),
        delay_s: fit.tau,
        gain: fit.g,
    })
}

fn fit_effect(kind: EffectKind, m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    match kind {
        EffectKind::TimeBase => fit_time_base(m, z, fit),
        EffectKind::Frames => fit_frames(m, z, fit),
        EffectKind::Exposure => fit_exposure(m, z, fit),
        EffectKind::Interference => fit_interference(m, z, fit),
        EffectKind::Transfer => fit_transfer(m, z, fit),
        EffectKind::SoftClip => fit_soft_clip(m, z, fit),
    }
}

/// An effect [`calibrate`] kept, with its held-out gain.
struct Kept {
    c: Candidate,
    gain: f64,
}

/// The kept corrections in the order they apply: interference lines first
/// (subtracted from the recovery as delivered), then the others in the
/// order they were kept.
fn chain(kept: &[Kept]) -> Vec<Correction> {
    let lines = kept
        .iter()
        .filter(|k| k.c.correction.kind() == EffectKind::Interference);
    let rest = kept
        .iter()
        .filter(|k| k.c.correction.kind() != EffectKind::Interference);
    lines.chain(rest).map(|k| k.c.correction.clone()).collect()
}

/// One effect fitted in a round of [`calibrate`].
struct Tried {
    kind: EffectKind,
    c: Candidate,
    gain: f64,
}

/// Applies `corrections` in order to a recovery at `fs`.
pub fn apply_all(corrections: &[Correction], y: &[f64], fs: f64) -> Vec<f64> {
    let mut z = y.to_vec();
    for c in corrections {
        z = c.apply(&z, fs);
    }
    z
}

/// The reusable corrections stored in a report (`effects` of `REPORT.json`).
pub fn reusable_from_report(report: &Value) -> Result<Vec<Correction>, String> {
    let effects = report
        .get("effects")
        .and_then(Value::as_array)
        .ok_or("no `effects` list")?;
    let mut out = Vec::new();
    for (i, e) in effects.iter().enumerate() {
        let name = e
            .get("name")
            .and_then(Value::as_str)
            .ok_or_else(|| format!("effects[{i}]: no `name`"))?;
        let p = e
            .get("parameters")
            .ok_or_else(|| format!("effects[{i}] ({name}): no `parameters`"))?;
        if let Some(c) = Correction::from_json(name, p).map_err(|m| format!("effects[{i}]: {m}"))? {
            out.push(c);
        }
    }
    Ok(out)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    fn chirp(fr: f64, secs: f64, f0: f64, f1: f64) -> Vec<f64> {
        let n = (fr * secs) as usize;
        (0..n)
            .map(|i| {
                let t = i as f64 / fr;
                (2.0 * PI * (f0 * t + (f1 - f0) * t * t / (2.0 * secs))).sin()
            })
            .collect()
    }

    #[test]
    fn sample_at_is_exact_on_samples_and_interpolates_a_tone() {
        let fr = 8000.0;
        let x: Vec<f64> = (0..800)
            .map(|i| (2.0 * PI * 440.0 * i as f64 / fr).sin())
            .collect();
        let on = sample_at(&x, fr, (0..800).map(|i| i as f64 / fr));
        assert_eq!(on, x);
        let mid = sample_at(&x, fr, (100..700).map(|i| (i as f64 + 0.37) / fr));
        for (k, v) in mid.iter().enumerate() {
            let t = (k as f64 + 100.37) / fr;
            assert!((v - (2.0 * PI * 440.0 * t).sin()).abs() < 1e-4, "{k}: {v}");
        }
    }

    #[test]
    fn equalize_with_unit_gain_reconstructs() {
        let x = chirp(2200.0, 1.0, 100.0, 900.0);
        let y = equalize(&x, 2200.0, |_| Complex::new(1.0, 0.0));
        let err: f64 = x
            .iter()
            .zip(&y)
            .map(|(a, b)| (a - b).abs())
            .fold(0.0, f64::max);
        assert!(err < 1e-9, "{err}");
        // A gain of 2 doubles.
        let y = equalize(&x, 2200.0, |_| Complex::new(2.0, 0.0));
        assert!((y[1000] - 2.0 * x[1000]).abs() < 1e-9);
    }

    #[test]
    fn alias_folds() {
        assert_eq!(alias(1500.0, 2200.0), 700.0);
        assert_eq!(alias(300.0, 2200.0), 300.0);
        assert_eq!(alias(2500.0, 2200.0), 300.0);
    }

    fn opts() -> Options {
        Options::for_rate(2200.0)
    }

    /// `0.3 x` plus deterministic white noise of std 0.003 (about 30 dB SNR).
    fn noisy(x: &[f64], seed: u64) -> Vec<f64> {
        let mut s = seed
            .wrapping_mul(6364136223846793005)
            .wrapping_add(1442695040888963407);
        x.iter()
            .map(|v| {
                let mut u = 0.0;
                for _ in 0..12 {
                    s = s
                        .wrapping_mul(6364136223846793005)
                        .wrapping_add(1442695040888963407);
                    u += (s >> 11) as f64 / (1u64 << 53) as f64;
                }
                0.3 * v + 0.003 * (u - 6.0)
            })
            .collect()
    }

    /// A recovery made from the reference by a known time warp: the model
    /// finds the clock error, and plain data gets no effect.
    #[test]
    fn time_base_on_a_pure_signal() {
        let fr = 8000.0;
        let r = chirp(fr, 2.0, 100.0, 1000.0);
        let fs = 2200.0;
        let e = 3000e-6;
        let m = Model {
            r: &r,
            fr,
            fs,
            opts: &opts(),
        };
        // Captured at the true rate fs (1 + e), high-passed, scaled.
        let y = noisy(&m.target(4000, 0, 0.0, e * 1e6), 1);
        let cal = calibrate(&y, fs, &r, fr, &opts()).unwrap();
        let names: Vec<&str> = cal.report.effects.iter().map(|e| e.name.as_str()).collect();
        assert_eq!(names, ["time_base"], "{:?}", cal.report);
        let ppm = cal.report.effects[0].parameters["clock_error_ppm"]
            .as_f64()
            .unwrap();
        assert!((ppm - 3000.0).abs() < 50.0, "{ppm}");
        assert!(cal.report.after.snr_db > cal.report.before.snr_db + 10.0);
        // No warp: nothing to claim.
        let y = noisy(&m.target(4000, 0, 0.0, 0.0), 2);
        let cal = calibrate(&y, fs, &r, fr, &opts()).unwrap();
        assert!(cal.report.effects.is_empty(), "{:?}", cal.report.effects);
    }

    #[test]
    fn frame_events_are_found_and_undone() {
        let fr = 8000.0;
        let r = chirp(fr, 2.0, 100.0, 1000.0);
        let fs = 2200.0;
        let o = Options {
            effects: vec![EffectKind::Frames],
            ..opts()
        };
        let m = Model {
            r: &r,
            fr,
            fs,
            opts: &o,
        };
        let clean = noisy(&m.target(4000, 0, 0.0, 0.0), 3);
        // Drop capture 1500, repeat capture 3000.
        let mut y: Vec<f64> = clean
            .iter()
            .enumerate()
            .filter(|(i, _)| *i != 1500)
            .map(|(_, v)| *v)
            .collect();
        y.insert(2999, y[2998]);
        let cal = calibrate(&y, fs, &r, fr, &o).unwrap();
        assert_eq!(cal.report.effects.len(), 1, "{:?}", cal.report);
        let ev = &cal.report.effects[0].parameters["events"];
        let ev = ev.as_array().unwrap();
        assert_eq!(ev.len(), 2, "{ev:?}");
        assert!(
            (ev[0]["frame"].as_i64().unwrap() - 1500).abs() <= 2,
            "{ev:?}"
        );
        assert_eq!(ev[0]["kind"], "dropped");
        assert!(
            (ev[1]["frame"].as_i64().unwrap() - 2999).abs() <= 2,
            "{ev:?}"
        );
        assert_eq!(ev[1]["kind"], "duplicated");
    }

    #[test]
    fn report_round_trips_the_reusable_corrections() {
        let c = [
            Correction::TimeBase { ppm: 120.0 },
            Correction::Exposure { exposure_s: 2e-4 },
            Correction::Transfer {
                freqs_hz: vec![100.0, 200.0],
                coef_db: vec![3.0, -2.0],
                phase_deg: vec![10.0, -20.0],
                k: 1.2,
            },
        ];
        let effects: Vec<Value> = c
            .iter()
            .map(|c| json!({"name": c.kind().name(), "parameters": c.parameters(2200.0, 1.0)}))
            .collect();
        let back = reusable_from_report(&json!({ "effects": effects })).unwrap();
        assert_eq!(back.len(), 3);
        assert_eq!(back[0], c[0]);
        assert_eq!(back[2], c[2]);
        match back[1] {
            Correction::Exposure { exposure_s } => assert!((exposure_s - 2e-4).abs() < 1e-12),
            _ => panic!("{back:?}"),
        }
        assert!(
            reusable_from_report(&json!({"effects": [{"name": "nope", "parameters": {}}]}))
                .is_err()
        );
    }
}
