//! The excitation: a unit-peak waveform of continuous time that drives the
//! object's displacement.

use super::detmath::sin_turns;
use super::SimError;
use std::path::{Path, PathBuf};
use std::sync::Arc;

/// What the object's motion follows (the `signal` table of a pipeline).
#[derive(Clone, Debug, serde::Deserialize, PartialEq)]
#[serde(tag = "type", rename_all = "snake_case", deny_unknown_fields)]
pub enum SignalSpec {
    /// `sin(2π f t + phase)`.
    Tone {
        freq_hz: f64,
        #[serde(default)]
        phase_rad: f64,
    },
    /// `Σ w_i sin(2π f_i t) / Σ |w_i|` (peak <= 1); weights default to 1.
    Tones {
        freqs_hz: Vec<f64>,
        #[serde(default)]
        weights: Vec<f64>,
    },
    /// Linear sweep from `f0_hz` to `f1_hz` over `duration_s`, then repeats
    /// (the phase restarts at zero each period).
    Chirp {
        f0_hz: f64,
        f1_hz: f64,
        duration_s: f64,
    },
    /// A WAV file: first channel, normalised to peak 1, linear
    /// interpolation between samples, zero before 0 and after its end.
    Wav { path: PathBuf },
    /// White noise sampled at `rate_hz` for `duration_s` (zero after), each
    /// sample the mean of four uniform draws in [-1, 1] (peak 1, nearly
    /// Gaussian), linear interpolation between samples, deterministic from
    /// `seed`. Through `resonances` it drives each like an ambient force.
    Noise {
        rate_hz: f64,
        duration_s: f64,
        #[serde(default = "default_noise_seed")]
        seed: u64,
    },
}

fn default_noise_seed() -> u64 {
    1
}

/// The most noise samples a scene may ask for.
const MAX_NOISE_SAMPLES: f64 = 2e8;

/// [`SignalSpec::Noise`]'s samples: splitmix64 draws, four per sample.
fn noise_samples(rate_hz: f64, duration_s: f64, seed: u64) -> Arc<[f32]> {
    let n = (rate_hz * duration_s).ceil() as usize + 1;
    let mut state = seed;
    let mut next = || {
        state = state.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = state;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        z ^= z >> 31;
        (z >> 11) as f64 / (1u64 << 53) as f64 * 2.0 - 1.0
    };
    (0..n)
        .map(|_| ((next() + next() + next() + next()) / 4.0) as f32)
        .collect()
}

#[derive(Clone, Debug)]
enum Kind {
    Tone { freq: f64, phase_turns: f64 },
    Tones { freqs: Vec<f64>, weights: Vec<f64> },
    Chirp { f0: f64, f1: f64, period: f64 },
    Wav { rate: f64, samples: Arc<[f32]> },
}

/// A validated, ready-to-evaluate [`SignalSpec`]. Cheap to clone (a WAV's
/// samples are shared).
#[derive(Clone, Debug)]
pub struct Signal {
    spec: SignalSpec,
    kind: Kind,
    /// Tones added after everything else (interference), `(Hz, weight)`.
    extra: Vec<(f64, f64)>,
    /// Soft clipping level (signal units): `c tanh(x / c)` before the extra tones.
    clip: Option<f64>,
    /// A static polynomial response, coefficients of x², x³, … (signal
    /// units): `x + c2 x² + c3 x³ + …`, before the clipping.
    poly: Vec<f64>,
    /// The excitation decays as `exp(-t / decay_s)` (a struck object),
    /// before the extra tones.
    decay_s: Option<f64>,
    /// Factor on the waveform's peak in [`Signal::peak_bound`]: the
    /// resonances' steady-state gain after [`Signal::through_checked`], 1
    /// otherwise.
    gain_bound: f64,
}

/// One resonance of an object's transfer function: a peaking section
/// (RBJ audio-EQ biquad) of `gain_db` at `freq_hz` with quality `q`.
/// Sections apply in series; `gain_db = 0` is flat.
#[derive(serde::Deserialize, Clone, Debug, PartialEq)]
#[serde(deny_unknown_fields)]
pub struct Resonance {
    pub freq_hz: f64,
    pub q: f64,
    pub gain_db: f64,
    /// The section acts from this time on (s); before, it is flat.
    #[serde(default)]
    pub from_s: Option<f64>,
    /// The section acts until this time (s); after, it is flat (its state
    /// cleared): with another section `from_s` the same time, a resonance
    /// that moves mid-run (a glass being filled).
    #[serde(default)]
    pub until_s: Option<f64>,
}

impl Resonance {
    /// A section that acts for the whole run.
    pub fn new(freq_hz: f64, q: f64, gain_db: f64) -> Resonance {
        Resonance {
            freq_hz,
            q,
            gain_db,
            from_s: None,
            until_s: None,
        }
    }

    fn active(&self, t_s: f64) -> bool {
        self.from_s.is_none_or(|a| t_s >= a) && self.until_s.is_none_or(|b| t_s < b)
    }
}

