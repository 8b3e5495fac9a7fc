//! Effect (g): a static nonlinear response with even and odd terms, the
//! family soft clipping (f) is the odd, saturating member of. A response
//! `x + c2 x² + c3 x³ + …` of the object (or loudspeaker) puts energy at
//! 2x, 3x, … the reference's frequency; the response is fitted as a
//! polynomial of the motion the linear model predicts, whose order `P`
//! (2 to [`MAX_ORDER`]) is chosen by cross-validation within the fit
//! blocks (so the held-out blocks that decide whether the effect is kept
//! stay unseen), and the inverse `listen` applies is derived from it
//! ([`fit_polynomial`]). [`super::calibrate`] fits it only when the
//! residual holds harmonics of the reference.

use super::model::{Fit, Fold, Model};
use super::signal::{redo_highpass, stft_len, undo_highpass};
use super::{Candidate, Correction, Uncertainty};

/// Highest order tried.
pub const MAX_ORDER: usize = 5;

/// The static response's inverse, fitted in two steps (since session
/// 62). First the object's response, forward, by linear least squares:
/// with `x` the target with its high-pass undone (the motion as the
/// linear model sees it, before the pipeline's high-pass), the recovery
/// `z ≈ HP(b1 x + b2 x² + … + bP x^P)`, its order `P` chosen by
/// cross-validation within the fit blocks. Its regressors are the
/// noiseless reference, and a response of few terms holds at every
/// amplitude. Then the inverse `u + a2 u² + … + a5 u⁵` that
/// [`Correction::Polynomial`] applies, by least squares over motions
/// drawn from a Laplace distribution (speech's amplitudes, peaked at
/// rest; its scale an eighth of the swept range) passed through that
/// response and the fit's own noise ([`inverse_over_amplitudes`]).
///
/// Why not the inverse fitted on the recording itself, as before: a sweep
/// of constant amplitude tells an inverse polynomial only what it must do
/// at that amplitude (its terms trade against each other there), and
/// speech spends its time at smaller ones. On `mixed_poly`
/// (`x + 0.15 x² - 0.2 x³`, session 62) the inverse fitted on the chirp
/// undid 2.4 of the 4.7 dB the response cost the next recording's
/// speech. `None` when no order keeps the response rising over the
/// motion's range (it would not be invertible) or a fit is degenerate.
pub(super) fn fit_polynomial(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let hp = m.opts.highpass;
    let s = Sweep::read(m, z, fit)?;
    let (p, _) = s.orders(m, z).1?;
    let fitted = |i: usize| m.is_fit(i);
    let (b, var, sigma2) = solve(&s.cols, z, p, &fitted)?;
    let (lo, hi, range) = (s.lo, s.hi, s.range);
    if !rising(&b, lo, hi) {
        return None;
    }
    let noise = sigma2.sqrt();
    // In the recovery's units (X = b1 x / peak): X + Σ ck X^k, ck = bk / b1^k.
    let response: Vec<f64> = (2..=p).map(|k| b[k - 1] / b[0].powi(k as i32)).collect();
    let (x0, x1) = {
        let (a, c) = (b[0] * lo, b[0] * hi);
        (a.min(c), a.max(c))
    };
    let (coefs, drawn_sds) = inverse_over_amplitudes(&response, (x0, x1), noise, range)?;
    // The inverse's uncertainty is the response's: to first order its
    // term in u^k moves with the response's in X^k (a2 = -c2), and the
    // draws' own least squares, over 20 000 noiseless motions, says
    // nothing of the recording. Terms beyond the response's order keep the
    // draws' figure.
    let sds: Vec<f64> = (2..=MAX_ORDER)
        .map(|k| {
            if k <= p {
                var[k - 1].sqrt() / b[0].abs().powi(k as i32)
            } else {
                drawn_sds[k - 2]
            }
        })
        .collect();
    if coefs.iter().chain(&sds).any(|v| !v.is_finite()) {
        return None;
    }
    Some(Candidate {
        correction: Correction::Polynomial {
            coefs,
            range,
            highpass: hp,
            from_response: true,
        },
        uncertainty: Uncertainty::Polynomial { coefficients: sds },
    })
}

/// An order chosen by [`Sweep::orders`] and its summed check.
type Choice = Option<(usize, f64)>;

