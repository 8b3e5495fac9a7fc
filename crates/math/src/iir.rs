//! Butterworth filters as cascades of second-order sections, streaming.
//!
//! Design: analog Butterworth prototype poles, low-pass to high-pass by
//! s -> Wc / s, bilinear transform with the cutoff pre-warped so the digital
//! filter is exactly -3 dB at `cutoff_hz`; conjugate pole pairs become
//! biquads (an odd order adds one first-order section). Each section runs in
//! transposed direct form II with f64 state, so a stream can be fed in
//! blocks of any size and the output does not depend on the block split.
//!
//! Band-pass and band-stop: the low-pass prototype of order n mapped by
//! s -> (s² + W0²) / (s B) (band-pass) or s -> s B / (s² + W0²) (band-stop),
//! with both edges pre-warped (W = 2 fs tan(pi f / fs), B = W2 - W1,
//! W0² = W1 W2), so the digital filter is exactly -3 dB at both edges; each
//! prototype pole gives a pair of poles, 2n in all.
//!
//! [`ZeroPhase`] runs a cascade forward, then backward over the forward
//! output (filtfilt): zero phase at every frequency, magnitude |H|², in
//! blocks with a look-ahead long enough for the backward pass to forget
//! where it started.

use std::f64::consts::PI;

/// One biquad: b0 + b1 z^-1 + b2 z^-2 over 1 + a1 z^-1 + a2 z^-2.
#[derive(Clone, Copy, Debug, PartialEq)]
pub struct Biquad {
    pub b: [f64; 3],
    pub a: [f64; 2],
}

/// A cascade of biquads with its running state.
#[derive(Clone, Debug)]
pub struct Sos {
    sections: Vec<Biquad>,
    state: Vec<[f64; 2]>,
}

/// Why a filter cannot be designed.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum DesignError {
    #[error("order must be 1..=16, got {0}")]
    Order(usize),
    #[error("cutoff {cutoff_hz} Hz must be above 0 and below half the sample rate ({rate_hz} Hz)")]
    Cutoff { cutoff_hz: f64, rate_hz: f64 },
    #[error(
        "band {lo_hz}-{hi_hz} Hz must have 0 < low < high < half the sample rate ({rate_hz} Hz)"
    )]
    Band {
        lo_hz: f64,
        hi_hz: f64,
        rate_hz: f64,
    },
}

/// The response shape of a Butterworth design.
#[derive(Clone, Copy, Debug, PartialEq)]
pub enum Shape {
    Highpass {
        cutoff_hz: f64,
    },
    /// Passes `lo_hz..hi_hz` (-3 dB at both edges).
    Bandpass {
        lo_hz: f64,
        hi_hz: f64,
    },
    /// Stops `lo_hz..hi_hz` (-3 dB at both edges).
    Bandstop {
        lo_hz: f64,
        hi_hz: f64,
    },
}

impl Shape {
    /// The analytic magnitude |H(f)| of the `order`-th order Butterworth
    /// of this shape at `f_hz` for a stream at `rate_hz` (bilinear, pre-warped):
    /// |H|² = 1 / (1 + w^2n), w the prototype frequency of f.
    pub fn magnitude(self, order: usize, f_hz: f64, rate_hz: f64) -> f64 {
        let t = |f: f64| (PI * f / rate_hz).tan();
        let w = t(f_hz);
        let wp = match self {
            Shape::Highpass { cutoff_hz } => t(cutoff_hz) / w,
            Shape::Bandpass { lo_hz, hi_hz } => {
                let (w1, w2) = (t(lo_hz), t(hi_hz));
                (w * w - w1 * w2) / (w * (w2 - w1))
            }
            Shape::Bandstop { lo_hz, hi_hz } => {
                let (w1, w2) = (t(lo_hz), t(hi_hz));
                w * (w2 - w1) / (w1 * w2 - w * w)
            }
        };
        1.0 / (1.0 + wp.abs().powi(2 * order as i32)).sqrt()
    }
}

