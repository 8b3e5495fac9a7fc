//! The residual explainer (issue 50): after the catalog's effects, what is
//! left of the residual is regressed on signals measured on the recording
//! itself, in the same run, that no family models: the motion of every
//! tile of the frame outside the region (both axes), the motion of the
//! tiles inside it that move on their own, and the mean intensity of
//! every tile, inside the region or not. Each candidate enters
//! through a short FIR (lags -[`LAGS`]..=[`LAGS`] frames), so a gain, a
//! small lag or a simple transfer function is allowed.
//!
//! Selection is forward and greedy on the calibration's own split: every
//! candidate's FIR is fitted on the fit part of the residual (after the
//! ones already kept, by projecting them out), candidates are ranked by
//! how much of the held-out residual they remove, and the best is kept
//! only when the corrected recovery, linear model refitted, gains at least
//! [`super::Options::min_gain_db`] of held-out SNR (the penalty for size;
//! at most [`MAX_KEPT`]), or, for a term `listen --calibration` fits again
//! on the next recording, at least [`WEAK_MIN_DB`] and a removal beyond
//! chance ([`WEAK_Z`] standard deviations above the same observable's
//! circular shifts: [`beyond_chance`]). Motion measured on the object is left out on
//! purpose: a regression on it would only be a better estimator of the
//! object, not an effect. A tile inside the region is observed only when
//! its motion does not follow the sound on either axis and moves with
//! another tile's that does not either ([`observed_motion`]): the
//! background around the object moving inside the region is then seen.
//!
//! Lines of the sensor: the mean intensity of every row that crosses the
//! region, measured beside it (left and right of it), and of every column,
//! measured above and below it. One row's offset (the sensor's row noise,
//! a flicker read out row by row) reaches the recovery weighed by that
//! row's texture, so no tile's mean explains it: the rows enter together,
//! as one candidate, fitted jointly, one weight per row and reference
//! frame of the recovery ([`reference_spans`]) at each of up to
//! [`MAX_LINE_SHIFTS`] lags within the recovery's reach
//! ([`super::Options::line_reach`]). The lags are chosen on the recording
//! (each alone, by the held-out residual it removes): the recovery's
//! `align` shifts each band by its own lag, and the bands that see a
//! row's offset carry no sound to align them by, so theirs is chance.
//!
//! Each kept covariate is reported with what it most likely is, read from
//! how the other tiles move with it: the camera or its mount when most of
//! the tiles outside the region move with it, another vibrating thing in
//! view when only some do (their rectangle is named), the light when the
//! intensities of many tiles change with it, the sensor's rows when only
//! tiles on the same rows do.

use super::model::Model;
use super::signal::centred_highpass;
use super::{apply_all, Correction};

/// Lags of each covariate's FIR, frames either side.
pub const LAGS: usize = 2;
/// Most lags at which the lines' joint candidate has a weight per line
/// and reference.
pub const MAX_LINE_SHIFTS: usize = 3;
/// The farthest lag (frames) a stored line term may name.
pub const MAX_LINE_REACH: usize = 64;
/// A lag joins the lines' first only when alone it removes at least this
/// share of what the first removes.
const LINE_SHIFT_SHARE: f64 = 0.25;
/// The tiles that move least, pooled for a motion of the whole image,
/// are those whose (high-passed) motion has at most this many times the
/// median tile's power.
const COMMON_POWER: f64 = 2.0;
/// Most covariates kept.
pub const MAX_KEPT: usize = 6;
/// Lags (frames either side) of the FIR through which the reference is
/// asked to explain a kept observable ([`follows_reference`]): longer than
/// the covariates' own, since a second object that hears the sound may
/// ring (a tine, a panel).
const REF_LAGS: usize = 16;
/// A kept observable "follows the reference" when the reference explains
/// at least this share of its held-out energy; such a term's FIR is never
/// fitted again on another recording (the fit would remove the sound
/// itself). For an observable independent of the sound the share is
/// chance, about `-(2 REF_LAGS + 1) / n` of the fit part's samples (under
/// 2% on a 2 s clip at 2200 fps).
pub const FOLLOWS_SHARE: f64 = 0.05;
/// A tile "moves with" a covariate when their high-passed signals
/// correlate beyond chance: `|r|` at least `WITH_IT_Z / sqrt(n)` over `n`
/// samples (and at least [`WITH_IT_MIN`]; a tile alone is noisy, so a
/// threshold on the correlation's size would miss the tiles a pooled
/// covariate was made of).
const WITH_IT_Z: f64 = 6.0;
const WITH_IT_MIN: f64 = 0.1;
/// A weak term (gaining under [`super::Options::min_gain_db`] but at
/// least this, dB of held-out SNR) is kept when it is beyond chance
/// ([`beyond_chance`]) and `listen --calibration` fits it again on the
/// next recording ([`Explanation::refit`]): there a term of a few taps
/// costs about its taps over the recording's samples of the noise, so a
/// real but weak effect (a faint shake under the sensor's noise) gains
/// what it can and a wrong one loses next to nothing.
const WEAK_MIN_DB: f64 = 0.1;
/// How far (standard deviations) a weak term's held-out removal must lie
/// above the removals of the same observable shifted in time
/// ([`beyond_chance`]).
const WEAK_Z: f64 = 6.0;
/// How many circular shifts of the observable make the chance removals.
const NULL_SHIFTS: usize = 16;

/// What an observable measures.
#[derive(Clone, Copy, Debug, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
#[serde(rename_all = "snake_case")]
pub enum Observable {
    /// Motion along +x, px.
    MotionX,
    /// Motion along +y, px.
    MotionY,
    /// Mean intensity, DN.
    Intensity,
    /// Mean intensity of a row's part (or a band of rows') beside the
    /// region, DN; the rows enter together ([`line_groups`]).
    RowIntensity,
    /// Mean intensity of a column's part (or a band of columns') above or
    /// below the region, DN.
    ColumnIntensity,
}

impl Observable {
    /// A line of the sensor (rows or columns), measured in parts.
    pub fn is_line(self) -> bool {
        matches!(self, Observable::RowIntensity | Observable::ColumnIntensity)
    }

    /// A tile's motion (along x or y).
    pub fn is_motion(self) -> bool {
        matches!(self, Observable::MotionX | Observable::MotionY)
    }

    /// The farthest lag its FIR is looked for at, given the recovery's
    /// `align` reach: lines and a tile's motion reach the recovery
    /// through the bands that see them, which `align` shifted by a lag of
    /// its own; an intensity about lag 0 (searched, one following the
    /// reference was taken for light).
    pub fn lag_reach(self, reach: usize) -> usize {
        match self.is_line() || self.is_motion() {
            true => reach,
            false => 0,
        }
    }
}

/// The lags of a tile's FIR, -[`LAGS`]..=[`LAGS`] frames.
pub fn tile_shifts() -> Vec<i64> {
    (-(LAGS as i64)..=LAGS as i64).collect()
}

/// A tile's FIR lags, -[`LAGS`]..=[`LAGS`] frames about the lag of
/// -`reach`..=`reach` whose column alone removes most ([`pick_shifts`]
/// with one lag; about 0 when none removes anything).
pub fn tile_shifts_about(
    xs: &[Vec<f64>],
    reach: usize,
    removes: impl Fn(&[Vec<f64>]) -> f64,
) -> Vec<i64> {
    let c = pick_shifts(xs, (1, reach), removes)
        .first()
        .copied()
        .unwrap_or(0);
    tile_shifts().into_iter().map(|s| s + c).collect()
}

/// The parts of `tiles` (rectangles `[x, y, w, h]` measuring `obs`) that
/// make one channel each, in order: for rows, the parts on the same rows
/// (left and right of the region), top to bottom; for columns, the parts
/// on the same columns, left to right; for a tile's observable, all of
/// them (their mean is one channel). A channel is the parts' mean weighed
/// by their areas ([`line_channels`]).
pub fn line_groups(obs: Observable, tiles: &[[u32; 4]]) -> Vec<Vec<usize>> {
    let key = |r: &[u32; 4]| match obs {
        Observable::RowIntensity => Some((r[1], r[3])),
        Observable::ColumnIntensity => Some((r[0], r[2])),
        _ => None,
    };
    let mut keys: Vec<Option<(u32, u32)>> = tiles.iter().map(key).collect();
    keys.sort_unstable();
    keys.dedup();
    keys.into_iter()
        .map(|k| (0..tiles.len()).filter(|&i| key(&tiles[i]) == k).collect())
        .collect()
}

/// The frames each reference of a recovery `n` frames long covers, in
/// order, when it renews its reference as `renewal` says
/// ([`super::Options::renewal`]); a last span shorter than half an
/// interval joins the one before it.
pub fn reference_spans(n: usize, renewal: Option<(usize, usize)>) -> Vec<std::ops::Range<usize>> {
    let mut cuts = vec![0];
    if let Some((interval, overlap)) = renewal.filter(|r| r.0 > 0) {
        let mut b = interval + overlap;
        while b < n {
            cuts.push(b);
            b += interval;
        }
        if cuts.len() > 1 && n - cuts[cuts.len() - 1] < interval / 2 {
            cuts.pop();
        }
    }
    cuts.push(n);
    cuts.windows(2).map(|w| w[0]..w[1]).collect()
}

/// Each of `channels` once per span of `spans` (zero outside it),
/// channel after channel: one weight per line and reference.
pub fn per_reference(channels: &[Vec<f64>], spans: &[std::ops::Range<usize>]) -> Vec<Vec<f64>> {
    channels
        .iter()
        .flat_map(|c| {
            spans.iter().map(move |s| {
                let mut v = vec![0.0; c.len()];
                let s = s.start.min(c.len())..s.end.min(c.len());
                v[s.clone()].copy_from_slice(&c[s]);
                v
            })
        })
        .collect()
}

/// The channels of `tiles` measuring `obs` ([`line_groups`]), each the
/// area-weighted mean of its parts' values (`values(i)`: tile `i`'s, one
/// a frame, `n` long; a shorter one counts as zero past its end).
pub fn line_channels<'a>(
    obs: Observable,
    tiles: &[[u32; 4]],
    n: usize,
    values: impl Fn(usize) -> &'a [f64],
) -> Vec<Vec<f64>> {
    line_groups(obs, tiles)
        .into_iter()
        .map(|g| {
            let area = |i: usize| f64::from(tiles[i][2]) * f64::from(tiles[i][3]);
            let total: f64 = g.iter().map(|&i| area(i)).sum();
            let mut out = vec![0.0; n];
            for &i in &g {
                let w = area(i) / total.max(f64::MIN_POSITIVE);
                for (o, v) in out.iter_mut().zip(values(i)) {
                    *o += w * v;
                }
            }
            out
        })
        .collect()
}

/// One candidate explanatory signal, measured on the recording.
#[derive(Clone, Debug)]
pub struct Covariate {
    pub observable: Observable,
    /// The tile `[x, y, w, h]` it was measured on.
    pub rect: [u32; 4],
    /// The tile overlaps the calibrated region.
    pub inside: bool,
    /// One value per delivered frame, as the recovery.
    pub values: Vec<f64>,
}

