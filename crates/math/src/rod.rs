//! Clamped rods (thesis ch. 5.4.1): the fundamental by voting over known
//! mode ratios, and Young's modulus or length from it with propagated
//! uncertainty.
//!
//! - **Voting** (Eq. 5.3): P(ω₁ = ω | S) ∝ Π_i S(ω η_i). Changing the
//!   material scales every mode alike, so a spike that is not a mode (mains
//!   hum, camera shake) collects votes at one ratio only, while the true
//!   fundamental collects them at all. As in the thesis the vote runs over
//!   the bins of the *highest* mode (ω = f_N / η_N), which places the
//!   fundamental on a grid η_N times finer than the bins. Two departures,
//!   both stated in the output: the spectrum is first divided by its local
//!   floor (a running median), so the rising floor towards DC cannot vote
//!   for tiny fundamentals; each S(ω η_i) is the largest value within
//!   `ratio_tolerance` of ω η_i, since real rods depart from the ideal
//!   ratios; and each factor saturates at [`VOTE_CAP_DB`] above the floor
//!   (a line 100 times above the floor is as surely a line as one a million
//!   times above it), so one strong non-modal line cannot outvote a set of
//!   modes at the right ratios.
//! - **Refinement** (through the 4th mode): each mode's peak is found near
//!   its predicted frequency (parabolic interpolation in dB), and the
//!   fundamental is the least-squares fit f_i = η_i f₁ over them,
//!   f₁ = Σ η_i f_i / Σ η_i², dominated by the highest mode.
//! - **Young's modulus** (Eq. 5.1, f₁ in Hz): f₁ = 0.1399 (d / L²) √(E/ρ),
//!   so E = ρ (f₁ L² / (0.1399 d))². **Length** (Eq. 5.4):
//!   L = √(0.1399 d η_i / f_i · √(E/ρ)) with f_i / η_i = f₁.
//! - **Errors** (Eq. 5.5): σ_F² = Σ (∂F/∂x)² σ_x² over independent inputs,
//!   derivatives by central differences.

/// Clamped-free rod: ratios of the first four modes to the fundamental
/// (Eq. 5.2; (βₙL)² / (β₁L)² of an Euler-Bernoulli cantilever).
pub const CLAMPED_FREE: [f64; 4] = [1.0, 6.27, 17.55, 34.39];
/// Ceiling of one mode's vote, dB above the local floor.
pub const VOTE_CAP_DB: f64 = 20.0;
/// Eq. 5.1's constant: (β₁L)² / (2π) · 1/4 for a round section (f in Hz).
pub const ROD_CONSTANT: f64 = 0.1399;

/// A spectrum in dB: `db[k]` at `f0_hz + k df_hz`.
#[derive(Clone, Copy, Debug)]
pub struct SpectrumDb<'a> {
    pub db: &'a [f64],
    pub f0_hz: f64,
    pub df_hz: f64,
}

/// One mode found by the vote.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RodMode {
    pub ratio: f64,
    pub predicted_hz: f64,
    pub frequency_hz: f64,
    /// Height above the local floor (dB).
    pub above_floor_db: f64,
}

/// The vote's result.
#[derive(Clone, Debug, serde::Serialize)]
pub struct RodFit {
    /// Least-squares fundamental over the modes (Hz).
    pub fundamental_hz: f64,
    pub fundamental_std_hz: f64,
    /// The fundamental's own peak (Hz), for comparison.
    pub fundamental_peak_hz: f64,
    pub modes: Vec<RodMode>,
    /// Mean height of the modes above the floor at the winning vote, and
    /// the best vote for a fundamental not within 5% of it (dB).
    pub vote_db: f64,
    pub runner_up_db: f64,
    pub runner_up_hz: f64,
}

/// Local floor: running median of `db` over ±max(8 bins, 5% of the bin
/// index), evaluated every few bins and interpolated.
fn floor(db: &[f64]) -> Vec<f64> {
    let n = db.len();
    let half = |k: usize| (k / 20).max(8);
    let mut knots: Vec<(usize, f64)> = Vec::new();
    let mut k = 0;
    while k < n {
        let h = half(k);
        let lo = k.saturating_sub(h);
        let hi = (k + h + 1).min(n);
        let mut w: Vec<f64> = db[lo..hi].to_vec();
        w.sort_by(f64::total_cmp);
        knots.push((k, w[w.len() / 2]));
        if k == n - 1 {
            break;
        }
        k = (k + (h / 4).max(1)).min(n - 1);
    }
    let mut out = vec![0.0; n];
    for pair in knots.windows(2) {
        let ((a, va), (b, vb)) = (pair[0], pair[1]);
        for (j, o) in out.iter_mut().enumerate().take(b + 1).skip(a) {
            let t = (j - a) as f64 / (b - a).max(1) as f64;
            *o = va + t * (vb - va);
        }
    }
    if knots.len() == 1 {
        out.iter_mut().for_each(|o| *o = knots[0].1);
    }
    out
}

