//! Effect (b): the camera's true frame rate differs from the declared one.

use super::correlation::corr_peak;
use super::model::{Fit, Model};
use super::signal::{curvature_sigma, gain_sse, golden, jackknife};
use super::{Candidate, Correction, Uncertainty};
use nalgebra::{Matrix3, Vector3};

/// The rate error: a grid over ±1% in steps that keep the drift over the
/// fit part under half a sample, each point scored by the best correlation
/// within ±32 samples of lag (the rate is warped about the fit part's
/// centre; for a chirp a delay mimics a rate error, so both are searched
/// together), then a nested golden-section search on rate and fractional
/// delay.
pub(super) fn fit_time_base(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let n = z.len();
    let nf = m.nfit(n);
    let zm = m.masked(z);
    let centre = n as f64 / 2.0;
    let step = 0.5 / n as f64;
    let steps = (0.01 / step).ceil() as i64;
    let score = |e: f64| {
        let t = m.target_about(n, 0, fit.tau, e * 1e6, centre);
        corr_peak(&zm, &t, 32)
    };
    let (mut best, mut best_v, mut best_lag) = (0.0, f64::NEG_INFINITY, 0.0);
    for i in -steps..=steps {
        let e = i as f64 * step;
        let (lag, v) = score(e);
        if v > best_v {
            (best, best_v, best_lag) = (e, v, lag);
        }
    }
    let tau0 = fit.tau + best_lag / m.fs;
    let sse_at = |e: f64| -> f64 {
        golden(
            |t| gain_sse(&m.masked(&m.target_about(n, 0, t, e * 1e6, centre)), &zm).1,
            tau0 - 0.6 / m.fs,
            tau0 + 0.6 / m.fs,
            16,
        )
        .1
    };
    let (e, sse) = golden(sse_at, best - step, best + step, 16);
    let sigma2 = sse / nf as f64;
    let sd = curvature_sigma(sse_at, e, 0.05 / n as f64, sigma2);
    // The curvature's σ assumes a white residual; a coloured one (a
    // transfer function not quite undone, speech's spectrum) makes it far
    // too small, so the larger of it and a delete-one-block jackknife.
    let tau = golden(
        |t| gain_sse(&m.masked(&m.target_about(n, 0, t, e * 1e6, centre)), &zm).1,
        tau0 - 0.6 / m.fs,
        tau0 + 0.6 / m.fs,
        16,
    )
    .0;
    let sd = sd.max(jackknife_sd(m, z, e, tau, centre));
    Some(Candidate {
        correction: Correction::TimeBase { ppm: e * 1e6 },
        uncertainty: Uncertainty::TimeBase {
            clock_error_ppm: sd * 1e6,
        },
    })
}

/// The delete-one-block jackknife's standard deviation of the rate error
/// `e` at the fit `(e, tau)`: the model `g T(e, tau)` linearised in its
/// three parameters, each fit block's share of the normal equations taken
/// out in turn, the step that would move the fit without it solved for.
fn jackknife_sd(m: &Model, z: &[f64], e: f64, tau: f64, centre: f64) -> f64 {
    let n = z.len();
    let target = |e: f64, tau: f64| m.target_about(n, 0, tau, e * 1e6, centre);
    let t = target(e, tau);
    let (g, _) = gain_sse(&m.masked(&t), &m.masked(z));
    let (he, ht) = (0.05 / n as f64, 0.05 / m.fs);
    let (ep, em) = (target(e + he, tau), target(e - he, tau));
    let (tp, tm) = (target(e, tau + ht), target(e, tau - ht));
    let blocks = m.fit_blocks(n);
    let mut parts = Vec::with_capacity(blocks.len());
    for b in &blocks {
        let (mut a, mut s) = (Matrix3::<f64>::zeros(), Vector3::<f64>::zeros());
        for i in b.clone().filter(|&i| m.is_fit(i)) {
            let j = Vector3::new(
                g * (ep[i] - em[i]) / (2.0 * he),
                g * (tp[i] - tm[i]) / (2.0 * ht),
                t[i],
            );
            a += j * j.transpose();
            s += j * (z[i] - g * t[i]);
        }
        parts.push((a, s));
    }
    if parts.len() < 3 {
        return f64::INFINITY;
    }
    let a: Matrix3<f64> = parts.iter().map(|p| p.0).sum();
    let s: Vector3<f64> = parts.iter().map(|p| p.1).sum();
    let Some(whole) = a.lu().solve(&s) else {
        return f64::INFINITY;
    };
    let mut steps = Vec::with_capacity(parts.len());
    for (ab, sb) in &parts {
        match (a - ab).lu().solve(&(s - sb)) {
            Some(d) => steps.push(d[0] - whole[0]),
            None => return f64::INFINITY,
        }
    }
    jackknife(steps.iter().copied())
}
