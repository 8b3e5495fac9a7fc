//! Identifiability (issue 15, item 3): once the greedy loop has kept its
//! effects, each is refitted with the others in place (the first kept was
//! fitted before the later ones existed), and each pair of kept effects is
//! checked for a second explanation: the later one fitted alone first,
//! then the other on top. When that explains the recording about as well
//! (within [`super::Options::min_gain_db`] of the held-out SNR) with the
//! later effect's main parameter somewhere else entirely, the pair is
//! reported as confounded, with the range the parameter spans over the
//! two explanations and the reference signal that would separate them.
//! (The alternative is built for every parametric effect of the catalog,
//! kept or not: fitted first, the others refitted on top.) An alternative
//! better by [`super::Options::min_gain_db`] becomes the kept explanation;
//! where either holds a transfer function, the two are judged with its
//! phase made from its gain ([`Confound::passive_snr_db`]), unless the
//! table leaves out level-dependent bins (its gain there is interpolated,
//! and no phase follows from it). Before the pairs, every kept effect
//! must still earn [`super::Options::min_gain_db`] with the others
//! refitted without it ([`let_go`]).

use super::model::Model;
use super::report::{Parameters, UnexplainedKind};
use super::{apply_all, chain, fit_effect, Correction, EffectKind, Kept, Uncertainty};

/// Two kept effects that a second, equally good explanation trades
/// against each other.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Confound {
    pub description: String,
    /// The effect whose parameter is not identified, then the kept effects
    /// it trades against.
    pub effects: Vec<String>,
    /// Held-out SNR (dB) of the effects as kept, and of the alternative.
    pub snr_db: f64,
    pub alternative_snr_db: f64,
    /// The alternative's parameters (the pair, in the same order).
    pub alternative: Vec<Parameters>,
    /// The first effect's main parameter, and the range it spans over the
    /// two explanations (each end widened by its own standard deviation):
    /// a joint uncertainty that the single-model one understates.
    pub parameter: String,
    /// Its value as kept, and in the alternative.
    pub values: [f64; 2],
    pub range: [f64; 2],
    /// A reference signal that would tell the two apart.
    pub separate_with: String,
    /// Where either explanation holds a transfer function: the held-out
    /// SNR (dB) of each (as kept, the alternative) with that function's
    /// phase made from its gain (minimum phase). The pair is judged on
    /// these instead of `snr_db` and `alternative_snr_db`.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub passive_snr_db: Option<[f64; 2]>,
}

impl Confound {
    /// Writes `description` from the fields.
    pub(super) fn describe(&mut self) {
        let a = self.effects.first().map_or("", String::as_str);
        let b = self.effects[1..].join(" and ");
        let p = &self.parameter;
        self.description = format!(
            "{a} is confounded with {b}: two explanations fit, {p} {:.4} as kept (held-out SNR {:.2} dB) and {p} {:.4} with {a} fitted first and the others on top ({:.2} dB); {p} is only known to lie in [{:.4}, {:.4}]. To separate them: {}",
            self.values[0],
            self.snr_db,
            self.values[1],
            self.alternative_snr_db,
            self.range[0],
            self.range[1],
            self.separate_with
        );
        if let Some([a, b]) = self.passive_snr_db {
            self.description.push_str(&format!(
                ". Judged with each transfer function's phase made from its gain (an object's response is minimum phase up to a delay; a drifting gain or a clock error can take a resonance's gain or phase on one sweep, leaving a phase no object has): {a:.2} dB as kept, {b:.2} dB for the alternative"
            ));
        }
    }

    /// The alternative became the kept explanation: the numbers trade
    /// places.
    pub(super) fn swap(&mut self, kept_params: Vec<Parameters>) {
        std::mem::swap(&mut self.snr_db, &mut self.alternative_snr_db);
        if let Some(p) = self.passive_snr_db.as_mut() {
            p.swap(0, 1);
        }
        self.values.swap(0, 1);
        self.alternative = kept_params;
        self.describe();
    }
}

/// Effects with a continuous parameter that a refit can move (events and
/// lines are placed, not traded).
fn parametric(k: EffectKind) -> bool {
    !matches!(k, EffectKind::Frames | EffectKind::Interference)
}

