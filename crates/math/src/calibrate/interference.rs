//! Effect (e): narrowband lines not in the reference (not harmonics or
//! intermodulation products of its tones).

use super::model::{Fit, Model};
use super::report::LineUncertainty;
use super::signal::{alias, golden, stft_len, welch};
use super::{Candidate, Correction, Line, Uncertainty};
use crate::numeric::median;
use std::f64::consts::PI;

/// Frequencies of the reference's tonal peaks (at most 3): bins 10 dB
/// above the local median of its spectrum.
pub(super) fn tonal_peaks(p: &[f64], df: f64) -> Vec<f64> {
    let mut peaks: Vec<(f64, f64)> = local_prominent(p, 10.0, 8)
        .into_iter()
        .map(|k| (k as f64 * df, p[k]))
        .collect();
    peaks.sort_by(|a, b| b.1.total_cmp(&a.1));
    peaks.truncate(3);
    peaks.into_iter().map(|(f, _)| f).collect()
}

/// Local maxima at least `ratio` (power) above the median of the `half`
/// bins on each side.
pub(super) fn local_prominent(p: &[f64], ratio: f64, half: usize) -> Vec<usize> {
    let mut out = Vec::new();
    for k in 1..p.len().saturating_sub(1) {
        if !(p[k] >= p[k - 1] && p[k] > p[k + 1]) {
            continue;
        }
        // Above the median on each side (the edge of a band is not a peak).
        let (a, b) = (k.saturating_sub(half), (k + half + 1).min(p.len()));
        let mut left: Vec<f64> = p[a..k].to_vec();
        let mut right: Vec<f64> = p[k + 1..b].to_vec();
        let (ml, mr) = (median(&mut left), median(&mut right));
        if p[k] > 0.0 && p[k] >= ratio * ml && p[k] >= ratio * mr {
            out.push(k);
        }
    }
    out
}

/// Whether `f` is (within `tol`) an alias of a harmonic or an
/// intermodulation product of order <= 5 of the tones `tones`.
pub(super) fn is_product(f: f64, tones: &[f64], fs: f64, tol: f64) -> bool {
    let near = |x: f64| (alias(x, fs) - f).abs() <= tol;
    for (i, &a) in tones.iter().enumerate() {
        for h in 1..=5 {
            if near(h as f64 * a) {
                return true;
            }
        }
        for &b in &tones[i + 1..] {
            for p in 1..=4i32 {
                for q in 1..=(5 - p) {
                    let (fp, fq) = (p as f64 * a, q as f64 * b);
                    if near(fp + fq) || near((fp - fq).abs()) {
                        return true;
                    }
                }
            }
        }
    }
    false
}

pub(super) fn fit_interference(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let n = z.len();
    let nf = m.nfit(n);
    // Frames of one block (the fit part's unit).
    let nfft = stft_len(m.fs);
    let df = m.fs / nfft as f64;
    let res: Vec<f64> = m.masked(&(0..n).map(|i| z[i] - fit.g * fit.t[i]).collect::<Vec<_>>());
    let gt: Vec<f64> = m.masked(&fit.t.iter().map(|v| v * fit.g).collect::<Vec<_>>());
    let (pr, pt) = (welch(&res, nfft), welch(&gt, nfft));
    let tones = tonal_peaks(&pt, df);
    let half = 8;
    let lo_bin = m.opts.highpass.map_or(1, |(_, c)| (c / df).ceil() as usize);
    let mut cands: Vec<usize> = local_prominent(&pr, 10.0, half)
        .into_iter()
        .filter(|&k| k >= lo_bin)
        .filter(|&k| !is_product(k as f64 * df, &tones, m.fs, 2.0 * df))
        .collect();
    cands.sort_by(|&a, &b| pr[b].total_cmp(&pr[a]));
    cands.truncate(4);
    if cands.is_empty() {
        return None;
    }
    let mut lines = Vec::new();
    let mut uncertainty = Vec::new();
    let mut r = res.clone();
    for k in cands {
        let power = |f: f64| {
            let w = 2.0 * PI * f / m.fs;
            let (mut c, mut s) = (0.0, 0.0);
            for (n, v) in r.iter().enumerate() {
                c += v * (w * n as f64).cos();
                s += v * (w * n as f64).sin();
            }
            -(c * c + s * s)
        };
        let f0 = k as f64 * df;
        // A fine grid over the bin (the periodogram of the whole recording
        // has side lobes every 1/T), then golden section.
        let fine = 0.25 * m.fs / n as f64;
        let (mut fb, mut pb) = (f0, f64::INFINITY);
        let mut f = f0 - df;
        while f <= f0 + df {
            let p = power(f);
            if p < pb {
                (fb, pb) = (f, p);
            }
            f += fine;
        }
        let (f, _) = golden(power, fb - fine, fb + fine, 20);
        // Least-squares amplitude and phase.
        let w = 2.0 * PI * f / m.fs;
        let fitted = r.iter().enumerate().filter(|&(n, _)| m.is_fit(n));
        let Some((a, b)) = crate::numeric::fit_cos_sin(fitted.map(|(n, &v)| (n, v)), w) else {
            continue;
        };
        for (n, v) in r.iter_mut().enumerate() {
            if m.is_fit(n) {
                let p = w * n as f64;
                *v -= a * p.cos() + b * p.sin();
            }
        }
        lines.push(Line { freq_hz: f, a, b });
        uncertainty.push(f);
    }
    if lines.is_empty() {
        return None;
    }
    // Cramér-Rao bound on each frequency, σ² from what is left.
    let sigma2 = r.iter().map(|v| v * v).sum::<f64>() / nf as f64;
    let sd: Vec<LineUncertainty> = lines
        .iter()
        .map(|l| {
            let amp2 = l.a * l.a + l.b * l.b;
            let n3 = (nf as f64).powi(3);
            LineUncertainty {
                freq_hz: m.fs / (2.0 * PI) * (12.0 * sigma2 / (amp2 * n3)).sqrt(),
            }
        })
        .collect();
    Some(Candidate {
        correction: Correction::Interference { lines },
        uncertainty: Uncertainty::Interference { lines: sd },
    })
}
