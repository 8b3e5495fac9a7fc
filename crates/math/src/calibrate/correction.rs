//! The corrections calibrate fits, one variant per effect of the catalog,
//! and how each applies to a recovery (its parameters as reported are in
//! [`super::report`]).

use super::signal::{equalize, redo_highpass, sample_at, undo_highpass};
use super::EffectKind;
use realfft::num_complex::Complex;
use std::f64::consts::PI;

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
    /// Subtract a line at each of `freqs_hz` (Hz, in the recovery as
    /// delivered), its amplitude and phase fitted by least squares on the
    /// recovery it is applied to: a line found on one recording (a
    /// machine, the mains) recurs on the next at the same frequency with
    /// its own level and phase. What a stored `interference` becomes on a
    /// new recording (`listen --calibration`); applied first.
    Lines { freqs_hz: Vec<f64> },
    /// Equalise by `coefficient^-k` (coefficients in dB at frequencies;
    /// the end values held beyond the table), at most ±30 dB, and undo the phase of the
    /// response (degrees at the same frequencies).
    Transfer {
        freqs_hz: Vec<f64>,
        coef_db: Vec<f64>,
        phase_deg: Vec<f64>,
        k: f64,
        /// The band (Hz) the table's rows were measured over. Rows
        /// outside it are not measurements: above the sweep's band the
        /// table returns to its median gain (see `transfer::curve`).
        /// Applying the table does not read it; what reports the band
        /// does (`listen --calibration`'s note on a recording's power
        /// outside it).
        measured_hz: [f64; 2],
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
        /// The recovery's peak when it was fitted: the nonlinear terms are
        /// held at ±`range` beyond it.
        range: f64,
        highpass: Option<(usize, f64)>,
    },
    /// Undo a static nonlinear response: `u + a2 u² + a3 u³ + …`
    /// (`coefs = [a2, a3, …]`, recovery units) on `u`, the recovery with
    /// its high-pass undone, then high-passed again (as for soft
    /// clipping). The terms are held at ±`range` (the recovery's peak when
    /// it was fitted) beyond it. `from_response`: derived from the
    /// object's fitted response over the amplitudes speech spends its time
    /// at (since session 62), not fitted on the calibration's own
    /// amplitudes (the report's `"fitted": "response"`).
    Polynomial {
        coefs: Vec<f64>,
        range: f64,
        highpass: Option<(usize, f64)>,
        from_response: bool,
    },
    /// Divide by the gain's trend over the recording: Legendre
    /// coefficients (relative to the mean) over `samples` samples; the
    /// trend's change from start to end, dB (reported).
    GainDrift {
        coefs: Vec<f64>,
        samples: usize,
        start_to_end_db: f64,
    },
    /// Sum strips of rows (first and end row each), strip `k` advanced by
    /// `delays_s[k]` and weighted by `weights[k]` ([`super::combine`]):
    /// it acts on the strips' recoveries, before every other correction,
    /// so on one recovery it does nothing. `line_delay_s` is the fitted
    /// time per row (reported); `per_region` says the delays are each
    /// strip's own rather than in proportion to the row.
    CaptureTime {
        rows: Vec<(u32, u32)>,
        delays_s: Vec<f64>,
        weights: Vec<f64>,
        line_delay_s: f64,
        per_region: bool,
    },
    /// Sum strips of rows (first and end row each) at one time, weighted
    /// by the magnitudes of `weights` with each strip's sign taken from
    /// the recording ([`super::combine`]): parts that move in antiphase add
    /// instead of cancelling. It acts on the strips' recoveries, so on one
    /// recovery it does nothing. The signs of `weights` are those fitted
    /// (reported: negative strips moved against the strongest).
    RegionGain {
        rows: Vec<(u32, u32)>,
        weights: Vec<f64>,
    },
}

/// Most boost the exposure inverse applies (the `exposure` stage's -12 dB floor).
pub(super) const EXPOSURE_MAX_GAIN: f64 = 4.0;
/// Most boost or cut the transfer equaliser applies, dB.
pub(super) const TRANSFER_MAX_DB: f64 = 30.0;
/// A transfer table measured to within this fraction of the Nyquist
/// frequency covers the band ([`Correction::unmeasured`]): the last few
/// bins hold the reference's window edge, not a band left out.
pub const UNMEASURED_EDGE: f64 = 0.05;

