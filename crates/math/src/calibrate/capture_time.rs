//! Family (i): the time at which the motion is seen changes across the
//! image. The residual's image axis: the region is recovered as horizontal
//! strips of rows ([`Strips`]) and each strip's delay against the
//! reference is measured on its own, less the region's, with an
//! uncertainty from the spread of that difference over the fit blocks (a
//! delete-one-block jackknife: a coloured residual widens it as it should,
//! and what moves every strip at once cancels). Delays that differ across
//! the rows by more
//! than that noise (a chi-square test at 1e-3) mean the rows were captured
//! at different times (a rolling shutter read out while the camera
//! declared a global one) or the parts of the object heard the sound at
//! different times (two objects, a non-rigid one).
//!
//! The family's members, each a delay per strip applied before the strips
//! are summed: `linear`, a delay proportional to the row (one parameter,
//! the time per row), and `per_region`, each strip's own delay (a step
//! between two objects). Both sum the strips by maximal-ratio combining
//! (each weighted by its gain over its noise variance, on the fit part),
//! each strip's sign taken from the recording ([`combine`]), and both are
//! scored against the same sum without delays, so the gain is the
//! timing's alone. The linear member is kept unless the per-region one
//! gains [`super::Options::min_gain_db`] more.

use super::correlation::recurrence;
use super::gain_drift::chi2_level;
use super::model::{Fit, Model};
use super::report::{Unexplained, UnexplainedKind};
use super::signal::{gain_sse, jackknife, redo_highpass, sample_at, stft_len, undo_highpass};
use super::{Candidate, Correction, Uncertainty};
use rustfft::num_complex::Complex;

/// Recoveries of horizontal strips of the region: the image's row axis.
#[derive(Clone, Debug, PartialEq)]
pub struct Strips {
    /// First and end row (exclusive) of each strip, image pixels.
    pub rows: Vec<(u32, u32)>,
    /// Each strip's recovery at the frame rate, as long as the region's.
    pub signals: Vec<Vec<f64>>,
    /// Each strip's bands before they are aligned and summed (its `phase`
    /// stage's channels, not high-passed), or empty. A strip's recovery
    /// takes its polarity from the band its `align` stage chose, and a
    /// band whose orientation is across the motion sees it with a sign
    /// that depends on the texture; the bands tell the parts' physical
    /// signs ([`physical_signs`]).
    pub bands: Vec<Vec<Vec<f64>>>,
}

/// One strip's linear model against the target.
#[derive(Clone, Debug)]
pub(super) struct StripFit {
    /// The strip's central row.
    pub(super) centre: f64,
    /// Its delay (s) less the region's.
    pub(super) lag_s: f64,
    /// One standard deviation of `lag_s` (jackknife over fit blocks);
    /// infinite when the strip holds no usable signal.
    pub(super) sigma_s: f64,
    pub(super) gain: f64,
    /// Residual variance on the fit part.
    pub(super) noise: f64,
    /// The fit's matched-filter SNR (amplitude; 0 without a fit).
    pub(super) snr: f64,
}

impl StripFit {
    /// The maximal-ratio weight: gain over noise variance.
    pub(super) fn weight(&self) -> f64 {
        if self.noise > 0.0 && self.gain.is_finite() {
            self.gain / self.noise
        } else {
            0.0
        }
    }
}

/// Gauss-Newton iterations of each strip's delay.
const ITERATIONS: usize = 3;
/// A strip's delay counts when its fit's matched-filter SNR (amplitude)
/// reaches this: below it the delay is noise.
const MIN_STRIP_SNR: f64 = 5.0;

/// Each strip's delay, gain and noise against the target. A strip's delay
/// is taken less the region's (`y`, its recovery, fitted the same way), and
/// its uncertainty is the jackknife of that difference over the fit
/// blocks: what moves every strip at once (a drifting clock, a tone's pitch
/// off its nominal value) cancels, as it does in the delays' spread.
pub(super) fn read(m: &Model, y: &[f64], strips: &Strips, fit: &Fit) -> Vec<StripFit> {
    let w = search_width(m, fit);
    let region = strip_fit(m, y, fit.tau);
    strips
        .signals
        .iter()
        .zip(&strips.rows)
        .map(|(s, &(a, b))| {
            let centre = 0.5 * (a as f64 + b as f64 - 1.0);
            let none = StripFit {
                centre,
                lag_s: 0.0,
                sigma_s: f64::INFINITY,
                gain: 0.0,
                noise: 0.0,
                snr: 0.0,
            };
            // Each strip's own delay near the region's (a part may lag it
            // by samples), then refined.
            let Some(t) = strip_fit(m, s, nearest_peak(m, s, fit, w)) else {
                return none;
            };
            let (lag_s, sigma_s) = match &region {
                Some(r) if r.loo.len() == t.loo.len() => (
                    t.tau - r.tau,
                    jackknife(t.loo.iter().zip(&r.loo).map(|(a, b)| a - b)),
                ),
                _ => (t.tau - fit.tau, jackknife(t.loo.iter().copied())),
            };
            StripFit {
                centre,
                lag_s,
                sigma_s: if t.snr >= MIN_STRIP_SNR {
                    sigma_s
                } else {
                    f64::INFINITY
                },
                gain: t.gain,
                noise: t.noise,
                snr: t.snr,
            }
        })
        .collect()
}

/// The widest spread of delays across the image searched: 5 ms (sound
/// crosses 1.7 m in that time), or a frame period if longer (a rolling
/// shutter reads the frame out within one).
pub(super) const MAX_SPREAD_S: f64 = 5e-3;

/// The delay of the strongest correlation (either sign: a strip may see
/// the motion inverted) of `y` with the target within `w` samples of the
/// region's delay.
fn nearest_peak(m: &Model, y: &[f64], fit: &Fit, w: isize) -> f64 {
    let n = y.len().min(fit.t.len());
    let t = &fit.t;
    let score = |l: isize| {
        // y(i) ≈ g T(i - l): a strip `l` samples later.
        let (mut yt, mut tt) = (0.0, 0.0);
        for i in (0..n as isize).filter(|&i| m.is_fit(i as usize)) {
            let j = i - l;
            if (0..n as isize).contains(&j) {
                let v = t[j as usize];
                yt += y[i as usize] * v;
                tt += v * v;
            }
        }
        if tt > 0.0 {
            yt.abs() / tt.sqrt()
        } else {
            0.0
        }
    };
    let best = (-w..=w)
        .map(|l| (l, score(l)))
        .max_by(|a, b| a.1.total_cmp(&b.1))
        .map_or(0, |(l, _)| l);
    fit.tau + best as f64 / m.fs
}

