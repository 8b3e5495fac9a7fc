//! Rolling shutter (issue 4, thesis ch. 4.5) against the forward model:
//! tones far above the frame rate heard through row timing, AR against
//! linear gap filling on speech, line-delay calibration, and bad
//! parameters rejected by name.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::*;
use rustfft::{num_complex::Complex, FftPlanner};
use std::path::Path;

/// Power spectrum (Hann window, zero-padded to a power of two >= 2·len) and bin spacing.
fn spectrum(x: &[f32], rate: f64) -> (Vec<f64>, f64) {
    let n = (2 * x.len()).next_power_of_two();
    let mean = x.iter().map(|&v| v as f64).sum::<f64>() / x.len() as f64;
    let mut buf: Vec<Complex<f64>> = (0..n)
        .map(|i| {
            if i < x.len() {
                let w = 0.5
                    - 0.5 * (2.0 * std::f64::consts::PI * i as f64 / (x.len() - 1) as f64).cos();
                Complex::new((x[i] as f64 - mean) * w, 0.0)
            } else {
                Complex::new(0.0, 0.0)
            }
        })
        .collect();
    FftPlanner::new().plan_fft_forward(n).process(&mut buf);
    (
        buf[..n / 2].iter().map(|c| c.norm_sqr()).collect(),
        rate / n as f64,
    )
}

/// Frequencies (parabolic interpolation) and powers of the `k` strongest local maxima in [lo, hi] Hz.
fn top_peaks(p: &[f64], df: f64, lo: f64, hi: f64, k: usize) -> Vec<(f64, f64)> {
    let mut peaks: Vec<(f64, f64)> = (1..p.len() - 1)
        .filter(|&i| p[i] > p[i - 1] && p[i] >= p[i + 1])
        .map(|i| {
            let (a, b, c) = (p[i - 1].ln(), p[i].ln(), p[i + 1].ln());
            let off = 0.5 * (a - c) / (a - 2.0 * b + c);
            ((i as f64 + off) * df, p[i])
        })
        .filter(|&(f, _)| f >= lo && f <= hi)
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    peaks.truncate(k);
    peaks
}

/// Median power in [lo, hi] Hz away from the listed frequencies (± `guard` Hz).
fn noise_floor(p: &[f64], df: f64, lo: f64, hi: f64, avoid: &[f64], guard: f64) -> f64 {
    let mut v: Vec<f64> = (0..p.len())
        .filter(|&i| {
            let f = i as f64 * df;
            f >= lo && f <= hi && avoid.iter().all(|a| (f - a).abs() > guard)
        })
        .map(|i| p[i])
        .collect();
    v.sort_by(f64::total_cmp);
    v[v.len() / 2]
}

fn run_ok(dir: &Path, args: &[&str]) -> String {
    let o = run_in(dir, args);
    assert_eq!(code(&o), 0, "{args:?}: {}", stderr(&o));
    stderr(&o)
}

#[test]
fn two_tones_far_above_the_frame_rate_are_heard() {
    let dir = tempfile::tempdir().unwrap();
    let d = dir.path();
    run_ok(
        d,
        &["run", "rolling-shutter", "-q", "--set", "out.path=rs.wav"],
    );
    let (rate, x) = read_wav(&d.join("rs.wav"));
    assert_eq!(rate, 62_500, "one sample per line delay");
    let (p, df) = spectrum(&x, rate as f64);
    let peaks = top_peaks(&p, df, 100.0, 5000.0, 4);
    let floor = noise_floor(&p, df, 100.0, 3000.0, &[440.0, 1200.0], 20.0);
    eprintln!("rolling shutter: peaks {peaks:?}, floor {floor:.3e}");
    for want in [440.0, 1200.0] {
        let (f, pw) = peaks
            .iter()
            .copied()
            .find(|(f, _)| (f - want).abs() <= 1.0)
            .unwrap_or_else(|| panic!("no peak within 1 Hz of {want} Hz: {peaks:?}"));
        let snr = 10.0 * (pw / floor).log10();
        eprintln!("{want} Hz: found at {f:.2} Hz, {snr:.1} dB above the noise floor");
        assert!(snr >= 20.0, "{want} Hz only {snr:.1} dB above the floor");
    }
}
