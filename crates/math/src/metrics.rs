//! Objective speech-quality metrics for judging recovered audio against a reference.
//!
//! Implements the four measures reported by the visual-microphone literature:
//!
//! * classic SNR ([`snr_db`]),
//! * segmental SNR after Hansen & Pellom (1998) ([`segmental_snr_db`]), following the
//!   composite-measure MATLAB code by Loizou (`comp_snr`),
//! * the LPC log-likelihood ratio ([`llr`]), following Loizou's `comp_llr`,
//! * the short-time objective intelligibility measure, STOI (Taal et al. 2011) ([`stoi`]),
//!   following the published `stoi.m`, including a MATLAB-`resample`-style polyphase
//!   resampler to the 10 kHz internal rate.
//!
//! The recovery methods of a visual microphone leave scale, sign and a small delay
//! undetermined, so [`best_lag_gain`] estimates those and [`score`] aligns before scoring.
//!
//! # Error convention
//!
//! No function here panics on any input. Where a metric is undefined (empty input,
//! reference and test of different lengths, any non-finite sample, an input shorter than
//! one analysis frame, a non-positive or non-finite sample rate, an all-silent reference
//! for STOI, ...) the function returns `f64::NAN` (and [`best_lag_gain`] returns a gain of
//! `NaN`). Each function documents its own cases.

use crate::numeric::{bessel_i0, gcd};
use realfft::num_complex::Complex;
use realfft::RealFftPlanner;

/// Machine epsilon as used by the MATLAB reference code (`eps`, 2^-52).
const EPS: f64 = f64::EPSILON;

/// All four scores of one reference/test pair (see [`score`]).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Scores {
    /// Classic SNR in dB ([`snr_db`]).
    pub snr_db: f64,
    /// Segmental SNR in dB ([`segmental_snr_db`]).
    pub ssnr_db: f64,
    /// Log-likelihood ratio, lower is better ([`llr`]).
    pub llr: f64,
    /// STOI in [-1, 1] (in practice [0, 1]), higher is better ([`stoi`]).
    pub stoi: f64,
}

impl Scores {
    /// All four scores `NaN`.
    const NAN: Scores = Scores {
        snr_db: f64::NAN,
        ssnr_db: f64::NAN,
        llr: f64::NAN,
        stoi: f64::NAN,
    };
}

// ---------------------------------------------------------------------------------------
// Shared helpers
// ---------------------------------------------------------------------------------------

/// True when both slices are non-empty, of equal length and entirely finite.
fn valid_pair(reference: &[f64], test: &[f64]) -> bool {
    !reference.is_empty()
        && reference.len() == test.len()
        && reference.iter().chain(test.iter()).all(|v| v.is_finite())
}

/// MATLAB's `hanning(n)`: the symmetric Hann window without the zero end points,
/// `0.5 * (1 - cos(2 pi k / (n + 1)))` for `k = 1..=n`.
fn hanning(n: usize) -> Vec<f64> {
    let denom = n as f64 + 1.0;
    (1..=n)
        .map(|k| 0.5 * (1.0 - (2.0 * std::f64::consts::PI * k as f64 / denom).cos()))
        .collect()
}

/// Frame geometry of Loizou's composite-measure code for a given sample rate:
/// `(winlength, skiprate)` with `winlength = round(30 ms * fs)` and
/// `skiprate = floor(winlength / 4)`. `None` when the rate is unusable or the input is
/// shorter than one window (which also bounds the window allocation by the input size).
fn loizou_frames(len: usize, fs: f64) -> Option<(usize, usize)> {
    if !fs.is_finite() || fs <= 0.0 {
        return None;
    }
    let wl = (30e-3 * fs).round();
    if !(4.0..=len as f64).contains(&wl) {
        return None;
    }
    let wl = wl as usize;
    Some((wl, wl / 4))
}

/// Number of frames in Loizou's code: `floor(len / skip - winlength / skip)`; frame `i`
/// starts at sample `i * skip`.
fn loizou_frame_count(len: usize, wl: usize, skip: usize) -> usize {
    if skip == 0 || len < wl {
        0
    } else {
        (len - wl) / skip
    }
}

fn mean(values: &[f64]) -> f64 {
    if values.is_empty() {
        f64::NAN
    } else {
        values.iter().sum::<f64>() / values.len() as f64
    }
}

// ---------------------------------------------------------------------------------------
// SNR and segmental SNR
// ---------------------------------------------------------------------------------------

/// Classic SNR of `test` against `reference`: `10 log10(Σ r² / Σ (r - t)²)` in dB.
///
/// Identical non-silent inputs give `+inf`. Returns `NaN` for empty input, different
/// lengths, non-finite samples, or when both the reference and the error are silent.
pub fn snr_db(reference: &[f64], test: &[f64]) -> f64 {
    if !valid_pair(reference, test) {
        return f64::NAN;
    }
    let signal: f64 = reference.iter().map(|r| r * r).sum();
    let noise: f64 = reference
        .iter()
        .zip(test)
        .map(|(r, t)| (r - t) * (r - t))
        .sum();
    10.0 * (signal / noise).log10()
}

/// Segmental SNR in dB after Hansen & Pellom (1998), as in Loizou's composite-measure
/// MATLAB code (`comp_snr`).
///
/// Frames of `round(30 ms * fs)` samples, hop `floor(winlength / 4)` (75 % overlap),
/// `floor(len / hop - winlength / hop)` frames, each weighted by MATLAB's `hanning`
/// window. Per frame `10 log10(E_s / (E_n + eps) + eps)`, clamped to [-10, 35] dB; the
/// result is the mean over frames. Identical signals therefore score 35.
///
/// Returns `NaN` for empty input, different lengths, non-finite samples or sample rate,
/// or input too short for one frame.
pub fn segmental_snr_db(reference: &[f64], test: &[f64], fs: f64) -> f64 {
    const MIN_SNR: f64 = -10.0;
    const MAX_SNR: f64 = 35.0;
    if !valid_pair(reference, test) {
        return f64::NAN;
    }
    let Some((wl, skip)) = loizou_frames(reference.len(), fs) else {
        return f64::NAN;
    };
    let window = hanning(wl);
    let n_frames = loizou_frame_count(reference.len(), wl, skip);
    let per_frame: Vec<f64> = (0..n_frames)
        .map(|i| {
            let start = i * skip;
            let r = &reference[start..start + wl];
            let t = &test[start..start + wl];
            let (mut signal, mut noise) = (0.0, 0.0);
            for ((r, t), w) in r.iter().zip(t).zip(&window) {
                let (rw, tw) = (r * w, t * w);
                signal += rw * rw;
                noise += (rw - tw) * (rw - tw);
            }
            let snr = 10.0 * (signal / (noise + EPS) + EPS).log10();
            snr.clamp(MIN_SNR, MAX_SNR)
        })
        .collect();
    mean(&per_frame)
}