/// The one number that says where an effect is, with its standard
/// deviation, in the units it is reported in.
fn main_parameter(c: &Correction, u: &Uncertainty, gain: f64) -> Option<(&'static str, f64, f64)> {
    Some(match (c, u) {
        (Correction::TimeBase { ppm }, Uncertainty::TimeBase { clock_error_ppm }) => {
            ("clock_error_ppm", *ppm, *clock_error_ppm)
        }
        (Correction::Exposure { exposure_s }, Uncertainty::Exposure { exposure_us }) => {
            ("exposure_us", exposure_s * 1e6, *exposure_us)
        }
        (Correction::Transfer { k, .. }, Uncertainty::Transfer { k: sd, .. }) => ("k", *k, *sd),
        (
            Correction::SoftClip { level, .. },
            Uncertainty::SoftClip {
                level_in_reference_units,
                ..
            },
        ) => (
            "level_in_reference_units",
            *level,
            *level_in_reference_units,
        ),
        (Correction::Polynomial { coefs, .. }, Uncertainty::Polynomial { coefficients }) => (
            "inverse_square_term",
            coefs.first()? * gain,
            coefficients.first()? * gain.abs(),
        ),
        (
            Correction::GainDrift {
                start_to_end_db, ..
            },
            Uncertainty::GainDrift { coefficients },
        ) => {
            // End minus start of a Legendre series is 2 (c1 + c3 + ...).
            let odd: f64 = coefficients.iter().skip(1).step_by(2).map(|v| v * v).sum();
            (
                "start_to_end_db",
                *start_to_end_db,
                20.0 / std::f64::consts::LN_10 * 2.0 * odd.sqrt(),
            )
        }
        _ => return None,
    })
}

/// The reference that separates `a` from `b`.
fn separating_reference(a: EffectKind, b: EffectKind) -> &'static str {
    use EffectKind as E;
    let pair = |x: E, y: E| (a == x && b == y) || (a == y && b == x);
    if pair(E::TimeBase, E::Transfer)
        || pair(E::TimeBase, E::Exposure)
        || pair(E::TimeBase, E::Frames)
    {
        "a reference whose frequencies repeat over time (two sweeps one after the other, or a sweep with a click as a time marker): a clock error moves the lag with time, a resonance or a filter with frequency"
    } else if pair(E::GainDrift, E::Exposure) || pair(E::GainDrift, E::Transfer) {
        "a reference whose frequencies repeat over time (two sweeps, or noise): a drifting gain changes with time, a filter with frequency"
    } else if pair(E::Exposure, E::Transfer) {
        "a sweep past the exposure's first null (1/E): a boxcar has nulls a resonance does not"
    } else {
        "two references of different kinds (a sweep and noise, or sweeps at different rates), so the two effects leave different traces"
    }
}

/// The held-out SNR (dB) of the recovery `y` with the corrections of
/// `kept` applied, the linear model refitted.
fn held_snr(m: &Model, y: &[f64], kept: &[Kept]) -> f64 {
    let z = apply_all(&chain(kept), y, m.fs);
    m.errors(&z, &m.fit_linear(&z)).snr_db
}

/// Refits each kept parametric effect with the others applied (twice over
/// the list), keeping a refit only when the held-out SNR does not fall.
pub(super) fn refit(m: &Model, y: &[f64], kept: &mut [Kept]) -> f64 {
    let snr = |kept: &[Kept]| held_snr(m, y, kept);
    let mut cur = snr(kept);
    for _ in 0..2 {
        for i in 0..kept.len() {
            let kind = kept[i].c.correction.kind();
            if !parametric(kind) || kept.len() < 2 {
                continue;
            }
            let others: Vec<Kept> = kept
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != i)
                .map(|(_, k)| k.clone())
                .collect();
            let w = apply_all(&chain(&others), y, m.fs);
            let Some(c) = fit_effect(kind, m, &w, &m.fit_linear(&w)) else {
                continue;
            };
            let old = std::mem::replace(&mut kept[i].c, c);
            let s = snr(kept);
            if s.is_finite() && s >= cur - 0.05 {
                cur = s;
            } else {
                kept[i].c = old;
            }
        }
    }
    cur
}

