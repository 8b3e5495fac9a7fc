//! Damped sinusoids measured in the time domain (issue 51, items 2-3).
//!
//! - [`fit_damped_sinusoid`]: a mode with few cycles in the record (a
//!   crane's 0.2 Hz sway filmed for ten seconds). Its spectral peak sits a
//!   few bins from zero, where the bins, not the line, set the precision;
//!   a least-squares fit of `c0 + c1 t + e^(-σt) (a cos ωt + b sin ωt)` to
//!   the samples themselves resolves it to the noise's limit. The signal is
//!   first low-passed and decimated to about sixteen samples a cycle, so
//!   what the fit leaves is the noise near the mode, not the other modes;
//!   uncertainties come from the residual (s² (JᵀJ)⁻¹), widened by the
//!   residual's own correlation (an effective sample count).
//! - [`fit_free_decay`]: a struck object's ring-down. The mode is
//!   demodulated to its complex envelope (multiplied by e^(-iωt), then
//!   low-passed below the distance to the next line); the envelope's
//!   logarithm, from its maximum down to the noise, falls on a line of
//!   slope -σ, and ζ = σ/ω (the logarithmic decrement, measured over every
//!   cycle at once). A record whose envelope does not fall (a mode driven
//!   all along) gives none.

// Small dense systems (6x6) read clearest indexed.
#![allow(clippy::needless_range_loop)]

use crate::numeric::jackknife_std;
use nalgebra::{SMatrix, SVector};
use std::f64::consts::PI;

/// A damped sinusoid fitted to a record.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct SineFit {
    /// The damped frequency ω/2π, Hz.
    pub frequency_hz: f64,
    pub frequency_std_hz: f64,
    /// σ/√(σ² + ω²); negative when the fitted envelope grows (a sway that
    /// is driven, not free: the value then says only that no decay shows).
    pub damping_ratio: f64,
    pub damping_ratio_std: f64,
    /// The sinusoid's amplitude at the window's start, in the record's unit.
    pub amplitude: f64,
    /// Cycles in the window fitted.
    pub cycles: f64,
    pub start_s: f64,
    pub duration_s: f64,
    /// The fitted sinusoid's power over the residual's, dB.
    pub snr_db: f64,
    /// Samples after decimation, and the effective count the uncertainties
    /// were taken with (fewer when the residual is correlated).
    pub samples: usize,
    pub effective_samples: f64,
}

/// Samples a cycle the fit decimates to (at least).
const SAMPLES_PER_CYCLE: f64 = 16.0;

/// A zero-phase low-pass of `y` (Hann-windowed sinc, cutoff `fc` in
/// cycles per sample, `half` taps either side), evaluated at every
/// `step`-th sample from 0. Near the ends the kernel's part inside the
/// record is renormalised, so no sample is lost.
fn lowpass_decimate(y: &[f64], fc: f64, half: usize, step: usize) -> Vec<f64> {
    let kernel: Vec<f64> = (0..=2 * half)
        .map(|k| {
            let x = k as f64 - half as f64;
            let sinc = if x == 0.0 {
                2.0 * fc
            } else {
                (2.0 * PI * fc * x).sin() / (PI * x)
            };
            let w = 0.5 + 0.5 * (PI * x / (half as f64 + 1.0)).cos();
            sinc * w
        })
        .collect();
    let n = y.len();
    (0..n)
        .step_by(step.max(1))
        .map(|i| {
            let lo = i.saturating_sub(half);
            let hi = (i + half).min(n - 1);
            let (mut acc, mut wsum) = (0.0, 0.0);
            for (j, &v) in y.iter().enumerate().take(hi + 1).skip(lo) {
                let w = kernel[j + half - i];
                acc += w * v;
                wsum += w;
            }
            if wsum.abs() > 1e-12 {
                acc / wsum
            } else {
                0.0
            }
        })
        .collect()
}

/// `a` (symmetric, row-major) as nalgebra's matrix.
fn matrix<const N: usize>(a: &[[f64; N]; N]) -> Option<SMatrix<f64, N, N>> {
    let m = SMatrix::<f64, N, N>::from_fn(|r, c| a[r][c]);
    m.iter().all(|v| v.is_finite()).then_some(m)
}