// ---------------------------------------------------------------------------------------
// LLR
// ---------------------------------------------------------------------------------------

/// Autocorrelation `R[0..=order]` of a frame and the LPC polynomial `[1, -a1, ..., -ap]`
/// from the Levinson-Durbin recursion, written as in Loizou's `lpcoeff`. A silent frame
/// yields `NaN` coefficients (0/0), exactly as the MATLAB code does.
fn lpc(frame: &[f64], order: usize) -> (Vec<f64>, Vec<f64>) {
    let n = frame.len();
    let r: Vec<f64> = (0..=order)
        .map(|k| {
            if k >= n {
                0.0
            } else {
                frame[..n - k]
                    .iter()
                    .zip(&frame[k..])
                    .map(|(a, b)| a * b)
                    .sum()
            }
        })
        .collect();
    // a[j] holds the MATLAB a(j+1); predictor coefficients of the current order.
    let mut a = vec![0.0; order];
    let mut past = vec![0.0; order];
    let mut err = r[0];
    for i in 0..order {
        past[..i].copy_from_slice(&a[..i]);
        // sum_term = Σ_{j<i} a_past[j] * R[i - j]
        let sum_term: f64 = (0..i).map(|j| past[j] * r[i - j]).sum();
        let k = (r[i + 1] - sum_term) / err;
        a[i] = k;
        for j in 0..i {
            a[j] = past[j] - k * past[i - 1 - j];
        }
        err *= 1.0 - k * k;
    }
    let mut poly = Vec::with_capacity(order + 1);
    poly.push(1.0);
    poly.extend(a.iter().map(|v| -v));
    (r, poly)
}

/// `p' T(R) p` with `T(R)` the symmetric Toeplitz matrix built from `r`.
fn toeplitz_quadratic(p: &[f64], r: &[f64]) -> f64 {
    let mut acc = 0.0;
    for (i, pi) in p.iter().enumerate() {
        for (j, pj) in p.iter().enumerate() {
            acc += pi * pj * r[i.abs_diff(j)];
        }
    }
    acc
}

/// Log-likelihood ratio after Loizou's `comp_llr`.
///
/// LPC order 10 for `fs < 10 kHz`, else 16; frames of `round(30 ms * fs)` samples with 75 %
/// overlap and MATLAB's `hanning` window (same framing as [`segmental_snr_db`]). Per frame
/// `ln(a_t' R_r a_t / a_r' R_r a_r)` capped at 2, where a frame whose ratio is undefined
/// (a silent frame in either signal) counts as 2 like MATLAB's `min(2, NaN)`; the result is
/// the mean of the lowest `round(0.95 * frames)` values. Lower is better; 0 for identical
/// signals.
///
/// Returns `NaN` for empty input, different lengths, non-finite samples or sample rate,
/// or input too short for one frame.
pub fn llr(reference: &[f64], test: &[f64], fs: f64) -> f64 {
    const ALPHA: f64 = 0.95;
    if !valid_pair(reference, test) {
        return f64::NAN;
    }
    let Some((wl, skip)) = loizou_frames(reference.len(), fs) else {
        return f64::NAN;
    };
    let order = if fs < 10_000.0 { 10 } else { 16 };
    let window = hanning(wl);
    let n_frames = loizou_frame_count(reference.len(), wl, skip);
    let mut ref_frame = vec![0.0; wl];
    let mut test_frame = vec![0.0; wl];
    let mut per_frame: Vec<f64> = Vec::with_capacity(n_frames);
    for i in 0..n_frames {
        let start = i * skip;
        for (k, w) in window.iter().enumerate() {
            ref_frame[k] = reference[start + k] * w;
            test_frame[k] = test[start + k] * w;
        }
        let (r_ref, a_ref) = lpc(&ref_frame, order);
        let (_, a_test) = lpc(&test_frame, order);
        let numerator = toeplitz_quadratic(&a_test, &r_ref);
        let denominator = toeplitz_quadratic(&a_ref, &r_ref);
        // f64::min ignores NaN, like MATLAB's min: undefined frames count as 2.
        per_frame.push(f64::min(2.0, (numerator / denominator).ln()));
    }
    per_frame.sort_by(f64::total_cmp);
    let keep = (per_frame.len() as f64 * ALPHA).round() as usize;
    mean(&per_frame[..keep.min(per_frame.len())])
}

// ---------------------------------------------------------------------------------------
// Resampling (MATLAB `resample` equivalent)
// ---------------------------------------------------------------------------------------

/// Largest `max(p, q)` accepted for a rational resampling ratio; bounds the filter to
/// about 2 million taps.
const MAX_PQ: u64 = 100_000;
/// Largest resampled length accepted (about 60 hours at 10 kHz).
const MAX_RESAMPLED_LEN: u64 = 1 << 31;

/// Rational `p / q ≈ to / from` in lowest terms with `max(p, q) <= MAX_PQ`: exact for
/// integer rates, otherwise the last continued-fraction convergent within the bound
/// (stopping early at relative error 1e-12, like MATLAB's `rat(x, 1e-12)`).
fn rational_ratio(to: f64, from: f64) -> Option<(u64, u64)> {
    if !(to.is_finite() && from.is_finite() && to > 0.0 && from > 0.0) {
        return None;
    }
    let is_int = |v: f64| v.fract() == 0.0 && v <= 9.0e15;
    if is_int(to) && is_int(from) {
        let (t, f) = (to as u64, from as u64);
        let g = gcd(t, f);
        let (p, q) = (t / g, f / g);
        return (p.max(q) <= MAX_PQ).then_some((p, q));
    }
    let target = to / from;
    let mut x = target;
    // Convergents h/k via the standard recurrence.
    let (mut h_prev, mut h) = (1u64, 0u64);
    let (mut k_prev, mut k) = (0u64, 1u64);
    let mut best: Option<(u64, u64)> = None;
    for _ in 0..64 {
        if !x.is_finite() || x > MAX_PQ as f64 {
            break;
        }
        let a = x.floor();
        let ai = a as u64;
        let h_next = ai.checked_mul(h_prev).and_then(|v| v.checked_add(h));
        let k_next = ai.checked_mul(k_prev).and_then(|v| v.checked_add(k));
        let (Some(h_next), Some(k_next)) = (h_next, k_next) else {
            break;
        };
        if h_next.max(k_next) > MAX_PQ {
            break;
        }
        (h, h_prev) = (h_prev, h_next);
        (k, k_prev) = (k_prev, k_next);
        if h_prev > 0 {
            best = Some((h_prev, k_prev));
            if ((h_prev as f64 / k_prev as f64) - target).abs() <= 1e-12 * target {
                break;
            }
        }
        let frac = x - a;
        if frac <= 0.0 {
            break;
        }
        x = 1.0 / frac;
    }
    best.map(|(p, q)| {
        let g = gcd(p, q);
        (p / g, q / g)
    })
}