fn invalid(field: impl Into<String>, msg: impl Into<String>) -> SimError {
    SimError::Invalid {
        field: field.into(),
        msg: msg.into(),
    }
}

fn positive_freq(field: String, v: f64) -> Result<f64, SimError> {
    if v.is_finite() && v > 0.0 {
        Ok(v)
    } else {
        Err(invalid(
            field,
            format!("must be a finite frequency > 0 Hz, got {v}"),
        ))
    }
}

impl Signal {
    /// Validates `spec` (and loads a WAV file once).
    pub fn new(spec: &SignalSpec) -> Result<Signal, SimError> {
        let kind = match spec {
            SignalSpec::Tone { freq_hz, phase_rad } => {
                let freq = positive_freq("freq_hz".into(), *freq_hz)?;
                if !phase_rad.is_finite() {
                    return Err(invalid(
                        "phase_rad",
                        format!("must be finite, got {phase_rad}"),
                    ));
                }
                Kind::Tone {
                    freq,
                    phase_turns: phase_rad / std::f64::consts::TAU,
                }
            }
            SignalSpec::Tones { freqs_hz, weights } => {
                if freqs_hz.is_empty() {
                    return Err(invalid("freqs_hz", "must list at least one frequency"));
                }
                let freqs = freqs_hz
                    .iter()
                    .enumerate()
                    .map(|(i, &f)| positive_freq(format!("freqs_hz[{i}]"), f))
                    .collect::<Result<Vec<_>, _>>()?;
                let weights = if weights.is_empty() {
                    vec![1.0; freqs.len()]
                } else if weights.len() != freqs.len() {
                    return Err(invalid(
                        "weights",
                        format!(
                            "has {} entries but freqs_hz has {} (give one weight per frequency, or none)",
                            weights.len(),
                            freqs.len()
                        ),
                    ));
                } else {
                    for (i, w) in weights.iter().enumerate() {
                        if !w.is_finite() {
                            return Err(invalid(
                                format!("weights[{i}]"),
                                format!("must be finite, got {w}"),
                            ));
                        }
                    }
                    weights.clone()
                };
                let norm: f64 = weights.iter().map(|w| w.abs()).sum();
                if norm <= 0.0 || !norm.is_finite() {
                    return Err(invalid("weights", "must not all be zero"));
                }
                Kind::Tones {
                    freqs,
                    weights: weights.iter().map(|w| w / norm).collect(),
                }
            }
            SignalSpec::Chirp {
                f0_hz,
                f1_hz,
                duration_s,
            } => {
                for (name, v) in [("f0_hz", f0_hz), ("f1_hz", f1_hz)] {
                    if !(v.is_finite() && *v >= 0.0) {
                        return Err(invalid(
                            name,
                            format!("must be a finite frequency >= 0 Hz, got {v}"),
                        ));
                    }
                }
                if *f0_hz == 0.0 && *f1_hz == 0.0 {
                    return Err(invalid("f1_hz", "f0_hz and f1_hz cannot both be 0"));
                }
                if !(duration_s.is_finite() && *duration_s > 0.0) {
                    return Err(invalid(
                        "duration_s",
                        format!("must be > 0 seconds, got {duration_s}"),
                    ));
                }
                Kind::Chirp {
                    f0: *f0_hz,
                    f1: *f1_hz,
                    period: *duration_s,
                }
            }
            SignalSpec::Wav { path } => load_wav(path)?,
            SignalSpec::Noise {
                rate_hz,
                duration_s,
                seed,
            } => {
                let n = rate_hz * duration_s;
                if !(rate_hz.is_finite() && *rate_hz > 0.0) {
                    return Err(invalid("rate_hz", format!("must be > 0 Hz, got {rate_hz}")));
                }
                if !(duration_s.is_finite() && *duration_s > 0.0) {
                    return Err(invalid(
                        "duration_s",
                        format!("must be > 0 seconds, got {duration_s}"),
                    ));
                }
                if n > MAX_NOISE_SAMPLES {
                    return Err(invalid(
                        "duration_s",
                        format!(
                            "{duration_s} s at {rate_hz} Hz is {n:.3e} samples, over the {MAX_NOISE_SAMPLES:.0e} a scene may hold"
                        ),
                    ));
                }
                Kind::Wav {
                    rate: *rate_hz,
                    samples: noise_samples(*rate_hz, *duration_s, *seed),
                }
            }
        };
        Ok(Signal {
            spec: spec.clone(),
            kind,
            extra: Vec::new(),
            clip: None,
            poly: Vec::new(),
            decay_s: None,
            gain_bound: 1.0,
        })
    }

