//! Calibration against a known sound (issue 6): compare what a visual
//! microphone recovered with what was played, fit the plain linear model
//! (delay, gain), then try a catalog of effects the model lacks, keeping an
//! effect only if it lowers the error on a held-out part of the recording,
//! and describe the residual that no accepted effect explains.
//!
//! # Model
//! The recovery `y[n]` (rate `fs`, the declared frame rate) is compared with
//! the *target* `T[n] = HP(r(n / fs - τ))`: the reference `r` (rate `fr`)
//! point-sampled at the frame times by band-limited interpolation (a camera
//! samples the motion without an anti-alias filter), then high-passed like
//! the recovery (the listen pipeline's Butterworth; part of the known
//! processing). The plain linear model is `y ≈ g T` with a fractional delay
//! `τ` and a gain `g`, both fitted on the fit part.
//!
//! Every effect is a *correction* applied to the recovery (so the corrected
//! recovery can be written out and the same correction reused on a new
//! recording of the same object and camera). The catalog: time-base
//! error, dropped or duplicated frames, exposure, narrowband interference
//! lines, object transfer function, soft saturation, a static polynomial
//! response with even and odd terms (the family soft saturation belongs
//! to; one of the two is kept at most; fitted only when the residual holds
//! harmonics) and a gain drifting over the recording (only when the
//! residual's gain moves). Before them, when the recoveries of strips of
//! rows are given ([`calibrate_strips`]), a capture time that changes
//! across the image's rows ([`capture_time`]: each strip advanced by its
//! delay before the strips are summed); it changes the recovery the
//! others are fitted on. Acceptance is
//! greedy, best first: each round fits every effect not yet kept on the
//! current corrected recovery and keeps the one that gains most on the
//! held-out part. Each is fitted on the fit part of the recording (blocks of
//! about 0.1 s: blocks 0, 2 and 4 of every five, 60%; interleaved so that
//! both parts see every frequency of a sweep), the linear model is refitted
//! on that part, and the effect is kept when the SNR on the held-out part
//! (blocks 1 and 3 of every five, 40%) rises by at least
//! [`Options::min_gain_db`]. Exception: dropped or duplicated frames are
//! events, not properties; their positions are found on the whole recording
//! with a per-event penalty (a likelihood-ratio test), and the held-out
//! gain is then measured as for the others.
//!
//! Interference lines are subtracted from the recovery as delivered,
//! before every other correction (their frequencies are on the declared
//! time base). When more than one effect is kept, each one's reported gain
//! is what the held-out SNR loses without it, and one that loses less
//! than [`Options::min_gain_db`] with the others refitted is let go
//! ([`identify`]); so is one whose main parameter (a clock error, an
//! exposure, a transfer function's `k`, a drift) lies within three of its
//! standard deviations of none (since session 65).
//!
//! Where a sweep drives the object into its nonlinear range at some
//! frequencies (the transfer family's level-dependent bins), the stretch
//! of the sweep that stands there is left out of every effect's fit and
//! of the held-out score: what the object did there held only at the
//! sweep's level.
//!
//! Errors are on the held-out part: SNR and segmental SNR
//! ([`crate::metrics`]) and the log-spectral distance (dB, STFT frames
//! where the target has energy, bins above the high-pass cutoff).
//! Uncertainties are one standard deviation by the Δχ² = 1 rule on the
//! fit-part squared error, with the residual variance taken as white noise
//! (residuals are coloured in practice, so these are lower bounds).
//!
//! One file per effect of the catalog ([`capture_time`], [`time_base`], [`frames`],
//! [`exposure`], [`interference`], [`transfer`], [`soft_clip`],
//! [`polynomial`], [`gain_drift`]); after the loop, [`identify`] refits the
//! kept effects together and reports those a second explanation trades
//! against each other; the
//! corrections they fit ([`correction`]), the linear model ([`model`]),
//! signal tools ([`signal`]), correlation ([`correlation`]) and the
//! residual analysis ([`residual`]) beside them; here the options, the
//! report and the greedy fit-and-keep loop.

mod capture_time;
mod correction;
mod correlation;
mod explain;
mod exposure;
mod folded;
mod frame;
mod frames;
mod gain_drift;
mod identify;
mod interference;
mod model;
mod polynomial;
mod relation;
mod report;
mod residual;
mod signal;
mod soft_clip;
mod time_base;
mod transfer;

