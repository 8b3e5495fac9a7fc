//! The short-time Fourier transform shared by the calibration and the
//! pitch plots: periodic Hann windows of `nfft` samples every `hop`.

use realfft::num_complex::Complex;
use realfft::RealFftPlanner;
use std::f64::consts::PI;

/// Hann-windowed spectra of `x` (`nfft / 2 + 1` bins each), one per window
/// starting at 0, `hop`, `2·hop`, ... that fits in `x`.
pub fn stft(x: &[f64], nfft: usize, hop: usize) -> Vec<Vec<Complex<f64>>> {
    let hop = hop.max(1);
    let mut planner = RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(nfft);
    let win: Vec<f64> = (0..nfft)
        .map(|i| 0.5 - 0.5 * (2.0 * PI * i as f64 / nfft as f64).cos())
        .collect();
    let mut frames = Vec::new();
    let mut buf = fwd.make_input_vec();
    let mut s = 0;
    while s + nfft <= x.len() {
        for ((b, v), w) in buf.iter_mut().zip(&x[s..s + nfft]).zip(&win) {
            *b = v * w;
        }
        let mut spec = fwd.make_output_vec();
        let _ = fwd.process(&mut buf, &mut spec);
        frames.push(spec);
        s += hop;
    }
    frames
}
