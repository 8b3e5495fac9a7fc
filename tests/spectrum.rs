//! Motion spectra, peaks and damping (issue 5, thesis ch. 3.3 and 5):
//! a simulated cantilever under random excitation against its known modes
//! and damping ratios, a real guitar recording against its strings, the
//! sliding (live) spectrum on the shipped pipeline, and bad input.

#![allow(clippy::unwrap_used, clippy::expect_used)]

mod common;
use common::*;
use vibroscope::analysis::peaks::{find_peaks, PeakOptions};
use vibroscope::stages::transform::spectrum::{SegmentFft, Taper};

/// Thesis Table 5.5: the cantilever beam's first three modes (Hz), with
/// damping ratios of our choosing in the 0.002-0.02 range.
const MODES_HZ: [f64; 3] = [7.3, 58.3, 128.0];
const DAMPING: [f64; 3] = [0.02, 0.01, 0.005];
/// Gains of the shared force into each mode (modal participation).
const GAINS: [f64; 3] = [0.3, 1.0, 1.0];
const FPS: f64 = 300.0;

/// SplitMix64 and Box-Muller: a seeded white Gaussian force.
struct Gauss(u64);
impl Gauss {
    fn uniform(&mut self) -> f64 {
        self.0 = self.0.wrapping_add(0x9E37_79B9_7F4A_7C15);
        let mut z = self.0;
        z = (z ^ (z >> 30)).wrapping_mul(0xBF58_476D_1CE4_E5B9);
        z = (z ^ (z >> 27)).wrapping_mul(0x94D0_49BB_1331_11EB);
        ((z ^ (z >> 31)) >> 11) as f64 / (1u64 << 53) as f64
    }
    fn next(&mut self) -> f64 {
        let u = self.uniform().max(1e-300);
        let v = self.uniform();
        (-2.0 * u.ln()).sqrt() * (2.0 * std::f64::consts::PI * v).cos()
    }
}

/// Displacement of a beam whose modes are driven by one white random force:
/// per mode a second-order section with poles r e^{±iωd/fs},
/// r = e^{-ξ ωn / fs}, ωd = ωn √(1-ξ²) (the exact discrete image of a
/// damped oscillator's poles, so its spectral peak has half width ξ fn).
fn beam_motion(seed: u64, n: usize) -> Vec<f32> {
    let mut force = Gauss(seed);
    let warm = (20.0 * FPS / (DAMPING[0] * 2.0 * std::f64::consts::PI * MODES_HZ[0])) as usize;
    let mut state = [[0.0f64; 2]; 3];
    let coef: Vec<(f64, f64)> = MODES_HZ
        .iter()
        .zip(DAMPING)
        .map(|(&f, xi)| {
            let wn = 2.0 * std::f64::consts::PI * f;
            let r = (-xi * wn / FPS).exp();
            let wd = wn * (1.0 - xi * xi).sqrt();
            (2.0 * r * (wd / FPS).cos(), -r * r)
        })
        .collect();
    let mut out = Vec::with_capacity(n);
    for i in 0..warm + n {
        let e = force.next();
        let mut y = 0.0;
        for ((s, &(a1, a2)), g) in state.iter_mut().zip(&coef).zip(GAINS) {
            let v = a1 * s[0] + a2 * s[1] + g * e;
            s[1] = s[0];
            s[0] = v;
            y += v;
        }
        if i >= warm {
            out.push(y as f32);
        }
    }
    out
}

fn write_wav(path: &std::path::Path, x: &[f32], rate: u32) {
    let spec = hound::WavSpec {
        channels: 1,
        sample_rate: rate,
        bits_per_sample: 32,
        sample_format: hound::SampleFormat::Float,
    };
    let mut w = hound::WavWriter::create(path, spec).unwrap();
    for &v in x {
        w.write_sample(v).unwrap();
    }
    w.finalize().unwrap();
}

fn welch(x: &[f32], segments: usize) -> (Vec<f64>, f64) {
    let n = ((2 * x.len()) / (segments + 1)) & !1;
    let hop = n / 2;
    let mut fft = SegmentFft::new(n, Taper::Hann, FPS);
    let mut acc = vec![0.0; fft.bins()];
    let mut k = 0;
    let mut s = 0;
    while s + n <= x.len() {
        fft.accumulate(&x[s..s + n], 1, 0, &mut acc);
        s += hop;
        k += 1;
    }
    acc.iter_mut().for_each(|p| *p /= k as f64);
    (acc, FPS / n as f64)
}

/// Scatter of the estimates over seeds on the true motion (no video):
/// `cargo test --release --test spectrum -- --ignored --nocapture`.
#[test]
#[ignore]
fn damping_scatter_over_seeds() {
    let n = (std::env::var("BEAM_S").map_or(600.0, |v| v.parse().unwrap()) * FPS) as usize;
    for seed in (1..=12u64).filter(|s| std::env::var("SEED").map_or(true, |v| v == s.to_string())) {
        let x = beam_motion(seed, n);
        let (p, df) = welch(&x, std::env::var("K").map_or(16, |v| v.parse().unwrap()));
        let peaks = find_peaks(
            &p,
            0.0,
            df,
            &PeakOptions {
                max_peaks: 3,
                ..Default::default()
            },
        );
        let row: Vec<String> = peaks
            .iter()
            .map(|p| {
                format!(
                    "{:.3} Hz xi {:.5}±{:.5} hp {:.5}±{:.5}",
                    p.frequency_hz,
                    p.damping_estimates[0].damping_ratio,
                    p.damping_estimates[0].damping_ratio_std,
                    p.damping_estimates[p.damping_estimates.len() - 1].damping_ratio,
                    p.damping_estimates[p.damping_estimates.len() - 1].damping_ratio_std
                )
            })
            .collect();
        eprintln!("seed {seed}: {}", row.join(" | "));
    }
}
