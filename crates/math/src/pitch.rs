//! Pitch: the YIN fundamental-frequency estimator (de Cheveigné and
//! Kawahara, "YIN, a fundamental frequency estimator for speech and music",
//! JASA 111(4), 2002), frame by frame with a confidence, as the thesis uses
//! pitch to show that recovered speech keeps its speaker's intonation even
//! where the words are unintelligible (section 4.6, Fig. 4-11).
//!
//! Per frame (steps of the paper): the difference function
//! `d(τ) = Σ (x[j] - x[j+τ])²` over a window of `W` samples (step 2), its
//! cumulative-mean normalisation `d'(τ) = d(τ) / ((1/τ) Σ_{k≤τ} d(k))`
//! (step 3), the first dip of `d'` under an absolute threshold, taken at its
//! local minimum (step 4), refined by a parabola through `d` (step 5). The
//! frame's aperiodicity is `d'` at the chosen lag; `confidence = 1 -
//! aperiodicity`, and a frame is voiced when the dip fell under the
//! threshold and the frame is not silent.

/// Settings of the tracker.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct YinParams {
    /// Lowest pitch searched, Hz (sets the longest lag and the window).
    pub fmin_hz: f64,
    /// Highest pitch searched, Hz (sets the shortest lag).
    pub fmax_hz: f64,
    /// Absolute threshold on `d'` (the paper's 0.1; 0.1-0.2 for noisy input).
    pub threshold: f64,
    /// Hop between frames, seconds.
    pub hop_s: f64,
    /// Frames whose RMS is this many dB below the loudest frame's are
    /// silent (unvoiced whatever their periodicity).
    pub silence_db: f64,
}

impl Default for YinParams {
    fn default() -> Self {
        YinParams {
            fmin_hz: 60.0,
            fmax_hz: 500.0,
            threshold: 0.15,
            hop_s: 0.01,
            silence_db: 40.0,
        }
    }
}

/// One frame of the track.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct PitchFrame {
    /// Centre of the frame's window, seconds from the first sample.
    pub time_s: f64,
    /// The best pitch estimate, Hz (given for unvoiced frames too: the
    /// lag of the deepest dip).
    pub f0_hz: f64,
    /// `1 - d'` at the chosen lag (1 = perfectly periodic).
    pub confidence: f64,
    /// Periodic enough (dip under the threshold) and not silent.
    pub voiced: bool,
    /// The frame's RMS.
    pub rms: f64,
}

/// Why a signal cannot be tracked.
#[derive(Clone, Debug, PartialEq, thiserror::Error)]
pub enum PitchError {
    #[error("invalid {field}: {message}")]
    Invalid {
        field: &'static str,
        message: String,
    },
    #[error(
        "the signal has {got} samples; at {rate_hz} Hz, YIN needs at least {need} \
         (two periods of the lowest pitch searched, {fmin_hz} Hz)"
    )]
    TooShort {
        got: usize,
        need: usize,
        rate_hz: f64,
        fmin_hz: f64,
    },
    #[error("the signal is silent (every sample is 0 or not finite): there is no pitch")]
    Silent,
}