fn sinc(x: f64) -> f64 {
    if x == 0.0 {
        1.0
    } else {
        let px = std::f64::consts::PI * x;
        px.sin() / px
    }
}

/// Resamples `x` by `p / q` the way MATLAB's `resample(x, p, q)` does with its defaults
/// (N = 10, beta = 5): an ideal low-pass at `1 / (2 max(p, q))` of the upsampled rate
/// (which is what `firls` yields for that band specification), Kaiser-windowed to
/// `2 * 10 * max(p, q) + 1` taps and normalised to a DC gain of `p`, applied as a polyphase
/// `upfirdn` with MATLAB's delay compensation; output length `ceil(len * p / q)`.
pub fn resample(x: &[f64], p: u64, q: u64) -> Option<Vec<f64>> {
    const N: u64 = 10;
    const BETA: f64 = 5.0;
    if p == 0 || q == 0 {
        return None;
    }
    if p == q {
        return Some(x.to_vec());
    }
    let lx = x.len() as u64;
    let ly = lx.checked_mul(p)?.div_ceil(q);
    if ly > MAX_RESAMPLED_LEN {
        return None;
    }
    let pqmax = p.max(q);
    let fc = 1.0 / (2.0 * pqmax as f64);
    let l = 2 * N * pqmax + 1;
    let lhalf = N * pqmax;
    let i0_beta = bessel_i0(BETA);
    let mut h: Vec<f64> = (0..l)
        .map(|n| {
            let m = n as f64 - lhalf as f64;
            let ratio = m / lhalf as f64;
            let kaiser = bessel_i0(BETA * (1.0 - ratio * ratio).max(0.0).sqrt()) / i0_beta;
            2.0 * fc * sinc(2.0 * fc * m) * kaiser
        })
        .collect();
    let sum: f64 = h.iter().sum();
    let scale = p as f64 / sum;
    h.iter_mut().for_each(|v| *v *= scale);
    // MATLAB prepends nz zeros so that downsampling by q hits the centre tap, then drops
    // `delay` leading output samples.
    let nz = q - lhalf % q;
    let delay = (lhalf + nz) / q;
    let (p, q, nz, l) = (p as i64, q as i64, nz as i64, l as i64);
    let mut y = Vec::with_capacity(ly as usize);
    for i in 0..ly as i64 {
        // Position in the upsampled, filtered stream, relative to the unpadded filter.
        let t = (i + delay as i64) * q - nz;
        // Input samples k contribute with tap t - k p, valid for 0 <= t - k p < l.
        let k_hi = t.div_euclid(p).min(lx as i64 - 1);
        let k_lo = ((t - l).div_euclid(p) + 1).max(0);
        let mut acc = 0.0;
        let mut k = k_lo;
        while k <= k_hi {
            acc += h[(t - k * p) as usize] * x[k as usize];
            k += 1;
        }
        y.push(acc);
    }
    Some(y)
}

// ---------------------------------------------------------------------------------------
// STOI
// ---------------------------------------------------------------------------------------

const STOI_FS: f64 = 10_000.0;
const STOI_FRAME: usize = 256;
const STOI_HOP: usize = STOI_FRAME / 2;
const STOI_NFFT: usize = 512;
const STOI_BANDS: usize = 15;
const STOI_MIN_FREQ: f64 = 150.0;
const STOI_SEGMENT: usize = 30;
const STOI_BETA_DB: f64 = -15.0;
const STOI_DYN_RANGE_DB: f64 = 40.0;

/// One-third-octave band matrix of `thirdoct.m`, as half-open FFT-bin ranges
/// `[lo, hi)` (each row of the MATLAB matrix is a contiguous run of ones).
fn third_octave_bands(
    fs: f64,
    nfft: usize,
    num_bands: usize,
    min_freq: f64,
) -> Vec<(usize, usize)> {
    let freqs: Vec<f64> = (0..=nfft / 2)
        .map(|k| k as f64 * fs / nfft as f64)
        .collect();
    let nearest = |target: f64| -> usize {
        let mut best = 0;
        let mut best_d = f64::INFINITY;
        for (i, f) in freqs.iter().enumerate() {
            let d = (f - target) * (f - target);
            if d < best_d {
                best_d = d;
                best = i;
            }
        }
        best
    };
    let bands: Vec<(usize, usize)> = (0..num_bands)
        .map(|k| {
            let k = k as f64;
            let centre = 2f64.powf(k / 3.0) * min_freq;
            let lower = (centre * 2f64.powf((k - 1.0) / 3.0) * min_freq).sqrt();
            let upper = (centre * 2f64.powf((k + 1.0) / 3.0) * min_freq).sqrt();
            (nearest(lower), nearest(upper))
        })
        .collect();
    // thirdoct.m drops trailing bands that are empty or narrower than their predecessor.
    let rank: Vec<usize> = bands
        .iter()
        .map(|&(lo, hi)| hi.saturating_sub(lo))
        .collect();
    let keep = (0..rank.len().saturating_sub(1))
        .rev()
        .find(|&i| rank[i + 1] >= rank[i] && rank[i + 1] != 0)
        .map_or(bands.len(), |i| i + 2);
    bands.into_iter().take(keep).collect()
}

/// Start indices of STOI's frames: `1:hop:(len - frame)` in MATLAB terms.
fn stoi_frame_starts(len: usize) -> impl Iterator<Item = usize> {
    let end = len.saturating_sub(STOI_FRAME);
    (0..end).step_by(STOI_HOP)
}

/// `removeSilentFrames.m`: drops frames whose clean energy is more than `range` dB below
/// the loudest clean frame, and overlap-adds the remaining windowed frames of both
/// signals. `None` when the clean signal is entirely silent or too short.
fn remove_silent_frames(x: &[f64], y: &[f64], window: &[f64]) -> Option<(Vec<f64>, Vec<f64>)> {
    let starts: Vec<usize> = stoi_frame_starts(x.len()).collect();
    let energies_db: Vec<f64> = starts
        .iter()
        .map(|&s| {
            let e: f64 = x[s..s + STOI_FRAME]
                .iter()
                .zip(window)
                .map(|(v, w)| (v * w) * (v * w))
                .sum();
            10.0 * (e / STOI_FRAME as f64).log10()
        })
        .collect();
    let max_db = energies_db
        .iter()
        .copied()
        .fold(f64::NEG_INFINITY, f64::max);
    if !max_db.is_finite() {
        return None;
    }
    let kept: Vec<usize> = starts
        .iter()
        .zip(&energies_db)
        .filter(|(_, &e)| e - max_db + STOI_DYN_RANGE_DB > 0.0)
        .map(|(&s, _)| s)
        .collect();
    if kept.is_empty() {
        return None;
    }
    let out_len = (kept.len() - 1) * STOI_HOP + STOI_FRAME;
    let mut x_sil = vec![0.0; out_len];
    let mut y_sil = vec![0.0; out_len];
    for (j, &s) in kept.iter().enumerate() {
        let o = j * STOI_HOP;
        for k in 0..STOI_FRAME {
            x_sil[o + k] += x[s + k] * window[k];
            y_sil[o + k] += y[s + k] * window[k];
        }
    }
    Some((x_sil, y_sil))
}