/// A sweep's motion and the columns a static response is fitted on.
struct Sweep {
    /// `(x / peak)^k`, k = 1..=[`MAX_ORDER`], each high-passed as the
    /// recovery is (`x` the target with its high-pass undone).
    cols: Vec<Vec<f64>>,
    /// The motion's range on the fit blocks, scaled to its peak: where the
    /// response must rise.
    lo: f64,
    hi: f64,
    /// The recovery's peak with its high-pass undone.
    range: f64,
}

impl Sweep {
    fn read(m: &Model, z: &[f64], fit: &Fit) -> Option<Sweep> {
        let hp = m.opts.highpass;
        let x = undo_highpass(&fit.t, m.fs, hp);
        let peak = x.iter().fold(0.0f64, |a, v| a.max(v.abs()));
        let range = undo_highpass(z, m.fs, hp)
            .iter()
            .fold(0.0f64, |a, v| a.max(v.abs()));
        if !(peak.is_finite() && peak > 0.0 && range.is_finite() && range > 0.0) {
            return None;
        }
        let cols: Vec<Vec<f64>> = (1..=MAX_ORDER as i32)
            .map(|k| {
                redo_highpass(
                    &x.iter().map(|v| (v / peak).powi(k)).collect::<Vec<_>>(),
                    m.fs,
                    hp,
                )
            })
            .collect();
        let (lo, hi) = (0..x.len().min(z.len()))
            .filter(|&i| m.is_fit(i))
            .fold((0.0f64, 0.0f64), |(lo, hi), i| {
                (lo.min(x[i] / peak), hi.max(x[i] / peak))
            });
        Some(Sweep {
            cols,
            lo,
            hi,
            range,
        })
    }

    /// The order (2 to [`MAX_ORDER`]) by three-fold cross-validation
    /// within the fit blocks (0, 2 and 4 of every five): each order is
    /// fitted on two of them and checked on the third, the checks summed.
    /// Two choices from the same fits: `(any, rising)`, the best of every
    /// order, and the best of the orders whose every fit rises over the
    /// motion's range; each the order and its summed check.
    fn orders(&self, m: &Model, z: &[f64]) -> (Choice, Choice) {
        let block = stft_len(m.fs);
        let part = move |i: usize| (i / block) % 5;
        let (mut any, mut rises): (Choice, Choice) = (None, None);
        'orders: for p in 2..=MAX_ORDER {
            let (mut total, mut all_rise) = (0.0, true);
            for held in [0, 2, 4] {
                let train = |i: usize| m.is_fit(i) && part(i) != held;
                let check = |i: usize| part(i) == held && m.is_fit(i);
                let Some((b, ..)) = solve(&self.cols, z, p, &train) else {
                    continue 'orders;
                };
                all_rise &= rising(&b, self.lo, self.hi);
                total += sse(&self.cols, z, &b, &check);
            }
            for (best, counts) in [(&mut any, true), (&mut rises, all_rise)] {
                if counts && best.is_none_or(|(_, e)| total < e) {
                    *best = Some((p, total));
                }
            }
        }
        (any, rises)
    }
}

/// The error (dB) by which a response that folds must beat every response
/// that rises before [`fold`] says it folds.
const FOLD_BETTER_DB: f64 = 1.0;

/// Whether the object's static response, fitted forward as
/// [`fit_polynomial`] fits it but free to fall, stops rising within the
/// sweep: the order chosen by cross-validation falls somewhere in the
/// motion's range, and it explains the recovery (held out within the fit
/// blocks) at least [`FOLD_BETTER_DB`] better than the best response that
/// rises. Two motions then give one image, and no inverse undoes it at
/// the sweep's level; [`fit_polynomial`] keeps none that falls.
pub(super) fn fold(m: &Model, z: &[f64], fit: &Fit) -> Option<Fold> {
    let s = Sweep::read(m, z, fit)?;
    let (any, rises) = s.orders(m, z);
    let (p, free) = any?;
    let rises = rises.map_or(f64::INFINITY, |(_, e)| e);
    let better_db = 10.0 * (rises / free).log10();
    if better_db.is_nan() || better_db < FOLD_BETTER_DB {
        return None;
    }
    let (b, ..) = solve(&s.cols, z, p, &|i| m.is_fit(i))?;
    if rising(&b, s.lo, s.hi) {
        return None;
    }
    // From rest outward on each side, the first step where the slope's
    // sign turns; the nearer of the two.
    let turn = |end: f64| -> Option<f64> {
        (1..=400)
            .map(|i| end * i as f64 / 400.0)
            .find(|&x| slope(&b, x) * b[0] <= 0.0)
    };
    let at = [turn(s.lo), turn(s.hi)]
        .into_iter()
        .flatten()
        .min_by(|a, c| a.abs().total_cmp(&c.abs()))?;
    Some(Fold {
        at,
        response: (1..p).map(|k| b[k] / b[0]).collect(),
        better_db,
    })
}

