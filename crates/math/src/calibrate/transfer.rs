//! Effect (a): the object's transfer function (thesis ch. 4.3.3).

use super::model::{eq_sse, Fit, Model};
use super::signal::{
    alias, curvature_sigma, dominant, golden, jackknife, peak, smooth3, stft, stft_len,
};
use super::{Candidate, Correction, Uncertainty};
use crate::numeric::median;
use realfft::num_complex::Complex;

/// The share of the reference's median power (per bin, over the fit
/// frames) below which the table's edge bins are left out.
const EDGE_POWER: f64 = 0.1;

/// How far (dB) the error that a bin's harmonics imply for the gain
/// measured there may exceed the table's median before the bin is left
/// out ([`level_dependent`]).
pub(super) const LEVEL_DB: f64 = 3.0;

/// Where the gain a sweep measures holds only at its level. A static
/// response `x - c x³` driven at amplitude `A` passes the fundamental at
/// `1 - 3cA²/4` and puts a third harmonic of `cA³/4` beside it: the
/// fundamental's gain is off by `1 + 3r` (to first order) where `r` is
/// the harmonic's amplitude over the fundamental's. A resonance that
/// drives the object into its nonlinear range changes the gain the table
/// reads at its frequencies with the level (down to a dip where a +5 dB
/// resonance folds a cubic response), and a recording at another level
/// (speech, quieter than the sweep) does not see that gain.
///
/// Per STFT bin over the fit frames: the harmonics-to-fundamental power
/// ratio `R` of the frames whose reference is a tone (its strongest bin
/// and the two either side hold half its power; others say nothing),
/// weighted by the reference's power in that bin (as the table's own
/// sums are). The harmonics are the recovery's power above its per-bin
/// median at the aliases of 2 to 5 times the tone's frequency, where the
/// reference has none. Each bin's implied error is `20 log10(1 + 3 √R)`
/// dB; the bins where it exceeds the median over the reference's bins by
/// [`LEVEL_DB`] are returned with their `R` (dB) and that excess. A
/// distortion the same at every frequency changes the gain the same at
/// every frequency, which the table (relative to its median) does not
/// see.
pub(super) fn level_dependent(m: &Model, z: &[f64], t: &[f64]) -> Vec<(usize, f64, f64)> {
    let nfft = stft_len(m.fs);
    let (fz, ft) = (stft(z, nfft), stft(t, nfft));
    let nb = nfft / 2 + 1;
    let df = m.fs / nfft as f64;
    if fz.is_empty() {
        return Vec::new();
    }
    let floor: Vec<f64> = (0..nb)
        .map(|k| {
            let mut v: Vec<f64> = fz.iter().map(|f| f[k].norm_sqr()).collect();
            median(&mut v)
        })
        .collect();
    let lo_bin = m
        .opts
        .highpass
        .map_or(1, |(_, c)| (1.5 * c / df).ceil() as usize);
    let (mut dist, mut w) = (vec![0.0; nb], vec![0.0; nb]);
    for (i, (a, b)) in fz.iter().zip(&ft).enumerate() {
        if !m.is_fit(i * nfft / 2 + nfft / 2) {
            continue;
        }
        let Some((k0, pref, f0)) = tone(b, df) else {
            continue;
        };
        let near = |k: usize| k.abs_diff(k0) <= 2;
        let fund: f64 = (0..nb)
            .filter(|&k| k.abs_diff(k0) <= 1)
            .map(|k| a[k].norm_sqr())
            .sum();
        let mut harm = 0.0;
        let mut seen = Vec::with_capacity(15);
        for h in 2..=5 {
            let kh = (alias(h as f64 * f0, m.fs) / df).round() as usize;
            for k in kh.saturating_sub(1)..=(kh + 1).min(nb - 1) {
                if k < lo_bin || near(k) || b[k].norm_sqr() > 1e-3 * pref || seen.contains(&k) {
                    continue;
                }
                seen.push(k);
                harm += (a[k].norm_sqr() - floor[k]).max(0.0);
            }
        }
        if fund <= 0.0 {
            continue;
        }
        for k in 0..nb {
            let px = b[k].norm_sqr();
            dist[k] += harm / fund * px;
            w[k] += px;
        }
    }
    let wmax = w.iter().cloned().fold(0.0, f64::max);
    let bins: Vec<usize> = (lo_bin..nb).filter(|&k| w[k] > 1e-3 * wmax).collect();
    let err = |k: usize| 20.0 * (1.0 + 3.0 * (dist[k] / w[k]).sqrt()).log10();
    let mut all: Vec<f64> = bins.iter().map(|&k| err(k)).collect();
    let med = median(&mut all);
    if !med.is_finite() {
        return Vec::new();
    }
    bins.into_iter()
        .filter(|&k| err(k) > med + LEVEL_DB)
        .map(|k| (k, 10.0 * (dist[k] / w[k]).max(1e-30).log10(), err(k) - med))
        .collect()
}