impl Sos {
    /// An `order`-th order Butterworth high-pass at `cutoff_hz` for a stream at `rate_hz`.
    pub fn butterworth_highpass(
        order: usize,
        cutoff_hz: f64,
        rate_hz: f64,
    ) -> Result<Self, DesignError> {
        if !(1..=16).contains(&order) {
            return Err(DesignError::Order(order));
        }
        if !(cutoff_hz.is_finite()
            && rate_hz.is_finite()
            && cutoff_hz > 0.0
            && cutoff_hz < 0.5 * rate_hz)
        {
            return Err(DesignError::Cutoff { cutoff_hz, rate_hz });
        }
        let fs2 = 2.0 * rate_hz;
        let wc = fs2 * (PI * cutoff_hz / rate_hz).tan();
        let mut sections = Vec::with_capacity(order.div_ceil(2));
        // Prototype poles p_k = exp(i pi (2k + n + 1) / 2n), upper half plane
        // first; each high-pass pole is wc / p, mapped by the bilinear transform.
        let n = order as f64;
        for k in 0..order / 2 {
            let th = PI * (2.0 * k as f64 + n + 1.0) / (2.0 * n);
            let (pr, pi) = (th.cos(), th.sin());
            // wc / p = wc * conj(p) (|p| = 1).
            let (sr, si) = (wc * pr, -wc * pi);
            // z = (fs2 + s) / (fs2 - s)
            let (nr, ni) = (fs2 + sr, si);
            let (dr, di) = (fs2 - sr, -si);
            let d2 = dr * dr + di * di;
            let (zr, zi) = ((nr * dr + ni * di) / d2, (ni * dr - nr * di) / d2);
            let a = [-2.0 * zr, zr * zr + zi * zi];
            // Zeros at z = 1 (s = 0): (1 - z^-1)^2; unit gain at Nyquist (z = -1).
            let g = (1.0 - a[0] + a[1]) / 4.0;
            sections.push(Biquad {
                b: [g, -2.0 * g, g],
                a,
            });
        }
        if order % 2 == 1 {
            // Real pole p = -1: s = -wc.
            let z = (fs2 - wc) / (fs2 + wc);
            let g = (1.0 + z) / 2.0;
            sections.push(Biquad {
                b: [g, -g, 0.0],
                a: [-z, 0.0],
            });
        }
        let state = vec![[0.0; 2]; sections.len()];
        Ok(Self { sections, state })
    }

    /// The `order`-th order Butterworth of `shape` for a stream at `rate_hz`.
    pub fn butterworth(order: usize, shape: Shape, rate_hz: f64) -> Result<Self, DesignError> {
        match shape {
            Shape::Highpass { cutoff_hz } => Self::butterworth_highpass(order, cutoff_hz, rate_hz),
            Shape::Bandpass { lo_hz, hi_hz } => Self::band(order, lo_hz, hi_hz, rate_hz, false),
            Shape::Bandstop { lo_hz, hi_hz } => Self::band(order, lo_hz, hi_hz, rate_hz, true),
        }
    }