/// Solves the symmetric positive system `a x = b` by Cholesky (nalgebra);
/// `None` when it is not positive definite or not finite.
fn cholesky_solve<const N: usize>(a: &[[f64; N]; N], b: &[f64; N]) -> Option<[f64; N]> {
    let x = matrix(a)?
        .cholesky()?
        .solve(&SVector::<f64, N>::from_column_slice(b));
    x.iter()
        .all(|v| v.is_finite())
        .then(|| std::array::from_fn(|i| x[i]))
}

/// The inverse of a symmetric positive matrix (Cholesky, nalgebra).
fn inverse<const N: usize>(a: &[[f64; N]; N]) -> Option<[[f64; N]; N]> {
    let inv = matrix(a)?.cholesky()?.inverse();
    inv.iter()
        .all(|v| v.is_finite())
        .then(|| std::array::from_fn(|r| std::array::from_fn(|c| inv[(r, c)])))
}

/// The model's basis at time `t` for (ω, σ): [1, t, e cos, e sin].
fn basis(t: f64, w: f64, s: f64) -> [f64; 4] {
    let e = (-s * t).exp();
    [1.0, t, e * (w * t).cos(), e * (w * t).sin()]
}

/// The linear part's least squares for fixed (ω, σ): coefficients and RSS.
fn linear(t: &[f64], z: &[f64], w: f64, s: f64) -> Option<([f64; 4], f64)> {
    let mut a = [[0.0; 4]; 4];
    let mut b = [0.0; 4];
    for (&ti, &zi) in t.iter().zip(z) {
        let g = basis(ti, w, s);
        for i in 0..4 {
            b[i] += g[i] * zi;
            for j in 0..4 {
                a[i][j] += g[i] * g[j];
            }
        }
    }
    // A whisker of ridge keeps a near-singular trend solvable.
    for (i, row) in a.iter_mut().enumerate() {
        row[i] *= 1.0 + 1e-12;
    }
    let c = cholesky_solve(&a, &b)?;
    let rss: f64 = t
        .iter()
        .zip(z)
        .map(|(&ti, &zi)| {
            let g = basis(ti, w, s);
            let m: f64 = (0..4).map(|k| c[k] * g[k]).sum();
            (zi - m).powi(2)
        })
        .sum();
    Some((c, rss))
}

/// The lag-1 autocorrelation of `r` (0 when it cannot be taken).
fn lag1(r: &[f64]) -> f64 {
    let e: f64 = r.iter().map(|v| v * v).sum();
    if e <= 0.0 || r.len() < 3 {
        return 0.0;
    }
    r.windows(2).map(|w| w[0] * w[1]).sum::<f64>() / e
}

/// The model at `t`: p = [c0, c1, a, b, ω, σ].
fn model(p: &[f64; 6], t: f64) -> f64 {
    let e = (-p[5] * t).exp();
    p[0] + p[1] * t + e * (p[2] * (p[4] * t).cos() + p[3] * (p[4] * t).sin())
}

/// The model's gradient in its six parameters at `t`.
fn jac(p: &[f64; 6], t: f64) -> [f64; 6] {
    let e = (-p[5] * t).exp();
    let (sn, cs) = (p[4] * t).sin_cos();
    let osc = p[2] * cs + p[3] * sn;
    [
        1.0,
        t,
        e * cs,
        e * sn,
        e * t * (-p[2] * sn + p[3] * cs),
        -t * e * osc,
    ]
}

/// JᵀJ and Jᵀr at `p`.
fn normal(t: &[f64], z: &[f64], p: &[f64; 6]) -> ([[f64; 6]; 6], [f64; 6]) {
    let mut a = [[0.0; 6]; 6];
    let mut g = [0.0; 6];
    for (&ti, &zi) in t.iter().zip(z) {
        let j = jac(p, ti);
        let r = zi - model(p, ti);
        for i in 0..6 {
            g[i] += j[i] * r;
            for k in 0..6 {
                a[i][k] += j[i] * j[k];
            }
        }
    }
    (a, g)
}