/// How far (whole samples) a strip's delay is searched from the region's:
/// [`MAX_SPREAD_S`] or a frame period, and less than half the lag at which
/// the target first resembles itself again (|autocorrelation| at a local
/// peak of at least 0.8), since beyond it the delay is ambiguous: a tone's
/// is only known modulo half a period, its sign free.
fn search_width(m: &Model, fit: &Fit) -> isize {
    let w = (MAX_SPREAD_S.max(1.0 / m.fs) * m.fs).ceil() as isize;
    match recurrence(&m.masked(&fit.t), 2 * w as usize + 1, true) {
        Some(l) => w.min((l.round() as isize - 1) / 2),
        None => w,
    }
}

/// A signal's linear model against the target: the delay, the delays
/// with each fit block left out in turn (every fit block, in order, so
/// that two signals' lists pair up), the gain, the residual variance and
/// the fit's matched-filter SNR (amplitude).
struct Timed {
    tau: f64,
    loo: Vec<f64>,
    gain: f64,
    noise: f64,
    snr: f64,
}

/// [`Timed`] for `y ≈ g T(τ)`: Gauss-Newton on the delay (`y ≈ g T + c
/// ∂T/∂τ`, so `δτ = c / g`), from `tau0`, on the fit part.
fn strip_fit(m: &Model, y: &[f64], tau0: f64) -> Option<Timed> {
    let n = y.len();
    let block = stft_len(m.fs);
    let h = 0.05 / m.fs;
    let mut tau = tau0;
    for it in 0..ITERATIONS {
        let t = m.target(n, 0, tau, 0.0);
        let (tp, tm) = (m.target(n, 0, tau + h, 0.0), m.target(n, 0, tau - h, 0.0));
        // Per block: Σyy, Σyt, Σyd, Σtt, Σtd, Σdd over its fit samples.
        let mut sums: Vec<[f64; 6]> = vec![[0.0; 6]; n.div_ceil(block)];
        for i in (0..n).filter(|&i| m.is_fit(i)) {
            let d = (tp[i] - tm[i]) / (2.0 * h);
            let s = &mut sums[i / block];
            let (yv, tv) = (y[i], t[i]);
            s[0] += yv * yv;
            s[1] += yv * tv;
            s[2] += yv * d;
            s[3] += tv * tv;
            s[4] += tv * d;
            s[5] += d * d;
        }
        // The fit blocks (the same for every signal of this length).
        let sums: Vec<[f64; 6]> = sums
            .into_iter()
            .enumerate()
            .filter(|(b, _)| m.is_fit(b * block))
            .map(|(_, s)| s)
            .collect();
        let total = sums.iter().fold([0.0; 6], |mut acc, s| {
            acc.iter_mut().zip(s).for_each(|(a, b)| *a += b);
            acc
        });
        let (g, c) = solve(&total)?;
        let delta = (c / g).clamp(-0.5 / m.fs, 0.5 / m.fs);
        if it + 1 < ITERATIONS {
            tau += delta;
            continue;
        }
        if sums.len() < 3 {
            return None;
        }
        let loo = sums
            .iter()
            .map(|s| {
                let mut r = total;
                r.iter_mut().zip(s).for_each(|(a, b)| *a -= b);
                solve(&r).map(|(g, c)| tau + c / g)
            })
            .collect::<Option<Vec<f64>>>()?;
        let noise = (total[0] - g * total[1] - c * total[2]).max(0.0) / m.nfit(n) as f64;
        return Some(Timed {
            tau: tau + delta,
            loo,
            gain: g,
            noise,
            snr: g.abs() * total[3].sqrt() / noise.sqrt().max(1e-300),
        });
    }
    None
}

/// `(g, c)` of the 2x2 normal equations in `s` (Σyy, Σyt, Σyd, Σtt, Σtd, Σdd).
fn solve(s: &[f64; 6]) -> Option<(f64, f64)> {
    let det = s[3] * s[5] - s[4] * s[4];
    if det.is_nan() || det <= 0.0 {
        return None;
    }
    let g = (s[1] * s[5] - s[2] * s[4]) / det;
    let c = (s[2] * s[3] - s[1] * s[4]) / det;
    (g != 0.0 && g.is_finite() && c.is_finite()).then_some((g, c))
}

/// The strips whose delay is measured (finite σ), as (centre, lag, 1/σ²).
fn usable(fits: &[StripFit]) -> Vec<(f64, f64, f64)> {
    fits.iter()
        .filter(|f| f.sigma_s.is_finite() && f.sigma_s > 0.0)
        .map(|f| (f.centre, f.lag_s, 1.0 / (f.sigma_s * f.sigma_s)))
        .collect()
}

/// Weighted least-squares line `lag = a + b (row - c̄)` through the usable
/// strips, with the slope's σ (widened by the line's misfit), the chi-
/// squares about the mean and about the line, and the strips' count.
pub(super) struct Line {
    pub(super) a: f64,
    pub(super) b: f64,
    pub(super) sigma_b: f64,
    pub(super) cbar: f64,
    pub(super) chi2_const: f64,
    pub(super) chi2_line: f64,
    pub(super) count: usize,
}

pub(super) fn line(fits: &[StripFit]) -> Option<Line> {
    let u = usable(fits);
    if u.len() < 3 {
        return None;
    }
    let sw: f64 = u.iter().map(|p| p.2).sum();
    let cbar = u.iter().map(|p| p.2 * p.0).sum::<f64>() / sw;
    let lbar = u.iter().map(|p| p.2 * p.1).sum::<f64>() / sw;
    let scc: f64 = u.iter().map(|p| p.2 * (p.0 - cbar).powi(2)).sum();
    let scl: f64 = u.iter().map(|p| p.2 * (p.0 - cbar) * (p.1 - lbar)).sum();
    let chi2_const: f64 = u.iter().map(|p| p.2 * (p.1 - lbar).powi(2)).sum();
    if scc <= 0.0 {
        return None;
    }
    let b = scl / scc;
    let chi2_line = (chi2_const - b * b * scc).max(0.0);
    // Where the line misfits (strips that only partly hold the object
    // sit off it), its slope is known the worse for it.
    let misfit = if u.len() > 2 {
        (chi2_line / (u.len() - 2) as f64).max(1.0).sqrt()
    } else {
        1.0
    };
    Some(Line {
        a: lbar,
        b,
        sigma_b: misfit / scc.sqrt(),
        cbar,
        chi2_const,
        chi2_line,
        count: u.len(),
    })
}