pub use capture_time::{combine, unfold, Strips, Unfolded, UNFOLD_MAX_CORRELATION};
pub use correction::{Correction, FrameEvent, Line, UNMEASURED_EDGE};
pub use explain::{
    line_channels, line_groups, mean_of, pooled_motion, pooled_motion_and_share,
    pooled_noise_share, reference_spans, remove_explained, Covariate, Explanation, Measured,
    Observable, StoredTerm, FOLLOWS_SHARE, LAGS, MAX_LINE_REACH, MAX_LINE_SHIFTS,
};
pub use folded::Folding;
pub use frame::{pixel_frame, pixel_frame_on_tiles, PixelFrame};
pub use identify::Confound;
pub use relation::{check_silent, LINE_DB, MARGIN_DB, SILENT_PEAK};
pub use report::{
    explained_from_report, frame_from_report, harmonics_left_from_report,
    level_dependent_from_report, reusable_from_report, unsettled_from_report, EventReport,
    LineReport, LineUncertainty, Parameters, ReportError, Uncertainty, Unexplained,
    UnexplainedKind, Unsettled, MAX_STORED_TILES,
};
pub use signal::{alias, centred_highpass, equalize, sample_at, stft_len};
pub use signal::{peak, smooth3};

use model::{Fit, Model};
use residual::unexplained;

/// Options of [`calibrate`].
#[derive(Clone, Debug)]
pub struct Options {
    /// Least held-out SNR gain (dB) for an effect to be kept.
    pub min_gain_db: f64,
    /// Largest delay searched between reference and recovery (seconds).
    pub max_lag_s: f64,
    /// The recovery's high-pass: `(order, cutoff_hz)`, applied to the
    /// target too; `None` for none.
    pub highpass: Option<(usize, f64)>,
    /// The catalog, in the order effects are tried.
    pub effects: Vec<EffectKind>,
    /// After the catalog, explain what is left with the recording's own
    /// observables when they are given ([`calibrate_with`]).
    pub explain: bool,
    /// How the recovery renews its reference frame, `(interval, overlap)`
    /// in frames: every `interval` frames from the first, the next
    /// reference takes over `overlap` frames later (the `phase` stage's
    /// `reference_interval_s` and `reference_overlap`); `None`: one
    /// reference throughout. The sensor's lines reach the recovery through
    /// each reference frame's own noise, so their weights are fitted per
    /// reference ([`reference_spans`]).
    pub renewal: Option<(usize, usize)>,
    /// The farthest lag (frames) by which the recovery may shift one of
    /// its bands against the others (its `align` stage's `max_lag`): the
    /// sensor's lines are looked for at lags up to it.
    pub line_reach: usize,
}

impl Options {
    /// The defaults for a recovery at `fs` by the listen pipeline: its
    /// 4th-order high-pass at fs/40 (20-100 Hz), the whole catalog.
    pub fn for_rate(fs: f64) -> Options {
        Options {
            min_gain_db: 0.5,
            max_lag_s: 0.5,
            highpass: Some((4, crate::iir::default_highpass_cutoff_hz(fs))),
            effects: CATALOG.to_vec(),
            explain: true,
            renewal: None,
            line_reach: 0,
        }
    }
}

/// The effects calibrate knows.
#[derive(Clone, Copy, Debug, PartialEq, Eq)]
pub enum EffectKind {
    /// (b) The camera's true frame rate differs from the declared one.
    TimeBase,
    /// (d) Frames the camera dropped or delivered twice.
    Frames,
    /// (c) The exposure's boxcar low-pass.
    Exposure,
    /// (e) Narrowband lines not in the reference.
    Interference,
    /// (a) The object's transfer function (thesis ch. 4.3.3).
    Transfer,
    /// (f) The response saturates softly (`L tanh(x / L)`): a nonlinear
    /// object or loudspeaker driven hard. Added by the worked example in
    /// the README's "Closing the loop".
    SoftClip,
    /// (g) A static nonlinear response with even and odd terms (`x + c2
    /// x² + …`, order chosen on data the coefficients were not fitted on):
    /// the family soft clipping belongs to, for the responses it cannot
    /// fit (a quadratic term: energy at twice the reference's frequency).
    /// Of the two, the simpler is kept unless the other gains
    /// [`Options::min_gain_db`] more.
    Polynomial,
    /// (h) The gain changes slowly over the recording (a decaying strike,
    /// a fading light): a smooth trend in time, fitted only when the
    /// residual's time axis shows one. Per recording.
    GainDrift,
    /// (i) The time the motion is seen changes across the image's rows
    /// (rows read out one after another, two objects that hear the sound
    /// at different times): each strip of rows advanced by its delay
    /// before the strips are summed ([`capture_time`]). Needs the strips'
    /// recoveries ([`calibrate_strips`]); decided before the others, since
    /// it changes what the others are fitted on.
    CaptureTime,
    /// (j) Parts of the object move in antiphase (a non-rigid object's
    /// mode, two objects), so a sum over the region cancels them: the
    /// strips of rows summed with the signs and maximal-ratio weights
    /// they move with ([`capture_time::decide_gain`]). Decided after the
    /// capture time (whose sum already carries the signs), when it was
    /// not kept.
    RegionGain,
}