/// A covariate the explainer kept.
#[derive(Clone, Debug, serde::Serialize)]
pub struct Explanation {
    pub observable: Observable,
    /// The tile `[x, y, w, h]` (for a mean over tiles, the rectangle
    /// holding them).
    pub rect: [u32; 4],
    /// The tiles whose observable is averaged (one for a tile alone):
    /// what `listen --calibration` measures again on a new recording.
    pub tiles: Vec<[u32; 4]>,
    /// One of its tiles overlaps the region (for a motion: a tile there
    /// that moves on its own, not with the sound).
    pub inside_region: bool,
    /// What it most likely is, in words.
    pub label: String,
    /// The physical cause: `camera`, `other_object`, `light`, `sensor_rows`,
    /// `sensor_columns`, or `object` (a tile's brightness inside the region
    /// that follows the reference: the object's own motion through its texture).
    pub cause: &'static str,
    /// Where the cause is seen: the rectangle holding the tiles that move
    /// or brighten with it.
    pub seen_at: [u32; 4],
    /// Tiles (of the same observable, outside the region for motion) that
    /// move or brighten with it, and how many were looked at.
    pub tiles_with_it: usize,
    pub tiles_of: usize,
    /// Share of the held-out error's energy before the explainer that
    /// keeping this covariate removed, after the ones kept before it (the
    /// report's order): in [0, 1], and the shares add up to what the
    /// explainer removes.
    pub residual_share: f64,
    /// Held-out SNR lost without it, the others kept (dB).
    pub snr_gain_db: f64,
    /// Held-out SNR gained when it was kept, after the ones before it
    /// (dB; the report's order): these add up to the explainer's gain,
    /// and [`Explanation::residual_share`] is their energy.
    pub kept_gain_db: f64,
    /// The FIR from the observable (px or DN) to the recovery (recovery
    /// units), at the lags of [`Explanation::shifts`]: what is subtracted
    /// at frame n is `Σ taps[k] x[n - shifts[k]]`. For lines, one such
    /// FIR per line ([`line_groups`]'s order) and reference
    /// ([`reference_spans`]), one after another.
    pub taps: Vec<f64>,
    /// The FIR's lags, frames: -[`LAGS`]..=[`LAGS`] for a tile's
    /// observable; for lines, those chosen on this recording (at most
    /// [`MAX_LINE_SHIFTS`]; a new recording chooses as many again).
    pub shifts: Vec<i64>,
    /// For lines: how the recovery renewed its reference
    /// (`[interval, overlap]` frames, [`super::Options::renewal`]); each
    /// line has one FIR per reference, fitted again on a new recording
    /// over that recording's own references (a record: `listen` does not
    /// read it back).
    #[serde(skip_serializing_if = "Option::is_none")]
    pub renewal: Option<[usize; 2]>,
    /// Share of the observable's held-out energy (high-passed, as the
    /// recovery) that the reference explains through an FIR of lags
    /// -16..=16 frames fitted on the fit part: the observable hears the
    /// sound too (a second object in the same acoustic field) when it is
    /// at least [`FOLLOWS_SHARE`].
    pub follows_reference: f64,
    /// Whether `listen --calibration` fits this term's FIR again on the
    /// new recording (least squares of the recovery on the observable's
    /// lagged values, measured there), instead of the stored taps brought
    /// to its scale: only when the observable does not follow the
    /// reference, since then the fit cannot remove the sound, and it
    /// holds the new recording's own coupling (a texture couples a shake
    /// across the measured axis into the recovery its own way).
    pub refit: bool,
    /// Its tiles' motion is pooled weighing each tile by its noise
    /// ([`pooled_motion`]: the tiles that move least, for a motion of the
    /// whole image), on this recording and again on the new one.
    #[serde(skip_serializing_if = "std::ops::Not::not")]
    pub weighed: bool,
    /// For tiles weighed by their noise: the share of their pooled
    /// motion's power that is the tiles' own noise
    /// ([`pooled_noise_share`]); subtracting the term removes at most
    /// about one minus it of what the motion costs.
    #[serde(skip_serializing_if = "Option::is_none")]
    pub tiles_noise_share: Option<f64>,
}

/// An explanation as a stored report holds it: what to measure again on a
/// new recording and the FIR to subtract.
#[derive(Clone, Debug, PartialEq, serde::Deserialize)]
pub struct StoredTerm {
    pub observable: Observable,
    pub tiles: Vec<[u32; 4]>,
    pub taps: Vec<f64>,
    /// The FIR's lags (absent in a report written before lines were
    /// observed: [`tile_shifts`]).
    #[serde(default = "tile_shifts")]
    pub shifts: Vec<i64>,
    /// Fitted again on the new recording (absent in a report written
    /// before the calibration said: the stored taps).
    #[serde(default)]
    pub refit: bool,
    /// Its tiles' motion pooled weighing each by its noise
    /// ([`pooled_motion`]; absent in a report written before: the plain
    /// mean).
    #[serde(default)]
    pub weighed: bool,
}

/// What [`explain`] found.
pub(super) struct Explained {
    pub(super) kept: Vec<Explanation>,
    /// The recovery as delivered with the kept covariates' parts removed.
    pub(super) cleaned: Vec<f64>,
}

/// `x[n - lag]` for lags `-lags..=lags` (zero outside).
fn lagged_by(x: &[f64], lags: usize) -> Vec<Vec<f64>> {
    let all: Vec<i64> = (-(lags as i64)..=lags as i64).collect();
    shifted(x, &all)
}

/// `x[n - lag]` for each lag of `shifts` (zero outside).
fn shifted(x: &[f64], shifts: &[i64]) -> Vec<Vec<f64>> {
    let n = x.len();
    shifts
        .iter()
        .map(|&lag| {
            (0..n as i64)
                .map(|i| {
                    let j = i - lag;
                    if j >= 0 && j < n as i64 {
                        x[j as usize]
                    } else {
                        0.0
                    }
                })
                .collect()
        })
        .collect()
}

/// The corrections whose action on a sum is the sum of their actions (a
/// covariate's part passes through them as the recovery does).
fn linear(c: &Correction) -> bool {
    matches!(
        c,
        Correction::TimeBase { .. }
            | Correction::Frames { .. }
            | Correction::Exposure { .. }
            | Correction::Transfer { .. }
            | Correction::GainDrift { .. }
    )
}

/// Takes the span of `basis` (orthonormal under `dot`) out of each of
/// `cols`.
fn project_out(cols: &mut [Vec<f64>], basis: &[Vec<f64>], dot: &dyn Fn(&[f64], &[f64]) -> f64) {
    for col in cols {
        for b in basis {
            let g = dot(b, col);
            for (a, v) in col.iter_mut().zip(b) {
                *a -= g * v;
            }
        }
    }
}

/// How many standard deviations `took` (the held-out energy a candidate
/// removes) lies above what the same observable `x` removes when shifted
/// in time by [`NULL_SHIFTS`] circular shifts spread over the recording
/// (`null`: the held-out energy a shifted copy removes, its lag chosen and
/// its taps fitted the same way). The shifts keep the observable's spectrum and the residual's, and
/// break only their alignment: chance as this recording makes it. `0`
/// when the shifts remove as much.
fn beyond_chance(took: f64, x: &[f64], null: impl Fn(&[f64]) -> f64) -> f64 {
    let n = x.len();
    if n < 2 * NULL_SHIFTS {
        return 0.0;
    }
    let chance: Vec<f64> = (1..=NULL_SHIFTS)
        .map(|k| {
            let mut r = x.to_vec();
            r.rotate_left(k * n / (NULL_SHIFTS + 1));
            null(&r)
        })
        .collect();
    let mean = chance.iter().sum::<f64>() / chance.len() as f64;
    let var = chance.iter().map(|v| (v - mean).powi(2)).sum::<f64>() / (chance.len() - 1) as f64;
    let z = (took - mean) / var.sqrt();
    if z.is_finite() {
        z
    } else {
        0.0
    }
}

/// Pearson correlation of two equally long signals.
fn corr(a: &[f64], b: &[f64]) -> f64 {
    let (mut ab, mut aa, mut bb) = (0.0, 0.0, 0.0);
    for (x, y) in a.iter().zip(b) {
        ab += x * y;
        aa += x * x;
        bb += y * y;
    }
    if aa > 0.0 && bb > 0.0 {
        ab / (aa * bb).sqrt()
    } else {
        0.0
    }
}

/// One candidate as the regression sees it.
struct Cand {
    index: usize,
    /// The high-passed covariate, as delivered (one per line for the
    /// lines' joint candidate).
    xs: Vec<Vec<f64>>,
    /// The lags of each one's FIR.
    shifts: Vec<i64>,
    /// Their lagged columns through the linear corrections, with the kept
    /// ones' span projected out on the fit part.
    cols: Vec<Vec<f64>>,
}

impl Cand {
    /// `Σ taps · x` over its covariates' lagged columns, each `x` passed
    /// through `lin` first.
    fn part(&self, taps: &[f64], (lin, fs): (&[Correction], f64), len: usize) -> Vec<f64> {
        let mut part = vec![0.0; len];
        for (x, t) in self.xs.iter().zip(taps.chunks(self.shifts.len())) {
            let through = apply_all(lin, x, fs);
            for (a, col) in t.iter().zip(shifted(&through, &self.shifts)) {
                for (p, v) in part.iter_mut().zip(col) {
                    *p += a * v;
                }
            }
        }
        part
    }
}