    /// Band-pass (`stop = false`) or band-stop of prototype order `order`
    /// (2 `order` poles) between `lo_hz` and `hi_hz`.
    fn band(
        order: usize,
        lo_hz: f64,
        hi_hz: f64,
        rate_hz: f64,
        stop: bool,
    ) -> Result<Self, DesignError> {
        use realfft::num_complex::Complex;
        if !(1..=16).contains(&order) {
            return Err(DesignError::Order(order));
        }
        if !(lo_hz.is_finite()
            && hi_hz.is_finite()
            && rate_hz.is_finite()
            && lo_hz > 0.0
            && lo_hz < hi_hz
            && hi_hz < 0.5 * rate_hz)
        {
            return Err(DesignError::Band {
                lo_hz,
                hi_hz,
                rate_hz,
            });
        }
        let fs2 = 2.0 * rate_hz;
        let (w1, w2) = (
            fs2 * (PI * lo_hz / rate_hz).tan(),
            fs2 * (PI * hi_hz / rate_hz).tan(),
        );
        let (bw, w0sq) = (w2 - w1, w1 * w2);
        // Digital centre: where the analog centre W0 lands.
        let wc = 2.0 * (w0sq.sqrt() / fs2).atan();
        let zc = Complex::from_polar(1.0, -wc);
        let bilinear = |s: Complex<f64>| (fs2 + s) / (fs2 - s);
        let num = if stop {
            [1.0, -2.0 * wc.cos(), 1.0]
        } else {
            [1.0, 0.0, -1.0]
        };
        // One biquad from two digital poles (a conjugate pair, or two real ones).
        let section = |z1: Complex<f64>, z2: Complex<f64>| -> Biquad {
            let a = [-(z1 + z2).re, (z1 * z2).re];
            let h = |z: Complex<f64>| {
                (num[0] + z * num[1] + z * z * num[2]) / (1.0 + z * a[0] + z * z * a[1])
            };
            // Unit gain where the prototype's is 1: the centre (band-pass)
            // or DC (band-stop).
            let g = 1.0 / h(if stop { Complex::new(1.0, 0.0) } else { zc }).norm();
            Biquad {
                b: [g * num[0], g * num[1], g * num[2]],
                a,
            }
        };
        // Roots of s² - c s + W0² with c = p B (band-pass) or B / p (band-stop).
        let roots = |p: Complex<f64>| {
            let c = if stop { bw / p } else { p * bw };
            let d = (c * c - 4.0 * w0sq).sqrt();
            ((c + d) * 0.5, (c - d) * 0.5)
        };
        let n = order as f64;
        let mut sections = Vec::with_capacity(order);
        for k in 0..order / 2 {
            let th = PI * (2.0 * k as f64 + n + 1.0) / (2.0 * n);
            let (s1, s2) = roots(Complex::from_polar(1.0, th));
            for s in [s1, s2] {
                let z = bilinear(s);
                sections.push(section(z, z.conj()));
            }
        }
        if order % 2 == 1 {
            let (s1, s2) = roots(Complex::new(-1.0, 0.0));
            sections.push(section(bilinear(s1), bilinear(s2)));
        }
        let state = vec![[0.0; 2]; sections.len()];
        Ok(Self { sections, state })
    }

    /// Sets the state to the steady state for a constant input `u` (as if
    /// `u` had always been fed): a signal that starts away from zero
    /// starts without a step transient.
    pub fn settle(&mut self, u: f64) {
        let mut v = u;
        for (s, st) in self.sections.iter().zip(self.state.iter_mut()) {
            let den = 1.0 + s.a[0] + s.a[1];
            let y = if den.abs() > 1e-300 {
                v * (s.b[0] + s.b[1] + s.b[2]) / den
            } else {
                0.0
            };
            st[1] = s.b[2] * v - s.a[1] * y;
            st[0] = s.b[1] * v - s.a[0] * y + st[1];
            v = y;
        }
    }

    /// Samples after which the impulse response carries less than `rel` of
    /// its total absolute sum (at most `cap`).
    pub fn settling_samples(&self, rel: f64, cap: usize) -> usize {
        let mut f = self.clone();
        f.reset();
        // Slowest pole radius: |z|² = a2 for a pair, and the real roots otherwise.
        let r = self
            .sections
            .iter()
            .map(|s| {
                let disc = s.a[0] * s.a[0] - 4.0 * s.a[1];
                if disc < 0.0 {
                    s.a[1].max(0.0).sqrt()
                } else {
                    ((s.a[0].abs() + disc.sqrt()) * 0.5).min(1.0)
                }
            })
            .fold(0.0f64, f64::max);
        let span = if r < 1.0 {
            (80.0 / -r.ln()).ceil() as usize
        } else {
            cap
        };
        let len = span.clamp(16, cap.max(16));
        let mut h = Vec::with_capacity(len);
        for k in 0..len {
            h.push(f.step(if k == 0 { 1.0 } else { 0.0 }).abs());
        }
        let total: f64 = h.iter().sum();
        let mut rest = 0.0;
        for k in (0..len).rev() {
            rest += h[k];
            if rest >= rel * total {
                return (k + 1).min(cap);
            }
        }
        1
    }