/// The catalog in the order it is tried: the capture time and the gain
/// across the image (before the rest, on the strips), time base, then frames, then the
/// spectral effects, then the nonlinearities, then (last, and only in a
/// round where nothing else gains) a drifting gain.
pub const CATALOG: [EffectKind; 10] = [
    EffectKind::CaptureTime,
    EffectKind::RegionGain,
    EffectKind::TimeBase,
    EffectKind::Frames,
    EffectKind::Exposure,
    EffectKind::Interference,
    EffectKind::Transfer,
    EffectKind::SoftClip,
    EffectKind::Polynomial,
    EffectKind::GainDrift,
];

impl EffectKind {
    pub fn name(self) -> &'static str {
        match self {
            EffectKind::TimeBase => "time_base",
            EffectKind::Frames => "dropped_frames",
            EffectKind::Exposure => "exposure",
            EffectKind::Interference => "interference",
            EffectKind::Transfer => "transfer_function",
            EffectKind::SoftClip => "soft_clip",
            EffectKind::Polynomial => "static_nonlinearity",
            EffectKind::GainDrift => "gain_drift",
            EffectKind::CaptureTime => "capture_time",
            EffectKind::RegionGain => "region_gain",
        }
    }
}

/// Errors of a recovery against the target on a span of samples.
#[derive(Clone, Copy, Debug, PartialEq, serde::Serialize)]
pub struct Errors {
    pub snr_db: f64,
    pub ssnr_db: f64,
    pub lsd_db: f64,
}

/// One accepted effect, as reported.
#[derive(Clone, Debug, serde::Serialize)]
pub struct EffectReport {
    pub name: String,
    pub parameters: Parameters,
    pub uncertainty: Uncertainty,
    pub snr_gain_db: f64,
    /// The structure of the residual that pointed to this effect, as it
    /// was before the effect was added (a nonlinearity: the harmonics).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub evidence: Vec<Unexplained>,
    /// What the correction cannot undo, in words
    /// ([`Correction::cannot_correct`]): what stays of the effect on a
    /// recording it is applied to.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub cannot_correct: Option<String>,
}

/// What `calibrate` found: `REPORT.json` is this, serialised.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Report {
    pub before: Errors,
    pub effects: Vec<EffectReport>,
    pub after: Errors,
    pub unexplained: Vec<Unexplained>,
    /// The residual of the plain linear model, before any effect, on
    /// every axis read (frequency: harmonics, lines, lag against
    /// frequency; time: lag and gain over the recording).
    pub linear_residual: Vec<Unexplained>,
    /// Pairs of kept effects a second explanation trades against each
    /// other, with the range their parameter spans ([`Confound`]).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub confounded: Vec<Confound>,
    /// What the residual explainer found in the recording's own
    /// observables after the catalog ([`explain`]): each kept covariate
    /// with its likely cause. `listen --calibration` measures each term's
    /// observable again on the new recording and subtracts it (fitted
    /// there, or through its stored taps for a tile's motion that follows
    /// the reference; a tile's brightness or a line that follows it is
    /// left out).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub explained: Vec<Explanation>,
    /// The recovery against the region's motion in pixels ([`PixelFrame`]),
    /// when it was measured: what `listen --calibration` brings a new
    /// recording's recovery to before applying a static nonlinearity.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub pixel_frame: Option<PixelFrame>,
}

/// A candidate that was fitted but not kept (for logs).
#[derive(Clone, Debug)]
pub struct Rejected {
    pub name: &'static str,
    pub parameters: Parameters,
    pub snr_gain_db: f64,
}

/// The result of [`calibrate`].
#[derive(Clone, Debug)]
pub struct Calibration {
    pub report: Report,
    /// The accepted corrections, in the order they apply.
    pub corrections: Vec<Correction>,
    pub rejected: Vec<Rejected>,
    /// The corrected recovery at `fs`, divided by the gain, on the capture grid.
    pub corrected: Vec<f64>,
    /// Delay (s) and gain of the final linear model.
    pub delay_s: f64,
    pub gain: f64,
}