/// The residual's image axis: delays that change across the rows beyond
/// their noise (chi-square at 1e-3 over `count - 1` degrees of freedom),
/// or `None` (`l` is the strips' [`line`]).
pub(super) fn lag_across_rows(fits: &[StripFit], l: &Line) -> Option<Unexplained> {
    let level = chi2_level(l.count - 1);
    if l.chi2_const <= level {
        return None;
    }
    let u = usable(fits);
    let lags_us: Vec<f64> = fits
        .iter()
        .map(|f| {
            if f.sigma_s.is_finite() {
                ((f.lag_s - l.a) * 1e6 * 100.0).round() / 100.0
            } else {
                f64::NAN
            }
        })
        .collect();
    let rows: Vec<f64> = fits.iter().map(|f| f.centre).collect();
    let (lo, hi) = u
        .iter()
        .fold((f64::INFINITY, f64::NEG_INFINITY), |(a, b), p| {
            (a.min(p.1 - l.a), b.max(p.1 - l.a))
        });
    let linear = l.chi2_line <= chi2_level((l.count - 2).max(1));
    let description = format!(
        "the delay changes across the image's rows by {:.1} µs ({:+.1} to {:+.1} µs about the mean; {:.0}x the level the strips' own noise reaches by chance){}: rows captured at different times (a rolling shutter read out while the camera declares a global one), or parts of the object that hear the sound at different times (two objects, a non-rigid one)",
        (hi - lo) * 1e6,
        lo * 1e6,
        hi * 1e6,
        l.chi2_const / level,
        if linear {
            format!(
                "; in proportion to the row, each row seen {:.3} ± {:.3} µs after the one above",
                -l.b * 1e6,
                l.sigma_b * 1e6
            )
        } else {
            "; not in proportion to the row".to_string()
        }
    );
    Some(Unexplained::LagAcrossImage {
        axis: "rows",
        description,
        frequencies_hz: [],
        kind: UnexplainedKind::LagAcrossImage,
        lags_us,
        rows,
        significance: l.chi2_const / level,
    })
}

/// The family's members.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub(super) enum Member {
    Linear,
    PerRegion,
}

impl Member {
    pub(super) fn name(self) -> &'static str {
        match self {
            Member::Linear => "linear",
            Member::PerRegion => "per_region",
        }
    }
}

/// Each strip's delay under `member` (s, about the signal-weighted mean),
/// and its uncertainty (`l` is the strips' [`line`]).
pub(super) fn delays(fits: &[StripFit], l: &Line, member: Member) -> (Vec<f64>, Vec<f64>, f64) {
    let raw: Vec<(f64, f64)> = fits
        .iter()
        .map(|f| {
            let lin = l.a + l.b * (f.centre - l.cbar);
            let lin_sigma = l.sigma_b * (f.centre - l.cbar).abs();
            match member {
                Member::Linear => (lin, lin_sigma),
                Member::PerRegion if f.sigma_s.is_finite() => (f.lag_s, f.sigma_s),
                Member::PerRegion => (lin, f64::INFINITY),
            }
        })
        .collect();
    // About the mean delay the strips' signal carries (the sum's delay
    // stays the region's).
    let (mut num, mut den) = (0.0, 0.0);
    for (f, r) in fits.iter().zip(&raw) {
        let s = f.weight() * f.gain;
        num += s * r.0;
        den += s;
    }
    let mean = if den > 0.0 { num / den } else { l.a };
    (
        raw.iter().map(|r| r.0 - mean).collect(),
        raw.iter().map(|r| r.1).collect(),
        l.sigma_b,
    )
}

/// The strips summed with the magnitudes of `weights`, strip `k` read
/// `delays_s[k]` later (advanced by its delay), at `fs`. Each strip's sign
/// is taken from the recording itself: the sign of its correlation, once
/// aligned, with the most heavily weighted strip's. A strip's polarity is
/// its pipeline's (the `align` stage's reference band, chosen per
/// recording), so a sign fitted on one recording need not hold on the next.
pub fn combine(signals: &[Vec<f64>], weights: &[f64], delays_s: &[f64], fs: f64) -> Vec<f64> {
    let n = signals.iter().map(Vec::len).min().unwrap_or(0);
    let moved: Vec<Option<Vec<f64>>> = signals
        .iter()
        .zip(weights)
        .zip(delays_s)
        .map(|((y, &w), &d)| {
            (w != 0.0 && w.is_finite()).then(|| {
                if d == 0.0 {
                    y[..n].to_vec()
                } else {
                    sample_at(y, fs, (0..n).map(|i| i as f64 / fs + d))
                }
            })
        })
        .collect();
    let mut out = vec![0.0; n];
    let top = weights
        .iter()
        .enumerate()
        .filter(|(_, w)| w.is_finite())
        .max_by(|a, b| a.1.abs().total_cmp(&b.1.abs()))
        .map(|(k, _)| k);
    let Some(Some(reference)) = top.map(|k| &moved[k]) else {
        return out;
    };
    for (m, &w) in moved.iter().zip(weights) {
        let Some(m) = m else { continue };
        let c: f64 = m.iter().zip(reference).map(|(a, b)| a * b).sum();
        let w = if c < 0.0 { -w.abs() } else { w.abs() };
        for (o, v) in out.iter_mut().zip(m) {
            *o += w * v;
        }
    }
    out
}

/// Strips whose capture times spread over so little of a frame period
/// that a frequency's and its alias's columns correlate above this
/// ([`unfold`]) cannot tell them apart: not unfolded.
pub const UNFOLD_MAX_CORRELATION: f64 = 0.95;
/// The alias's power is estimated over this much of the spectrum either
/// side of each frequency (Hz), [`unfold`].
const UNFOLD_SMOOTH_HZ: f64 = 20.0;