fn cost(t: &[f64], z: &[f64], p: &[f64; 6]) -> f64 {
    t.iter()
        .zip(z)
        .map(|(&ti, &zi)| (zi - model(p, ti)).powi(2))
        .sum()
}

/// Levenberg-Marquardt on all six parameters from `p`: the parameters and
/// the residual sum of squares.
fn levenberg_marquardt(t: &[f64], z: &[f64], mut p: [f64; 6]) -> Option<([f64; 6], f64)> {
    let mut rss = cost(t, z, &p);
    if !rss.is_finite() {
        return None;
    }
    let mut lambda = 1e-3;
    for _ in 0..200 {
        let (a, g) = normal(t, z, &p);
        let mut damped = a;
        for i in 0..6 {
            damped[i][i] = a[i][i] * (1.0 + lambda) + 1e-300;
        }
        let Some(d) = cholesky_solve(&damped, &g) else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
            continue;
        };
        let mut q = p;
        for i in 0..6 {
            q[i] += d[i];
        }
        let cq = cost(t, z, &q);
        if cq.is_finite() && cq < rss {
            let gain = (rss - cq) / rss.max(f64::MIN_POSITIVE);
            p = q;
            rss = cq;
            lambda = (lambda * 0.3).max(1e-12);
            if gain < 1e-12 {
                break;
            }
        } else {
            lambda *= 10.0;
            if lambda > 1e12 {
                break;
            }
        }
    }
    Some((p, rss))
}

/// Blocks of the record the jackknife leaves out one at a time.
const JACKKNIFE_BLOCKS: usize = 5;

/// The delete-a-block jackknife's standard deviation of ω and σ about the
/// fit `p`: what the record's own parts say of the estimate, whatever the
/// noise's colour or the model's shortfall (a slowly changing gain, a
/// start-up transient). `None` when a part's fit fails.
fn jackknife(t: &[f64], z: &[f64], p: &[f64; 6]) -> Option<(f64, f64)> {
    let g = JACKKNIFE_BLOCKS;
    let n = t.len();
    let mut est = Vec::with_capacity(g);
    for b in 0..g {
        let (lo, hi) = (b * n / g, (b + 1) * n / g);
        let (ts, zs): (Vec<f64>, Vec<f64>) = t
            .iter()
            .zip(z)
            .enumerate()
            .filter(|(i, _)| *i < lo || *i >= hi)
            .map(|(_, (&ti, &zi))| (ti, zi))
            .unzip();
        let (q, _) = levenberg_marquardt(&ts, &zs, *p)?;
        est.push((q[4], q[5]));
    }
    Some((
        jackknife_std(est.iter().map(|e| e.0)),
        jackknife_std(est.iter().map(|e| e.1)),
    ))
}