/// Explains what `chain` leaves of the residual of `y` (the recovery as
/// delivered, or the strips' timed sum) with `covs`; `None` when nothing
/// is kept.
pub(super) fn explain(
    m: &Model,
    y: &[f64],
    chain: &[Correction],
    covs: &[Covariate],
    min_gain_db: f64,
) -> Option<Explained> {
    let t0 = std::time::Instant::now();
    let n = y.len();
    let lines: Vec<&Covariate> = covs.iter().filter(|c| c.observable.is_line()).collect();
    let covs: Vec<Covariate> = covs
        .iter()
        .filter(|c| !c.observable.is_line())
        .cloned()
        .collect();
    let fs = m.fs;
    let hp = m.opts.highpass;
    let lin: Vec<Correction> = chain.iter().filter(|c| linear(c)).cloned().collect();
    let spans = reference_spans(n, m.opts.renewal);
    let z = apply_all(chain, y, fs);
    let fit = m.fit_linear(&z);
    let start = m.errors(&z, &fit);
    let len = z.len();
    let fitw: Vec<f64> = (0..len).map(|i| f64::from(u8::from(m.is_fit(i)))).collect();
    let simd = crate::join::Simd::detect();
    let dot = |a: &[f64], b: &[f64]| -> f64 { super::signal::weighted_dot(simd, a, b, &fitw) };
    let heldw: Vec<f64> = (0..len)
        .map(|i| f64::from(u8::from(m.is_held(i))))
        .collect();
    let held_energy = |a: &[f64]| -> f64 { super::signal::weighted_dot(simd, a, a, &heldw) };
    // Which tiles' motion may explain: those outside the region, and
    // those inside it that move on their own.
    // Each tile's motion, high-passed (read by both below).
    let moving: Vec<Option<Vec<f64>>> = covs
        .iter()
        .map(|c| {
            (c.observable.is_motion() && c.values.len() == n)
                .then(|| centred_highpass(&c.values, fs, hp))
        })
        .collect();
    let observed = observed_motion(&covs, &moving, (&lin, fs), &fit.t, &dot, &held_energy);
    // Each tile is noisy alone: means over tiles that share a cause (all
    // those observed, a row of tiles, a column, those inside the region
    // that move on their own) join the candidates.
    let pooled = pool(&covs, &observed, &moving, (n, fs, hp));
    let singles = covs.len();
    let joints = joint_lines(&lines, n);
    // The tiles each candidate is the mean of (for lines, the parts of
    // every line).
    let members: Vec<Vec<[u32; 4]>> = covs
        .iter()
        .map(|c| vec![c.rect])
        .chain(pooled.iter().map(|p| p.1.clone()))
        .chain(joints.iter().map(|j| j.1.clone()))
        .collect();
    // The lines of each joint candidate, by the candidate's index.
    let pooled_len = pooled.len();
    // Whether each candidate's tiles are weighed by their noise.
    let weighed_of: Vec<bool> = std::iter::repeat_n(false, singles)
        .chain(pooled.iter().map(|p| p.2))
        .chain(joints.iter().map(|_| false))
        .collect();
    let mut channels_of: Vec<Option<Vec<Vec<f64>>>> = vec![None; singles + pooled_len];
    let covs: Vec<Covariate> = covs
        .into_iter()
        .chain(pooled.into_iter().map(|p| p.0))
        .chain(joints.into_iter().map(|(c, _, ch)| {
            channels_of.push(Some(ch));
            c
        }))
        .collect();
    let covs = &covs[..];
    // A single tile as observed; a mean of tiles is made of observed
    // ones; the lines are beside the region.
    let usable: Vec<usize> = (0..covs.len())
        .filter(|&i| {
            let c = &covs[i];
            c.values.len() == n
                && (i >= singles || observed[i])
                && (i < singles + pooled_len
                    || !(c.inside && c.observable != Observable::Intensity))
                && c.values.iter().all(|v| v.is_finite())
        })
        .collect();
    if usable.is_empty() {
        return None;
    }
    // The residual of the best model so far.
    let resid0: Vec<f64> = z.iter().zip(&fit.t).map(|(a, t)| a - fit.g * t).collect();
    // The held-out energy of `r` that `cols` remove, fitted on the fit
    // part.
    let removed = |cols: &[Vec<f64>], r: &[f64]| {
        let mut after = r.to_vec();
        for b in orthonormal(cols, &dot) {
            let beta = dot(&b, r);
            for (a, v) in after.iter_mut().zip(&b) {
                *a -= beta * v;
            }
        }
        held_energy(r) - held_energy(&after)
    };
    let mut cands: Vec<Cand> = usable
        .iter()
        .filter_map(|&i| {
            let xs: Vec<Vec<f64>> = match &channels_of[i] {
                Some(ch) => {
                    let hp: Vec<Vec<f64>> =
                        ch.iter().map(|v| centred_highpass(v, fs, hp)).collect();
                    per_reference(&hp, &spans)
                }
                None => vec![centred_highpass(&covs[i].values, fs, hp)],
            };
            let through: Vec<Vec<f64>> = xs.iter().map(|x| apply_all(&lin, x, fs)).collect();
            let shifts = match channels_of[i] {
                // Each lag alone, by the held-out residual it removes.
                Some(_) => {
                    let reach = m.opts.line_reach.min(MAX_LINE_REACH);
                    pick_shifts(&through, (MAX_LINE_SHIFTS, reach), |cols| {
                        removed(cols, &resid0)
                    })
                }
                // A tile's FIR: its lags about the lag at which it alone
                // removes most. A motion across the object's reaches the
                // recovery through the bands oriented to see it, which
                // carry none of the sound: `align` shifted them by a lag
                // of chance.
                None => {
                    let reach =
                        (covs[i].observable).lag_reach(m.opts.line_reach.min(MAX_LINE_REACH));
                    tile_shifts_about(&through, reach, |cols| removed(cols, &resid0))
                }
            };
            if shifts.is_empty() {
                return None;
            }
            let cols: Vec<Vec<f64>> = through.iter().flat_map(|x| shifted(x, &shifts)).collect();
            if cols.iter().any(|c| c.len() != len)
                || cols.iter().all(|c| c.iter().all(|&a| a == 0.0))
            {
                return None;
            }
            Some(Cand {
                index: i,
                xs,
                shifts,
                cols,
            })
        })
        .collect();
    tracing::debug!(
        ms = t0.elapsed().as_secs_f64() * 1e3,
        "explainer's candidates prepared"
    );
    // The residual with the kept candidates' span (fit-part inner
    // product) removed.
    let mut resid = resid0.clone();
    let mut kept: Vec<Cand> = Vec::new();
    let mut cur = start;
    let mut cleaned = y.to_vec();
    let mut taps_all: Vec<Vec<f64>> = Vec::new();
    // The kept candidates' span, orthonormal on the fit part.
    let mut basis: Vec<Vec<f64>> = Vec::new();
    // The held-out SNR before the explainer, then after each kept term.
    let mut steps = vec![start.snr_db];
    while kept.len() < MAX_KEPT && !cands.is_empty() {
        // Rank by the held-out residual energy each removes. Candidates
        // within 2% of the best carry the same signal (a light reads as
        // motion on a tile whose gradients do not sum to zero): the more
        // direct observable is kept, an intensity before a motion, then the
        // one that pools more of the image.
        let gains: Vec<f64> = cands.iter().map(|c| removed(&c.cols, &resid)).collect();
        let top = gains.iter().copied().fold(0.0, f64::max);
        tracing::debug!(
            ms = t0.elapsed().as_secs_f64() * 1e3,
            "explainer's candidates ranked"
        );
        let rank = |ci: usize| {
            let c = &covs[cands[ci].index];
            let area = u64::from(c.rect[2]) * u64::from(c.rect[3]);
            (c.observable == Observable::Intensity, area)
        };
        let best: Option<(usize, f64)> = (0..cands.len())
            .filter(|&ci| top > 0.0 && gains[ci] >= 0.98 * top)
            .max_by_key(|&ci| rank(ci))
            .map(|ci| (ci, gains[ci]));
        let Some((ci, took)) = best else { break };
        tracing::debug!(
            candidates = cands.len(),
            covariate = ?covs[cands[ci].index].observable,
            rect = ?covs[cands[ci].index].rect,
            held_out_share = took / held_energy(&resid).max(1e-300),
            "explainer's best candidate"
        );
        // Verified: the joint fit of every kept covariate and this one,
        // subtracted from the recovery as delivered, the model refitted.
        let mut trial: Vec<&Cand> = kept.iter().collect();
        trial.push(&cands[ci]);
        let taps = joint_taps(&trial, &resid0, (&lin, fs), &dot);
        let y2 = subtract(y, &trial, &taps);
        let z2 = apply_all(chain, &y2, fs);
        let e2 = m.errors(&z2, &m.fit_linear(&z2));
        let gain = e2.snr_db - cur.snr_db;
        tracing::debug!(gain_db = gain, "explainer's candidate verified");
        if gain.is_nan() || gain < min_gain_db {
            // A weak term: kept only when fitted again on the next
            // recording (a tile's observable that does not follow the
            // reference) and beyond chance.
            let c = &cands[ci];
            let weak = gain >= WEAK_MIN_DB
                && channels_of[c.index].is_none()
                && follows_reference(&apply_all(&lin, &c.xs[0], fs), &fit.t, &dot, &held_energy)
                    < FOLLOWS_SHARE
                && {
                    // Each shifted copy chooses its own lag as the
                    // candidate did, so that the choice's luck is in
                    // chance too.
                    let reach = covs[c.index]
                        .observable
                        .lag_reach(m.opts.line_reach.min(MAX_LINE_REACH));
                    let null = |x: &[f64]| {
                        let through = [apply_all(&lin, x, fs)];
                        let shifts =
                            tile_shifts_about(&through, reach, |cols| removed(cols, &resid));
                        let mut cols = shifted(&through[0], &shifts);
                        project_out(&mut cols, &basis, &dot);
                        removed(&cols, &resid)
                    };
                    let z = beyond_chance(took, &c.xs[0], null);
                    tracing::debug!(z, "explainer's weak candidate against chance");
                    z >= WEAK_Z
                };
            if !weak {
                break;
            }
        }
        tracing::info!(
            covariate = ?covs[cands[ci].index].observable,
            rect = ?covs[cands[ci].index].rect,
            gain_db = e2.snr_db - cur.snr_db,
            "explainer keeps"
        );
        cur = e2;
        steps.push(cur.snr_db);
        cleaned = y2;
        taps_all = taps;
        let c = cands.swap_remove(ci);
        // Its span joins the basis; the others and the residual lose it.
        let q = orthonormal(&c.cols, &dot);
        project_out(std::slice::from_mut(&mut resid), &q, &dot);
        for o in &mut cands {
            project_out(&mut o.cols, &q, &dot);
        }
        basis.extend(q);
        kept.push(c);
    }
    if kept.is_empty() {
        return None;
    }
    let refs: Vec<&Cand> = kept.iter().collect();
    let explanations = kept
        .iter()
        .enumerate()
        .map(|(k, c)| {
            // Its own part of the joint fit (for the labels below).
            let part = c.part(&taps_all[k], (&lin, fs), len);
            // Without it, the others kept (as fitted).
            let others: Vec<&Cand> = refs
                .iter()
                .copied()
                .filter(|o| o.index != c.index)
                .collect();
            let others_taps: Vec<Vec<f64>> = taps_all
                .iter()
                .enumerate()
                .filter(|(j, _)| *j != k)
                .map(|(_, t)| t.clone())
                .collect();
            let w = apply_all(chain, &subtract(y, &others, &others_taps), fs);
            let without = m.errors(&w, &m.fit_linear(&w)).snr_db;
            // What keeping it removed of the held-out error, after the
            // terms kept before it, as a share of the error before the
            // explainer (the SNR's reference power is the same at every
            // step, so an error's energy is 10^(-SNR/10) of it): in
            // [0, 1], and the shares add up to what the explainer removes.
            // Its own part's share of the joint fit was reported until
            // session 72: two terms that move together (the camera's
            // tiles, then all tiles) cancel in part, and one read "+1.61
            // dB, -15% of the residual". The energy of its gain without
            // it (the others kept as fitted) is no better: it can pass
            // 100% where a second term cancels a nuisance the first
            // brought in.
            let left = |snr: f64| 10f64.powf(-(snr - steps[0]) / 10.0);
            let share = (left(steps[k]) - left(steps[k + 1])).clamp(0.0, 1.0);
            let cov = &covs[c.index];
            let ((cause, label, (with_it, of), seen_at), follows) = match &channels_of[c.index] {
                // The lines' fitted sum: one line alone is mostly noise.
                Some(ch) => (
                    label_lines(cov, ch, (fs, hp), (&c.shifts, spans.len())),
                    follows_reference(&part, &fit.t, &dot, &held_energy),
                ),
                None => (
                    label(cov, (&covs[..singles], &observed), fs, hp),
                    follows_reference(&apply_all(&lin, &c.xs[0], fs), &fit.t, &dot, &held_energy),
                ),
            };
            // A tile's brightness inside the region that follows the
            // reference is the object's own motion, turned into
            // brightness by the texture under the tile (issue 50, session
            // 65: on `square_at_resonance` it was named the light).
            let (cause, label) = if cov.observable == Observable::Intensity
                && cov.inside
                && follows >= FOLLOWS_SHARE
            {
                let [x, y, w, h] = cov.rect;
                (
                    "object",
                    format!(
                        "the object's own motion, seen in the brightness of [{x}, {y}, {w}, {h}] inside the region (the texture there turns motion into brightness): the reference explains {:.0}% of it, so it is the object's response beyond what the corrections model (its nonlinearity, say), read through that tile's texture, which another recording of another texture or light does not share",
                        100.0 * follows
                    ),
                )
            } else {
                (cause, label)
            };
            // For tiles weighed by their noise: how much of the pooled
            // motion is that noise, which bounds what subtracting it can
            // gain (said when it is most of it).
            let noise_share = weighed_of[c.index]
                .then(|| {
                    let tiles: Vec<&[f64]> = members[c.index]
                        .iter()
                        .filter_map(|r| {
                            covs[..singles]
                                .iter()
                                .find(|t| t.rect == *r && t.observable == cov.observable)
                                .map(|t| t.values.as_slice())
                        })
                        .collect();
                    pooled_noise_share(&tiles, fs, hp)
                })
                .flatten();
            let label = match noise_share {
                Some(q) if q >= 0.5 => format!(
                    "{label}; its {} tiles' own noise is {:.0}% of their pooled motion's power, so subtracting it removes at most about {:.0}% of what this motion costs (more texture in view outside the region would measure it better)",
                    members[c.index].len(),
                    100.0 * q,
                    100.0 * (1.0 - q)
                ),
                _ => label,
            };
            Explanation {
                observable: cov.observable,
                rect: cov.rect,
                tiles: members[c.index].clone(),
                inside_region: cov.inside,
                label,
                cause,
                seen_at,
                tiles_with_it: with_it,
                tiles_of: of,
                residual_share: share,
                snr_gain_db: cur.snr_db - without,
                kept_gain_db: steps[k + 1] - steps[k],
                taps: taps_all[k].clone(),
                shifts: c.shifts.clone(),
                renewal: channels_of[c.index]
                    .as_ref()
                    .and(m.opts.renewal)
                    .map(|(a, b)| [a, b]),
                follows_reference: follows,
                refit: follows < FOLLOWS_SHARE,
                weighed: weighed_of[c.index],
                tiles_noise_share: noise_share,
            }
        })
        .collect();
    Some(Explained {
        kept: explanations,
        cleaned,
    })
}