/// The strips' samples as one signal at twice the frame rate, what lies
/// between the frame rate's Nyquist frequency and the frame rate itself
/// unfolded (issue 50, item 3: a readout across the rows samples the
/// motion at more instants than one a frame). Strip `k` holds
/// `g_k x(n / fs - d_k)` plus its noise (`delays_s[k] = d_k`, as
/// [`combine`] takes them); below `fs` each frequency `f` of a strip's
/// spectrum holds `x` at `f` and at `f - fs` (the alias), each turned by
/// its own delay, `e^{-i 2π f d_k}` and `e^{-i 2π (f - fs) d_k}`. With
/// capture times spread over a frame period the two are told apart, per
/// frequency, by weighted least squares over the strips (weights
/// `g_k² / σ_k²`), and written at their own frequencies at `2 fs`. The
/// alias is shrunk by a Wiener factor from its power, estimated from the
/// strips themselves: where the motion holds nothing above the Nyquist
/// frequency the result is the delays' sum ([`combine`]), where it holds
/// more than the strips' noise it is unfolded.
///
/// Each strip's gain and noise are measured on this recording against
/// [`combine`]'s sum (with `weights`, and the strip's delay): a strip's
/// gain depends on its texture and its sign on its pipeline. `None` when
/// the delays do not spread enough ([`UNFOLD_MAX_CORRELATION`]), or fewer
/// than three strips hold the signal (one left out must be predicted by
/// the two unknowns of the others). Whether anything lies above the
/// Nyquist frequency at all is [`Unfolded::holds_alias`]: the caller
/// decides. The result is as long as twice the
/// shortest strip, in the strips' units (the sum's scale), and high-passed
/// as a recovery at twice the frame rate is by default: the strips' own
/// high-pass (`highpass`, at the frame rate) undone, that one applied.
pub fn unfold(
    signals: &[Vec<f64>],
    (weights, delays_s): (&[f64], &[f64]),
    (fs, highpass): (f64, Option<(usize, f64)>),
) -> Option<Unfolded> {
    let n = signals.iter().map(Vec::len).min().unwrap_or(0);
    if n < 16 || fs.is_nan() || fs <= 0.0 || delays_s.len() != signals.len() {
        return None;
    }
    // The strips' gains and noises against the sum at the frame rate
    // first (where the delays suppress the aliases), then once more
    // against the unfolded signal, read at each strip's instants.
    let mut template = (combine(signals, weights, delays_s, fs), fs);
    let mut press = f64::NAN;
    for pass in 0..2 {
        let strips = gains(signals, (weights, delays_s), (&template.0, template.1), fs);
        let nm = Normal::of(&strips, fs)?;
        // Decided on the strips' gains against the frame rate's sum,
        // before anything was unfolded.
        if pass == 0 {
            press = press_ratio(&strips, fs, n, &nm);
        }
        template = (solve_unfolded(&strips, fs, n, &nm), 2.0 * fs);
    }
    // The strips' high-pass (`highpass`, at the frame rate) becomes the
    // one a recovery at twice the rate carries (its default), as the
    // model that scores it assumes.
    let to = super::Options::for_rate(2.0 * fs).highpass;
    let signal = if to == highpass {
        template.0
    } else {
        let flat = undo_highpass(&template.0, 2.0 * fs, highpass);
        redo_highpass(&flat, 2.0 * fs, to)
    };
    Some(Unfolded {
        signal,
        press_ratio: press,
    })
}

/// What [`unfold`] gives: the signal at twice the frame rate, and how much
/// better (below 1) or worse (above) the strips are predicted with what
/// lies above the frame rate's Nyquist frequency than without it.
#[derive(Clone, Debug)]
pub struct Unfolded {
    /// The motion at twice the frame rate.
    pub signal: Vec<f64>,
    /// Each strip left out in turn and predicted from the others, per
    /// frequency below the frame rate (its squared error weighted by the
    /// strip's `g² / σ²`, summed over strips and frequencies: PRESS): with
    /// the alias over without it. Below 1 the strips hold something above
    /// the Nyquist frequency that the frame rate's model (the delays'
    /// sum) does not predict; above 1 the alias's column only fits noise.
    /// Measured with the strips' gains against the frame rate's sum,
    /// before anything is unfolded.
    pub press_ratio: f64,
}

impl Unfolded {
    /// Whether the strips hold anything above the Nyquist frequency:
    /// they are better predicted with it ([`Unfolded::press_ratio`]
    /// below 1).
    pub fn holds_alias(&self) -> bool {
        self.press_ratio < 1.0
    }
}

/// Each usable strip (a finite nonzero weight and delay) divided by its
/// gain against `template` (at `rate`, read at the strip's instants
/// `i / fs - d`), with its weight `g² / σ²` and delay.
fn gains(
    signals: &[Vec<f64>],
    (weights, delays_s): (&[f64], &[f64]),
    (template, rate): (&[f64], f64),
    fs: f64,
) -> Vec<(Vec<f64>, f64, f64)> {
    let n = signals.iter().map(Vec::len).min().unwrap_or(0);
    let mut strips = Vec::new();
    for ((s, &w), &d) in signals.iter().zip(weights).zip(delays_s) {
        if w == 0.0 || !w.is_finite() || !d.is_finite() {
            continue;
        }
        let zk = sample_at(template, rate, (0..n).map(|i| i as f64 / fs - d));
        let zz: f64 = zk.iter().map(|v| v * v).sum();
        let g = s[..n].iter().zip(&zk).map(|(a, b)| a * b).sum::<f64>() / zz;
        if !g.is_finite() || g == 0.0 {
            continue;
        }
        let noise = s[..n]
            .iter()
            .zip(&zk)
            .map(|(a, b)| (a - g * b).powi(2))
            .sum::<f64>()
            / n as f64;
        let c = if noise > 0.0 { g * g / noise } else { 0.0 };
        if c > 0.0 && c.is_finite() {
            strips.push((s[..n].iter().map(|v| v / g).collect(), c, d));
        }
    }
    strips
}

/// [`unfold`]'s normal equations over `strips` ([`gains`]), the same at
/// every frequency: `[[t, x], [x*, t]]` (the strips' weights summed, a
/// tiny ridge keeping them solvable, and their turns `e^{i 2π fs d}`
/// summed with the weights), its determinant, each strip's turn and its
/// leverages (with the delays' sum alone, `c / t`, and with the alias,
/// `c (2t - 2 Re(x conj(turn))) / det`). `None` with fewer than three
/// strips, delays that do not tell a frequency from its alias
/// ([`UNFOLD_MAX_CORRELATION`]), or a strip the others cannot predict
/// (a leverage of 1: it alone decides the fit).
struct Normal {
    t: f64,
    x: Complex<f64>,
    det: f64,
    turns: Vec<Complex<f64>>,
    leverage: Vec<(f64, f64)>,
}

impl Normal {
    fn of(strips: &[(Vec<f64>, f64, f64)], fs: f64) -> Option<Normal> {
        if strips.len() < 3 {
            return None;
        }
        let total: f64 = strips.iter().map(|s| s.1).sum();
        let turns: Vec<Complex<f64>> = strips
            .iter()
            .map(|(_, _, d)| Complex::from_polar(1.0, 2.0 * std::f64::consts::PI * fs * d))
            .collect();
        let cross: Complex<f64> = strips.iter().zip(&turns).map(|((_, c, _), u)| u * *c).sum();
        if cross.norm() / total > UNFOLD_MAX_CORRELATION {
            return None;
        }
        let (t, x) = (total + 1e-6 * total, cross);
        let det = t * t - x.norm_sqr();
        let leverage: Vec<(f64, f64)> = strips
            .iter()
            .zip(&turns)
            .map(|((_, c, _), turn)| (c / t, c * (2.0 * t - 2.0 * (x * turn.conj()).re) / det))
            .collect();
        if leverage.iter().any(|l| !(l.0 < 1.0 && l.1 < 1.0)) {
            return None;
        }
        Some(Normal {
            t,
            x,
            det,
            turns,
            leverage,
        })
    }

