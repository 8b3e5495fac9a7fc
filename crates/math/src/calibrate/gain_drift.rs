//! Effect (h): the gain changes slowly over the recording (a struck object
//! decaying, a light fading, an automatic gain): the family "slow
//! modulation of gain" of issue 15. Read on the residual's time axis: the
//! recovery's gain against the target block by block (its magnitude, on
//! the target and its quadrature, so a drifting lag does not read as a
//! falling gain), a smooth trend in it against the scatter from block to
//! block. Fitted as a polynomial in time (Legendre, order 1 to
//! [`MAX_ORDER`], chosen by cross-validation within the fit blocks); the
//! correction divides the recovery by it. It belongs to one recording.

use super::correction::{envelope, legendre, MIN_RELATIVE_GAIN};
use super::model::{Fit, Model};
use super::report::{Unexplained, UnexplainedKind};
use super::signal::{equalize, stft_len};
use super::{Candidate, Correction, Uncertainty};
use crate::numeric::median;
use realfft::num_complex::Complex;

/// Highest polynomial order of the gain's trend.
pub const MAX_ORDER: usize = 4;

/// One block's gain: centre (samples), magnitude, and the target's
/// energy in it.
#[derive(Clone, Copy, Debug)]
struct BlockGain {
    centre: f64,
    gain: f64,
    energy: f64,
}

/// Per block of one STFT length: the least-squares fit `z ≈ a T + b Q`
/// (`Q` the target's quadrature), gain `|a + ib|`; only blocks where the
/// target holds at least 1% of its busiest block's energy, and (with
/// `fit_only`) only the fit blocks.
fn block_gains(m: &Model, z: &[f64], t: &[f64], fit_only: bool) -> Vec<BlockGain> {
    let q = equalize(t, m.fs, |_| Complex::new(0.0, -1.0));
    let n = z.len().min(t.len()).min(q.len());
    let len = stft_len(m.fs);
    let mut out = Vec::new();
    let mut start = 0;
    while start + len <= n {
        if !fit_only || m.is_fit(start) {
            let (mut tt, mut qq, mut tq, mut zt, mut zq) = (0.0, 0.0, 0.0, 0.0, 0.0);
            for i in start..start + len {
                tt += t[i] * t[i];
                qq += q[i] * q[i];
                tq += t[i] * q[i];
                zt += z[i] * t[i];
                zq += z[i] * q[i];
            }
            let det = tt * qq - tq * tq;
            if det > 0.0 {
                let a = (zt * qq - zq * tq) / det;
                let b = (zq * tt - zt * tq) / det;
                out.push(BlockGain {
                    centre: start as f64 + 0.5 * len as f64,
                    gain: a.hypot(b),
                    energy: tt,
                });
            }
        }
        start += len;
    }
    let emax = out.iter().map(|b| b.energy).fold(0.0, f64::max);
    out.retain(|b| b.energy >= 0.01 * emax && b.gain.is_finite());
    out
}

/// Least squares of the block gains on P0..=order of their normalised time
/// (`x = 2 centre / n - 1`); the coefficients.
fn trend(blocks: &[BlockGain], n: usize, order: usize) -> Option<Vec<f64>> {
    let k = order + 1;
    if blocks.len() <= k {
        return None;
    }
    let mut a = nalgebra::DMatrix::<f64>::zeros(k, k);
    let mut rhs = nalgebra::DVector::<f64>::zeros(k);
    for b in blocks {
        let p = legendre(2.0 * b.centre / n as f64 - 1.0, order);
        for r in 0..k {
            rhs[r] += p[r] * b.gain;
            for c in 0..k {
                a[(r, c)] += p[r] * p[c];
            }
        }
    }
    let c = a.lu().solve(&rhs)?;
    let c: Vec<f64> = c.iter().copied().collect();
    c.iter().all(|v| v.is_finite()).then_some(c)
}

/// The scatter of one block's gain: from successive differences (robust to
/// a smooth trend and to a residual that is not white).
fn scatter(blocks: &[BlockGain]) -> f64 {
    let mut d: Vec<f64> = blocks
        .windows(2)
        .map(|w| (w[1].gain - w[0].gain).abs())
        .collect();
    if d.is_empty() {
        return f64::NAN;
    }
    1.4826 * median(&mut d) / std::f64::consts::SQRT_2
}

/// The level chi-square with `k` degrees of freedom exceeds with
/// probability 1e-3 (Wilson-Hilferty): a trend's power over the
/// block-to-block scatter must pass it to count.
pub(super) fn chi2_level(k: usize) -> f64 {
    let k = k as f64;
    let z = 3.09; // the normal's 1 - 1e-3 quantile
    let h = 2.0 / (9.0 * k);
    k * (1.0 - h + z * h.sqrt()).powi(3)
}

