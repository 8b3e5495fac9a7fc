//! Exposure: each rolling-shutter row averages the motion over its
//! exposure E (thesis ch. 4.5), a boxcar whose response
//! |H(f)| = |sin(π f E) / (π f E)| falls to its first null at 1/E and
//! delays by E/2. Two linear-phase FIR filters undo what can be undone:
//!
//! - [`Mode::Lowpass`]: pass below the first null 1/E, stop above (beyond
//!   it the boxcar leaves mostly noise and inverted-sign side lobes);
//! - [`Mode::Compensate`]: the inverse 1/|H(f)| wherever the boxcar's gain
//!   is above `floor_db` (-12 dB by default, so at most 4x boost), zero
//!   above that frequency.
//!
//! Filters are designed by sampling the desired zero-phase response on a
//! fine grid, integrating to the impulse response and applying a Blackman
//! window. [`Fir`] and [`CubicResampler`] stream with state kept across
//! blocks and allocate nothing per sample.

use std::f64::consts::PI;

/// Which response the exposure filter has.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Deserialize, serde::Serialize)]
#[serde(rename_all = "lowercase")]
pub enum Mode {
    Lowpass,
    Compensate,
}

/// |sin(π f E) / (π f E)|, the boxcar's gain at `f_hz`.
pub fn boxcar_gain(f_hz: f64, exposure_s: f64) -> f64 {
    let x = PI * f_hz * exposure_s;
    if x.abs() < 1e-12 {
        1.0
    } else {
        (x.sin() / x).abs()
    }
}

/// The frequency below the first null where the boxcar's gain falls to
/// `floor_db` (negative dB), by bisection on the monotone main lobe.
pub fn gain_floor_hz(exposure_s: f64, floor_db: f64) -> f64 {
    let target = 10f64.powf(floor_db / 20.0);
    let (mut lo, mut hi) = (0.0, 1.0 / exposure_s);
    for _ in 0..100 {
        let mid = 0.5 * (lo + hi);
        if boxcar_gain(mid, exposure_s) > target {
            lo = mid;
        } else {
            hi = mid;
        }
    }
    lo
}

/// Odd FIR length used for exposure `exposure_s` at `rate_hz`: about eight
/// exposures long (transition about a quarter of 1/E wide), 31..=1023 taps.
pub fn default_taps(exposure_s: f64, rate_hz: f64) -> usize {
    let n = (8.0 * exposure_s * rate_hz).round() as usize;
    (n.clamp(31, 1023)) | 1
}

/// The exposure filter's taps (odd length, delay (len - 1) / 2 samples).
pub fn design(mode: Mode, exposure_s: f64, rate_hz: f64, taps: usize, floor_db: f64) -> Vec<f64> {
    let taps = taps | 1;
    let nyq = 0.5 * rate_hz;
    let (cut, compensate) = match mode {
        Mode::Lowpass => ((1.0 / exposure_s).min(nyq), false),
        Mode::Compensate => (gain_floor_hz(exposure_s, floor_db).min(nyq), true),
    };
    let desired = |f: f64| {
        if f >= cut {
            0.0
        } else if compensate {
            1.0 / boxcar_gain(f, exposure_s)
        } else {
            1.0
        }
    };
    // Frequency sampling: D on an FFT grid much finer than the filter
    // (N >= 16 taps), one inverse real FFT, then the central taps (the
    // zero-phase impulse response, circularly centred on 0).
    let n_fft = (16 * taps).next_power_of_two().max(4096);
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let inv = planner.plan_fft_inverse(n_fft);
    let mut spec: Vec<realfft::num_complex::Complex<f64>> = (0..=n_fft / 2)
        .map(|k| {
            realfft::num_complex::Complex::new(desired(k as f64 * rate_hz / n_fft as f64), 0.0)
        })
        .collect();
    let mut circ = vec![0.0; n_fft];
    if inv.process(&mut spec, &mut circ).is_err() {
        return vec![0.0; taps];
    }
    let c = taps / 2;
    let mut h: Vec<f64> = (0..taps)
        .map(|i| circ[(i + n_fft - c) % n_fft] / n_fft as f64)
        .collect();
    // Blackman window.
    let m = (taps - 1).max(1) as f64;
    for (n, v) in h.iter_mut().enumerate() {
        let x = n as f64 / m;
        *v *= 0.42 - 0.5 * (2.0 * PI * x).cos() + 0.08 * (4.0 * PI * x).cos();
    }
    // Unit gain at DC (D(0) = 1 in both modes).
    let dc: f64 = h.iter().sum();
    if dc.abs() > 1e-12 {
        h.iter_mut().for_each(|v| *v /= dc);
    }
    h
}

/// Magnitude response of FIR taps at `f_hz`.
pub fn fir_gain(taps: &[f64], f_hz: f64, rate_hz: f64) -> f64 {
    let w = 2.0 * PI * f_hz / rate_hz;
    let (mut re, mut im) = (0.0, 0.0);
    for (n, t) in taps.iter().enumerate() {
        re += t * (w * n as f64).cos();
        im -= t * (w * n as f64).sin();
    }
    (re * re + im * im).sqrt()
}