/// Why calibration cannot run.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum CalError {
    #[error("rates must be > 0 (recovery {fs} Hz, reference {fr} Hz)")]
    Rates { fs: f64, fr: f64 },
    #[error("the recovery has {len} samples; calibration needs at least {min_len} ({:.2} s)", *.min_len as f64 / .fs)]
    TooShort { len: usize, min_len: usize, fs: f64 },
    #[error("non-finite samples")]
    NonFinite,
    #[error("the reference is silent (peak {peak:e}): there is nothing to calibrate against")]
    Silent { peak: f64 },
    #[error("the recovery does not follow the reference: held-out SNR {snr_db:.1} dB, within {} dB of what the same search reaches against a reference that was not played ({chance_db:.1} dB, the reference reversed in time); is it the signal that was played during the recording, and does the region see the object?", relation::MARGIN_DB)]
    Unrelated { snr_db: f64, chance_db: f64 },
    #[error("the recovery does not hold the reference's tone: at {hz:.1} Hz it stands {db:.1} dB above the recovery's spectrum around it, less than {} dB; is it the tone that was played, and does the region see the object?", relation::LINE_DB)]
    NoLine { hz: f64, db: f64 },
}

/// A fitted correction with its uncertainty.
#[derive(Clone)]
struct Candidate {
    correction: Correction,
    uncertainty: Uncertainty,
}

/// A candidate effect about to be fitted (for a progress display).
#[derive(Clone, Copy, Debug)]
pub struct Step {
    /// The greedy round (1-based).
    pub round: usize,
    pub effect: EffectKind,
    /// This candidate's place in the round (0-based) and the round's size.
    pub index: usize,
    pub of: usize,
}

/// Calibrates the recovery `y` (at `fs`, the declared frame rate) against
/// the reference `r` (at `fr`): see the module docs.
pub fn calibrate(
    y: &[f64],
    fs: f64,
    r: &[f64],
    fr: f64,
    opts: &Options,
) -> Result<Calibration, CalError> {
    calibrate_observed(y, fs, r, fr, opts, &mut |_| {})
}

/// [`calibrate`], calling `on_step` before each candidate is fitted.
pub fn calibrate_observed(
    y: &[f64],
    fs: f64,
    r: &[f64],
    fr: f64,
    opts: &Options,
    on_step: &mut dyn FnMut(Step),
) -> Result<Calibration, CalError> {
    calibrate_strips(y, None, fs, r, fr, opts, on_step)
}

/// [`calibrate_observed`] with the recoveries of strips of rows across the
/// region (the residual's image axis, and effect (i)): `y` is the region's
/// recovery, each strip's as long.
pub fn calibrate_strips(
    y: &[f64],
    strips: Option<&Strips>,
    fs: f64,
    r: &[f64],
    fr: f64,
    opts: &Options,
    on_step: &mut dyn FnMut(Step),
) -> Result<Calibration, CalError> {
    calibrate_with(y, (strips, &[]), fs, (r, fr), opts, on_step)
}

