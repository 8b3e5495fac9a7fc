//! Butterworth filters as cascades of second-order sections, streaming.
//!
//! Design: analog Butterworth prototype poles, low-pass to high-pass by
//! s -> Wc / s, bilinear transform with the cutoff pre-warped so the digital
//! filter is exactly -3 dB at `cutoff_hz`; conjugate pole pairs become
//! biquads (an odd order adds one first-order section). Each section runs in
//! transposed direct form II with f64 state, so a stream can be fed in
//! blocks of any size and the output does not depend on the block split.

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
    fn bad_designs_are_errors() {
        assert!(Sos::butterworth_highpass(0, 10.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(17, 10.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(2, 50.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(2, 0.0, 100.0).is_err());
        assert!(Sos::butterworth_highpass(2, f64::NAN, 100.0).is_err());
    }
}