/// The share of `x`'s held-out energy that `t` (the reference, as the
/// model aligns it to the recovery) explains through an FIR of lags
/// -[`REF_LAGS`]..=[`REF_LAGS`] fitted on the fit part (`dot`, the
/// fit part's inner product; `held`, the held-out energy): near zero, or
/// below, for an observable independent of the sound.
fn follows_reference(
    x: &[f64],
    t: &[f64],
    dot: &dyn Fn(&[f64], &[f64]) -> f64,
    held: &dyn Fn(&[f64]) -> f64,
) -> f64 {
    let e = held(x);
    if x.len() != t.len() || e <= 0.0 {
        return 0.0;
    }
    // Normal equations with a ridge: the lagged columns of a tone are
    // nearly dependent, and a basis made orthonormal from them on the fit
    // part alone blows up on the held-out part.
    let cols = lagged_by(t, REF_LAGS);
    let refs: Vec<&[f64]> = cols.iter().map(Vec::as_slice).collect();
    let Some(beta) = ridge_solve(&refs, x, dot, 1e-3) else {
        return 0.0;
    };
    let mut after = x.to_vec();
    for (col, w) in cols.iter().zip(beta.iter()) {
        for (r, v) in after.iter_mut().zip(col) {
            *r -= w * v;
        }
    }
    (1.0 - held(&after) / e).clamp(-1.0, 1.0)
}

/// Which of `covs` may explain: every intensity, the motion of every
/// tile outside the region, and the motion of a tile inside it that
/// moves on its own, that is when (a) the reference `t` explains under
/// [`FOLLOWS_SHARE`] of its motion on either axis ([`follows_reference`],
/// after `lin`): a tile on the object moves with the sound, and a
/// regression on it would only be a better estimator of the object; and
/// (b) its motion moves with another tile's, beyond chance (as
/// [`label`] counts a tile with a covariate), that tile not moving with
/// the sound either: a tile's own noise moves with no other, so a tile
/// on the object whose motion is mostly noise is not taken for a
/// mover. A background moving around the object inside the region is
/// what this lets the explainer see.
fn observed_motion(
    covs: &[Covariate],
    moving: &[Option<Vec<f64>>],
    (lin, fs): (&[Correction], f64),
    t: &[f64],
    dot: &dyn Fn(&[f64], &[f64]) -> f64,
    held: &dyn Fn(&[f64]) -> f64,
) -> Vec<bool> {
    let n = t.len();
    // Each finite tile's high-passed motion (`moving`).
    let prep: Vec<Option<&Vec<f64>>> = covs
        .iter()
        .zip(moving)
        .map(|(c, p)| {
            p.as_ref()
                .filter(|_| c.values.iter().all(|v| v.is_finite()))
        })
        .collect();
    // The rectangles inside the region whose motion follows the sound on
    // either axis.
    let mut follows: Vec<[u32; 4]> = Vec::new();
    for (c, p) in covs.iter().zip(&prep) {
        if let Some(p) = p.filter(|_| c.inside) {
            if follows_reference(&apply_all(lin, p, fs), t, dot, held) >= FOLLOWS_SHARE {
                follows.push(c.rect);
            }
        }
    }
    let threshold = (WITH_IT_Z / (n.max(1) as f64).sqrt()).max(WITH_IT_MIN);
    covs.iter()
        .enumerate()
        .map(|(i, c)| {
            if !c.observable.is_motion() || !c.inside {
                return true;
            }
            let Some(me) = prep[i] else {
                return false;
            };
            if follows.contains(&c.rect) {
                return false;
            }
            covs.iter().zip(&prep).any(|(o, p)| {
                o.observable == c.observable
                    && o.rect != c.rect
                    && !follows.contains(&o.rect)
                    && p.is_some_and(|p| corr(me, p).abs() >= threshold)
            })
        })
        .collect()
}

/// The plain mean of `tiles` (one value per frame each), as long as the
/// shortest.
pub fn mean_of(tiles: &[&[f64]]) -> Vec<f64> {
    let n = tiles.iter().map(|t| t.len()).min().unwrap_or(0);
    let k = tiles.len().max(1) as f64;
    let mut mean = vec![0.0; n];
    for t in tiles {
        for (m, v) in mean.iter_mut().zip(t.iter()) {
            *m += v / k;
        }
    }
    mean
}

/// The motion of a group of tiles (each one value per frame, in pixels):
/// their mean, each tile weighed by the inverse of its own noise, read as
/// the power of its (high-passed: `fs`, `hp`) motion about the tiles'
/// plain mean. A motion the tiles share (the camera's) stays in pixels;
/// a tile with less texture, whose motion is noisier, counts less, and a
/// tile something else also moves counts less too. `calibrate` pools
/// the tiles so and `listen --calibration` again on the new recording,
/// whose texture (and so whose weights) may differ. The plain mean where
/// any tile's power is not positive and finite (one tile, tiles alike).
pub fn pooled_motion(tiles: &[&[f64]], fs: f64, hp: Option<(usize, f64)>) -> Vec<f64> {
    pool_tiles(tiles, fs, hp).0
}

/// [`pooled_motion`] and the tiles' weights (`None` where the plain mean
/// is used).
fn pool_tiles(tiles: &[&[f64]], fs: f64, hp: Option<(usize, f64)>) -> (Vec<f64>, Option<Vec<f64>>) {
    let plain = mean_of(tiles);
    match pool_weights(tiles, &plain, fs, hp) {
        Some(weights) => (weighed_mean(tiles, &weights, plain.len()), Some(weights)),
        None => (plain, None),
    }
}

/// The mean of `tiles`' first `n` values, each tile counted by its weight.
fn weighed_mean(tiles: &[&[f64]], weights: &[f64], n: usize) -> Vec<f64> {
    let total: f64 = weights.iter().sum();
    let mut out = vec![0.0; n];
    for (t, w) in tiles.iter().zip(weights) {
        for (o, v) in out.iter_mut().zip(t.iter()) {
            *o += v * w / total;
        }
    }
    out
}

/// [`pooled_motion`]'s weights: each tile's inverse noise power (its
/// high-passed motion about the tiles' plain mean `plain`); `None` where
/// the plain mean is used.
fn pool_weights(
    tiles: &[&[f64]],
    plain: &[f64],
    fs: f64,
    hp: Option<(usize, f64)>,
) -> Option<Vec<f64>> {
    if tiles.len() < 2 {
        return None;
    }
    let n = plain.len().max(1) as f64;
    let weights: Vec<f64> = tiles
        .iter()
        .map(|t| {
            let dev: Vec<f64> = t.iter().zip(plain).map(|(a, m)| a - m).collect();
            let d = centred_highpass(&dev, fs, hp);
            1.0 / (d.iter().map(|v| v * v).sum::<f64>() / n)
        })
        .collect();
    weights
        .iter()
        .all(|w| w.is_finite() && *w > 0.0)
        .then_some(weights)
}

/// The share of [`pooled_motion`]'s high-passed power that is its tiles'
/// own noise: the weighed mean's noise power (each tile's noise read from
/// its power about the plain mean) over the pooled motion's power, at
/// most 1. A correction made from the pooled motion removes at most about
/// one minus this share of what the motion it stands for costs (the best
/// gain on a signal seen through white noise). `None` where the plain
/// mean is used.
pub fn pooled_noise_share(tiles: &[&[f64]], fs: f64, hp: Option<(usize, f64)>) -> Option<f64> {
    pooled_motion_and_share(tiles, fs, hp).1
}

/// [`pooled_motion`] and [`pooled_noise_share`] from one reading of the
/// tiles' weights (`listen --calibration` says the share of the motion it
/// subtracts).
pub fn pooled_motion_and_share(
    tiles: &[&[f64]],
    fs: f64,
    hp: Option<(usize, f64)>,
) -> (Vec<f64>, Option<f64>) {
    let (pooled, weights) = pool_tiles(tiles, fs, hp);
    let share = weights.and_then(|w| noise_share(&w, &pooled, fs, hp));
    (pooled, share)
}

/// [`pooled_noise_share`] of the motion `pooled` with the tiles' weights.
fn noise_share(weights: &[f64], pooled: &[f64], fs: f64, hp: Option<(usize, f64)>) -> Option<f64> {
    let p = centred_highpass(pooled, fs, hp);
    let power = p.iter().map(|v| v * v).sum::<f64>() / p.len().max(1) as f64;
    // A tile's power about the plain mean, d_i = 1 / w_i, holds its own
    // noise's σ_i² (1 - 2/N) and the mean's Σσ²/N²: so Σσ² = Σd · N/(N-1),
    // and each σ_i² = (d_i - Σσ²/N²) / (1 - 2/N) (for two tiles, which
    // cannot be told apart, half of Σσ² each). The weighed mean's noise is
    // then Σ w_i² σ_i² / (Σ w)².
    let k = weights.len() as f64;
    let d: Vec<f64> = weights.iter().map(|w| 1.0 / w).collect();
    let all = d.iter().sum::<f64>() * k / (k - 1.0);
    let own = |di: f64| {
        if weights.len() > 2 {
            ((di - all / (k * k)) / (1.0 - 2.0 / k)).max(0.0)
        } else {
            all / k
        }
    };
    let total: f64 = weights.iter().sum();
    let noise = weights
        .iter()
        .zip(&d)
        .map(|(w, &di)| w * w * own(di))
        .sum::<f64>()
        / (total * total);
    (power > 0.0 && noise.is_finite()).then(|| (noise / power).min(1.0))
}

