//! Effect (a): the object's transfer function (thesis ch. 4.3.3).

use super::model::{eq_sse, Fit, Model};
use super::signal::{curvature_sigma, golden, stft, stft_len};
use super::{Candidate, Correction, Uncertainty};
use realfft::num_complex::Complex;

/// Transfer coefficients (thesis ch. 4.3.3): per STFT bin, the average of
/// the recovery's magnitude over time weighted by the reference's short-
/// time power, over the same average of the reference's magnitude; in dB
/// relative to the linear gain, smoothed over three bins; bins where the
/// reference has little energy are left out (coefficient 1, 0 dB). Also
/// the phase of the response: the angle of the cross-spectrum (recovery
/// times the conjugate reference, sign of the gain removed) summed over the
/// same frames, smoothed over three bins. The thesis' coefficients are
/// magnitudes; without the phase, a resonance leaves a lag that changes
/// with frequency, which other effects then try to explain.
pub(super) fn transfer_coefficients(
    m: &Model,
    z: &[f64],
    fit: &Fit,
) -> (Vec<f64>, Vec<f64>, Vec<f64>) {
    let nfft = stft_len(m.fs);
    let (fz, ft) = (stft(z, nfft), stft(&fit.t, nfft));
    let nb = nfft / 2 + 1;
    let (mut num, mut den, mut wsum) = (vec![0.0; nb], vec![0.0; nb], vec![0.0; nb]);
    let mut cross = vec![Complex::new(0.0, 0.0); nb];
    for (i, (a, b)) in fz.iter().zip(&ft).enumerate() {
        // Frames centred in the fit part.
        if !m.is_fit(i * nfft / 2 + nfft / 2) {
            continue;
        }
        for k in 0..nb {
            let px = b[k].norm_sqr();
            num[k] += a[k].norm() * px;
            den[k] += b[k].norm() * px;
            wsum[k] += px;
            cross[k] += a[k] * b[k].conj() * fit.g.signum();
        }
    }
    let wmax = wsum.iter().cloned().fold(0.0, f64::max);
    let lo = m.opts.highpass.map_or(0.0, |(_, c)| 1.5 * c);
    let g = fit.g.abs().max(1e-300);
    let valid: Vec<usize> = (1..nb)
        .filter(|&k| wsum[k] > 1e-3 * wmax && den[k] > 0.0 && k as f64 * m.fs / nfft as f64 >= lo)
        .collect();
    let raw: Vec<f64> = valid
        .iter()
        .map(|&k| 20.0 * (num[k] / den[k] / g).max(1e-12).log10())
        .collect();
    let smooth: Vec<f64> = (0..raw.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 2).min(raw.len()));
            raw[a..b].iter().sum::<f64>() / (b - a) as f64
        })
        .collect();
    let phase: Vec<f64> = (0..valid.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 2).min(valid.len()));
            let c: Complex<f64> = valid[a..b]
                .iter()
                .map(|&k| cross[k] / cross[k].norm().max(1e-300))
                .sum();
            c.arg().to_degrees()
        })
        .collect();
    let freqs = valid
        .iter()
        .map(|&k| k as f64 * m.fs / nfft as f64)
        .collect();
    (freqs, smooth, phase)
}

pub(super) fn fit_transfer(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let (freqs, coef, phase) = transfer_coefficients(m, z, fit);
    if freqs.len() < 3 {
        return None;
    }
    let corr = |k: f64| Correction::Transfer {
        freqs_hz: freqs.clone(),
        coef_db: coef.clone(),
        phase_deg: phase.clone(),
        k,
    };
    let grid: Vec<(f64, f64)> = (0..=12)
        .map(|i| {
            let k = i as f64 * 0.25;
            (k, eq_sse(m, z, fit, &corr(k)))
        })
        .collect();
    let (bi, _) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    let (lo, hi) = (grid[bi].0 - 0.25, grid[bi].0 + 0.25);
    let (k, sse) = golden(|k| eq_sse(m, z, fit, &corr(k)), lo.max(0.0), hi, 16);
    let nf = m.nfit(z.len());
    let sd = curvature_sigma(|k| eq_sse(m, z, fit, &corr(k)), k, 0.02, sse / nf as f64);
    Some(Candidate {
        correction: corr(k),
        uncertainty: Uncertainty::Transfer { k: sd },
    })
}