impl Correction {
    pub fn kind(&self) -> EffectKind {
        match self {
            Correction::TimeBase { .. } => EffectKind::TimeBase,
            Correction::Frames { .. } => EffectKind::Frames,
            Correction::Exposure { .. } => EffectKind::Exposure,
            Correction::Interference { .. } | Correction::Lines { .. } => EffectKind::Interference,
            Correction::Transfer { .. } => EffectKind::Transfer,
            Correction::SoftClip { .. } => EffectKind::SoftClip,
            Correction::Polynomial { .. } => EffectKind::Polynomial,
            Correction::GainDrift { .. } => EffectKind::GainDrift,
            Correction::CaptureTime { .. } => EffectKind::CaptureTime,
            Correction::RegionGain { .. } => EffectKind::RegionGain,
        }
    }

    /// A property of object and camera (worth reusing on a new recording),
    /// rather than of one recording.
    pub fn reusable(&self) -> bool {
        matches!(
            self,
            Correction::TimeBase { .. }
                | Correction::Exposure { .. }
                | Correction::Transfer { .. }
                | Correction::Polynomial { .. }
                | Correction::Lines { .. }
                | Correction::CaptureTime { .. }
                | Correction::RegionGain { .. }
        )
    }

    /// What the correction cannot undo on a recording at `fs` frames a
    /// second, in words (`None`: nothing known to stay). The exposure's
    /// boxcar filters the object's motion before the frame rate samples
    /// it: its inverse restores the band below the Nyquist frequency, but
    /// what lay above it arrives folded onto the band at the gain the
    /// boxcar gave it at its own frequency, beside the band's own content
    /// at another; no filter at the frame rate tells the two apart.
    pub fn cannot_correct(&self, fs: f64) -> Option<String> {
        let Correction::Exposure { exposure_s: e } = *self else {
            return None;
        };
        if !(e > 0.0 && fs > 0.0) {
            return None;
        }
        let nyq = fs / 2.0;
        let gain = |f: f64| crate::exposure::boxcar_gain(f, e);
        Some(format!(
            "the exposure ({:.0} µs, {:.2} of the frame period) is undone only below the frame rate's Nyquist frequency ({nyq:.0} Hz): what the object did above it was filtered by the exposure (x{:.2} at {:.0} Hz, x{:.2} at {:.0} Hz, nothing at {:.0} Hz) before the frame rate folded it onto the band, where it lies beside the band's own content at another gain; no correction at the frame rate tells the two apart, so that part of the error stays (none where the motion holds nothing above {nyq:.0} Hz)",
            e * 1e6,
            e * fs,
            gain(1.5 * nyq),
            1.5 * nyq,
            gain(fs),
            fs,
            1.0 / e,
        ))
    }

    /// The band a transfer table was measured over, where it stops more
    /// than [`UNMEASURED_EDGE`] short of the Nyquist frequency of `fs`
    /// (`None` otherwise, and for any other correction): the condition
    /// [`Correction::unmeasured`] and [`Correction::outside_measured`]
    /// both speak on.
    fn unmeasured_band(&self, fs: f64) -> Option<[f64; 2]> {
        match *self {
            Correction::Transfer {
                measured_hz: [lo, hi],
                ..
            } if hi > 0.0 && hi < (1.0 - UNMEASURED_EDGE) * fs / 2.0 => Some([lo, hi]),
            _ => None,
        }
    }

    /// Where a transfer table was not measured, in words (`None` for
    /// any other correction, or a table measured to within
    /// [`UNMEASURED_EDGE`] of the Nyquist frequency of `fs`): above the
    /// highest frequency its reference reached, the table is not a
    /// measurement, and a later recording's content there is left as
    /// recorded.
    pub fn unmeasured(&self, fs: f64) -> Option<String> {
        let [lo, hi] = self.unmeasured_band(fs)?;
        let nyq = fs / 2.0;
        Some(format!(
            "transfer_function measured the object's response at {lo:.0}-{hi:.0} Hz, where the reference had power; from {hi:.0} Hz to the frame rate's Nyquist frequency ({nyq:.0} Hz) nothing was measured (the table holds its last row to the highest frequency the reference reached, then returns to its median gain; below {lo:.0} Hz it holds its first row), so a resonance or dip of the object there is not corrected on a later recording with content there (speech has some: `listen --calibration` says how much); a reference that sweeps to {nyq:.0} Hz would measure it"
        ))
    }