/// Every kept effect must still earn its place with the others refitted
/// without it: one kept early that a later one explains better (a clock
/// error read from a resonance's phase before the transfer function took
/// it) is let go when the held-out SNR loses less than `min_gain_db`
/// without it, the least needed first, the rest refitted each time
/// (together, or the last one alone on the recovery; a refit kept only
/// where it does not lower the held-out SNR). Returns each effect let go
/// with what the held-out SNR lost without it.
pub(super) fn let_go(
    m: &Model,
    y: &[f64],
    kept: &mut Vec<Kept>,
    min_gain_db: f64,
) -> Vec<(Kept, f64)> {
    let snr = |ks: &[Kept]| held_snr(m, y, ks);
    let settle = |ks: &mut Vec<Kept>| {
        if ks.len() > 1 {
            refit(m, y, ks);
        } else if let Some(k) = ks.first_mut() {
            if let Some(c) = fit_effect(k.c.correction.kind(), m, y, &m.fit_linear(y)) {
                let before = snr(std::slice::from_ref(k));
                let old = std::mem::replace(&mut k.c, c);
                let after = snr(std::slice::from_ref(k));
                if after.is_nan() || after < before - 0.05 {
                    k.c = old;
                }
            }
        }
    };
    let mut out = Vec::new();
    while kept.len() > 1 {
        let cur = snr(kept);
        let without = |i: usize| {
            let mut others: Vec<Kept> = kept
                .iter()
                .enumerate()
                .filter(|&(j, _)| j != i)
                .map(|(_, k)| k.clone())
                .collect();
            settle(&mut others);
            cur - snr(&others)
        };
        let Some((i, loss)) = (0..kept.len())
            .map(|i| (i, without(i)))
            .filter(|(_, l)| l.is_finite())
            .min_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        if loss >= min_gain_db {
            break;
        }
        out.push((kept.remove(i), loss));
        settle(kept);
    }
    out
}

/// How many standard deviations from its neutral value a kept effect's
/// main parameter must lie for the effect to be told from none.
pub(super) const SIGNIFICANT_SD: f64 = 3.0;

/// Kept effects whose main parameter lies within [`SIGNIFICANT_SD`]
/// standard deviations of its neutral value (a clock error, an exposure, a
/// transfer function's `k` or a drift that the recording cannot tell from
/// none; not a polynomial, whose square term is zero for an odd response)
/// are let go, the least significant first, the rest refitted each time:
/// what such an effect gains held out is the noise of this recording,
/// and on the next one it is an error. Returns each with its distance from
/// neutral in standard deviations and the held-out SNR lost without it.
pub(super) fn insignificant(m: &Model, y: &[f64], kept: &mut Vec<Kept>) -> Vec<(Kept, f64, f64)> {
    let mut out = Vec::new();
    loop {
        let z = apply_all(&chain(kept), y, m.fs);
        let fit = m.fit_linear(&z);
        let Some((i, d)) = kept
            .iter()
            .enumerate()
            .filter_map(|(i, k)| {
                let kind = k.c.correction.kind();
                if kind == EffectKind::Polynomial {
                    return None;
                }
                let (_, v, sd) = main_parameter(&k.c.correction, &k.c.uncertainty, fit.g)?;
                let d = (v - neutral(kind)?).abs() / sd;
                (sd > 0.0 && d.is_finite() && d < SIGNIFICANT_SD).then_some((i, d))
            })
            .min_by(|a, b| a.1.total_cmp(&b.1))
        else {
            break;
        };
        // The held-out SNR with it: `held_snr` of the set, from the fit above.
        let before = m.errors(&z, &fit).snr_db;
        let k = kept.remove(i);
        if kept.len() > 1 {
            refit(m, y, kept);
        }
        out.push((k, d, before - held_snr(m, y, kept)));
    }
    out
}

/// The value a main parameter has when its effect is absent (no clock
/// error, no exposure, no equalising, no square term, no drift); `None`
/// where absence is not a value (a saturation level).
fn neutral(k: EffectKind) -> Option<f64> {
    match k {
        EffectKind::TimeBase
        | EffectKind::Exposure
        | EffectKind::Transfer
        | EffectKind::Polynomial
        | EffectKind::GainDrift => Some(0.0),
        _ => None,
    }
}