/// [`calibrate_strips`] with the recording's observables (tile motions and
/// intensities, each one value per frame) for the residual explainer
/// ([`explain`]), run after the catalog when [`Options::explain`].
pub fn calibrate_with(
    y: &[f64],
    (strips, covariates): (Option<&Strips>, &[Covariate]),
    fs: f64,
    (r, fr): (&[f64], f64),
    opts: &Options,
    on_step: &mut dyn FnMut(Step),
) -> Result<Calibration, CalError> {
    if !(fs.is_finite() && fs > 0.0 && fr.is_finite() && fr > 0.0) {
        return Err(CalError::Rates { fs, fr });
    }
    let min_len = 4 * stft_len(fs);
    if y.len() < min_len {
        return Err(CalError::TooShort {
            len: y.len(),
            min_len,
            fs,
        });
    }
    let strip_values = strips.iter().flat_map(|s| s.signals.iter().flatten());
    let observed = covariates.iter().flat_map(|c| c.values.iter());
    if y.iter()
        .chain(r)
        .chain(strip_values)
        .chain(observed)
        .any(|v| !v.is_finite())
    {
        return Err(CalError::NonFinite);
    }
    relation::check_silent(r)?;
    let m = Model {
        r,
        fr,
        fs,
        opts,
        level: &[],
        skip: &[],
        fold: None,
    };
    let fit0 = m.fit_linear(y);
    let level = transfer::level_dependent(&m, y, &fit0.t);
    let fold = polynomial::fold(&m, y, &fit0);
    // Left out of the effects' fits and their score; with no effect to
    // fit (the linear model's SNR alone, as the tests score a recording),
    // the whole recording is scored, whatever its level did.
    let skip = if opts.effects.is_empty() {
        Vec::new()
    } else {
        transfer::level_stretch(&m, &fit0.t, &level)
    };
    let m = Model {
        level: &level,
        skip: &skip,
        fold: fold.as_ref(),
        ..m
    };
    // The linear model again without the stretch left out (the same fit
    // where nothing is).
    let fit0 = if skip.is_empty() {
        fit0
    } else {
        m.fit_linear(y)
    };
    let recovery = y;
    let before = m.errors(y, &fit0);
    let mut linear_residual = unexplained(&m, y, &fit0);
    let mut kept: Vec<Kept> = Vec::new();
    let mut rejected = Vec::new();
    // (i), (j) The image's row axis, read first: a capture time that
    // changes across the rows, or parts that move in antiphase, change the
    // recovery every other effect is fitted on (the strips, each advanced
    // by its delay or signed, weighted, then summed). The gain is tried
    // only when the capture time was not kept (its sum carries the signs).
    let mut capture: Option<EffectReport> = None;
    let mut kept_capture: Option<Correction> = None;
    let mut timed: Vec<f64> = Vec::new();
    // The strips' fits, read once for both effects.
    let fits = strips
        .filter(|s| {
            capture_time::usable_strips(s, &fit0)
                && opts
                    .effects
                    .iter()
                    .any(|k| matches!(k, EffectKind::CaptureTime | EffectKind::RegionGain))
        })
        .map(|s| (s, capture_time::read(&m, y, s, &fit0)));
    for (index, kind) in [EffectKind::CaptureTime, EffectKind::RegionGain]
        .into_iter()
        .enumerate()
    {
        let Some((s, f)) = fits
            .as_ref()
            .filter(|_| opts.effects.contains(&kind) && capture.is_none())
        else {
            continue;
        };
        on_step(Step {
            round: 1,
            effect: kind,
            index,
            of: opts.effects.len(),
        });
        let d = match kind {
            EffectKind::CaptureTime => capture_time::decide(&m, (s, f), opts.min_gain_db),
            _ => capture_time::decide_gain(&m, y, (s, f), &fit0, opts.min_gain_db),
        };
        linear_residual.extend(d.evidence.clone());
        for (c, gain) in d.rejected {
            rejected.push(Rejected {
                name: kind.name(),
                parameters: c.parameters(fs, fit0.g),
                snr_gain_db: gain,
            });
        }
        if let Some((c, gain, z)) = d.kept {
            capture = Some(EffectReport {
                name: kind.name().to_string(),
                parameters: c.correction.parameters(fs, fit0.g),
                uncertainty: c.uncertainty.clone(),
                snr_gain_db: gain,
                evidence: d.evidence.into_iter().collect(),
                cannot_correct: c.correction.cannot_correct(fs),
            });
            timed = z;
            kept_capture = Some(c.correction);
        }
    }
    let y: &[f64] = if capture.is_some() { &timed } else { y };
    // Greedy, best first: each round fits every effect not yet kept (in
    // catalog order) on the current corrected recovery and keeps the one
    // with the largest held-out gain, if it reaches `min_gain_db`.
    let mut left: Vec<EffectKind> = opts.effects.clone();
    left.retain(|&k| !matches!(k, EffectKind::CaptureTime | EffectKind::RegionGain));
    // What the greedy loop starts from: the linear model on the recovery
    // as it now is (the strips' timed sum when the capture time was kept),
    // and its residual.
    let (fit_start, residual_start) = if capture.is_some() {
        let f = m.fit_linear(y);
        let u = unexplained(&m, y, &f);
        (f, u)
    } else {
        (fit0.clone(), linear_residual.clone())
    };
    let cur_start = m.errors(y, &fit_start);
    let (mut z, mut fit, mut cur) = (y.to_vec(), fit_start, cur_start);
    let mut round_no = 0;
    loop {
        round_no += 1;
        let mut round: Vec<Tried> = Vec::new();
        // The residual's harmonics now: a nonlinearity is only fitted
        // when there are some (the general polynomial otherwise finds an
        // amplitude-dependent gain, which on a chirp of varying response
        // mimics a filter: +0.5 dB on scenes with no nonlinearity at all).
        // (The first round's was read above.)
        let residual_now = if kept.is_empty() {
            residual_start.clone()
        } else {
            unexplained(&m, &z, &fit)
        };
        let harmonics: Vec<Unexplained> = residual_now
            .iter()
            .filter(|u| matches!(u, Unexplained::Harmonics { .. }))
            .cloned()
            .collect();
        let gain_moves: Vec<Unexplained> = residual_now
            .iter()
            .filter(|u| matches!(u, Unexplained::GainOverTime { .. }))
            .cloned()
            .collect();
        // A drifting gain is tried last, in a round where nothing else
        // gains: on a sweep, a gain that changes with frequency (exposure,
        // a resonance: properties of camera and object, worth reusing)
        // also changes with time.
        let mut try_kind = |kind: EffectKind, index: usize, round: &mut Vec<Tried>| {
            on_step(Step {
                round: round_no,
                effect: kind,
                index,
                of: left.len(),
            });
            if (kind == EffectKind::Polynomial && harmonics.is_empty())
                || (kind == EffectKind::GainDrift && gain_moves.is_empty())
            {
                return;
            }
            let Some(c) = fit_effect(kind, &m, &z, &fit) else {
                return;
            };
            let z2 = c.correction.apply(&z, fs);
            let fit2 = m.fit_linear(&z2);
            let e2 = m.errors(&z2, &fit2);
            let gain = e2.snr_db - cur.snr_db;
            tracing::info!(effect = kind.name(), gain_db = gain, "candidate");
            round.push(Tried { kind, c, gain });
        };
        for (index, &kind) in left.iter().enumerate() {
            if kind != EffectKind::GainDrift {
                try_kind(kind, index, &mut round);
            }
        }
        let gains = |round: &[Tried]| {
            round
                .iter()
                .any(|r| r.gain.is_finite() && r.gain >= opts.min_gain_db)
        };
        if !gains(&round) {
            if let Some(index) = left.iter().position(|&k| k == EffectKind::GainDrift) {
                try_kind(EffectKind::GainDrift, index, &mut round);
            }
        }
        let mut best = round
            .iter()
            .enumerate()
            .filter(|(_, r)| r.gain.is_finite() && r.gain >= opts.min_gain_db)
            .max_by(|a, b| a.1.gain.total_cmp(&b.1.gain))
            .map(|(i, _)| i);
        // One nonlinearity family: soft clipping, the simpler member (one
        // level), is kept over the general polynomial unless the
        // polynomial gains `min_gain_db` more.
        if let Some(bi) = best {
            if round[bi].kind == EffectKind::Polynomial {
                if let Some((ci, c)) = round
                    .iter()
                    .enumerate()
                    .find(|(_, r)| r.kind == EffectKind::SoftClip)
                {
                    if c.gain >= opts.min_gain_db && round[bi].gain - c.gain < opts.min_gain_db {
                        best = Some(ci);
                    }
                }
            }
        }
        let Some(bi) = best else {
            for t in round {
                rejected.push(Rejected {
                    name: t.kind.name(),
                    parameters: t.c.correction.parameters(fs, fit.g),
                    snr_gain_db: t.gain,
                });
            }
            break;
        };
        let mut t = round.swap_remove(bi);
        left.retain(|&k| k != t.kind);
        if matches!(t.kind, EffectKind::SoftClip | EffectKind::Polynomial) {
            left.retain(|&k| !matches!(k, EffectKind::SoftClip | EffectKind::Polynomial));
        }
        // Lines are subtracted first, from the recovery as delivered.
        if let Correction::Interference { lines } = &mut t.c.correction {
            let up = chain(&kept);
            for l in lines.iter_mut() {
                *l = Correction::line_before(*l, &up, fs);
            }
        }
        let evidence = match t.kind {
            EffectKind::SoftClip | EffectKind::Polynomial => harmonics.clone(),
            EffectKind::GainDrift => gain_moves.clone(),
            _ => Vec::new(),
        };
        kept.push(Kept {
            c: t.c,
            gain: t.gain,
            evidence,
        });
        z = apply_all(&chain(&kept), y, fs);
        fit = m.fit_linear(&z);
        cur = m.errors(&z, &fit);
    }
    // Each kept effect refitted with the others in place, then the pairs a
    // second explanation trades against each other.
    if kept.len() > 1 {
        identify::refit(&m, y, &mut kept);
        z = apply_all(&chain(&kept), y, fs);
        fit = m.fit_linear(&z);
        cur = m.errors(&z, &fit);
    }
    // Every kept effect must still earn its place with the others in
    // place (identify::let_go), and be told from none by its own
    // uncertainty (identify::insignificant).
    let mut gone = identify::let_go(&m, y, &mut kept, opts.min_gain_db);
    for (k, sds, loss) in identify::insignificant(&m, y, &mut kept) {
        tracing::info!(
            effect = k.c.correction.kind().name(),
            sds,
            loss_db = loss,
            "let go: within {} standard deviations of none",
            identify::SIGNIFICANT_SD
        );
        gone.push((k, loss));
    }
    if !gone.is_empty() {
        for (k, loss) in gone {
            rejected.push(Rejected {
                name: k.c.correction.kind().name(),
                parameters: k.c.correction.parameters(fs, fit.g),
                snr_gain_db: loss,
            });
        }
        z = apply_all(&chain(&kept), y, fs);
        fit = m.fit_linear(&z);
        cur = m.errors(&z, &fit);
    }
    let gates: Vec<UnexplainedKind> = residual_start.iter().map(Unexplained::kind).collect();
    let mut found = identify::confounds(&m, y, &kept, cur.snr_db, fit.g, &gates);
    // Where either explanation holds a transfer function, the two are
    // compared with its phase made from its gain (an object's response is
    // minimum phase up to a delay): a gain drift or a clock error can take
    // a resonance's gain or phase on a single sweep, leaving a transfer
    // function whose phase no object has.
    let passive_snr = |ks: &[Kept]| {
        let cs: Vec<Correction> = chain(ks).iter().map(|c| transfer::passive(c, fs)).collect();
        let z = apply_all(&cs, y, fs);
        m.errors(&z, &m.fit_linear(&z)).snr_db
    };
    let has_transfer = |ks: &[Kept]| {
        ks.iter()
            .any(|k| k.c.correction.kind() == EffectKind::Transfer)
    };
    // Not where the table leaves out level-dependent bins: its gain there
    // is interpolated, not the object's, and no phase follows from it.
    let annotate = |found: &mut [(Confound, Vec<Kept>)], kept: &[Kept]| {
        if !m.level.is_empty() {
            return;
        }
        let kept_passive = has_transfer(kept).then(|| passive_snr(kept));
        for (c, alt) in found.iter_mut() {
            if kept_passive.is_some() || has_transfer(alt) {
                let k = kept_passive.unwrap_or(c.snr_db);
                c.passive_snr_db = Some([k, passive_snr(alt)]);
                c.describe();
            }
        }
    };
    annotate(&mut found, &kept);
    // The two SNRs an alternative is judged on: held-out, or with the
    // transfer functions' phases made from their gains.
    let judged = |c: &Confound| c.passive_snr_db.unwrap_or([c.snr_db, c.alternative_snr_db]);
    // An alternative that explains the held-out part better by the least
    // gain becomes the kept explanation (the pair is still reported).
    let best = found
        .iter()
        .enumerate()
        .filter(|(_, (c, _))| judged(c)[1] >= judged(c)[0] + opts.min_gain_db)
        .max_by(|x, y| judged(&x.1 .0)[1].total_cmp(&judged(&y.1 .0)[1]))
        .map(|(i, _)| i);
    let mut confounded: Vec<Confound> = Vec::new();
    match best {
        None => confounded.extend(found.into_iter().map(|(c, _)| c)),
        Some(bi) => {
            // The better explanation is kept; its record stays (numbers
            // swapped) and the others are read again against it.
            let mut found = found;
            let (mut c, alt) = found.swap_remove(bi);
            let old: Vec<Parameters> = chain(&kept)
                .iter()
                .map(|k| k.parameters(fs, fit.g))
                .collect();
            kept = alt;
            z = apply_all(&chain(&kept), y, fs);
            fit = m.fit_linear(&z);
            cur = m.errors(&z, &fit);
            c.swap(old);
            let mut again = identify::confounds(&m, y, &kept, cur.snr_db, fit.g, &gates);
            annotate(&mut again, &kept);
            let more: Vec<Confound> = again
                .into_iter()
                .map(|(n, _)| n)
                .filter(|n| n.parameter != c.parameter)
                .collect();
            confounded.push(c);
            confounded.extend(more);
        }
    }
    // What is left, explained by the recording's own observables: their
    // parts are removed from the recovery the catalog's corrections act on.
    let mut explained = Vec::new();
    let mut cleaned: Option<Vec<f64>> = None;
    if opts.explain && !covariates.is_empty() {
        let all: Vec<Correction> = chain(&kept);
        if let Some(e) = explain::explain(&m, y, &all, covariates, opts.min_gain_db) {
            z = apply_all(&all, &e.cleaned, fs);
            fit = m.fit_linear(&z);
            cur = m.errors(&z, &fit);
            explained = e.kept;
            cleaned = Some(e.cleaned);
        }
    }
    let y: &[f64] = cleaned.as_deref().unwrap_or(y);
    let corrections = chain(&kept);
    let effects: Vec<EffectReport> = corrections
        .iter()
        .enumerate()
        .map(|(i, c)| {
            let k = kept
                .iter()
                .find(|k| k.c.correction.kind() == c.kind())
                .expect("every correction comes from a kept effect");
            // With more than one kept: what the held-out SNR loses without
            // this one (the others as fitted).
            let gain = if corrections.len() > 1 {
                let mut others = corrections.clone();
                others.remove(i);
                let w = apply_all(&others, y, fs);
                cur.snr_db - m.errors(&w, &m.fit_linear(&w)).snr_db
            } else {
                k.gain
            };
            EffectReport {
                name: c.kind().name().to_string(),
                parameters: c.parameters(fs, fit.g),
                uncertainty: k.c.uncertainty.clone(),
                snr_gain_db: gain,
                evidence: k.evidence.clone(),
                cannot_correct: c.cannot_correct(fs),
            }
        })
        .collect();
    // The capture time comes first: it is applied to the strips.
    let effects: Vec<EffectReport> = capture.into_iter().chain(effects).collect();
    let corrections: Vec<Correction> = kept_capture.into_iter().chain(corrections).collect();
    relation::check_follows(&m, recovery, cur.snr_db)?;
    let unexplained = unexplained(&m, &z, &fit);
    let g = if fit.g != 0.0 { fit.g } else { 1.0 };
    Ok(Calibration {
        report: Report {
            before,
            effects,
            after: cur,
            unexplained,
            linear_residual,
            confounded,
            explained,
            pixel_frame: None,
        },
        corrections,
        rejected,
        corrected: z.iter().map(|v| v / g).collect(),
        delay_s: fit.tau,
        gain: fit.g,
    })
}