/// One-third-octave band magnitudes `sqrt(Σ |X(k)|²)` per frame (`stdft.m` followed by
/// the band matrix), returned band-major: `out[band][frame]`.
fn band_envelopes(
    x: &[f64],
    window: &[f64],
    bands: &[(usize, usize)],
    planner: &mut RealFftPlanner<f64>,
) -> Option<Vec<Vec<f64>>> {
    let fft = planner.plan_fft_forward(STOI_NFFT);
    let mut input = fft.make_input_vec();
    let mut spectrum = fft.make_output_vec();
    let mut out: Vec<Vec<f64>> = vec![Vec::new(); bands.len()];
    for s in stoi_frame_starts(x.len()) {
        input.iter_mut().for_each(|v| *v = 0.0);
        for (k, w) in window.iter().enumerate() {
            input[k] = x[s + k] * w;
        }
        fft.process(&mut input, &mut spectrum).ok()?;
        for (band, &(lo, hi)) in out.iter_mut().zip(bands) {
            let energy: f64 = spectrum
                .get(lo..hi.max(lo))
                .unwrap_or(&[])
                .iter()
                .map(Complex::norm_sqr)
                .sum();
            band.push(energy.sqrt());
        }
    }
    Some(out)
}

/// Sample correlation coefficient (`taa_corr.m`), with `eps` guards on the norms so that
/// a constant vector gives 0 rather than `NaN`.
fn correlation(x: &[f64], y: &[f64]) -> f64 {
    let n = x.len() as f64;
    let mx = x.iter().sum::<f64>() / n;
    let my = y.iter().sum::<f64>() / n;
    let (mut sxy, mut sxx, mut syy) = (0.0, 0.0, 0.0);
    for (a, b) in x.iter().zip(y) {
        let (da, db) = (a - mx, b - my);
        sxy += da * db;
        sxx += da * da;
        syy += db * db;
    }
    sxy / ((sxx.sqrt() + EPS) * (syy.sqrt() + EPS))
}

/// Short-time objective intelligibility (Taal, Hendriks, Heusdens & Jensen 2011), as in the
/// published `stoi.m`.
///
/// Both signals are resampled to 10 kHz (MATLAB-`resample`-equivalent polyphase filter;
/// non-integer rates are approximated by a rational ratio with `max(p, q) <= 100 000`),
/// frames of 256 samples (MATLAB `hanning`, 50 % overlap) more than 40 dB below the
/// loudest clean frame are removed, a 512-point DFT feeds 15 one-third-octave bands from
/// 150 Hz, and over 30-frame (384 ms) segments the band envelopes of the test signal are
/// normalised, clipped at beta = -15 dB and correlated with the clean ones; the result is
/// the mean correlation. Unlike the MATLAB code, the envelope normalisation and the
/// correlation carry `eps` guards (as in the Python port `pystoi`), so a band that is
/// exactly silent contributes 0 instead of turning the result into `NaN`.
///
/// Returns `NaN` for empty input, different lengths, non-finite samples or sample rate,
/// an all-silent reference, or fewer than 30 frames after silent-frame removal (about
/// 0.4 s of active speech).
pub fn stoi(reference: &[f64], test: &[f64], fs: f64) -> f64 {
    if !valid_pair(reference, test) {
        return f64::NAN;
    }
    let Some((p, q)) = rational_ratio(STOI_FS, fs) else {
        return f64::NAN;
    };
    let (Some(x), Some(y)) = (resample(reference, p, q), resample(test, p, q)) else {
        return f64::NAN;
    };
    let window = hanning(STOI_FRAME);
    let Some((x, y)) = remove_silent_frames(&x, &y, &window) else {
        return f64::NAN;
    };
    let bands = third_octave_bands(STOI_FS, STOI_NFFT, STOI_BANDS, STOI_MIN_FREQ);
    let mut planner = RealFftPlanner::<f64>::new();
    let (Some(xb), Some(yb)) = (
        band_envelopes(&x, &window, &bands, &mut planner),
        band_envelopes(&y, &window, &bands, &mut planner),
    ) else {
        return f64::NAN;
    };
    let n_frames = xb.first().map_or(0, Vec::len);
    if n_frames < STOI_SEGMENT {
        return f64::NAN;
    }
    let clip = 10f64.powf(-STOI_BETA_DB / 20.0);
    let mut total = 0.0;
    let mut count = 0usize;
    let mut y_prime = vec![0.0; STOI_SEGMENT];
    for (xband, yband) in xb.iter().zip(&yb) {
        for end in STOI_SEGMENT..=n_frames {
            let xs = &xband[end - STOI_SEGMENT..end];
            let ys = &yband[end - STOI_SEGMENT..end];
            let x_norm = xs.iter().map(|v| v * v).sum::<f64>().sqrt();
            let y_norm = ys.iter().map(|v| v * v).sum::<f64>().sqrt();
            let alpha = x_norm / (y_norm + EPS);
            for ((yp, xv), yv) in y_prime.iter_mut().zip(xs).zip(ys) {
                *yp = (alpha * yv).min(xv * (1.0 + clip));
            }
            total += correlation(xs, &y_prime);
            count += 1;
        }
    }
    if count == 0 {
        f64::NAN
    } else {
        total / count as f64
    }
}

// ---------------------------------------------------------------------------------------
// Alignment
// ---------------------------------------------------------------------------------------