/// The samples of a recording of `n` where the sweep stood in the
/// `level` bins ([`level_dependent`]): every sample of each STFT frame of
/// the target `t` whose reference is a tone ([`tone`]) with its strongest
/// bin within one of a level-dependent one. What the object did there
/// held only at the sweep's level, so every fit and the held-out score
/// leave it out ([`Model::skip`]); empty when no bin is.
pub(super) fn level_stretch(m: &Model, t: &[f64], level: &[(usize, f64, f64)]) -> Vec<bool> {
    if level.is_empty() {
        return Vec::new();
    }
    let nfft = stft_len(m.fs);
    let df = m.fs / nfft as f64;
    let mut skip = vec![false; t.len()];
    for (i, b) in stft(t, nfft).iter().enumerate() {
        let Some((k0, ..)) = tone(b, df) else {
            continue;
        };
        if level.iter().any(|l| l.0.abs_diff(k0) <= 1) {
            let start = i * nfft / 2;
            skip[start..(start + nfft).min(t.len())].fill(true);
        }
    }
    skip
}

/// A frame's tone: its strongest bin, that bin's power and its refined
/// frequency ([`dominant`]), where the strongest bin and the two either
/// side hold half the frame's power; `None` where they do not (the frame
/// is not a tone).
fn tone(b: &[Complex<f64>], df: f64) -> Option<(usize, f64, f64)> {
    let (k0, pref, f0) = dominant(b, df);
    let total: f64 = b.iter().map(|c| c.norm_sqr()).sum();
    let near: f64 = b
        .iter()
        .enumerate()
        .filter(|(k, _)| k.abs_diff(k0) <= 2)
        .map(|(_, c)| c.norm_sqr())
        .sum();
    (pref > 0.0 && near >= 0.5 * total).then_some((k0, pref, f0))
}

/// Per STFT bin: Σ|Z| P, Σ|T| P, Σ P (P the reference's short-time power)
/// and the cross-spectrum Σ Z T* sign(g), over some frames; and the
/// reference's power over every frame of the recording, held out or not
/// (the band the sweep covers), in a total only.
#[derive(Clone)]
struct Sums {
    num: Vec<f64>,
    den: Vec<f64>,
    wsum: Vec<f64>,
    cross: Vec<Complex<f64>>,
    whole: Vec<f64>,
}

impl Sums {
    fn new(nb: usize) -> Sums {
        Sums {
            num: vec![0.0; nb],
            den: vec![0.0; nb],
            wsum: vec![0.0; nb],
            cross: vec![Complex::new(0.0, 0.0); nb],
            whole: vec![0.0; nb],
        }
    }

    /// `self` plus (`sign` 1) or minus (-1) `o`.
    fn add(&mut self, o: &Sums, sign: f64) {
        for k in 0..self.num.len() {
            self.num[k] += sign * o.num[k];
            self.den[k] += sign * o.den[k];
            self.wsum[k] += sign * o.wsum[k];
            self.cross[k] += o.cross[k] * sign;
        }
    }
}

