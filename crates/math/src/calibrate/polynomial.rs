//! Effect (g): a static nonlinear response with even and odd terms, the
//! family soft clipping (f) is the odd, saturating member of. A response
//! `x + c2 x² + c3 x³ + …` of the object (or loudspeaker) puts energy at
//! 2x, 3x, … the reference's frequency; its inverse is fitted as a
//! polynomial of the recovery, `u + a2 u² + … + aP u^P`, whose order `P`
//! (2 to [`MAX_ORDER`]) is chosen by cross-validation within the fit
//! blocks (so the held-out blocks that decide whether the effect is kept
//! stay unseen). [`super::calibrate`] fits it only when the residual holds
//! harmonics of the reference.

use super::model::{Fit, Model};
use super::signal::{redo_highpass, stft_len, undo_highpass};
use super::{Candidate, Correction, Uncertainty};

/// Highest order tried.
pub const MAX_ORDER: usize = 5;

/// The inverse response's coefficients by linear least squares: with `u`
/// the recovery with its high-pass undone (the nonlinearity acts on the
/// motion, before the pipeline's high-pass), `T ≈ HP(b1 u + b2 u² + … +
/// bP u^P)`, so `ak = bk / b1`. `None` when no order keeps the inverse
/// monotonic over the recovery's range (a response that folds back is not
/// invertible) or the fit is degenerate.
pub(super) fn fit_polynomial(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let hp = m.opts.highpass;
    let u = undo_highpass(z, m.fs, hp);
    let peak = u.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if !(peak.is_finite() && peak > 0.0) {
        return None;
    }
    // Columns (u / peak)^k, k = 1..=MAX_ORDER, each high-passed as the target is.
    let cols: Vec<Vec<f64>> = (1..=MAX_ORDER as i32)
        .map(|k| {
            redo_highpass(
                &u.iter().map(|v| (v / peak).powi(k)).collect::<Vec<_>>(),
                m.fs,
                hp,
            )
        })
        .collect();
    // The order by three-fold cross-validation within the fit blocks (0,
    // 2 and 4 of every five): each order is fitted on two of them and
    // checked on the third, the checks summed.
    let block = stft_len(m.fs);
    let part = move |i: usize| (i / block) % 5;
    let mut best: Option<(usize, f64)> = None;
    'orders: for p in 2..=MAX_ORDER {
        let mut total = 0.0;
        for held in [0, 2, 4] {
            let train = |i: usize| matches!(part(i), 0 | 2 | 4) && part(i) != held;
            let check = |i: usize| part(i) == held;
            let Some((b, _)) = solve(&cols, &fit.t, p, &train) else {
                continue 'orders;
            };
            if !monotonic(&b) {
                continue 'orders;
            }
            total += sse(&cols, &fit.t, &b, &check);
        }
        if best.is_none_or(|(_, e)| total < e) {
            best = Some((p, total));
        }
    }
    let (p, _) = best?;
    let (b, var) = solve(&cols, &fit.t, p, &|i| m.is_fit(i))?;
    if !monotonic(&b) {
        return None;
    }
    // Back to the recovery's units: ak (u / peak)^k / (u / peak) scaled.
    let coefs: Vec<f64> = (2..=p)
        .map(|k| b[k - 1] / b[0] / peak.powi(k as i32 - 1))
        .collect();
    let sds: Vec<f64> = (2..=p)
        .map(|k| var[k - 1].sqrt() / b[0].abs() / peak.powi(k as i32 - 1))
        .collect();
    if coefs.iter().chain(&sds).any(|v| !v.is_finite()) {
        return None;
    }
    Some(Candidate {
        correction: Correction::Polynomial {
            coefs,
            range: peak,
            highpass: hp,
        },
        uncertainty: Uncertainty::Polynomial { coefficients: sds },
    })
}

/// Least squares of `t` on the first `p` columns over the samples `use_i`
/// selects: the coefficients and their variances (residual variance taken
/// as white).
fn solve(
    cols: &[Vec<f64>],
    t: &[f64],
    p: usize,
    use_i: &dyn Fn(usize) -> bool,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let n = t.len().min(cols[0].len());
    let mut a = nalgebra::DMatrix::<f64>::zeros(p, p);
    let mut rhs = nalgebra::DVector::<f64>::zeros(p);
    let mut count = 0usize;
    for i in (0..n).filter(|&i| use_i(i)) {
        count += 1;
        for r in 0..p {
            rhs[r] += cols[r][i] * t[i];
            for c in r..p {
                a[(r, c)] += cols[r][i] * cols[c][i];
            }
        }
    }
    for r in 0..p {
        for c in 0..r {
            a[(r, c)] = a[(c, r)];
        }
    }
    if count <= p {
        return None;
    }
    let inv = a.clone().lu().try_inverse()?;
    let b = &inv * &rhs;
    if b[0] == 0.0 || b.iter().any(|v| !v.is_finite()) {
        return None;
    }
    let b: Vec<f64> = b.iter().copied().collect();
    let e = sse(cols, t, &b, use_i);
    let sigma2 = e / (count - p) as f64;
    let var = (0..p).map(|k| inv[(k, k)] * sigma2).collect();
    Some((b, var))
}

fn sse(cols: &[Vec<f64>], t: &[f64], b: &[f64], use_i: &dyn Fn(usize) -> bool) -> f64 {
    let n = t.len().min(cols[0].len());
    (0..n)
        .filter(|&i| use_i(i))
        .map(|i| {
            let y: f64 = b.iter().enumerate().map(|(k, bk)| bk * cols[k][i]).sum();
            (t[i] - y).powi(2)
        })
        .sum()
}

/// The inverse `b1 x + b2 x² + …` keeps the sign of its slope on |x| <= 1
/// (the recovery's range, scaled to its peak).
fn monotonic(b: &[f64]) -> bool {
    let slope = |x: f64| -> f64 {
        b.iter()
            .enumerate()
            .map(|(k, bk)| (k + 1) as f64 * bk * x.powi(k as i32))
            .sum()
    };
    let s0 = slope(0.0);
    (-100..=100).all(|i| slope(i as f64 / 100.0) * s0 > 0.0)
}