/// A streaming FIR filter (direct form, doubled ring buffer so every dot
/// product reads one contiguous slice).
pub struct Fir {
    taps: Vec<f64>,
    buf: Vec<f64>,
    pos: usize,
}

impl Fir {
    pub fn new(taps: Vec<f64>) -> Self {
        let n = taps.len().max(1);
        // Reversed, so the newest sample meets taps[0].
        let mut rev = taps;
        rev.reverse();
        Self {
            taps: rev,
            buf: vec![0.0; 2 * n],
            pos: 0,
        }
    }

    /// Delay in samples of the (symmetric) filter.
    pub fn delay(&self) -> usize {
        self.taps.len() / 2
    }

    pub fn reset(&mut self) {
        self.buf.iter_mut().for_each(|v| *v = 0.0);
        self.pos = 0;
    }

    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        let n = self.taps.len();
        self.buf[self.pos] = x;
        self.buf[self.pos + n] = x;
        self.pos = (self.pos + 1) % n;
        // buf[pos..pos + n] holds the last n samples, oldest first.
        self.buf[self.pos..self.pos + n]
            .iter()
            .zip(&self.taps)
            .map(|(a, b)| a * b)
            .sum()
    }
}

/// Streaming resampler by 4-point cubic (Catmull-Rom) interpolation: for
/// signals already band-limited well below both rates (here, after the
/// exposure filter: under 1/E, a small fraction of 1/d).
pub struct CubicResampler {
    ratio: f64,
    last: [f64; 4],
    /// Input samples seen.
    n_in: u64,
    /// Output samples produced.
    n_out: u64,
}

impl CubicResampler {
    pub fn new(rate_in: f64, rate_out: f64) -> Self {
        Self {
            ratio: rate_in / rate_out,
            last: [0.0; 4],
            n_in: 0,
            n_out: 0,
        }
    }

    pub fn reset(&mut self) {
        self.last = [0.0; 4];
        self.n_in = 0;
        self.n_out = 0;
    }

    /// Feeds one input sample; pushes the outputs that became computable.
    /// Output j is at input position j·ratio (output 0 at input 0).
    pub fn push(&mut self, x: f64, out: &mut Vec<f32>) {
        self.last = [self.last[1], self.last[2], self.last[3], x];
        self.n_in += 1;
        loop {
            let u = self.n_out as f64 * self.ratio;
            let i = u.floor();
            // Needs x[i-1..=i+2]; the newest input is n_in - 1. Each push
            // makes computable only outputs with i + 2 == n_in - 1, so
            // `last` is exactly that window (x[-1] reads as 0).
            if i as u64 + 2 > self.n_in - 1 {
                break;
            }
            let t = u - i;
            // last[3] is input n_in - 1 = i + 2, so last[0..4] = x[i-1..=i+2].
            let [p0, p1, p2, p3] = self.last;
            let v = p1
                + 0.5
                    * t
                    * (p2 - p0
                        + t * (2.0 * p0 - 5.0 * p1 + 4.0 * p2 - p3
                            + t * (3.0 * (p1 - p2) + p3 - p0)));
            out.push(v as f32);
            self.n_out += 1;
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn lowpass_passes_below_and_stops_above_the_null() {
        let (e, fs) = (1.0 / 2000.0, 62_500.0);
        let h = design(Mode::Lowpass, e, fs, default_taps(e, fs), -12.0);
        assert!((fir_gain(&h, 440.0, fs) - 1.0).abs() < 0.01);
        assert!((fir_gain(&h, 1200.0, fs) - 1.0).abs() < 0.02);
        assert!(fir_gain(&h, 4000.0, fs) < 0.01);
    }

    #[test]
    fn compensation_inverts_the_boxcar_where_it_is_above_the_floor() {
        let (e, fs) = (1.0 / 2000.0, 62_500.0);
        let f12 = gain_floor_hz(e, -12.0);
        assert!((boxcar_gain(f12, e) - 0.2512).abs() < 1e-3, "{f12}");
        let h = design(Mode::Compensate, e, fs, default_taps(e, fs), -12.0);
        for f in [300.0, 800.0, 1200.0] {
            let total = fir_gain(&h, f, fs) * boxcar_gain(f, e);
            assert!((total - 1.0).abs() < 0.03, "{f} Hz: {total}");
        }
        assert!(fir_gain(&h, 2.0 / e, fs) < 0.05);
    }

    #[test]
    fn cubic_resampler_follows_a_slow_sine() {
        let (fin, fout, f) = (62_500.0, 16_000.0, 700.0);
        let mut r = CubicResampler::new(fin, fout);
        let mut out = Vec::new();
        for n in 0..6250 {
            r.push((2.0 * PI * f * n as f64 / fin).sin(), &mut out);
        }
        assert!((out.len() as i64 - 1600).abs() <= 2, "{}", out.len());
        for (j, v) in out.iter().enumerate().skip(2) {
            let want = (2.0 * PI * f * j as f64 / fout).sin();
            assert!((*v as f64 - want).abs() < 1e-3, "{j}: {v} vs {want}");
        }
    }
}