    /// How much of a new recording `z` (at `fs`) lies outside the band a
    /// transfer table was measured over, in words, where that band stops
    /// short of the Nyquist frequency as in [`Correction::unmeasured`]
    /// (`None` otherwise, and for any other correction). Of the recovery
    /// before any correction, noise included. Said whatever the share: a
    /// dip of the object there lowers the share itself (issue 50, session
    /// 68: on the protocol's `dip_above_sweep`, a -8 dB dip at 1000 Hz
    /// above a table measured to 851 Hz, the speech's recovery holds 0.9%
    /// of its power above 851 Hz, the same speech without the dip 2.7%),
    /// so no threshold on it tells a user whether the object hid
    /// something there.
    pub fn outside_measured(&self, z: &[f64], fs: f64) -> Option<String> {
        let [lo, hi] = self.unmeasured_band(fs)?;
        let n = z.len();
        if n < 16 {
            return None;
        }
        let mean = z.iter().sum::<f64>() / n as f64;
        let mut x: Vec<f64> = z.iter().map(|v| v - mean).collect();
        let mut spec = vec![Complex::new(0.0, 0.0); n / 2 + 1];
        let fft = realfft::RealFftPlanner::<f64>::new().plan_fft_forward(n);
        fft.process(&mut x, &mut spec).ok()?;
        let (mut below, mut above, mut all) = (0.0, 0.0, 0.0);
        for (k, c) in spec.iter().enumerate().skip(1) {
            let (f, p) = (k as f64 * fs / n as f64, c.norm_sqr());
            all += p;
            if f < lo {
                below += p;
            } else if f > hi {
                above += p;
            }
        }
        if all.is_nan() || all <= 0.0 {
            return None;
        }
        let pct = |p: f64| match p / all {
            s if s < 1e-3 => "under 0.1%".to_string(),
            s => format!("{:.1}% ({:.1} dB)", 100.0 * s, 10.0 * s.log10()),
        };
        Some(format!(
            "this recording holds {} of its power above {hi:.0} Hz and {} below {lo:.0} Hz (its recovery before the calibration, noise included), outside the band where the calibration's reference measured the object's response ({lo:.0}-{hi:.0} Hz): the transfer table there is not a measurement (above, its last row held to the reference's reach, then its median gain; below, its first row held), so a resonance or dip of the object there is not corrected, and that part of the error stays (a dip there also makes the share above look smaller than the sound's); a reference that sweeps to {:.0} Hz would measure it",
            pct(above),
            pct(below),
            fs / 2.0
        ))
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
            // The odd polynomial `u + a3 u³ + a5 u⁵`, held at ±range as a
            // polynomial's terms are.
            Correction::SoftClip {
                a3,
                a5,
                range,
                highpass,
                ..
            } => apply_polynomial(z, fs, &[0.0, *a3, 0.0, *a5], *range, *highpass),
            Correction::Polynomial {
                coefs,
                range,
                highpass,
                ..
            } => apply_polynomial(z, fs, coefs, *range, *highpass),
            Correction::GainDrift { coefs, samples, .. } => apply_gain_drift(z, coefs, *samples),
            // Applied to the strips (`super::combine`), not here.
            Correction::CaptureTime { .. } | Correction::RegionGain { .. } => z.to_vec(),
            Correction::Exposure { .. } | Correction::Transfer { .. } => equalize(z, fs, |f| {
                self.response(f).unwrap_or(Complex::new(1.0, 0.0))
            }),
            Correction::Interference { lines } => {
                let mut out = z.to_vec();
                for l in lines {
                    subtract_line(&mut out, 2.0 * PI * l.freq_hz / fs, (l.a, l.b));
                }
                out
            }
            Correction::Lines { freqs_hz } => {
                let mut out = z.to_vec();
                for &f in freqs_hz {
                    let w = 2.0 * PI * f / fs;
                    if !(w > 0.0 && w < PI) {
                        continue;
                    }
                    if let Some(ab) =
                        crate::numeric::fit_cos_sin(out.iter().copied().enumerate(), w)
                    {
                        subtract_line(&mut out, w, ab);
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
                ..
            } => {
                let c = interp_held(freqs_hz, coef_db, f);
                let ph = interp_held(freqs_hz, phase_deg, f).to_radians();
                Some(Complex::from_polar(transfer_gain(*k, c), -ph))
            }
            _ => None,
        }
    }

    /// A line seen after the corrections `upstream` (applied in order) as
    /// it is in the recovery before them: a time-base correction scales
    /// frequencies by its rate ratio, a filter scales the line's phasor
    /// `a - ib` by its gain; frame events are ignored (the phase jump
    /// they cause is lost).
    pub(super) fn line_before(line: Line, upstream: &[Correction], fs: f64) -> Line {
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
}

/// The transfer equaliser's gain where its table reads `coef_db` (dB):
/// `coefficient^-k`, at most [`TRANSFER_MAX_DB`] either way.
pub(super) fn transfer_gain(k: f64, coef_db: f64) -> f64 {
    10f64.powf((-k * coef_db).clamp(-TRANSFER_MAX_DB, TRANSFER_MAX_DB) / 20.0)
}

/// `x[n] -= a cos(w n) + b sin(w n)`: a line (`w` radians per sample)
/// taken out of a recovery.
fn subtract_line(x: &mut [f64], w: f64, (a, b): (f64, f64)) {
    for (n, v) in x.iter_mut().enumerate() {
        let p = w * n as f64;
        *v -= a * p.cos() + b * p.sin();
    }
}

/// Linear interpolation in a table, holding its end values outside it.
pub(super) fn interp_held(xs: &[f64], ys: &[f64], x: f64) -> f64 {
    match (xs.first(), xs.last()) {
        (Some(&a), _) if x <= a => ys[0],
        (_, Some(&b)) if x >= b => ys[ys.len() - 1],
        _ => interp_table(xs, ys, x),
    }
}

/// Linear interpolation in a table; 0 outside it.
pub(super) fn interp_table(xs: &[f64], ys: &[f64], x: f64) -> f64 {
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

/// Frame events undone: lost captures filled by AR interpolation, repeated
/// ones merged.
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

// The static polynomial (family g) and the gain drift (family h), as
// applied: here, beside the correction that names them, so the families
// that fit them depend on the correction and not the other way round.

/// The trend may not fall below this fraction of its mean anywhere (a
/// correction would lift the noise by more than 20 dB).
pub(super) const MIN_RELATIVE_GAIN: f64 = 0.1;

/// Applies `u + Σ ak u^k` to `u`, the recovery with its high-pass undone,
/// and high-passes again. Outside the range the calibration saw, the
/// polynomial's terms are held at the range's edge (a fitted polynomial
/// must not extrapolate).
pub(super) fn apply_polynomial(
    z: &[f64],
    fs: f64,
    coefs: &[f64],
    range: f64,
    hp: Option<(usize, f64)>,
) -> Vec<f64> {
    let u = undo_highpass(z, fs, hp);
    let p: Vec<f64> = u
        .iter()
        .map(|&v| {
            let x = v.clamp(-range, range);
            let mut acc = 0.0;
            for c in coefs.iter().rev() {
                acc = acc * x + c;
            }
            v + acc * x * x
        })
        .collect();
    redo_highpass(&p, fs, hp)
}

/// Legendre polynomials P0..=order at `x` in [-1, 1].
pub(super) fn legendre(x: f64, order: usize) -> Vec<f64> {
    let mut p = vec![1.0, x];
    for k in 2..=order {
        let kf = k as f64;
        let next = ((2.0 * kf - 1.0) * x * p[k - 1] - (kf - 1.0) * p[k - 2]) / kf;
        p.push(next);
    }
    p.truncate(order + 1);
    p
}

/// The trend's value at sample `i` of `n`.
pub(super) fn envelope(coefs: &[f64], i: f64, n: usize) -> f64 {
    let x = (2.0 * i / n.max(1) as f64 - 1.0).clamp(-1.0, 1.0);
    legendre(x, coefs.len() - 1)
        .iter()
        .zip(coefs)
        .map(|(p, c)| p * c)
        .sum()
}

/// Divides `z` by the trend (sample `i` at its place among the fitted
/// recording's `samples`).
pub(super) fn apply_gain_drift(z: &[f64], coefs: &[f64], samples: usize) -> Vec<f64> {
    z.iter()
        .enumerate()
        .map(|(i, v)| v / envelope(coefs, i as f64, samples).max(MIN_RELATIVE_GAIN))
        .collect()
}