/// The lags and window the settings give at `rate_hz`: (shortest lag,
/// longest lag, window length), samples.
fn geometry(p: &YinParams, rate_hz: f64) -> Result<(usize, usize, usize), PitchError> {
    let invalid = |field, message: String| PitchError::Invalid { field, message };
    if !(rate_hz.is_finite() && rate_hz > 0.0) {
        return Err(invalid("rate", format!("{rate_hz} Hz must be positive")));
    }
    if !(p.fmin_hz.is_finite() && p.fmin_hz > 0.0) {
        return Err(invalid(
            "fmin",
            format!("{} Hz must be positive", p.fmin_hz),
        ));
    }
    if !(p.fmax_hz.is_finite() && p.fmax_hz > p.fmin_hz) {
        return Err(invalid(
            "fmax",
            format!("{} Hz must be above fmin ({} Hz)", p.fmax_hz, p.fmin_hz),
        ));
    }
    if p.fmax_hz > rate_hz / 4.0 {
        return Err(invalid(
            "fmax",
            format!(
                "{} Hz is above a quarter of the sample rate ({rate_hz} Hz): too few samples a period",
                p.fmax_hz
            ),
        ));
    }
    if !(p.threshold > 0.0 && p.threshold < 1.0) {
        return Err(invalid(
            "threshold",
            format!("{} must be in (0, 1)", p.threshold),
        ));
    }
    if !(p.hop_s.is_finite() && p.hop_s > 0.0) {
        return Err(invalid("hop", format!("{} s must be positive", p.hop_s)));
    }
    if !(p.silence_db.is_finite() && p.silence_db > 0.0) {
        return Err(invalid(
            "silence",
            format!("{} dB must be positive", p.silence_db),
        ));
    }
    if rate_hz / p.fmin_hz > f64::from(1u32 << 16) {
        return Err(invalid(
            "fmin",
            format!(
                "{} Hz at {rate_hz} Hz gives a lag over 65536 samples",
                p.fmin_hz
            ),
        ));
    }
    Ok(geometry_at(p, rate_hz))
}

/// Whether the settings work on a signal at `rate_hz` (before it is
/// interpolated: the highest pitch must have four samples a period).
pub fn check(p: &YinParams, rate_hz: f64) -> Result<(), PitchError> {
    geometry(p, rate_hz).map(|_| ())
}

/// [`geometry`] of checked settings.
fn geometry_at(p: &YinParams, rate_hz: f64) -> (usize, usize, usize) {
    let max_lag = (rate_hz / p.fmin_hz).ceil() as usize;
    let min_lag = ((rate_hz / p.fmax_hz).floor() as usize).max(2);
    // The window holds one period of the lowest pitch (the paper's choice).
    (min_lag, max_lag, max_lag)
}

/// `x` interpolated to `k` times its rate, band-limited (zero-padding its
/// spectrum; the signal is treated as periodic, which only touches its
/// first and last few periods).
fn upsample(x: &[f64], k: usize) -> Vec<f64> {
    let n = x.len();
    let m = n * k;
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(n);
    let inv = planner.plan_fft_inverse(m);
    let mut input = x.to_vec();
    let mut spec = fwd.make_output_vec();
    if fwd.process(&mut input, &mut spec).is_err() {
        return x.to_vec();
    }
    let mut padded = inv.make_input_vec();
    padded[..spec.len()].copy_from_slice(&spec);
    if n.is_multiple_of(2) {
        // The old Nyquist bin becomes an ordinary one, counted twice.
        padded[n / 2] *= 0.5;
    }
    padded[0].im = 0.0;
    let mut out = inv.make_output_vec();
    if inv.process(&mut padded, &mut out).is_err() {
        return x.to_vec();
    }
    let scale = 1.0 / n as f64;
    out.iter_mut().for_each(|v| *v *= scale);
    out
}

/// Signals sampled below this rate are interpolated up to it (band-limited)
/// before YIN: with few samples a period, `d` at whole-sample lags misses
/// the true period, and the first dip under the threshold falls on twice
/// or three times it (octave errors; a 290 Hz voice at 2200 Hz has 7.6
/// samples a period).
pub const MIN_RATE_HZ: f64 = 8000.0;

/// Tracks the pitch of `x` sampled at `rate_hz`: the whole signal, each
/// frame's silence judged against the loudest frame of the signal (the
/// live [`Tracker`] can only judge against the loudest so far).
pub fn track(x: &[f64], rate_hz: f64, p: &YinParams) -> Result<Vec<PitchFrame>, PitchError> {
    let (_, max_lag, w) = geometry(p, rate_hz)?;
    let need = w + max_lag + 2;
    if x.len() < need {
        return Err(PitchError::TooShort {
            got: x.len(),
            need,
            rate_hz,
            fmin_hz: p.fmin_hz,
        });
    }
    if !x.iter().any(|v| v.is_finite() && *v != 0.0) {
        return Err(PitchError::Silent);
    }
    let x: Vec<f64> = x
        .iter()
        .map(|v| if v.is_finite() { *v } else { 0.0 })
        .collect();
    let up = upsampling(rate_hz);
    let x = if up > 1 { upsample(&x, up) } else { x };
    let mut t = Tracker::new(p, rate_hz * up as f64, Silence::Off)?;
    let mut frames = Vec::new();
    t.push(&x, |f| frames.push(f));
    // Silence: relative to the loudest frame.
    let loud = frames.iter().map(|f| f.rms).fold(0.0, f64::max);
    let floor = loud * 10f64.powf(-p.silence_db / 20.0);
    for f in &mut frames {
        if f.rms <= floor {
            f.voiced = false;
        }
    }
    Ok(frames)
}