/// Means of tiles' observables that share a cause, as candidates: for
/// motion (each axis), of the tiles `observed` ([`observed_motion`]): all
/// of them, those inside the region, those whose motion has at most
/// [`COMMON_POWER`] times the median tile's power (`moving`: each tile's
/// high-passed motion), each row of tiles and each column;
/// for intensity, every tile, each row and each column. A mean's
/// rectangle holds its tiles. The tiles that move least, which stand for
/// a motion of the whole image, are weighed each by its noise
/// ([`pooled_motion`]; `fs`, `hp`: the recovery's high-pass; the flag
/// returned), and come first, so that when they are all the tiles the
/// weighted mean is the one kept; the other means are plain, since a
/// mover's tiles, which the weights would silence, are what they pool.
fn pool(
    covs: &[Covariate],
    observed: &[bool],
    moving: &[Option<Vec<f64>>],
    (n, fs, hp): (usize, f64, Option<(usize, f64)>),
) -> Vec<(Covariate, Vec<[u32; 4]>, bool)> {
    let mut out = Vec::new();
    for obs in [
        Observable::MotionX,
        Observable::MotionY,
        Observable::Intensity,
    ] {
        let at: Vec<usize> = (0..covs.len())
            .filter(|&i| covs[i].observable == obs && covs[i].values.len() == n && observed[i])
            .collect();
        let tiles: Vec<&Covariate> = at.iter().map(|&i| &covs[i]).collect();
        // Each group with whether its mean is weighed.
        let mut groups: Vec<(Vec<&Covariate>, bool)> = Vec::new();
        if obs.is_motion() {
            // The tiles that move least: a motion of the whole image is in
            // every tile, and the tiles a mover also moves, whose motion
            // has more power, would only add it to their mean.
            let power: Vec<f64> = at
                .iter()
                .map(|&i| moving[i].iter().flatten().map(|v| v * v).sum())
                .collect();
            let mut sorted = power.clone();
            sorted.sort_by(f64::total_cmp);
            if let Some(&median) = sorted.get(sorted.len() / 2) {
                groups.push((
                    tiles
                        .iter()
                        .zip(&power)
                        .filter(|&(_, &p)| p <= COMMON_POWER * median)
                        .map(|(c, _)| *c)
                        .collect(),
                    true,
                ));
            }
            // The tiles inside the region that move on their own.
            groups.push((tiles.iter().copied().filter(|c| c.inside).collect(), false));
        }
        groups.insert(usize::from(obs.is_motion()), (tiles.clone(), false));
        // Each row of tiles (same rows), then each column (same columns).
        let rows = |c: &Covariate| (c.rect[1], c.rect[3]);
        let cols = |c: &Covariate| (c.rect[0], c.rect[2]);
        for key in [&rows as &dyn Fn(&Covariate) -> (u32, u32), &cols] {
            let mut keys: Vec<(u32, u32)> = tiles.iter().map(|c| key(c)).collect();
            keys.sort_unstable();
            keys.dedup();
            for k in keys {
                groups.push((
                    tiles.iter().copied().filter(|c| key(c) == k).collect(),
                    false,
                ));
            }
        }
        let mut seen: Vec<Vec<[u32; 4]>> = Vec::new();
        for (g, weighed) in groups {
            let rects: Vec<[u32; 4]> = g.iter().map(|c| c.rect).collect();
            if g.len() < 2 || seen.contains(&rects) {
                continue;
            }
            seen.push(rects);
            let tiles: Vec<&[f64]> = g.iter().map(|c| c.values.as_slice()).collect();
            let values = match weighed {
                true => pooled_motion(&tiles, fs, hp),
                false => mean_of(&tiles),
            };
            out.push((
                Covariate {
                    observable: obs,
                    rect: bounds(&g),
                    inside: g.iter().any(|c| c.inside),
                    values,
                },
                g.iter().map(|c| c.rect).collect(),
                weighed,
            ));
        }
    }
    out
}

/// The lines' joint candidates, rows then columns (each with two lines
/// or more): a covariate standing for them (their mean; the rectangle
/// holding their parts), the parts, and one channel per line
/// ([`line_channels`]).
#[allow(clippy::type_complexity)]
fn joint_lines(lines: &[&Covariate], n: usize) -> Vec<(Covariate, Vec<[u32; 4]>, Vec<Vec<f64>>)> {
    [Observable::RowIntensity, Observable::ColumnIntensity]
        .into_iter()
        .filter_map(|obs| {
            let parts: Vec<&Covariate> = lines
                .iter()
                .copied()
                .filter(|c| {
                    c.observable == obs
                        && c.values.len() == n
                        && c.values.iter().all(|v| v.is_finite())
                })
                .collect();
            let rects: Vec<[u32; 4]> = parts.iter().map(|c| c.rect).collect();
            let channels = line_channels(obs, &rects, n, |i| &parts[i].values);
            if channels.len() < 2 {
                return None;
            }
            let mut mean = vec![0.0; n];
            for ch in &channels {
                for (m, v) in mean.iter_mut().zip(ch) {
                    *m += v / channels.len() as f64;
                }
            }
            Some((
                Covariate {
                    observable: obs,
                    rect: bounds(&parts),
                    inside: false,
                    values: mean,
                },
                rects,
                channels,
            ))
        })
        .collect()
}

/// One explained term on a new recording: its observable measured there
/// (one channel, or one a line for lines: [`line_channels`]; one value
/// per frame) and the stored FIRs brought to that recording's scale, or
/// `None` where the calibration said to fit it again
/// ([`Explanation::refit`]).
pub struct Measured {
    /// What the channels measure: lines choose their lags as lines, a
    /// tile's observable as a tile's, within its [`Observable::lag_reach`].
    pub observable: Observable,
    pub channels: Vec<Vec<f64>>,
    /// This recording's recovery's `align` reach, frames.
    pub reach: usize,
    /// The lags of each channel's FIR; when fitted again ([`Measured::taps`]
    /// `None`), chosen again here by the energy each removes from this
    /// recording's recovery: on lines as many lags ([`pick_shifts`]), on a
    /// tile's observable -[`LAGS`]..=[`LAGS`] about the best one
    /// ([`tile_shifts_about`]).
    pub shifts: Vec<i64>,
    /// The spans of frames over which each channel has its own FIR (one
    /// per reference for lines, [`reference_spans`]; the whole recording
    /// otherwise), high-passed first.
    pub spans: Vec<std::ops::Range<usize>>,
    pub taps: Option<Vec<f64>>,
}

/// `y` (a recovery at `fs`, high-passed by `hp`) with each term's part
/// removed, each observable high-passed like the recovery first: the
/// stored FIRs (at their stored lags, in `y`'s units per the observable's)
/// are subtracted, then the terms to fit again are fitted jointly on what
/// is left, by least squares on their lagged values over the whole
/// recording, and subtracted. How `listen --calibration` applies what the
/// explainer kept to a new recording, its observables measured again.
/// Returns the corrected recovery and the share of `y`'s energy the
/// refitted terms removed. A term whose observable is not as long as `y`
/// is left out.
pub fn remove_explained(
    y: &[f64],
    terms: &[Measured],
    fs: f64,
    hp: Option<(usize, f64)>,
) -> (Vec<f64>, f64) {
    let simd = crate::join::Simd::detect();
    let dot = |a: &[f64], b: &[f64]| super::signal::plain_dot(simd, a, b);
    let mut out = y.to_vec();
    let mut cols = Vec::new();
    for t in terms {
        if t.channels.is_empty() || t.channels.iter().any(|c| c.len() != y.len()) {
            continue;
        }
        let passed: Vec<Vec<f64>> = t
            .channels
            .iter()
            .map(|c| centred_highpass(c, fs, hp))
            .collect();
        let xs = per_reference(&passed, &t.spans);
        let removes = |cols: &[Vec<f64>]| {
            orthonormal(cols, &dot)
                .iter()
                .map(|q| dot(q, y).powi(2))
                .sum()
        };
        let reach = t.observable.lag_reach(t.reach);
        let shifts = match (&t.taps, t.observable.is_line()) {
            (None, true) => pick_shifts(&xs, (t.shifts.len(), reach), removes),
            (None, false) => tile_shifts_about(&xs, reach, removes),
            _ => t.shifts.clone(),
        };
        let lags: Vec<Vec<f64>> = xs.iter().flat_map(|c| shifted(c, &shifts)).collect();
        match &t.taps {
            Some(taps) if taps.len() == lags.len() => {
                for (col, a) in lags.iter().zip(taps) {
                    for (o, v) in out.iter_mut().zip(col) {
                        *o -= a * v;
                    }
                }
            }
            Some(_) => {}
            None => cols.extend(lags),
        }
    }
    let before = dot(&out, &out);
    for q in orthonormal(&cols, &dot) {
        let g = dot(&q, &out);
        for (o, v) in out.iter_mut().zip(&q) {
            *o -= g * v;
        }
    }
    let e = dot(y, y);
    let share = if e > 0.0 {
        (before - dot(&out, &out)) / e
    } else {
        0.0
    };
    (out, share)
}

/// Orthonormal columns (fit-part inner product) spanning `cols`; columns
/// already in the span of the previous ones are dropped.
fn orthonormal(cols: &[Vec<f64>], dot: &dyn Fn(&[f64], &[f64]) -> f64) -> Vec<Vec<f64>> {
    let mut q: Vec<Vec<f64>> = Vec::new();
    let scale = cols.iter().map(|c| dot(c, c)).fold(0.0, f64::max);
    for c in cols {
        let mut v = c.clone();
        for b in &q {
            let g = dot(b, &v);
            for (a, x) in v.iter_mut().zip(b) {
                *a -= g * x;
            }
        }
        let nn = dot(&v, &v);
        if nn > 1e-10 * scale && nn > 0.0 {
            let s = 1.0 / nn.sqrt();
            v.iter_mut().for_each(|a| *a *= s);
            q.push(v);
        }
    }
    q
}

/// The joint least-squares FIR taps (fit part) of `cands` on `resid`, one
/// list per candidate, by normal equations on their lagged columns through
/// the linear corrections `lin` (rebuilt: the candidates' stored columns
/// have earlier ones projected out).
fn joint_taps(
    cands: &[&Cand],
    resid: &[f64],
    (lin, fs): (&[Correction], f64),
    dot: &dyn Fn(&[f64], &[f64]) -> f64,
) -> Vec<Vec<f64>> {
    let built: Vec<Vec<f64>> = cands
        .iter()
        .flat_map(|c| {
            c.xs.iter()
                .flat_map(|x| shifted(&apply_all(lin, x, fs), &c.shifts))
                .collect::<Vec<_>>()
        })
        .collect();
    let cols: Vec<&[f64]> = built.iter().map(Vec::as_slice).collect();
    // A small ridge keeps a nearly dependent set solvable.
    let sol = ridge_solve(&cols, resid, dot, 1e-9)
        .unwrap_or_else(|| nalgebra::DVector::zeros(cols.len()));
    let mut off = 0;
    cands
        .iter()
        .map(|c| {
            let k = c.xs.len() * c.shifts.len();
            let taps = (off..off + k).map(|j| sol[j]).collect();
            off += k;
            taps
        })
        .collect()
}