    /// The motion of an object with transfer function `res` (peaking
    /// sections in series, causal, from rest at t = 0) driven by this
    /// signal: sampled at `rate_hz` over `[0, duration_s]`, filtered, and
    /// read back with linear interpolation. Not renormalised: a resonance
    /// that boosts by 12 dB moves the object 4 times as far there.
    pub fn through(
        self,
        res: &[Resonance],
        rate_hz: f64,
        duration_s: f64,
    ) -> Result<Signal, SimError> {
        if res.is_empty() {
            return Ok(self);
        }
        let (n, sections) = check_resonances(res, rate_hz, duration_s)?;
        let mut state = vec![[0.0f64; 2]; sections.len()];
        let samples: Vec<f32> = (0..n as usize)
            .map(|k| {
                let t = k as f64 / rate_hz;
                let mut x = self.value(t);
                for ((c, z), r) in sections.iter().zip(state.iter_mut()).zip(res) {
                    if !r.active(t) {
                        *z = [0.0; 2];
                        continue;
                    }
                    // Transposed direct form II.
                    let y = c[0] * x + z[0];
                    z[0] = c[1] * x - c[3] * y + z[1];
                    z[1] = c[2] * x - c[4] * y;
                    x = y;
                }
                x as f32
            })
            .collect();
        Ok(Signal {
            spec: self.spec,
            kind: Kind::Wav {
                rate: rate_hz,
                samples: samples.into(),
            },
            extra: self.extra,
            clip: self.clip,
            poly: self.poly,
            decay_s: self.decay_s,
            gain_bound: 1.0,
        })
    }

    /// [`Signal::through`]'s checks without its filtering (which costs
    /// `duration_s * rate_hz` samples): the waveform is left as it is and
    /// its [`Signal::peak_bound`] scaled by the sections' steady-state peak
    /// gain (10^(gain_db / 20) for each boost), what a tone at the
    /// resonances would reach. A transient can go further; the peak of
    /// [`Signal::through`]'s samples is the exact one.
    pub fn through_checked(
        mut self,
        res: &[Resonance],
        rate_hz: f64,
        duration_s: f64,
    ) -> Result<Signal, SimError> {
        // No resonances: nothing is sampled, so the length is not checked.
        if !res.is_empty() {
            check_resonances(res, rate_hz, duration_s)?;
        }
        // Sections act over their own spans: the bound is the largest
        // product of the boosts acting at one time (each span's start).
        let mut starts: Vec<f64> = vec![0.0];
        starts.extend(res.iter().flat_map(|r| [r.from_s, r.until_s]).flatten());
        let gain: f64 = starts
            .iter()
            .map(|&t| {
                res.iter()
                    .filter(|r| r.active(t))
                    .map(|r| {
                        super::detmath::exp(r.gain_db.max(0.0) / 20.0 * std::f64::consts::LN_10)
                    })
                    .product::<f64>()
            })
            .fold(1.0, f64::max);
        self.gain_bound *= gain;
        Ok(self)
    }

    /// Adds tones `(Hz, weight)` on top (narrowband interference such as
    /// camera shake at a machine's rate), weights relative to unit peak.
    pub fn plus_tones(mut self, tones: &[(f64, f64)]) -> Result<Signal, SimError> {
        for (i, &(f, w)) in tones.iter().enumerate() {
            positive_freq(format!("interference[{i}].freq_hz"), f)?;
            if !w.is_finite() {
                return Err(invalid(
                    format!("interference[{i}]"),
                    "amplitude must be finite",
                ));
            }
            self.extra.push((f, w));
        }
        Ok(self)
    }

    /// Saturates the motion softly at `level` (signal units): `level ·
    /// tanh(x / level)`, a nonlinear object or loudspeaker (odd harmonics);
    /// applied before the extra tones (interference is not clipped).
    pub fn soft_clipped(mut self, level: f64) -> Result<Signal, SimError> {
        if !(level.is_finite() && level > 0.0) {
            return Err(invalid(
                "soft_clip_px",
                format!("must be a finite level > 0, got {level}"),
            ));
        }
        self.clip = Some(level);
        Ok(self)
    }

    /// A static nonlinear response of the object: `x + c2 x² + c3 x³ +
    /// …` with `coefs = [c2, c3, …]` in signal units (x at unit peak: 0.3
    /// puts 30% of the peak in the square term at the peak), applied
    /// before soft clipping and the extra tones. Even terms make even
    /// harmonics, which `tanh` cannot.
    pub fn with_polynomial(mut self, coefs: &[f64]) -> Result<Signal, SimError> {
        if coefs.len() > 8 {
            return Err(invalid(
                "response_poly",
                format!("at most 8 coefficients (x² to x⁹), got {}", coefs.len()),
            ));
        }
        for (i, c) in coefs.iter().enumerate() {
            if !(c.is_finite() && c.abs() <= 10.0) {
                return Err(invalid(
                    format!("response_poly[{i}]"),
                    format!("must be finite and within ±10, got {c}"),
                ));
            }
        }
        self.poly = coefs.to_vec();
        Ok(self)
    }

    /// The object's motion decays as `exp(-t / decay_s)` over the
    /// recording (a struck object ringing down), before the extra tones.
    pub fn decaying(mut self, decay_s: f64) -> Result<Signal, SimError> {
        if !(decay_s.is_finite() && decay_s > 0.0) {
            return Err(invalid(
                "gain_decay_s",
                format!("must be a finite time > 0, got {decay_s}"),
            ));
        }
        self.decay_s = Some(decay_s);
        Ok(self)
    }