/// Transfer coefficients (thesis ch. 4.3.3): per STFT bin, the average of
/// the recovery's magnitude over time weighted by the reference's short-
/// time power, over the same average of the reference's magnitude; in dB
/// relative to the linear gain, smoothed over three bins; bins where the
/// reference has little energy are left out (interpolated between
/// neighbours inside the table; below it the first row holds, above it
/// [`curve`] returns to the band's median gain). Also
/// the phase of the response: the angle of the cross-spectrum (recovery
/// times the conjugate reference, sign of the gain removed) summed over the
/// same frames, smoothed over three bins. The thesis' coefficients are
/// magnitudes; without the phase, a resonance leaves a lag that changes
/// with frequency, which other effects then try to explain.
///
/// Returns the sums of each fit block's frames (frames centred in the fit
/// part, grouped by the block their centre is in) and their total; the
/// coefficients are [`curve`] of the total.
fn block_sums(m: &Model, z: &[f64], fit: &Fit) -> (Vec<Sums>, Sums) {
    let nfft = stft_len(m.fs);
    let (fz, ft) = (stft(z, nfft), stft(&fit.t, nfft));
    let nb = nfft / 2 + 1;
    let mut blocks: Vec<(usize, Sums)> = Vec::new();
    for (i, (a, b)) in fz.iter().zip(&ft).enumerate() {
        let centre = i * nfft / 2 + nfft / 2;
        if !m.is_fit(centre) {
            continue;
        }
        let block = centre / nfft;
        if blocks.last().is_none_or(|(k, _)| *k != block) {
            blocks.push((block, Sums::new(nb)));
        }
        let Some((_, s)) = blocks.last_mut() else {
            continue;
        };
        for k in 0..nb {
            let px = b[k].norm_sqr();
            s.num[k] += a[k].norm() * px;
            s.den[k] += b[k].norm() * px;
            s.wsum[k] += px;
            s.cross[k] += a[k] * b[k].conj() * fit.g.signum();
        }
    }
    let blocks: Vec<Sums> = blocks.into_iter().map(|(_, s)| s).collect();
    let mut all = Sums::new(nb);
    blocks.iter().for_each(|b| all.add(b, 1.0));
    for b in &ft {
        for (w, c) in all.whole.iter_mut().zip(b) {
            *w += c.norm_sqr();
        }
    }
    (blocks, all)
}

/// A transfer table: its frequencies (Hz), smoothed coefficients (dB) and
/// phases (degrees), and the band (Hz) its rows were measured over.
type Table = (Vec<f64>, Vec<f64>, Vec<f64>, [f64; 2]);