fn fit_effect(kind: EffectKind, m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    match kind {
        EffectKind::TimeBase => time_base::fit_time_base(m, z, fit),
        EffectKind::Frames => frames::fit_frames(m, z, fit),
        EffectKind::Exposure => exposure::fit_exposure(m, z, fit),
        EffectKind::Interference => interference::fit_interference(m, z, fit),
        EffectKind::Transfer => transfer::fit_transfer(m, z, fit),
        EffectKind::SoftClip => soft_clip::fit_soft_clip(m, z, fit),
        EffectKind::Polynomial => polynomial::fit_polynomial(m, z, fit),
        EffectKind::GainDrift => gain_drift::fit_gain_drift(m, z, fit),
        // Fitted on the strips, before the loop.
        EffectKind::CaptureTime | EffectKind::RegionGain => None,
    }
}

/// An effect [`calibrate`] kept, with its held-out gain.
#[derive(Clone)]
struct Kept {
    c: Candidate,
    gain: f64,
    evidence: Vec<Unexplained>,
}

/// The kept corrections in the order they apply: interference lines first
/// (subtracted from the recovery as delivered), then the others in the
/// order they were kept.
fn chain(kept: &[Kept]) -> Vec<Correction> {
    let lines = kept
        .iter()
        .filter(|k| k.c.correction.kind() == EffectKind::Interference);
    let rest = kept
        .iter()
        .filter(|k| k.c.correction.kind() != EffectKind::Interference);
    lines.chain(rest).map(|k| k.c.correction.clone()).collect()
}

/// One effect fitted in a round of [`calibrate`].
struct Tried {
    kind: EffectKind,
    c: Candidate,
    gain: f64,
}

/// Applies `corrections` in order to a recovery at `fs`.
pub fn apply_all(corrections: &[Correction], y: &[f64], fs: f64) -> Vec<f64> {
    let mut z = y.to_vec();
    for c in corrections {
        z = c.apply(&z, fs);
    }
    z
}

/// Applies `corrections` in order to a new recording's recovery at `fs`,
/// as `listen --calibration` does: as [`apply_all`], except that a
/// transfer table is applied as a Wiener inverse against what folds into
/// the band from above the Nyquist frequency ([`folded`]), with what that
/// found.
pub fn apply_to_recording(
    corrections: &[Correction],
    y: &[f64],
    fs: f64,
) -> (Vec<f64>, Vec<Folding>) {
    let mut z = y.to_vec();
    let mut found = Vec::new();
    for c in corrections {
        match folded::apply(c, &z, fs) {
            Some((out, f)) => {
                z = out;
                found.push(f);
            }
            None => z = c.apply(&z, fs),
        }
    }
    (z, found)
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests;