    pub fn sections(&self) -> &[Biquad] {
        &self.sections
    }

    /// Filters one sample.
    #[inline]
    pub fn step(&mut self, x: f64) -> f64 {
        let mut v = x;
        for (s, st) in self.sections.iter().zip(self.state.iter_mut()) {
            let y = s.b[0] * v + st[0];
            st[0] = s.b[1] * v - s.a[0] * y + st[1];
            st[1] = s.b[2] * v - s.a[1] * y;
            v = y;
        }
        v
    }

    /// Magnitude response at `f_hz` for a stream at `rate_hz`.
    pub fn gain_at(&self, f_hz: f64, rate_hz: f64) -> f64 {
        self.response_at(f_hz, rate_hz).norm()
    }

    /// Complex response at `f_hz` for a stream at `rate_hz`.
    pub fn response_at(&self, f_hz: f64, rate_hz: f64) -> realfft::num_complex::Complex<f64> {
        cascade_response(self.sections.iter().map(|s| (s.b, s.a)), f_hz, rate_hz)
    }

    /// Forgets the past (zero state).
    pub fn reset(&mut self) {
        self.state.iter_mut().for_each(|s| *s = [0.0; 2]);
    }
}

/// Complex response at `f_hz` (stream at `rate_hz`) of a cascade of
/// biquads given as `(b, a)`: `b0 + b1 z⁻¹ + b2 z⁻²` over `1 + a1 z⁻¹ + a2 z⁻²`.
pub fn cascade_response(
    sections: impl Iterator<Item = ([f64; 3], [f64; 2])>,
    f_hz: f64,
    rate_hz: f64,
) -> realfft::num_complex::Complex<f64> {
    use realfft::num_complex::Complex;
    let w = 2.0 * PI * f_hz / rate_hz;
    let (z1, z2) = (
        Complex::from_polar(1.0, -w),
        Complex::from_polar(1.0, -2.0 * w),
    );
    sections
        .map(|(b, a)| (b[0] + z1 * b[1] + z2 * b[2]) / (1.0 + z1 * a[0] + z2 * a[1]))
        .product()
}

/// Forward-backward (zero-phase) filtering of a stream, in blocks.
///
/// The forward pass runs as the samples arrive. The backward pass needs
/// the future: it runs over everything not yet released, from its end,
/// and releases all but the last [`ZeroPhase::tail`] samples, whose
/// backward values still depend on samples to come. `tail` is where the
/// impulse response has given all but 1e-9 of its absolute sum, so a
/// released sample differs from the whole-signal filtfilt by at most 1e-9
/// of the signal's peak. The result has zero phase and magnitude |H|²;
/// samples are held back by up to `tail + chunk` (the price of looking
/// ahead, acceptable on replay, not live). The first sample primes the
/// forward state and the last one the backward state ([`Sos::settle`]),
/// so a signal away from zero at either end starts and ends without a
/// step transient.
#[derive(Clone, Debug)]
pub struct ZeroPhase {
    fwd: Sos,
    bwd: Sos,
    tail: usize,
    chunk: usize,
    primed: bool,
    pending: Vec<f64>,
    back: Vec<f64>,
}

/// Longest look-ahead a [`ZeroPhase`] keeps, in samples.
pub const ZERO_PHASE_MAX_TAIL: usize = 1 << 22;

