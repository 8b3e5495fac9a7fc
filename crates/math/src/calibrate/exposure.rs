//! Effect (c): the exposure's boxcar low-pass.

use super::model::{eq_sse, Fit, Model};
use super::signal::{curvature_sigma, gain_sse, golden};
use super::{Candidate, Correction, Uncertainty};

pub(super) fn fit_exposure(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let period = 1.0 / m.fs;
    let corr = |e: f64| Correction::Exposure { exposure_s: e };
    let steps = 20;
    let grid: Vec<(f64, f64)> = (0..=steps)
        .map(|i| {
            let e = period * i as f64 / steps as f64;
            let s = if i == 0 {
                gain_sse(&m.masked(&fit.t), &m.masked(z)).1
            } else {
                eq_sse(m, z, fit, &corr(e))
            };
            (e, s)
        })
        .collect();
    let (bi, _) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    if bi == 0 {
        return None;
    }
    let step = period / steps as f64;
    let lo = (grid[bi].0 - step).max(step * 0.1);
    let hi = (grid[bi].0 + step).min(period);
    let (e, sse) = golden(|e| eq_sse(m, z, fit, &corr(e)), lo, hi, 16);
    let nf = m.nfit(z.len());
    let sd = curvature_sigma(
        |x| eq_sse(m, z, fit, &corr(x)),
        e,
        0.02 * period,
        sse / nf as f64,
    );
    Some(Candidate {
        correction: corr(e),
        uncertainty: Uncertainty::Exposure {
            exposure_us: sd * 1e6,
        },
    })
}
