//! The amplitude spectrum of a motion: per channel the mean removed, a
//! Hann window, a real FFT; scaled so that a sinusoid of amplitude A at a
//! bin's frequency reads A (|X_k| · 2 / Σw); channels (x and y of one
//! region) added in quadrature, so a motion along any direction reads its
//! amplitude along that direction.

use realfft::RealFftPlanner;

/// The amplitude spectrum of `channels` (equal lengths, at `rate_hz`):
/// bins `k · df` for k = 0..=n/2, and df. Empty for fewer than 2 samples.
pub fn amplitude_spectrum(channels: &[&[f32]], rate_hz: f64) -> (Vec<f64>, f64) {
    let n = channels.iter().map(|c| c.len()).min().unwrap_or(0);
    if n < 2 || rate_hz.is_nan() || rate_hz <= 0.0 {
        return (Vec::new(), f64::NAN);
    }
    let w: Vec<f64> = (0..n)
        .map(|i| 0.5 - 0.5 * (std::f64::consts::TAU * i as f64 / n as f64).cos())
        .collect();
    let gain = 2.0 / w.iter().sum::<f64>();
    let fft = RealFftPlanner::<f64>::new().plan_fft_forward(n);
    let mut input = fft.make_input_vec();
    let mut spec = fft.make_output_vec();
    let mut power = vec![0.0; n / 2 + 1];
    for c in channels {
        let c = &c[..n];
        let mean = c.iter().map(|&v| f64::from(v)).sum::<f64>() / n as f64;
        for ((x, &v), &wi) in input.iter_mut().zip(c).zip(&w) {
            *x = (f64::from(v) - mean) * wi;
        }
        if fft.process(&mut input, &mut spec).is_err() {
            return (Vec::new(), f64::NAN);
        }
        for (p, s) in power.iter_mut().zip(&spec) {
            *p += (s.norm() * gain).powi(2);
        }
    }
    (
        power.into_iter().map(f64::sqrt).collect(),
        rate_hz / n as f64,
    )
}

/// The `order`-th time derivative (0, 1 or 2) of `x` sampled at
/// `rate_hz`, by the frequency domain (each bin times (jω)^order): the
/// straight line through `x` (least squares) is taken out first and its
/// slope put back, and the rest is extended by its mirror image so that
/// the record has no jump where the FFT joins its ends. Exact to rounding
/// on a band-limited signal away from the record's ends; within a few
/// periods of the lowest frequency of each end the mirror makes the
/// derivative lean toward zero.
pub fn time_derivative(x: &[f64], rate_hz: f64, order: u32) -> Vec<f64> {
    let n = x.len();
    if order == 0 || n < 2 || rate_hz.is_nan() || rate_hz <= 0.0 {
        return x.to_vec();
    }
    // The line a + b·i through the samples.
    let nf = n as f64;
    let mi = (nf - 1.0) / 2.0;
    let mx = x.iter().sum::<f64>() / nf;
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (i, &v) in x.iter().enumerate() {
        let di = i as f64 - mi;
        sxy += di * (v - mx);
        sxx += di * di;
    }
    let b = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    let m = 2 * n;
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(m);
    let inv = planner.plan_fft_inverse(m);
    let mut buf = fwd.make_input_vec();
    for (i, &v) in x.iter().enumerate() {
        let r = v - mx - b * (i as f64 - mi);
        buf[i] = r;
        buf[m - 1 - i] = r;
    }
    let mut spec = fwd.make_output_vec();
    if fwd.process(&mut buf, &mut spec).is_err() {
        return vec![f64::NAN; n];
    }
    let last = spec.len() - 1;
    for (k, s) in spec.iter_mut().enumerate() {
        let w = std::f64::consts::TAU * rate_hz * k as f64 / m as f64;
        let jw = realfft::num_complex::Complex::new(0.0, w);
        // The Nyquist bin of a real signal has no sign for odd orders.
        *s = if k == last && order % 2 == 1 {
            realfft::num_complex::Complex::new(0.0, 0.0)
        } else {
            *s * jw.powu(order)
        };
    }
    spec[0] = realfft::num_complex::Complex::new(0.0, 0.0);
    if inv.process(&mut spec, &mut buf).is_err() {
        return vec![f64::NAN; n];
    }
    let slope = if order == 1 { b * rate_hz } else { 0.0 };
    buf[..n].iter().map(|v| v / m as f64 + slope).collect()
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_tone_reads_its_amplitude() {
        let (n, rate) = (1000, 1000.0);
        let tone = |a: f64, ph: f64| -> Vec<f32> {
            (0..n)
                .map(|i| {
                    (a * (std::f64::consts::TAU * 120.0 * i as f64 / rate + ph).sin() + 3.0) as f32
                })
                .collect()
        };
        // 0.3 along a direction 30° from x: 0.3 cos 30° in x, 0.3 sin 30° in y.
        let (x, y) = (tone(0.3 * 0.866_025_4, 0.2), tone(0.3 * 0.5, 0.2));
        let (a, df) = amplitude_spectrum(&[&x, &y], rate);
        assert_eq!(df, 1.0);
        assert!((a[120] - 0.3).abs() < 1e-6, "{}", a[120]);
        assert!(a[0] < 1e-9 && a[300] < 1e-9);
    }

    #[test]
    fn derivatives_of_a_tone_and_a_ramp() {
        let (n, rate, f) = (2200, 2200.0, 123.4);
        let w = std::f64::consts::TAU * f;
        let t = |i: usize| i as f64 / rate;
        let x: Vec<f64> = (0..n)
            .map(|i| 0.2 * (w * t(i) + 0.3).sin() + 5.0 * t(i) + 1.0)
            .collect();
        let v = time_derivative(&x, rate, 1);
        let a = time_derivative(&x, rate, 2);
        // Away from the ends (the mirror's reach), to rounding.
        let (mut ev, mut ea) = (0.0f64, 0.0f64);
        for i in n / 10..n - n / 10 {
            ev = ev.max((v[i] - (0.2 * w * (w * t(i) + 0.3).cos() + 5.0)).abs());
            ea = ea.max((a[i] + 0.2 * w * w * (w * t(i) + 0.3).sin()).abs());
        }
        assert!(ev < 1e-4 * 0.2 * w, "velocity off by {ev}");
        assert!(ea < 1e-4 * 0.2 * w * w, "acceleration off by {ea}");
        assert_eq!(time_derivative(&x, rate, 0), x);
    }
}