/// The factor by which a signal at `rate_hz` is interpolated before YIN
/// (to at least [`MIN_RATE_HZ`]; 1 at or above it).
pub fn upsampling(rate_hz: f64) -> usize {
    if rate_hz < MIN_RATE_HZ {
        (MIN_RATE_HZ / rate_hz).ceil() as usize
    } else {
        1
    }
}

/// How a [`Tracker`] decides that a frame is silent.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum Silence {
    /// Against the loudest frame so far (causal: the first frames of a
    /// quiet start count as loud until something louder comes).
    SoFar,
    /// Not at all (the caller decides, as [`track`] does on the whole
    /// signal).
    Off,
}

/// YIN on a stream: samples go in as they come (already at a rate where
/// YIN works, see [`upsampling`]), a [`PitchFrame`] comes out every hop
/// once a window and the longest lag are in. Frame `k` covers samples
/// `k·hop .. k·hop + W + max_lag` of the stream, as in [`track`], so both
/// give the same frames at the same times. Nothing is allocated after
/// [`Tracker::new`].
pub struct Tracker {
    rate_hz: f64,
    min_lag: usize,
    max_lag: usize,
    w: usize,
    hop: usize,
    span: usize,
    threshold: f64,
    silence: Silence,
    silence_ratio: f64,
    loudest: f64,
    /// The last `span` samples, written twice (at `i` and `i + span`) so the
    /// window is always one slice.
    ring: Vec<f64>,
    pos: usize,
    /// Samples pushed so far.
    n: u64,
    d: Vec<f64>,
    dn: Vec<f64>,
}

impl Tracker {
    /// A tracker for samples at `rate_hz` (the settings are checked
    /// against it).
    pub fn new(p: &YinParams, rate_hz: f64, silence: Silence) -> Result<Tracker, PitchError> {
        geometry(p, rate_hz)?;
        let (min_lag, max_lag, w) = geometry_at(p, rate_hz);
        let span = w + max_lag + 1;
        Ok(Tracker {
            rate_hz,
            min_lag,
            max_lag,
            w,
            hop: ((p.hop_s * rate_hz).round() as usize).max(1),
            span,
            threshold: p.threshold,
            silence,
            silence_ratio: 10f64.powf(-p.silence_db / 20.0),
            loudest: 0.0,
            ring: vec![0.0; 2 * span],
            pos: 0,
            n: 0,
            d: vec![0.0; max_lag + 2],
            dn: vec![0.0; max_lag + 2],
        })
    }

    /// Samples between frames.
    pub fn hop(&self) -> usize {
        self.hop
    }

    /// The rate of the samples it takes, Hz.
    pub fn rate_hz(&self) -> f64 {
        self.rate_hz
    }

    /// Samples a frame spans (the window plus the longest lag): a frame is
    /// out this many samples after its first.
    pub fn span(&self) -> usize {
        self.span
    }

    /// Samples from a frame's first to its reported time (half a window).
    pub fn centre(&self) -> f64 {
        self.w as f64 / 2.0
    }

    /// Feeds samples (non-finite ones count as 0); `emit` gets each frame
    /// completed, its time counted from the first sample ever pushed.
    pub fn push(&mut self, x: &[f64], mut emit: impl FnMut(PitchFrame)) {
        for &v in x {
            let v = if v.is_finite() { v } else { 0.0 };
            self.ring[self.pos] = v;
            self.ring[self.pos + self.span] = v;
            self.pos = (self.pos + 1) % self.span;
            self.n += 1;
            if self.n < self.span as u64
                || !(self.n - self.span as u64).is_multiple_of(self.hop as u64)
            {
                continue;
            }
            let start = self.n - self.span as u64;
            let f = self.frame(start);
            emit(f);
        }
    }

