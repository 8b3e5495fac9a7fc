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
}