    /// The least-squares `(p, q)` (the motion at `f` and its alias) from
    /// a bin's right-hand sides.
    fn solve(&self, ra: Complex<f64>, rb: Complex<f64>) -> (Complex<f64>, Complex<f64>) {
        let (t, x, det) = (self.t, self.x, self.det);
        ((ra * t - rb * x) / det, (rb * t - ra * x.conj()) / det)
    }

    /// Bin `j` (frequency `f`) of `spectra`: each strip's phase factors
    /// (`a` at `f`, `b` at its alias `f - fs`) into `factors`, and the
    /// right-hand sides.
    fn rhs(
        &self,
        strips: &[(Vec<f64>, f64, f64)],
        spectra: &[Vec<Complex<f64>>],
        (j, f): (usize, f64),
        factors: &mut [(Complex<f64>, Complex<f64>)],
    ) -> (Complex<f64>, Complex<f64>) {
        let (mut ra, mut rb) = (Complex::new(0.0, 0.0), Complex::new(0.0, 0.0));
        for (k, ((_, c, d), spec)) in strips.iter().zip(spectra).enumerate() {
            let a = Complex::from_polar(1.0, -2.0 * std::f64::consts::PI * f * d);
            let b = a * self.turns[k];
            factors[k] = (a, b);
            ra += a.conj() * spec[j] * *c;
            rb += b.conj() * spec[j] * *c;
        }
        (ra, rb)
    }
}

/// Each strip's spectrum over `n` samples, its sample `i` weighed by
/// `taper(i, d)` (`d` its delay) first.
fn strip_spectra(
    strips: &[(Vec<f64>, f64, f64)],
    n: usize,
    taper: impl Fn(usize, f64) -> f64,
) -> Vec<Vec<Complex<f64>>> {
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let fwd = planner.plan_fft_forward(n);
    strips
        .iter()
        .map(|(u, _, d)| {
            let mut input: Vec<f64> = u[..n]
                .iter()
                .enumerate()
                .map(|(i, a)| a * taper(i, *d))
                .collect();
            let mut out = fwd.make_output_vec();
            // Lengths match the plan: it cannot fail.
            let _ = fwd.process(&mut input, &mut out);
            out
        })
        .collect()
}

/// [`unfold`]'s least squares, per frequency, over `strips` ([`gains`]),
/// each `n` samples at `fs` (`nm`: their normal equations): the signal at
/// `2 fs`.
fn solve_unfolded(strips: &[(Vec<f64>, f64, f64)], fs: f64, n: usize, nm: &Normal) -> Vec<f64> {
    let spectra = strip_spectra(strips, n, |_, _| 1.0);
    let (t, x, det) = (nm.t, nm.x, nm.det);
    let half = n / 2;
    // Per bin, in one pass over the strips' phase factors (`a` at `f`,
    // `b` at its alias `f - fs`): the right-hand sides; the alias's
    // least-squares estimate, whose power (smoothed over
    // ±UNFOLD_SMOOTH_HZ, less that estimate's noise: a strip's noise of
    // variance 1/c a sample is n/c in a bin) decides how far it is shrunk
    // (Wiener: where the motion holds little above the Nyquist frequency,
    // its estimate would be mostly noise, down to the delays' sum where
    // it holds none); and what the least squares leave over there. The
    // strips' noises were measured against a sum that holds them, so they
    // read low, and a recovery's noise is not white: its level per
    // frequency is taken from those leftovers, `K - 2` complex degrees of
    // freedom a bin, smoothed as the power.
    let mut factors = vec![(Complex::new(0.0, 0.0), Complex::new(0.0, 0.0)); strips.len()];
    let mut rhs = Vec::with_capacity(half + 1);
    let (mut q_ls, mut left) = (Vec::with_capacity(half + 1), Vec::with_capacity(half + 1));
    for j in 0..=half {
        let (ra, rb) = nm.rhs(
            strips,
            &spectra,
            (j, j as f64 * fs / n as f64),
            &mut factors,
        );
        let (p, q) = nm.solve(ra, rb);
        let mut e = 0.0;
        for (((_, c, _), spec), (a, b)) in strips.iter().zip(&spectra).zip(&factors) {
            e += c * (spec[j] - a * p - b * q).norm_sqr();
        }
        rhs.push((ra, rb));
        q_ls.push(q.norm_sqr());
        left.push(e);
    }
    let dof = strips.len().saturating_sub(2) as f64;
    let w = ((UNFOLD_SMOOTH_HZ * n as f64 / fs).round() as usize).max(2);
    let (q_mean, left_mean) = (smoothed(&q_ls, w), smoothed(&left, w));
    let m = 2 * n;
    let mut out = vec![Complex::new(0.0, 0.0); m / 2 + 1];
    for (j, (ra, rb)) in rhs.iter().enumerate() {
        // The noise's scale here (1 where the strips' noises are right).
        let kappa = if dof > 0.0 {
            (left_mean[j] / (dof * n as f64)).max(1.0)
        } else {
            1.0
        };
        let power = (q_mean[j] - kappa * n as f64 * t / det).max(0.0);
        let (p, q) = if power > 0.0 {
            // [p, q] = [[t, x], [x*, t + n / power]]^-1 [ra, rb].
            let l = kappa * n as f64 / power;
            let d = t * (t + l) - x.norm_sqr();
            ((ra * (t + l) - rb * x) / d, (rb * t - ra * x.conj()) / d)
        } else {
            (ra / t, Complex::new(0.0, 0.0))
        };
        // At 2 fs over 2n samples the spectrum is twice as large.
        out[j] += p * 2.0;
        let k = n - j;
        if k <= m / 2 {
            out[k] += q.conj() * 2.0;
        }
    }
    // The bins that are their own mirror (0, n) must be real for a real
    // signal; where both halves land on one bin (n/2, n even), it is their mean.
    if n.is_multiple_of(2) {
        out[half] *= 0.5;
    }
    out[0].im = 0.0;
    out[m / 2].im = 0.0;
    let inv = realfft::RealFftPlanner::<f64>::new().plan_fft_inverse(m);
    let mut y = inv.make_output_vec();
    let _ = inv.process(&mut out, &mut y);
    let scale = 1.0 / m as f64;
    y.iter().map(|v| v * scale).collect()
}