    pub fn spec(&self) -> &SignalSpec {
        &self.spec
    }

    /// Length of a WAV signal in seconds (`None` for periodic signals).
    pub fn duration_s(&self) -> Option<f64> {
        match &self.kind {
            Kind::Wav { rate, samples } => Some(samples.len() as f64 / rate),
            _ => None,
        }
    }

    /// Instantaneous frequency at `t_s` (Hz) for tones and chirps; `None`
    /// for multi-tone and WAV signals.
    pub fn instantaneous_freq_hz(&self, t_s: f64) -> Option<f64> {
        match &self.kind {
            Kind::Tone { freq, .. } => Some(*freq),
            Kind::Chirp { f0, f1, period } => {
                let tau = t_s - period * (t_s / period).floor();
                Some(f0 + (f1 - f0) * tau / period)
            }
            _ => None,
        }
    }

    /// An upper bound of |value|: 1 for the plain signals (unit peak), more
    /// after a resonance or with interference added (after
    /// [`Signal::through_checked`], the bound at the resonances' steady-state
    /// gain).
    pub fn peak_bound(&self) -> f64 {
        let base = match &self.kind {
            Kind::Wav { samples, .. } => samples.iter().fold(0.0f64, |m, &v| m.max(v.abs() as f64)),
            _ => 1.0,
        };
        let p = base * self.gain_bound;
        let poly: f64 = self
            .poly
            .iter()
            .enumerate()
            .map(|(i, c)| c.abs() * p.powi(i as i32 + 2))
            .sum();
        p + poly + self.extra.iter().map(|(_, w)| w.abs()).sum::<f64>()
    }

    /// Unit-peak waveform value at time `t_s` seconds (plus any
    /// interference tones).
    pub fn value(&self, t_s: f64) -> f64 {
        let extra: f64 = self
            .extra
            .iter()
            .map(|&(f, w)| w * sin_turns(turns(f, t_s)))
            .sum();
        let mut b = self.base_value(t_s);
        if !self.poly.is_empty() {
            // Horner on x (c2 + x (c3 + …)), times x², plus x.
            let mut acc = 0.0;
            for c in self.poly.iter().rev() {
                acc = acc * b + c;
            }
            b += acc * b * b;
        }
        let b = match self.clip {
            // tanh(u) = 1 - 2 / (exp(2u) + 1), with the deterministic exp.
            Some(c) => {
                let u = (b / c).clamp(-20.0, 20.0);
                c * (1.0 - 2.0 / (super::detmath::exp(2.0 * u) + 1.0))
            }
            None => b,
        };
        let b = match self.decay_s {
            Some(d) => b * super::detmath::exp(-t_s.max(0.0) / d),
            None => b,
        };
        b + extra
    }

    fn base_value(&self, t_s: f64) -> f64 {
        match &self.kind {
            Kind::Tone { freq, phase_turns } => sin_turns(turns(*freq, t_s) + phase_turns),
            Kind::Tones { freqs, weights } => freqs
                .iter()
                .zip(weights)
                .map(|(f, w)| w * sin_turns(turns(*f, t_s)))
                .sum(),
            Kind::Chirp { f0, f1, period } => {
                let tau = (t_s - period * (t_s / period).floor()).clamp(0.0, *period);
                // ∫ f(τ) dτ with f(τ) = f0 + (f1 - f0) τ / T.
                let phase = f0 * tau + (f1 - f0) * tau * tau / (2.0 * period);
                sin_turns(phase)
            }
            Kind::Wav { rate, samples } => {
                let p = t_s * rate;
                if !(p > -1.0 && p < samples.len() as f64) {
                    return 0.0;
                }
                let i = p.floor();
                let a = p - i;
                let i = i as i64;
                let at = |k: i64| -> f64 {
                    if k < 0 {
                        0.0
                    } else {
                        samples.get(k as usize).map_or(0.0, |&s| s as f64)
                    }
                };
                at(i) * (1.0 - a) + at(i + 1) * a
            }
        }
    }
}

/// RBJ peaking biquad `[b0, b1, b2, a1, a2]` (a0 = 1), cosines from the
/// deterministic [`super::detmath`].
fn peaking(r: &Resonance, fs: f64) -> [f64; 5] {
    let (sn, cs) = super::detmath::sin_cos_turns(r.freq_hz / fs);
    let a = super::detmath::exp(r.gain_db / 40.0 * std::f64::consts::LN_10);
    let alpha = sn / (2.0 * r.q);
    let a0 = 1.0 + alpha / a;
    [
        (1.0 + alpha * a) / a0,
        -2.0 * cs / a0,
        (1.0 - alpha * a) / a0,
        -2.0 * cs / a0,
        (1.0 - alpha / a) / a0,
    ]
}