/// The second explanations of the recording (see the module docs): for
/// each parametric effect `E` of the catalog, `E` fitted first on the
/// recovery as delivered, then each kept effect refitted on top in the
/// order kept (dropped when it no longer gains). Where that explains the
/// held-out part about as well as the kept set (or better) with `E`'s main
/// parameter far from its kept value (its neutral value when `E` was not
/// kept), the effects are confounded. Each comes with the alternative's
/// kept list.
pub(super) fn confounds(
    m: &Model,
    y: &[f64],
    kept: &[Kept],
    cur_snr: f64,
    gain: f64,
    gates: &[UnexplainedKind],
) -> Vec<(Confound, Vec<Kept>)> {
    let snr = |z: &[f64]| m.errors(z, &m.fit_linear(z)).snr_db;
    let mut out = Vec::new();
    for &e in &m.opts.effects {
        // The families the greedy loop gates on their residual structure
        // (in the linear model's residual) are gated here too.
        let gated = match e {
            EffectKind::Polynomial => !gates.contains(&UnexplainedKind::Harmonics),
            EffectKind::GainDrift => !gates.contains(&UnexplainedKind::GainOverTime),
            _ => false,
        };
        // Soft clipping and the polynomial are one family, already
        // chosen between (the simpler unless the other gains more).
        let nonlinear = |k: EffectKind| matches!(k, EffectKind::SoftClip | EffectKind::Polynomial);
        let same_family = nonlinear(e)
            && kept
                .iter()
                .any(|k| k.c.correction.kind() != e && nonlinear(k.c.correction.kind()));
        if !parametric(e) || gated || same_family {
            continue;
        }
        let mine = kept.iter().find(|k| k.c.correction.kind() == e);
        let (pb, sb) = match mine {
            Some(k) => match main_parameter(&k.c.correction, &k.c.uncertainty, gain) {
                Some((_, v, sd)) => (v, sd),
                None => continue,
            },
            None => match neutral(e) {
                Some(v) => (v, 0.0),
                None => continue,
            },
        };
        let fit0 = m.fit_linear(y);
        let Some(ce) = fit_effect(e, m, y, &fit0) else {
            continue;
        };
        let mut z = ce.correction.apply(y, m.fs);
        let mut s = snr(&z);
        // An alternative needs E to explain something on its own.
        let own = s - snr(y);
        if own.is_nan() || own < m.opts.min_gain_db {
            continue;
        }
        let mut alt = vec![Kept {
            c: ce.clone(),
            gain: s - snr(y),
            evidence: mine.map(|k| k.evidence.clone()).unwrap_or_default(),
        }];
        for k in kept.iter().filter(|k| k.c.correction.kind() != e) {
            let Some(mut c) = fit_effect(k.c.correction.kind(), m, &z, &m.fit_linear(&z)) else {
                continue;
            };
            let z2 = c.correction.apply(&z, m.fs);
            // Lines are applied first (to the recovery as delivered): as
            // the greedy loop does, move them back through what came before.
            if let Correction::Interference { lines } = &mut c.correction {
                let up = chain(&alt);
                for l in lines.iter_mut() {
                    *l = Correction::line_before(*l, &up, m.fs);
                }
            }
            let s2 = snr(&z2);
            if s2 - s >= m.opts.min_gain_db {
                alt.push(Kept {
                    c,
                    gain: s2 - s,
                    evidence: k.evidence.clone(),
                });
                (z, s) = (z2, s2);
            }
        }
        let fit_alt = m.fit_linear(&z);
        let Some((name, pb2, sb2)) = main_parameter(&ce.correction, &ce.uncertainty, fit_alt.g)
        else {
            continue;
        };
        let apart = (pb2 - pb).abs() > 3.0 * sb.max(sb2);
        if !(s.is_finite() && s >= cur_snr - m.opts.min_gain_db && apart) {
            continue;
        }
        // The kept effects the alternative trades E against.
        let others: Vec<EffectKind> = kept
            .iter()
            .map(|k| k.c.correction.kind())
            .filter(|&k| k != e)
            .collect();
        let Some(&partner) = others.first() else {
            continue;
        };
        let range = [(pb - sb).min(pb2 - sb2), (pb + sb).max(pb2 + sb2)];
        let mut effects = vec![e.name().to_string()];
        effects.extend(others.iter().map(|k| k.name().to_string()));
        let alternative: Vec<Parameters> = chain(&alt)
            .iter()
            .map(|c| c.parameters(m.fs, fit_alt.g))
            .collect();
        let mut c = Confound {
            description: String::new(),
            effects,
            snr_db: cur_snr,
            alternative_snr_db: s,
            alternative,
            parameter: format!("{}.{name}", e.name()),
            values: [pb, pb2],
            range,
            separate_with: separating_reference(e, partner).to_string(),
            passive_snr_db: None,
        };
        c.describe();
        out.push((c, alt));
    }
    out
}
