//! Effect (f): the response saturates softly (`L tanh(x / L)`).

use super::model::{Fit, Model};
use super::signal::{curvature_sigma, gain_sse, golden, redo_highpass, undo_highpass};
use super::{Candidate, Correction, Uncertainty};

/// The odd-order inverse of a saturation, by linear least squares on the
/// fit part: with `u` the recovery with its high-pass undone,
/// `T ≈ HP(b1 u + b3 u³ + b5 u⁵)`, so `a3 = b3 / b1`, `a5 = b5 / b1` (the
/// quintic term is dropped when it is negative or would make the inverse
/// fold back within the recovery's range). A polynomial rather than
/// `L atanh(u / L)`: the exact inverse amplifies the noise at the peaks by
/// `1 / (1 - (u / L)²)`, which at this effect's levels costs more than the harmonics it
/// removes; least squares picks the trade-off. `None` unless the inverse
/// expands (`a3 > 0`), as undoing a saturation must.
pub(super) fn fit_soft_clip(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let hp = m.opts.highpass;
    let u = undo_highpass(z, m.fs, hp);
    let peak = u.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    if peak.is_nan() || peak <= 0.0 {
        return None;
    }
    // Columns u, u³, u⁵ (scaled to the peak for conditioning), each
    // high-passed as the target is.
    let col = |k: i32| {
        redo_highpass(
            &u.iter().map(|v| (v / peak).powi(k)).collect::<Vec<_>>(),
            m.fs,
            hp,
        )
    };
    let (c1, c3, c5) = (col(1), col(3), col(5));
    let cols = |p: usize| -> Vec<[f64; 3]> {
        (0..u.len())
            .map(|i| [c1[i], c3[i], if p == 5 { c5[i] } else { 0.0 }])
            .collect()
    };
    let solve = |p: usize| -> Option<([f64; 3], [f64; 3], f64)> {
        let x = cols(p);
        let dim = if p == 5 { 3 } else { 2 };
        let mut a = [[0.0; 3]; 3];
        let mut rhs = [0.0; 3];
        for (i, row) in x.iter().enumerate() {
            if !m.is_fit(i) {
                continue;
            }
            for r in 0..dim {
                rhs[r] += row[r] * fit.t[i];
                for c in 0..dim {
                    a[r][c] += row[r] * row[c];
                }
            }
        }
        // The inverse of the leading `dim` x `dim` block (zero elsewhere).
        let block = nalgebra::DMatrix::from_fn(dim, dim, |r, c| a[r][c])
            .lu()
            .try_inverse()?;
        let mut inv = [[0.0; 3]; 3];
        for r in 0..dim {
            for c in 0..dim {
                inv[r][c] = block[(r, c)];
            }
        }
        let mut b = [0.0; 3];
        for r in 0..dim {
            b[r] = (0..dim).map(|c| inv[r][c] * rhs[c]).sum();
        }
        let sse: f64 = x
            .iter()
            .enumerate()
            .filter(|(i, _)| m.is_fit(*i))
            .map(|(i, row)| (fit.t[i] - (0..dim).map(|c| b[c] * row[c]).sum::<f64>()).powi(2))
            .sum();
        let sigma2 = sse / m.nfit(z.len()) as f64;
        let var = [inv[0][0] * sigma2, inv[1][1] * sigma2, inv[2][2] * sigma2];
        Some((b, var, sse))
    };
    // Monotonic on |u| <= 1: 1 + 3 a3 u² + 5 a5 u⁴ > 0.
    let monotonic = |a3: f64, a5: f64| {
        (0..=100).all(|i| {
            let w = (i as f64 / 100.0).powi(2);
            1.0 + 3.0 * a3 * w + 5.0 * a5 * w * w > 0.0
        })
    };
    let (b, var, _) = match solve(5) {
        // The inverse of a saturation expands: atanh's series has every
        // odd term positive; a negative quintic is something else.
        Some((b, v, e))
            if b[0] != 0.0 && b[2] / b[0] >= 0.0 && monotonic(b[1] / b[0], b[2] / b[0]) =>
        {
            (b, v, e)
        }
        _ => solve(3)?,
    };
    if b[0] == 0.0 {
        return None;
    }
    let (a3, a5) = (b[1] / b[0], b[2] / b[0]);
    if a3.is_nan() || a3 <= 0.0 {
        return None;
    }
    // The level itself by the forward model, which the recovery's noise
    // does not bias (the polynomial's trade-off with the noise does):
    // `z ≈ g HP(L tanh(r / L))` on the fit part, L on a geometric grid from
    // a quarter to four times the reference's peak, then golden section.
    let rpk = m.r.iter().fold(0.0f64, |a, v| a.max(v.abs()));
    let zm = m.masked(z);
    let raw = m.unfiltered_target(z.len(), fit.tau);
    let sse = |l: f64| {
        let t = redo_highpass(
            &raw.iter().map(|v| l * (v / l).tanh()).collect::<Vec<_>>(),
            m.fs,
            hp,
        );
        gain_sse(&m.masked(&t), &zm).1
    };
    let level_at = |i: usize| 0.25 * rpk * 16f64.powf(i as f64 / 32.0);
    let grid: Vec<f64> = (0..=32).map(|i| sse(level_at(i))).collect();
    let (bi, _) = grid.iter().enumerate().min_by(|a, b| a.1.total_cmp(b.1))?;
    let (level, best) = golden(
        sse,
        level_at(bi.saturating_sub(1)),
        level_at((bi + 1).min(32)),
        20,
    );
    let nf = m.nfit(z.len());
    let level_sd = curvature_sigma(sse, level, 0.01 * level, best / nf as f64);
    Some(Candidate {
        correction: Correction::SoftClip {
            a3: a3 / peak.powi(2),
            a5: a5 / peak.powi(4),
            level,
            range: peak,
            highpass: hp,
        },
        uncertainty: Uncertainty::SoftClip {
            a3: var[1].sqrt() / b[0].abs() / peak.powi(2),
            a5: var[2].sqrt() / b[0].abs() / peak.powi(4),
            level_in_reference_units: level_sd,
        },
    })
}