/// Whether the strips hold anything above the Nyquist frequency, decided
/// by how well each model predicts a strip it was not fitted to (each
/// left out in turn, per frequency, squared errors weighted by `c` and
/// summed: PRESS): the delays' sum alone (`a` at `f`), or with the alias
/// (`b` at `f - fs`). The alias's column fits noise too, so where nothing
/// lies above the Nyquist frequency it predicts a left-out strip worse.
/// Each residual is divided by one less the strip's leverage, the same
/// at every frequency ([`Normal`]). The strips are tapered (Hann, each
/// at its own instants) first: a delay is a turn of phase per frequency
/// only for a periodic signal, and the ends of a recording are not,
/// which the alias's column would fit. The ratio with the alias over
/// without.
fn press_ratio(strips: &[(Vec<f64>, f64, f64)], fs: f64, n: usize, nm: &Normal) -> f64 {
    // Strip `k` holds `x(i / fs - d_k)`: tapered by `w(i / fs - d_k)`, it
    // holds `(w x)(i / fs - d_k)`, one signal read `d_k` later, exactly.
    let spectra = strip_spectra(strips, n, |i, d| {
        let u = (i as f64 + 0.5 - d * fs) / n as f64;
        if (0.0..=1.0).contains(&u) {
            (std::f64::consts::PI * u).sin().powi(2)
        } else {
            0.0
        }
    });
    let mut factors = vec![(Complex::new(0.0, 0.0), Complex::new(0.0, 0.0)); strips.len()];
    let mut press = (0.0, 0.0);
    for j in 0..=n / 2 {
        let (ra, rb) = nm.rhs(
            strips,
            &spectra,
            (j, j as f64 * fs / n as f64),
            &mut factors,
        );
        let p1 = ra / nm.t;
        let (p, q) = nm.solve(ra, rb);
        for (((lev, (_, c, _)), spec), (a, b)) in
            nm.leverage.iter().zip(strips).zip(&spectra).zip(&factors)
        {
            press.0 += c * (spec[j] - a * p1).norm_sqr() / (1.0 - lev.0).powi(2);
            press.1 += c * (spec[j] - a * p - b * q).norm_sqr() / (1.0 - lev.1).powi(2);
        }
    }
    press.1 / press.0
}

/// The mean of `v` over `±w` samples about each (fewer at the ends).
fn smoothed(v: &[f64], w: usize) -> Vec<f64> {
    let mut prefix = vec![0.0; v.len() + 1];
    for (i, x) in v.iter().enumerate() {
        prefix[i + 1] = prefix[i] + x;
    }
    (0..v.len())
        .map(|j| {
            let (lo, hi) = (j.saturating_sub(w), (j + w + 1).min(v.len()));
            (prefix[hi] - prefix[lo]) / (hi - lo) as f64
        })
        .collect()
}

/// Maximal-ratio weights, normalised to the largest magnitude.
pub(super) fn weights(fits: &[StripFit]) -> Vec<f64> {
    let w: Vec<f64> = fits.iter().map(StripFit::weight).collect();
    let top = w.iter().fold(0.0f64, |m, v| m.max(v.abs()));
    if top > 0.0 {
        w.iter().map(|v| v / top).collect()
    } else {
        w
    }
}

/// What the image axis decided: the structure read (if any), the member
/// kept with its held-out gain and the strips' sum it gives, and the
/// members fitted but not kept.
#[derive(Default)]
pub(super) struct Decision {
    pub(super) evidence: Option<Unexplained>,
    pub(super) kept: Option<(Candidate, f64, Vec<f64>)>,
    pub(super) rejected: Vec<(Correction, f64)>,
}

/// Whether `strips` can be read against `fit`: a signal per strip, at
/// least three, each as long as the recovery.
pub(super) fn usable_strips(strips: &Strips, fit: &Fit) -> bool {
    let n = fit.t.len();
    strips.signals.len() == strips.rows.len()
        && strips.signals.len() >= 3
        && strips.signals.iter().all(|s| s.len() == n)
}

/// Reads the image axis and, when the delays move across the rows, fits
/// both members and keeps the better by held-out gain (the linear one
/// unless the per-region one gains `min_gain_db` more), if it gains
/// `min_gain_db` over the strips summed without delays.
pub(super) fn decide(
    m: &Model,
    (strips, fits): (&Strips, &[StripFit]),
    min_gain_db: f64,
) -> Decision {
    let Some(l) = line(fits) else {
        return Decision::default();
    };
    let Some(evidence) = lag_across_rows(fits, &l) else {
        return Decision::default();
    };
    let w = weights(fits);
    let zero = vec![0.0; fits.len()];
    let base = combine(&strips.signals, &w, &zero, m.fs);
    let e0 = m.errors(&base, &m.fit_linear(&base)).snr_db;
    let mut tried: Vec<(Candidate, f64, Vec<f64>)> = Vec::new();
    for member in [Member::Linear, Member::PerRegion] {
        let (d, sd, sigma_b) = delays(fits, &l, member);
        let z = combine(&strips.signals, &w, &d, m.fs);
        let gain = m.errors(&z, &m.fit_linear(&z)).snr_db - e0;
        let correction = Correction::CaptureTime {
            rows: strips.rows.clone(),
            delays_s: d,
            weights: w.clone(),
            // A row seen later shows the motion earlier (a smaller delay).
            line_delay_s: -l.b,
            per_region: member == Member::PerRegion,
        };
        let uncertainty = Uncertainty::CaptureTime {
            delays_us: sd.iter().map(|v| v * 1e6).collect(),
            line_delay_us: sigma_b * 1e6,
        };
        tracing::info!(
            effect = "capture_time",
            member = member.name(),
            gain_db = gain,
            "candidate"
        );
        tried.push((
            Candidate {
                correction,
                uncertainty,
            },
            gain,
            z,
        ));
    }
    let pick = match tried.as_slice() {
        [lin, per] if per.1 >= lin.1 + min_gain_db => 1,
        [] => return Decision::default(),
        _ => 0,
    };
    let mut out = Decision {
        evidence: Some(evidence),
        ..Decision::default()
    };
    for (i, t) in tried.into_iter().enumerate() {
        if i == pick && t.1.is_finite() && t.1 >= min_gain_db {
            out.kept = Some(t);
        } else {
            out.rejected.push((t.0.correction, t.1));
        }
    }
    out
}