/// Fits `c0 + c1 t + e^(-σt)(a cos ωt + b sin ωt)` to `y` (sampled at
/// `fs` Hz), starting from `f_guess` Hz and damping ratio `zeta_guess`.
/// `None` when the record is too short or not finite, or the fit does not
/// settle within three record-bandwidths (3/T Hz) of the guess.
pub fn fit_damped_sinusoid(y: &[f64], fs: f64, f_guess: f64, zeta_guess: f64) -> Option<SineFit> {
    if !(fs.is_finite() && fs > 0.0 && f_guess.is_finite() && f_guess > 0.0 && f_guess < fs / 2.0)
        || y.len() < 16
        || y.iter().any(|v| !v.is_finite())
    {
        return None;
    }
    let step = ((fs / (SAMPLES_PER_CYCLE * f_guess)).floor() as usize).max(1);
    let fsd = fs / step as f64;
    // Low-passed and decimated where the whole kernel lies inside the
    // record (a kernel cut short at an end would lag a sloping signal).
    let (t, z): (Vec<f64>, Vec<f64>) = if step > 1 {
        let half = 3 * step;
        lowpass_decimate(y, 0.35 / step as f64, half, step)
            .into_iter()
            .enumerate()
            .map(|(k, v)| (k * step, v))
            .filter(|&(i, _)| i >= half && i + half < y.len())
            .map(|(i, v)| (i as f64 / fs, v))
            .unzip()
    } else {
        y.iter()
            .enumerate()
            .map(|(i, &v)| (i as f64 / fs, v))
            .unzip()
    };
    let n = z.len();
    if n < 12 {
        return None;
    }
    let (t0, span) = (t[0], (t[n - 1] - t[0]).max(1.0 / fsd));
    // A coarse search of (ω, σ) by the linear part's residual: the
    // spectral guess is only good to a bin (1/T).
    let w0 = 2.0 * PI * f_guess;
    let s0 = (zeta_guess.clamp(0.0, 0.3) * w0).max(0.0);
    let mut best = (f64::INFINITY, w0, s0);
    for i in -30..=30 {
        let w = w0 + 2.0 * PI * (i as f64) * 0.05 / span;
        if w <= 0.0 || w >= PI * fsd {
            continue;
        }
        for s in [0.0, s0, 0.5 / span, 1.0 / span, 2.0 / span, 4.0 / span] {
            if let Some((_, rss)) = linear(&t, &z, w, s) {
                if rss < best.0 {
                    best = (rss, w, s);
                }
            }
        }
    }
    let (c, _) = linear(&t, &z, best.1, best.2)?;
    let (p, rss) = levenberg_marquardt(&t, &z, [c[0], c[1], c[2], c[3], best.1, best.2])?;
    let (w, s) = (p[4], p[5]);
    let c = [p[0], p[1], p[2], p[3]];
    let f = w / (2.0 * PI);
    if !(f.is_finite() && (f - f_guess).abs() <= 3.0 / span && w > 0.0 && w < PI * fsd) {
        return None;
    }
    let dof = n.saturating_sub(6).max(1) as f64;
    let resid: Vec<f64> = t
        .iter()
        .zip(&z)
        .map(|(&ti, &zi)| zi - model(&p, ti))
        .collect();
    let rho = lag1(&resid).clamp(0.0, 0.95);
    let inflation = (1.0 + rho) / (1.0 - rho);
    let s2 = rss / dof * inflation;
    let (a, _) = normal(&t, &z, &p);
    let cov = inverse(&a)?;
    let (mut var_w, mut var_s, mut cov_ws) = (cov[4][4] * s2, cov[5][5] * s2, cov[4][5] * s2);
    // The larger of the residual's and the jackknife's spread (the
    // latter only ever widens it; their correlation then kept).
    if let Some((jw, js)) = jackknife(&t, &z, &p) {
        let (kw, ks) = (
            (jw * jw / var_w.max(f64::MIN_POSITIVE)).max(1.0),
            (js * js / var_s.max(f64::MIN_POSITIVE)).max(1.0),
        );
        cov_ws *= (kw * ks).sqrt();
        var_w *= kw;
        var_s *= ks;
    }
    let r2 = s * s + w * w;
    let zeta = s / r2.sqrt();
    let (dz_ds, dz_dw) = (w * w / r2.powf(1.5), -s * w / r2.powf(1.5));
    let var_z = dz_ds * dz_ds * var_s + dz_dw * dz_dw * var_w + 2.0 * dz_ds * dz_dw * cov_ws;
    let amplitude = c[2].hypot(c[3]) * (-s * t0).exp();
    let signal: f64 = t
        .iter()
        .map(|&ti| {
            let g = basis(ti, w, s);
            (c[2] * g[2] + c[3] * g[3]).powi(2)
        })
        .sum();
    Some(SineFit {
        frequency_hz: f,
        frequency_std_hz: var_w.max(0.0).sqrt() / (2.0 * PI),
        damping_ratio: zeta,
        damping_ratio_std: var_z.max(0.0).sqrt(),
        amplitude,
        cycles: f * span,
        start_s: t0,
        duration_s: span,
        snr_db: 10.0 * (signal / rss.max(f64::MIN_POSITIVE)).log10(),
        samples: n,
        effective_samples: n as f64 / inflation,
    })
}

/// A weighted least-squares line through points (x, y, weight): its
/// weighted sums about the means and its slope.
struct Line {
    sw: f64,
    sxx: f64,
    sxy: f64,
    syy: f64,
    slope: f64,
}