    /// The frame over the ring's window, which starts at sample `start`.
    fn frame(&mut self, start: u64) -> PitchFrame {
        let seg = &self.ring[self.pos..self.pos + self.span];
        difference(seg, self.w, &mut self.d);
        normalise(&self.d, &mut self.dn);
        let (tau, dip) = choose(&self.dn, self.min_lag, self.max_lag + 1, self.threshold);
        let lag = refine(&self.d, tau);
        let rms = (seg[..self.w].iter().map(|v| v * v).sum::<f64>() / self.w as f64).sqrt();
        let mut voiced = dip < self.threshold;
        if self.silence == Silence::SoFar {
            self.loudest = self.loudest.max(rms);
            voiced &= rms > self.loudest * self.silence_ratio;
        }
        PitchFrame {
            time_s: (start as f64 + self.w as f64 / 2.0) / self.rate_hz,
            f0_hz: self.rate_hz / lag,
            confidence: (1.0 - dip).clamp(0.0, 1.0),
            voiced,
            rms,
        }
    }
}

/// Step 2: `d[τ] = Σ_{j<w} (s[j] - s[j+τ])²` for τ in 0..d.len().
fn difference(s: &[f64], w: usize, d: &mut [f64]) {
    for (tau, dt) in d.iter_mut().enumerate() {
        *dt = s[..w]
            .iter()
            .zip(&s[tau..tau + w])
            .map(|(a, b)| (a - b) * (a - b))
            .sum();
    }
}

/// Step 3: cumulative-mean normalised difference, `dn[0] = 1`.
fn normalise(d: &[f64], dn: &mut [f64]) {
    dn[0] = 1.0;
    let mut sum = 0.0;
    for tau in 1..d.len() {
        sum += d[tau];
        dn[tau] = if sum > 0.0 {
            d[tau] * tau as f64 / sum
        } else {
            1.0
        };
    }
}

/// Step 4: the first lag in `lo..hi` where `dn` dips under `threshold`,
/// followed down to its local minimum; the global minimum when none does.
/// Returns the lag and `dn` there.
fn choose(dn: &[f64], lo: usize, hi: usize, threshold: f64) -> (usize, f64) {
    let hi = hi.min(dn.len() - 1);
    let mut tau = lo;
    while tau < hi {
        if dn[tau] < threshold {
            while tau + 1 < hi && dn[tau + 1] < dn[tau] {
                tau += 1;
            }
            return (tau, dn[tau]);
        }
        tau += 1;
    }
    let best = (lo..hi)
        .min_by(|&a, &b| dn[a].total_cmp(&dn[b]))
        .unwrap_or(lo);
    (best, dn[best])
}

/// Step 5: the lag of the minimum of a parabola through `d` at `tau - 1,
/// tau, tau + 1` (kept within half a sample).
fn refine(d: &[f64], tau: usize) -> f64 {
    if tau == 0 || tau + 1 >= d.len() {
        return tau as f64;
    }
    let (a, b, c) = (d[tau - 1], d[tau], d[tau + 1]);
    let den = a - 2.0 * b + c;
    if den <= 0.0 {
        return tau as f64;
    }
    tau as f64 + (0.5 * (a - c) / den).clamp(-0.5, 0.5)
}

/// Short-time power spectra of `x` (Hann window of `len` samples, a
/// spectrum every `hop`), to draw a track over: (centre time in seconds,
/// power per bin `k·rate/len`) for each window.
pub fn spectrogram(x: &[f64], rate_hz: f64, len: usize, hop: usize) -> Vec<(f64, Vec<f64>)> {
    let len = len.max(4);
    crate::stft::stft(x, len, hop)
        .into_iter()
        .enumerate()
        .map(|(k, spec)| {
            let t = ((k * hop.max(1)) as f64 + len as f64 / 2.0) / rate_hz;
            (t, spec.iter().map(|c| c.norm_sqr()).collect())
        })
        .collect()
}