/// Cross-correlation `c[l] = Σ_n r[n] t[n + l]` for every lag, computed by FFT. Returned
/// circularly: lag `l >= 0` at index `l`, lag `l < 0` at index `len + l`.
fn cross_correlation(reference: &[f64], test: &[f64]) -> Option<Vec<f64>> {
    let n = reference
        .len()
        .checked_add(test.len())?
        .checked_sub(1)?
        .checked_next_power_of_two()?;
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(n);
    let inverse = planner.plan_fft_inverse(n);
    let mut buf = forward.make_input_vec();
    buf[..reference.len()].copy_from_slice(reference);
    let mut spec_r = forward.make_output_vec();
    forward.process(&mut buf, &mut spec_r).ok()?;
    buf.iter_mut().for_each(|v| *v = 0.0);
    buf[..test.len()].copy_from_slice(test);
    let mut spec_t = forward.make_output_vec();
    forward.process(&mut buf, &mut spec_t).ok()?;
    for (t, r) in spec_t.iter_mut().zip(&spec_r) {
        *t *= r.conj();
    }
    // The DC and Nyquist bins of a real signal's spectrum are real; make that exact.
    if let Some(first) = spec_t.first_mut() {
        first.im = 0.0;
    }
    if n % 2 == 0 {
        if let Some(last) = spec_t.last_mut() {
            last.im = 0.0;
        }
    }
    let mut out = inverse.make_output_vec();
    inverse.process(&mut spec_t, &mut out).ok()?;
    Some(out)
}

/// The overlapping parts of `reference` and `test` when `test` is delayed by `lag`
/// samples (`test[n + lag]` pairs with `reference[n]`).
fn overlap<'a>(reference: &'a [f64], test: &'a [f64], lag: isize) -> (&'a [f64], &'a [f64]) {
    let shift = lag.unsigned_abs();
    let (r, t) = if lag >= 0 {
        (reference, test.get(shift..).unwrap_or(&[]))
    } else {
        (reference.get(shift..).unwrap_or(&[]), test)
    };
    let len = r.len().min(t.len());
    (&r[..len], &t[..len])
}

/// Best integer lag and least-squares gain of `test` relative to `reference`.
///
/// The lag `l` (within `±max_lag`, and within the signals' extent) maximises the magnitude
/// of the FFT cross-correlation `Σ_n r[n] t[n + l]`, so a positive lag means `test` is
/// delayed; ties go to the smallest `|l|`. The gain is the least-squares `g` in
/// `t[n + l] ≈ g r[n]` over the overlap, `Σ r t / Σ r²`, sign included (a visual
/// microphone's scale and polarity are arbitrary). Returns `(lag, gain)`.
///
/// Returns `(0, NaN)` when either input is empty or contains non-finite samples; the gain
/// is `NaN` when the reference is silent over the overlap.
pub fn best_lag_gain(reference: &[f64], test: &[f64], max_lag: usize) -> (isize, f64) {
    let finite = reference.iter().chain(test).all(|v| v.is_finite());
    if reference.is_empty() || test.is_empty() || !finite {
        return (0, f64::NAN);
    }
    let Some(xcorr) = cross_correlation(reference, test) else {
        return (0, f64::NAN);
    };
    let n = xcorr.len();
    // Slice lengths never exceed isize::MAX, so these conversions are lossless.
    let max_pos = max_lag.min(test.len() - 1);
    let max_neg = max_lag.min(reference.len() - 1);
    let mut best_lag: isize = 0;
    let mut best_val = xcorr.first().map_or(0.0, |v| v.abs());
    for d in 1..=max_pos.max(max_neg) {
        if d <= max_pos {
            let v = xcorr.get(d).map_or(0.0, |v| v.abs());
            if v > best_val {
                best_val = v;
                best_lag = d as isize;
            }
        }
        if d <= max_neg {
            let v = xcorr.get(n - d).map_or(0.0, |v| v.abs());
            if v > best_val {
                best_val = v;
                best_lag = -(d as isize);
            }
        }
    }
    let (r, t) = overlap(reference, test, best_lag);
    let cross: f64 = r.iter().zip(t).map(|(a, b)| a * b).sum();
    let energy: f64 = r.iter().map(|a| a * a).sum();
    let gain = if energy > 0.0 {
        cross / energy
    } else {
        f64::NAN
    };
    (best_lag, gain)
}

/// The SNR a stationary Wiener filter built from the true spectra reaches on `test`:
/// the limit of any linear time-invariant denoiser (issue 14), to set a denoiser's
/// [`score`] against.
///
/// [`best_lag_gain`] splits the aligned `test` into its signal `g r` and its noise
/// `t - g r`; their power spectra are Welch averages (segments of the power
/// of two nearest 0.1 s at `fs`, at least 16 samples, half overlapping, [`hanning`]
/// windows); the filter is
/// `H = S / (S + N)` per bin, interpolated linearly in frequency and applied with zero
/// phase to the whole aligned test (zero-padded, so nothing wraps around); the result is
/// scored as [`score`] scores SNR (its own lag and gain, then [`snr_db`]). A denoiser that
/// adapts to speech's changing spectrum can exceed this figure; one that scores below it
/// does worse than the best fixed filter.
///
/// `NaN` when [`score`]'s SNR is undefined (empty or non-finite input, a silent
/// reference or test) or when the overlap is shorter than two segments. A test that is
/// the reference scaled has no noise to filter and scores the FFT's rounding (about
/// 300 dB).
pub fn stationary_wiener_snr_db(reference: &[f64], test: &[f64], fs: f64, max_lag: usize) -> f64 {
    let (lag, gain) = best_lag_gain(reference, test, max_lag);
    if !(gain.is_finite() && gain != 0.0 && fs.is_finite() && fs > 0.0) {
        return f64::NAN;
    }
    let (r, t) = overlap(reference, test, lag);
    let seg = (0.1 * fs).log2().round().exp2().max(16.0) as usize;
    if r.len() < 2 * seg {
        return f64::NAN;
    }
    let noise: Vec<f64> = r.iter().zip(t).map(|(r, t)| t - gain * r).collect();
    let signal_psd = welch(r, seg);
    let noise_psd = welch(&noise, seg);
    drop(noise);
    let (Some(s), Some(n)) = (signal_psd, noise_psd) else {
        return f64::NAN;
    };
    // The filter per Welch bin; the signal's spectrum is g² times the reference's.
    let h: Vec<f64> = s
        .iter()
        .zip(&n)
        .map(|(s, n)| {
            let s = gain * gain * s;
            if s + n > 0.0 {
                s / (s + n)
            } else {
                0.0
            }
        })
        .collect();
    let Some(len) = t
        .len()
        .checked_add(seg)
        .and_then(usize::checked_next_power_of_two)
    else {
        return f64::NAN;
    };
    let mut planner = RealFftPlanner::<f64>::new();
    let forward = planner.plan_fft_forward(len);
    let inverse = planner.plan_fft_inverse(len);
    let mut buf = forward.make_input_vec();
    buf[..t.len()].copy_from_slice(t);
    let mut spec = forward.make_output_vec();
    if forward.process(&mut buf, &mut spec).is_err() {
        return f64::NAN;
    }
    let step = seg as f64 / len as f64;
    for (k, c) in spec.iter_mut().enumerate() {
        let x = k as f64 * step;
        let i = (x.floor() as usize).min(h.len() - 1);
        let f = x - i as f64;
        let w = match h.get(i + 1) {
            Some(next) => h[i] * (1.0 - f) + next * f,
            None => h[i],
        };
        *c *= w / len as f64;
    }
    spec[0].im = 0.0;
    if let Some(last) = spec.last_mut() {
        last.im = 0.0;
    }
    if inverse.process(&mut spec, &mut buf).is_err() {
        return f64::NAN;
    }
    // Free what is done with before the alignment's own transforms (memory
    // peaks there: `score` bounds its input by it).
    drop(spec);
    buf.truncate(t.len());
    buf.shrink_to_fit();
    let (lag, gain) = best_lag_gain(r, &buf, max_lag);
    if !(gain.is_finite() && gain != 0.0) {
        return f64::NAN;
    }
    let (r, z) = overlap(r, &buf, lag);
    let signal: f64 = r.iter().map(|r| r * r).sum();
    let error: f64 = r.iter().zip(z).map(|(r, z)| (r - z / gain).powi(2)).sum();
    10.0 * (signal / error).log10()
}

