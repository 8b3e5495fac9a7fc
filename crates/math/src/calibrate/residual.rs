//! The residual no accepted effect explains: harmonics of the reference,
//! coherent energy without it, a lag that changes with frequency or time.

use super::correlation::{local_lags, local_window, recurrence};
use super::model::{Fit, Model};
use super::report::{Unexplained, UnexplainedKind};
use super::signal::{alias, dominant, stft, stft_len};
use crate::numeric::median;
use realfft::num_complex::Complex;

/// Share of the residual's energy a structure must hold to be reported.
pub(super) const NOTABLE: f64 = 0.05;

pub(super) fn round_to(v: f64, step: f64) -> f64 {
    (v / step).round() * step
}

/// Describes what is left of `z / g - T`: energy at harmonics of the
/// reference, coherent energy where the reference has none (each reported
/// when it holds at least 5% of the residual's energy), a lag that changes
/// with frequency, a lag that changes over time.
pub(super) fn unexplained(m: &Model, z: &[f64], fit: &Fit) -> Vec<Unexplained> {
    let mut out = Vec::new();
    let g = if fit.g != 0.0 { fit.g } else { 1.0 };
    let zh: Vec<f64> = z.iter().map(|v| v / g).collect();
    let t = &fit.t;
    let res: Vec<f64> = zh.iter().zip(t).map(|(a, b)| a - b).collect();
    let nfft = stft_len(m.fs);
    let df = m.fs / nfft as f64;
    let (fr, ftg, fz) = (stft(&res, nfft), stft(t, nfft), stft(&zh, nfft));
    if fr.is_empty() {
        return out;
    }
    let nb = nfft / 2 + 1;
    let lo_bin = m
        .opts
        .highpass
        .map_or(1, |(_, c)| (1.5 * c / df).ceil() as usize);
    let signal: f64 = ftg
        .iter()
        .flat_map(|f| f.iter().map(|c| c.norm_sqr()))
        .sum::<f64>()
        .max(1e-300);

    let residual: f64 = fr
        .iter()
        .flat_map(|f| f.iter().map(|c| c.norm_sqr()))
        .sum::<f64>()
        .max(1e-300);
    // Per-bin noise floor of the residual: median over frames.
    let floor: Vec<f64> = (0..nb)
        .map(|k| {
            let mut v: Vec<f64> = fr.iter().map(|f| f[k].norm_sqr()).collect();
            median(&mut v)
        })
        .collect();
    let frame_e: Vec<f64> = ftg
        .iter()
        .map(|f| f.iter().map(|c| c.norm_sqr()).sum())
        .collect();
    let emax = frame_e.iter().cloned().fold(0.0, f64::max);
    // Excess cells: residual 10 dB over its floor where the target is 30 dB
    // below its own peak in that frame.
    let mut harm: Vec<(f64, Vec<f64>, Vec<f64>)> = (2..=5).map(|_| (0.0, vec![], vec![])).collect();
    let mut other = vec![0.0; nb];
    for (i, (a, b)) in fr.iter().zip(&ftg).enumerate() {
        if frame_e[i] < 1e-3 * emax {
            continue;
        }
        let (_, pref, fref) = dominant(b, df);
        for k in lo_bin..nb {
            let p = a[k].norm_sqr();
            if b[k].norm_sqr() > 1e-3 * pref || p < 10.0 * floor[k] {
                continue;
            }
            let f = k as f64 * df;
            let excess = p - floor[k];
            match (2..=5).find(|&h| (alias(h as f64 * fref, m.fs) - f).abs() <= 1.5 * df) {
                Some(h) => {
                    let e = &mut harm[h - 2];
                    e.0 += excess;
                    e.1.push(fref);
                    e.2.push(f);
                }
                None => other[k] += excess,
            }
        }
    }
    for (i, (e, refs, fs_)) in harm.iter_mut().enumerate() {
        let h = i + 2;
        let level = 10.0 * (*e / signal).log10();
        if refs.len() < 3 || *e < NOTABLE * residual {
            continue;
        }
        let (rlo, rhi) = (
            refs.iter().cloned().fold(f64::INFINITY, f64::min),
            refs.iter().cloned().fold(0.0, f64::max),
        );
        let mut fl: Vec<f64> = fs_.iter().map(|f| round_to(*f, df)).collect();
        fl.sort_by(|a, b| a.total_cmp(b));
        fl.dedup();
        out.push(Unexplained::Harmonics {
            kind: UnexplainedKind::Harmonics,
            order: h,
            level_db: level,
            reference_hz: [rlo, rhi],
            frequencies_hz: fl,
            description: format!(
                "energy at {h}x the reference's frequency ({:.0}-{:.0} Hz played, heard at {}), {:.1} dB relative to the signal: a nonlinear response of the object or the loudspeaker (or clipping); lower the level, or model it",
                rlo, rhi,
                if h as f64 * rhi > m.fs / 2.0 { "its aliases below fs/2" } else { "those multiples" },
                level
            ),
        });
    }
    // Frequencies where the sweep's gain holds only at its level (read
    // once, on the recording as recovered).
    let level = m.level;
    if let Some(worst) = level.iter().map(|l| l.2).reduce(f64::max) {
        let freqs: Vec<f64> = level.iter().map(|l| l.0 as f64 * df).collect();
        let harmonics_db: Vec<f64> = level.iter().map(|l| l.1).collect();
        let top = harmonics_db
            .iter()
            .cloned()
            .fold(f64::NEG_INFINITY, f64::max);
        // Contiguous runs of bins, as ranges.
        let mut runs: Vec<(f64, f64)> = Vec::new();
        for (i, &(k, ..)) in level.iter().enumerate() {
            match runs.last_mut() {
                Some(r) if i > 0 && level[i - 1].0 + 1 == k => r.1 = k as f64 * df,
                _ => runs.push((k as f64 * df, k as f64 * df)),
            }
        }
        let where_ = runs
            .iter()
            .map(|(a, b)| {
                if a == b {
                    format!("{a:.0} Hz")
                } else {
                    format!("{a:.0}-{b:.0} Hz")
                }
            })
            .collect::<Vec<_>>()
            .join(", ");
        let left = match m.skip.iter().filter(|&&s| s).count() {
            0 => String::new(),
            n => format!(
                "the {:.2} s of the sweep spent there are left out of every fit and of the held-out score, ",
                n as f64 / m.fs
            ),
        };
        out.push(Unexplained::LevelDependent {
            kind: UnexplainedKind::LevelDependent,
            frequencies_hz: freqs,
            harmonics_db,
            max_error_db: worst,
            description: format!(
                "the gain at {where_} holds only at the sweep's level: there the recovery's harmonics reach {top:+.1} dB against its fundamental, a gain error of up to {worst:.1} dB beyond the rest of the band's; the object's response is in its nonlinear range at those frequencies (a resonance driving it into saturation or past a fold), and no linear gain measured at one level carries to a recording at another, so {left}a transfer table fitted on this sweep holds the rest of the band's gain there (its phase interpolated from their neighbours), and nothing here corrects them; sweep at a lower level to measure them"
            ),
        });
    }
    // A static response that stops rising within the sweep (read once).
    if let Some(f) = m.fold {
        let terms: String = f
            .response
            .iter()
            .enumerate()
            .filter(|(_, c)| c.abs() >= 0.005)
            .map(|(i, c)| {
                format!(
                    " {} {:.2} u{}",
                    if *c < 0.0 { '-' } else { '+' },
                    c.abs(),
                    ["²", "³", "⁴", "⁵"].get(i).copied().unwrap_or("ⁿ")
                )
            })
            .collect();
        out.push(Unexplained::ResponseFolds {
            kind: UnexplainedKind::ResponseFolds,
            frequencies_hz: [],
            fold_at: f.at,
            response: f.response.clone(),
            better_db: f.better_db,
            description: format!(
                "the object's response stops rising at {:.2} of the sweep's peak motion ({} side) and falls beyond it: fitted forward, u{terms} (u the motion over the sweep's peak), {:.1} dB closer to the recovery held out than any response that rises; beyond the fold two motions give the same image, so no inverse undoes this sweep's distortion, and a static correction fitted on it can only follow a response that rises; sweep below {:.2} of this level to measure it",
                f.at.abs(),
                if f.at > 0.0 { "positive" } else { "negative" },
                f.better_db,
                f.at.abs()
            ),
        });
    }
    // Coherent energy with no reference: bands of excess energy.
    let total_other: f64 = other.iter().sum();
    if total_other > NOTABLE * residual {
        let mut idx: Vec<usize> = (0..nb).filter(|&k| other[k] > 0.0).collect();
        idx.sort_by(|&a, &b| other[b].total_cmp(&other[a]));
        let mut picked: Vec<usize> = Vec::new();
        for k in idx {
            if picked.iter().all(|&p| p.abs_diff(k) > 2) {
                picked.push(k);
            }
            if picked.len() == 5 {
                break;
            }
        }
        let freqs: Vec<f64> = picked.iter().map(|&k| k as f64 * df).collect();
        let description = format!(
                "energy 10 dB above the residual floor where the reference has none, strongest at {} Hz: vibration from another source (a machine, camera shake, a light's flicker) or aliases of content above fs/2",
                freqs.iter().map(|f| format!("{f:.0}")).collect::<Vec<_>>().join(", ")
            );
        out.push(Unexplained::CoherentWithoutReference {
            kind: UnexplainedKind::CoherentWithoutReference,
            level_db: 10.0 * (total_other / signal).log10(),
            frequencies_hz: freqs,
            description,
        });
    }
    // Lag against frequency: cross-spectral phase where coherent.
    let (mut sxy, mut sxx, mut syy) = (
        vec![Complex::new(0.0, 0.0); nb],
        vec![0.0; nb],
        vec![0.0; nb],
    );
    for (a, b) in fz.iter().zip(&ftg) {
        for k in 0..nb {
            sxy[k] += a[k] * b[k].conj();
            sxx[k] += b[k].norm_sqr();
            syy[k] += a[k].norm_sqr();
        }
    }
    let xmax = sxx.iter().cloned().fold(0.0, f64::max);
    let mut bad: Vec<(f64, f64)> = Vec::new();
    for k in lo_bin..nb.saturating_sub(1) {
        let coh = sxy[k].norm_sqr() / (sxx[k] * syy[k]).max(1e-300);
        if sxx[k] < 1e-3 * xmax || coh < 0.5 {
            continue;
        }
        let ph = sxy[k].arg().to_degrees();
        if ph.abs() > 20.0 {
            bad.push((k as f64 * df, ph));
        }
    }
    if bad.len() >= 2 {
        let worst = bad
            .iter()
            .cloned()
            .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
            .unwrap_or((0.0, 0.0));
        let (flo, fhi) = (bad[0].0, bad[bad.len() - 1].0);
        out.push(Unexplained::LagVsFrequency {
            kind: UnexplainedKind::LagVsFrequency,
            frequencies_hz: [flo, fhi],
            max_phase_deg: worst.1,
            at_hz: worst.0,
            lag_samples_at: worst.1 / 360.0 * m.fs / worst.0.max(1e-9),
            description: format!(
                "phase error beyond 20 degrees at {:.0}-{:.0} Hz (worst {:.0} deg at {:.0} Hz): the delay changes with frequency, as across a resonance; a magnitude equaliser does not undo it (a complex transfer function or a minimum-phase model would)",
                flo, fhi, worst.1, worst.0
            ),
        });
    }
    // Lag over time.
    let pre = 512;
    let t_ext = m.target(z.len() + pre, pre, fit.tau, 0.0);
    let mut lags = local_lags(z, &t_ext, pre, fit.g, z.len(), m.fs);
    // Against a periodic reference (a tone) a window's lag is only known
    // modulo the period: follow it from window to window instead of
    // reading its jumps by whole periods as movement.
    if let Some(p) = recurrence(&m.masked(&fit.t), local_window(m.fs) / 2, false) {
        for i in 1..lags.len() {
            let prev = lags[i - 1].1;
            let l = &mut lags[i].1;
            *l -= ((*l - prev) / p).round() * p;
        }
    }
    if lags.len() >= 3 {
        let lo = lags.iter().map(|l| l.1).fold(f64::INFINITY, f64::min);
        let hi = lags.iter().map(|l| l.1).fold(f64::NEG_INFINITY, f64::max);
        if hi - lo > 0.3 {
            let pts: Vec<(f64, f64)> = lags.iter().map(|&(c, l, _)| (c, l)).collect();
            let slope = theil_sen(&pts).map_or(0.0, |p| p.0);
            out.push(Unexplained::LagOverTime {
                kind: UnexplainedKind::LagOverTime,
                lag_range_samples: [lo, hi],
                drift_ppm: slope * 1e6,
                frequencies_hz: [],
                description: format!(
                    "the delay moves by {:.2} samples over the recording (trend {:.0} ppm): a clock error, dropped frames or a changing path",
                    hi - lo, slope * 1e6
                ),
            });
        }
    }
    out.extend(super::gain_drift::gain_over_time(m, z, fit));
    out
}

/// Theil-Sen slope and intercept of `(x, y)` points.
pub(super) fn theil_sen(p: &[(f64, f64)]) -> Option<(f64, f64)> {
    let mut slopes = Vec::new();
    for i in 0..p.len() {
        for j in i + 1..p.len() {
            if p[j].0 != p[i].0 {
                slopes.push((p[j].1 - p[i].1) / (p[j].0 - p[i].0));
            }
        }
    }
    if slopes.is_empty() {
        return None;
    }
    let s = median(&mut slopes);
    let mut ints: Vec<f64> = p.iter().map(|(x, y)| y - s * x).collect();
    Some((s, median(&mut ints)))
}