/// [`Line`] through `pts`; `None` when the x do not spread (or no weight).
fn weighted_line<'a>(pts: impl Iterator<Item = &'a (f64, f64, f64)> + Clone) -> Option<Line> {
    let sw: f64 = pts.clone().map(|p| p.2).sum();
    let mx = pts.clone().map(|p| p.2 * p.0).sum::<f64>() / sw;
    let my = pts.clone().map(|p| p.2 * p.1).sum::<f64>() / sw;
    let (mut sxx, mut sxy, mut syy) = (0.0, 0.0, 0.0);
    for p in pts {
        sxx += p.2 * (p.0 - mx).powi(2);
        sxy += p.2 * (p.0 - mx) * (p.1 - my);
        syy += p.2 * (p.1 - my).powi(2);
    }
    (sxx > 0.0).then(|| Line {
        sw,
        sxx,
        sxy,
        syy,
        slope: sxy / sxx,
    })
}

/// A ring-down's damping from its envelope.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct FreeDecay {
    pub damping_ratio: f64,
    pub damping_ratio_std: f64,
    /// Where the decay fitted starts (half an envelope kernel after its
    /// maximum) and how long it lasts.
    pub start_s: f64,
    pub duration_s: f64,
    /// How far the envelope fell over the window, dB.
    pub fall_db: f64,
    /// How much of the log-envelope's variance the line explains.
    pub r_squared: f64,
}

/// The least fall of the envelope taken as a decay, dB.
pub const MIN_DECAY_DB: f64 = 10.0;
/// The least share of the log-envelope a decay must explain.
pub const MIN_DECAY_R2: f64 = 0.9;