/// Phase `f·t` in turns, reduced to [0, 1) before adding anything to it.
fn turns(f: f64, t: f64) -> f64 {
    let p = f * t;
    p - p.floor()
}

/// A WAV file's first channel (read by [`vibroscope_io::wav::read_mono`]),
/// stored as `f32` (non-finite samples as 0) and normalised to peak 1.
fn load_wav(path: &Path) -> Result<Kind, SimError> {
    let (rate, mono) = vibroscope_io::wav::read_mono(path)?;
    if rate == 0 {
        return Err(invalid(
            "path",
            format!("{}: sample rate is 0", path.display()),
        ));
    }
    // Integers are scaled by a power of two, which the normalisation below
    // undoes exactly: the samples are those of the raw integers.
    let mut samples: Vec<f32> = mono
        .iter()
        .map(|&v| if v.is_finite() { v as f32 } else { 0.0 })
        .collect();
    if samples.is_empty() {
        return Err(invalid(
            "path",
            format!("{}: the WAV file has no samples", path.display()),
        ));
    }
    let peak = samples.iter().fold(0.0f32, |m, s| m.max(s.abs()));
    if peak > 0.0 {
        let inv = 1.0 / peak as f64;
        for s in &mut samples {
            *s = (*s as f64 * inv) as f32;
        }
    }
    Ok(Kind::Wav {
        rate: rate as f64,
        samples: samples.into(),
    })
}