/// Largest whitened value within `tol_hz` of `f` and its bin, or None
/// outside the spectrum.
fn best_near(w: &[f64], s: &SpectrumDb, f: f64, tol_hz: f64) -> Option<(usize, f64)> {
    let lo = ((f - tol_hz - s.f0_hz) / s.df_hz).ceil().max(1.0);
    let hi = ((f + tol_hz - s.f0_hz) / s.df_hz).floor();
    let last = (w.len() - 2) as f64;
    if lo > last || hi < 1.0 {
        return None;
    }
    let (lo, hi) = (lo as usize, hi.min(last).max(lo) as usize);
    (lo..=hi)
        .map(|k| (k, w[k]))
        .max_by(|a, b| a.1.total_cmp(&b.1))
}

/// Votes for the fundamental of a rod with mode `ratios` (the first 1).
/// `None` when the spectrum is too short to hold the highest mode above 3
/// bins of fundamental.
pub fn vote(s: &SpectrumDb, ratios: &[f64], ratio_tolerance: f64) -> Option<RodFit> {
    let n = s.db.len();
    if n < 16
        || ratios.is_empty()
        || !(s.df_hz.is_finite() && s.df_hz > 0.0)
        || s.db.iter().any(|v| !v.is_finite())
    {
        return None;
    }
    let top = *ratios.last()?;
    let fl = floor(s.db);
    let w: Vec<f64> = s.db.iter().zip(&fl).map(|(d, f)| d - f).collect();
    let tol = |f: f64| 0.5 * s.df_hz + ratio_tolerance * f;
    // Candidates: every bin of the highest mode whose fundamental is at
    // least 3 bins up.
    let mut votes: Vec<(f64, f64)> = Vec::new();
    for k in 1..n - 1 {
        let f_top = s.f0_hz + k as f64 * s.df_hz;
        let f1 = f_top / top;
        if f1 < s.f0_hz + 3.0 * s.df_hz {
            continue;
        }
        let mut sum = 0.0;
        let mut ok = true;
        for &r in ratios {
            let f = f1 * r;
            // The highest mode is the candidate bin itself.
            let t = if r == top { 0.5 * s.df_hz } else { tol(f) };
            match best_near(&w, s, f, t) {
                Some((_, v)) => sum += v.min(VOTE_CAP_DB),
                None => {
                    ok = false;
                    break;
                }
            }
        }
        if ok {
            votes.push((f1, sum / ratios.len() as f64));
        }
    }
    let &(f1, vote_db) = votes.iter().max_by(|a, b| a.1.total_cmp(&b.1))?;
    let (runner_up_hz, runner_up_db) = votes
        .iter()
        .filter(|(f, _)| (f - f1).abs() > 0.05 * f1)
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .copied()
        .unwrap_or((f64::NAN, f64::NAN));
    // Refinement: each mode's peak near its prediction.
    let mut modes = Vec::new();
    for &r in ratios {
        let pred = f1 * r;
        let (k, v) = best_near(&w, s, pred, tol(pred))?;
        let (ym, y0, yp) = (s.db[k - 1], s.db[k], s.db[k + 1]);
        let den = ym - 2.0 * y0 + yp;
        let d = if den < 0.0 {
            (0.5 * (ym - yp) / den).clamp(-0.5, 0.5)
        } else {
            0.0
        };
        modes.push(RodMode {
            ratio: r,
            predicted_hz: pred,
            frequency_hz: s.f0_hz + (k as f64 + d) * s.df_hz,
            above_floor_db: v,
        });
    }
    let s_eta2: f64 = modes.iter().map(|m| m.ratio * m.ratio).sum();
    let fund = modes.iter().map(|m| m.ratio * m.frequency_hz).sum::<f64>() / s_eta2;
    // Uncertainty: a peak's position is known to about a bin / √12; with
    // several modes, the scatter about the ratios if larger.
    let quant = s.df_hz / 12f64.sqrt();
    let scatter = if modes.len() > 1 {
        let r2: f64 = modes
            .iter()
            .map(|m| (m.frequency_hz - m.ratio * fund).powi(2))
            .sum();
        (r2 / (modes.len() - 1) as f64).sqrt()
    } else {
        0.0
    };
    Some(RodFit {
        fundamental_hz: fund,
        fundamental_std_hz: quant.max(scatter) / s_eta2.sqrt(),
        fundamental_peak_hz: modes[0].frequency_hz,
        modes,
        vote_db,
        runner_up_db,
        runner_up_hz,
    })
}