impl ZeroPhase {
    pub fn new(sos: Sos) -> Self {
        let tail = sos.settling_samples(1e-9, ZERO_PHASE_MAX_TAIL);
        let chunk = tail.max(1024);
        let mut fwd = sos.clone();
        fwd.reset();
        Self {
            bwd: fwd.clone(),
            fwd,
            tail,
            chunk,
            primed: false,
            pending: Vec::with_capacity(2 * (tail + chunk)),
            back: Vec::with_capacity(2 * (tail + chunk)),
        }
    }

    /// Samples of look-ahead the backward pass needs.
    pub fn tail(&self) -> usize {
        self.tail
    }

    /// The most samples held back before release (`tail + chunk`).
    pub fn max_held(&self) -> usize {
        self.tail + self.chunk
    }

    /// Runs the forward pass over `x`.
    pub fn push(&mut self, x: &[f32]) {
        if let (false, Some(&x0)) = (self.primed, x.first()) {
            self.fwd.settle(f64::from(x0));
            self.primed = true;
        }
        let f = &mut self.fwd;
        self.pending.extend(x.iter().map(|&v| f.step(f64::from(v))));
    }

    /// Samples that can be released now (0 until `tail + chunk` are held).
    pub fn ready(&self) -> usize {
        if self.pending.len() >= self.tail + self.chunk {
            self.pending.len() - self.tail
        } else {
            0
        }
    }

    /// Samples pushed and not yet released.
    pub fn held(&self) -> usize {
        self.pending.len()
    }

    /// Releases the first `n` held samples (`n <= ready()`, or all at the
    /// end of the stream with `end`), appending them to `out`.
    pub fn release(&mut self, n: usize, end: bool, out: &mut Vec<f32>) {
        let n = n.min(self.pending.len());
        if n == 0 {
            return;
        }
        self.bwd.reset();
        if let (true, Some(&last)) = (end, self.pending.last()) {
            self.bwd.settle(last);
        }
        self.back.clear();
        let b = &mut self.bwd;
        self.back
            .extend(self.pending.iter().rev().map(|&v| b.step(v)));
        let m = self.back.len();
        out.extend((0..n).map(|i| self.back[m - 1 - i] as f32));
        self.pending.drain(..n);
    }
}