/// A voice-like signal of known pitch `f0(t)` (Hz at `t` seconds), to test
/// trackers with: a band-limited pulse train, the first `harmonics`
/// harmonics below Nyquist with amplitude 1/k, `secs` long at `rate_hz`.
pub fn voice(rate_hz: f64, secs: f64, harmonics: usize, f0: impl Fn(f64) -> f64) -> Vec<f64> {
    let n = (rate_hz * secs) as usize;
    let mut phase = 0.0;
    (0..n)
        .map(|i| {
            let f = f0(i as f64 / rate_hz);
            phase += 2.0 * std::f64::consts::PI * f / rate_hz;
            (1..=harmonics)
                .filter(|k| (*k as f64) * f < rate_hz / 2.0)
                .map(|k| (k as f64 * phase).sin() / k as f64)
                .sum()
        })
        .collect()
}

/// Median relative error `|f / truth - 1|` over the frames voiced in
/// `truth` (frames matched by index; both tracks made with the same
/// settings on signals of the same rate), and how many frames it used.
pub fn median_error(est: &[PitchFrame], truth: &[PitchFrame]) -> (f64, usize) {
    let mut e: Vec<f64> = est
        .iter()
        .zip(truth)
        .filter(|(_, t)| t.voiced)
        .map(|(f, t)| (f.f0_hz / t.f0_hz - 1.0).abs())
        .collect();
    let n = e.len();
    (crate::numeric::median(&mut e), n)
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    #[test]
    fn tracks_a_known_gliding_pitch() {
        for (rate, base) in [(2200.0, 110.0), (2200.0, 280.0), (16_000.0, 110.0)] {
            let f0 = |t: f64| base + 60.0 * t + 5.0 * (2.0 * PI * 5.0 * t).sin();
            let x = voice(rate, 1.5, 12, f0);
            let frames = track(&x, rate, &YinParams::default()).unwrap();
            let mut e: Vec<f64> = frames
                .iter()
                .map(|f| (f.f0_hz / f0(f.time_s) - 1.0).abs())
                .collect();
            let voiced = frames.iter().filter(|f| f.voiced).count();
            let med = crate::numeric::median(&mut e);
            eprintln!(
                "{rate} Hz, {base} Hz: median error {med:.5}, {voiced} of {} voiced",
                frames.len()
            );
            assert!(med < 0.005, "{rate} Hz: median error {med}");
            let octave = e.iter().filter(|v| **v > 0.2).count();
            assert_eq!(octave, 0, "{rate} Hz, {base} Hz: {octave} octave errors");
            assert!(
                voiced * 10 >= frames.len() * 9,
                "{voiced} of {}",
                frames.len()
            );
        }
    }

    #[test]
    fn noise_is_not_voiced_and_silence_is_refused() {
        let mut r = crate::rng::Xoshiro256::new(3);
        let z = crate::rng::Ziggurat::new();
        let x: Vec<f64> = (0..16_000).map(|_| z.sample(&mut r)).collect();
        let frames = track(&x, 16_000.0, &YinParams::default()).unwrap();
        let voiced = frames.iter().filter(|f| f.voiced).count();
        eprintln!("noise: {voiced} of {} voiced", frames.len());
        assert!(
            voiced * 20 < frames.len(),
            "{voiced} of {} voiced",
            frames.len()
        );
        assert_eq!(
            track(&[0.0; 4000], 16_000.0, &YinParams::default()),
            Err(PitchError::Silent)
        );
        assert!(matches!(
            track(&x[..100], 16_000.0, &YinParams::default()),
            Err(PitchError::TooShort { .. })
        ));
        let bad = YinParams {
            fmax_hz: 1000.0,
            ..YinParams::default()
        };
        assert!(matches!(
            track(&x, 2200.0, &bad),
            Err(PitchError::Invalid { field: "fmax", .. })
        ));
    }
}
