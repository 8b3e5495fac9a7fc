//! Effect (b): the camera's true frame rate differs from the declared one.

use super::correlation::corr_peak;
use super::model::{Fit, Model};
use super::signal::{curvature_sigma, gain_sse, golden};
use super::{Candidate, Correction, Uncertainty};

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
    Some(Candidate {
        correction: Correction::TimeBase { ppm: e * 1e6 },
        uncertainty: Uncertainty::TimeBase {
            clock_error_ppm: sd * 1e6,
        },
    })
}