/// The default high-pass cutoff for a stream at `rate_hz`: 1/40 of the
/// rate, within 20-100 Hz, and never above a quarter of the rate.
pub fn default_highpass_cutoff_hz(rate_hz: f64) -> f64 {
    (rate_hz / 40.0).clamp(20.0, 100.0).min(rate_hz / 4.0)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn tone_gain(order: usize, fc: f64, fs: f64, f: f64) -> f64 {
        let mut h = Sos::butterworth_highpass(order, fc, fs).unwrap();
        let n = (fs * 4.0) as usize;
        let mut acc_in = 0.0;
        let mut acc_out = 0.0;
        for i in 0..n {
            let x = (2.0 * PI * f * i as f64 / fs).sin();
            let y = h.step(x);
            if i > n / 2 {
                acc_in += x * x;
                acc_out += y * y;
            }
        }
        (acc_out / acc_in).sqrt()
    }

    #[test]
    fn butterworth_magnitude_matches_the_analytic_response() {
        // |H(f)|^2 = 1 / (1 + (tan(pi fc/fs) / tan(pi f/fs))^(2n)) after pre-warping.
        for &(order, fc, fs) in &[
            (1, 50.0, 2200.0),
            (2, 55.0, 2200.0),
            (4, 20.0, 600.0),
            (5, 100.0, 8000.0),
        ] {
            let h = Sos::butterworth_highpass(order, fc, fs).unwrap();
            for &f in &[fc / 4.0, fc / 2.0, fc, 2.0 * fc, 5.0 * fc, 0.45 * fs] {
                let r = (PI * fc / fs).tan() / (PI * f / fs).tan();
                let want = 1.0 / (1.0 + r.powi(2 * order as i32)).sqrt();
                let got = h.gain_at(f, fs);
                assert!(
                    (got - want).abs() < 1e-9 * want.max(1e-6) + 1e-12,
                    "order {order} fc {fc} f {f}: {got} vs {want}"
                );
            }
            assert!((h.gain_at(fc, fs) - 0.5f64.sqrt()).abs() < 1e-9);
        }
    }

    #[test]
    fn time_domain_tones_pass_and_stop() {
        let g_pass = tone_gain(4, 55.0, 2200.0, 440.0);
        let g_stop = tone_gain(4, 55.0, 2200.0, 10.0);
        assert!((g_pass - 1.0).abs() < 0.01, "{g_pass}");
        assert!(g_stop < 1e-2, "{g_stop}");
    }

    #[test]
    fn block_split_does_not_change_output() {
        let x: Vec<f64> = (0..1000)
            .map(|i| ((i * 37 % 101) as f64 - 50.0) / 50.0)
            .collect();
        let mut a = Sos::butterworth_highpass(3, 30.0, 1000.0).unwrap();
        let whole: Vec<f64> = x.iter().map(|&v| a.step(v)).collect();
        let mut b = Sos::butterworth_highpass(3, 30.0, 1000.0).unwrap();
        let mut parts = Vec::new();
        for chunk in x.chunks(17) {
            parts.extend(chunk.iter().map(|&v| b.step(v)));
        }
        assert_eq!(whole, parts);
    }

    #[test]
    fn band_designs_match_the_analytic_butterworth_magnitude() {
        for &(order, lo, hi, fs) in &[
            (1, 60.0, 120.0, 600.0),
            (2, 70.0, 95.0, 600.0),
            (4, 300.0, 500.0, 2200.0),
            (3, 10.0, 1000.0, 8000.0),
        ] {
            for shape in [
                Shape::Bandpass {
                    lo_hz: lo,
                    hi_hz: hi,
                },
                Shape::Bandstop {
                    lo_hz: lo,
                    hi_hz: hi,
                },
            ] {
                let h = Sos::butterworth(order, shape, fs).unwrap();
                assert_eq!(h.sections().len(), order);
                for i in 1..200 {
                    let f = 0.5 * fs * i as f64 / 200.0;
                    let want = shape.magnitude(order, f, fs);
                    let got = h.gain_at(f, fs);
                    assert!(
                        (got - want).abs() < 1e-9 * want.max(1e-6) + 1e-12,
                        "{shape:?} order {order} f {f}: {got} vs {want}"
                    );
                }
                for f in [lo, hi] {
                    let g = h.gain_at(f, fs);
                    assert!((g - 0.5f64.sqrt()).abs() < 1e-9, "{shape:?} at {f}: {g}");
                }
            }
        }
    }

    /// Gain and phase (degrees) of `y` against the unit sine at `f` over
    /// the middle half.
    fn fit(y: &[f32], f: f64, fs: f64) -> (f64, f64) {
        let (g, ph) = crate::numeric::fit_tone(y, f, fs, y.len() / 4..3 * y.len() / 4);
        (g, ph.to_degrees())
    }

    fn zero_phase(sos: &Sos, x: &[f32], block: usize) -> Vec<f32> {
        let mut z = ZeroPhase::new(sos.clone());
        let mut out = Vec::new();
        for c in x.chunks(block) {
            z.push(c);
            let n = z.ready();
            z.release(n, false, &mut out);
        }
        let n = z.held();
        z.release(n, true, &mut out);
        out
    }

    /// Forward-backward filtering of tones, fed in blocks: the output has
    /// the input's phase (within 1 degree in the pass band, where it is
    /// measurable to far better) and the squared analytic magnitude
    /// (within 0.1 dB wherever it is above -120 dB).
    #[test]
    fn zero_phase_tones_keep_their_phase_and_get_the_squared_magnitude() {
        let fs = 2200.0;
        for (order, shape) in [
            (4, Shape::Highpass { cutoff_hz: 55.0 }),
            (
                2,
                Shape::Bandpass {
                    lo_hz: 300.0,
                    hi_hz: 500.0,
                },
            ),
            (
                3,
                Shape::Bandstop {
                    lo_hz: 80.0,
                    hi_hz: 160.0,
                },
            ),
        ] {
            let sos = Sos::butterworth(order, shape, fs).unwrap();
            for f in [
                20.0, 40.0, 55.0, 90.0, 120.0, 200.0, 300.0, 400.0, 500.0, 700.0, 1000.0,
            ] {
                let x: Vec<f32> = (0..22000)
                    .map(|n| (2.0 * PI * f * n as f64 / fs).sin() as f32)
                    .collect();
                let y = zero_phase(&sos, &x, 37);
                assert_eq!(y.len(), x.len());
                let want = shape.magnitude(order, f, fs).powi(2);
                let (g, ph) = fit(&y, f, fs);
                if want > 1e-6 {
                    let db = 20.0 * (g / want).log10();
                    assert!(db.abs() < 0.1, "{shape:?} {f} Hz: {db:.4} dB off |H|²");
                }
                if want > 0.5 {
                    assert!(ph.abs() < 1.0, "{shape:?} {f} Hz: phase {ph:.4} deg");
                }
            }
        }
    }

    /// Released in blocks of any size, the output equals one forward-backward
    /// pass over the whole signal (to 1e-7 of its peak), and the
    /// cross-correlation of a broadband signal with its filtered version peaks
    /// at lag 0 (the causal filter's peak lags).
    #[test]
    fn zero_phase_blocks_match_the_whole_signal_and_align_at_lag_0() {
        let fs = 600.0;
        let sos = Sos::butterworth_highpass(4, 20.0, fs).unwrap();
        let mut seed = 7u64;
        let x: Vec<f32> = (0..6000)
            .map(|_| {
                seed = seed
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((seed >> 33) as f64 / (1u64 << 31) as f64 - 1.0) as f32
            })
            .collect();
        let whole = zero_phase(&sos, &x, x.len());
        for block in [1, 16, 333, 5000] {
            let y = zero_phase(&sos, &x, block);
            let err = y
                .iter()
                .zip(&whole)
                .map(|(a, b)| (a - b).abs())
                .fold(0.0f32, f32::max);
            assert!(err < 1e-6, "block {block}: max difference {err}");
        }
        let xcorr_peak = |y: &[f32]| {
            (-20i64..=20)
                .max_by(|&a, &b| {
                    let c = |l: i64| -> f64 {
                        (100..x.len() - 100)
                            .map(|n| f64::from(x[n]) * f64::from(y[(n as i64 + l) as usize]))
                            .sum()
                    };
                    c(a).total_cmp(&c(b))
                })
                .unwrap_or(0)
        };
        assert_eq!(xcorr_peak(&whole), 0, "zero-phase output is not aligned");
        let mut causal = sos.clone();
        let c: Vec<f32> = x
            .iter()
            .map(|&v| causal.step(f64::from(v)) as f32)
            .collect();
        let lag = xcorr_peak(&c);
        eprintln!("cross-correlation peak: zero-phase lag 0, causal lag {lag}");
    }

    #[test]
    fn bad_designs_are_errors() {
        assert!(Sos::butterworth_highpass(0, 10.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(17, 10.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(2, 50.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(2, 0.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(2, f64::NAN, 100.0).is_err());
        let band = |lo, hi| Shape::Bandpass {
            lo_hz: lo,
            hi_hz: hi,
        };
        assert!(Sos::butterworth(2, band(30.0, 20.0), 100.0).is_err());
        assert!(Sos::butterworth(2, band(20.0, 50.0), 100.0).is_err());
        assert!(Sos::butterworth(2, band(0.0, 20.0), 100.0).is_err());
        assert!(Sos::butterworth(0, band(10.0, 20.0), 100.0).is_err());
    }
}