/// The frequencies, smoothed coefficients (dB) and phases (degrees) of the
/// bins `sums` says enough about, and the band they were measured over:
/// from the first to the last of those bins (the rows outside it, added
/// below, are not measurements).
fn curve(m: &Model, sums: &Sums, g: f64, skip: &[usize]) -> Table {
    let Sums {
        num,
        den,
        wsum,
        cross,
        whole,
    } = sums;
    let nb = num.len();
    let nfft = stft_len(m.fs);
    let hz = |k: usize| k as f64 * m.fs / nfft as f64;
    let wmax = wsum.iter().cloned().fold(0.0, f64::max);
    let lo = m.opts.highpass.map_or(0.0, |(_, c)| 1.5 * c);
    let g = g.abs().max(1e-300);
    let valid: Vec<usize> = (1..nb)
        .filter(|&k| wsum[k] > 1e-3 * wmax && den[k] > 0.0 && hz(k) >= lo)
        .collect();
    // The last bin the reference feeds at all over the whole recording
    // (its leakage included).
    let reach = {
        let top = whole.iter().cloned().fold(0.0, f64::max);
        (1..nb).rev().find(|&k| whole[k] > 1e-3 * top).unwrap_or(0)
    };
    // The table's ends: the bins at either edge that the reference feeds
    // only through the window's leakage (under a tenth of its median
    // power) are left out (what the table holds beyond them: below).
    let valid: Vec<usize> = {
        let mut w: Vec<f64> = valid.iter().map(|&k| wsum[k]).collect();
        w.sort_by(f64::total_cmp);
        let med = w.get(w.len() / 2).copied().unwrap_or(0.0);
        let ok = |k: usize| wsum[k] >= EDGE_POWER * med;
        let a = valid.iter().position(|&k| ok(k)).unwrap_or(0);
        let b = valid.iter().rposition(|&k| ok(k)).map_or(0, |b| b + 1);
        valid[a..b.max(a)].to_vec()
    };
    // The bins whose gain holds only at the sweep's level are not
    // measured here: the stretch of the sweep spent within a bin of them
    // is left out of the fit, so they and their neighbours hold little of
    // the reference's power, if any. Those within the table are put back
    // below with the band's own gain.
    let valid: Vec<usize> = valid.into_iter().filter(|k| !skip.contains(k)).collect();
    let level: Vec<usize> = match (valid.first(), valid.last()) {
        (Some(&a), Some(&b)) => (a + 1..b)
            .filter(|k| !valid.contains(k) && skip.iter().any(|s| s.abs_diff(*k) <= 1))
            .collect(),
        _ => Vec::new(),
    };
    let raw: Vec<f64> = valid
        .iter()
        .map(|&k| 20.0 * (num[k] / den[k] / g).max(1e-12).log10())
        .collect();
    let smooth = smooth3(&raw);
    let phase: Vec<f64> = (0..valid.len())
        .map(|i| {
            let (a, b) = (i.saturating_sub(1), (i + 2).min(valid.len()));
            let c: Complex<f64> = valid[a..b]
                .iter()
                .map(|&k| cross[k] / cross[k].norm().max(1e-300))
                .sum();
            c.arg().to_degrees()
        })
        .collect();
    let freqs: Vec<f64> = valid.iter().map(|&k| hz(k)).collect();
    let band = match (freqs.first(), freqs.last()) {
        (Some(&a), Some(&b)) => [a, b],
        _ => [0.0, 0.0],
    };
    if freqs.len() < 3 {
        return (freqs, smooth, phase, band);
    }
    // A bin whose gain holds only at the sweep's level holds the band's
    // median gain: the sweep measured there a gain the object has at no
    // other level (compressed, or past a fold), and an interpolation
    // from its neighbours, themselves part-way into the compression,
    // claims a gain nobody measured. Neither is boosted nor cut; its phase
    // is interpolated from its neighbours (past a fold the fundamental's
    // phase turns over too, so the bin's own is not read).
    let neutral = {
        let mut c = smooth.clone();
        median(&mut c)
    };
    let mut rows: Vec<(f64, f64, f64)> = freqs
        .iter()
        .zip(&smooth)
        .zip(&phase)
        .map(|((&f, &c), &p)| (f, c, p))
        .collect();
    for k in level {
        let f = hz(k);
        let p = super::correction::interp_held(&freqs, &phase, f);
        rows.push((f, neutral, p));
    }
    rows.sort_by(|a, b| a.0.total_cmp(&b.0));
    // Above the sweep's band nothing was measured either. The last row
    // is held up to the last bin the reference feeds over the whole
    // recording (the table's own rows end where the fit frames' power
    // does, and the held-out frames at the sweep's end reach a little
    // further); from there the gain returns to the band's median by
    // halfway to the Nyquist frequency, rather than holding the last
    // row's value (a resonance's or a dip's) across every frequency above
    // it, which a later recording with content there (speech) would be
    // boosted or cut by. Below the band the first row is held: an
    // object's gain under its first resonance is its stiffness's, flat
    // towards zero frequency.
    let top = valid.last().copied().unwrap_or(0);
    if reach > top {
        let (_, c, p) = rows[rows.len() - 1];
        rows.push((hz(reach), c, p));
    }
    let measured = rows.len();
    let (last_hz, last_db) = (rows[measured - 1].0, rows[measured - 1].1);
    let width = 0.5 * (0.5 * m.fs - last_hz);
    for k in reach.max(top) + 1..nfft / 2 {
        let f = hz(k);
        let t = ((f - last_hz) / width).min(1.0);
        rows.push((f, last_db + (neutral - last_db) * t, 0.0));
    }
    // The table carries no pure delay. Its phase is measured against the
    // lag the linear model fitted to the raw recovery, which the object's
    // own phase biases (a dip's or a resonance's group delay), and the
    // table's phase then holds the opposite delay. A later recording's lag
    // is fitted again, so the delay does nothing for what the band holds,
    // but it shifts what folds into the band from above the Nyquist
    // frequency as though it were in band. So the delay (least squares,
    // through zero frequency) that separates the measured phase from the
    // minimum phase of the table's gain is taken out: an object's response
    // is minimum phase up to a delay. The rows above the band take the
    // minimum phase.
    let f: Vec<f64> = rows.iter().map(|r| r.0).collect();
    let gain: Vec<f64> = rows.iter().map(|r| r.1).collect();
    let mp = minimum_phase_deg(&f, &gain, m.fs);
    let (mut sxy, mut sxx) = (0.0, 0.0);
    for (r, p) in rows[..measured].iter().zip(&mp) {
        sxy += wrap_deg(r.2 - p) * r.0;
        sxx += r.0 * r.0;
    }
    let delay = if sxx > 0.0 { sxy / sxx } else { 0.0 };
    for (i, (r, p)) in rows.iter_mut().zip(&mp).enumerate() {
        r.2 = if i < measured { r.2 - delay * r.0 } else { *p };
    }
    (
        rows.iter().map(|r| r.0).collect(),
        rows.iter().map(|r| r.1).collect(),
        rows.iter().map(|r| r.2).collect(),
        band,
    )
}