/// Each strip's physical sign (+1 or -1, 0 where it cannot be told): the
/// sign of its gain against the target in the one band whose sum over the
/// strips is the strongest. A band oriented along the motion sees every
/// part of a rigid object with one sign; a band across it sees each part
/// with a sign its texture decides, so its sum over the strips partly
/// cancels and another band is chosen. Each band is high-passed as the
/// recovery is; a strip whose band has a matched-filter SNR below
/// [`MIN_STRIP_SNR`] gets 0. `None` without the strips' bands.
pub(super) fn physical_signs(m: &Model, strips: &Strips, fit: &Fit) -> Option<Vec<f64>> {
    let n = fit.t.len();
    let nb = strips.bands.first()?.len();
    if nb == 0
        || strips.bands.len() != strips.signals.len()
        || strips.bands.iter().any(|b| b.len() != nb)
    {
        return None;
    }
    let t = m.masked(&fit.t);
    let tt: f64 = t.iter().map(|v| v * v).sum();
    if tt.is_nan() || tt <= 0.0 {
        return None;
    }
    let nf = m.nfit(n) as f64;
    // (gain, SNR) of each strip's each band.
    let g: Vec<Vec<(f64, f64)>> = strips
        .bands
        .iter()
        .map(|bands| {
            bands
                .iter()
                .map(|x| {
                    let mut x = x.clone();
                    x.resize(n, 0.0);
                    let h = m.masked(&redo_highpass(&x, m.fs, m.opts.highpass));
                    let (gain, sse) = gain_sse(&t, &h);
                    (gain, gain.abs() * tt.sqrt() / (sse / nf).sqrt().max(1e-300))
                })
                .collect()
        })
        .collect();
    let sum = |b: usize| g.iter().map(|k| k[b].0).sum::<f64>().abs();
    let best = (0..nb).max_by(|&a, &b| sum(a).total_cmp(&sum(b)))?;
    Some(
        g.iter()
            .map(|k| match k[best] {
                (gain, snr) if snr >= MIN_STRIP_SNR => gain.signum(),
                _ => 0.0,
            })
            .collect(),
    )
}

/// What summing the usable strips as one rigid object loses against
/// summing them with their own signs, dB, predicted from their fits and
/// physical signs `signs` ([`physical_signs`]): with `q_k = |w_k g_k|` and
/// `s` the share of `q` in strips whose physical sign is the other than
/// the strongest's, the rigid sum's signal falls by `|1 - 2 s|` at the
/// same noise. `None` without usable strips.
fn rigid_loss_db(fits: &[StripFit], signs: &[f64]) -> Option<f64> {
    let usable: Vec<(&StripFit, f64)> = fits
        .iter()
        .zip(signs)
        .filter(|(f, p)| f.sigma_s.is_finite() && **p != 0.0)
        .map(|(f, p)| (f, *p))
        .collect();
    let top = usable
        .iter()
        .max_by(|a, b| a.0.weight().abs().total_cmp(&b.0.weight().abs()))?;
    let q = |f: &StripFit| (f.weight() * f.gain).abs();
    let total: f64 = usable.iter().map(|(f, _)| q(f)).sum();
    let against: f64 = usable
        .iter()
        .filter(|(_, p)| *p != top.1)
        .map(|(f, _)| q(f))
        .sum();
    (total > 0.0).then(|| -20.0 * (1.0 - 2.0 * against / total).abs().max(1e-6).log10())
}

/// The residual's image axis by gain: strips that move in antiphase with
/// the strongest (by their physical signs), when summing the strips as
/// one rigid object would lose at least `min_gain_db` for it
/// ([`rigid_loss_db`]). Each sign counted is at least [`MIN_STRIP_SNR`]
/// standard deviations from zero, so it is not noise; the threshold asks
/// that it matter.
pub(super) fn gain_across_rows(
    fits: &[StripFit],
    signs: &[f64],
    min_gain_db: f64,
) -> Option<Unexplained> {
    let loss = rigid_loss_db(fits, signs)?;
    if loss < min_gain_db {
        return None;
    }
    let (top, p0) = fits
        .iter()
        .zip(signs)
        .filter(|(f, p)| f.sigma_s.is_finite() && **p != 0.0)
        .max_by(|a, b| a.0.weight().abs().total_cmp(&b.0.weight().abs()))?;
    let gains: Vec<f64> = fits
        .iter()
        .zip(signs)
        .map(|(f, p)| {
            if f.sigma_s.is_finite() && *p != 0.0 {
                (p * p0 * (f.gain / top.gain).abs() * 1000.0).round() / 1000.0
            } else {
                f64::NAN
            }
        })
        .collect();
    let against: Vec<String> = fits
        .iter()
        .zip(&gains)
        .filter(|(_, g)| **g < 0.0)
        .map(|(f, g)| format!("row {:.1} at {g:+.2}", f.centre))
        .collect();
    let description = format!(
        "strips of rows move in antiphase with the strongest ({}, gains relative to it, signs read in the band that sees the motion along its orientation): summed as one rigid object they cancel, {loss:.1} dB below their sum with their own signs: parts of the object that move in opposite directions (a non-rigid object's mode, two objects)",
        against.join(", ")
    );
    Some(Unexplained::GainAcrossImage {
        axis: "rows",
        description,
        frequencies_hz: [],
        gains,
        kind: UnexplainedKind::GainAcrossImage,
        loss_db: loss,
        rows: fits.iter().map(|f| f.centre).collect(),
    })
}