/// The least-squares weights of `cols` for `y` by normal equations in
/// `dot`, with `ridge` times the largest diagonal added to the diagonal;
/// `None` when every column is zero or the system is not solvable.
fn ridge_solve(
    cols: &[&[f64]],
    y: &[f64],
    dot: &dyn Fn(&[f64], &[f64]) -> f64,
    ridge: f64,
) -> Option<nalgebra::DVector<f64>> {
    let k = cols.len();
    let mut a = nalgebra::DMatrix::<f64>::zeros(k, k);
    let mut b = nalgebra::DVector::<f64>::zeros(k);
    for i in 0..k {
        b[i] = dot(cols[i], y);
        for j in 0..=i {
            let v = dot(cols[i], cols[j]);
            a[(i, j)] = v;
            a[(j, i)] = v;
        }
    }
    let ridge = (0..k).map(|i| a[(i, i)]).fold(0.0, f64::max) * ridge;
    if ridge <= 0.0 {
        return None;
    }
    for i in 0..k {
        a[(i, i)] += ridge;
    }
    a.cholesky().map(|c| c.solve(&b))
}

/// `y` minus each candidate's FIR on its (high-passed) covariate.
fn subtract(y: &[f64], cands: &[&Cand], taps: &[Vec<f64>]) -> Vec<f64> {
    let mut out = y.to_vec();
    for (c, t) in cands.iter().zip(taps) {
        for (x, tx) in c.xs.iter().zip(t.chunks(c.shifts.len())) {
            for (a, col) in tx.iter().zip(shifted(x, &c.shifts)) {
                for (o, v) in out.iter_mut().zip(col) {
                    *o -= a * v;
                }
            }
        }
    }
    out
}

/// Up to `most` lags of -`reach`..=`reach` for the signals `xs`: each
/// lag alone is scored by `removes` (what its columns, one per signal,
/// remove); the best is kept, then the next best while each removes at
/// least [`LINE_SHIFT_SHARE`] of what the best does. Empty when none
/// removes anything.
pub fn pick_shifts(
    xs: &[Vec<f64>],
    (most, reach): (usize, usize),
    removes: impl Fn(&[Vec<f64>]) -> f64,
) -> Vec<i64> {
    let reach = reach.min(MAX_LINE_REACH) as i64;
    let mut scored: Vec<(f64, i64)> = (-reach..=reach)
        .map(|s| {
            let cols: Vec<Vec<f64>> = xs.iter().flat_map(|x| shifted(x, &[s])).collect();
            (removes(&cols), s)
        })
        .filter(|(r, _)| r.is_finite() && *r > 0.0)
        .collect();
    scored.sort_by(|a, b| b.0.total_cmp(&a.0));
    let top = scored.first().map_or(0.0, |t| t.0);
    let mut out: Vec<i64> = scored
        .iter()
        .take(most)
        .filter(|(r, _)| *r >= LINE_SHIFT_SHARE * top)
        .map(|t| t.1)
        .collect();
    out.sort_unstable();
    out
}

/// What a kept joint candidate of lines (`cov`, standing for them;
/// `channels`, one a line) most likely is: the sensor's rows (columns)
/// when the lines change each on its own, the light when they change
/// together (read, like [`label`], from the correlations of their
/// high-passed signals: how many pairs of neighbouring lines correlate
/// beyond chance).
fn label_lines(
    cov: &Covariate,
    channels: &[Vec<f64>],
    (fs, hp): (f64, Option<(usize, f64)>),
    (shifts, references): (&[i64], usize),
) -> (&'static str, String, (usize, usize), [u32; 4]) {
    let prep: Vec<Vec<f64>> = channels
        .iter()
        .map(|v| centred_highpass(v, fs, hp))
        .collect();
    let n = prep.first().map_or(1, Vec::len).max(1);
    let threshold = (WITH_IT_Z / (n as f64).sqrt()).max(WITH_IT_MIN);
    let pairs = prep.len().saturating_sub(1);
    let together = prep
        .windows(2)
        .filter(|w| corr(&w[0], &w[1]).abs() >= threshold)
        .count();
    let (what, whose) = match cov.observable {
        Observable::RowIntensity => ("rows", "row"),
        _ => ("columns", "column"),
    };
    let [x, y, w, h] = cov.rect;
    if 2 * together > pairs {
        (
            "light",
            format!(
                "the light, changing along the sensor's {what}: {together} of the {pairs} pairs of neighbouring {what}' intensities (measured beside the region, within [{x}, {y}, {w}, {h}]) change together"
            ),
            (together, pairs),
            cov.rect,
        )
    } else {
        let cause = match cov.observable {
            Observable::RowIntensity => "sensor_rows",
            _ => "sensor_columns",
        };
        (
            cause,
            format!(
                "the sensor's {what}: each {whose}'s intensity, measured beside the region (within [{x}, {y}, {w}, {h}]), changes on its own ({together} of the {pairs} pairs of neighbouring {what} change together), and the recovery weighs each {whose}'s offset by its own texture; the {} {what} are fitted jointly, a weight for each {whose}, each of the recovery's {references} reference frame(s) and each lag of {shifts:?} frames (the recovery's bands are aligned at lags of their own)",
                channels.len()
            ),
            (channels.len() - together.min(channels.len()), channels.len()),
            cov.rect,
        )
    }
}

/// What a kept covariate most likely is: its cause, in words, and how
/// many tiles (of how many) move or brighten with it.
fn label(
    cov: &Covariate,
    (covs, observed): (&[Covariate], &[bool]),
    fs: f64,
    hp: Option<(usize, f64)>,
) -> (&'static str, String, (usize, usize), [u32; 4]) {
    let prep = |v: &[f64]| centred_highpass(v, fs, hp);
    let me = prep(&cov.values);
    let peers: Vec<&Covariate> = covs
        .iter()
        .zip(observed)
        .filter(|(c, &o)| c.observable == cov.observable && c.values.len() == cov.values.len() && o)
        .map(|(c, _)| c)
        .collect();
    let threshold = (WITH_IT_Z / (me.len().max(1) as f64).sqrt()).max(WITH_IT_MIN);
    let with: Vec<&Covariate> = peers
        .iter()
        .copied()
        .filter(|c| corr(&me, &prep(&c.values)).abs() >= threshold)
        .collect();
    // Motion: the camera is judged on the tiles outside the region; the
    // tiles inside it that move on their own only show where another
    // thing moves.
    let outside = |v: &[&Covariate]| match cov.observable.is_motion() {
        true => v.iter().filter(|c| !c.inside).count(),
        false => v.len(),
    };
    let (k, of) = (outside(&with), outside(&peers));
    let (k_in, of_in) = (with.len() - k, peers.len() - of);
    let [x, y, w, h] = cov.rect;
    // Intensities that change with a motion: the light, read as motion.
    let lights: Vec<&Covariate> = covs
        .iter()
        .filter(|c| c.observable == Observable::Intensity && c.values.len() == cov.values.len())
        .collect();
    let lit = match cov.observable {
        Observable::Intensity => 0,
        _ => lights
            .iter()
            .filter(|c| corr(&me, &prep(&c.values)).abs() >= threshold)
            .count(),
    };
    match cov.observable {
        Observable::MotionX | Observable::MotionY if 2 * lit > lights.len() => (
            "light",
            format!(
                "the light: the brightness changes and reads as motion where a tile's texture does not average out ({lit} of the {} tiles' intensities change with the motion at [{x}, {y}, {w}, {h}])",
                lights.len()
            ),
            (lit, lights.len()),
            cov.rect,
        ),
        Observable::MotionX | Observable::MotionY => {
            let axis = if cov.observable == Observable::MotionX {
                "x"
            } else {
                "y"
            };
            if 2 * k > of {
                (
                    "camera",
                    format!(
                        "the camera or its mount: the whole image moves along {axis} ({k} of the {of} tiles outside the region move with [{x}, {y}, {w}, {h}])"
                    ),
                    (k, of),
                    cov.rect,
                )
            } else {
                let b = bounds(&with);
                (
                    "other_object",
                    format!(
                        "another vibrating thing in view, moving along {axis} at [{}, {}, {}, {}] ({k} of the {of} tiles outside the region move with it{})",
                        b[0], b[1], b[2], b[3],
                        match of_in {
                            0 => String::new(),
                            _ => format!(", and {k_in} of the {of_in} inside it that do not move with the sound"),
                        }
                    ),
                    (k, of),
                    b,
                )
            }
        }
        // Lines are labelled by `label_lines`.
        Observable::Intensity | Observable::RowIntensity | Observable::ColumnIntensity => {
            let same_rows = with.iter().all(|c| c.rect[1] == y && c.rect[3] == h);
            let other_rows = peers.iter().any(|c| c.rect[1] != y);
            if same_rows && other_rows && k > 1 {
                (
                    "sensor_rows",
                    format!(
                        "the sensor's rows: the intensity of rows {y} to {} changes on its own ({k} tiles on those rows change with it, none elsewhere)",
                        y + h - 1
                    ),
                    (k, of),
                    bounds(&with),
                )
            } else {
                (
                    "light",
                    format!(
                        "the light: the brightness changes ({k} of the {of} tiles change with [{x}, {y}, {w}, {h}])"
                    ),
                    (k, of),
                    bounds(&with),
                )
            }
        }
    }
}

/// The rectangle `[x, y, w, h]` that holds every tile of `tiles`.
fn bounds(tiles: &[&Covariate]) -> [u32; 4] {
    let x0 = tiles.iter().map(|c| c.rect[0]).min().unwrap_or(0);
    let y0 = tiles.iter().map(|c| c.rect[1]).min().unwrap_or(0);
    let x1 = tiles
        .iter()
        .map(|c| c.rect[0] + c.rect[2])
        .max()
        .unwrap_or(0);
    let y1 = tiles
        .iter()
        .map(|c| c.rect[1] + c.rect[3])
        .max()
        .unwrap_or(0);
    [x0, y0, x1 - x0, y1 - y0]
}

#[cfg(test)]
#[allow(clippy::unwrap_used)]
mod tests {
    use super::super::signal::redo_highpass;
    use super::super::{calibrate_with, sample_at, Options};
    use super::*;
    use crate::rng::{Xoshiro256, Ziggurat};
    use std::f64::consts::PI;

    /// A test case: the recovery, the reference, the covariates, options.
    type Case = (Vec<f64>, Vec<f64>, Vec<Covariate>, Options);