/// The free-decay damping of the mode at `f_hz` in `y` (sampled at `fs`),
/// its envelope taken within `band_hz` of it (below the distance to the
/// next line, above the mode's own half-power width). `None` when the
/// envelope does not fall by [`MIN_DECAY_DB`] on a line (R² at least
/// [`MIN_DECAY_R2`]) after its maximum: no ring-down to measure.
pub fn fit_free_decay(y: &[f64], fs: f64, f_hz: f64, band_hz: f64) -> Option<FreeDecay> {
    if !(fs.is_finite() && fs > 0.0 && f_hz > 0.0 && f_hz < fs / 2.0 && band_hz > 0.0)
        || y.len() < 32
        || y.iter().any(|v| !v.is_finite())
    {
        return None;
    }
    let w = 2.0 * PI * f_hz / fs;
    let mean = y.iter().sum::<f64>() / y.len() as f64;
    let (re, im): (Vec<f64>, Vec<f64>) = y
        .iter()
        .enumerate()
        .map(|(i, &v)| {
            let (s, c) = (w * i as f64).sin_cos();
            ((v - mean) * c, -(v - mean) * s)
        })
        .unzip();
    // The envelope's low-pass: cutoff `band_hz`, about four of its periods
    // long, evaluated every `step` samples (eight a period of the band: the
    // envelope holds nothing faster, and a long record's kernel costs
    // nothing per sample skipped); its ends (half a kernel) are left out of
    // the fit. Envelope sample k is the record's sample k·step.
    let fc = (band_hz / fs).min(0.25);
    let half = ((2.0 / fc).ceil() as usize).clamp(4, y.len() / 4);
    let step = ((fs / (8.0 * band_hz)).floor() as usize).clamp(1, half);
    let (er, ei) = (
        lowpass_decimate(&re, fc, half, step),
        lowpass_decimate(&im, fc, half, step),
    );
    let env: Vec<f64> = er.iter().zip(&ei).map(|(a, b)| 2.0 * a.hypot(*b)).collect();
    let skip = half.div_ceil(step);
    let (lo, hi) = (skip, env.len().saturating_sub(skip));
    if hi <= lo + 8 {
        return None;
    }
    let (peak_i, _) =
        env[lo..hi].iter().enumerate().fold(
            (0, 0.0f64),
            |b, (i, &v)| if v > b.1 { (i + lo, v) } else { b },
        );
    // The noise's envelope: the envelope's 10th percentile.
    let mut sorted: Vec<f64> = env[lo..hi].to_vec();
    sorted.sort_by(f64::total_cmp);
    let noise = sorted[sorted.len() / 10];
    // From half a kernel after the maximum (the low-pass smears the strike
    // over a kernel's length; after it an exponential stays exponential,
    // the filter only scales it) to where the envelope first comes within
    // 10x (20 dB) of the noise (nearer, the noise and a camera's
    // quantisation bend it).
    let floor = 10.0 * noise;
    let peak_i = peak_i + skip;
    if peak_i + 8 >= hi {
        return None;
    }
    let peak = env[peak_i];
    if peak <= 0.0 || !peak.is_finite() {
        return None;
    }
    let end = (peak_i..hi).find(|&i| env[i] <= floor).unwrap_or(hi);
    let fall_db = 20.0 * (peak / env[end.min(hi - 1)].max(f64::MIN_POSITIVE)).log10();
    let dt = step as f64 / fs;
    // At least two cycles: less is a transient, not a ring-down.
    if end < peak_i + 8 || fall_db < MIN_DECAY_DB || (end - peak_i) as f64 * dt * f_hz < 2.0 {
        return None;
    }
    // The log-envelope's line, weighted by the envelope's power (where it
    // stands above the noise).
    let pts: Vec<(f64, f64, f64)> = (peak_i..end)
        .map(|i| {
            let e = env[i];
            let snr = (e / noise.max(f64::MIN_POSITIVE)).powi(2);
            (i as f64 * dt, e.ln(), snr / (1.0 + snr))
        })
        .collect();
    let Line {
        sw,
        sxx,
        sxy,
        syy,
        slope,
    } = weighted_line(pts.iter())?;
    if syy.is_nan() || syy <= 0.0 {
        return None;
    }
    let r_squared = sxy * sxy / (sxx * syy);
    if !(slope < 0.0 && r_squared >= MIN_DECAY_R2) {
        return None;
    }
    // The slope's uncertainty from the scatter about the line, with one
    // independent sample per envelope correlation time (1/(2 band)).
    let resid = (syy - slope * sxy).max(0.0) / sw;
    let m = pts.len() as f64;
    let independent = (m * 2.0 * band_hz * dt).clamp(2.0, m);
    let mut slope_std = (resid / (sxx / sw) / (independent - 1.0).max(1.0)).sqrt();
    // And the delete-a-block jackknife's spread, when larger: a decay that
    // bends (a camera's response, a second line in the band) shows there.
    let g = JACKKNIFE_BLOCKS;
    let parts: Vec<f64> = (0..g)
        .filter_map(|b| {
            let (lo, hi) = (b * pts.len() / g, (b + 1) * pts.len() / g);
            let kept = pts
                .iter()
                .enumerate()
                .filter(move |(i, _)| *i < lo || *i >= hi)
                .map(|(_, p)| p);
            weighted_line(kept).map(|l| l.slope)
        })
        .collect();
    if parts.len() == g {
        slope_std = slope_std.max(jackknife_std(parts.iter().copied()));
    }
    let sigma = -slope;
    let wr = 2.0 * PI * f_hz;
    Some(FreeDecay {
        damping_ratio: sigma / sigma.hypot(wr),
        damping_ratio_std: slope_std / wr,
        start_s: peak_i as f64 * dt,
        duration_s: (end - peak_i) as f64 * dt,
        fall_db,
        r_squared,
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::rng::Xoshiro256;

    fn gauss(rng: &mut Xoshiro256) -> f64 {
        (0..12).map(|_| rng.next_f64()).sum::<f64>() - 6.0
    }

    /// Two and a half cycles of a 0.2 Hz sway in noise and a drift: the
    /// frequency within its stated uncertainty over many draws (the
    /// uncertainty is honest: about 68% inside one sigma, nearly all
    /// inside three), and far better than the spectrum's 0.08 Hz bin.
    #[test]
    fn a_few_cycle_sway_is_measured_within_its_uncertainty() {
        let (fs, f, secs) = (24.0, 0.2, 12.5);
        let n = (fs * secs) as usize;
        let (mut inside1, mut inside3, trials) = (0, 0, 200);
        let mut worst = 0.0f64;
        for seed in 0..trials {
            let mut rng = Xoshiro256::new(seed + 1);
            let phase = rng.next_f64() * 2.0 * PI;
            let y: Vec<f64> = (0..n)
                .map(|i| {
                    let t = i as f64 / fs;
                    (2.0 * PI * f * t + phase).sin() + 0.3 * t / secs + 0.3 * gauss(&mut rng)
                })
                .collect();
            let fit = fit_damped_sinusoid(&y, fs, 0.24, 0.05).expect("a fit");
            let err = (fit.frequency_hz - f).abs();
            worst = worst.max(err / f);
            if err <= fit.frequency_std_hz {
                inside1 += 1;
            }
            if err <= 3.0 * fit.frequency_std_hz {
                inside3 += 1;
            }
            assert!(fit.frequency_std_hz < 0.01, "{fit:?}");
        }
        assert!(worst < 0.05, "worst relative error {worst}");
        let share1 = inside1 as f64 / trials as f64;
        assert!((0.5..=0.9).contains(&share1), "{share1} inside one sigma");
        assert!(
            inside3 as f64 >= 0.97 * trials as f64,
            "{inside3} inside 3 sigma"
        );
    }

    /// A clean decaying sinusoid: frequency and damping to a part in 10⁴.
    #[test]
    fn a_damped_sinusoid_is_recovered() {
        let (fs, f, zeta) = (200.0, 3.0, 0.02f64);
        let w = 2.0 * PI * f;
        let wd = w * (1.0 - zeta * zeta).sqrt();
        let y: Vec<f64> = (0..1000)
            .map(|i| {
                let t = i as f64 / fs;
                (-zeta * w * t).exp() * (wd * t + 0.3).cos()
            })
            .collect();
        let fit = fit_damped_sinusoid(&y, fs, 3.1, 0.05).unwrap();
        assert!(
            (fit.frequency_hz - wd / (2.0 * PI)).abs() < 1e-4 * f,
            "{fit:?}"
        );
        assert!((fit.damping_ratio - zeta).abs() < 1e-4, "{fit:?}");
    }

    /// A struck mode among another line and noise: its ring-down damping
    /// within 10%; a mode driven all along (no fall) gives none.
    #[test]
    fn a_ring_down_gives_its_damping_and_a_steady_tone_none() {
        let fs = 500.0;
        let mut rng = Xoshiro256::new(7);
        let (f, zeta) = (40.0, 0.005);
        let w = 2.0 * PI * f;
        let y: Vec<f64> = (0..10_000)
            .map(|i| {
                let t = i as f64 / fs;
                let ring = if t >= 1.0 {
                    (-zeta * w * (t - 1.0)).exp() * (w * (t - 1.0)).sin()
                } else {
                    0.0
                };
                ring + 0.3 * (2.0 * PI * 90.0 * t).sin() + 0.01 * gauss(&mut rng)
            })
            .collect();
        let d = fit_free_decay(&y, fs, f, 5.0).expect("a ring-down");
        assert!((d.damping_ratio / zeta - 1.0).abs() < 0.1, "{d:?}");
        // The fit starts half a kernel (1/(2 band) ... 2/band) after the strike.
        assert!(d.start_s > 1.0 && d.start_s < 1.6, "{d:?}");
        let steady: Vec<f64> = (0..10_000)
            .map(|i| (w * i as f64 / fs).sin() + 0.01 * gauss(&mut rng))
            .collect();
        assert!(fit_free_decay(&steady, fs, f, 5.0).is_none());
    }

    #[test]
    fn bad_input_fits_nothing() {
        assert!(fit_damped_sinusoid(&[], 24.0, 0.2, 0.01).is_none());
        assert!(fit_damped_sinusoid(&[f64::NAN; 100], 24.0, 0.2, 0.01).is_none());
        assert!(fit_damped_sinusoid(&[0.0; 100], 24.0, 20.0, 0.01).is_none());
        assert!(fit_damped_sinusoid(&[1.0; 3], 24.0, 0.2, 0.01).is_none());
        assert!(fit_free_decay(&[0.0; 1000], 24.0, 2.0, 0.5).is_none());
    }
}