/// Region-wise gain (j): when the strips move in antiphase
/// ([`gain_across_rows`]), the strips summed at one time with their
/// maximal-ratio weights and the signs they move with, scored on held-out
/// blocks against the same strips summed as one rigid object (the
/// weights' magnitudes, each strip's polarity set by its physical sign)
/// and against the region's own recovery `y`; kept when it gains
/// `min_gain_db` over both. Its gain is reported against the region's
/// recovery, what would be used without it.
pub(super) fn decide_gain(
    m: &Model,
    y: &[f64],
    (strips, fits): (&Strips, &[StripFit]),
    fit: &Fit,
    min_gain_db: f64,
) -> Decision {
    let n = fit.t.len();
    let Some(signs) = physical_signs(m, strips, fit) else {
        return Decision::default();
    };
    let Some(evidence) = gain_across_rows(fits, &signs, min_gain_db) else {
        return Decision::default();
    };
    // Weights with physical signs, the strongest strip's +1 (a strip
    // whose sign cannot be told keeps the strongest's).
    let w = weights(fits);
    let k0 = (0..w.len())
        .max_by(|&a, &b| w[a].abs().total_cmp(&w[b].abs()))
        .unwrap_or(0);
    let p0 = if signs[k0] != 0.0 { signs[k0] } else { 1.0 };
    let physical: Vec<f64> = w
        .iter()
        .zip(&signs)
        .map(|(v, p)| v.abs() * if *p != 0.0 { p * p0 } else { 1.0 })
        .collect();
    let zero = vec![0.0; fits.len()];
    let signed = combine(&strips.signals, &w, &zero, m.fs);
    // As one rigid object: each strip's recovery turned to its physical
    // sign (its polarity against the target times that sign), with the
    // weight's magnitude.
    let mut rigid = vec![0.0; n];
    for ((s, f), p) in strips.signals.iter().zip(fits).zip(&physical) {
        let c = p * f.gain.signum() * f.weight().abs();
        for (o, v) in rigid.iter_mut().zip(s) {
            *o += c * v;
        }
    }
    let snr = |z: &[f64]| m.errors(z, &m.fit_linear(z)).snr_db;
    let e = snr(&signed);
    let (over_rigid, over_region) = (e - snr(&rigid), e - m.errors(y, fit).snr_db);
    tracing::info!(
        effect = "region_gain",
        gain_db = over_region,
        over_rigid_db = over_rigid,
        "candidate"
    );
    let candidate = Candidate {
        correction: Correction::RegionGain {
            rows: strips.rows.clone(),
            weights: physical.clone(),
        },
        uncertainty: Uncertainty::RegionGain {
            weights: fits
                .iter()
                .zip(&physical)
                .map(|(f, wk)| {
                    if f.snr > 0.0 {
                        wk.abs() / f.snr
                    } else {
                        f64::INFINITY
                    }
                })
                .collect(),
        },
    };
    let mut out = Decision {
        evidence: Some(evidence),
        ..Decision::default()
    };
    if over_rigid >= min_gain_db && over_region.is_finite() && over_region >= min_gain_db {
        out.kept = Some((candidate, over_region, signed));
    } else {
        out.rejected.push((candidate.correction, over_region));
    }
    out
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::*;
    use std::f64::consts::PI;

    /// Strips of a motion with a tone above the frame rate's Nyquist
    /// frequency, read out across a frame period: unfolded, the motion at
    /// twice the frame rate comes back, its tone at its own frequency;
    /// the delays alone, at the frame rate, cannot. Strips captured at
    /// one instant are not unfolded.
    #[test]
    fn a_readout_unfolds_what_lies_above_nyquist() {
        let (fs, n) = (2200.0, 4400);
        let x = |t: f64| (2.0 * PI * 300.0 * t).sin() + 0.5 * (2.0 * PI * 1500.0 * t + 0.3).sin();
        let count = 8;
        let delays: Vec<f64> = (0..count)
            .map(|k| 0.9 * k as f64 / (count as f64 * fs))
            .collect();
        let mut seed = 7u64;
        let mut noise = || {
            seed = seed
                .wrapping_mul(6364136223846793005)
                .wrapping_add(1442695040888963407);
            ((seed >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * 2e-3
        };
        let signals: Vec<Vec<f64>> = delays
            .iter()
            .enumerate()
            .map(|(k, d)| {
                // Gains of either sign and size, as strips' pipelines give.
                let g = (1.0 + 0.2 * k as f64) * if k % 3 == 1 { -1.0 } else { 1.0 };
                (0..n).map(|i| g * x(i as f64 / fs - d) + noise()).collect()
            })
            .collect();
        let weights = vec![1.0; count];
        // Declared with the high-pass a recovery at 2 fs carries: none is
        // undone or applied, and the tones come back as they were.
        let hp = super::super::Options::for_rate(2.0 * fs).highpass;
        let u = unfold(&signals, (&weights, &delays), (fs, hp)).unwrap();
        // The strips are better predicted with the alias than without.
        eprintln!("PRESS ratio {:.3}", u.press_ratio);
        assert!(u.holds_alias(), "{}", u.press_ratio);
        let y = u.signal;
        assert_eq!(y.len(), 2 * n);
        // Up to the sum's scale (the strips' gains relative to the sum).
        let truth: Vec<f64> = (0..2 * n).map(|i| x(i as f64 / (2.0 * fs))).collect();
        let snr = snr_db(&y, &truth);
        assert!(snr > 30.0, "unfolded SNR {snr:.1} dB");
        // At the frame rate the tone folds to 700 Hz; the delays cannot
        // align it.
        let z = combine(&signals, &weights, &delays, fs);
        let folded: Vec<f64> = (0..n).map(|i| x(i as f64 / fs)).collect();
        let snr_frame = snr_db(&z, &folded);
        assert!(snr_frame < 20.0, "frame-rate SNR {snr_frame:.1} dB");
        // One capture instant: nothing to unfold.
        assert!(unfold(&signals, (&weights, &vec![0.0; count]), (fs, hp)).is_none());
    }

    /// Strips that hold nothing above the frame rate's Nyquist frequency
    /// are predicted worse with the alias's column than without it, over
    /// seeds and noise levels: `listen` keeps the frame rate.
    #[test]
    fn strips_with_nothing_above_nyquist_are_not_unfolded() {
        let (fs, n) = (2200.0, 4400);
        // Two tones and a sweep (100 to 900 Hz), all below 1100 Hz.
        let x = |t: f64| {
            (2.0 * PI * 300.0 * t).sin()
                + 0.5 * (2.0 * PI * 870.0 * t + 0.3).sin()
                + 0.3 * (2.0 * PI * (100.0 + 200.0 * t) * t).sin()
        };
        let count = 8;
        let delays: Vec<f64> = (0..count)
            .map(|k| 0.9 * k as f64 / (count as f64 * fs))
            .collect();
        for (seed, level) in [(1u64, 1e-3), (2, 1e-2), (3, 1e-1)] {
            let mut state = seed;
            let mut noise = || {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                ((state >> 11) as f64 / (1u64 << 53) as f64 - 0.5) * level
            };
            let signals: Vec<Vec<f64>> = delays
                .iter()
                .enumerate()
                .map(|(k, d)| {
                    let g = (1.0 + 0.2 * k as f64) * if k % 3 == 1 { -1.0 } else { 1.0 };
                    (0..n).map(|i| g * x(i as f64 / fs - d) + noise()).collect()
                })
                .collect();
            let hp = super::super::Options::for_rate(2.0 * fs).highpass;
            let u = unfold(&signals, (&vec![1.0; count], &delays), (fs, hp)).unwrap();
            eprintln!(
                "seed {seed}, noise {level}: PRESS ratio {:.3}",
                u.press_ratio
            );
            assert!(
                !u.holds_alias(),
                "seed {seed}, noise {level}: {}",
                u.press_ratio
            );
        }
    }

    /// SNR (dB) of `y` against `truth` after the best gain.
    fn snr_db(y: &[f64], truth: &[f64]) -> f64 {
        let g = y.iter().zip(truth).map(|(a, b)| a * b).sum::<f64>()
            / truth.iter().map(|b| b * b).sum::<f64>();
        let err: f64 = y.iter().zip(truth).map(|(a, b)| (a - g * b).powi(2)).sum();
        10.0 * (truth.iter().map(|b| (g * b).powi(2)).sum::<f64>() / err).log10()
    }
}