/// `d` (degrees) wrapped into [-180, 180).
fn wrap_deg(d: f64) -> f64 {
    (d + 180.0).rem_euclid(360.0) - 180.0
}

/// The delete-one-block jackknife's standard deviations of [`peak`]'s
/// frequency and height (infinite with fewer than three fit blocks).
fn peak_sd(m: &Model, (blocks, all): &(Vec<Sums>, Sums), g: f64, skip: &[usize]) -> (f64, f64) {
    if blocks.len() < 3 {
        return (f64::INFINITY, f64::INFINITY);
    }
    let mut loo = Vec::with_capacity(blocks.len());
    for b in blocks {
        let mut s = all.clone();
        s.add(b, -1.0);
        let (f, c, ..) = curve(m, &s, g, skip);
        match peak(&f, &c) {
            Some(p) => loo.push(p),
            None => return (f64::INFINITY, f64::INFINITY),
        }
    }
    (
        jackknife(loo.iter().map(|p| p.0)),
        jackknife(loo.iter().map(|p| p.1)),
    )
}

/// The phase (degrees, at `freqs_hz`) of the minimum-phase response whose
/// gain is `gain_db` at those frequencies (the table's end values held
/// beyond it, over 0 to `fs`/2): by the real cepstrum, folded onto
/// positive quefrencies (the Hilbert transform of the log gain). A
/// passive object's response is minimum phase up to a delay: its phase
/// follows from its gain. A phase that moves where the gain does not (or
/// the other way) is not an object's response.
pub(super) fn minimum_phase_deg(freqs_hz: &[f64], gain_db: &[f64], fs: f64) -> Vec<f64> {
    const N: usize = 4096;
    if freqs_hz.is_empty() || freqs_hz.len() != gain_db.len() || fs.is_nan() || fs <= 0.0 {
        return vec![0.0; freqs_hz.len()];
    }
    let df = fs / N as f64;
    let mut planner = realfft::RealFftPlanner::<f64>::new();
    let (inv, fwd) = (planner.plan_fft_inverse(N), planner.plan_fft_forward(N));
    let mut spec: Vec<Complex<f64>> = (0..=N / 2)
        .map(|k| {
            let db = super::correction::interp_held(freqs_hz, gain_db, k as f64 * df);
            Complex::new(db * std::f64::consts::LN_10 / 20.0, 0.0)
        })
        .collect();
    let mut cep = vec![0.0; N];
    if inv.process(&mut spec, &mut cep).is_err() {
        return vec![0.0; freqs_hz.len()];
    }
    for (n, c) in cep.iter_mut().enumerate() {
        let fold = match n {
            0 => 1.0,
            n if n == N / 2 => 1.0,
            n if n < N / 2 => 2.0,
            _ => 0.0,
        };
        *c *= fold / N as f64;
    }
    let mut out = vec![Complex::new(0.0, 0.0); N / 2 + 1];
    if fwd.process(&mut cep, &mut out).is_err() {
        return vec![0.0; freqs_hz.len()];
    }
    freqs_hz
        .iter()
        .map(|&f| {
            let x = (f / df).clamp(0.0, (N / 2) as f64);
            let (i, t) = (x.floor() as usize, x.fract());
            let j = (i + 1).min(N / 2);
            (out[i].im + t * (out[j].im - out[i].im)).to_degrees()
        })
        .collect()
}

/// `c` with a transfer function's phase replaced by the minimum phase of
/// its gain ([`minimum_phase_deg`]); any other correction as it is.
pub(super) fn passive(c: &Correction, fs: f64) -> Correction {
    match c {
        Correction::Transfer {
            freqs_hz,
            coef_db,
            k,
            measured_hz,
            ..
        } => {
            let gain: Vec<f64> = coef_db.iter().map(|c| k * c).collect();
            Correction::Transfer {
                freqs_hz: freqs_hz.clone(),
                coef_db: coef_db.clone(),
                phase_deg: minimum_phase_deg(freqs_hz, &gain, fs),
                k: *k,
                measured_hz: *measured_hz,
            }
        }
        other => other.clone(),
    }
}