    /// Three seeds of a case with no effect (`make(0.0, seed)`): nothing
    /// is kept.
    fn nothing_kept_without_it(make: fn(f64, u64) -> Case) {
        for seed in [1, 2, 3] {
            let (y, r, covs, opts) = make(0.0, seed);
            let c = calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {})
                .unwrap();
            assert!(
                c.report.explained.is_empty(),
                "seed {seed}: {:#?}",
                c.report.explained
            );
        }
    }

    /// A 2.2 s chirp from 100 Hz to 1 kHz sampled at `fr`.
    fn chirp(fr: f64) -> Vec<f64> {
        (0..(fr * 2.2) as usize)
            .map(|i| {
                let t = i as f64 / fr;
                (2.0 * PI * (100.0 * t + 900.0 * t * t / 4.4)).sin()
            })
            .collect()
    }

    /// A recovery of a chirp with `leak` times a broadband motion `c` in
    /// it, and covariates: `c` seen on one tile outside the region (with
    /// its own noise), an unrelated motion on another, an intensity.
    fn case(leak: f64, seed: u64) -> Case {
        case_late(leak, seed, 0)
    }

    /// A recovery of a 2.2 s chirp `t` (2200 fps; the reference `r` at
    /// 8800 Hz) with noise `w` and `leak` times a broadband motion `c`
    /// reaching it `late` frames late; `rng` goes on for the covariates.
    struct Leaking {
        y: Vec<f64>,
        r: Vec<f64>,
        opts: Options,
        c: Vec<f64>,
        t: Vec<f64>,
        w: Vec<f64>,
        rng: Xoshiro256,
    }

    /// `n` samples of Gaussian noise of deviation `s`.
    fn gauss(rng: &mut Xoshiro256, n: usize, s: f64) -> Vec<f64> {
        let z = Ziggurat::new();
        (0..n).map(|_| z.sample(rng) * s).collect()
    }

    fn leaking(leak: f64, seed: u64, late: usize) -> Leaking {
        let (fs, fr) = (2200.0, 8800.0);
        let opts = Options {
            line_reach: if late > 0 { 8 } else { 0 },
            ..Options::for_rate(fs)
        };
        let r = chirp(fr);
        let n = 4400;
        let mut rng = Xoshiro256::new(seed);
        let c = gauss(&mut rng, n, 1.0);
        let t = sample_at(&r, fr, (0..n).map(|i| i as f64 / fs));
        let w = gauss(&mut rng, n, 0.3);
        let y: Vec<f64> = (0..n)
            .map(|i| t[i] + leak * i.checked_sub(late).map_or(0.0, |k| c[k]) + w[i])
            .collect();
        let y = redo_highpass(&y, fs, opts.highpass);
        Leaking {
            y,
            r,
            opts,
            c,
            t,
            w,
            rng,
        }
    }

    /// [`case`] with the motion reaching the recovery `late` frames late
    /// (through bands `align` shifted), the recovery's reach 8 frames.
    fn case_late(leak: f64, seed: u64, late: usize) -> Case {
        let Leaking {
            y,
            r,
            opts,
            c,
            mut rng,
            ..
        } = leaking(leak, seed, late);
        let n = y.len();
        let mut noise = |s: f64| gauss(&mut rng, n, s);
        let seen: Vec<f64> = c.iter().zip(noise(0.2)).map(|(a, b)| a + b).collect();
        let covs = vec![
            Covariate {
                observable: Observable::MotionX,
                rect: [0, 0, 10, 10],
                inside: false,
                values: seen,
            },
            Covariate {
                observable: Observable::MotionX,
                rect: [50, 0, 10, 10],
                inside: false,
                values: noise(1.0),
            },
            Covariate {
                observable: Observable::Intensity,
                rect: [20, 20, 10, 10],
                inside: true,
                values: noise(3.0),
            },
        ];
        (y, r, covs, opts)
    }

    /// A recovery of a chirp with `leak` times a broadband motion `c` in
    /// it, seen only on tiles inside the region (the background around
    /// the object moving): two tiles that see `c` (each with its own
    /// noise), a tile on the object whose motion is a fifth of the sound
    /// plus the recovery's own noise (subtracting it would remove that
    /// noise: a better estimator of the object, not an effect), and a
    /// tile of noise alone.
    fn case_inside(leak: f64, seed: u64) -> Case {
        let Leaking {
            y,
            r,
            opts,
            c,
            t,
            w,
            mut rng,
        } = leaking(leak, seed, 0);
        let n = y.len();
        let tile = |rect, values| Covariate {
            observable: Observable::MotionX,
            rect,
            inside: true,
            values,
        };
        let sees = |k: usize| -> Vec<f64> {
            let mut rng = Xoshiro256::new(seed * 100 + k as u64);
            c.iter()
                .zip(gauss(&mut rng, n, 0.3))
                .map(|(a, b)| a + b)
                .collect()
        };
        let on_object: Vec<f64> = t.iter().zip(&w).map(|(a, b)| 0.2 * a + b).collect();
        let covs = vec![
            tile([0, 0, 10, 10], sees(1)),
            tile([10, 0, 10, 10], sees(2)),
            tile([10, 10, 10, 10], on_object),
            tile([0, 10, 10, 10], gauss(&mut rng, n, 1.0)),
        ];
        (y, r, covs, opts)
    }

    /// A motion seen only on tiles inside the region is found there, on
    /// the tiles that move together and not with the sound; the tile on
    /// the object is never taken, and without a leak nothing is kept
    /// (where subtracting that tile would remove the recovery's noise).
    #[test]
    fn a_motion_inside_the_region_is_found_on_the_tiles_that_move_on_their_own() {
        let (y, r, covs, opts) = case_inside(0.5, 3);
        let c =
            calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {}).unwrap();
        let e = &c.report.explained;
        assert!(!e.is_empty(), "nothing kept");
        for k in e {
            assert!(
                k.tiles
                    .iter()
                    .all(|t| [[0, 0, 10, 10], [10, 0, 10, 10]].contains(t)),
                "{e:#?}"
            );
        }
        let gain = c.report.after.snr_db - c.report.before.snr_db;
        assert!(gain > 3.0, "gain {gain} dB");
        nothing_kept_without_it(case_inside);
    }

    /// A recovery of a chirp with `leak` times a motion of the whole image
    /// `c` in it, seen on a 4x3 grid of tiles outside the region (each
    /// with its own noise), three of which (one in each row and column
    /// of tiles) another thing also moves, ten times more.
    fn case_common(leak: f64, seed: u64) -> Case {
        let Leaking {
            y,
            r,
            opts,
            c,
            mut rng,
            ..
        } = leaking(leak, seed, 0);
        let n = y.len();
        let mover = gauss(&mut rng, n, 10.0);
        let covs = (0..12u32)
            .map(|k| {
                let (i, j) = (k % 4, k / 4);
                let moved = i == j;
                let own = gauss(&mut rng, n, 1.0);
                Covariate {
                    observable: Observable::MotionX,
                    rect: [10 * i, 10 * j, 10, 10],
                    inside: false,
                    values: (0..n)
                        .map(|t| c[t] + own[t] + if moved { mover[t] } else { 0.0 })
                        .collect(),
                }
            })
            .collect();
        (y, r, covs, opts)
    }

    /// A motion of the whole image is found on the mean of the tiles that
    /// move least, without the three another thing also moves (no row or
    /// column of tiles is clear of them); without a leak nothing is kept.
    #[test]
    fn a_motion_of_the_whole_image_is_found_on_the_tiles_that_move_least() {
        let (y, r, covs, opts) = case_common(0.5, 3);
        let c =
            calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {}).unwrap();
        let e = &c.report.explained;
        assert_eq!(e.len(), 1, "{e:#?}");
        let moved = [[0, 0, 10, 10], [10, 10, 10, 10], [20, 20, 10, 10]];
        assert!(
            e[0].tiles.len() >= 6 && e[0].tiles.iter().all(|t| !moved.contains(t)),
            "{e:#?}"
        );
        let gain = c.report.after.snr_db - c.report.before.snr_db;
        assert!(gain > 3.0, "gain {gain} dB");
        nothing_kept_without_it(case_common);
    }

    /// The leaking motion is found on the tile that sees it, and removing
    /// it gains; without a leak nothing is kept.
    #[test]
    fn a_motion_seen_elsewhere_is_found_and_nothing_without_it() {
        let (y, r, covs, opts) = case(0.5, 3);
        let c =
            calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {}).unwrap();
        let e = &c.report.explained;
        assert_eq!(e.len(), 1, "{e:#?}");
        assert_eq!(e[0].rect, [0, 0, 10, 10], "{e:#?}");
        assert_eq!(e[0].observable, Observable::MotionX);
        let gain = c.report.after.snr_db - c.report.before.snr_db;
        assert!(gain > 3.0, "gain {gain} dB");
        // The middle tap carries the leak (in recovery units, ~0.5 through
        // the high-pass).
        assert!((e[0].taps[LAGS] - 0.5).abs() < 0.1, "{:?}", e[0].taps);
        nothing_kept_without_it(case);
    }

    /// The share of the pooled motion that is its tiles' noise, against
    /// the truth (the pooled motion less the shared one): a faint shared
    /// motion under the noise, a strong one over it, tiles alike and not.
    #[test]
    fn pooled_noise_share_is_the_noise_in_the_pooled_motion() {
        let (fs, n) = (2200.0, 4400);
        let hp = Options::for_rate(fs).highpass;
        let power = |v: &[f64]| {
            let d = centred_highpass(v, fs, hp);
            d.iter().map(|x| x * x).sum::<f64>() / n as f64
        };
        for (seed, motion, noise) in [
            (1, 0.05, &[0.3, 0.3, 0.3, 0.3, 0.3][..]),
            (2, 0.1, &[0.2, 0.4, 0.3, 0.6, 0.25, 0.3, 0.5, 0.2][..]),
            (3, 1.0, &[0.3, 0.3, 0.3, 0.3][..]),
            (4, 0.02, &[0.05, 0.1, 0.2][..]),
        ] {
            let mut rng = Xoshiro256::new(seed);
            let shared = gauss(&mut rng, n, motion);
            let tiles: Vec<Vec<f64>> = noise
                .iter()
                .map(|&s| {
                    let own = gauss(&mut rng, n, s);
                    (0..n).map(|i| shared[i] + own[i]).collect()
                })
                .collect();
            let refs: Vec<&[f64]> = tiles.iter().map(Vec::as_slice).collect();
            let pooled = pooled_motion(&refs, fs, hp);
            let err: Vec<f64> = pooled.iter().zip(&shared).map(|(a, b)| a - b).collect();
            let truth = power(&err) / power(&pooled);
            let got = pooled_noise_share(&refs, fs, hp).unwrap();
            eprintln!("seed {seed}: noise share {got:.3}, truth {truth:.3}");
            assert!(
                (got - truth).abs() < 0.1 * truth.max(0.05),
                "seed {seed}: {got} against {truth}"
            );
        }
        let one = vec![1.0; n];
        assert_eq!(pooled_noise_share(&[&one], fs, hp), None);
    }

    /// Two terms whose parts of the joint fit cancel in part (one tile
    /// sees the leak and a nuisance, the other the nuisance alone): each
    /// term's share is what its step removed, not its own part's share
    /// (negative for both here: each part alone brings the nuisance
    /// back).
    #[test]
    fn overlapping_terms_report_the_share_of_their_gain() {
        let Leaking {
            y,
            r,
            opts,
            c,
            mut rng,
            ..
        } = leaking(0.5, 3, 0);
        let n = y.len();
        let d = gauss(&mut rng, n, 2.0);
        let tile = |rect, values| Covariate {
            observable: Observable::MotionX,
            rect,
            inside: false,
            values,
        };
        let covs = vec![
            tile(
                [0, 0, 10, 10],
                c.iter().zip(&d).map(|(a, b)| a + b).collect(),
            ),
            tile([50, 0, 10, 10], d.clone()),
        ];
        let cal =
            calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {}).unwrap();
        let e = &cal.report.explained;
        assert_eq!(e.len(), 2, "{e:#?}");
        let total = cal.report.after.snr_db - cal.report.before.snr_db;
        assert!(total > 3.0, "gain {total} dB");
        // In the order kept: each share is the energy its step removed,
        // in [0, 1], and they add up to the error removed in all.
        let (mut at, mut shares) = (0.0, 0.0);
        let left = |db: f64| 10f64.powf(-db / 10.0);
        for t in e {
            assert!(t.kept_gain_db > 0.0 && t.residual_share > 0.0, "{t:#?}");
            let want = left(at) - left(at + t.kept_gain_db);
            assert!((t.residual_share - want).abs() < 1e-9, "{t:#?}: {want}");
            at += t.kept_gain_db;
            shares += t.residual_share;
        }
        assert!((at - total).abs() < 1e-9, "steps {at} against {total} dB");
        assert!((shares - (1.0 - left(total))).abs() < 1e-9 && shares < 1.0);
        // The gain without a term (the others as fitted) is another
        // figure: here it passes the total, since each part alone brings
        // the nuisance back.
        assert!(e.iter().all(|t| t.snr_gain_db > total), "{e:#?}");
    }

    /// A weak leak (a faint shake: its term gains under `min_gain_db` on
    /// the held-out part) is kept, since `listen --calibration` fits it
    /// again on the next recording, and it lies far beyond what the same
    /// tile shifted in time removes; without a leak nothing is kept over
    /// three seeds, nor with the leak on a tile that does not see it.
    #[test]
    fn a_weak_motion_beyond_chance_is_kept_and_nothing_without_it() {
        for seed in [3, 4, 5] {
            let (y, r, covs, opts) = case(0.08, seed);
            let c = calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {})
                .unwrap();
            let e = &c.report.explained;
            assert_eq!(e.len(), 1, "seed {seed}: {e:#?}");
            assert_eq!(e[0].rect, [0, 0, 10, 10], "{e:#?}");
            assert!(e[0].refit, "{e:#?}");
            let gain = c.report.after.snr_db - c.report.before.snr_db;
            assert!(
                (WEAK_MIN_DB..opts.min_gain_db).contains(&gain),
                "seed {seed}: gain {gain} dB"
            );
            // The tile that sees it left out: nothing else is taken.
            let blind: Vec<Covariate> = covs[1..].to_vec();
            let c = calibrate_with(&y, (None, &blind), 2200.0, (&r, 8800.0), &opts, &mut |_| {})
                .unwrap();
            assert!(c.report.explained.is_empty(), "{:#?}", c.report.explained);
        }
        nothing_kept_without_it(case);
    }

    /// A motion every tile shares, each tile with noise of its own (one
    /// ten times noisier, one moved by something else too): the weighed
    /// mean stays in pixels and lies nearer the shared motion than the
    /// plain mean; one tile, or tiles alike, give the plain mean.
    #[test]
    fn pooled_motion_weighs_each_tile_by_its_noise() {
        let (fs, n) = (2200.0, 4400);
        let hp = Options::for_rate(fs).highpass;
        let mut rng = Xoshiro256::new(7);
        let shared = gauss(&mut rng, n, 1.0);
        let mover = gauss(&mut rng, n, 3.0);
        let tiles: Vec<Vec<f64>> = [0.3, 0.3, 0.3, 3.0, 0.3]
            .iter()
            .enumerate()
            .map(|(k, &s)| {
                let own = gauss(&mut rng, n, s);
                (0..n)
                    .map(|i| shared[i] + own[i] + if k == 4 { mover[i] } else { 0.0 })
                    .collect()
            })
            .collect();
        let refs: Vec<&[f64]> = tiles.iter().map(Vec::as_slice).collect();
        let err = |v: &[f64]| {
            let d = centred_highpass(
                &v.iter()
                    .zip(&shared)
                    .map(|(a, b)| a - b)
                    .collect::<Vec<_>>(),
                fs,
                hp,
            );
            d.iter().map(|x| x * x).sum::<f64>() / n as f64
        };
        let weighed = pooled_motion(&refs, fs, hp);
        let mut plain = vec![0.0; n];
        for t in &tiles {
            for (p, v) in plain.iter_mut().zip(t) {
                *p += v / tiles.len() as f64;
            }
        }
        let (ew, ep) = (err(&weighed), err(&plain));
        assert!(ew < 0.1 * ep, "weighed {ew}, plain {ep}");
        // In pixels: the shared motion's gain is one.
        let g = weighed.iter().zip(&shared).map(|(a, b)| a * b).sum::<f64>()
            / shared.iter().map(|b| b * b).sum::<f64>();
        assert!((g - 1.0).abs() < 0.02, "gain {g}");
        assert_eq!(pooled_motion(&refs[..1], fs, hp), tiles[0]);
        let same = [refs[0], refs[0]];
        assert_eq!(pooled_motion(&same, fs, hp), tiles[0]);
        // A stored term says whether its tiles are weighed; a report
        // written before says nothing, and is read as the plain mean.
        let term = |extra: &str| {
            let v: serde_json::Value = serde_json::from_str(&format!(
                r#"{{"explained": [{{"observable": "motion_x", "tiles": [[0, 0, 10, 10], [10, 0, 10, 10]], "taps": [0, 0, 1, 0, 0]{extra}}}]}}"#
            ))
            .unwrap();
            super::super::explained_from_report(&v).unwrap()[0].weighed
        };
        assert!(term(r#", "weighed": true"#));
        assert!(!term(""));
    }

    /// Chance as the recording makes it: a removal as large as the
    /// shifted copies' is not beyond chance, one far above them is.
    #[test]
    fn chance_is_what_the_shifted_observable_removes() {
        let x: Vec<f64> = (0..400).map(|i| (i as f64 * 0.37).sin()).collect();
        // The shifted copies remove 1 + a little, varying with the shift.
        let null = |r: &[f64]| 1.0 + 0.01 * r[0];
        let z_same = beyond_chance(1.0, &x, null);
        assert!(z_same.abs() < 3.0, "{z_same}");
        assert!(beyond_chance(2.0, &x, null) > 50.0);
        // Too short to shift: never beyond chance.
        assert_eq!(beyond_chance(5.0, &x[..20], null), 0.0);
    }

    /// A motion that reaches the recovery 5 frames late (a band `align`
    /// shifted) is fitted about that lag, and the term fitted again on a
    /// new recording finds its lag there; without a leak nothing is kept.
    #[test]
    fn a_motion_the_recovery_shifted_is_found_at_its_lag() {
        let late = |leak, seed| case_late(leak, seed, 5);
        let (y, r, covs, opts) = late(0.5, 3);
        let c =
            calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {}).unwrap();
        let e = &c.report.explained;
        assert_eq!(e.len(), 1, "{e:#?}");
        assert_eq!(e[0].shifts, vec![3, 4, 5, 6, 7], "{e:#?}");
        assert!((e[0].taps[LAGS] - 0.5).abs() < 0.1, "{:?}", e[0].taps);
        let gain = c.report.after.snr_db - c.report.before.snr_db;
        assert!(gain > 3.0, "gain {gain} dB");
        // On a new recording the same motion arrives 7 frames late: fitted
        // again about the lag found there it removes the leak (about 0.3
        // of the recovery's energy), at lags -2..2 nothing.
        let (y2, _, covs2, _) = case_late(0.5, 4, 7);
        let t = Measured {
            observable: covs2[0].observable,
            channels: vec![covs2[0].values.clone()],
            reach: 8,
            shifts: e[0].shifts.clone(),
            spans: reference_spans(y2.len(), None),
            taps: None,
        };
        let (_, share) = remove_explained(&y2, &[t], 2200.0, opts.highpass);
        let (_, share_lag0) = remove_explained(
            &y2,
            &[Measured {
                observable: covs2[0].observable,
                channels: vec![covs2[0].values.clone()],
                reach: 0,
                shifts: tile_shifts(),
                spans: reference_spans(y2.len(), None),
                taps: None,
            }],
            2200.0,
            opts.highpass,
        );
        assert!(share > 0.2 && share_lag0 < 0.02, "{share} {share_lag0}");
        nothing_kept_without_it(|leak, seed| case_late(leak, seed, 5));
    }

    /// A recovery of the chirp with each of 24 rows' offsets in it,
    /// weighed per row and per reference (the weights change at the
    /// renewal, as a reference frame's own noise sets them), and the rows
    /// observed beside the region, left and right, each part with its own
    /// noise; a second set of weights reaches the recovery two frames late
    /// (a band `align` shifted). `gain`: the offsets' size in the recovery
    /// (0: none).
    fn rows_case(gain: f64, seed: u64) -> Case {
        let (fs, fr) = (2200.0, 8800.0);
        let opts = Options {
            renewal: Some((2200, 32)),
            line_reach: 4,
            ..Options::for_rate(fs)
        };
        let r = chirp(fr);
        let n = 4400;
        let mut rng = Xoshiro256::new(seed);
        let z = Ziggurat::new();
        let mut draw =
            |s: f64, k: usize| -> Vec<f64> { (0..k).map(|_| z.sample(&mut rng) * s).collect() };
        let rows = 24;
        let offsets: Vec<Vec<f64>> = (0..rows).map(|_| draw(3.0, n)).collect();
        let weights = [draw(1.0, rows), draw(1.0, rows)];
        let late = [draw(0.7, rows), draw(0.7, rows)];
        let t = sample_at(&r, fr, (0..n).map(|i| i as f64 / fs));
        let w = draw(0.3, n);
        let spans = reference_spans(n, opts.renewal);
        let y: Vec<f64> = (0..n)
            .map(|i| {
                let k = spans.iter().position(|s| s.contains(&i)).unwrap();
                let e: f64 = (0..rows)
                    .map(|j| {
                        let two_ago = if i >= 2 { offsets[j][i - 2] } else { 0.0 };
                        weights[k][j] * offsets[j][i] + late[k][j] * two_ago
                    })
                    .sum();
                t[i] + gain * e + w[i]
            })
            .collect();
        let y = redo_highpass(&y, fs, opts.highpass);
        let mut covs = Vec::new();
        for (j, o) in offsets.iter().enumerate() {
            for (x, width) in [(0, 20), (80, 30)] {
                let noise = draw(0.3, n);
                covs.push(Covariate {
                    observable: Observable::RowIntensity,
                    rect: [x, 30 + j as u32, width, 1],
                    inside: false,
                    values: o.iter().zip(noise).map(|(a, b)| 100.0 + a + b).collect(),
                });
            }
        }
        (y, r, covs, opts)
    }

    /// The rows' offsets are found together, as the sensor's rows, with one
    /// tap a row and reference; without them nothing is kept.
    #[test]
    fn rows_that_change_each_on_its_own_are_found_together_and_nothing_without_them() {
        let spans = reference_spans(4400, Some((2200, 32)));
        assert_eq!(spans, vec![0..2232, 2232..4400]);
        assert_eq!(reference_spans(2500, Some((2200, 32))), vec![0..2500]);
        assert_eq!(reference_spans(100, None), vec![0..100]);
        let (y, r, covs, opts) = rows_case(0.05, 5);
        let c =
            calibrate_with(&y, (None, &covs), 2200.0, (&r, 8800.0), &opts, &mut |_| {}).unwrap();
        let e = &c.report.explained;
        assert_eq!(e.len(), 1, "{e:#?}");
        assert_eq!(e[0].observable, Observable::RowIntensity);
        assert_eq!(e[0].cause, "sensor_rows", "{}", e[0].label);
        assert_eq!(e[0].tiles.len(), 48);
        assert_eq!(e[0].shifts, vec![0, 2]);
        assert_eq!(e[0].taps.len(), 96, "24 rows x 2 references x 2 lags");
        assert!(e[0].refit, "{e:#?}");
        let gain = c.report.after.snr_db - c.report.before.snr_db;
        assert!(gain > 6.0, "gain {gain} dB");
        nothing_kept_without_it(rows_case);
    }
}