/// How many motions [`inverse_over_amplitudes`] draws.
const DRAWS: usize = 20_000;

/// The inverse `u + a2 u² + … + a5 u⁵` (recovery units, `[a2, …]`, and
/// each one's standard error) of the response `X + c2 X² + …`
/// (`response = [c2, …]`) by least squares over motions `X` drawn from a
/// Laplace distribution of scale an eighth of `span` (truncated to it),
/// each passed through the response with Gaussian noise of `noise`: the
/// estimate of the motion a recording of that noise allows, at the
/// amplitudes speech spends its time at rather than the sweep's. The
/// draws are seeded (the same fit gives the same inverse). Scaled so
/// that its linear term is 1 (the recovery's scale is the linear
/// model's).
fn inverse_over_amplitudes(
    response: &[f64],
    span: (f64, f64),
    noise: f64,
    range: f64,
) -> Option<(Vec<f64>, Vec<f64>)> {
    let (x0, x1) = span;
    if !(x1 > x0 && noise.is_finite() && range > 0.0) {
        return None;
    }
    let f = |x: f64| -> f64 {
        let mut acc = 0.0;
        for c in response.iter().rev() {
            acc = acc * x + c;
        }
        x + acc * x * x
    };
    let scale = (x1 - x0) / 8.0;
    let mut rng = crate::rng::Xoshiro256::new(62);
    let mut us = Vec::with_capacity(DRAWS);
    let mut xs = Vec::with_capacity(DRAWS);
    while xs.len() < DRAWS {
        let v = rng.next_f64() - 0.5;
        let x = -scale * v.signum() * (1.0 - 2.0 * v.abs()).max(1e-300).ln();
        if !(x > x0 && x < x1) {
            continue;
        }
        // Box-Muller.
        let (a, c) = (rng.next_f64().max(1e-300), rng.next_f64());
        let n = (-2.0 * a.ln()).sqrt() * (2.0 * std::f64::consts::PI * c).cos();
        us.push((f(x) + noise * n) / range);
        xs.push(x);
    }
    let cols: Vec<Vec<f64>> = (1..=MAX_ORDER as i32)
        .map(|k| us.iter().map(|u| u.powi(k)).collect())
        .collect();
    let (a, var, _) = solve(&cols, &xs, MAX_ORDER, &|_| true)?;
    // x ≈ Σ ak (u / range)^k, to u + Σ (ak / a1) u^k / range^(k-1).
    let coefs = (2..=MAX_ORDER)
        .map(|k| a[k - 1] / a[0] / range.powi(k as i32 - 1))
        .collect();
    let sds = (2..=MAX_ORDER)
        .map(|k| var[k - 1].sqrt() / a[0].abs() / range.powi(k as i32 - 1))
        .collect();
    Some((coefs, sds))
}

/// Least squares of `t` on the first `p` columns over the samples `use_i`
/// selects: the coefficients, their variances (residual variance taken
/// as white) and that residual variance.
fn solve(
    cols: &[Vec<f64>],
    t: &[f64],
    p: usize,
    use_i: &dyn Fn(usize) -> bool,
) -> Option<(Vec<f64>, Vec<f64>, f64)> {
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
    Some((b, var, sigma2))
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

/// The response `b1 x + b2 x² + …` keeps the sign of its slope at 0 over
/// `lo..=hi` (the motion's range, scaled to its peak).
fn rising(b: &[f64], lo: f64, hi: f64) -> bool {
    let s0 = slope(b, 0.0);
    (0..=200).all(|i| slope(b, lo + (hi - lo) * i as f64 / 200.0) * s0 > 0.0)
}

/// The slope of the response `b1 x + b2 x² + …` at `x`.
fn slope(b: &[f64], x: f64) -> f64 {
    b.iter()
        .enumerate()
        .map(|(k, bk)| (k + 1) as f64 * bk * x.powi(k as i32))
        .sum()
}