/// Welch's power spectrum of `x`: [`hanning`] segments of `seg` samples, half
/// overlapping, `seg / 2 + 1` bins (unnormalised: only ratios are used).
fn welch(x: &[f64], seg: usize) -> Option<Vec<f64>> {
    let window = hanning(seg);
    let mut planner = RealFftPlanner::<f64>::new();
    let fft = planner.plan_fft_forward(seg);
    let mut buf = fft.make_input_vec();
    let mut spec = fft.make_output_vec();
    let mut psd = vec![0.0; spec.len()];
    let mut start = 0;
    while start + seg <= x.len() {
        for ((b, v), w) in buf.iter_mut().zip(&x[start..start + seg]).zip(&window) {
            *b = v * w;
        }
        fft.process(&mut buf, &mut spec).ok()?;
        for (p, c) in psd.iter_mut().zip(&spec) {
            *p += c.norm_sqr();
        }
        start += seg / 2;
    }
    Some(psd)
}

/// Aligns `test` to `reference` and computes all four scores.
///
/// [`best_lag_gain`] (lag searched within `±max_lag`) gives the delay and gain; both
/// signals are trimmed to their overlap at that lag and the test is divided by the gain
/// (left unscaled if the gain is zero or not finite), which undoes a visual microphone's
/// arbitrary scale and polarity. Any score that is undefined for the aligned pair is `NaN`
/// (see the individual functions); all four are `NaN` for empty or non-finite input.
pub fn score(reference: &[f64], test: &[f64], fs: f64, max_lag: usize) -> Scores {
    let (lag, gain) = best_lag_gain(reference, test, max_lag);
    if gain.is_nan() && (reference.is_empty() || test.is_empty()) {
        return Scores::NAN;
    }
    let (r, t) = overlap(reference, test, lag);
    let aligned: Vec<f64> = if gain.is_finite() && gain != 0.0 {
        t.iter().map(|v| v / gain).collect()
    } else {
        t.to_vec()
    };
    Scores {
        snr_db: snr_db(r, &aligned),
        ssnr_db: segmental_snr_db(r, &aligned, fs),
        llr: llr(r, &aligned, fs),
        stoi: stoi(r, &aligned, fs),
    }
}

#[cfg(test)]
#[allow(clippy::unwrap_used, clippy::expect_used)]
mod tests {
    use super::*;

    /// The reference speech files beside the repository. The package's
    /// directory is read when the test runs (cargo sets it, and runs tests
    /// there), not compiled in: a build at another path stays reusable.
    fn data_dir() -> std::path::PathBuf {
        std::env::var_os("CARGO_MANIFEST_DIR")
            .map_or_else(
                || std::env::current_dir().unwrap_or_default(),
                std::path::PathBuf::from,
            )
            .join("../../../shared/data/speech-metrics")
    }

    /// A signal confined to the lowest eighth of the band under white noise of the
    /// same power (0 dB): the best fixed filter passes that eighth and stops the rest,
    /// keeping an eighth of the noise, 10 log10(8) = 9.0 dB. A filter from wrong spectra
    /// (or none) would stay near 0 dB.
    #[test]
    fn the_stationary_wiener_bound_of_a_band_limited_signal() {
        let n = 1 << 15;
        let (mut rng, normal) = (crate::rng::Xoshiro256::new(7), crate::rng::Ziggurat::new());
        let white: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
        let noise: Vec<f64> = (0..n).map(|_| normal.sample(&mut rng)).collect();
        let mut planner = RealFftPlanner::<f64>::new();
        let (fwd, inv) = (planner.plan_fft_forward(n), planner.plan_fft_inverse(n));
        let mut buf = white.clone();
        let mut spec = fwd.make_output_vec();
        fwd.process(&mut buf, &mut spec).unwrap();
        for (k, c) in spec.iter_mut().enumerate() {
            if k > n / 16 {
                *c = Complex::new(0.0, 0.0);
            }
        }
        inv.process(&mut spec, &mut buf).unwrap();
        let power = |x: &[f64]| x.iter().map(|v| v * v).sum::<f64>() / x.len() as f64;
        let scale = (power(&noise) / power(&buf)).sqrt();
        let signal: Vec<f64> = buf.iter().map(|v| v * scale).collect();
        let test: Vec<f64> = signal
            .iter()
            .zip(&noise)
            .map(|(s, e)| -0.5 * (s + e))
            .collect();
        let raw = score(&signal, &test, 8000.0, 10).snr_db;
        let bound = stationary_wiener_snr_db(&signal, &test, 8000.0, 10);
        assert!(raw.abs() < 0.3, "raw SNR {raw:.2} dB");
        assert!(
            (bound - 10.0 * 8f64.log10()).abs() < 0.5,
            "bound {bound:.2} dB, want 9.0"
        );
        // No noise: nothing to filter (only FFT rounding is left).
        assert!(stationary_wiener_snr_db(&signal, &signal, 8000.0, 0) > 200.0);
        // Too short for two segments, silent, empty, bad rate.
        assert!(stationary_wiener_snr_db(&signal[..1000], &test[..1000], 8000.0, 0).is_nan());
        assert!(stationary_wiener_snr_db(&vec![0.0; n], &test, 8000.0, 0).is_nan());
        assert!(stationary_wiener_snr_db(&[], &[], 8000.0, 0).is_nan());
        assert!(stationary_wiener_snr_db(&signal, &test, 0.0, 0).is_nan());
    }