/// A measured quantity with its standard uncertainty.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Measured {
    pub value: f64,
    pub std: f64,
}

/// Eq. 5.5: value and σ of `f(x)` for independent inputs `x` with σs.
pub fn propagate(f: impl Fn(&[f64]) -> f64, x: &[Measured]) -> Measured {
    let v: Vec<f64> = x.iter().map(|m| m.value).collect();
    let value = f(&v);
    let mut var = 0.0;
    for (i, m) in x.iter().enumerate() {
        if m.std == 0.0 {
            continue;
        }
        let h = 1e-6 * m.value.abs().max(1e-300);
        let mut a = v.clone();
        let mut b = v.clone();
        a[i] += h;
        b[i] -= h;
        let d = (f(&a) - f(&b)) / (2.0 * h);
        var += (d * m.std).powi(2);
    }
    Measured {
        value,
        std: var.sqrt(),
    }
}

/// Young's modulus (Pa) from Eq. 5.1: inputs [f₁ Hz, d m, L m, ρ kg/m³].
pub fn youngs_modulus(x: &[f64]) -> f64 {
    let (f1, d, l, rho) = (x[0], x[1], x[2], x[3]);
    rho * (f1 * l * l / (ROD_CONSTANT * d)).powi(2)
}

/// Length (m) from Eq. 5.4: inputs [f₁ Hz, d m, E Pa, ρ kg/m³].
pub fn length(x: &[f64]) -> f64 {
    let (f1, d, e, rho) = (x[0], x[1], x[2], x[3]);
    (ROD_CONSTANT * d / f1 * (e / rho).sqrt()).sqrt()
}

/// Eq. 5.1 forwards: the fundamental (Hz) of a rod.
pub fn fundamental_hz(d: f64, l: f64, e: f64, rho: f64) -> f64 {
    ROD_CONSTANT * d / (l * l) * (e / rho).sqrt()
}

#[cfg(test)]
mod tests {
    use super::*;

    /// Eq. 5.1 and 5.4 invert each other, and the propagated error of E
    /// follows the power law: σE/E = √((2σf/f)² + (2σd/d)² + (4σL/L)² + (σρ/ρ)²).
    #[test]
    fn modulus_and_length_invert_eq_5_1() {
        let (d, l, e, rho) = (0.00635, 0.5588, 97e9, 8530.0);
        let f1 = fundamental_hz(d, l, e, rho);
        assert!((youngs_modulus(&[f1, d, l, rho]) / e - 1.0).abs() < 1e-12);
        assert!((length(&[f1, d, e, rho]) / l - 1.0).abs() < 1e-12);
        let x = [
            Measured {
                value: f1,
                std: 0.01 * f1,
            },
            Measured {
                value: d,
                std: 0.02 * d,
            },
            Measured {
                value: l,
                std: 0.005 * l,
            },
            Measured {
                value: rho,
                std: 0.03 * rho,
            },
        ];
        let m = propagate(youngs_modulus, &x);
        let want = (0.02f64.powi(2) + 0.04f64.powi(2) + 0.02f64.powi(2) + 0.03f64.powi(2)).sqrt();
        assert!(
            (m.std / m.value / want - 1.0).abs() < 1e-4,
            "{m:?} vs {want}"
        );
    }

    /// Modes at the ratios beat a stronger spike elsewhere.
    #[test]
    fn vote_prefers_the_ratios_over_a_spike() {
        let df = 0.1;
        let f1 = 3.3;
        let db: Vec<f64> = (0..1500)
            .map(|k| {
                let f = k as f64 * df;
                let line = |c: f64, h: f64| h * (-(f - c).powi(2) / (2.0 * 0.1f64.powi(2))).exp();
                CLAMPED_FREE.iter().map(|r| line(f1 * r, 20.0)).sum::<f64>() + line(47.0, 40.0)
            })
            .collect();
        let s = SpectrumDb {
            db: &db,
            f0_hz: 0.0,
            df_hz: df,
        };
        let fit = vote(&s, &CLAMPED_FREE, 0.01).expect("a vote");
        assert!((fit.fundamental_hz - f1).abs() < 0.01, "{fit:?}");
        assert!(vote(&s, &CLAMPED_FREE, 0.01).is_some());
        assert!(vote(&SpectrumDb { db: &[], ..s }, &CLAMPED_FREE, 0.01).is_none());
    }
}