/// The residual's time axis: a gain that moves over the recording beyond
/// the block-to-block scatter (order-`MAX_ORDER` trend, chi-square test at
/// 1e-3); `None` when it does not.
pub(super) fn gain_over_time(m: &Model, z: &[f64], fit: &Fit) -> Option<Unexplained> {
    let blocks = block_gains(m, z, &fit.t, false);
    let n = z.len();
    let c = trend(
        &blocks,
        n,
        MAX_ORDER.min(blocks.len().saturating_sub(2)).max(1),
    )?;
    let s = scatter(&blocks);
    if !(s.is_finite() && s > 0.0) || c[0] <= 0.0 {
        return None;
    }
    // The trend's power about its mean, in units of one block's scatter.
    let ss: f64 = blocks
        .iter()
        .map(|b| (envelope(&c, b.centre, n) - c[0]).powi(2))
        .sum::<f64>()
        / (s * s);
    if ss < chi2_level(c.len() - 1) {
        return None;
    }
    let vals: Vec<f64> = blocks.iter().map(|b| envelope(&c, b.centre, n)).collect();
    let lo = vals.iter().cloned().fold(f64::INFINITY, f64::min);
    let hi = vals.iter().cloned().fold(0.0, f64::max);
    let db = |v: f64| 20.0 * (v.max(1e-9) / c[0]).log10();
    let first = vals.first().copied().unwrap_or(c[0]);
    let last = vals.last().copied().unwrap_or(c[0]);
    Some(Unexplained::GainOverTime {
        kind: UnexplainedKind::GainOverTime,
        frequencies_hz: [],
        gain_range_db: [db(lo), db(hi)],
        start_to_end_db: db(last) - db(first),
        significance: ss / chi2_level(c.len() - 1),
        description: format!(
            "the gain moves over the recording from {:+.1} to {:+.1} dB about its mean ({:+.1} dB from start to end; {:.0}x the level block-to-block scatter reaches by chance): a decaying or growing excitation, a changing light, an automatic gain",
            db(lo),
            db(hi),
            db(last) - db(first),
            ss / chi2_level(c.len() - 1)
        ),
    })
}

/// The gain's trend over the recording, fitted on the fit blocks (order by
/// three-fold cross-validation over the block classes 0, 2 and 4 of every
/// five), normalised to mean 1; `None` when it falls under
/// [`MIN_RELATIVE_GAIN`] of its mean anywhere.
pub(super) fn fit_gain_drift(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let blocks = block_gains(m, z, &fit.t, true);
    let n = z.len();
    let len = stft_len(m.fs);
    let class = |b: &BlockGain| ((b.centre as usize) / len) % 5;
    let mut best: Option<(usize, f64)> = None;
    'orders: for order in 1..=MAX_ORDER {
        let mut err = 0.0;
        for held in [0, 2, 4] {
            let train: Vec<BlockGain> = blocks
                .iter()
                .filter(|b| class(b) != held)
                .copied()
                .collect();
            let Some(c) = trend(&train, n, order) else {
                continue 'orders;
            };
            err += blocks
                .iter()
                .filter(|b| class(b) == held)
                .map(|b| (b.gain - envelope(&c, b.centre, n)).powi(2))
                .sum::<f64>();
        }
        if best.is_none_or(|(_, e)| err < e) {
            best = Some((order, err));
        }
    }
    let (order, _) = best?;
    let c = trend(&blocks, n, order)?;
    if c[0] <= 0.0 {
        return None;
    }
    let coefs: Vec<f64> = c.iter().map(|v| v / c[0]).collect();
    let lowest = (0..=200)
        .map(|i| envelope(&coefs, i as f64 * n as f64 / 200.0, n))
        .fold(f64::INFINITY, f64::min);
    if lowest.is_nan() || lowest < MIN_RELATIVE_GAIN {
        return None;
    }
    // One block's scatter, relative: each coefficient's standard error.
    let s = scatter(&blocks) / c[0];
    let sd: Vec<f64> = (0..coefs.len())
        .map(|k| s * ((2 * k + 1) as f64 / blocks.len() as f64).sqrt())
        .collect();
    let start_to_end_db = 20.0
        * (envelope(&coefs, n as f64, n).max(1e-9) / envelope(&coefs, 0.0, n).max(1e-9)).log10();
    Some(Candidate {
        correction: Correction::GainDrift {
            coefs,
            samples: n,
            start_to_end_db,
        },
        uncertainty: Uncertainty::GainDrift { coefficients: sd },
    })
}