    /// Reads a mono WAV as f64 samples (float, or integer scaled to [-1, 1)).
    fn read_wav(name: &str) -> Option<(Vec<f64>, f64)> {
        let path = data_dir().join(name);
        if !path.exists() {
            return None;
        }
        let mut reader = hound::WavReader::open(&path).expect("open wav");
        let spec = reader.spec();
        assert_eq!(spec.channels, 1, "{name} must be mono");
        let samples: Vec<f64> = match spec.sample_format {
            hound::SampleFormat::Float => reader
                .samples::<f32>()
                .map(|s| f64::from(s.expect("sample")))
                .collect(),
            hound::SampleFormat::Int => {
                let scale = f64::from(1u32 << (spec.bits_per_sample - 1));
                reader
                    .samples::<i32>()
                    .map(|s| f64::from(s.expect("sample")) / scale)
                    .collect()
            }
        };
        Some((samples, f64::from(spec.sample_rate)))
    }

    /// Clean, noisy and processed signals and their sample rate.
    type ReferenceData = (Vec<f64>, Vec<f64>, Vec<f64>, f64);

    /// The three reference recordings, or `None` with a printed reason.
    fn load_reference_data() -> Option<ReferenceData> {
        let clean = read_wav("1_speech_16000_Hz.wav");
        let noisy = read_wav("1_noisySpeech_16000_Hz.wav");
        let processed = read_wav("1_processed_16000_Hz.wav");
        match (clean, noisy, processed) {
            (Some((c, fs)), Some((n, _)), Some((p, _))) => Some((c, n, p, fs)),
            _ => {
                eprintln!(
                    "SKIPPED: reference speech data not found in {}",
                    data_dir().display()
                );
                None
            }
        }
    }

    fn assert_close(what: &str, got: f64, want: f64, tol: f64) {
        println!(
            "{what}: got {got:.4}, published {want:.4}, |diff| {:.5}",
            (got - want).abs()
        );
        assert!(
            (got - want).abs() <= tol,
            "{what}: got {got}, published {want}, tolerance {tol}"
        );
    }

    #[test]
    fn published_segmental_snr() {
        let Some((clean, noisy, processed, fs)) = load_reference_data() else {
            return;
        };
        assert_close(
            "segSNR noisy",
            segmental_snr_db(&clean, &noisy, fs),
            -0.2169,
            0.01,
        );
        assert_close(
            "segSNR processed",
            segmental_snr_db(&clean, &processed, fs),
            -1.2034,
            0.01,
        );
    }

    #[test]
    fn published_llr() {
        let Some((clean, noisy, processed, fs)) = load_reference_data() else {
            return;
        };
        assert_close("LLR noisy", llr(&clean, &noisy, fs), 1.2531, 0.01);
        assert_close("LLR processed", llr(&clean, &processed, fs), 1.6044, 0.01);
    }

    #[test]
    fn published_stoi() {
        let Some((clean, noisy, processed, fs)) = load_reference_data() else {
            return;
        };
        assert_close("STOI noisy", stoi(&clean, &noisy, fs), 0.8389, 0.005);
        assert_close(
            "STOI processed",
            stoi(&clean, &processed, fs),
            0.6612,
            0.005,
        );
    }

    /// Deterministic speech-like test signal: a few harmonics under a slow envelope plus a
    /// little pseudo-random noise.
    fn test_signal(len: usize, fs: f64, seed: u64) -> Vec<f64> {
        let mut state = seed;
        (0..len)
            .map(|i| {
                state = state
                    .wrapping_mul(6364136223846793005)
                    .wrapping_add(1442695040888963407);
                let noise = ((state >> 11) as f64 / (1u64 << 53) as f64) - 0.5;
                let t = i as f64 / fs;
                let env = 0.6 + 0.4 * (2.0 * std::f64::consts::PI * 3.0 * t).sin();
                let tone = (2.0 * std::f64::consts::PI * 220.0 * t).sin()
                    + 0.5 * (2.0 * std::f64::consts::PI * 660.0 * t).sin()
                    + 0.25 * (2.0 * std::f64::consts::PI * 1500.0 * t).sin();
                env * tone + 0.05 * noise
            })
            .collect()
    }

    #[test]
    fn snr_of_identical_signal_is_infinite() {
        let x = test_signal(4000, 16_000.0, 1);
        assert_eq!(snr_db(&x, &x), f64::INFINITY);
        let half: Vec<f64> = x.iter().map(|v| 0.5 * v).collect();
        assert!((snr_db(&x, &half) - 10.0 * 4f64.log10()).abs() < 1e-9);
    }

    #[test]
    fn score_of_scaled_signal_has_very_large_snr() {
        let fs = 16_000.0;
        let x = test_signal(16_000, fs, 2);
        let y: Vec<f64> = x.iter().map(|v| -0.5 * v).collect();
        let s = score(&x, &y, fs, 100);
        assert!(s.snr_db > 200.0, "{s:?}");
        assert_eq!(s.ssnr_db, 35.0);
        assert!(s.llr.abs() < 1e-6, "{s:?}");
        assert!((s.stoi - 1.0).abs() < 1e-6, "{s:?}");
    }

    #[test]
    fn best_lag_gain_finds_known_delay_and_negative_gain() {
        let x = test_signal(8000, 16_000.0, 3);
        let lag = 37;
        let mut y = vec![0.0; x.len() + lag];
        for (i, v) in x.iter().enumerate() {
            y[i + lag] = -0.5 * v;
        }
        let (l, g) = best_lag_gain(&x, &y, 200);
        assert_eq!(l, 37);
        assert!((g + 0.5).abs() < 1e-9, "gain {g}");
        // The other direction: the reference is the delayed one.
        let (l, g) = best_lag_gain(&y, &x, 200);
        assert_eq!(l, -37);
        assert!((g + 2.0).abs() < 1e-9, "gain {g}");
        // The lag is limited to the search range.
        let (l, _) = best_lag_gain(&x, &y, 10);
        assert!(l.abs() <= 10);
    }

    #[test]
    fn score_undoes_delay_and_gain() {
        let fs = 16_000.0;
        let x = test_signal(24_000, fs, 4);
        let lag = 37;
        let mut y = vec![0.0; x.len()];
        for i in lag..x.len() {
            y[i] = -0.5 * x[i - lag];
        }
        let s = score(&x, &y, fs, 100);
        assert!(s.snr_db > 200.0, "{s:?}");
        assert_eq!(s.ssnr_db, 35.0);
    }

    #[test]
    fn segmental_snr_of_identical_signals_is_clamped_to_35() {
        let x = test_signal(8000, 16_000.0, 5);
        assert_eq!(segmental_snr_db(&x, &x, 16_000.0), 35.0);
        assert_eq!(segmental_snr_db(&x, &x, 8_000.0), 35.0);
    }