/// The sample count and the biquad sections of `through`, checked.
fn check_resonances(
    res: &[Resonance],
    rate_hz: f64,
    duration_s: f64,
) -> Result<(f64, Vec<[f64; 5]>), SimError> {
    let n = (duration_s * rate_hz).ceil();
    if !(n.is_finite() && (1.0..=1e9).contains(&n)) {
        return Err(invalid(
            "resonances",
            format!("cannot sample {duration_s} s at {rate_hz} Hz"),
        ));
    }
    let mut sections = Vec::with_capacity(res.len());
    for (i, r) in res.iter().enumerate() {
        if !(r.freq_hz.is_finite() && r.freq_hz > 0.0 && r.freq_hz < 0.45 * rate_hz) {
            return Err(invalid(
                format!("resonances[{i}].freq_hz"),
                format!(
                    "must be > 0 and below {:.0} Hz, got {}",
                    0.45 * rate_hz,
                    r.freq_hz
                ),
            ));
        }
        if !(r.q.is_finite() && r.q > 0.0 && r.q <= 1000.0) {
            return Err(invalid(
                format!("resonances[{i}].q"),
                format!("must be in (0, 1000], got {}", r.q),
            ));
        }
        if !(r.gain_db.is_finite() && r.gain_db.abs() <= 60.0) {
            return Err(invalid(
                format!("resonances[{i}].gain_db"),
                format!("must be within ±60 dB, got {}", r.gain_db),
            ));
        }
        for (name, v) in [("from_s", r.from_s), ("until_s", r.until_s)] {
            if let Some(v) = v {
                if !(v.is_finite() && v >= 0.0) {
                    return Err(invalid(
                        format!("resonances[{i}].{name}"),
                        format!("must be a time >= 0 s, got {v}"),
                    ));
                }
            }
        }
        if let (Some(a), Some(b)) = (r.from_s, r.until_s) {
            if a >= b {
                return Err(invalid(
                    format!("resonances[{i}].until_s"),
                    format!("must be after from_s ({a} s), got {b}"),
                ));
            }
        }
        sections.push(peaking(r, rate_hz));
    }
    Ok((n, sections))
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;

    fn tone(f: f64, ph: f64) -> Signal {
        Signal::new(&SignalSpec::Tone {
            freq_hz: f,
            phase_rad: ph,
        })
        .unwrap()
    }

    /// Issue 15: the static polynomial response is `x + c2 x² + c3 x³` on
    /// the signal, bounded in `peak_bound`, and bad coefficients are
    /// refused naming `response_poly`.
    #[test]
    fn a_polynomial_response_adds_its_terms() {
        let s = tone(10.0, 0.3).with_polynomial(&[0.25, -0.1]).unwrap();
        let plain = tone(10.0, 0.3);
        for k in 0..50 {
            let t = k as f64 * 0.0071;
            let x = plain.value(t);
            let want = x + 0.25 * x * x - 0.1 * x * x * x;
            assert!((s.value(t) - want).abs() < 1e-12, "{t}");
            assert!(s.value(t).abs() <= s.peak_bound() + 1e-12);
        }
        assert!((s.peak_bound() - 1.35).abs() < 1e-12);
        for bad in [vec![f64::NAN], vec![11.0], vec![0.1; 9]] {
            let e = tone(10.0, 0.0).with_polynomial(&bad).unwrap_err();
            assert!(e.to_string().contains("response_poly"), "{e}");
        }
    }

    #[test]
    fn tone_values_period_and_phase() {
        let s = tone(440.0, 0.0);
        assert_eq!(s.value(0.0), 0.0);
        assert!((s.value(1.0 / 1760.0) - 1.0).abs() < 1e-12);
        for k in 0..200 {
            let t = k as f64 * 1.37e-4;
            let v = s.value(t);
            assert!((v - (std::f64::consts::TAU * 440.0 * t).sin()).abs() < 1e-11);
            assert!(
                (v - s.value(t + 1.0 / 440.0)).abs() < 1e-9,
                "not periodic at {t}"
            );
        }
        let c = tone(10.0, std::f64::consts::FRAC_PI_2);
        assert!((c.value(0.0) - 1.0).abs() < 1e-15);
        assert!((c.value(0.05) + 1.0).abs() < 1e-12);
        // Long times keep their precision.
        let t = 3600.0 + 0.25 / 440.0;
        assert!((s.value(t) - 1.0).abs() < 1e-9);
    }

    #[test]
    fn tones_are_normalised_to_unit_peak() {
        let s = Signal::new(&SignalSpec::Tones {
            freqs_hz: vec![100.0, 300.0, 500.0],
            weights: vec![],
        })
        .unwrap();
        let mut peak = 0.0f64;
        for k in 0..20_000 {
            let t = k as f64 * 1e-6 * 7.0;
            let v = s.value(t);
            peak = peak.max(v.abs());
            let want = [100.0f64, 300.0, 500.0]
                .iter()
                .map(|f| (std::f64::consts::TAU * f * t).sin())
                .sum::<f64>()
                / 3.0;
            assert!((v - want).abs() < 1e-12);
        }
        assert!(peak <= 1.0 && peak > 0.5, "peak {peak}");
        // Weights: a single non-zero weight gives exactly that tone.
        let w = Signal::new(&SignalSpec::Tones {
            freqs_hz: vec![50.0, 80.0],
            weights: vec![0.0, -2.0],
        })
        .unwrap();
        assert!((w.value(1.0 / 320.0) + 1.0).abs() < 1e-12);
        let e = Signal::new(&SignalSpec::Tones {
            freqs_hz: vec![50.0, 80.0],
            weights: vec![1.0],
        })
        .unwrap_err()
        .to_string();
        assert!(e.contains("weights"), "{e}");
    }

    /// Local frequency from the spacing of zero crossings around `t`.
    fn local_freq(s: &Signal, t: f64, half_window: f64) -> f64 {
        let n = 200_000;
        let dt = 2.0 * half_window / n as f64;
        let mut crossings = Vec::new();
        let mut prev = s.value(t - half_window);
        for k in 1..=n {
            let tk = t - half_window + k as f64 * dt;
            let v = s.value(tk);
            if (prev < 0.0) != (v < 0.0) {
                // Linear refinement.
                crossings.push(tk - dt * v / (v - prev));
            }
            prev = v;
        }
        assert!(crossings.len() >= 3, "too few crossings near {t}");
        let span = crossings[crossings.len() - 1] - crossings[0];
        (crossings.len() - 1) as f64 / (2.0 * span)
    }

    #[test]
    fn chirp_instantaneous_frequency_and_repeat() {
        let s = Signal::new(&SignalSpec::Chirp {
            f0_hz: 100.0,
            f1_hz: 1100.0,
            duration_s: 1.0,
        })
        .unwrap();
        for t in [0.1, 0.3, 0.5, 0.9] {
            let want = 100.0 + 1000.0 * t;
            let got = local_freq(&s, t, 0.01);
            assert!(
                (got - want).abs() / want < 0.01,
                "f({t}) = {got}, want {want}"
            );
            assert_eq!(s.instantaneous_freq_hz(t), Some(want));
        }
        // Repeats every duration_s.
        for t in [0.0123, 0.4567, 0.999] {
            assert!((s.value(t) - s.value(t + 1.0)).abs() < 1e-9);
            assert!((s.value(t) - s.value(t + 5.0)).abs() < 1e-8);
        }
        // Downward sweeps work too.
        let d = Signal::new(&SignalSpec::Chirp {
            f0_hz: 2000.0,
            f1_hz: 500.0,
            duration_s: 0.5,
        })
        .unwrap();
        let got = local_freq(&d, 0.25, 0.005);
        assert!((got - 1250.0).abs() < 12.0, "{got}");
    }

    fn temp_path(name: &str) -> PathBuf {
        std::env::temp_dir().join(format!("vibroscope-sim-{}-{name}", std::process::id()))
    }

    #[test]
    fn wav_is_loaded_normalised_and_interpolated() {
        let path = temp_path("mono.wav");
        let spec = hound::WavSpec {
            channels: 2,
            sample_rate: 8000,
            bits_per_sample: 16,
            sample_format: hound::SampleFormat::Int,
        };
        let data: Vec<i16> = (0..800)
            .map(|i| ((i as f64 * 0.05).sin() * 8000.0).round() as i16)
            .collect();
        {
            let mut w = hound::WavWriter::create(&path, spec).unwrap();
            for &s in &data {
                w.write_sample(s).unwrap();
                w.write_sample(-20000i16).unwrap(); // 2nd channel: ignored
            }
            w.finalize().unwrap();
        }
        let s = Signal::new(&SignalSpec::Wav { path: path.clone() }).unwrap();
        std::fs::remove_file(&path).ok();
        let peak = data.iter().map(|v| v.unsigned_abs()).max().unwrap() as f64;
        assert!((s.duration_s().unwrap() - 0.1).abs() < 1e-12);
        for i in [0usize, 1, 17, 400, 799] {
            let t = i as f64 / 8000.0;
            assert!(
                (s.value(t) - data[i] as f64 / peak).abs() < 1e-6,
                "sample {i}"
            );
        }
        // Halfway between samples: the mean of the two.
        let mid = s.value(10.5 / 8000.0);
        let want = (data[10] as f64 + data[11] as f64) / (2.0 * peak);
        assert!((mid - want).abs() < 1e-6);
        let max = (0..8000)
            .map(|k| s.value(k as f64 / 80_000.0).abs())
            .fold(0.0, f64::max);
        assert!((max - 1.0).abs() < 1e-6, "peak {max}");
        assert_eq!(s.value(0.2), 0.0);
        assert_eq!(s.value(-0.01), 0.0);
        assert_eq!(s.value(f64::NAN), 0.0);

        // 24-bit and float files too.
        let path = temp_path("f32.wav");
        {
            let spec = hound::WavSpec {
                channels: 1,
                sample_rate: 1000,
                bits_per_sample: 32,
                sample_format: hound::SampleFormat::Float,
            };
            let mut w = hound::WavWriter::create(&path, spec).unwrap();
            for v in [0.0f32, 0.25, -0.5, 0.1] {
                w.write_sample(v).unwrap();
            }
            w.finalize().unwrap();
        }
        let s = Signal::new(&SignalSpec::Wav { path: path.clone() }).unwrap();
        std::fs::remove_file(&path).ok();
        assert!((s.value(0.002) + 1.0).abs() < 1e-9);
        assert!((s.value(0.001) - 0.5).abs() < 1e-9);
    }

    #[test]
    fn missing_wav_names_the_path() {
        let p = PathBuf::from("/nonexistent/dir/x.wav");
        let e = Signal::new(&SignalSpec::Wav { path: p })
            .unwrap_err()
            .to_string();
        assert!(e.contains("/nonexistent/dir/x.wav"), "{e}");
    }

    #[test]
    fn invalid_specs_are_errors_naming_the_field() {
        let cases: Vec<(SignalSpec, &str)> = vec![
            (
                SignalSpec::Tone {
                    freq_hz: 0.0,
                    phase_rad: 0.0,
                },
                "freq_hz",
            ),
            (
                SignalSpec::Tone {
                    freq_hz: -5.0,
                    phase_rad: 0.0,
                },
                "freq_hz",
            ),
            (
                SignalSpec::Tone {
                    freq_hz: f64::NAN,
                    phase_rad: 0.0,
                },
                "freq_hz",
            ),
            (
                SignalSpec::Tone {
                    freq_hz: 5.0,
                    phase_rad: f64::INFINITY,
                },
                "phase_rad",
            ),
            (
                SignalSpec::Tones {
                    freqs_hz: vec![],
                    weights: vec![],
                },
                "freqs_hz",
            ),
            (
                SignalSpec::Tones {
                    freqs_hz: vec![1.0, -1.0],
                    weights: vec![],
                },
                "freqs_hz[1]",
            ),
            (
                SignalSpec::Tones {
                    freqs_hz: vec![1.0],
                    weights: vec![0.0],
                },
                "weights",
            ),
            (
                SignalSpec::Chirp {
                    f0_hz: 10.0,
                    f1_hz: 20.0,
                    duration_s: 0.0,
                },
                "duration_s",
            ),
            (
                SignalSpec::Chirp {
                    f0_hz: -1.0,
                    f1_hz: 20.0,
                    duration_s: 1.0,
                },
                "f0_hz",
            ),
        ];
        for (spec, field) in cases {
            let e = Signal::new(&spec).unwrap_err().to_string();
            assert!(e.contains(field), "{spec:?}: {e}");
        }
    }

    #[test]
    fn spec_deserialises_with_defaults_and_rejects_unknown_fields() {
        let s: SignalSpec = serde_json::from_str(r#"{"type":"tone","freq_hz":440}"#).unwrap();
        assert_eq!(
            s,
            SignalSpec::Tone {
                freq_hz: 440.0,
                phase_rad: 0.0
            }
        );
        let s: SignalSpec = serde_json::from_str(r#"{"type":"tones","freqs_hz":[1,2]}"#).unwrap();
        assert_eq!(
            s,
            SignalSpec::Tones {
                freqs_hz: vec![1.0, 2.0],
                weights: vec![]
            }
        );
        let s: SignalSpec =
            serde_json::from_str(r#"{"type":"chirp","f0_hz":1,"f1_hz":2,"duration_s":3}"#).unwrap();
        assert!(matches!(s, SignalSpec::Chirp { .. }));
        let s: SignalSpec = serde_json::from_str(r#"{"type":"wav","path":"a.wav"}"#).unwrap();
        assert!(matches!(s, SignalSpec::Wav { .. }));
        assert!(
            serde_json::from_str::<SignalSpec>(r#"{"type":"tone","freq_hz":1,"fraq":2}"#).is_err()
        );
        assert!(serde_json::from_str::<SignalSpec>(r#"{"type":"noise"}"#).is_err());
    }
}

#[cfg(test)]
mod transfer_tests {
    use super::*;

    /// A tone at a peaking resonance comes out `gain_db` louder once the
    /// section has settled; a tone far away is barely touched.
    #[test]
    fn resonance_gain_at_and_away_from_its_frequency() {
        let res = [Resonance::new(500.0, 3.0, 12.0)];
        for (f, want_db) in [(500.0, 12.0), (60.0, 0.0)] {
            let s = Signal::new(&SignalSpec::Tone {
                freq_hz: f,
                phase_rad: 0.0,
            })
            .unwrap()
            .through(&res, 96_000.0, 2.0)
            .unwrap();
            let peak = (0..20_000)
                .map(|k| s.value(1.0 + k as f64 / 20_000.0 / f * 2.0).abs())
                .fold(0.0f64, f64::max);
            let db = 20.0 * peak.log10();
            assert!((db - want_db).abs() < 0.3, "{f} Hz: {db:.2} dB");
        }
    }

    /// The checked (unfiltered) signal bounds the peak at the sections'
    /// steady-state gain: a cut adds nothing, boosts multiply, and a tone
    /// at the boost, filtered for real, reaches that bound.
    #[test]
    fn checked_peak_bound_is_the_steady_state_gain() {
        let tone = || {
            Signal::new(&SignalSpec::Tone {
                freq_hz: 500.0,
                phase_rad: 0.0,
            })
            .unwrap()
        };
        let r = |freq_hz, gain_db| Resonance::new(freq_hz, 3.0, gain_db);
        let res = [r(500.0, 12.0), r(3000.0, -20.0), r(9000.0, 6.0)];
        let checked = tone().through_checked(&res, 96_000.0, 2.0).unwrap();
        let want = 10f64.powf(18.0 / 20.0);
        assert!((checked.peak_bound() - want).abs() < 1e-9 * want);
        // The waveform itself is untouched.
        assert_eq!(checked.value(0.37), tone().value(0.37));
        let exact = tone()
            .through(&res[..1], 96_000.0, 2.0)
            .unwrap()
            .peak_bound();
        let steady = 10f64.powf(12.0 / 20.0);
        assert!((exact / steady - 1.0).abs() < 0.05, "{exact} vs {steady}");
        // Arguments are checked as `through` checks them.
        assert!(tone()
            .through_checked(&[r(60_000.0, 6.0)], 96_000.0, 2.0)
            .is_err());
        assert!(tone().through_checked(&res, 96_000.0, 1e9).is_err());
    }

    /// Noise through a resonance that moves at 5 s: the strongest line of
    /// each half is at that half's resonance, and the noise is
    /// deterministic from its seed.
    #[test]
    fn noise_through_a_resonance_that_moves() {
        let spec = SignalSpec::Noise {
            rate_hz: 400.0,
            duration_s: 10.0,
            seed: 7,
        };
        let before = Resonance {
            until_s: Some(5.0),
            ..Resonance::new(40.0, 100.0, 30.0)
        };
        let after = Resonance {
            from_s: Some(5.0),
            ..Resonance::new(44.0, 100.0, 30.0)
        };
        let res = [before, after];
        let s = Signal::new(&spec)
            .unwrap()
            .through(&res, 400.0, 10.0)
            .unwrap();
        let again = Signal::new(&spec)
            .unwrap()
            .through(&res, 400.0, 10.0)
            .unwrap();
        assert_eq!(s.value(3.3), again.value(3.3));
        // The strongest of 0.25 Hz-spaced probe lines, by correlation.
        let peak = |t0: f64| {
            let xs: Vec<f64> = (0..1600).map(|k| s.value(t0 + k as f64 / 400.0)).collect();
            (120..200)
                .map(|j| j as f64 * 0.25)
                .map(|f| {
                    let (mut c, mut q) = (0.0, 0.0);
                    for (k, x) in xs.iter().enumerate() {
                        let ph = std::f64::consts::TAU * f * k as f64 / 400.0;
                        c += x * ph.cos();
                        q += x * ph.sin();
                    }
                    (f, c * c + q * q)
                })
                .fold((0.0, 0.0), |a, b| if b.1 > a.1 { b } else { a })
                .0
        };
        assert!((peak(0.5) - 40.0).abs() <= 0.5, "{}", peak(0.5));
        assert!((peak(5.5) - 44.0).abs() <= 0.5, "{}", peak(5.5));
    }
}