pub(super) fn fit_transfer(m: &Model, z: &[f64], fit: &Fit) -> Option<Candidate> {
    let sums = block_sums(m, z, fit);
    let skip: Vec<usize> = m.level.iter().map(|(k, ..)| *k).collect();
    let (freqs, coef, phase, measured_hz) = curve(m, &sums.1, fit.g, &skip);
    if freqs.len() < 3 {
        return None;
    }
    let corr = |k: f64| Correction::Transfer {
        freqs_hz: freqs.clone(),
        coef_db: coef.clone(),
        phase_deg: phase.clone(),
        k,
        measured_hz,
    };
    let grid: Vec<(f64, f64)> = (0..=12)
        .map(|i| {
            let k = i as f64 * 0.25;
            (k, eq_sse(m, z, fit, &corr(k)))
        })
        .collect();
    let (bi, _) = grid
        .iter()
        .enumerate()
        .min_by(|a, b| a.1 .1.total_cmp(&b.1 .1))?;
    let (lo, hi) = (grid[bi].0 - 0.25, grid[bi].0 + 0.25);
    let (k, sse) = golden(|k| eq_sse(m, z, fit, &corr(k)), lo.max(0.0), hi, 16);
    let nf = m.nfit(z.len());
    let sd = curvature_sigma(|k| eq_sse(m, z, fit, &corr(k)), k, 0.02, sse / nf as f64);
    let (peak_hz, peak_db) = peak_sd(m, &sums, fit.g, &skip);
    Some(Candidate {
        correction: corr(k),
        uncertainty: Uncertainty::Transfer {
            k: sd,
            peak_hz,
            peak_db,
        },
    })
}

#[cfg(test)]
mod tests {
    use super::{minimum_phase_deg, peak};
    use realfft::num_complex::Complex;

    /// A one-pole low-pass and a two-pole resonance are minimum phase: the
    /// phase made from their gain alone is their phase.
    #[test]
    fn the_minimum_phase_of_a_gain_is_the_phase_of_a_minimum_phase_filter() {
        let fs = 2200.0;
        let freqs: Vec<f64> = (1..1100).map(|k| k as f64).collect();
        let z = |f: f64| Complex::from_polar(1.0, -2.0 * std::f64::consts::PI * f / fs);
        let filters: [&dyn Fn(f64) -> Complex<f64>; 2] = [
            &|f| Complex::new(0.4, 0.0) / (Complex::new(1.0, 0.0) - z(f) * 0.6),
            &|f| {
                let (r, w) = (0.95, 2.0 * std::f64::consts::PI * 400.0 / fs);
                Complex::new(1.0, 0.0)
                    / (Complex::new(1.0, 0.0) - z(f) * (2.0 * r * w.cos()) + z(f) * z(f) * (r * r))
            },
        ];
        for (i, h) in filters.iter().enumerate() {
            let gain: Vec<f64> = freqs.iter().map(|&f| 20.0 * h(f).norm().log10()).collect();
            let got = minimum_phase_deg(&freqs, &gain, fs);
            for (k, &f) in freqs.iter().enumerate().step_by(50) {
                let want = h(f).arg().to_degrees();
                assert!(
                    (got[k] - want).abs() < 1.0,
                    "filter {i} at {f} Hz: {} against {want}",
                    got[k]
                );
            }
        }
        // A zero outside the unit circle has the gain of its mirror inside
        // and another phase: the phase made from the gain is the mirror's.
        let outside = |f: f64| Complex::new(1.0, 0.0) - z(f) * 2.0;
        let gain: Vec<f64> = freqs
            .iter()
            .map(|&f| 20.0 * outside(f).norm().log10())
            .collect();
        let got = minimum_phase_deg(&freqs, &gain, fs);
        let k = 549; // 550 Hz
        let mirror = (Complex::new(2.0, 0.0) - z(freqs[k])).arg().to_degrees();
        assert!((got[k] - mirror).abs() < 1.0, "{} against {mirror}", got[k]);
        assert!((got[k] - outside(freqs[k]).arg().to_degrees()).abs() > 30.0);
    }

    /// The peak of a sampled bump lies between bins, and its height is
    /// read against the curve's median, not its floor or its mean.
    #[test]
    fn the_peak_lies_between_bins_above_the_median() {
        let f: Vec<f64> = (1..100).map(|k| k as f64 * 10.0).collect();
        let c: Vec<f64> = f
            .iter()
            .map(|&x| 1.0 + 9.0 * (-((x - 503.0) / 40.0).powi(2)).exp())
            .collect();
        let (hz, db) = peak(&f, &c).unwrap();
        assert!((hz - 503.0).abs() < 1.0, "{hz}");
        assert!((db - 9.0).abs() < 0.1, "{db}");
        assert!(peak(&f[..2], &c[..2]).is_none());
        assert!(peak(&f, &c[..50]).is_none());
    }
}