    #[test]
    fn silence_is_handled() {
        let zeros = vec![0.0; 16_000];
        let x = test_signal(16_000, 16_000.0, 6);
        assert!(snr_db(&zeros, &zeros).is_nan());
        assert_eq!(snr_db(&x, &zeros), 0.0);
        assert_eq!(segmental_snr_db(&zeros, &zeros, 16_000.0), -10.0);
        assert!(segmental_snr_db(&x, &zeros, 16_000.0).abs() < 1e-12);
        assert_eq!(llr(&zeros, &zeros, 16_000.0), 2.0);
        assert_eq!(llr(&x, &zeros, 16_000.0), 2.0);
        assert!(stoi(&zeros, &x, 16_000.0).is_nan());
        let st = stoi(&x, &zeros, 16_000.0);
        assert!(st.is_finite() && st.abs() < 1e-6, "{st}");
        let (_, g) = best_lag_gain(&zeros, &x, 10);
        assert!(g.is_nan());
        let s = score(&zeros, &x, 16_000.0, 10);
        assert_eq!(s.snr_db, f64::NEG_INFINITY);
        let s = score(&x, &zeros, 16_000.0, 10);
        assert_eq!(s.snr_db, 0.0);
    }

    #[test]
    fn degenerate_inputs_never_panic() {
        let empty: [f64; 0] = [];
        let x = test_signal(20_000, 16_000.0, 7);
        let short = &x[..100];
        let mut with_nan = x.clone();
        with_nan[500] = f64::NAN;
        let mut with_inf = x.clone();
        with_inf[10] = f64::INFINITY;
        for fs in [
            16_000.0,
            8_000.0,
            44_100.0,
            22_050.5,
            0.0,
            -1.0,
            f64::NAN,
            f64::INFINITY,
            1e-9,
            1e300,
        ] {
            for (a, b) in [
                (&empty[..], &empty[..]),
                (&x[..], &empty[..]),
                (&empty[..], &x[..]),
                (&x[..], short),
                (&x[..], &with_nan[..]),
                (&with_inf[..], &x[..]),
            ] {
                assert!(snr_db(a, b).is_nan());
                assert!(segmental_snr_db(a, b, fs).is_nan());
                assert!(llr(a, b, fs).is_nan());
                assert!(stoi(a, b, fs).is_nan());
                let _ = best_lag_gain(a, b, usize::MAX);
                let _ = best_lag_gain(a, b, 0);
                let _ = score(a, b, fs, 1000);
            }
        }
        assert_eq!(best_lag_gain(&empty, &x, 5).0, 0);
        assert!(best_lag_gain(&empty, &x, 5).1.is_nan());
        assert!(best_lag_gain(&x, &with_nan, 5).1.is_nan());
        let s = score(&empty, &empty, 16_000.0, 10);
        assert!(s.snr_db.is_nan() && s.ssnr_db.is_nan() && s.llr.is_nan() && s.stoi.is_nan());
        // Too short for any frame at any of those rates (100 samples, 6.25 ms at 16 kHz).
        for fs in [16_000.0, 8_000.0, 44_100.0, 0.0, f64::NAN, 1e-9, 1e300] {
            assert!(segmental_snr_db(short, short, fs).is_nan());
            assert!(llr(short, short, fs).is_nan());
            assert!(stoi(short, short, fs).is_nan());
        }
        assert_eq!(snr_db(short, short), f64::INFINITY);
        // Single samples and tiny max_lag.
        assert_eq!(best_lag_gain(&[1.0], &[2.0], usize::MAX), (0, 2.0));
        assert!(stoi(&x[..1000], &x[..1000], 16_000.0).is_nan());
    }

    #[test]
    fn other_sample_rates_work() {
        for fs in [
            8_000.0, 11_025.0, 22_050.0, 44_100.0, 48_000.0, 20_000.0, 12_345.6,
        ] {
            let x = test_signal((fs * 2.0) as usize, fs, 8);
            let s = stoi(&x, &x, fs);
            assert!((s - 1.0).abs() < 1e-6, "fs {fs}: {s}");
            assert!(llr(&x, &x, fs).abs() < 1e-6, "fs {fs}");
            let noisy: Vec<f64> = x
                .iter()
                .zip(test_signal(x.len(), fs, 99))
                .map(|(a, b)| a + 0.3 * b)
                .collect();
            let s = stoi(&x, &noisy, fs);
            assert!(s > 0.3 && s < 1.0, "fs {fs}: {s}");
        }
    }

    #[test]
    fn resampler_matches_matlab_conventions() {
        // Output length ceil(len * p / q).
        let x = test_signal(1001, 16_000.0, 9);
        assert_eq!(resample(&x, 5, 8).map(|y| y.len()), Some(626));
        assert_eq!(resample(&x, 8, 5).map(|y| y.len()), Some(1602));
        // A low-frequency sine passes with unit gain and no delay.
        let fs = 16_000.0;
        let f = 300.0;
        let x: Vec<f64> = (0..16_000)
            .map(|i| (2.0 * std::f64::consts::PI * f * i as f64 / fs).sin())
            .collect();
        let y = resample(&x, 5, 8).expect("resample");
        for (i, v) in y.iter().enumerate().skip(200).take(9_000) {
            let want = (2.0 * std::f64::consts::PI * f * i as f64 / 10_000.0).sin();
            assert!((v - want).abs() < 2e-3, "sample {i}: {v} vs {want}");
        }
        assert_eq!(rational_ratio(10_000.0, 16_000.0), Some((5, 8)));
        assert_eq!(rational_ratio(10_000.0, 44_100.0), Some((100, 441)));
        assert_eq!(rational_ratio(10_000.0, 10_000.0), Some((1, 1)));
        assert_eq!(rational_ratio(10_000.0, 20_000.5), Some((20_000, 40_001)));
    }

    #[test]
    fn third_octave_bands_match_thirdoct() {
        let bands = third_octave_bands(10_000.0, 512, 15, 150.0);
        assert_eq!(bands.len(), 15);
        // First band: 150 Hz centre, edges ~133.6 Hz and ~168.4 Hz -> bins 7..9 (19.53 Hz bins).
        assert_eq!(bands[0], (7, 9));
        for w in bands.windows(2) {
            assert_eq!(w[0].1, w[1].0, "bands must be contiguous");
        }
    }

    #[test]
    fn llr_is_positive_for_distorted_signal() {
        let fs = 16_000.0;
        let x = test_signal(16_000, fs, 10);
        let noisy: Vec<f64> = x
            .iter()
            .zip(test_signal(x.len(), fs, 11))
            .map(|(a, b)| a + b)
            .collect();
        let v = llr(&x, &noisy, fs);
        assert!(v > 0.0 && v <= 2.0, "{v}");
    }
}
